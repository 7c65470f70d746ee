"""Disgust that reads as disgust (issue 21): its upper lip and the furrow beside the nose wing
as JAFFE's real disgust photos show them.

Blind raters named our disgust at 100 % anger or sadness ("lips pressed and pushed out", "the
lower lip pushed up into a pout"): its upper lip's sides were curled up into two humps beside
a resting middle (a heart-shaped pout) which no real disgust photo shows, kept only because
the furrow beside the nose wing was drawn from that curl.
"""

from __future__ import annotations

import cv2
import numpy as np
from conftest import jaffe_changes

from editor.engine.creases import _MIN_STRENGTH, fold_lines
from editor.engine.landmarks import detect_landmarks
from editor.formats.presets import apply_preset

#: the columns (IOD from the mouth's middle) where the upper lip's sides are compared with it
_SIDE = 0.12


def _upper_lip_top(img: np.ndarray) -> float | None:
    """How much higher the top edge of the upper lip's red lies at its sides (+-``_SIDE`` IOD
    from the middle, mean of both) than at its middle, IOD (> 0: sides higher; its own
    landmarks, so the head's pose does not count). The edge is the strongest darkening going
    down, per column, between the nose base and the lips' line (grey level, blurred by 0.01
    IOD), the photo resampled at 200 px per IOD in the eyes' frame."""
    g = img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    p = detect_landmarks(img if img.ndim == 3 else cv2.cvtColor(img, cv2.COLOR_GRAY2RGB)
                         ).points.astype(np.float64)
    a, b = p[36:42].mean(0), p[42:48].mean(0)
    c, ex = 0.5 * (a + b), b - a
    iod = float(np.linalg.norm(ex))
    ex /= iod
    ey = np.array([-ex[1], ex[0]])

    def rel(q: np.ndarray) -> np.ndarray:
        return ((q - c) @ np.c_[ex, ey]) / iod

    nose, line = rel(p[33])[1] + 0.08, rel(p[[62, 66]]).mean(0)[1] - 0.02
    mid = rel(p[[51, 57]]).mean(0)[0]
    if line - nose < 0.05:
        return None
    s = 200.0
    X, Y = np.meshgrid(np.arange(mid - 0.2, mid + 0.2, 1 / s), np.arange(nose, line, 1 / s))
    mx = (c[0] + (X * ex[0] + Y * ey[0]) * iod).astype(np.float32)
    my = (c[1] + (X * ex[1] + Y * ey[1]) * iod).astype(np.float32)
    r = cv2.GaussianBlur(cv2.remap(g.astype(np.float32), mx, my, cv2.INTER_LINEAR), (0, 0), 2.0)
    d = np.diff(r, axis=0)  # < 0 where it darkens going down
    col = lambda x: int(round((x - (mid - 0.2)) * s))  # noqa: E731
    top = {x: float(np.argmin(d[:, col(mid + x)])) / s for x in (-_SIDE, 0.0, _SIDE)}
    return top[0.0] - 0.5 * (top[-_SIDE] + top[_SIDE])


def test_jaffe_disgust_raises_the_upper_lip_without_a_heart_shape():
    """JAFFE's real disgust keeps the upper lip's top edge level: its sides (0.12 IOD out) rise
    by -0.003 IOD over its middle against each woman's neutral photo (median of 29; p10..p90
    -0.058..0.021). The renders curled the sides up 0.025 over the middle at 100 % and 0.029
    at 150 %, beyond the real p90, with 55/56 at -200 and 51 at rest: a heart-shaped pout. Now
    inside the real p90 at both (measured 0.016 and 0.016)."""
    real, ours, strong = jaffe_changes(_upper_lip_top, "DI", "disgust")
    assert abs(np.median(real)) <= 0.01, np.median(real)  # (the measure itself)
    p90 = np.percentile(real, 90)
    assert np.median(ours) <= p90, (np.median(ours), p90, ours)
    assert np.median(strong) <= p90, (np.median(strong), p90, strong)


def test_nose_wing_furrow_from_the_raised_cheek_not_the_lip(sample_neutral):
    """The furrow beside the nose wing (the upper_lip fold) follows the cheek pushed up against
    the nose wing (AU9 / AU6: disgust, joy), not the upper lip's rise: anger's mouth rises with
    the chin and squeezes that skin as much as disgust's lip raise, yet real anger photos
    hardly deepen the furrow (0.108 over the image median against 0.086 neutral, disgust
    0.172). Before, it was drawn from the lip's rise: anger drew it, and disgust only with the
    lip's sides curled into a pout. On the sample (strength at its deepest sample): disgust
    0.205, anger 0.182, the cheek lift alone 0.000, the upper lip raised alone 0.209; now
    0.189, 0.015, 0.201, 0.037."""
    f = sample_neutral

    def upper(vec: np.ndarray) -> float:
        return max(float(s.max()) for k, _p, s in fold_lines(f, f.deform(vec))
                   if k == "upper_lip")

    disgust = upper(apply_preset("disgust"))
    assert disgust > 2 * _MIN_STRENGTH
    assert upper(apply_preset("anger")) < 0.25 * disgust
    # the cheek lift alone draws it; the upper lip raised alone (outer contour 200 MNS) hardly
    cheek = np.zeros(68, np.float32)
    cheek[[40, 41]] = 100  # lift_l_cheek / lift_r_cheek (FAPs 41, 42)
    lip = np.zeros(68, np.float32)
    lip[[50, 54, 55]] = -200  # lower_t_midlip_o, lower_t_lip_lm_o / rm_o (FAPs 51, 55, 56)
    assert upper(cheek) > 0.75 * disgust
    assert upper(lip) < 0.25 * upper(cheek)
