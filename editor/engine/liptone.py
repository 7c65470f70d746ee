"""A stretched upper lip pales and the lower lip's shadow recedes, a narrowed mouth's lower
lip casts one again (issue 21). No Qt.

A smile stretches the upper lip across the teeth: thinner and taut, its vermilion turns
paler. JAFFE's ten women, median luminance of the upper lip's core (landmark polygon eroded
2 px) relative to the forehead, real smile photos against each woman's neutral: paler on all
ten, x 1.06-1.74 (median 1.22), i.e. about 0.1 of the way from the lip's tone to the skin's.
A warp only moves the lip, so the rendered smiles kept (or darkened: 0.84-1.08) the neutral
lip's dark tone, the "dark lips pasted on" of the blind raters. Fear, disgust and sadness,
whose mouths widen little, leave the upper lip's tone as it is (0.99-1.01).

* **Once per face** (:func:`tone_plan`): the upper lip's colour (per-channel median of its
  vermilion on the photo, the mesh's outer and inner upper-lip loops, eroded) and the skin's
  above it (a band 0.03-0.10 IOD above the outer upper lip), and the mouth's width (outer
  corners) on the neutral mesh and on the photo's.
* **Per frame** (:func:`apply_lip_tone`): the strain ``e`` of the mouth's width beyond the
  photo's own, over the neutral width (a smile's 0.25; fear's, disgust's and sadness's
  0.04-0.07 stay under the threshold ``E0``); the upper lip's pixels (its loop on the deformed mesh,
  anti-aliased, feathered over a pixel and fading towards the corners, which stay in their
  shadow) are moved ``a = clip(K (e - E0), 0, A_MAX)`` of the way towards the skin's colour by a
  pixel's own distance to the skin's colour (``p + a max(skin - p, 0)``: the lip's texture
  keeps 1 - a of its contrast; a pixel as light as the skin or lighter, a highlight or the
  skin the loop's edge takes, stays).

The lower lip, stretched flat over the teeth, no longer overhangs the chin: its shadow on the
skin below recedes. The same ten women, the skin below the lower lip's middle over the
forehead at 0.04-0.10 IOD: 0.63-0.76 on their neutral photos, 0.72-0.84 in their smiles, and
the warp carried the neutral lip's shadow along (0.63-0.76). Once per face that shadow is
measured (:func:`_shadow_lift`: each pixel's gain to the skin's lit level further down, in a
band below the lip's middle); per frame it is carried by the warp's backward map and lifted
by a share that follows the paling's (at most :data:`SHADOW_MAX`), or the lip's pull towards
the chin (:func:`pull_share`: fear's lower lip drawn down and flat; real fear photos 0.83-0.87
there, the renders 0.69-0.83 before, 0.78-0.83 now), whichever is larger.

The other way, a mouth narrower than the photo's (a smiling photo neutralised, a pout) lets
the lower lip protrude again: a soft shadow under its middle, in full (CAST_DEPTH) from a
narrowing of CAST_FULL (:func:`_cast_shadow`; a smiling photo has no shadow there to carry, and
its neutralised closed lips read as a flat smear without it). The upper lip's tone is not
deepened by the inverse of the paling: tried on JAFFE's toothy smiles, their closed lips turned
heavier and darker, with nothing real to calibrate it against.

Nothing changes where the mouth is neither wider nor narrower than the photo's by more than E0
of the neutral width (the untouched photo; on a neutral photo sadness, fear, disgust, anger and
surprise), on a lip no darker than its skin, or on a mouth too small to measure.
Runs after the lip seal, before the mouth layer (whose inner-lip shading reads the lips).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import cv2
import numpy as np

from .creases import SHADOW_TINT
from .fitting import channel_median, clamp, clip, interp, is_grey, smooth01
from .gaze import spread3
from .layers import _rebox, _union
from .lipseal import _reached, _support, reach_step
from .perface import per_face
from .warp import WarpResult, box_maps

if TYPE_CHECKING:
    from .face import Face

#: how far towards the skin the upper lip goes per unit of width strain beyond E0. JAFFE's
#: ten women: joy at 100 % widens the mouth by 0.25 of its neutral width (fear and disgust
#: 0.05, sadness 0.04, at 150 % 0.07, 0.07, 0.06: no paling in their real photos); the
#: upper lip's median luminance over the skin above it, expression / neutral photo (mesh
#: loops): real smiles 1.27 (1.06-2.01), the renders of joy 1.27 (1.09-1.57) with these
#: values (1.34 at K = 0.55 without E0; 1.0 without the layer)
K, E0 = 0.66, 0.08
#: the most it goes (a 150 % grin: 0.3 strain)
A_MAX = 0.2
#: the corners keep their tone over this share of the lip's width from each end
CORNER_FADE = 0.2
#: the skin band above the outer upper lip (inter-ocular distances)
SKIN_BAND = (0.03, 0.10)
#: the lower lip's shadow on the skin below it: where it is lifted (from, to: inter-ocular
#: distances below the outer lower lip; the lit level looked for within the third) and over
#: which share of the mouth's half-width from its middle (fading out beyond). JAFFE's ten
#: women, the skin below the lower lip's middle over the forehead at 0.04-0.06, 0.06-0.08,
#: 0.08-0.10 IOD: neutral photos 0.63 0.73 0.76, real smiles 0.72 0.77 0.84, the renders of
#: joy 0.63 0.71 0.76 (the neutral lip's shadow carried along)
SHADOW_BAND = (0.02, 0.12, 0.2)
SHADOW_SPAN = 0.6
#: the lift's field is blurred by this (inter-ocular distances) once per face: its inner edge
#: follows the mesh's straight lower-lip segments and rose over a third of SHADOW_BAND[0]
#: (3 px on a 4K face), which drew fear's lifted skin under the lower lip as a pale polygon
#: with a hard rim (the lip above it not lifted); blurred, the lift fades into the lip
SHADOW_SOFT = 0.015
#: the share of that lift at the paling's most (A_MAX; in proportion below it): at 0.7 the
#: renders of joy give 0.69 0.78 0.79 at 100 %, 0.80 0.80 0.81 at 150 %
SHADOW_MAX = 0.7
#: the lower lip pulled down towards the chin lifts its shadow too: share K_PULL (c - C_PULL)
#: of a lip-to-chin distance shortened by c. JAFFE at 100 %: fear shortens it by 0.15 (its real
#: photos' skin there 0.83 0.85 0.87, the renders 0.69 0.77 0.83 without this, 0.78 0.80 0.83
#: with it), surprise 0.09, joy and disgust 0.05 (under C_PULL), anger lengthens it
K_PULL, C_PULL = 6.5, 0.08
#: the nose-to-chin distance over the photo's from which a dropped jaw fades the pull's lift
#: out, and where it is gone: real surprise's skin under the lip does not lighten (0.66 0.72
#: 0.76, neutral 0.63 0.73 0.76; its open jaw turns the chin away from the light). JAFFE at
#: 100 %: fear 1.08-1.11, surprise 1.11-1.20 (1.25 at 150 %)
JAW_WIDE = (1.11, 1.15)
#: a mouth narrower than the photo's (a smiling photo neutralised, a pout) lets the lower lip
#: protrude again: its shadow under it, at most CAST_DEPTH darker right under the lip, gone by
#: CAST_REACH IOD below it, in full from a narrowing of CAST_FULL of the neutral width (a
#: smiling photo's neutral face: the sample's mouth is 0.38 narrower). JAFFE's neutral
#: photos against their smiles, relative to the lit chin: 0.82 0.90 0.91 at 0.01-0.05 IOD
CAST_DEPTH, CAST_RISE, CAST_REACH, CAST_FULL = 0.13, 0.03, 0.11, 0.25
_SHIFT = 4  # sub-pixel bits of the rasterised loop
_N_OUTER = 9  # the loop's outer part: lipo_c0, lipo_u1..7, lipo_c1


@dataclass(frozen=True, eq=False)
class TonePlan:
    loop: np.ndarray  # (n,) vertex indices: outer upper lip left to right, inner back
    corners: tuple[int, int]  # the outer corners' vertex indices
    w_neutral: float  # outer corner distance on the neutral mesh (px)
    w_photo: float  # ... on the photo's mesh
    skin: np.ndarray  # (3,) float32 the skin's colour above the lip
    # the lower lip's shadow on the skin below it, as a lift on the photo: (h, w) float32
    # ``band weight x (lit level / pixel - 1)`` over the photo's box ``shadow_org`` (x, y);
    # None where there is none to lift
    shadow: np.ndarray | None = None
    shadow_org: tuple[int, int] = (0, 0)
    lower: np.ndarray = field(default_factory=lambda: np.zeros(0, np.intp))  # outer lower lip
    iod: float = 1.0
    tint: np.ndarray = field(default_factory=lambda: np.ones(3))  # per-channel shadow weights
    pull: tuple[int, int] = (0, 0)  # the lower lip's middle 8.2 and the chin 2.1
    pull0: float = 1.0  # their distance on the photo's mesh (px)
    nose: int = 0  # the nose's base 9.15
    nose0: float = 1.0  # its distance to the chin on the photo's mesh (px)

    @cached_property
    def cast_mat(self) -> np.ndarray:
        """(3, 2) float32: ``cv2.transform``'s map of a shadow's darkening ``g`` to the
        channels' factors ``1 - g tint`` (:func:`_cast_shadow`)."""
        m = np.ones((3, 2), np.float32)
        m[:, 0] = -self.tint
        m.setflags(write=False)
        return m

    @cached_property
    def shadow_support(self) -> tuple[int, int, int, int] | None:
        """The box of :attr:`shadow`'s nonzero pixels (its coordinates; :func:`_lift_shadow`)."""
        return None if self.shadow is None else _support(self.shadow[..., None])


