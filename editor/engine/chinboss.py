"""The chin boss bunched by the chin raiser (AU17): its shade. No Qt.

When the mentalis contracts (anger's pressed lips, sadness's pout, disgust), it pushes the
chin boss up against the lower lip: the soft tissue bunches into a rounded bulge whose lower
part turns away from the light, and its skin puckers into small pits ("peau d'orange").
A warp moves the chin's pixels but keeps their light, so the rendered chin stays as smooth
and as bright as on the neutral photo.

Measured on JAFFE (ten women; the lip-to-chin band 0.15-0.75 of the way from the outer
lower lip's middle to the chin, 0.2 IOD wide, over the cheeks' light under the eyes, on
re-detected landmarks; tests/test_chinboss.py): the neutral photos 0.74 (median), the anger
photos 0.56, sadness 0.67, disgust 0.73. The renders kept the neutral light (0.74, 0.76,
0.75), and anger's lower lip, pushed up over the still chin, stretched a pale band under it;
with this layer 0.59, 0.65 and 0.72. The real shade covers the whole boss: 0.16-0.28 IOD
either side of the middle the anger photos fall to 0.57 (neutral 0.70); a narrow, peaked
ellipse (1.05 x half the mouth, ``(1 - r^2)^2``) drew 0.65 there, a dark spot under the
lip's middle; this broader, flatter one 0.62 (flat ``1 - r^2`` at 1.35 x: 0.58, but its
tails shaded pixels outside the face's outline, sadness's 0.10 IOD out: tests/test_tears.py).

This layer darkens an ellipse over the chin boss (wider than the mouth, from the lower lip
to the chin, strongest a little above the middle), carried by the chin's own motion (an
affine fit of the lower lip, the chin and the mouth corners). The real chins' pits are not
drawn: a band-pass pattern of them read as stubble on colour photos and on soft ones.
Its strength follows how far the chin boss (2.10) rose over the chin (2.1) beyond the
neutral mesh (and the photo's own), saturating, and fades out as the lips part (an open mouth is no
pout). It belongs to the skin-fold layer: ``creases=False`` leaves it out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from .fitting import is_grey, smooth01_float
from .layers import _rebox, _union
from .perface import per_face
from .warp import WarpResult

if TYPE_CHECKING:
    from .face import Face

#: darkening of the bulge's core at full bunching
DARKEST = 0.40
#: boss rise (IOD beyond the photo's) at which the darkening reaches 63 % of DARKEST;
#: anger at 100 % raises the boss 0.042-0.054 IOD on the JAFFE neutrals, sadness 0.027-0.034,
#: disgust 0.027-0.036
RISE = 0.06
#: parting of the inner lips (IOD beyond the photo's) at which the bunching is gone
OPEN = 0.04
#: the ellipse: half-width over half the mouth's width, half-height over the lip-to-chin
#: distance, and its centre's place from the lower lip (0) to the chin (1)
HALF_W, HALF_H, CENTRE = 1.1, 0.58, 0.38
#: the bump's profile, ``(1 - r^2)^(2 * SHAPE)``: flatter than ``(1 - r^2)^2`` (the real
#: shade is even over the boss; see the module's notes), its tails still inside the outline
SHAPE = 0.75
#: the shade's share on red, green and blue: skin in shadow is warmer than the same skin lit
#: (less red is lost than green and blue); a grey photo gets an even shade
TINT = (0.8, 1.0, 1.1)
#: below this strength nothing is drawn
_TOL = 2e-3


@dataclass(frozen=True)
class ChinPlan:
    """Per face: the anchors (mesh vertex indices) and the texture field on the photo."""

    anchors: np.ndarray  # (4,) lower lip middle, chin, mouth corners
    boss: tuple[int, int]  # chin boss (2.10), chin (2.1)
    lips: tuple[int, int]  # inner lip middles (2.2, 2.3)
    iod: float
    boss_gap0: float  # boss-to-chin distance at rest, IOD (see chin_plan)
    lips_gap0: float  # inner lips' distance on the neutral mesh, IOD
    solve: np.ndarray  # (3, 4): the affine fit's pseudo-inverse of the photo's anchors
    field: np.ndarray  # (h, w) float32 darkening (0..1) over ``box``
    tint: np.ndarray  # (3,) float32 share of the shade per channel
    box: tuple[int, int, int, int]  # (x0, y0, x1, y1) of ``field`` on the photo


def _gap(v: np.ndarray, pair: tuple[int, int]) -> float:
    a, b = v[pair[0]], v[pair[1]]
    return math.hypot(float(b[0] - a[0]), float(b[1] - a[1]))


@per_face
def chin_plan(face: Face) -> ChinPlan | None:
    """The face's chin plan (None when its mesh lacks the chin's feature points)."""
    fdp = face.mesh.fdp
    try:
        anchors = np.array([fdp[k] for k in ("8.2", "2.1", "8.3", "8.4")])
        boss = (fdp["2.10"], fdp["2.1"])
        lips = (fdp["2.2"], fdp["2.3"])
    except KeyError:
        return None
    rest = np.asarray(face.vertices, np.float64)
    iod = float(face.interocular)
    lip, chin, c0, c1 = rest[anchors]
    down = chin - lip
    length = float(np.hypot(*down))
    if length < 2.0 or iod < 4.0:
        return None
    down /= length
    across = np.array([-down[1], down[0]])
    ax = HALF_W * 0.5 * float(np.hypot(*(c1 - c0)))
    ay = HALF_H * length
    centre = lip + CENTRE * length * down
    # the ellipse's box on the photo (it never needs more: the fit carries it)
    ext = np.abs(np.outer([ax, ay], [1.0, 1.0]) * np.stack([across, down])).sum(0)
    H, W = face.image.shape[:2]
    x0, y0 = (int(math.floor(c)) for c in centre - ext - 1)
    x1, y1 = (int(math.ceil(c)) + 1 for c in centre + ext + 1)
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, W), min(y1, H)
    if x1 - x0 < 3 or y1 - y0 < 3:
        return None
    field = ellipse_bump((x0, y0, x1, y1), centre, across, down, ax, ay) ** SHAPE
    P = np.hstack([rest[anchors], np.ones((4, 1))])
    # the drive's zero: the neutral mesh (the photo's own expression removed), or the photo's
    # own mesh where its chin boss is higher (a photo's own bunching is in its pixels already;
    # the untouched photo renders as it is)
    neutral = np.asarray(face.neutral_vertices, np.float64) if face.has_expression else rest
    return ChinPlan(anchors=anchors, boss=boss, lips=lips, iod=iod,
                    boss_gap0=max(_gap(rest, boss), _gap(neutral, boss)) / iod,
                    lips_gap0=_gap(neutral, lips) / iod,
                    solve=np.linalg.pinv(P), field=field.astype(np.float32),
                    tint=shade_tint(face.image),
                    box=(x0, y0, x1, y1))


def bunching(plan: ChinPlan, vertices: np.ndarray) -> float:
    """How much the chin is bunched on the deformed mesh (0 = not at all, DARKEST at most):
    the chin boss's rise over the chin, saturating, gated by the lips staying together."""
    v = np.asarray(vertices, np.float64)
    rise = _gap(v, plan.boss) / plan.iod - plan.boss_gap0
    if rise <= 0.0:
        return 0.0
    closed = 1.0 - smooth01_float((_gap(v, plan.lips) / plan.iod - plan.lips_gap0) / OPEN)
    return DARKEST * (1.0 - math.exp(-rise / RISE)) * closed


