"""Layered rendering behind the warped face (SPEC §3): mouth interior and eyeballs. No Qt.

Depth order (SPEC §3.1): tongue 3, lower teeth 2, upper teeth 1, warped face 0, over a dark
shaded cavity (:mod:`mouth`); the eyeball (white + iris, :mod:`gaze`) behind each eye opening.

:func:`render_layers` runs after :func:`warp`. For each opening that changed (its polygon moved,
the skull turned, or, for an eye, a gaze / thrust / pupil FAP is set) it

1. computes the opening's pixel coverage ``a`` on the deformed polygon (4x4 supersampling);
2. gets the interior colours from the mouth or eye model for the opening's box (+1 px);
3. gives the pixels the warp assigned to the opening a face colour continued from their
   neighbours (normalised box filter), so that edge pixels can blend lip/lid with interior;
4. writes ``a * interior + (1 - a) * face``: edges along the inner lips and the eyelids are
   anti-aliased, and a closed opening (zero area) shows only skin.

An outline that has not moved uses the warp's own pixel set as ``a`` (the photo's edges are
already smooth); the supersampled coverage fades in over the outline's first pixel of motion,
and the eye and mouth models reproduce the photo at rest, so small FAPs change the image
continuously. Openings that did not change are left exactly as the warp made them (a zero FAP
vector reproduces the photo); every written pixel lies in the returned ``bbox``.

:func:`layer_plan` builds the eye and mouth models once per face and analyses the photo for
them (skin lighting, its own teeth, what its mouth opening shows: :func:`_own_interior`).
"""

from __future__ import annotations

import itertools
import math
import weakref
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING, cast

import cv2
import numpy as np
import numpy.typing as npt
from numpy.lib.stride_tricks import sliding_window_view

from .deform import eye_state
from .fitting import (
    channel_median,
    clamp,
    clip,
    gather_px,
    masked_rows,
    median,
    pad_edge,
    smooth01,
    smooth01_float,
)
from .gaze import (
    EXTRA_INDEX,
    EYE_FAPS,
    PLATE_WORK_R,
    EyePlan,
    edge_ramp,
    photo_through,
    spread3,
)
from .grain import grain_over
from .mouth import (
    CROWN,
    GUM_FADE,
    MouthPlan,
    _lum,
    _poly_mask,
    _sat,
    _smoothstep1,
)
from .outline import CHORD_PX, smooth_loop, splits
from .threads import Pending
from .warp import WarpResult, box_maps

if TYPE_CHECKING:
    from .face import Face
    from .mesh import StandardMesh

_SHIFT = 4
_TOL = 1e-3
_SKIN_SAT = 0.22  # saturation of the skin the mouth textures were drawn for
#: each eye's FAPs (EYE_FAPS: every other index from its first) as a slice: a view, cheaper
#: than a fancy index
_EYE_FAP_IDX = {k: slice(v[0], v[-1] + 1, v[1] - v[0]) for k, v in EYE_FAPS.items()}
assert all(list(range(99))[_EYE_FAP_IDX[k]] == list(v) for k, v in EYE_FAPS.items())
_CROSS = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
_SQUARE = np.ones((3, 3), np.uint8)
#: the mouth's blurred coverage counts from this level up (:func:`_soft_edge`): 0.25 at the
#: outline, as the inside-only fade before it, so a re-detection reads the opening's size as
#: it did (cloning's round trip of joy on the 3x sample: 7.84 % mean error before, 8.21 with
#: the plain blur, 7.86 with this), little spill onto the lips, a thin wedge fainter still
EDGE_CUT = 0.2


@lru_cache(maxsize=8)
def _disc(k: int) -> np.ndarray:
    """A k x k disc (kept: a face's size recurs from frame to frame; a square's opening
    leaves blocky steps on the lips)."""
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))
_ZEROS2 = np.zeros(2)  # (np.pad's two zeros either side, without its set-up)


@dataclass(eq=False)
class LayerPlan:
    mouth: MouthPlan
    eyes: dict[str, EyePlan]
    #: edge ramp (px) of the openings' layers: 1 on a sharp photo; on a soft one (upscaled,
    #: defocused: a large face whose edges span several pixels) the eyeballs and the mouth's
    #: interior fade in over as many pixels inside the lids and lips (:func:`gaze.edge_ramp`
    #: of both irises' edges)
    soft: float = 1.0


_PLANS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def layer_plan(face: Face) -> LayerPlan:
    """The per-face precomputation (cached for the face's lifetime)."""
    p = _PLANS.get(face)
    if p is None:
        lm = face.landmarks
        img, v, mesh = face.image, face.vertices.astype(np.float64), face.mesh
        irises = {"eye_l": lm.iris_left, "eye_r": lm.iris_right}

        def build_eyes() -> dict[str, EyePlan]:
            return {k: EyePlan.build(img, v, mesh.holes[k], k,
                                     (irises[k].cx, irises[k].cy, irises[k].r),
                                     face.plan.frame_rot)
                    for k in ("eye_l", "eye_r")}

        # large eyes (a photo of ~10 MP and more) are built on a thread while this one builds
        # the mouth: their arrays are large enough for numpy and OpenCV to run mostly without
        # the GIL (24 MP: ~85 ms of eyes beside ~55 ms of mouth); small ones would only
        # contend for it
        if min(lm.iris_left.r, lm.iris_right.r) <= PLATE_WORK_R:
            p = _build_rest(face, img, v, mesh, build_eyes)
        else:
            p = _build_rest(face, img, v, mesh, Pending(build_eyes).result)
        _PLANS[face] = p
    return p


