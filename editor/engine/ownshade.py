"""A smiling photo's own lit cheek top, taken back as its smile is undone (issue 21). No Qt.

A smile bunches the cheeks into a rounded mass whose top, over the cheekbone, turns towards
the light (what :mod:`.cheeks` lightens on a neutral photo's smile). On a smiling photo that
light is in the pixels, and the warp that neutralises the smile moves them but keeps their
light: the neutral and every expression rendered from it kept the smile's raised, lit
cheeks (blind raters on the sample's neutral and anger: "a faint hint of smile", "cheeks a
little raised").

Measured on JAFFE (31 smiling photos of ten women, each neutralised, ``render(0)``, against
the median of the same woman's real neutral photos; mean log luminance on re-detected
landmarks, in the eyes' frame, x from the midline and y below the eye line, IOD): the upper
flanks (x 0.7-0.8, y 0.45-0.6) of the real smiles lie +0.068 over their neutral (median), the
neutralised ones still +0.052; with this layer +0.019 (mean distance to the real neutral 0.076
-> 0.063; HA1 alone: real +0.088, +0.070 -> +0.027).

This layer undoes :mod:`.cheeks`' lightening (a screen, ``px = n + a (255 - n)``, over the
same round ellipse on the photo, carried by the same affine fit of the cheek's anchors) by
:data:`UNDO` times how much more the photo's mouth corner is pulled along the zygomaticus's
line than the rendered mesh's, both beyond the neutral mesh's (:func:`.cheeks.lift`'s
saturating strength). At the photo's own expression the two pulls are equal and nothing is
drawn (the untouched document renders the photo as it is); a neutral photo (no own
expression) has no plan. The undone light is bounded below by the photo's own darkest light
around (an erosion, :data:`REACH`): a lit top is lowered, no dark patch is made.

The smile's darker lower flank beside the nasolabial fold is not undone here: the inverse
of :mod:`.cheeks`' darkening lifted it to -0.041 (from -0.072; real -0.085) but left pale
ovals 20-30 grey levels over the skin's closing beside the sample's folds (its flash lights
the front of the cheek where JAFFE's lower flank is shaded), and kept off the folds' valleys
(which creases.py's unfold lifts) and bounded by the skin's light it changed the flank by
0.006 only. The fold's own valley is creases.py's.

It belongs to the skin-fold layer: ``creases=False`` leaves it out. Per side the undo is a
per-face gain over the lit cheek top's box (within the side's shade box; computed on the
photo's smoothed light, so that the warped skin's grain is not imprinted), carried
(:func:`.chinboss.carried`) and scaled per frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from .cheeks import LIGHT_AT, LIGHT_HALF, CheekPlan, CheekSide, cheek_plan, saturate
from .chinboss import carried
from .layers import _rebox, _union
from .perface import per_face
from .warp import WarpResult

if TYPE_CHECKING:
    from .face import Face

#: the share of :mod:`.cheeks`' full lightening a smiling photo is taken to hold at the same
#: pull (1: that layer's own calibration on JAFFE's real smiles)
UNDO = 1.0
#: the half-side (IOD) of the square whose erosion of the photo's smoothed light bounds the
#: undone light from below (the reach of the own folds' lift in creases.py: 4 x 0.026 x 1.25)
REACH = 0.13
#: below this strength nothing is drawn
_TOL = 2e-3


@dataclass(frozen=True)
class OwnCheeks:
    """The photo's cheek sides with a smile's lit top, and each one's mouth-corner pull."""

    plan: CheekPlan
    sides: tuple[CheekSide, ...]
    zero: tuple[float, ...]  # the corner's place along the pull on the neutral mesh (IOD)
    photo: tuple[float, ...]  # the shade's strength at the photo's own mesh
    #: per side (h, w, 3) float32 over its box: the gain per channel that undoes the whole
    #: light the photo holds, less 1, over that strength (``1 + u gain`` undoes a share
    #: ``u``: exact at the neutral and at the photo)
    gains: tuple[np.ndarray, ...]
    boxes: tuple[tuple[int, int, int, int], ...]  # (x0, y0, x1, y1) of each gain on the photo
    pulls: tuple[tuple[float, float], ...]  # each side's ``pull`` (x, y), Python floats


def _undo_gain(px: np.ndarray, floor: np.ndarray, light: np.ndarray, s: float) -> np.ndarray:
    """The per-channel gain (h, w, 3) that takes share ``s`` of the screen ``light`` (h, w, 1)
    back from the photo's smoothed light ``px``: ``n = (px - 255 a) / (1 - a)``, no lower
    than ``floor`` (the darkest light around) nor than ``px (1 - a)`` (a dark pixel was not
    lit by the bulge)."""
    a = s * light
    n = np.maximum((px - 255.0 * a) / (1.0 - a), px * (1.0 - a))
    n = np.maximum(n, np.minimum(floor, px))
    return n / np.maximum(px, 1.0)