def ellipse_bump(box: tuple[int, int, int, int], centre: np.ndarray, e1: np.ndarray,
                 e2: np.ndarray, h1: float, h2: float) -> np.ndarray:
    """(y1 - y0, x1 - x0) float64 over ``box`` (x0, y0, x1, y1): the smooth bump
    ``(1 - r^2)^2`` of the ellipse about ``centre`` with half-axes ``h1`` along the unit
    ``e1`` and ``h2`` along ``e2`` (0 outside it)."""
    x0, y0, x1, y1 = box
    dx = np.arange(x0, x1, dtype=np.float64)[None, :] - centre[0]
    dy = np.arange(y0, y1, dtype=np.float64)[:, None] - centre[1]
    u = (dx * e1[0] + dy * e1[1]) / h1
    w = (dx * e2[0] + dy * e2[1]) / h2
    r2 = u * u + w * w
    return np.where(r2 < 1.0, (1.0 - r2) ** 2, 0.0)


def shade_tint(image: np.ndarray) -> np.ndarray:
    """(3,) float32: a shade's share on red, green and blue (:data:`TINT`; even on a grey
    photo)."""
    return np.array((1.0, 1.0, 1.0) if is_grey(image) else TINT, np.float32)


def carried(field: np.ndarray, box: tuple[int, int, int, int], A: np.ndarray,
            shape: tuple[int, ...]) -> tuple[np.ndarray, tuple[int, int, int, int]] | None:
    """A per-face ``field`` (h, w[, c]) float32 laid over ``box`` (x0, y0, x1, y1) of the
    photo, carried into a frame of ``shape`` by the affine map ``A`` (2, 3; photo ->
    deformed): the field resampled over the destination box of the box's corners (clipped
    to the frame), and that box; None when it is under 2 px wide or tall. (The shade layers
    that ride on a fit of a few mesh points: the chin boss here, the cheeks.)"""
    bx0, by0, bx1, by1 = box
    # (the box's corners through A in Python floats: numpy's calls on a 4 x 3 array cost
    # several times more every frame)
    (a, b, c), (d, e, f) = np.asarray(A, np.float64).tolist()
    pts = ((bx0, by0), (bx1, by0), (bx0, by1), (bx1, by1))
    xs = [x * a + y * b + c for x, y in pts]
    ys = [x * d + y * e + f for x, y in pts]
    H, W = shape[:2]
    x0, y0 = max(math.floor(min(xs)), 0), max(math.floor(min(ys)), 0)
    x1, y1 = min(math.ceil(max(xs)) + 1, W), min(math.ceil(max(ys)) + 1, H)
    if x1 - x0 < 2 or y1 - y0 < 2:
        return None
    # field pixel (i, j) sits at photo (bx0 + j, by0 + i); destination box pixel at (x0, y0)
    # (the linear part's product by the box's corner as numpy computes it; the sums on
    # Python floats: the same float64 values)
    M = np.array(A, np.float64)
    px, py = (M[:, :2] @ np.array([bx0, by0], np.float64)).tolist()
    M[0, 2] = px + c - x0
    M[1, 2] = py + f - y0
    got = cv2.warpAffine(field, M, (x1 - x0, y1 - y0), flags=cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    return np.asarray(got, np.float32), (x0, y0, x1, y1)


def apply_chin_boss(face: Face, res: WarpResult, vertices: np.ndarray) -> WarpResult:
    """Darken and pit the chin boss of ``res.image`` (in place) as far as the deformed mesh
    ``vertices`` bunches it (:func:`bunching`); the result's ``bbox`` grown to what was
    written."""
    plan = chin_plan(face)
    if plan is None:
        return res
    v = np.asarray(vertices, np.float64)
    s = bunching(plan, v)
    if s < _TOL:
        return res
    # photo -> deformed: the affine least-squares fit of the four anchors
    got = carried(plan.field, plan.box, (plan.solve @ v[plan.anchors]).T, res.image.shape)
    if got is None:
        return res
    dark, (x0, y0, x1, y1) = got
    out = res.image
    gain = 1.0 - (np.float32(s) * dark)[..., None] * plan.tint
    view = out[y0:y1, x0:x1]
    view[:] = np.clip(view.astype(np.float32) * gain + 0.5, 0, 255).astype(np.uint8)
    bbox = _union(res.bbox, (x0, y0, x1, y1))
    return res if bbox == res.bbox else _rebox(res, bbox, {})
