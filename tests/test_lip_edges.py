"""The mesh's inner-lip contour moved onto the photo's inner lip edges (issue 14, open mouths)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from conftest import jaffe_images

from editor.engine.facemesh import MediaPipeDetector
from editor.engine.imageio import load_image
from editor.engine.lip_edges import (
    INNER_LOWER,
    INNER_UPPER,
    OUTER_LOWER,
    OUTER_UPPER,
    refine_inner_lips,
)

# a synthetic mouth: eyes 100 px apart, lips a grey band between two ellipses around (200, 250)
CX, CY = 200.0, 250.0
MOUTH_A, OUTER_B = 50.0, 24.0  # outer lip contour: half width, half height
OPEN_B = 9.0  # the dark opening's half height (its half width is MOUTH_A - 6)


def _ellipse(a: float, b: float, n: int = 11, upper: bool = True) -> np.ndarray:
    """n points on the upper (or lower) half of an ellipse, image-left corner to right."""
    t = np.linspace(np.pi, 0, n) if upper else np.linspace(np.pi, 2 * np.pi, n)
    return np.c_[CX + a * np.cos(t), CY - b * np.sin(t)]


def _mouth(open_b: float) -> np.ndarray:
    img = np.full((400, 400, 3), 190, np.uint8)
    cv2.ellipse(img, ((CX, CY), (2 * MOUTH_A, 2 * OUTER_B), 0), (110, 110, 110), -1)
    if open_b > 0:
        cv2.ellipse(img, ((CX, CY), (2 * (MOUTH_A - 6), 2 * open_b), 0), (25, 25, 25), -1)
    return img


def _mesh(inner_b: float) -> np.ndarray:
    """A mesh whose eyes, outer lips and inner lips are set (the rest: the face's centre); its
    inner contour an ellipse of half height ``inner_b``."""
    m = np.tile([CX, CY - 60], (468, 1)).astype(np.float32)
    m[[33, 133]] = [(135, 160), (165, 160)]
    m[[362, 263]] = [(235, 160), (265, 160)]
    m[OUTER_UPPER] = _ellipse(MOUTH_A, OUTER_B)
    m[OUTER_LOWER] = _ellipse(MOUTH_A, OUTER_B, upper=False)
    m[INNER_UPPER] = _ellipse(MOUTH_A - 6, inner_b)
    m[INNER_LOWER] = _ellipse(MOUTH_A - 6, inner_b, upper=False)
    return m


def _off_edge(mesh: np.ndarray) -> np.ndarray:
    """Each inner point's distance (px) from the opening's true edge (the ellipse of half axes
    MOUTH_A - 6, OPEN_B), along the vertical; the corners left out."""
    pts = np.vstack([mesh[INNER_UPPER[1:-1]], mesh[INNER_LOWER[1:-1]]]).astype(np.float64)
    a = MOUTH_A - 6
    edge_y = OPEN_B * np.sqrt(np.clip(1 - ((pts[:, 0] - CX) / a) ** 2, 0, 1))
    return np.abs(np.abs(pts[:, 1] - CY) - edge_y)


def test_an_opening_drawn_too_large_moves_onto_the_lips_inner_edge():
    """The mesh's contour 4 px outside a dark opening of 9 px half height (inside the lips):
    every inner point ends within 1 px of the opening's edge, 0.7 px on average (it started
    1.5-4 px off; the smooth correction, a bulge and a tilt, cannot follow exactly), the
    corrections are smooth (a quartic in x through each curve's offsets misses none by 0.1 px:
    no jagged contour) and the curves do not cross; the corners stay."""
    mesh = _mesh(OPEN_B + 4)
    img = _mouth(OPEN_B)
    before = _off_edge(mesh)
    out = refine_inner_lips(img, mesh)
    after = _off_edge(out)
    assert before[[3, 4, 5, 12, 13, 14]].min() > 3.5, before
    assert after.max() < 1.0 and after.mean() < 0.7, after
    np.testing.assert_array_equal(out[[78, 308]], mesh[[78, 308]])
    for idx in (INNER_UPPER, INNER_LOWER):
        x, dy = mesh[idx, 0].astype(np.float64), (out[idx] - mesh[idx])[:, 1].astype(np.float64)
        assert np.abs(np.polyval(np.polyfit(x, dy, 4), x) - dy).max() < 0.1, dy
    assert ((out[INNER_LOWER] - out[INNER_UPPER])[1:-1, 1] > 0).all()
    # everything but the 18 inner-lip points is the mesh's own
    rest = np.setdiff1d(np.arange(468), np.r_[INNER_UPPER[1:-1], INNER_LOWER[1:-1]])
    np.testing.assert_array_equal(out[rest], mesh[rest])


def test_a_contour_inside_the_lip_moves_a_little_inwards_only_when_open():
    """A closed mouth (the mesh's opening under 1.5 px) is left as it is, even over an image
    with a lip line; an opening drawn too small is not blown up past the lips' middle."""
    closed = _mesh(0.5)
    np.testing.assert_array_equal(refine_inner_lips(_mouth(0), closed), closed)
    np.testing.assert_array_equal(refine_inner_lips(_mouth(OPEN_B), closed), closed)
    # no interior contrast at all (a plain grey face): nothing moves
    flat = np.full((400, 400, 3), 120, np.uint8)
    mesh = _mesh(OPEN_B + 4)
    np.testing.assert_array_equal(refine_inner_lips(flat, mesh), mesh)


def _lower_edge_row(lum: np.ndarray, x: float, y_top: float, y_bottom: float) -> float:
    """The strongest luminance step (either sign) down the image column nearest ``x`` between
    the two rows, with a parabolic sub-pixel peak: found without the mesh's normals."""
    col = cv2.GaussianBlur(lum, (0, 0), 1.0)[:, int(round(x))].astype(np.float64)
    g = np.abs(np.gradient(col))
    ys = np.arange(int(np.ceil(y_top)), int(np.floor(y_bottom)) + 1)
    k = ys[np.argmax(g[ys])]
    a, b, c = g[k - 1], g[k], g[k + 1]
    return float(k + 0.5 * (a - c) / (a - 2 * b + c)) if a - 2 * b + c < 0 else float(k)


@pytest.mark.skipif(not jaffe_images("KL.SU1.*"), reason="../shared/data/jaffe is not available")
def test_jaffe_open_mouth_lower_inner_lip_on_the_cavitys_edge():
    """KL.SU1 (surprise, a wide dark cavity): the model puts the lower inner-lip middle (mesh
    14) on the lower lip's body, 2.5 px below the cavity's lower edge; refined, it lies within
    1 px of that edge (the strongest step down the middle column between the opening's centre
    and the lower lip's outer edge). The upper middle (13) stays within 1.5 px of the upper
    edge found the same way from the upper lip's middle down (the skin-to-lip step above it
    is stronger)."""
    rgb = load_image(jaffe_images("KL.SU1.*")[0])
    raw = MediaPipeDetector(refine_lips=False).run(rgb).mesh.astype(np.float64)
    new = MediaPipeDetector().run(rgb).mesh.astype(np.float64)
    lum = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY).astype(np.float32)
    centre = (raw[13] + raw[14]) / 2
    lower = _lower_edge_row(lum, centre[0], centre[1] + 2, raw[17, 1] - 2)
    upper = _lower_edge_row(lum, centre[0], (raw[0, 1] + raw[13, 1]) / 2, centre[1] - 2)
    assert abs(raw[14, 1] - lower) > 2.0, (raw[14], lower)
    assert abs(new[14, 1] - lower) < 1.0, (new[14], lower)
    assert abs(new[13, 1] - upper) < 1.5, (new[13], upper)