@per_face
def tone_plan(face: Face) -> TonePlan | None:
    """The face's lip tone plan (cached for its lifetime); None where nothing can pale."""
    return _build(face)


def _loop(face: Face) -> tuple[np.ndarray, tuple[int, int]]:
    ix = face.mesh.index
    outer = ["lipo_c0", *(f"lipo_u{k}" for k in range(1, 8)), "lipo_c1"]
    inner = [*(f"lipi_u{k}" for k in range(7, 0, -1))]
    return (np.array([ix(n) for n in outer + inner], np.intp),
            (ix("lipo_c0"), ix("lipo_c1")))


def _build(face: Face) -> TonePlan | None:
    loop, (c0, c1) = _loop(face)
    v = np.asarray(face.vertices, np.float64)
    n = np.asarray(face.neutral_vertices, np.float64)
    w_photo = float(np.linalg.norm(v[c1] - v[c0]))
    w_neutral = float(np.linalg.norm(n[c1] - n[c0]))
    iod = float(face.interocular)
    if w_neutral < 8.0 or iod < 8.0:
        return None
    img = face.image
    H, W = img.shape[:2]
    poly = v[loop]
    m = int(math.ceil(SKIN_BAND[1] * iod)) + 2
    x0, y0 = max(int(poly[:, 0].min()) - m, 0), max(int(poly[:, 1].min()) - m, 0)
    x1, y1 = min(int(poly[:, 0].max()) + m + 1, W), min(int(poly[:, 1].max()) + 2, H)
    if x1 - x0 < 4 or y1 - y0 < 4:
        return None
    patch = np.ascontiguousarray(img[y0:y1, x0:x1])
    lip = np.zeros(patch.shape[:2], np.uint8)
    cv2.fillPoly(lip, [np.round(poly - (x0, y0)).astype(np.int32)], 1)
    core = cv2.erode(lip, np.ones((3, 3), np.uint8))
    if int(core.sum()) < 6:
        return None
    # the skin above: outside the outer lips (the upper loop closed along its chord) within
    # the band, above the corners' line
    d = cv2.distanceTransform((1 - lip).astype(np.uint8), cv2.DIST_L2, 3)
    ys = np.arange(y0, y1, dtype=np.float64)[:, None]
    xs = np.arange(x0, x1, dtype=np.float64)[None, :]
    t = np.clip((xs - v[c0, 0]) / max(v[c1, 0] - v[c0, 0], 1.0), 0.0, 1.0)
    above = ys < v[c0, 1] + t * (v[c1, 1] - v[c0, 1])
    band = (d > SKIN_BAND[0] * iod) & (d <= SKIN_BAND[1] * iod) & above
    band &= (xs > v[c0, 0]) & (xs < v[c1, 0])
    if int(band.sum()) < 6:
        return None
    lip_rgb = channel_median(patch, core)
    skin_rgb = channel_median(patch, band.astype(np.uint8))
    if float((skin_rgb - lip_rgb).max()) < 4.0:  # a lip as light as the skin: nothing to pale
        return None
    ix = face.mesh.index
    lower = np.array([ix(n) for n in ("lipo_c0", *(f"lipo_d{k}" for k in range(1, 8)),
                                      "lipo_c1")], np.intp)
    shadow, org = _shadow_lift(face, v[lower], iod)
    tint = np.ones(3) if is_grey(img) else np.array(SHADOW_TINT)
    pull = (face.mesh.fdp["8.2"], face.mesh.fdp["2.1"])
    pull0 = max(float(np.linalg.norm(v[pull[1]] - v[pull[0]])), 1.0)
    nose = face.mesh.fdp["9.15"]
    nose0 = max(float(np.linalg.norm(v[pull[1]] - v[nose])), 1.0)
    return TonePlan(loop, (c0, c1), w_neutral, w_photo, skin_rgb.astype(np.float32), shadow,
                    org, lower, iod, tint, pull, pull0, nose, nose0)


