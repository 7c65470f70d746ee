"""The upper lip's shadow lifted off the lower lip when the lips part (issue 21). No Qt.

Where closed lips meet, the upper lip overhangs the lower one and shades its top: the dark
line of a closed mouth (JAFFE's neutral photos: 0.27 of the lips' light at its darkest, see
:data:`~editor.engine.lipseal.LINE_DEPTH`). A warp that parts the lips carries the lower half
of that line down with the lower lip: a dark rim along the lower lip's inner edge, under the
teeth, that real open mouths do not have (the lower lip's top, out of the upper lip's shadow,
is as light as the lip's body). Measured on JAFFE (the darkest of the first quarter of the
lower lip from its inner edge, over the lip's middle, at the mouth's middle; re-detected
landmarks; photos with the lips more than 0.05 IOD apart): real smiles 0.98, real fear 0.95,
real surprise 0.92; the presets drawn on the women's neutral photos 0.69, 0.94, 0.80 (the
blind raters' "dark, heavy lips"), with this layer 0.88, 0.95, 0.87 (0.88, 0.97, 0.90 with
the closing on the raw light, see below). The upper lip's own inner rim stays dark: its
underside faces away from the light (real 0.47-0.66 of its body).

* **Once per face** (:func:`rim_plan`): on a photo whose lips are closed, the valley of the
  lips' luminance across their meeting line, found by a closing with a vertical segment
  :data:`CLOSE_IOD` tall (the line's dip is 0.07-0.10 IOD wide at half depth) on the lips'
  light without their specular specks (an opening :data:`SPECK_IOD` across), and its gain
  over the photo where it lies on the lower lip: from the meeting line down
  :data:`REACH_IOD`, fading over as much again, inside the outer lip contour and away from
  the corners (the commissures stay in shadow). The gain is that of the shadow's smooth
  profile (the lip's texture is kept), capped so that no pixel ends lighter than the
  closing or than it was: with the closing on the raw light, a glossy lip's highlight
  lifted the dark pixels of its column up to its own light, bright vertical bars down the
  parted lower lip (JAFFE's KA, KL, YM: up to 13 x their light on the photos upscaled 4 x;
  tests/test_liprims.py). Kept: the photo times that gain minus the photo, over the
  mouth's box.
* **Per frame** (:func:`apply_lip_rims`): the share ``o`` by which the lips part (their mean
  gap along the inner lips beyond the photo's, over :data:`OPEN_FULL` IOD, clipped to
  [0, 1]); the difference is carried by the warp's backward map with the lower lip and added
  times ``o`` (an untouched or closed mouth: nothing).

A photo with its lips apart has no plan (its lower lip's top is already out of the shadow).
Runs after the lip seal and the lip tone, before the mouth layer (which reads the lips'
colour at the opening's edge).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from .fitting import luminance, smooth01
from .gaze import spread3, zero_alpha
from .layers import _rebox, _union
from .lipseal import add_carried, lip_curves, lower_outer_curve
from .perface import per_face
from .warp import WarpResult

if TYPE_CHECKING:
    from .face import Face

#: a photo's lips count as closed when their mean gap along the inner lips is under this
#: share of the inter-ocular distance
CLOSED_IOD = 0.02
#: height of the closing across the meeting line (IOD): taller than the line's dip (0.07-0.10
#: IOD wide at half depth on JAFFE's neutral photos), shorter than a lip (0.12-0.18)
CLOSE_IOD = 0.14
#: how far below the meeting line the shadow is lifted in full (IOD), then fading over as much.
#: The lower lip's rim index of the module docstring, joy / fear / surprise on the ten JAFFE
#: women: 0.86 / 0.97 / 0.96 at 0.05 (real 0.98 / 0.95 / 0.92; 0.86 / 1.00 / 0.95 with the
#: corners' fade at 0.3); 0.87 / 0.89 / 0.97 at 0.035;
#: with a closing 0.18 tall 0.96 / 1.12 / 1.09 (lighter than the lip's body: a pale stripe)
REACH_IOD = 0.05
#: the lips' mean gap (IOD) beyond the photo's at which the shadow is lifted in full
OPEN_FULL = 0.03
#: share of the mouth's width at each corner over which the lift fades in: a parted mouth's
#: corners stay in the cheeks' shadow (real JAFFE fear: the opening's outer columns 0.37 of its
#: middle's light), and the mouth layer shades the cavity from the lips' colour beside it: at
#: 0.15 the lifted lip lightened fear's corners on KA to 0.52 of the middle (0.49 without the
#: layer), at 0.3 0.49; the rim index of REACH_IOD unchanged (joy 0.86, fear 1.00, surprise 0.95)
CORNER_FADE = 0.3
#: the specular specks of a glossy lip (IOD across) left out of the lips' light before the
#: closing looks for the lip's body above and below the shadow
SPECK_IOD = 0.05
#: Gaussian sigma (IOD) of the shadow's profile whose gain is lifted
SHADE_SIGMA_IOD = 0.012
#: below this share nothing is drawn
_MIN_SHARE = 0.02


@dataclass(eq=False)
class RimPlan:
    """What :func:`apply_lip_rims` needs of one face (see the module docstring)."""

    diff: np.ndarray  # (h, w, 4) float32: the lifted photo minus the photo (4th channel 0)
    org: tuple[int, int]  # the box's top-left corner on the photo
    upper: np.ndarray  # (n,) vertex indices of the upper inner lip, corner to corner
    lower: np.ndarray  # (n,) the lower inner lip, the same corners
    lower_outer: np.ndarray  # vertex indices of the outer lower lip (the frame's box)
    gap0: float  # the photo's mean inner-lip gap, px
    iod: float


def _mean_gap(v: np.ndarray, upper: np.ndarray, lower: np.ndarray) -> float:
    """Mean distance between facing inner-lip points (corners left out), px."""
    d = v[lower[1:-1]] - v[upper[1:-1]]
    return float(np.hypot(d[:, 0], d[:, 1]).mean())


@per_face
def rim_plan(face: Face) -> RimPlan | None:
    """The face's :class:`RimPlan` (cached for its lifetime; None: its lips are apart, or
    there is no shadow between them to lift)."""
    m = face.mesh
    iod = float(face.interocular)
    V = face.vertices.astype(np.float64)
    upper, lower, outer = lip_curves(m)
    lower_outer = lower_outer_curve(m)
    gap0 = _mean_gap(V, upper, lower)
    if gap0 > CLOSED_IOD * iod:
        return None
    img = face.image
    H, W = img.shape[:2]
    pad = int(math.ceil(CLOSE_IOD * iod)) + 2
    lo, hi = V[outer].min(0) - pad, V[outer].max(0) + pad
    x0, y0 = max(int(math.floor(lo[0])), 0), max(int(math.floor(lo[1])), 0)
    x1, y1 = min(int(math.ceil(hi[0])) + 1, W), min(int(math.ceil(hi[1])) + 1, H)
    if x1 - x0 < 6 or y1 - y0 < 6:
        return None
    patch = img[y0:y1, x0:x1]
    L = cv2.GaussianBlur(luminance(patch).astype(np.float32), (0, 0), 0.7)
    k = max(int(round(CLOSE_IOD * iod)) | 1, 3)
    # the lips' light without their specular specks (an opening by a disc SPECK_IOD across:
    # a glossy lip's highlights are bright dots as small as that), so that the closing finds
    # the lip's body, not a highlight a few pixels away in the same column
    r = max(int(round(0.5 * SPECK_IOD * iod)), 1)
    body = cv2.morphologyEx(L, cv2.MORPH_OPEN, cv2.getStructuringElement(
        cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1)))
    closed = cv2.morphologyEx(body, cv2.MORPH_CLOSE, np.ones((k, 1), np.uint8))
    # the shadow's gain on the smooth profile (the photo's texture is kept, not flattened to
    # the closing), and never above the lip's body: a pixel ends at most as light as the
    # closing, or as it was
    shade = cv2.GaussianBlur(body, (0, 0), max(SHADE_SIGMA_IOD * iod, 0.7))
    gain = np.minimum(closed / np.maximum(shade, 1.0),
                      np.maximum(closed / np.maximum(L, 1.0), np.float32(1.0))) - np.float32(1.0)
    np.maximum(gain, 0.0, out=gain)
    # where: below the meeting line (the midline of the inner lips, as y of x), inside the
    # outer lip contour, fading in from the corners
    mid = 0.5 * (V[upper] + V[lower]) - (x0, y0)
    order = np.argsort(mid[:, 0])
    xs = np.arange(x1 - x0, dtype=np.float64)
    y_line = np.interp(xs, mid[order, 0], mid[order, 1])
    below = (np.arange(y1 - y0, dtype=np.float64)[:, None] - y_line[None, :]) / iod
    # (feathered over 0.02 IOD above the line: the photo's line is a pixel or two wide)
    w = smooth01(np.clip(below / 0.02 + 1.0, 0.0, 1.0))
    w *= 1.0 - smooth01(np.clip((below - REACH_IOD) / REACH_IOD, 0.0, 1.0))
    c0, c1 = float(mid[:, 0].min()), float(mid[:, 0].max())
    fade = max(CORNER_FADE * (c1 - c0), 1.0)
    w *= smooth01(np.clip(np.minimum(xs - c0, c1 - xs) / fade, 0.0, 1.0))[None, :]
    lips = np.zeros((y1 - y0, x1 - x0), np.uint8)
    cv2.fillPoly(lips, [np.round((V[outer] - (x0, y0)) * 16).astype(np.int32)], 1, cv2.LINE_AA, 4)
    w *= cv2.GaussianBlur(lips.astype(np.float32), (0, 0), 0.7)
    lift = (w * gain).astype(np.float32)
    if float(lift.max()) < 0.02:
        return None
    diff = zero_alpha(patch.astype(np.float32) * spread3(lift))
    return RimPlan(diff, (x0, y0), upper, lower, lower_outer, gap0, iod)


def open_share(plan: RimPlan, vertices: np.ndarray) -> float:
    """How far (0-1) the lips of ``vertices`` are apart beyond the photo's, of OPEN_FULL."""
    g = _mean_gap(np.asarray(vertices, np.float64), plan.upper, plan.lower)
    o = min(max((g - plan.gap0) / (OPEN_FULL * plan.iod), 0.0), 1.0)
    return max(o - _MIN_SHARE, 0.0) / (1.0 - _MIN_SHARE)