def test_an_upscaled_photos_opening_moves_as_its_small_ones():
    """The search is laid out in inter-ocular distances; its step threshold follows the
    smoothing's width. A smile's teeth (60 grey levels over the lips) seen on the synthetic
    mouth and on the same picture upscaled 7 x (cubic, as the 4K bench face is made from the
    sample): the contour moves onto the same edge at both sizes. Before, the upscaled one's
    edge (under 4 grey levels per pixel after the 8.4 px smoothing) was not taken: its contour
    stayed 4 px (small-scale) outside the opening, where the 4K bench face's upper lip was
    0.064 IOD thick against 0.10 at 512 and 1080 px."""
    img = _mouth(0)  # (lips 110, teeth 170)
    cv2.ellipse(img, ((CX, CY), (2 * (MOUTH_A - 6), 2 * OPEN_B), 0), (170, 170, 170), -1)
    mesh = _mesh(OPEN_B + 4)
    small = refine_inner_lips(img, mesh)
    K = 7
    big_img = cv2.resize(img, None, fx=K, fy=K, interpolation=cv2.INTER_CUBIC)
    big = refine_inner_lips(big_img,
                            ((mesh.astype(np.float64) + 0.5) * K - 0.5).astype(np.float32))
    back = (big.astype(np.float64) + 0.5) / K - 0.5
    assert _off_edge(small).mean() < 0.7, _off_edge(small)
    assert _off_edge(back).mean() < 0.7, _off_edge(back)
    assert np.abs(back - small).max() < 0.5