def _shadow_lift(face: Face, lower: np.ndarray, iod: float
                 ) -> tuple[np.ndarray | None, tuple[int, int]]:
    """The lift of the lower lip's shadow on the photo (see :attr:`TonePlan.shadow`): below
    the outer lower lip, between SHADOW_BAND's distances and over the mouth's middle
    (SHADOW_SPAN of its half-width), each pixel's gain to the skin's lit level further down
    (per column, the brightest of the smoothed luminance within SHADOW_BAND[2] below the
    lip: the chin's top), minus 1; blurred by SHADOW_SOFT, which carries it a little into the
    lip. ``lower`` (n, 2): the outer lower lip on the photo's mesh, corner to corner."""
    img = face.image
    H, W = img.shape[:2]
    c0, c1 = lower[0], lower[-1]
    reach = SHADOW_BAND[2] * iod
    x0, x1 = max(int(c0[0]) - 2, 0), min(int(c1[0]) + 3, W)
    y0 = max(int(min(c0[1], c1[1])) - 2, 0)
    y1 = min(int(lower[:, 1].max() + reach) + 2, H)
    if x1 - x0 < 6 or y1 - y0 < 6:
        return None, (0, 0)
    patch = img[y0:y1, x0:x1]
    L = cv2.GaussianBlur(cv2.cvtColor(np.ascontiguousarray(patch), cv2.COLOR_RGB2GRAY)
                         .astype(np.float32), (0, 0), max(0.012 * iod, 0.7))
    # the mouth's lower outline closed along its corners' chord: distance below it
    poly = np.vstack([lower, lower[:1]]) - (x0, y0)
    inside = np.zeros(L.shape, np.uint8)
    cv2.fillPoly(inside, [np.round(poly).astype(np.int32)], 1)
    d = cv2.distanceTransform((1 - inside).astype(np.uint8), cv2.DIST_L2, 3) / np.float32(iod)
    ys = np.arange(y0, y1, dtype=np.float32)[:, None]
    xs = np.arange(x0, x1, dtype=np.float32)[None, :]
    yl = np.interp(xs[0], lower[:, 0], lower[:, 1]).astype(np.float32)[None, :]
    below = (ys > yl) & (inside == 0)
    lit = np.where(below & (d <= SHADOW_BAND[2]), L, 0.0).max(0)  # per column
    lit = cv2.GaussianBlur(lit[None, :].astype(np.float32), (0, 0), max(0.03 * iod, 1.0))[0]
    gain = np.clip(lit[None, :] / np.maximum(L, 1.0) - 1.0, 0.0, 1.0)
    a, b = SHADOW_BAND[:2]
    w = clamp((d - 0.3 * a) / (0.7 * a), 0.0, 1.0) * clamp((b - d) / (0.4 * b), 0.0, 1.0)
    cx, half = 0.5 * float(c0[0] + c1[0]), max(0.5 * float(c1[0] - c0[0]), 1.0)
    u = np.abs(xs - np.float32(cx)) / np.float32(half)
    span = smooth01((1.0 - u) / (1.0 - SHADOW_SPAN))
    field = (gain * smooth01(w) * span * below).astype(np.float32)
    field = cv2.GaussianBlur(field, (0, 0), SHADOW_SOFT * iod)
    # (the blur's far tails zeroed: a lift under 1/512 moves no 8-bit level, and the frame's
    # work covers only the field's nonzero box, TonePlan.shadow_support)
    field[field < np.float32(1.0 / 512.0)] = 0.0
    if float(field.max()) < 0.01:
        return None, (0, 0)
    return np.ascontiguousarray(field), (x0, y0)