def apply_lip_rims(face: Face, res: WarpResult, vertices: np.ndarray) -> WarpResult:
    """Lift the upper lip's shadow off the lower lip of ``res.image`` (in place) by the share
    the deformed mesh ``vertices`` parts the lips; the result's ``bbox`` grown to what was
    written."""
    plan = rim_plan(face)
    if plan is None or res.maps is None:
        return res
    o = open_share(plan, vertices)
    if o <= 0.0:
        return res
    out = res.image
    H, W = out.shape[:2]
    h, w = plan.diff.shape[:2]
    ox, oy = plan.org
    # the frame's pixels whose photo position may fall in the box: the box where the photo
    # has it and where the lower lip went, with a margin
    q = np.asarray(vertices, np.float64)[plan.lower_outer]
    pad = int(math.ceil(REACH_IOD * plan.iod)) + 2
    x0 = max(int(min(ox, float(q[:, 0].min()) - pad)), 0)
    y0 = max(int(min(oy, float(q[:, 1].min()) - pad)), 0)
    x1 = min(int(max(ox + w, float(q[:, 0].max()) + pad)) + 1, W)
    y1 = min(int(max(oy + h, float(q[:, 1].max()) + pad)) + 1, H)
    if x1 - x0 < 2 or y1 - y0 < 2:
        return res
    add_carried(out, res.maps, (x0, y0, x1, y1), plan.diff, (ox, oy), o)
    bbox = _union(res.bbox, (x0, y0, x1, y1))
    return res if bbox == res.bbox or bbox is None else _rebox(res, bbox, {})


__all__ = ["RimPlan", "apply_lip_rims", "open_share", "rim_plan"]
