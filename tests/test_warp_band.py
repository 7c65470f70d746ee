"""Head rotation (FAPs 48-50) warps the frame's band through a coarse map (issue 15): the
picture matches the exact per-pixel warp within a stated tolerance, the face itself exactly."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from conftest import map_error

import editor.engine.warp as warp_mod
from editor.core import FAPS, Face
from editor.engine.imageio import load_image
from editor.engine.warp import WarpPlan, warp
from editor.resources import SAMPLE_FACE

#: tolerance of the band's backward map against the exact piecewise-affine one, pixels
MAP_MAX_PX = 2.0
MAP_MEAN_PX = 0.02
#: share of the pixels whose map is off by more than half a pixel
MAP_OVER_HALF = 0.001

HEAD = {"open_jaw": 400, "raise_l_cornerlip": 200, "raise_r_cornerlip": 200, 48: 14000,
        49: -20000, 50: 16000}


@pytest.fixture(scope="module")
def wide_face() -> Face:
    """The sample in a 1280 x 720 frame (padded by reflection, as the bench's canvases)."""
    img = load_image(SAMPLE_FACE)
    s = 720 / img.shape[0]
    fit = cv2.resize(img, None, fx=s, fy=s, interpolation=cv2.INTER_CUBIC)
    left = (1280 - fit.shape[1]) // 2
    canvas = cv2.copyMakeBorder(fit, 0, 0, left, 1280 - fit.shape[1] - left,
                                cv2.BORDER_REFLECT_101)
    return Face.from_image(np.ascontiguousarray(canvas), own_expression=False)


def _both(face: Face, faps: dict, monkeypatch: pytest.MonkeyPatch):
    """(band result, exact result, calls of the band path)."""
    calls = []
    real = warp_mod._warp_band
    monkeypatch.setattr(warp_mod, "_warp_band", lambda *a: calls.append(1) or real(*a))
    pts = face.deform(faps)
    tf = face.layer_transforms(pts)
    exact = WarpPlan(face.image, face.vertices, face.mesh.triangles, face.mesh.holes)
    assert exact.band is None and face.warp_plan.band is not None
    return (warp(face.warp_plan, pts, tf, cavity=False), warp(exact, pts, tf, cavity=False),
            len(calls))


def test_head_rotation_matches_exact_warp_within_tolerance(wide_face, monkeypatch):
    fast, exact, calls = _both(wide_face, HEAD, monkeypatch)
    assert calls == 1  # the band path was taken
    h, w = wide_face.image.shape[:2]
    assert fast.bbox == exact.bbox
    # the band ends on the mesh's outer ring, a face radius beyond the margin: the head turns,
    # the shoulders and the rest of the frame stay (bit for bit)
    bx0, by0, bx1, by1 = fast.bbox
    assert (bx1 - bx0) * (by1 - by0) < 0.5 * w * h
    outside = np.ones((h, w), bool)
    outside[by0:by1, bx0:bx1] = False
    assert np.array_equal(fast.image[outside], wide_face.image[outside])
    err = map_error(fast, exact)
    assert err.max() <= MAP_MAX_PX
    assert err.mean() <= MAP_MEAN_PX
    assert (err > 0.5).mean() <= MAP_OVER_HALF
    # the openings exactly; the face (inside the band's inner box) by the exact per-pixel
    # map (up to which triangle owns a pixel on an edge of the large triangles that the box
    # clips: neighbouring maps agree on their edge, so a small fraction of a pixel)
    assert np.array_equal(fast.mouth_mask, exact.mouth_mask)
    assert np.array_equal(fast.eye_mask, exact.eye_mask)
    moved_t = np.flatnonzero((np.abs(wide_face.deform(HEAD) - wide_face.vertices).max(1)
                              > 1e-3)[wide_face.mesh.triangles].any(1))
    x0, y0, x1, y1 = warp_mod._inner_box(wide_face.warp_plan, wide_face.deform(HEAD), moved_t,
                                         w, h)
    x0, y0, x1, y1 = max(x0, bx0) - bx0, max(y0, by0) - by0, min(x1, bx1) - bx0, min(y1, by1) - by0
    assert (x1 - x0) * (y1 - y0) > 0
    assert err[y0:y1, x0:x1].max() <= 0.25
    assert (err[y0:y1, x0:x1] > 0).mean() < 0.001
    d = np.abs(fast.image.astype(np.int16) - exact.image.astype(np.int16))
    assert d.mean() <= 0.1  # grey levels over the frame


def test_expression_without_head_rotation_is_the_exact_warp(wide_face, monkeypatch):
    fast, exact, calls = _both(wide_face, {k: v for k, v in HEAD.items() if k not in (48, 49, 50)},
                               monkeypatch)
    assert calls == 0
    assert fast.bbox == exact.bbox
    assert np.array_equal(fast.image, exact.image)


def test_full_render_with_head_rotation_close_to_exact(wide_face):
    vec = FAPS.clamp(FAPS.vector(HEAD))
    fast = wide_face.render(vec)
    try:
        wide_face.__dict__["warp_plan"] = WarpPlan(wide_face.image, wide_face.vertices,
                                                   wide_face.mesh.triangles,
                                                   wide_face.mesh.holes)
        exact = wide_face.render(vec)
    finally:
        del wide_face.__dict__["warp_plan"]
    d = np.abs(fast.astype(np.int16) - exact.astype(np.int16))
    assert 0 < d.mean() <= 0.1