def tone_share(plan: TonePlan, vertices: np.ndarray) -> float:
    """``a``: how far the upper lip goes towards the skin for the deformed mesh ``vertices``
    (0 unless the mouth is wider than both the photo's and the neutral one).

    (Not the other way: deepening a neutralised smile's stretched lip by the inverse, measured
    on JAFFE's toothy smiles, made their closed lips heavier and darker, the blind raters'
    "dark lips pasted on", with nothing real to calibrate it against.)"""
    e = (_dist(vertices, *plan.corners) - max(plan.w_photo, plan.w_neutral)) / plan.w_neutral
    return min(max(K * (e - E0), 0.0), A_MAX)


def _dist(vertices: np.ndarray, i: int, j: int) -> float:
    """Distance (px) between vertices ``i`` and ``j`` of a mesh."""
    a, b = vertices[i], vertices[j]
    return math.hypot(float(b[0]) - float(a[0]), float(b[1]) - float(a[1]))


def pull_share(plan: TonePlan, vertices: np.ndarray) -> float:
    """The share of the lower lip's shadow lifted because the lip is pulled down towards the
    chin (AU16 and AU20 of fear, beyond the jaw): the lip-to-chin distance (8.2 to 2.1)
    shortened by ``c`` of the photo's, ``K_PULL (c - C_PULL)``, at most SHADOW_MAX. A jaw that
    drops moves both and does not count; a chin pushed up under a pouting lip lengthens it."""
    c = 1.0 - _dist(vertices, *plan.pull) / plan.pull0
    if c <= C_PULL:
        return 0.0
    # a jaw dropped wide (the nose-to-chin distance beyond JAW_WIDE[0] of the photo's) turns
    # the chin away from the light: the lift fades out by JAW_WIDE[1]
    r = _dist(vertices, plan.nose, plan.pull[1]) / plan.nose0
    jaw = min(max((JAW_WIDE[1] - r) / (JAW_WIDE[1] - JAW_WIDE[0]), 0.0), 1.0)
    return min(K_PULL * (c - C_PULL), SHADOW_MAX) * jaw


