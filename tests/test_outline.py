"""The mouth opening's smooth outline (editor/engine/outline.py)."""

from __future__ import annotations

import numpy as np

from editor.engine.outline import CHORD_PX, smooth_loop, splits


def _lips(a: float, b_up: float, b_low: float, n: int = 7) -> tuple[np.ndarray, np.ndarray]:
    """A mouth loop as the mesh orders it (corner, n upper points, corner, n lower points
    backwards) on two parabolic arcs of half-width ``a`` that meet at the corners as lips do;
    and a dense copy of the same two arcs (the true outline)."""
    x = np.linspace(-a, a, n + 2)
    up = np.stack([x, -b_up * (1 - (x / a) ** 2)], 1)
    low = np.stack([x, b_low * (1 - (x / a) ** 2)], 1)[::-1]
    loop = np.concatenate([up, low[1:-1]]).astype(np.float32)
    s = np.linspace(-a, a, 4000)
    dense = np.concatenate([np.stack([s, -b_up * (1 - (s / a) ** 2)], 1),
                            np.stack([s, b_low * (1 - (s / a) ** 2)], 1)])
    return loop, dense


def _smooth(loop: np.ndarray) -> np.ndarray:
    n = len(loop)
    split = splits(loop, (np.arange(n) + 1) % n, np.array([0]), [CHORD_PX])[0]
    return smooth_loop(loop, (0, 8), split)


def _farthest_from(points: np.ndarray, dense: np.ndarray) -> float:
    """Largest distance of the segments' midpoints (closed loop) to the dense outline."""
    mid = 0.5 * (points + np.roll(points, -1, 0))
    d = np.linalg.norm(mid[:, None, :] - dense[None, :, :], axis=2).min(1)
    return float(d.max())


def test_a_small_mouth_stays_the_mesh_polygon():
    loop, _ = _lips(0.5 * CHORD_PX * 3, 4.0, 5.0)  # sides shorter than CHORD_PX
    assert _smooth(loop) is loop


def test_a_large_mouth_follows_its_lips_arcs_through_the_same_vertices():
    loop, dense = _lips(300.0, 60.0, 90.0)  # a 4K face's open mouth: sides of ~60-90 px
    out = _smooth(loop)
    assert out.dtype == loop.dtype and len(out) > 8 * len(loop)
    # every vertex of the mesh is on the curve, in the loop's order
    hits = [int(np.argmin(np.linalg.norm(out - p, axis=1))) for p in loop]
    assert np.allclose(out[hits], loop, atol=1e-3)
    assert hits == sorted(hits)
    # the straight sides depart from the lips' arcs by 1.4 px, the curve by 0.08
    before, after = _farthest_from(loop, dense), _farthest_from(out, dense)
    assert before > 1.0 and after < 0.15, (before, after)
    # no side longer than the chord asked for
    assert np.linalg.norm(np.diff(out, axis=0, append=out[:1]), axis=1).max() <= CHORD_PX + 1e-3


def test_closed_lips_stay_closed_and_the_corners_sharp():
    loop, _ = _lips(300.0, 60.0, 90.0)
    closed = loop.copy()
    closed[9:] = closed[1:8][::-1]  # the lower lip on the upper one
    out = _smooth(closed)
    x, y = out[:, 0].astype(np.float64), out[:, 1].astype(np.float64)
    assert abs(0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))) < 1e-3
    # the corners stay points where the lips meet: the curve turns back there (no rounding
    # past the corner: the samples either side of it lie towards the mouth's middle)
    for c in (0, 8):
        k = int(np.argmin(np.linalg.norm(out - loop[c], axis=1)))
        assert np.allclose(out[k], loop[c], atol=1e-3)
        side = np.sign(loop[4, 0] - loop[c, 0])
        assert side * (out[k - 1, 0] - out[k, 0]) > 0 and side * (out[k + 1, 0] - out[k, 0]) > 0


def test_a_large_faces_eyes_and_mouth_open_along_smooth_lids(sample_face, monkeypatch):
    """The pixel sets the layers composite (layers._opening_masks) follow the lids' and lips'
    arcs on a large face (the sample upscaled 4 x: eye loops with sides of 10-25 px, which drew
    a chamfered lid margin over the iris) and stay the mesh's polygons at the sample's size."""
    import cv2

    from editor.core import Face, apply_preset
    from editor.engine import layers

    seen: list[list[int]] = []
    real = layers._opening_masks

    def spy(items):
        seen.append([len(loop) for loop, _, _ in items])
        return real(items)

    monkeypatch.setattr(layers, "_opening_masks", spy)
    faps = apply_preset("surprise", 1.5)
    sample_face.render(faps)
    assert seen[-1] == [12, 12, 16]
    big = Face.from_image(cv2.resize(sample_face.image, None, fx=4, fy=4,
                                     interpolation=cv2.INTER_CUBIC))
    big.render(faps)
    assert all(n >= 2 * k for n, k in zip(seen[-1], (12, 12, 16), strict=True)), seen[-1]