@per_face
def own_cheeks(face: Face) -> OwnCheeks | None:
    """The face's own-cheek plan: None for a photo without an own expression, without the
    cheeks' plan, or whose own corners are not pulled beyond the neutral's."""
    if not face.has_expression:
        return None
    plan = cheek_plan(face)
    if plan is None:
        return None
    P = np.asarray(face.vertices, np.float64)
    N = np.asarray(face.neutral_vertices, np.float64)
    img = face.image
    H, W = img.shape[:2]
    iod = plan.iod
    r = max(math.ceil(REACH * iod), 1)
    # (a square: OpenCV erodes by one in two 1-D passes, ~0.3 ms on a 4K face's box, where a
    # disc of the same reach took ~50 ms a side)
    square = np.ones((2 * r + 1, 2 * r + 1), np.uint8)
    out: dict[str, list] = {k: [] for k in ("sides", "zero", "photo", "gains", "boxes",
                                            "pulls")}
    for side in plan.sides:
        c = side.anchors[1]
        z = float(N[c] @ side.pull) / iod
        s = UNDO * saturate(float(P[c] @ side.pull) / iod - z)
        if s < _TOL:
            continue
        # the lit top's ellipse alone (the plan's box also holds the lower flank's)
        centre = np.array(LIGHT_AT) @ P[side.anchors]
        ext = LIGHT_HALF * iod + 2.0
        x0, y0 = max(math.floor(centre[0] - ext), 0), max(math.floor(centre[1] - ext), 0)
        x1, y1 = min(math.ceil(centre[0] + ext) + 1, W), min(math.ceil(centre[1] + ext) + 1, H)
        bx0, by0, bx1, by1 = side.box
        x0, y0, x1, y1 = max(x0, bx0), max(y0, by0), min(x1, bx1), min(y1, by1)
        if x1 - x0 < 3 or y1 - y0 < 3:
            continue
        light = side.field[y0 - by0:y1 - by0, x0 - bx0:x1 - bx0, 1:]
        X0, Y0, X1, Y1 = max(x0 - r, 0), max(y0 - r, 0), min(x1 + r, W), min(y1 + r, H)
        # (the skin's smoothed light: the gain is applied to the warped skin, whose grain is
        # not the photo's pixel for pixel)
        sm = cv2.GaussianBlur(img[Y0:Y1, X0:X1].astype(np.float32), (0, 0),
                              max(0.04 * iod, 1.0))
        cut = (slice(y0 - Y0, y1 - Y0), slice(x0 - X0, x1 - X0))
        g = _undo_gain(sm[cut], cv2.erode(sm, square)[cut], light, s)
        out["sides"].append(side)
        out["zero"].append(z)
        out["photo"].append(s)
        out["gains"].append(np.ascontiguousarray((g - 1.0) / s, np.float32))
        out["boxes"].append((x0, y0, x1, y1))
        out["pulls"].append((float(side.pull[0]), float(side.pull[1])))
    if not out["sides"]:
        return None
    return OwnCheeks(plan, *(tuple(out[k]) for k in ("sides", "zero", "photo", "gains",
                                                     "boxes", "pulls")))


def undo_share(own: OwnCheeks, k: int, vertices: np.ndarray) -> float:
    """How much of side ``k``'s lit top the deformed mesh ``vertices`` takes back: the
    photo's strength less the mesh's (:data:`UNDO` times the saturating pull), at least 0."""
    corner = np.asarray(vertices[own.sides[k].anchors[1]], np.float64).tolist()
    return _undo(own, k, corner)


def _undo(own: OwnCheeks, k: int, corner: list[float]) -> float:
    """:func:`undo_share` of side ``k`` with its mouth corner at ``corner`` (x, y): the rise
    along the pull in Python floats (two products and a sum: numpy's calls on two values cost
    several times more)."""
    px, py = own.pulls[k]
    rise = (corner[0] * px + corner[1] * py) / own.plan.iod
    return max(own.photo[k] - UNDO * saturate(rise - own.zero[k]), 0.0)


def apply_own_cheeks(face: Face, res: WarpResult, vertices: np.ndarray) -> WarpResult:
    """Take back (in place) the lit cheek top a smiling photo carries into ``res.image`` as
    far as the deformed mesh ``vertices`` lowers its mouth corners (:func:`undo_share`); the
    result's ``bbox`` grown to what was written. Each side's gain is carried by the affine fit
    of its cheek's anchors (photo -> deformed mesh), as :mod:`.cheeks` carries its shade."""
    own = own_cheeks(face)
    if own is None:
        return res
    v = np.asarray(vertices, np.float64)
    out = res.image
    bbox = res.bbox
    for k, side in enumerate(own.sides):
        pts = v.take(side.anchors, 0)  # (take: cheaper rows)
        u = _undo(own, k, pts[1].tolist())
        if u < _TOL:
            continue
        got = carried(own.gains[k], own.boxes[k], (side.solve @ pts).T, out.shape)
        if got is None:
            continue
        g, (X0, Y0, X1, Y1) = got
        g *= np.float32(u)
        g += 1.0
        view = out[Y0:Y1, X0:X1]
        # (the float32 product rounded and saturated into the view: >= 0, as 1 + u gain is)
        cv2.multiply(g, view, view, 1.0, cv2.CV_8U)
        bbox = _union(bbox, (X0, Y0, X1, Y1))
    return res if bbox == res.bbox or bbox is None else _rebox(res, bbox, {})


__all__ = ["UNDO", "OwnCheeks", "apply_own_cheeks", "own_cheeks", "undo_share"]