def narrowing_share(plan: TonePlan, vertices: np.ndarray) -> float:
    """How far (0-1) the mouth is narrower than the photo's, beyond E0 of the neutral width,
    up to CAST_FULL: a smiling photo's neutralised or pouting lower lip protrudes again."""
    e = (plan.w_photo - _dist(vertices, *plan.corners)) / plan.w_neutral
    return min(max((e - E0) / (CAST_FULL - E0), 0.0), 1.0)


def _cast_shadow(plan: TonePlan, out: np.ndarray, vertices: np.ndarray, depth: float
                 ) -> tuple[int, int, int, int] | None:
    """Darken the skin under the deformed outer lower lip (in place) by up to ``depth``: the
    shadow of a lower lip that protrudes again (JAFFE's neutral lips over their smiles' at
    0-0.10 IOD below the lip: 0.82 0.90 0.91 0.99 0.95, relative to the lit chin). The box
    written, or None."""
    # (rows gathered with take; the box from Python floats: the same values as numpy's
    # reductions, without their per-call cost on nine points)
    lower = np.asarray(vertices).take(plan.lower, 0).astype(np.float64)
    lx, ly = lower[:, 0].tolist(), lower[:, 1].tolist()
    H, W = out.shape[:2]
    reach = CAST_REACH * plan.iod
    x0, x1 = max(int(min(lx)), 0), min(int(max(lx)) + 1, W)
    y0 = max(int(min(ly)), 0)
    y1 = min(int(max(ly) + reach) + 2, H)
    if x1 - x0 < 3 or y1 - y0 < 3:
        return None
    xs = np.arange(x0, x1, dtype=np.float64)
    by_x = lower.take(np.argsort(lower[:, 0]), 0)
    yl = interp(xs, np.ascontiguousarray(by_x[:, 0]), np.ascontiguousarray(by_x[:, 1]))
    # a soft bump: rising over the lip's own edge (CAST_RISE), gone by CAST_REACH below it
    # (nothing above the lip): the smoothstep of min(dy / CAST_RISE, (CAST_REACH - dy) /
    # (CAST_REACH - CAST_RISE)) clipped to [0, 1], dy the height below the lip (IOD), the
    # product of the rise's smoothstep and one less the fall's (one of them is 1 wherever the
    # other is not: smoothstep(1 - t) = 1 - smoothstep(t)), each term a row's part plus a
    # column's (float32, ~1e-7 of the float64 product's values; 0.1 ms -> 0.05 ms a frame
    # on the 1080p bench face, its frame unchanged)
    a_r, a_f = 1.0 / (CAST_RISE * plan.iod), 1.0 / ((CAST_REACH - CAST_RISE) * plan.iod)
    ys = np.arange(y1 - y0, dtype=np.float64)  # (rows and the lip from row y0: small numbers)
    yl -= y0
    t = np.subtract((ys * a_r).astype(np.float32)[:, None], (yl * a_r).astype(np.float32)[None, :])
    fall = np.add(((CAST_REACH * plan.iod - ys) * a_f).astype(np.float32)[:, None],
                  (yl * a_f).astype(np.float32)[None, :])
    np.minimum(t, fall, out=t)
    clip(t, 0.0, 1.0, out=t)
    g = np.multiply(t, t)
    t *= np.float32(-2.0)
    t += np.float32(3.0)
    g *= t
    cx, half = 0.5 * (lx[0] + lx[-1]), max(0.5 * abs(lx[-1] - lx[0]), 1.0)
    g *= (depth * smooth01((1.0 - np.abs(xs - cx) / half) / (1.0 - SHADOW_SPAN))).astype(
        np.float32)[None, :]
    # (on a colour photo darker towards red, as shadows on skin look; creases' tint) (the
    # three channels' factors 1 - g tint in one transform)
    f = cv2.transform(g[..., None], plan.cast_mat)
    view = out[y0:y1, x0:x1]
    cv2.multiply(view, f, dst=view, dtype=cv2.CV_8U)
    return x0, y0, x1, y1


