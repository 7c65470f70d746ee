"""The smiling cheek's shade: the zygomaticus lifts the cheek into a bulge (AU6/AU12). No Qt.

A felt smile pulls the mouth corners up and out and the cheek's soft tissue bunches above
them into a rounded mass: its lit top faces the light a little more, and its lower flank,
beside the nasolabial fold, turns away from it. A warp moves the cheek's pixels but keeps
their light, so a rendered smile keeps the flat cheek of the neutral photo: the blind raters'
"no cheek raise", "the mouth pasted onto a neutral face" on joy.

Measured on JAFFE (ten women; the median over the women of the log-luminance ratio of each
real smile over the same woman's neutral photo, on re-detected landmarks, in the eyes' frame,
x from the midline and y down from the eye line, IOD): beside the nasolabial fold, at x 0.55
and y 0.6-0.9, real smiles darken by 0.07-0.15 (the renders of joy 0.01-0.09: only the fold's
own line; with this layer 0.04-0.15), at x 0.65, y 0.7-0.8 by 0.05-0.09 (renders 0; now
0.04-0.06); the upper flank at x 0.75, y 0.5-0.6 lightens by 0.07 (renders 0; now 0.05 at
0.5). The flanks' mean (tests/test_cheeks.py): real -0.100, renders -0.046, now -0.087.

This layer darkens an ellipse along the lower flank (beside the fold, elongated along it) and
lightens a smaller one on the upper flank, both carried by the cheek's own motion (an affine
fit of the nose wing, the mouth corner and the cheek's two feature points 5.1/5.3 of that
side). Its strength follows how far the mouth corner was pulled along the zygomaticus's line
(towards the cheekbone, 5.3/5.4) beyond the neutral mesh (and beyond the photo's own mesh: a
smiling photo's cheek shade is in its pixels already, the untouched photo renders as it is),
saturating. It belongs to the skin-fold layer: ``creases=False`` leaves it out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .chinboss import carried, ellipse_bump, shade_tint
from .layers import _rebox, _union
from .perface import per_face
from .warp import WarpResult

if TYPE_CHECKING:
    from .face import Face

#: darkening of the lower flank's core at full lift, and the upper flank's lightening (its
#: share of the way to white: a screen, so that a bright skin does not clip into a blob)
DARKEST, LIGHTEST = 0.20, 0.25
#: the corner's pull towards the cheekbone (IOD, beyond the neutral mesh) at which the shade
#: reaches 63 % of its full strength: joy at 100 % pulls the corners 0.13-0.14 IOD on the
#: JAFFE neutrals, 0.20 at 150 %
RISE = 0.12
#: the lower flank's ellipse: its centre as weights of (nose wing, mouth corner, cheek 5.1,
#: cheekbone 5.3), its half-length along the fold (nose wing -> mouth corner) and half-width
#: across it, IOD
DARK_AT = (0.20, 0.15, 0.25, 0.40)
DARK_HALF = (0.20, 0.10)
#: the upper flank's (round)
LIGHT_AT = (-0.1, 0.0, -0.15, 1.25)
LIGHT_HALF = 0.14
#: below this strength nothing is drawn
_TOL = 2e-3


@dataclass(frozen=True)
class CheekSide:
    """One cheek: its anchors (mesh vertex indices), the mouth corner's rest height and the
    shade's field over a box of the photo."""

    anchors: np.ndarray  # (4,) nose wing, mouth corner, cheek 5.1, cheekbone 5.3
    pull: np.ndarray  # (2,) unit: the zygomaticus's line, mouth corner -> cheekbone (5.3)
    rise0: float  # the corner's place along it on the neutral mesh (IOD)
    solve: np.ndarray  # (3, 4): the affine fit's pseudo-inverse of the photo's anchors
    field: np.ndarray  # (h, w, 2) float32: darkening and lightening at full lift
    box: tuple[int, int, int, int]  # (x0, y0, x1, y1) of ``field`` on the photo


@dataclass(frozen=True)
class CheekPlan:
    sides: tuple[CheekSide, ...]
    iod: float
    tint: np.ndarray  # (3,) float32