def _build_rest(face: Face, img: np.ndarray, v: np.ndarray, mesh: StandardMesh,
                eyes_of: Callable[[], dict[str, EyePlan]]) -> LayerPlan:
    """:func:`layer_plan` after the eyes were started: the mouth, then the eyes (``eyes_of``)
    and the edge ramp they measure."""
    # the photo's lighting: the cheeks' skin, its own teeth when the mouth shows some
    # drawn in the cheeks' box only (the same pixels as on the whole photo)
    q = np.round(v[_cheek_triangles(mesh)] * 16).astype(np.int32)  # (n, 3, 2)
    h, w = img.shape[:2]
    if len(q):
        bx0, by0 = clamp(q.reshape(-1, 2).min(0) // 16 - 1, 0, (w, h))
        bx1, by1 = clamp(q.reshape(-1, 2).max(0) // 16 + 2, 0, (w, h))
    else:
        bx0 = by0 = bx1 = by1 = 0
    skin_mask = np.zeros((max(by1 - by0, 0), max(bx1 - bx0, 0)), np.uint8)
    off = np.array([bx0, by0], np.int32) * 16
    for t in q:
        cv2.fillConvexPoly(skin_mask, t - off, 1, cv2.LINE_8, 4)
    skin = (channel_median(img[by0:by1, bx0:bx1], skin_mask).astype(np.float32)
            if skin_mask.any() else np.array([200.0, 160.0, 140.0], np.float32))
    skin_l = max(float(_lum(skin)), 20.0)
    sat = float(clamp(_sat(skin) / _SKIN_SAT, 0.0, 1.0))
    poly = v[mesh.holes["mouth"]]
    mouth = MouthPlan.build(v, mesh, face.plan, skin_l, sat, _photo_teeth(img, poly, skin_l),
                            skin, face.neutral_vertices)
    lower = v[[mesh.index(f"lipi_d{k}") for k in range(1, 8)]]
    eyes = eyes_of()
    soft = edge_ramp([*eyes["eye_l"].widths, *eyes["eye_r"].widths],
                     0.5 * (eyes["eye_l"].r0 + eyes["eye_r"].r0))
    mouth.attach_own(*_own_interior(img, poly, lower, mouth.mouth_nose, skin_l, mouth.gum,
                                    soft))
    mouth.soften(soft)
    return LayerPlan(mouth, eyes, soft)


@lru_cache(maxsize=4)
def _cheek_triangles(mesh: StandardMesh) -> np.ndarray:
    """(n, 3) vertex indices of the mesh's triangles whose corners all lie on the cheeks (per
    mesh, read-only: the comparison of its region names cost ~25 us a face)."""
    t = mesh.triangles[np.all(mesh.regions[mesh.triangles] == "cheek", axis=1)]
    t.flags.writeable = False
    return t


#: the mouth loop's corners (:func:`_opening_index`: lipi_c0 first, lipi_c1 after the upper lip)
_MOUTH_CORNERS = (0, 8)

#: an eye loop's corners (eye_*_c0 first, eye_*_c1 after the upper lid)
_EYE_CORNERS = (0, 6)

#: an eye's lids become smooth arcs once a side of its loop is longer than this (px): on a
#: JAFFE face (eyes ~25 px wide, sides up to 7 px) the arcs' pixels left the lash band the
#: eyeball layer carries along the mesh's lid edges, which roughened the lid line (1.31 x the
#: photo's against 0.96 x); on the 4K bench face (sides of 40-60 px) the straight sides drew a
#: chamfered lid margin over the iris
EYE_CHORD_PX = 12.0

#: the longest chord of each opening's outline (eye_l, eye_r, mouth)
_CHORDS = [EYE_CHORD_PX, EYE_CHORD_PX, CHORD_PX]


@lru_cache(maxsize=4)
def _opening_index(mesh) -> tuple[np.ndarray, np.ndarray]:
    """The vertex loops of eye_l, eye_r and mouth concatenated, and where each starts."""
    loops = [np.asarray(mesh.holes[k], np.intp) for k in ("eye_l", "eye_r", "mouth")]
    cuts = np.cumsum([0] + [len(x) for x in loops[:-1]])
    return np.concatenate(loops), cuts


_REST: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _rest_loops(face: Face) -> np.ndarray:
    """The openings' loops (:func:`_opening_index`) on the photo's mesh (once per face)."""
    got = _REST.get(face)
    if got is None:
        got = face.vertices[_opening_index(face.mesh)[0]]
        _REST[face] = got
    return got


def _box_of(lo: list[float], hi: list[float], shape: tuple[int, ...], pad: int = 2
            ) -> tuple[int, int, int, int]:
    """The pixel box of an outline whose extent is ``lo`` .. ``hi`` (x, y), ``pad`` px more,
    inside the image."""
    h, w = shape[:2]
    (lx, ly), (hx, hy) = lo, hi
    x0 = min(max(math.floor(lx) - pad, 0), w)
    y0 = min(max(math.floor(ly) - pad, 0), h)
    x1 = min(max(math.ceil(hx) + pad + 1, 0), w)
    y1 = min(max(math.ceil(hy) + pad + 1, 0), h)
    return x0, y0, x1, y1


@lru_cache(maxsize=8)
def _next_in_loop(ends: tuple[int, ...]) -> np.ndarray:
    """Index of the next vertex along each loop of concatenated loops ending at ``ends``."""
    nxt = np.arange(ends[-1]) + 1
    starts = (0, *ends[:-1])
    for a, b in zip(starts, ends, strict=True):
        nxt[b - 1] = a
    return nxt


_IDENTITY = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def _is_identity(m: np.ndarray, tol: float = 1e-4) -> bool:
    return bool(np.abs(np.asarray(m) - _IDENTITY).max() < tol)


def _union(a: tuple[int, int, int, int] | None, b: tuple[int, int, int, int]
           ) -> tuple[int, int, int, int]:
    if a is None:
        return b
    return min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3])