def apply_lip_tone(face: Face, res: WarpResult, vertices: np.ndarray) -> WarpResult:
    """Pale the upper lip of ``res.image`` (in place) by the mouth's widening beyond the
    photo's, and lift or cast the lower lip's shadow; ``res``."""
    plan = tone_plan(face)
    if plan is None:
        return res
    a = tone_share(plan, vertices)
    # the lower lip's shadow: lifted where the lip is stretched across (with the paling) or
    # pulled down towards the chin, else cast again where the mouth narrows
    lift = max(min(a / A_MAX, 1.0) * SHADOW_MAX, pull_share(plan, vertices))
    bbox = res.bbox
    box: tuple[int, int, int, int] | None = None
    if lift > 0.0:
        if plan.shadow is not None and res.maps is not None:
            box = _lift_shadow(plan, res, vertices, lift, reach_step(face))
    else:
        n = narrowing_share(plan, vertices)
        if n > 0.0:
            box = _cast_shadow(plan, res.image, vertices, n * CAST_DEPTH)
    if box is not None:
        bbox = _union(bbox, box)
    if a > 0.0:
        box = _pale(plan, res.image, vertices, a)
        if box is not None:
            bbox = _union(bbox, box)
    return res if bbox == res.bbox or bbox is None else _rebox(res, bbox, {})