@per_face
def cheek_plan(face: Face) -> CheekPlan | None:
    """The face's cheek plan (None when its mesh lacks the cheeks' feature points)."""
    fdp = face.mesh.fdp
    try:
        sides_idx = [np.array([fdp[a], fdp[b], fdp[c], fdp[d]])
                     for a, b, c, d in (("9.1", "8.3", "5.1", "5.3"), ("9.2", "8.4", "5.2", "5.4"))]
    except KeyError:
        return None
    rest = np.asarray(face.vertices, np.float64)
    neutral = np.asarray(face.neutral_vertices, np.float64) if face.has_expression else rest
    iod = float(face.interocular)
    if iod < 4.0:
        return None
    H, W = face.image.shape[:2]
    sides = []
    for idx in sides_idx:
        wing, corner, cheek, bone = rest[idx]
        along = corner - wing
        along /= max(float(np.hypot(*along)), 1e-9)
        dark_c = np.array(DARK_AT) @ rest[idx]
        light_c = np.array(LIGHT_AT) @ rest[idx]
        ext = max(DARK_HALF[0], LIGHT_HALF) * iod + 2.0
        lo = np.minimum(dark_c, light_c) - ext
        hi = np.maximum(dark_c, light_c) + ext
        x0, y0 = max(int(math.floor(lo[0])), 0), max(int(math.floor(lo[1])), 0)
        x1, y1 = min(int(math.ceil(hi[0])) + 1, W), min(int(math.ceil(hi[1])) + 1, H)
        if x1 - x0 < 3 or y1 - y0 < 3:
            continue
        box = (x0, y0, x1, y1)
        across = np.array([-along[1], along[0]])
        field = np.dstack([
            DARKEST * ellipse_bump(box, dark_c, along, across, DARK_HALF[0] * iod,
                                   DARK_HALF[1] * iod),
            LIGHTEST * ellipse_bump(box, light_c, along, across, LIGHT_HALF * iod,
                                    LIGHT_HALF * iod)])
        P = np.hstack([rest[idx], np.ones((4, 1))])
        # the drive's zero: the neutral mesh's corner or the photo's own, whichever is
        # further along the muscle's line
        pull = bone - corner
        pull /= max(float(np.hypot(*pull)), 1e-9)
        rise0 = max(float(neutral[idx[1]] @ pull), float(rest[idx[1]] @ pull)) / iod
        sides.append(CheekSide(anchors=idx, pull=pull, rise0=rise0, solve=np.linalg.pinv(P),
                               field=field.astype(np.float32), box=(x0, y0, x1, y1)))
    if not sides:
        return None
    return CheekPlan(sides=tuple(sides), iod=iod, tint=shade_tint(face.image))


def lift(plan: CheekPlan, side: CheekSide, vertices: np.ndarray) -> float:
    """The shade's strength (0-1) on one cheek of the deformed mesh: how far its mouth corner
    was pulled along the zygomaticus's line (towards the cheekbone) beyond its rest, saturating."""
    return saturate(float(np.asarray(vertices[side.anchors[1]], np.float64) @ side.pull)
                    / plan.iod - side.rise0)


def saturate(rise: float) -> float:
    """The shade's strength (0-1) for a corner pulled ``rise`` (IOD) beyond its rest along the
    muscle's line: ``1 - exp(-rise / RISE)``, 0 for no rise."""
    return 1.0 - math.exp(-rise / RISE) if rise > 0.0 else 0.0


def apply_cheeks(face: Face, res: WarpResult, vertices: np.ndarray) -> WarpResult:
    """Shade the lifted cheeks of ``res.image`` (in place) as far as the deformed mesh
    ``vertices`` pulls the mouth corners towards the cheekbones (:func:`lift`); the result's
    ``bbox`` grown to what was written."""
    plan = cheek_plan(face)
    if plan is None:
        return res
    v = np.asarray(vertices, np.float64)
    out = res.image
    bbox = res.bbox
    for side in plan.sides:
        s = lift(plan, side, v)
        if s < _TOL:
            continue
        got = carried(side.field, side.box, (side.solve @ v[side.anchors]).T, out.shape)
        if got is None:
            continue
        shade, (x0, y0, x1, y1) = got
        shade *= np.float32(s)
        view = out[y0:y1, x0:x1]
        px = view.astype(np.float32)
        px *= 1.0 - shade[..., :1] * plan.tint
        # the lit top towards white as a screen does (a highlight never clips a bright skin)
        px += shade[..., 1:] * (255.0 - px)
        view[:] = np.clip(px + 0.5, 0, 255).astype(np.uint8)
        bbox = _union(bbox, (x0, y0, x1, y1))
    return res if bbox == res.bbox or bbox is None else _rebox(res, bbox, {})


__all__ = ["CheekPlan", "apply_cheeks", "cheek_plan", "lift", "saturate"]