def _mouth_rim(out: np.ndarray, box: tuple[int, int, int, int], hole: np.ndarray,
               alpha: np.ndarray, D: float, strength: float = 1.0, with_shade: bool = True
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """What the lips around an opening give its interior, and their own shading.

    Returns the colour of the nearest lip pixel (h, w, 3) and the distance (px) to the lips
    (h, w) at every pixel of ``box`` (one distance transform with labels), and a factor
    (h, w) that darkens the lips' inner edge (their surface turning into the mouth) over about
    a pixel outside the opening, in proportion to how open it is there (None when
    ``with_shade`` is False: a soft photo's edge ramp is the lips' surface turning in,
    :func:`_soft_edge`).
    """
    x0, y0, x1, y1 = box
    face = out[y0:y1, x0:x1]
    # (``hole`` is a 0/1 byte mask viewed as bool: its bytes are the uint8 mask itself)
    inside = hole.view(np.uint8) if hole.flags.c_contiguous else hole.astype(np.uint8)
    depth, labels = cv2.distanceTransformWithLabels(inside, cv2.DIST_L2, 3,
                                                    labelType=cv2.DIST_LABEL_PIXEL)
    labels = cast("npt.NDArray[np.int32]", labels)  # the stubs say int or float: int32 labels
    rim = _blur(_nearest_outside(face, hole, labels), 1.0, 5)
    if not with_shade:
        return rim, depth, None
    # the inner edge of the lips: darker close to the opening, scaled with its local width
    # (the coverage blurred over the lip band), nothing where the lips meet
    s = min(max(0.03 * D, 0.7), 1.5)
    spread: np.ndarray = _blur(alpha, s)  # >= 0: clamped above only
    spread *= np.float32(1.6)
    shade = 1.0 - 0.35 * strength * np.minimum(spread, 1.0) * (1.0 - alpha)
    return rim, depth, shade.astype(np.float32, copy=False)


def _nearest_outside(face: np.ndarray, hole: np.ndarray, labels: np.ndarray,
                     empty: np.ndarray | None = None) -> np.ndarray:
    """(h, w, 3) float32: at every pixel of ``face`` (h, w, 3) the colour of the pixel
    outside ``hole`` that ``labels`` names (``cv2.distanceTransformWithLabels`` of the hole,
    ``DIST_LABEL_PIXEL``: the zero pixels numbered from 1 row by row); ``empty`` (or zeros)
    when every pixel is in the hole.

    (One gather of rows by flat indices composed from the labels: a boolean mask of a
    3-channel view, ``face[~hole]``, costs several times more on these small boxes. From
    :data:`GATHER4_PX` pixels the rows are gathered as 4-byte words of an RGBA copy, a
    third faster than 3-byte rows: the 4K bench face's boxes, ~0.1 ms of ~0.3.)"""
    outside = (~hole).ravel().nonzero()[0]  # (np.flatnonzero's values, without its wrappers)
    if not len(outside):
        return np.zeros(face.shape, np.float32) if empty is None else empty.astype(np.float32)
    at = outside.take(labels - 1, mode="clip")
    if at.size >= GATHER4_PX:
        words = cv2.cvtColor(face, cv2.COLOR_RGB2RGBA).view(np.uint32).reshape(-1)
        got = words.take(at).view(np.uint8).reshape(*face.shape[:2], 4)
        return cv2.cvtColor(got, cv2.COLOR_RGBA2RGB).astype(np.float32)
    rows = np.ascontiguousarray(face).reshape(-1, 3)
    return rows.take(at, 0).reshape(face.shape).astype(np.float32)


#: From this many pixels :func:`_nearest_outside` gathers 4-byte words (the 1080p bench
#: face's boxes, ~1000 px, gather 3-byte rows: there the RGBA copies cost more than they save)
GATHER4_PX = 4096


#: the bright structures :func:`_clean_lip_line` takes off a soft photo's lips: up to this
#: many edge ramps (plus 2 px) wide. A JAFFE face upscaled 4 x (ramp 4.1 px) carries its
#: photo's lip line (teeth between parted lips, 1-2 px there) as a 5-8 px light band along the
#: opened lips: at half a ramp it stayed, a light outline around the opening
LIP_LINE_SOFT = 1.0
#: from this disc (px) on, :func:`_clean_lip_line` opens at half resolution
LIP_LINE_HALF = 13


def _clean_lip_line(out: np.ndarray, box: tuple[int, int, int, int], poly: np.ndarray,
                    alpha: np.ndarray, strength: float, soft: float = 1.0) -> None:
    """Remove thin bright specks from the lips along the inner-lip outline (in place).

    The photo's lip triangles end on its inner-lip contour; pixels there that are partly
    teeth ride on the moving lips and line up as white dots when the lips close or stretch.
    Within ~1.5 px of the deformed outline, outside the opening, a grey-level opening (3x3)
    of the colours takes out bright structures thinner than 3 px, nothing else. On a soft
    photo (edge ramp ``soft`` > 1 px: a large face) that strip of teeth is several pixels
    wide: the opening (a disc) grows to k = ``soft`` / 2 + 2 px (odd), the band to k - 1 px
    either side of the outline.
    """
    x0, y0, x1, y1 = box
    k = 3 if soft <= 1.0 else max(3, int(round(LIP_LINE_SOFT * soft + 2.0)) | 1)
    band = np.zeros((y1 - y0, x1 - x0), np.uint8)
    # (the outline in fixed point, then moved to the box by whole pixels: the same integers
    # as rounding it less the box's corner, the scale a power of two; an int32 row, no
    # broadcast of a float pair)
    q = np.rint(np.multiply(poly, float(1 << _SHIFT), dtype=np.float64)).astype(np.int32)
    q -= np.array((x0 << _SHIFT, y0 << _SHIFT), np.int32)
    cv2.polylines(band, [q], True, 1, 3 if k == 3 else 2 * k - 1, cv2.LINE_8, _SHIFT)
    # (float32 throughout: ``strength`` as a Python number, the weight spread and applied in
    # float32; at full strength the same values as in float64)
    w = band.astype(np.float32) * clip(1.0 - 2.0 * alpha, 0.0, 1.0) * float(strength)
    if not np.count_nonzero(w):
        return
    patch = out[y0:y1, x0:x1]
    h, w_ = patch.shape[:2]
    if k >= LIP_LINE_HALF and h >= 8 and w_ >= 8:
        # a wide disc (a very soft photo: the 4K bench face's 17 px) on the patch's 2 x 2
        # block means, upsampled: the photo is smooth at that scale, and the full-resolution
        # opening cost ~0.5 ms a frame there
        small = cv2.resize(patch, ((w_ + 1) // 2, (h + 1) // 2), None, 0, 0, cv2.INTER_AREA)
        small = cv2.morphologyEx(small, cv2.MORPH_OPEN, _disc((k // 2) | 1))
        opened = cv2.resize(small, (w_, h), None, 0, 0, cv2.INTER_LINEAR)
    else:
        opened = cv2.morphologyEx(patch, cv2.MORPH_OPEN, _SQUARE if k == 3 else _disc(k))
    res = opened.astype(np.float32)
    res -= patch
    res *= spread3(w)
    res += patch
    _to_uint8(res, out[y0:y1, x0:x1])


def _to_uint8(res: np.ndarray, dst: np.ndarray) -> None:
    """``dst[:] = res`` rounded to the nearest integer and saturated to uint8, in place (one
    OpenCV conversion; ``res`` float32, ``dst`` a uint8 view of the same shape)."""
    cv2.add(res, _zeros32(res.shape), dst, None, cv2.CV_8U)  # (positional: cheaper)


@lru_cache(maxsize=64)
def _gauss_kernel(ksize: int, sigma: float) -> np.ndarray:
    """The float32 Gaussian kernel ``cv2.GaussianBlur`` uses for float images (kept: the
    sigmas of a face recur from frame to frame)."""
    k = cv2.getGaussianKernel(ksize, sigma, cv2.CV_32F)
    k.setflags(write=False)
    return k


def _blur(a: np.ndarray, sigma: float, ksize: int = 0) -> np.ndarray:
    """``cv2.GaussianBlur(a, (ksize, ksize), sigma)`` of a float32 image (the same values: the
    same kernel through ``cv2.sepFilter2D``, without GaussianBlur's per-call set-up, which
    costs as much as the filtering on a layer's box). ``ksize`` 0: OpenCV's size for the
    sigma of a float image, ``round(8 sigma + 1) | 1``."""
    if ksize <= 0:
        ksize = int(round(sigma * 8.0 + 1.0)) | 1
    k = _gauss_kernel(ksize, float(sigma))
    return cv2.sepFilter2D(a, -1, k, k)


#: The eyeball of a photo whose edges ramp over at least this many px (a soft photo, e.g.
#: a large face from an upscaled picture) is evaluated on blocks of ``soft // EYE_BLOCK_SOFT``
#: px and upsampled (:meth:`gaze.EyePlan.render`); faces up to 1080p (softness below ~3 px)
#: per pixel
EYE_BLOCK_SOFT = 6.0

#: A blur of :func:`_blur_wide` at least this wide (sigma, px) is computed at half
#: resolution: the photo's softness on a large face from an upscaled picture (the bench's
#: 4K face: 15 px, its lids' and lips' blurs of sigma 6-8 px cost ~0.5 ms each at full
#: resolution). Faces up to 1080p (softness below ~3 px) blur at full resolution.
WIDE_SIGMA = 4.0


def _blur_wide(a: np.ndarray, sigma: float) -> np.ndarray:
    """:func:`_blur` of a float32 image, for a wide Gaussian (``sigma`` >= :data:`WIDE_SIGMA`)
    on the image's 2 x 2 block means (padded to an even size by reflection), upsampled
    bilinearly: the block means and the upsampling blur by about 0.92 px^2 of variance
    between them, which the half-resolution Gaussian leaves out (its sigma
    ``sqrt(sigma^2 - 0.92) / 2``). Within a fraction of a percent of the full-resolution blur
    of the images it is used on (colours, coverages: smooth at the scale of 2 px)."""
    h, w = a.shape[:2]
    if sigma < WIDE_SIGMA or h < 8 or w < 8:
        return _blur(a, sigma)
    ph, pw = h & 1, w & 1
    src = cv2.copyMakeBorder(a, 0, ph, 0, pw, cv2.BORDER_REFLECT_101) if ph or pw else a
    small = cv2.resize(src, ((w + pw) // 2, (h + ph) // 2), None, 0, 0, cv2.INTER_AREA)
    small = _blur(small, math.sqrt(sigma * sigma - 0.92) / 2.0)
    big = cv2.resize(small, (w + pw, h + ph), None, 0, 0, cv2.INTER_LINEAR)
    return np.ascontiguousarray(big[:h, :w]) if ph or pw else big


@lru_cache(maxsize=32)
def _zeros32(shape: tuple[int, ...]) -> np.ndarray:
    """A read-only float32 array of zeros (kept: a box's shape recurs from frame to frame)."""
    z = np.zeros(shape, np.float32)
    z.setflags(write=False)
    return z


def _soft_edge(out: np.ndarray, box: tuple[int, int, int, int], hole: np.ndarray,
               alpha: np.ndarray, soft: float, t: float,
               known: tuple[np.ndarray, np.ndarray] | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
    """An opening's coverage softened to the photo's edges, and the colour (h, w, 3) the face
    continues with inside it: the nearest pixel outside (the lid's or lip's margin), smoothed
    over the ramp.

    A soft photo (a large face from an upscaled or defocused picture) draws its lid and lip
    margins as gradients several pixels wide; an interior cut in at one pixel then reads as
    a sticker. An eye's coverage fades in over ``soft`` px inside its outline only (the lids
    keep their shape and carry their lash bands, :mod:`gaze`); the mouth's is blurred as the
    photo is, centred on the outline (``known`` given). ``t`` in [0, 1]: how far the fade
    has come in (it follows the opening's first pixel of motion, as the coverage does: at
    rest the interior is the photo's own, edges included). ``known``: the distance to the
    outline and the nearest margin colour when already measured (:func:`_mouth_rim`)."""
    if known is not None:
        depth, rim = known
    else:
        x0, y0, x1, y1 = box
        face = out[y0:y1, x0:x1]
        inside = hole.view(np.uint8) if hole.flags.c_contiguous else hole.astype(np.uint8)
        depth, labels = cv2.distanceTransformWithLabels(inside, cv2.DIST_L2, 3,
                                                        labelType=cv2.DIST_LABEL_PIXEL)
        labels = cast("npt.NDArray[np.int32]", labels)
        rim = _nearest_outside(face, hole, labels, face)
    raw = np.ascontiguousarray(rim, np.float32)
    rim = _blur_wide(raw, max(0.5 * soft, 0.8))
    if known is None:
        # an eye: at the outline the nearest margin pixel itself, smoothed further in (blurred
        # up to the outline, the continued face stepped against the lid beside it: a staircase
        # along the warp's pixel raster of the opening on a soft photo's lower lid). depth is 1
        # on the opening's first pixel row. (The mouth's outline is blurred as a whole, below,
        # and a re-detection of its lips reads this colour: cloning's round trip of fear on
        # the 3x sample fell below its bar with it.)
        wgt = clip((np.asarray(depth, np.float32) - np.float32(1.0)) * np.float32(2.0 / soft),
                   0.0, 1.0)
        rim -= raw
        rim *= spread3(wgt)
        rim += raw
    if known is not None:
        # the mouth: its coverage seen through the photo's blur (a Gaussian of ramp / 2.56, as
        # the folds' in :mod:`creases`), centred on the outline. The lips' inner edge darkens
        # over the photo's ramp as a real open mouth's does, and a sliver narrower than the
        # blur (the thin wedge at a corner of a smile or of disgust's raised lip) cannot show
        # its full darkness through it: a 2 px wedge on a face whose edges ramp over 5 px
        # reaches ~0.4 (~0.2 from EDGE_CUT up). An inside-only fade (as the eyes') left a step
        # at the outline and drew such wedges as crisp black ticks on a soft face
        lim = _blur_wide(np.ascontiguousarray(alpha, np.float32), soft / 2.56)
        lim -= np.float32(EDGE_CUT)
        lim *= np.float32(1.0 / (1.0 - EDGE_CUT))
        clip(lim, 0.0, 1.0, out=lim)
        lim -= alpha  # (fading in with the outline's first pixel of motion, as the coverage)
        lim *= np.float32(t)
        lim += alpha
        return lim, rim
    fade = np.minimum(np.asarray(depth, np.float32) * np.float32(1.5 / soft), np.float32(1.0))
    fade -= 1.0
    fade *= np.float32(t)
    fade += 1.0
    return alpha * fade, rim


def _shown(box: tuple[int, int, int, int], outline: tuple[int, int, int, int],
           alpha_c: np.ndarray | None = None
           ) -> tuple[tuple[int, int, int, int], tuple[slice, slice]]:
    """The part of an opening's ``box`` whose interior colours the composite reads (as a box
    of the frame, and as slices of ``box``): the pixels where the interior shows (its
    coverage above zero) or where the face is continued into the opening (its pixel set: an
    open eye's margin takes the interior there, :func:`_composite`). Elsewhere
    ``(interior - face) * 0 + face`` is the face: the interior is not drawn there (the box's
    margin and the corners of a slanted opening: a third to half of the mouth's box).

    ``outline``: the box of the outline's pixels (:func:`_box_of` without margin; a pixel
    more for the mouth, whose coverage is blurred over 3 x 3). It holds both (the pixel set
    is filled where the outline's fixed-point vertices round to, the coverage counts samples
    strictly inside it), and so all of the coverage the mouth's thin-gap measure sums over a
    window (zeros beyond it, as at the box's edge); found without a pass over the pixels.
    ``alpha_c``: the soft edge's coverage, which the photo's blur spreads past the outline
    (the bounding box of its pixels above zero is added)."""
    x0, y0, x1, y1 = outline
    if alpha_c is not None:
        x, y, w, h = cv2.boundingRect((alpha_c != 0).view(np.uint8))
        if w > 0:
            x0, y0 = min(x0, box[0] + x), min(y0, box[1] + y)
            x1, y1 = max(x1, box[0] + x + w), max(y1, box[1] + y + h)
    return ((x0, y0, x1, y1),
            (slice(y0 - box[1], y1 - box[1]), slice(x0 - box[0], x1 - box[0])))


def _composite(out: np.ndarray, box: tuple[int, int, int, int], alpha: np.ndarray,
               hole: np.ndarray, interior: np.ndarray, shade: np.ndarray | None = None,
               inside: np.ndarray | None = None,
               margin: tuple[int, float] | None = None) -> None:
    """out[box] = alpha * interior + (1 - alpha) * face, face continued into ``hole`` (by
    ``inside`` (h, w, 3) when given: the soft edge's nearest lid or lip colour, else from the
    neighbours); ``shade`` (h, w) multiplies the face (the lips' inner edge).

    ``margin`` (rows, share): an open eye's upper lid on a sharp photo. In its first ``rows``
    the face continued into the hole takes the darker of the neighbours' colour and the
    interior's, by ``share``. A raised lid's lash line lies mostly inside the photo's
    opening: the eyeball layer carries it up with the lid (:mod:`gaze`'s bands) while the
    warped skin around the opening is the lighter lid above it; continued with that skin, the
    outline's partly covered (and its touched, uncovered) pixels along the raised lid
    alternated between the dark band and light skin: the lash line read as stitches (JAFFE
    anger and surprise, KL and YM at 1.5). Where the layer shows the white, the skin is the
    darker and stays. Not along the lower lid, whose margin is light (the iris would reach
    into it: a dark drip under the iris), nor for a closing eye (its margin is the lash line;
    what moves behind closed lids must not show through the pixels their outline touches)."""
    x0, y0, x1, y1 = box
    view = out[y0:y1, x0:x1]
    face = view.astype(np.float32)
    # (per-pixel weights spread over the 3 channels with cv2.merge: numpy's broadcasting of
    # an (h, w, 1) array over 3 channels is several times slower on these small boxes)
    if inside is not None:
        cv2.copyTo(np.asarray(inside, np.float32), hole.view(np.uint8), face)
    if shade is not None:
        face *= spread3(shade)
    if inside is None and np.count_nonzero(hole):
        # the face without the hole (zeros there: a masked copy, the same values as face times
        # a 0/1 weight) and the weights' box sums taken straight from the 0/1 byte mask
        keep = (~hole).view(np.uint8)
        # (box sums, not normalised; the arguments positional: keywords cost microseconds)
        num: np.ndarray = cv2.boxFilter(cv2.copyTo(face, keep), -1, (5, 5), None, (-1, -1),
                                        False, cv2.BORDER_REPLICATE)
        den = cv2.boxFilter(keep, cv2.CV_32F, (5, 5), None, (-1, -1), False,
                            cv2.BORDER_REPLICATE)
        fill = hole & (den > 0.5)
        np.maximum(den, 1e-6, out=den)
        num /= spread3(den)
        cv2.copyTo(num, fill.view(np.uint8), face)  # face[fill] = num[fill], in place
        if margin is not None and margin[0] > 0:
            k, share = margin
            top = face[:k]
            dark = np.minimum(top, interior[:k])
            if share < 1.0:
                dark -= top
                dark *= np.float32(share)
                dark += top
            cv2.copyTo(dark, fill[:k].view(np.uint8), top)
    res = interior - face  # alpha * interior + (1 - alpha) * face
    res *= spread3(alpha)
    res += face
    _to_uint8(res, view)


def _lower_margin(out: np.ndarray, maps: tuple[np.ndarray, np.ndarray,
                                                tuple[int, int, int, int]] | None,
                  ep: EyePlan, lids: tuple[np.ndarray, np.ndarray], sim: np.ndarray
                  ) -> tuple[int, int, int, int] | None:
    """A lowered lower lid's margin under the iris as the photo's margin under the white
    (:attr:`gaze.EyePlan.margin`, carried by the warp's backward ``maps``), added to ``out``
    in place; fading in over the lid's first pixel of motion under the iris centre. Returns
    the box written (the margin's box moved by the eye's similarity ``sim`` and grown by the
    lid's motion), or None.

    The warp carries the photo's lid margin down with the lid, and under the iris that margin
    holds the iris's blur: once the lid uncovers white there, it read as a grey-brown seam
    along the lid's new edge (the 4K bench face's surprise at 150 %). Runs before the
    eyeball's composite, whose soft edge continues the (cleaned) margin into the opening."""
    if maps is None or ep.margin is None:
        return None
    moved = ep.lowered(lids[1])
    if moved <= 0.0:
        return None
    share = smooth01_float(moved)
    # (the margin's box through the similarity, in Python floats: numpy's calls on a 4 x 2
    # array cost several times more)
    mh, mw = ep.margin.shape[:2]
    ax, ay = ep.margin_at
    (a, b, tx), (c, d, ty) = np.asarray(sim, np.float64).tolist()
    xs = [a * x + b * y + tx for x, y in ((ax, ay), (ax + mw, ay), (ax, ay + mh),
                                          (ax + mw, ay + mh))]
    ys = [c * x + d * y + ty for x, y in ((ax, ay), (ax + mw, ay), (ax, ay + mh),
                                          (ax + mw, ay + mh))]
    g = math.ceil(moved) + 2
    h, w = out.shape[:2]
    x0, y0 = max(math.floor(min(xs)) - g, 0), max(math.floor(min(ys)) - g, 0)
    x1, y1 = min(math.ceil(max(xs)) + g, w), min(math.ceil(max(ys)) + g, h)
    if x1 <= x0 or y1 <= y0:
        return None
    mx, my = box_maps(maps, (x0, y0, x1, y1), (ax, ay))
    carried = cv2.remap(ep.margin, mx, my, cv2.INTER_LINEAR)  # (zeros outside: the default)
    view = out[y0:y1, x0:x1]
    cv2.addWeighted(view, 1.0, carried, share, 0.0, view, cv2.CV_8U)  # rounded, saturated
    return (x0, y0, x1, y1)


def render_layers(face: Face, res: WarpResult, v: np.ndarray, extra: np.ndarray,
                  faps: np.ndarray, transforms: dict[str, np.ndarray]) -> WarpResult:
    """Composite the mouth interior and the eyeballs into a warp result (in place).

    ``v`` deformed vertices (V, 2), ``extra`` the deformed extra points (3.5, 3.6, 6.1-6.4),
    ``faps`` the clamped FAP vector, ``transforms`` :meth:`Face.layer_transforms` of ``v``.
    """
    out = res.image
    img = face.image
    jobs = []
    # how far each opening's outline moved (one gather for the three) and the irises
    idx_all, cuts = _opening_index(face.mesh)
    polys = v.take(idx_all, 0)  # (take: fancy indexing of rows costs several us more)
    # (over both coordinates of each loop at once: an axis-1 max of (n, 2) costs more)
    far = np.maximum.reduceat(np.abs(polys - _rest_loops(face)).ravel(), 2 * cuts).tolist()
    V = face.plan.n_vertices
    iris_far = [max(d) for d in np.abs(extra[:2] - face.plan.neutral[V:V + 2]).tolist()]  # 3.5, 3.6
    ends = [*cuts.tolist(), len(idx_all)]
    # ---- eyes
    state = None
    for k_open, name in enumerate(("eye_l", "eye_r")):
        poly = polys[ends[k_open]:ends[k_open + 1]]
        moved = far[k_open]
        eye_faps = np.count_nonzero(faps[_EYE_FAP_IDX[name]]) > 0
        iris_moved = iris_far[EXTRA_INDEX[name]] > _TOL
        sim = transforms[name]
        if not (moved > _TOL or eye_faps or iris_moved or not _is_identity(sim)):
            continue
        jobs.append(("eye", name, poly, sim, eye_faps or iris_moved, moved))
        if state is None and (eye_faps or iris_moved):
            lm = face.landmarks
            state = eye_state(face.plan, faps, np.array([lm.iris_left.r, lm.iris_right.r]))
    # ---- mouth
    # (its two lips as smooth arcs once a face is large enough for straight sides to show;
    # the eyes' lids too, later: samples per side for the three loops at once)
    split = splits(polys, _next_in_loop(tuple(ends[1:])), cuts, _CHORDS)
    poly = smooth_loop(polys[ends[2]:], _MOUTH_CORNERS, split[2])
    skull = transforms["mouth"]
    moved = far[2]
    if moved > _TOL or not _is_identity(skull):
        jobs.append(("mouth", "mouth", poly, skull, True, moved))
    if not jobs:
        return res
    lp = layer_plan(face)
    bbox = res.bbox
    drawn: dict[str, tuple[tuple[int, int, int, int], np.ndarray]] = {}
    # the three openings' extents at once (as :func:`_box` of each loop)
    lo_all = np.minimum.reduceat(polys, cuts).tolist()
    hi_all = np.maximum.reduceat(polys, cuts).tolist()
    slot = {"eye_l": 0, "eye_r": 1, "mouth": 2}
    # each eye's closure (1 - its area over the neutral one): the lash line is drawn from 0.6
    # on, and an open eye's upper lid margin continues its lash band (_composite's margin)
    closure = [0.0, 0.0]
    if jobs[0][0] == "eye":  # (the eyes' jobs come first)
        e = polys[:ends[2]].astype(np.float64)
        ex, ey = e[:, 0], e[:, 1]
        nx = _next_in_loop((ends[1], ends[2]))
        closure = (1.0 - 0.5 * np.abs(np.add.reduceat(ex * ey[nx] - ey * ex[nx], cuts[:2]))
                   / np.maximum([lp.eyes["eye_l"].area0, lp.eyes["eye_r"].area0], 1e-6)).tolist()
    # every opening's box, then their pixel sets and coverages at once (_opening_masks)
    # (an eye's pixel set follows its lids as smooth arcs on a large face, as the mouth's
    # does, once its sides pass EYE_CHORD_PX; the eye's own plans keep reading its 12
    # vertices)
    todo, outlines = [], []
    # (the mouth's coverage on a soft photo is blurred across its outline and its lip line
    # cleaned either side of it, each over about the photo's edge ramp: its box holds that
    # ramp, or the box's edge cut them off in a straight line across the lips: the 4K bench
    # face's fear at 150 % changed by up to 73 levels on the box's last row, 0 on the next)
    mouth_pad = 4 if lp.soft <= 1.0 else 4 + math.ceil(2.0 * lp.soft)
    for job in jobs:
        k_open = slot[job[1]]
        loop = job[2] if job[0] == "mouth" else smooth_loop(job[2], _EYE_CORNERS, split[k_open])
        if split[k_open] > 1:  # (the arcs reach past the loop's vertices)
            lo_all[k_open], hi_all[k_open] = loop.min(0).tolist(), loop.max(0).tolist()
        box = _box_of(lo_all[k_open], hi_all[k_open], out.shape,
                      mouth_pad if job[0] == "mouth" else 2)
        if box[2] > box[0] and box[3] > box[1]:
            todo.append((job, box))
            outlines.append(loop)
    masks = _opening_masks([(loop, box, job[5] > _TOL)
                            for (job, box), loop in zip(todo, outlines, strict=True)]
                           ) if todo else []
    for ((kind, name, poly, tf, active, moved), box), (hole, cov) in zip(todo, masks,
                                                                          strict=True):
        k_open = slot[name]
        # an outline that did not move keeps the photo's own edge pixels; the anti-aliased
        # coverage takes over within its first pixel of motion (no jump at small FAPs)
        alpha = hole.astype(np.float32)
        if cov is not None:
            t = min(moved, 1.0)
            if kind == "mouth":
                # a slit a pixel wide on a slant: its box-filtered coverage alternates from
                # pixel to pixel and the dark line reads dotted; a slightly wider filter
                cov = _blur(np.ascontiguousarray(cov), 0.6, 3)
            alpha += (t * t * (3.0 - 2.0 * t)) * (cov - alpha)
        lip_shade, margin = None, None
        alpha_c, inside = alpha, None  # (a soft photo's edge ramp replaces them: _soft_edge)
        if kind == "mouth":
            fade_in = _smoothstep1(min(moved, 1.0))
            # (on a soft photo no one-pixel inner-edge shade beside the soft edge's fade, which
            # is the lips' surface turning in: the two read as a drawn outline)
            rim, depth, lip_shade = _mouth_rim(out, box, hole, alpha, lp.mouth.mouth_nose,
                                               fade_in, with_shade=lp.soft <= 1.0)
            if lp.soft > 1.0:
                alpha_c, inside = _soft_edge(out, box, hole, alpha, lp.soft, float(fade_in),
                                             (depth, rim))
            # the interior drawn only where it shows (see _shown), embedded in the box
            # (a pixel more: the mouth's coverage was blurred over 3 x 3)
            sub, (ys, xs) = _shown(box, _box_of(lo_all[2], hi_all[2], out.shape, 1),
                                   alpha_c if lp.soft > 1.0 else None)
            interior = np.zeros((box[3] - box[1], box[2] - box[0], 3), np.float32)
            if sub[2] > sub[0]:
                interior[ys, xs] = lp.mouth.render(
                    sub, v, faps, tf, rim[ys, xs], depth[ys, xs],
                    np.ascontiguousarray(alpha[ys, xs]), grain_over(face, sub))
        else:
            ep = lp.eyes[name]
            k = EXTRA_INDEX[name]
            if active:
                assert state is not None  # computed when the first active eye job was queued
                r_new, p_new = (float(x) for x in state[k])
                shift = ep.gaze_shift(extra[k], tf)
            else:
                r_new, p_new, shift = ep.r_det, ep.r_det / 3.0, np.zeros(2)
            inv = cv2.invertAffineTransform(np.asarray(tf, np.float64))
            lids = ep.lid_frame(poly, tf, inv)
            fixed = _lower_margin(out, res.maps, ep, lids, tf)
            if fixed is not None:
                bbox = _union(bbox, fixed)
            if active or ep.lid_opening(poly, tf, lids) > _TOL:
                # the eyeball layer; it also continues the eye under a raised lid
                q = max(1, int(lp.soft // EYE_BLOCK_SOFT))
                if q > 1:  # (blocks upsampled over the box: drawn over all of it)
                    interior = ep.render(box, tf, shift, r_new, p_new, poly, lids, inv,
                                         lp.soft, q)
                else:  # drawn only where it shows (see _shown), embedded in the box
                    sub, (ys, xs) = _shown(box, _box_of(lo_all[k_open], hi_all[k_open],
                                                        out.shape, 0))
                    interior = np.zeros((box[3] - box[1], box[2] - box[0], 3), np.float32)
                    if sub[2] > sub[0]:
                        interior[ys, xs] = ep.render(sub, tf, shift, r_new, p_new, poly, lids,
                                                     inv, lp.soft, 1, box)
            else:  # the photo's own eye, moved with the corners (as the warp does)
                interior = photo_through(img, tf, box)
            if lp.soft > 1.0:  # (fading in with the outline's or the eyeball's first pixel)
                amount = max(moved, float(np.abs(shift).max()), 2.0 * abs(r_new - ep.r_det))
                alpha_c, inside = _soft_edge(out, box, hole, alpha, lp.soft,
                                             float(_smoothstep1(min(amount, 1.0))))
            elif closure[k_open] < 0.6:
                # an open eye on a sharp photo: its upper lid's margin continued dark
                # (_composite); the rows above the opening's mean height are the upper lid's
                # (``poly[:, 1].mean()``'s value: the sum in poly's type over the count in
                # float64, rounded to poly's type, without mean's Python layers)
                mean_y = poly.dtype.type(float(np.add.reduce(poly[:, 1])) / len(poly))
                margin = (int(round(float(mean_y))) - box[1],
                          min((0.6 - closure[k_open]) * 5.0, 1.0))
        _composite(out, box, alpha_c, hole, interior, lip_shade, inside, margin)
        if kind == "mouth":
            _clean_lip_line(out, box, poly, alpha, fade_in, lp.soft)
        else:
            # (the lash line is drawn from a closure above 0.6, checked with a margin before
            # its exact test in lash_line)
            lash = lp.eyes[name].lash_line(box, poly, lp.soft) if closure[k_open] > 0.59 \
                else None
            if lash is not None:  # a closing eye: one clean lash line where the lids meet
                la, col = lash
                x0, y0, x1, y1 = box
                o = out[y0:y1, x0:x1].astype(np.float32)
                la = la[..., None]
                _to_uint8(o + la * (col - o), out[y0:y1, x0:x1])
        drawn[name] = (box, hole)
        bbox = _union(bbox, box)
    if bbox is None or bbox == res.bbox:  # None: res.bbox is None and nothing was drawn
        return res
    return _rebox(res, bbox, drawn)


# ---------------------------------------------------------------------------- photo analysis
def _bright(patch: np.ndarray, skin_l: float) -> np.ndarray:
    """Teeth-like pixels: at least 0.8 of the skin's luminance, weakly coloured."""
    # (the channels' max / min pairwise: a reduction over an axis of 3 is several times slower)
    r, g, b = patch[..., 0], patch[..., 1], patch[..., 2]
    mx = np.maximum(np.maximum(r, g), b)
    mn = np.minimum(np.minimum(r, g), b)
    return (_lum(patch) >= 0.8 * skin_l) & ((mx - mn) < 0.35 * np.maximum(mx, 1.0))


def _photo_teeth(img: np.ndarray, poly: np.ndarray, skin_l: float) -> np.ndarray | None:
    """Median colour of the teeth visible in the photo's mouth opening, or None."""
    x0, y0 = np.floor(poly.min(0)).astype(int)
    x1, y1 = np.ceil(poly.max(0)).astype(int) + 1
    x0, y0 = max(x0, 0), max(y0, 0)
    patch = img[y0:y1, x0:x1].astype(np.float32)
    if patch.size == 0:
        return None
    sel = (_poly_mask(patch.shape[:2], poly, np.array([x0, y0])) > 0) & _bright(patch, skin_l)
    return median(masked_rows(patch, sel), axis=0) if sel.sum() >= 12 else None


def _own_interior(img: np.ndarray, poly: np.ndarray, lower_lip: np.ndarray, D: float,
                  skin_l: float, gum: np.ndarray, soft: float = 1.0):
    """What the photo shows inside its own mouth opening, split into skull and jaw parts.

    Per column of the opening: a run of teeth-like pixels starting at the top is the upper
    teeth (skull); everything below it (lower teeth, the lower lip's edge) follows the jaw;
    a column without teeth is split at its middle. Columns where the opening is a sliver (a
    closed mouth's lip line, at most two pixels) are flagged: they fade out as the lips part.
    Where the upper teeth start at the top, they are continued upwards
    and fade into the gum, for when the upper lip is raised. Returns the patch offset, masks
    (h, w, 2), colours (h, w, 6), whether the photo shows upper / lower teeth, the sliver
    weight per column (w,) and where the upper teeth were continued (h, w).
    """
    h, w = img.shape[:2]
    m, up_m = 3, int(np.ceil(0.6 * D)) + 3
    side_m = m + int(np.ceil(0.3 * np.ptp(poly[:, 0])))  # room for the teeth continued sideways
    x0 = int(max(0, np.floor(poly[:, 0].min()) - side_m))
    y0 = int(max(0, np.floor(poly[:, 1].min()) - up_m))
    x1 = int(min(w, np.ceil(poly[:, 0].max()) + side_m + 1))
    y1 = int(min(h, np.ceil(poly[:, 1].max()) + m + 1))
    off = np.array([x0, y0], np.float64)
    patch = img[y0:y1, x0:x1].astype(np.float32)
    ph, pw = patch.shape[:2]
    binary = _poly_mask((ph, pw), poly, off) > 0
    cov = _coverage(poly, (x0, y0, x1, y1), dilate=1)
    bright = binary & _bright(patch, skin_l)
    split, weight, first, gap, col_top, sliver = _teeth_columns(binary, bright)
    ok = np.flatnonzero(~np.isnan(split))
    kern = np.ones(5) / 5.0
    if len(ok):
        split = np.interp(np.arange(pw), ok, split[ok])
        # a smooth edge along the teeth's tips (upper envelope over 2 kb + 1 columns, then a
        # mean): a ragged per-column edge shows as dark specks once the jaw part moves away,
        # and the dark gap between two teeth (no teeth-like pixel in its columns) would be
        # split at the opening's middle and slide down with the jaw: on a large or soft photo
        # the gaps are several pixels wide (the 4K bench face's: ~10), so kb follows the
        # teeth's scale and the photo's blur (kb = 1 on a face 44 px between the eyes)
        kb = max(1, int(round(GAP_BRIDGE_D * D + 0.5 * soft)))
        split = sliding_window_view(pad_edge(split, kb), 2 * kb + 1).max(1)
        km = np.ones(2 * kb + 3) / (2 * kb + 3)
        split = np.convolve(pad_edge(split, kb + 1), km, mode="valid")
    else:
        split[:] = ph
    ys = np.arange(ph, dtype=np.float64)[:, None]
    up = clamp(split[None, :] - ys + 0.5, 0.0, 1.0)
    own_up = cov * up * weight[None, :]
    own_low = cov * (1.0 - up) * weight[None, :]
    rgb_up = patch.copy()
    ext = first >= 0
    ext_mask = np.zeros((ph, pw), np.float32)
    if ext.sum() >= 3:
        # every column between the outermost ones whose teeth start at the top is continued
        # (a column in between takes the top teeth colour of its nearest such column)
        cols = np.flatnonzero(ext)
        span = np.arange(cols.min(), cols.max() + 1)
        span = span[binary[:, span].any(0)]
        near = cols[np.abs(span[:, None] - cols[None, :]).argmin(1)]
        full = np.zeros(pw)
        full[span] = 1.0
        ext_w = np.convolve(np.concatenate((_ZEROS2, full, _ZEROS2)), kern, mode="valid")
        # the crown goes on above the opening for what the photo does not show of it (its
        # visible height in the middle columns), then fades into the gum
        fade = max(GUM_FADE * D, 1.0)
        mid = span[np.abs(span - 0.5 * (span[0] + span[-1])) <= max(0.15 * len(span), 1.0)]
        seen = float(median(split[mid] - col_top[mid])) if len(mid) else 0.0
        hidden = max(CROWN * D - seen, 0.0)
        # (all columns at once: the rows above each column's opening)
        top = col_top[span]  # first row of the opening in each column
        yi, ji = np.nonzero(np.arange(ph)[:, None] < top[None, :])
        j = span[ji]
        g = smooth01((top[ji] - yi - hidden) / fade)[:, None]
        crown = _crown_colours(patch, bright, first, split)
        rgb_up[yi, j] = (1.0 - g) * crown[near[ji]] + g * gum
        own_up[yi, j] = np.maximum(own_up[yi, j], ext_w[j])
        ext_mask[yi, j] = 1.0
        # the photo's first rows of teeth under its lip are in the lip's shadow (the renderer
        # draws that shadow where the lip is): lightened towards the crown colour, so that
        # they do not stay as a dark line across teeth whose lip has risen
        r = max(LIP_SHADOW_ROWS * D, 2.0)
        yi, ji = np.nonzero((np.arange(ph)[:, None] >= top[None, :])
                            & (np.arange(ph)[:, None] < top[None, :] + r))
        j = span[ji]
        t = smooth01(1.0 - (yi - top[ji] + 0.5) / r)[:, None]
        c = crown[near[ji]]
        rgb_up[yi, j] = np.maximum(rgb_up[yi, j], rgb_up[yi, j] + t * (c - rgb_up[yi, j]))
        ext_mask[yi, j] = np.maximum(ext_mask[yi, j], t[:, 0])
    below = ys >= split[None, :]
    has_low = int((bright & below & gap[None, :]).sum()) >= 12
    if not has_low:
        # no lower teeth: teeth-like pixels just under the split are the upper teeth's edge
        # (they stay with the skull, not a bright sliver riding on the lower lip); further
        # down they are the lower lip's highlights and ride with it
        tip = bright & below & (ys < split[None, :] + 1.5)
        own_up[tip] = np.maximum(own_up[tip], (cov * weight[None, :])[tip])
        own_low[tip] = 0.0
        # a thin run (2 px, 0.08 D) under the upper teeth is the lower lip's inner edge,
        # which the warp already draws: carried down with the jaw it would show as a bright
        # line across the opening
        thin = (own_low > 0.5).sum(0) <= max(2.0, 0.08 * D)
        own_low[:, thin] = 0.0
    if ext.sum() >= 3:
        own_up, own_low, rgb_up, ext_mask = _extend_sideways(
            own_up, own_low, rgb_up, ext_mask, split, np.flatnonzero(ext))
    # (stacked straight into float32: no float64 stack, no second copy)
    own = np.concatenate([own_up[..., None], own_low[..., None]], axis=2, dtype=np.float32)
    sliver = np.convolve(pad_edge(sliver.astype(np.float64), 2), kern, mode="valid")
    # (the two float32 colour arrays side by side by cv2.merge: numpy's concatenation along
    # the channels writes every 3 values apart, several times slower)
    rgb = cv2.merge([np.asarray(rgb_up, np.float32), patch])
    return (off, own, rgb, bool(ext.sum() >= 3), has_low, sliver.astype(np.float32), ext_mask)




#: Rows (in D) of the photo's upper teeth under its lip lightened towards the crown colour
LIP_SHADOW_ROWS = 0.08
#: the widest dark gap between two of the photo's own teeth that their row bridges, in units
#: of D (mouth-nose distance), plus half the photo's edge ramp (see _own_interior)
GAP_BRIDGE_D = 0.02


def _crown_colours(patch: np.ndarray, bright: np.ndarray, first: np.ndarray,
                   split: np.ndarray) -> np.ndarray:
    """(w, 3) per column: the mean colour of its upper teeth (the teeth-like pixels from the
    run's first row to the tips, ``split``), what the crown is continued upwards with. The
    run's first pixel alone (right under the photo's lip) is the lip's shadow, a gum papilla
    or an embrasure's dark corner as often as tooth: continued upwards, every column's own
    first pixel drew the crowns as vertical stripes of pink, grey and white."""
    ph = patch.shape[0]
    ys = np.arange(ph)[:, None]
    run = (bright & (ys >= first[None, :]) & (ys < split[None, :])
           & (first >= 0)[None, :]).astype(np.float32)
    # (the run's mean: a median over every column of a large face's patch cost ~10 ms; a
    # column whose teeth start at the top has a run, the others are never read: zeros)
    return np.einsum("yx,yxc->xc", run, patch, dtype=np.float64) \
        / np.maximum(run.sum(0), 1.0)[:, None]


def _teeth_columns(binary: np.ndarray, bright: np.ndarray):
    """Per column of the mouth opening ``binary`` (h, w) with teeth-like pixels ``bright``
    (inside it): ``split`` (w,) the row between the skull and jaw parts (NaN without
    opening), ``weight`` 1 where the column has opening, ``first`` the row where teeth start
    at the opening's top (at most a pixel below it; else -1), ``gap`` whether opening is left
    below the teeth, the opening's first row ``col_top`` and whether it is a ``sliver`` (at
    most two pixels). All columns at once (see :func:`_own_interior`)."""
    ph, pw = binary.shape
    has = binary.any(0)
    top = np.argmax(binary, 0)
    bot = ph - 1 - np.argmax(binary[::-1], 0)
    weight = has.astype(np.float64)
    sliver = has & (bot - top < 2)
    col_top = np.where(has, top, 0).astype(np.int64)
    # bridge one-pixel dips of the teeth inside each column's opening (``bright`` is within
    # it, so a dip's two neighbours are too)
    b = bright.copy()
    b[1:-1] |= bright[:-2] & bright[2:]
    teeth = has & b.any(0)
    f = np.argmax(b, 0)  # first teeth row
    # the first run of teeth ends before the first non-teeth row below its start
    yy = np.arange(ph)[:, None]
    after = np.vstack([~b & (yy > f[None, :]), np.ones((1, pw), bool)])
    e = np.argmax(after, 0) - 1  # the run's last row
    # the skull part ends with the teeth (their tips), also where they reach the lower lip:
    # the lip's darker inner edge rides with the jaw, not with the teeth
    split = np.where(teeth, e + 0.5, 0.5 * (top + bot))
    split[~has] = np.nan
    gap = teeth & (e + 1 <= bot)
    first = np.where(teeth & (f - top <= 1), f, -1)
    return split, weight, first, gap, col_top, sliver


def _extend_sideways(own_up: np.ndarray, own_low: np.ndarray, rgb_up: np.ndarray,
                     ext_mask: np.ndarray, split: np.ndarray, cols: np.ndarray):
    """Continue the photo's upper teeth row sideways past its outermost teeth.

    A wider smile than the photo's must not end the photo's teeth in a dark corner with drawn
    teeth beside them: each column beyond the outermost teeth column (the photo's dark mouth
    corner included) takes the column mirrored about it (the row's own texture: the next
    teeth outwards look like the last ones), shifted vertically so that the tips follow the
    line of the outer teeth's tips (the smile arc), slightly darker with each column (the
    arch turns away from the light; the renderer darkens the corners further). The jaw part
    in those columns is dropped (the lower teeth and cavity are drawn there).
    """
    ph, pw = own_up.shape
    lo, hi = int(cols.min()), int(cols.max())
    span = hi - lo + 1
    if span < 4:
        return own_up, own_low, rgb_up, ext_mask
    k = max(2, span // 6)
    # only teeth (rows above the split) are mirrored, with their upward continuation
    ys = np.arange(ph, dtype=np.float64)[:, None]
    teeth_a = own_up * clamp(split[None, :] - ys + 1.0, 0.0, 1.0)
    rows = np.arange(ph)[:, None]
    for side in (-1, 1):
        edge = lo if side < 0 else hi
        tgt = np.arange(0, lo) if side < 0 else np.arange(hi + 1, pw)
        if not len(tgt):
            continue
        d = np.abs(tgt - edge)
        src = edge - side * (d % (span - 1))  # mirrored into the teeth row (repeating)
        # per column outwards, at most a gentle rise (the last teeth's tips turn up steeply
        # into the photo's raised corner; extrapolated, the row would leave the opening)
        slope = float(clamp((split[edge] - split[edge - side * k]) / k, -0.2, 0.2))
        dy = np.round(split[edge] + slope * d - split[src]).astype(np.int64)
        r = clamp(rows - dy[None, :], 0, ph - 1)
        dim = (1.0 - 0.35 * smooth01(d / max(0.5 * span, 1.0)))[None, :]
        cols_t = slice(0, lo) if side < 0 else slice(hi + 1, pw)  # tgt, as a slice
        own_up[:, cols_t] = gather_px(teeth_a, r, src[None, :])
        own_low[:, cols_t] = 0.0
        # (float64 products rounded into the float32 colours, without a float64 copy)
        np.multiply(gather_px(rgb_up, r, src[None, :]), dim[..., None], out=rgb_up[:, cols_t],
                    casting="same_kind")
        ext_mask[:, cols_t] = 1.0
    return own_up, own_low, rgb_up, ext_mask


def _opening_masks(items: list[tuple[np.ndarray, tuple[int, int, int, int], bool]]
                   ) -> list[tuple[np.ndarray, np.ndarray | None]]:
    """The pixels ``warp`` gives to each of several openings (outline, box, coverage wanted;
    the same fill call and rule: bool (h, w) 0 / 1 bytes) and, where asked, their
    :func:`_coverage`, all at once: their boxes side by side on one canvas each, so that one fill,
    one erosion and one reduction serve all of them. The same values as one call per opening:
    every outline keeps its own fixed-point vertices, moved by whole pixels (whole samples),
    and each box's margin (>= 2 px around its outline) keeps the fills, the erosion and the
    4 x 4 sample blocks of neighbouring boxes apart. Returns views into the canvases."""
    ss = 4
    ws = [b[2] - b[0] for _, b, _ in items]
    hs = [b[3] - b[1] for _, b, _ in items]
    cols = list(itertools.accumulate([0, *ws[:-1]]))
    lens = [len(p) for p, _, _ in items]
    ends = list(itertools.accumulate(lens))
    parts = list(zip([0, *ends[:-1]], ends, strict=True))  # (slices: np.split costs more)
    P = np.concatenate([p for p, _, _ in items])
    # per vertex its box's origin and canvas column (one row per opening, repeated)
    per = np.array([(b[0], b[1], c) for (_, b, _), c in zip(items, cols, strict=True)]
                   ).repeat(lens, 0)
    org, col = per[:, :2], per[:, 2]
    # the pixel sets (as warp fills an opening: float32 outline minus box origin, 4 fractional
    # bits), moved to the box's columns by whole pixels
    q = np.rint((P.astype(np.float32) - org.astype(np.float32)) * (1 << _SHIFT)).astype(np.int32)
    q[:, 0] += col << _SHIFT
    m = np.zeros((max(hs), sum(ws)), np.uint8)
    cv2.fillPoly(m, [q[a:b] for a, b in parts], 1, cv2.LINE_8, _SHIFT)
    mb = m.view(bool)  # (viewed as bool once, on the contiguous canvas: cheaper than per box)
    holes = [mb[:h, c:c + w] for h, w, c in zip(hs, ws, cols, strict=True)]
    if not any(want for _, _, want in items):
        return [(hole, None) for hole in holes]
    # the coverages (as _coverage: the sample grid, 4 fractional bits, from float64)
    k = 16.0 * ss
    qc = np.rint(P.astype(np.float64) * k + (8.0 * ss - 8.0 - k * org)).astype(np.int32)
    qc[:, 0] += col * (16 * ss)
    big: np.ndarray = np.zeros((max(hs) * ss, sum(ws) * ss), np.uint8)
    cv2.fillPoly(big, [qc[a:b] for a, b in parts], 255, cv2.LINE_8, 4)
    big = cv2.erode(big, _CROSS)
    cov = _area4_coverage(big, sum(ws), max(hs))
    return [(hole, cov[:h, c:c + w] if want else None)
            for hole, (_, _, want), h, w, c in zip(holes, items, hs, ws, cols, strict=True)]


def _area4_coverage(big: np.ndarray, w: int, h: int) -> np.ndarray:
    """``cv2.resize(big, (w, h), interpolation=cv2.INTER_AREA) / 255`` (float32, as
    :func:`_coverage` computes it) of a 0 / 255 sample canvas ``big`` (4 h, 4 w) uint8: the
    same values through two 2 x reductions and a table (:func:`_area4_table`), when this
    OpenCV's reductions allow it. OpenCV 5's 4 x area reduction takes a generic path, ~8 x
    slower than two 2 x ones (the 4K bench face's canvas, 1.07 M samples: 0.37 ms against
    0.05 ms); the two round twice, which the table undoes."""
    table = _area4_table()
    if table is None:
        small = cv2.resize(big, (w, h), None, 0, 0, cv2.INTER_AREA)
        return np.multiply(small, np.float32(1.0 / 255.0), dtype=np.float32)
    half = cv2.resize(big, (2 * w, 2 * h), None, 0, 0, cv2.INTER_AREA)
    return cv2.LUT(cv2.resize(half, (w, h), None, 0, 0, cv2.INTER_AREA), table)


@lru_cache(maxsize=1)
def _area4_table() -> np.ndarray | None:
    """(256,) float32: for each value two 2 x ``INTER_AREA`` reductions give a 4 x 4 block of
    0 / 255 samples, the one 4 x reduction's value of the same block over 255 (the float32
    product :func:`_coverage` takes); None when some value comes from blocks whose 4 x
    values differ (then :func:`_area4_coverage` reduces 4 x at once). Found once per process
    on all 65536 blocks: they differ by at most 1 in 9 to 12 samples of 16 (the 2 x
    reductions round each quarter), which the 4 x value depends on only through their
    count."""
    bits = ((np.arange(1 << 16, dtype=np.uint32)[:, None] >> np.arange(16)) & 1)
    blocks = (bits.astype(np.uint8) * 255).reshape(256, 256, 4, 4).transpose(0, 2, 1, 3) \
        .reshape(1024, 1024)
    one = cv2.resize(blocks, (256, 256), None, 0, 0, cv2.INTER_AREA).ravel()
    two = cv2.resize(cv2.resize(blocks, (512, 512), None, 0, 0, cv2.INTER_AREA), (256, 256),
                     None, 0, 0, cv2.INTER_AREA).ravel()
    value = np.full(256, -1, np.int32)
    value[two] = one
    if np.any(value[two] != one):  # (a value from blocks of different 4 x values)
        return None
    value[value < 0] = np.arange(256)[value < 0]  # (values two reductions never give)
    table = np.multiply(value.astype(np.uint8), np.float32(1.0 / 255.0), dtype=np.float32)
    table.setflags(write=False)
    return table


def _coverage(poly: np.ndarray, box: tuple[int, int, int, int], ss: int = 4,
              dilate: int = 0) -> np.ndarray:
    """Fraction (h, w) float32 of each pixel of ``box`` covered by the polygon (supersampled).

    ``dilate`` grows the polygon by that many pixels first (used for the photo's own interior).
    """
    x0, y0, x1, y1 = box
    h, w = y1 - y0, x1 - x0
    if h <= 0 or w <= 0:
        return np.zeros((max(h, 0), max(w, 0)), np.float32)
    big: np.ndarray = np.zeros((h * ss, w * ss), np.uint8)
    # sample grid, 4 fractional bits: ((p - box origin) + 0.5) * ss - 0.5, times 16, in one
    # product and one sum (exact in float64 for power-of-two ss, as the step-by-step form)
    k = 16.0 * ss
    q = np.asarray(poly, np.float64) * k + (8.0 * ss - 8.0 - k * np.array([x0, y0]))
    cv2.fillPoly(big, [np.rint(q).astype(np.int32)], 255, cv2.LINE_8, 4)
    # OpenCV also fills every sample the outline touches: remove that rim (a zero-area polygon,
    # e.g. closed lids, then covers nothing)
    if not dilate:
        big = cv2.erode(big, _CROSS)
    else:
        k = 2 * dilate * ss + 1
        big = cv2.dilate(big, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k)))
    if ss == 4:
        return _area4_coverage(big, w, h)
    small = cv2.resize(big, (w, h), interpolation=cv2.INTER_AREA)
    return np.multiply(small, np.float32(1.0 / 255.0), dtype=np.float32)


def _rebox(res: WarpResult, bbox: tuple[int, int, int, int],
           drawn: dict[str, tuple[tuple[int, int, int, int], np.ndarray]]) -> WarpResult:
    """The result with a grown ``bbox``; the opening masks re-embedded in it."""
    x0, y0, x1, y1 = bbox
    shape = (y1 - y0, x1 - x0)
    masks = {}
    for key, local in (("mouth", res.mouth_local), ("eyes", res.eyes_local)):
        m = np.zeros(shape, bool)
        if local is not None and res.bbox is not None:
            a0, b0, a1, b1 = res.bbox
            m[b0 - y0:b1 - y0, a0 - x0:a1 - x0] = local
        masks[key] = m
    for name, (box, hole) in drawn.items():
        key = "mouth" if name == "mouth" else "eyes"
        a0, b0, a1, b1 = box
        masks[key][b0 - y0:b1 - y0, a0 - x0:a1 - x0] |= hole
    return WarpResult(res.image, bbox, masks["mouth"], masks["eyes"], res.maps,
                      res.interpolation)