def _pale(plan: TonePlan, out: np.ndarray, vertices: np.ndarray, a: float
          ) -> tuple[int, int, int, int] | None:
    """Move the upper lip's pixels ``a`` of the way towards the skin's colour (in place); the
    box written, or None."""
    H, W = out.shape[:2]
    poly = np.asarray(vertices, np.float64)[plan.loop]
    x0, y0 = max(int(poly[:, 0].min()) - 2, 0), max(int(poly[:, 1].min()) - 2, 0)
    x1, y1 = min(int(poly[:, 0].max()) + 3, W), min(int(poly[:, 1].max()) + 3, H)
    if x1 - x0 < 3 or y1 - y0 < 3:
        return None
    mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
    q = np.rint((poly - (x0, y0)) * (1 << _SHIFT)).astype(np.int32)
    cv2.fillPoly(mask, [q], 255, cv2.LINE_AA, _SHIFT)
    w = cv2.GaussianBlur(mask.astype(np.float32), (0, 0), 0.7) * np.float32(a / 255.0)
    # the corners stay in their shadow: a smooth fade over CORNER_FADE of the width
    c0x, c1x = float(poly[0, 0]), float(poly[_N_OUTER - 1, 0])
    span = max(c1x - c0x, 1.0)
    u = (np.arange(x0, x1, dtype=np.float32) - np.float32(c0x)) / np.float32(span)
    w *= smooth01(np.minimum(u, 1.0 - u) / np.float32(CORNER_FADE))[None, :]
    # each pixel moves towards the skin's colour by its own distance to it (a pixel at the
    # skin's level or lighter, e.g. the skin the loop's edge takes, stays as it is)
    view = out[y0:y1, x0:x1]
    up = plan.skin - view.astype(np.float32)
    np.maximum(up, 0.0, out=up)
    up *= spread3(w)  # (cv2.merge's values at about half its cost)
    cv2.add(view, up, dst=view, dtype=cv2.CV_8U)
    return x0, y0, x1, y1


def _lift_shadow(plan: TonePlan, res: WarpResult, vertices: np.ndarray, share: float,
                 step: int = 1) -> tuple[int, int, int, int] | None:
    """Lift the lower lip's shadow in ``res.image`` by ``share`` of :attr:`TonePlan.shadow`,
    carried from the photo by the warp's backward map; the box written, or None. ``step``:
    ``lipseal._reached``'s."""
    assert plan.shadow is not None and res.maps is not None
    out = res.image
    H, W = out.shape[:2]
    h, w = plan.shadow.shape
    ox, oy = plan.shadow_org
    # the frame's box: where the photo has it and where the lower lip took it, with a margin
    c0, c1 = plan.corners
    shift = 0.5 * (np.asarray(vertices[c0], np.float64) + np.asarray(vertices[c1], np.float64))
    m = 4
    sx, sy = float(shift[0]) - 0.5 * w - ox, float(shift[1]) - oy
    x0, y0 = max(int(min(ox, ox + sx)) - m, 0), max(int(min(oy, oy + sy)) - m, 0)
    x1 = min(int(max(ox + w, ox + w + sx)) + m + 1, W)
    y1 = min(int(max(oy + h, oy + h + sy)) + m + 1, H)
    if x1 - x0 < 2 or y1 - y0 < 2:
        return None
    box = (x0, y0, x1, y1)
    # only where the map reaches the shadow's nonzero pixels (elsewhere the lift is a gain of
    # exactly 1: the same frame)
    sup = plan.shadow_support
    sub = None if sup is None else _reached(res.maps, box, (ox, oy), sup, step)
    if sub is None:
        return box
    x0, y0, x1, y1 = sub
    mx, my = box_maps(res.maps, sub, (ox, oy))
    # (zeros outside: the default)
    f = np.asarray(cv2.remap(plan.shadow, mx, my, cv2.INTER_LINEAR), np.float32)
    f *= np.float32(share)
    f += np.float32(1.0)
    view = out[y0:y1, x0:x1]
    cv2.multiply(view, spread3(f), dst=view, dtype=cv2.CV_8U)
    return box
