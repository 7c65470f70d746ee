"""Skin creases where the deformation compresses the skin (SPEC §7.3). No Qt.

A geometry-only warp moves the skin but never folds it. This module adds the folds an
expression makes, procedurally (no example images): nasolabial folds, crow's feet, horizontal
forehead lines, vertical glabellar furrows, nose-bridge wrinkles and the nose's side wrinkles.

* **Where.** Each fold is a polyline laid out once per face on the photo's mesh, from its
  feature points and vertices (face frame, units of the inter-ocular distance). Every sample
  of it is stored as barycentric coordinates of the mesh triangle it lies in, so on the
  deformed mesh it moves with the face.
* **How strong.** Skin folds where it is compressed across the fold line. Per sample, the
  linear part ``A`` of the affine map of the triangles around it (deformed vs photo mesh)
  gives the new spacing ``det(A) / |A t|`` of skin lines parallel to the fold (``t`` its
  tangent; shear along the fold does not count); the compression ``c = max(0, 1 - spacing)``
  sets the strength ``depth * (1 - exp(-(c / c0)^2))``: zero at
  rest (and for pure stretching, rotation or translation), growing smoothly, saturating.
  It fades out towards the fold's ends and is smoothed along the line.
* **How it looks.** A multiplicative ratio image (SPEC §7.2-7.3), so the photo's own texture
  and light stay: a dark Gaussian line (width in units of the inter-ocular distance), a
  slightly lighter, broader ridge beside it, on colour photos darkened slightly towards red
  (as folds look), weighted by how skin-like each pixel is (hair, brows and eyes are spared).
  It is evaluated only in a small box around each active fold: the line is splatted
  (bilinear, sub-pixel) into the box and blurred with OpenCV.

* **The photo's own folds.** A photo that smiles has folds of its own that the warp carries
  into every expression. Where the target spreads the skin across a fold relative to the
  photo's mesh, by the share of what the photo's neutral mesh spreads it
  (:func:`unfold_strength`), the fold's valley is lifted to the skin level either side of it
  (:func:`_unfold_draw`: a closing of the image smoothed along the fold, as a per-channel gain >= 1,
  so the skin's grain and colour stay and nothing darkens), in a band centred on the valley the
  photo actually shows near the laid-out line (:func:`_own_valleys`, found once per face); the
  photo's own expression is left exactly as it is.

:func:`apply_creases` runs after :func:`render_layers`. A zero FAP vector gives no crease.
"""

from __future__ import annotations

import functools
import itertools
import math
import time
import weakref
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal, cast, overload

import cv2
import numpy as np

try:  # (the compiled function np.convolve calls, without its Python wrapper: numpy 2.x)
    from numpy._core.multiarray import correlate as _correlate
except ImportError:  # another numpy: its public wrapper, the same values
    _correlate = np.correlate

from .fitting import (
    box_medians,
    catmull_rom,
    clamp,
    clip,
    interp,
    is_grey,
    linspace,
    luminance,
    median,
    pad_edge,
    smooth01,
    smooth01_float,
)
from .gaze import spread3, zero_alpha
from .layers import _blur, _rebox, _union, layer_plan
from .lipseal import sealed_box
from .warp import WarpResult, box_maps

if TYPE_CHECKING:
    from .face import Face, FapInput

#: how far below the lower lid its furrow lies (inter-ocular distances; JAFFE smiles' dip
#: 0.08 IOD below the detected lid, whose skin the cheek raise lifts)
LID_FURROW = 0.10
#: per-channel weights of a darkening on a colour photo (R, G, B): folds and shadows on skin
#: turn darker towards red (grey photos: 1, 1, 1)
SHADOW_TINT = (0.8, 1.0, 1.12)
#: the mentolabial groove (kind "chin"): its half-length over the mouth's width, and how far
#: (IOD) its ends curve up, following the chin boss's round top (JAFFE's angry grooves run
#: across the lower lip's width: 0.34 and 0.05 drew a short dash under the lip's middle, 0.68 x
#: the real groove's depth 0.16-0.24 IOD either side; tests/test_creases.py)
CHIN_HALF_W = 0.5
CHIN_CURVE = 0.08
#: the knitted brows' shade (kind "knit", see STYLES): how far (IOD) it reaches above the
#: inner brow ends and below them (on the neutral mesh; the lowered brows carry it down)
KNIT_SPAN = (0.18, 0.08)
#: and how far either side of the middle its outermost lines lie, and their number
KNIT_X, KNIT_N = 0.19, 9
#: where its drive, the skin's vertical compression, is read (IOD from the glabella's middle
#: and the inner brow ends' height: below and beside them, towards the nasal root)
KNIT_PROBES = ((-0.2, 0.1), (0.2, 0.1), (-0.15, 0.12), (0.15, 0.12))
#: below this darkening (fraction) a fold is not drawn (2 grey levels on white)
_MIN_STRENGTH = 0.008
#: compression below this is float rounding (float32 vertices), not a fold
_C_TOL = 1e-4


@dataclass(frozen=True)
class FoldStyle:
    """Look of one kind of fold (lengths in inter-ocular distances)."""

    sigma: float  # Gaussian half-width of the dark line
    depth: float  # darkening at full strength (fraction of the pixel value)
    c0: float  # compression across the line that gives 63 % of ``depth``
    ridge: float  # brightening of the ridge beside it, relative to ``depth`` (< 0: a shadow)
    ridge_off: float  # ridge distance from the line (in sigmas; sign = side)
    probe: float  # distance of the compression probes either side of the line
    spread: float = 0.5  # share of the fold's strongest compression given to the whole line
    dead: float = 0.0  # compression that does not fold yet (subtracted first)
    # -1: the fold deepens where the skin across it is spread relative to along it (the
    # mentolabial sulcus: in 2-D the lower lip pushed up over the still chin spreads the skin
    # between them, where in 3-D the chin boss bulges and the groove above it deepens); the
    # measure is 1 under any similarity, so a scaled or turned face is no pout (_spread)
    sign: float = 1.0
    # True: the fold is driven by how far the skin at its probes is pushed up towards the eye
    # (IOD, relative to the eye's corners, beyond the photo's mesh) instead of by compression:
    # the cheek raiser lifts the skin under the eye nearly rigidly in the mesh, while the real
    # lower lid, held by the eyeball, lets it bunch into a roll and a furrow (_lift_push)
    lift: bool = False
    # compression added per unit of brow effort (:func:`_brow_effort`: the inner brows raised
    # (AU1) while drawn together (AU4), as in fear and sadness), which the mesh does not show:
    # the corrugator and the medial frontalis bunch the skin between the brows against each
    # other, where the landmarks move little (JAFFE fear's inner brows rise 0.04 IOD and
    # close in 0.04 IOD, yet its glabellar lines are the deepest of all six expressions)
    effort: float = 0.0
    # > 0: the brow effort drives the middle of each line only, as a Gaussian of this
    # half-width (share of the line's length) about its middle (the medial frontalis, AU1,
    # folds the central forehead; the lateral part, AU2, is not in the effort)
    effort_mid: float = 0.0
    # compression added per unit of brow effort times the upper lids' raise (AU5, see
    # :func:`_add_lid_effort`), along the whole line: fear's wide eyes come with the whole
    # frontalis working against the brow lowerer, where sadness's lowered lids do not
    effort_lid: float = 0.0
    # > 0: the fold's push (FoldStyle.lift) counts only as far as the inner brows are lowered
    # below rest (:func:`_frown_gate`, this the lowering, in inner eye corners' distances,
    # beyond :data:`_FROWN_DEAD`, over which the gate opens): the nose wrinkler (AU9) lifts the
    # cheek beside the nose wing and pulls the brow heads down with the skin of the nose, where
    # a smile's cheek raiser (AU6) lifts the cheek under brows that stay and anger's brow
    # lowerer (AU4) lowers the brows over a cheek that stays (the mesh moves the nose itself
    # rigidly in all three). On a photo with its own expression such a fold's push is also
    # measured from the neutral mesh, not the photo's (_fast: a smiling photo's raised cheek
    # brings no nose wrinkles to carry)
    frown: float = 0.0


STYLES: dict[str, FoldStyle] = {
    # JAFFE's smiles: the nasolabial valley across the middle of the laid-out line, 0.143 of its
    # shoulders' level below them (median of 40 folds; 0.04 on the neutral photos, p90 0.57).
    # Depth 0.17 / c0 0.38 drew 0.027 at joy 100 % on the ten neutral faces (a smile without
    # its folds); tests/test_creases.py measures it too.
    # Its cross-section (31 smiles, MediaPipe's nose wing to mouth corner, 0.3-0.45 of the way
    # down, profiles +-0.2 IOD aligned on their minimum, over the cheek 0.12-0.2 IOD out): a
    # valley whose nose side stays in shadow (0.93 of the cheek at 0.075-0.1 IOD in, 0.90 at
    # 0.05) and whose cheek side has no highlight (0.91-0.99 at 0.05-0.1 out). The line with a
    # light ridge 2.6 sigma out on the cheek side drew the nose side at 0.96-0.99 and the cheek
    # side 8 % above the cheek (1.08: a scratch with a bright edge, read as drawn); with a
    # shadow of half the line's depth 1.5 sigma in on the nose side instead, 0.96 0.97 0.93 in
    # and 1.02-1.05 out (the photo's own light there: 1.01-1.03 without creases). The depth
    # (tests/test_creases.py's measure, ours over real): 0.90 (1.07 before)
    "nasolabial": FoldStyle(sigma=0.026, depth=0.17, c0=0.22, ridge=-0.5, ridge_off=-1.5,
                            probe=0.07, spread=0.75),
    # the upper nasolabial furrow beside the nose wing. It lies on the nasolabial line's upper
    # part and is the same furrow: the darker of the two is drawn (_twins), not their sum,
    # with the nasolabial group's style (sigma and ridge here are that one's).
    # JAFFE (valley across the line's middle, 0.06 IOD window): disgust 0.172 (median of 40
    # photos; 0.086 on the neutral ones), joy 0.247, anger 0.108. Real disgust deepens it with
    # the upper lip barely raised (its red's top edge -0.005 IOD, median of 29) and real anger,
    # whose mouth rises with the chin and squeezes this skin almost as much, hardly at all: the
    # furrow follows the nose wrinkler / cheek raiser (AU9, AU6) bunching the cheek against the
    # nose wing, not the lip's landmarks. Driven by the cheek beside the nose wing pushed up
    # towards the eye (FoldStyle.lift; probes 0.10-0.16 IOD out from the wing): anger 0.001,
    # disgust 0.017, joy 0.028 IOD (median of the ten JAFFE meshes). Driven before by the skin
    # between the wing and the lip squeezed vertically (dead 0.08, c0 0.05: anger 0.10,
    # disgust 0.14), disgust reached its depth only with the upper lip's sides curled up 0.035
    # IOD, a heart-shaped pout no real photo shows (and 0.23 x the real depth once the lip was
    # raised as in the photos; anger 0.98 x, disgust 1.01 x with the curl). Now (c0 0.0095 on
    # the push) disgust 1.07 x real (150 %: 0.21, real p90 0.54), anger 0.73 x (0.079: its
    # photos' own valley; real anger adds 0.02 to the neutral's), joy 1.14 x as before
    "upper_lip": FoldStyle(sigma=0.026, depth=0.21, c0=0.0095, ridge=-0.5, ridge_off=-1.5,
                           probe=0.07, lift=True),
    "crow": FoldStyle(sigma=0.010, depth=0.12, c0=0.15, ridge=0.25, ridge_off=2.2,
                      probe=0.05),
    # the lower lid's furrow under a felt smile's raised cheek (AU6): the skin below the lid
    # rolls up into a bulge with a crease beneath it. JAFFE's ten women, the vertical profile
    # under the lower lid (iris column, over the cheek below): their neutral photos rise
    # smoothly 0.65 0.74 0.78 0.81 0.86 at 0.04-0.12 IOD, their smiles roll 0.73 0.75 then dip
    # 0.73 0.77 0.82 at 0.08-0.12; the renders of joy kept the smooth rise (0.78 0.85 0.88:
    # "the eyes are not smiling", the blind raters' most frequent word on joy); with this fold
    # 0.74 0.74 0.76 0.80 0.84 (disgust: real 0.73 0.76 0.76 0.80 0.83, ours 0.75 0.75 0.77
    # 0.81 0.85; tests/test_creases.py). When joy's lower lids and cheeks were lowered to the
    # real smiles' rise, the push under the lids halved and the fold faded (0.73 0.74 0.76 0.81
    # 0.85): c0 0.03 -> 0.012 with depth 0.16 -> 0.17 draws it at the push a real smile gives.
    # The six presets' profiles against their real photos' (two a woman), largest difference:
    # joy 0.049 -> 0.023, sadness 0.037 -> 0.029, fear 0.032 -> 0.029, surprise 0.027 (no
    # push), anger 0.040 -> 0.048, disgust 0.023 -> 0.038 (its strong push now saturates)
    "lower_lid": FoldStyle(sigma=0.025, depth=0.17, c0=0.012, ridge=0.45, ridge_off=2.2,
                           probe=0.05, lift=True),
    # JAFFE's ten surprised photos: the forehead's row profile dips 0.055 below its shoulders
    # (median; 0.03 on their neutral photos, p90 0.20). Depth 0.12 / c0 0.25 drew 0.020 at
    # 100 % (fainter than the photos' own texture); now 0.052 at 100 %, 0.105 at 150 %.
    # Fear and sadness raise the inner brows (AU1) while drawing them together: the mesh
    # barely compresses the forehead, and their central forehead lines (tests/test_creases.py,
    # fine lines x +-0.3 IOD, 0.55-0.95 IOD above the eyes, x 1000 over the neutral photo:
    # real median fear 4.1, sadness 2.2) were drawn 0.84 and 0.81. The brow effort drives
    # the lines' middle (a Gaussian of 0.22 of their length): 2.9 and 2.3 (row-profile dip
    # at 100 %: fear 0.020 -> 0.028, real 0.038; sadness 0.021 -> 0.027, real 0.025; at
    # 150 % 0.043 and 0.035, under the real p90 0.157 and 0.040); surprise has no effort.
    # Real fear folds the forehead across its width too (fine lines x +-0.7 IOD: fear 7.5,
    # sadness 1.7; ours 1.9, 1.6), though its outer brows stay down: the effort times the
    # upper lids' raise (effort_lid, :func:`_add_lid_effort`) drives the whole lines: fear's
    # dip 0.040 at 100 % (real median 0.038), 0.073 at 150 % (p90 0.157); wide 3.9, central
    # 7.4 (real p90 28.5); sadness unchanged
    "forehead": FoldStyle(sigma=0.014, depth=0.30, c0=0.15, ridge=0.30, ridge_off=2.4,
                          probe=0.06, effort=0.06, effort_mid=0.22, effort_lid=0.15),
    # JAFFE's glabellar fine lines (tests/test_creases.py, x 1000 over each woman's neutral):
    # fear 7.5, sadness 6.2, anger 2.6; from the mesh's compression alone fear drew 1.9 and
    # sadness 3.2 (their brows close in half as far as anger's); with the brow effort 3.8
    # and 5.8 (anger unchanged: 5.2). Real furrows there are broad, soft bunching beside the
    # brow heads; at sigma 0.013 they were drawn as thin parallel scratches, plain on a face
    # 250 px between the eyes (JAFFE upscaled 4 x); at 0.024 softer, the same measure 4.4,
    # 6.8, 5.3 (disgust 6.6 both; at 150 % fear 7.4, sadness 9.3). With the knitted brows'
    # shade below (drawn in this group's canvas), depth 0.14 -> 0.12 and effort 0.6 -> 0.75:
    # anger 4.96 (150 %: 8.01, real p90 9.34; 9.5 with the old depth), fear 4.42, sadness 6.56
    "glabella": FoldStyle(sigma=0.024, depth=0.12, c0=0.28, ridge=0.20, ridge_off=2.4,
                          probe=0.05, effort=0.75),
    # the knitted brows' shade (AU4 lowering and drawing the brows together): JAFFE's angry
    # glabellas, between and beside the brow heads (x +-0.16 IOD, 0.15-0.3 IOD above the
    # eyes), fall 0.086 of the median light below their neutral photos' (disgust 0.11); the
    # warp brightened it (+0.020: the lighter forehead slides down) and the furrows are too
    # thin to shade it. Nine parallel lines (KNIT_N) in the glabella group's canvas, driven by
    # the vertical compression below the inner brow ends (KNIT_PROBES: lowered brows only):
    # anger -0.063 (150 %: -0.078, real p10 -0.18), disgust -0.098; fear and sadness none
    # (tests/test_creases.py)
    "knit": FoldStyle(sigma=0.024, depth=0.075, c0=0.05, ridge=0.0, ridge_off=2.4, probe=0.12),
    # the mentolabial sulcus under an angry pout (AU17 + AU24 push the lower lip up over the
    # chin). JAFFE: the deepest dip down the lip-to-chin band 0.178 of the median light in the
    # anger photos (median of 20; 0.043 on the neutral ones, 0.049 disgust, 0.077 sadness);
    # drawn 0.022 before this fold existed, now 0.154 / 0.243 at 100 / 150 % (p90 0.304;
    # tests). Drawn only with the chin boss raised and the lips together (_closed_lips): the
    # JAFFE closed loop's estimates of smiles and sad faces drew it too (lips 2.37 -> 2.50 %
    # IOD; now 2.41: the detector reads the groove a little as the lower lip's edge). No light
    # ridge beside it (0.35 before, on the chin side): JAFFE's angry chins have none (the
    # bunched boss below the groove is shaded, chinboss.py), and the ridge lit a pale band
    # under the lower lip; 0.183 / 0.264 at 100 / 150 % with the boss's shade. Drawn over
    # 0.34 of the mouth's width either side (sigma 0.018, depth 0.45) it was a short dash under
    # the lip's middle (raters: "a dark smudge"), its sides 0.084 deep for the real 0.124
    # (0.16-0.24 IOD out); across the lip's width (CHIN_HALF_W), softer and shallower: sides
    # 0.148, middle 0.187 / 0.217 at 100 / 150 % (real 0.178)
    "chin": FoldStyle(sigma=0.022, depth=0.34, c0=0.07, ridge=0.0, ridge_off=2.4,
                      probe=0.05, dead=0.02, sign=-1.0),
    # JAFFE's disgust: the nasal-root lines 0.02 deep (median of 40 photos' lines, over the
    # image's median luminance; 0.009 on the neutral ones: their grain). Depth 0.13 drew 0.073
    # (scratches across the nose under disgust and anger), 0.06 drew 0.025 on the warp's
    # smoothed skin and 0.037 with the photo's grain put back (grain.py); now 0.024
    "bridge": FoldStyle(sigma=0.011, depth=0.03, c0=0.07, ridge=0.25, ridge_off=2.2,
                        probe=0.04, dead=0.04),
    # the nose wrinkler's (AU9) oblique lines on the sides of the nose, from beside the dorsum
    # out and down towards the cheek (JAFFE disgust: KA, KL; anger: KA, MK). JAFFE's ten women
    # (tests/test_creases.py: the valley across the middle of the laid-out lines, 0.04 IOD
    # window, over the image's median light, two photos each): disgust 0.064 (p90 0.093), the
    # neutral photos 0.054 (their grain), anger 0.054, sadness 0.059, joy 0.062. Without them
    # disgust drew 0.047 at 100 % (the warp's smoothed grain: "the nose is too plain"), 0.041
    # at 150 %; now 0.063 and 0.071. Driven by the cheek beside the nose wing pushed up (the
    # upper_lip furrow's probes: disgust 0.018, joy 0.024, anger 0.0005 IOD, median of the ten
    # meshes) while the inner brows are lowered (FoldStyle.frown; lowering over the inner eye
    # corners' distance: disgust 0.116, anger 0.135, joy 0.022): joy, anger (0.001-0.005 on
    # the ten at 150 %), sadness, fear and surprise draw none; their renders' valley stays
    # under their real photos' (anger 0.044, sadness 0.048, joy 0.050 at 100 %)
    "nose_side": FoldStyle(sigma=0.015, depth=0.06, c0=0.012, ridge=0.25, ridge_off=2.2,
                           probe=0.04, lift=True, frown=0.06),
}


@dataclass(eq=False)
class CreasePlan:
    """Per-face fold geometry (see the module docstring).

    ``tri``/``bary`` (N, 3) place the N fold samples (all folds concatenated) on the mesh;
    ``probe_tri`` (N, 4) the triangles whose compression each sample reads; ``normal`` (N, 2)
    the line's normal on the photo's mesh; ``taper`` (N,) the fade along each line;
    ``fold`` (N,) the fold index of each sample; ``group`` per fold: drawn together in one box.
    """

    kinds: list[str]
    group: np.ndarray  # (F,) group index per fold
    group_names: list[str]
    start: np.ndarray  # (F + 1,) sample offsets per fold
    tri: np.ndarray
    bary: np.ndarray
    probe_tri: np.ndarray
    normal: np.ndarray
    taper: np.ndarray
    fold: np.ndarray
    tri_inv: np.ndarray  # (T, 2, 2) inverse edge matrix of each photo-mesh triangle
    iod: float
    tint: np.ndarray  # (3,) per-channel darkening weights (1, 1, 1 on grey photos)
    skin: np.ndarray  # (F, 3) skin colour around each fold in the photo
    utaper: np.ndarray  # (N,) fade along each line of the photo's own fold

    @property
    def n_folds(self) -> int:
        return len(self.kinds)


_PLANS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def crease_plan(face: Face) -> CreasePlan:
    """The fold layout of a face (cached for the face's lifetime)."""
    p = _PLANS.get(face)
    if p is None:
        p = _build_plan(face)
        _PLANS[face] = p
    return p


# ---------------------------------------------------------------------------- layout
def _fade(t: np.ndarray, a: float, b: float) -> np.ndarray:
    """Taper along a line: rises over [0, a], falls over [1 - b, 1] (smoothstep)."""
    # (both ramps in one array: the same values with half the small-array operations)
    n = len(t)
    x = smooth01(np.concatenate([t / max(a, 1e-6), (1.0 - t) / max(b, 1e-6)]))
    return x[:n] * x[n:]


def _pairs(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.stack([a, b], 1)`` of two 1-D float arrays of one length (the same (n, 2) array
    without np.stack's Python-level set-up: the layout makes a dozen)."""
    out = np.empty((len(a), 2), np.result_type(a, b))
    out[:, 0] = a
    out[:, 1] = b
    return out


def _cut(a: np.ndarray, ends: list[int]) -> list[np.ndarray]:
    """``np.split(a, ends[:-1])`` (``ends``: the pieces' cumulative lengths): the same views,
    without np.split's per-piece axis swaps."""
    return [a[i:j] for i, j in zip([0, *ends[:-1]], ends, strict=True)]


@dataclass
class _Line:
    """One fold on the photo's mesh, in face-frame coordinates and units of the IOD.

    ``probes``: None = the compression is read on the line and ``probe`` either side of it,
    across it; else (4, 2) frame points whose compression along ``measure`` (a frame
    direction) drives the line (where the muscle's pull shows in the mesh).
    """

    kind: str
    group: str
    pts: np.ndarray
    taper: np.ndarray
    side: tuple[float, float]  # frame direction of the ridge beside the line
    probes: np.ndarray | None = None  # (4, 2)
    measure: tuple[float, float] = (0.0, 1.0)
    utaper: np.ndarray | None = None  # fade of the photo's own fold (default: ``taper``)


@functools.cache
def _line_constants() -> dict[str, list]:
    """The parts of :func:`_fold_lines` that do not depend on the face, made once per
    process (read-only): the nasolabial folds', the lower lids' and the crow's feet's
    tapers, the crow's feet's offsets from their eye corner, and the irregular lines'
    (forehead, glabella, bridge, chin, nose sides) fixed random draws, in the order the lines
    drew them per face before, with what of those lines depends on the draws alone (each line's
    arithmetic stays in its own order: the same values; ~0.25 ms a face before)."""
    out: dict[str, list] = {"crow": []}
    # ---- nasolabial folds (28 samples, their upper part 16) and the lower lids' (16)
    t = linspace(0.0, 1.0, 28)
    tu = linspace(0.0, 1.0, int(0.6 * 28))
    t_l = linspace(0.0, 1.0, 16)
    out["nasolabial"] = [_fade(t, 0.2, 0.45), _fade(t, 0.2, 0.25), _fade(tu, 0.3, 0.5),
                         np.zeros(len(tu))]
    out["lower_lid"] = [_fade(t_l, 0.3, 0.3), np.zeros(len(t_l))]
    # ---- crow's feet: per side and line, the points' offsets ``rr d`` and ``bend perp``
    crow_fade = _fade(linspace(0, 1, 10), 0.35, 0.6)
    for sg in (-1.0, 1.0):
        for ang, r0, r1 in ((-24.0, 0.14, 0.27), (-2.0, 0.12, 0.29), (22.0, 0.12, 0.26)):
            a = np.deg2rad(ang)
            d = np.array([sg * np.cos(a), np.sin(a)])
            rr = linspace(r0, r1, 10)
            bend = 0.015 * np.sin(np.pi * (rr - r0) / (r1 - r0))  # slightly curved
            perp = np.array([-d[1], d[0]])
            probes = np.array([(sg * 0.12, 0.12), (sg * 0.22, 0.1), (sg * 0.05, 0.2),
                               (sg * 0.18, 0.2)])
            out["crow"].append((rr[:, None] * d, bend[:, None] * perp, probes, crow_fade))
    # ---- the irregular lines' fixed random draws (in _fold_lines' order) and what of their
    # lines does not depend on the face: per forehead line its height share, its three waves
    # and its taper; per glabellar furrow its five draws; per bridge wrinkle its place, its
    # bend, slope and wave and its taper; the chin's x shape, wave, taper and own taper
    rng = np.random.default_rng(1729)
    t = linspace(0.0, 1.0, 40)
    for j, (f, amp) in enumerate(((0.16, 0.006), (0.30, 0.008), (0.44, 0.007))):
        f = f + rng.uniform(-0.025, 0.025)
        ph = rng.uniform(0, 2 * np.pi, 3)
        w1 = amp * np.sin(2 * np.pi * 1.3 * t + ph[0])
        w2 = 0.5 * amp * np.sin(2 * np.pi * rng.uniform(2.5, 3.5) * t + ph[1])
        w3 = 0.25 * amp * np.sin(2 * np.pi * rng.uniform(6.0, 8.0) * t + ph[2])
        # broken lines: a dip near the middle and another somewhere else, of varying depth
        gap = 1.0 - (0.55 if j != 1 else 0.25) * np.exp(-((t - 0.5 - 0.06 * (j - 1)
                                                           - rng.uniform(-0.05, 0.05)) / 0.07)
                                                          ** 2)
        gap *= 1.0 - rng.uniform(0.3, 0.8) * np.exp(-((t - rng.uniform(0.15, 0.85))
                                                      / rng.uniform(0.03, 0.07)) ** 2)
        # uneven depth along the line
        pk = rng.uniform(0, 2 * np.pi, 2)
        depth = 1.0 + 0.15 * np.sin(2 * np.pi * 2.1 * t + pk[0]) + 0.1 * np.sin(
            2 * np.pi * 4.3 * t + pk[1])
        taper = _fade(t, rng.uniform(0.18, 0.32), rng.uniform(0.18, 0.32)) * gap * depth
        out.setdefault("forehead", []).append((f, w1, w2, w3, taper))
    for _ in range(2):  # (x, top, bow phase, evenness phase, fade-in)
        out.setdefault("glabella", []).append(
            tuple(rng.uniform(a, b) for a, b in ((0.9, 1.1), (0.85, 1.1), (0, 6.3), (0, 6.3),
                                                 (0.3, 0.5))))
    for at, half_w, k_b, dx, tilt, curve in ((0.05, 0.11, 1.0, 0.0, 0.03, 0.06),
                                             (-0.35, 0.07, 0.55, 0.015, -0.05, 0.02)):
        xs_b = linspace(-half_w, half_w, 12)
        t_b = linspace(0, 1, 12)
        wave = 0.003 * np.sin(2 * np.pi * 1.3 * t_b + rng.uniform(0, 6.3))
        even = k_b * (1.0 + 0.2 * np.sin(2 * np.pi * 1.1 * t_b + rng.uniform(0, 6.3)))
        out.setdefault("bridge", []).append((at, dx, xs_b, curve * xs_b ** 2 / half_w,
                                             tilt * xs_b, wave,
                                             _fade(t_b, 0.35, 0.35) * even))
    t_c = linspace(0.0, 1.0, 18)
    out["chin"] = [2.0 * t_c - 1.0,
                   0.003 * np.sin(2 * np.pi * 0.9 * t_c + rng.uniform(0, 6.3)),
                   _fade(t_c, 0.35, 0.35), np.zeros(len(t_c))]
    # ---- the nose's side wrinkles (drawn after the chin's: the draws above stay the same):
    # per side two oblique lines, each its start below the nasal sidewall's top, its slope,
    # bow, wave and taper (not mirror images, not evenly spaced)
    t_n = linspace(0.0, 1.0, 10)
    for _side in range(2):
        for off, slope, bow in ((-0.06, 0.75, 0.012), (0.05, 0.6, 0.008)):
            off += rng.uniform(-0.02, 0.02)
            wave = 0.003 * np.sin(2 * np.pi * 1.2 * t_n + rng.uniform(0, 6.3))
            even = 1.0 + 0.2 * np.sin(2 * np.pi * 1.1 * t_n + rng.uniform(0, 6.3))
            out.setdefault("nose_side", []).append(
                (off, t_n, slope + rng.uniform(-0.08, 0.08), -bow * np.sin(np.pi * t_n) + wave,
                 _fade(t_n, 0.3, 0.4) * even))
    out["nose_side_u"] = [np.zeros(len(t_n))]
    for v in out.values():  # (shared by every face's lines: read-only)
        for a in v:
            for x in (a if isinstance(a, tuple) else (a,)):
                if isinstance(x, np.ndarray):
                    x.setflags(write=False)
    return out


def _fold_lines(face: Face) -> list[_Line]:
    """Every fold of the face (x towards the subject's left, y down)."""
    fr = face.frame
    iod = float(face.interocular)
    m = face.mesh
    fixed = _line_constants()
    # every vertex in frame coordinates over the IOD, in one product (a vertex's row is the
    # value of the product of that vertex alone; ~70 feature points are read)
    F = fr.to_frame(face.vertices.astype(np.float64)) / iod

    def q(name: str) -> np.ndarray:
        return F[m.index(name)]

    lines: list[_Line] = []
    # ---- nasolabial folds: from above the nose wing, down and out past the mouth corner
    nl_taper, nl_utaper, up_taper, up_utaper = fixed["nasolabial"]
    for s, sg in (("r", -1.0), ("l", 1.0)):
        ala = q(f"ala_{s}")
        corner = q(f"lipo_c{0 if s == 'r' else 1}")
        top = ala + (sg * 0.03, -0.06)
        mid = corner + (sg * 0.1, -0.03)
        bot = corner + (sg * 0.14, 0.16)
        d = mid - top
        bow = np.array([-d[1], d[0]]) * (0.12 * sg)  # slightly convex towards the cheek
        ctrl = np.array([top, 0.5 * (top + mid) - bow, mid, bot])  # mirror images
        pts = catmull_rom(ctrl, 28)
        # a smiling photo's own fold reaches from the nose wing down past the corner
        lines.append(_Line("nasolabial", f"nasolabial_{s}", pts, nl_taper, (sg, -0.5),
                           utaper=nl_utaper))
        # its upper part, driven by how far the cheek beside the nose wing is pushed up
        # towards the eye (FoldStyle.lift; the nose wrinkler AU9 and the cheek raiser AU6
        # lift it; see STYLES["upper_lip"])
        up = pts[: int(0.6 * len(pts))]
        probes = ala + np.array([(sg * 0.10, 0.02), (sg * 0.14, 0.04), (sg * 0.12, 0.08),
                                 (sg * 0.16, 0.08)])
        lines.append(_Line("upper_lip", f"nasolabial_{s}", up, up_taper, (sg, -0.5), probes,
                           (0.0, 1.0), utaper=up_utaper))
    # ---- crow's feet: a fan of short lines beyond each outer eye corner, driven by the
    # skin below them (the cheek raiser pushes it up; a lowered brow does not count)
    crows = iter(fixed["crow"])
    for s in ("r", "l"):
        oc = q(f"eye_{s}_c{0 if s == 'r' else 1}")
        for _ in range(3):
            along, bend, probes, crow_fade = next(crows)
            lines.append(_Line("crow", f"crow_{s}", oc + along + bend, crow_fade, (0.0, -1.0),
                               oc + probes))
    # ---- forehead: three horizontal lines between the brows and the hairline
    brow = np.array([q(f"brow_r_u{k}") for k in range(1, 6)] + [q(f"brow_l_u{k}")
                                                              for k in range(1, 6)])
    brow = brow[np.argsort(brow[:, 0])]
    top = np.array([q(f"forehead_2_{k}") for k in range(1, 8)])
    top = top[np.argsort(top[:, 0])]
    xs = linspace(brow[1, 0], brow[-2, 0], 40)
    yb = interp(xs, brow[:, 0], brow[:, 1])
    # the lines curve gently like the brows (half as much), not with the brows' gap
    yb_s = 0.5 * yb + 0.5 * float(median(yb))
    yh = interp(xs, top[:, 0], top[:, 1])
    h = (yb_s - yh) / 0.7  # brow -> hairline
    # real lines are irregular: uneven waviness, breaks, lengths and strength along the line
    # (a fixed draw: the same at any resolution, made once, _line_constants), so they do not
    # look drawn with a ruler
    for f, w1, w2, w3, taper in fixed["forehead"]:
        y = yb_s - f * h + w1 + w2 + w3
        lines.append(_Line("forehead", "forehead", _pairs(xs, y), taper, (0.0, -1.0)))
    # ---- glabella: two short vertical furrows between the inner brow ends, not mirror images
    # (different lengths, bowed apart towards the top, uneven along their length)
    ri, li = q("brow_r_e1"), q("brow_l_e0")
    g = q("glabella")
    half = 0.5 * abs(li[0] - ri[0])
    for (sg, tilt), (d_x, d_top, d_bow, d_even, d_fade) in zip(((-1.0, -0.01), (1.0, 0.01)),
                                                               fixed["glabella"], strict=True):
        x = g[0] + sg * max(0.32 * half, 0.07) * d_x
        y_brow = 0.5 * (ri[1] + li[1])
        y_top, y_bot = y_brow - 0.24 * d_top, max(g[1], y_brow + 0.04)
        ys = linspace(y_top, y_bot, 14)
        u = (ys - y_top) / (y_bot - y_top)
        pts = _pairs(x + tilt * u - sg * 0.02 * u * u + sg * 0.015 * (1 - u) ** 2
                     + 0.004 * np.sin(2 * np.pi * 1.5 * u + d_bow), ys)
        even = 1.0 + 0.15 * np.sin(2 * np.pi * 1.2 * u + d_even)
        lines.append(_Line("glabella", "glabella", pts, _fade(u, d_fade, 0.3) * even,
                           (sg, 0.0)))
    # ---- the knitted brows' shade (kind "knit"): the skin between the brow heads, bunched by
    # the corrugator and the procerus (AU4), bulges and shades the whole glabella down to the
    # nasal root, beyond its furrows: a broad, soft shade from above the inner brow ends down,
    # driven by the skin below them pushed down towards the nasal root (the brows lowered:
    # anger, disgust; raised inner brows (fear, sadness) stretch it instead). Drawn as
    # parallel vertical lines two of the furrows' sigmas apart in the furrows' own canvas
    # (group "glabella"): their sum is an even shade, and one canvas keeps the coarse drawing
    # of a large face within a grey level of the fine one (a second, broader canvas over the
    # furrows added the two drawings' rounding: 2 levels). The group draws them in its first
    # style's look (the furrows': a light ridge 2.4 sigma beside each line), so each line's
    # ridge side is set outward from the face's midline, as the furrows' are (a side along
    # the lines left it to the float rounding of the plan's side test: 6 of the sample's 9
    # ridges fell one way, 3 the other)
    y_brow = 0.5 * (ri[1] + li[1])
    ys = linspace(y_brow - KNIT_SPAN[0], y_brow + KNIT_SPAN[1], 12)
    u = (ys - ys[0]) / (ys[-1] - ys[0])
    probes = np.array([(g[0] + dx, y_brow + dy) for dx, dy in KNIT_PROBES])
    knit_taper = _fade(u, 0.3, 0.3)
    for dx in linspace(-KNIT_X, KNIT_X, KNIT_N):
        lines.append(_Line("knit", "glabella", _pairs(g[0] + dx + 0.0 * ys, ys), knit_taper,
                           (1.0 if dx >= 0.0 else -1.0, 0.0), probes, (0.0, 1.0)))
    # ---- nose bridge: short wrinkles across the nasal root (procerus / nose wrinkler, AU4 and
    # AU9), driven by the skin between the inner brow ends and the inner eye corners pushed
    # down (the mesh does not bunch the bridge itself; a smile does not lower the brows)
    n27, n28 = q("nose_27"), q("nose_28")
    bi_r, bi_l = q("brow_r_e1"), q("brow_l_e0")
    ec_r, ec_l = q("eye_r_c1"), q("eye_l_c0")
    # probes between the inner brow end, the inner canthus and the nasal root, in the skin
    # the lowered brow head squeezes but not on the upper lid's ring (closing the eyes moves
    # that ring down and is no frown)
    probes = np.array([b + k * (e - b) + 0.8 * k * (n27 - b) for b, e in ((bi_r, ec_r),
                                                                          (bi_l, ec_l))
                       for k in (0.2, 0.27)])
    # one main wrinkle at the root and a shorter, fainter one above it, off-centre, tilted
    # and bowed differently (three evenly spaced concentric arcs read as a drawn ripple)
    for at, dx, xs_b, bend, slope, wave, taper in fixed["bridge"]:
        c = n27 + at * (n28 - n27)
        y_b = c[1] + bend + slope + wave
        pts = _pairs(c[0] + dx + xs_b, y_b)
        lines.append(_Line("bridge", "bridge", pts, taper, (0.0, -1.0), probes, (0.0, 1.0)))
    # ---- mentolabial sulcus: the groove between the lower lip and the chin, deepened when the
    # chin raiser (AU17, anger and disgust) pushes the chin boss up against the lower lip.
    # JAFFE's anger photos show it 0.45 of the way from the lower lip's middle (8.2) to the
    # chin (2.1), 0.04 IOD wide (half depth), following the chin's round top
    lip_m, chin = q("lipo_d4"), q("contour_16")
    mouth_w = abs(q("lipo_c1")[0] - q("lipo_c0")[0])
    half_w = CHIN_HALF_W * mouth_w
    c = lip_m + 0.45 * (chin - lip_m)
    shape_c, wave_c, taper_c, utaper_c = fixed["chin"]
    xs_c = shape_c * half_w
    y_c = c[1] - CHIN_CURVE * (xs_c / half_w) ** 2 + wave_c
    lines.append(_Line("chin", "chin", _pairs(c[0] + xs_c, y_c), taper_c, (0.0, 1.0),
                       utaper=utaper_c))
    # ---- the lower lids' furrows: under each lower lid, LID_FURROW below it and following
    # its curve, driven by how far the skin under the eye is pushed up (the cheek raiser
    # AU6, and the lid tightener AU7; FoldStyle.lift) (added after the others: their random
    # draws stay the same)
    lid_taper, lid_utaper = fixed["lower_lid"]
    for s in ("r", "l"):
        lid = np.array([q(f"eye_{s}_c0")] + [q(f"eye_{s}_d{k}") for k in range(1, 6)]
                       + [q(f"eye_{s}_c1")])
        lid = lid[np.argsort(lid[:, 0])]
        xs_l = linspace(lid[0, 0] + 0.1 * (lid[-1, 0] - lid[0, 0]),
                        lid[-1, 0] + 0.05 * (lid[-1, 0] - lid[0, 0]), 16)
        y_l = interp(xs_l, lid[:, 0], lid[:, 1]) + LID_FURROW
        mid = lid[1:-1].mean(0)
        probes = mid + np.array([(-0.06, 0.05), (0.06, 0.05), (-0.06, 0.18), (0.06, 0.18)])
        lines.append(_Line("lower_lid", f"lower_lid_{s}", _pairs(xs_l, y_l), lid_taper,
                           (0.0, -1.0), probes, (0.0, 1.0), utaper=lid_utaper))
    # ---- the nose's sides: short wrinkles across the nasal sidewall, from beside the dorsum
    # out and a little down towards the cheek (the nose wrinkler AU9 pulls the skin of the
    # nose up against the lowered brow heads: JAFFE KA, KL, MK), driven by the cheek beside
    # the nose wing pushed up towards the eye (the upper_lip furrow's probes) while the brows
    # are lowered (FoldStyle.frown); never taken for the photo's own fold (no unfold)
    n28 = q("nose_28")
    sides = iter(fixed["nose_side"])
    (no_unfold,) = fixed["nose_side_u"]
    for s, sg in (("r", -1.0), ("l", 1.0)):
        ns, ala = q(f"nose_side_{s}"), q(f"ala_{s}")
        x0 = n28[0] + sg * 0.04
        x1 = ns[0] + sg * 0.08
        probes = ala + np.array([(sg * 0.10, 0.02), (sg * 0.14, 0.04), (sg * 0.12, 0.08),
                                 (sg * 0.16, 0.08)])
        for _ in range(2):
            off, t_n, slope, bend, taper = next(sides)
            xs_n = x0 + (x1 - x0) * t_n
            lines.append(_Line("nose_side", f"nose_side_{s}",
                               _pairs(xs_n, ns[1] + off + slope * np.abs(xs_n - x0) + bend),
                               taper, (0.0, -1.0), probes, (0.0, 1.0), utaper=no_unfold))
    return lines


def _on_mesh(V: np.ndarray, tri: tuple[np.ndarray, ...], bary: tuple[np.ndarray, ...]
             ) -> np.ndarray:
    """Points (N, 2) on the mesh ``V`` given as 3 x (N,) vertex indices and 3 x (N, 1)
    barycentric weights (rows gathered with ``take``: fancy indexing costs more)."""
    (t0, t1, t2), (b0, b1, b2) = tri, bary
    return V.take(t0, 0) * b0 + V.take(t1, 0) * b1 + V.take(t2, 0) * b2


def _lines_normals(lines: list[np.ndarray]) -> list[np.ndarray]:
    """Unit normals (n, 2) of each polyline (n >= 2): its tangent turned by +90 degrees, all
    in one pass over their concatenated points (the same values line by line: a point's
    central difference reads its two neighbours; each line's ends are its own one-sided
    differences, written after)."""
    # (np.gradient's and np.linalg.norm's arithmetic without their Python-level overhead:
    # central differences inside, one-sided at the ends)
    # (in place into preallocated arrays, no np.stack: -(ty / n) is -ty / n bit for bit)
    p = np.concatenate(lines).astype(np.float64, copy=False)
    ends = np.cumsum([len(x) for x in lines])
    first, last = np.concatenate(([0], ends[:-1])), ends - 1
    tang = np.empty_like(p)
    np.subtract(p[2:], p[:-2], out=tang[1:-1])
    tang[1:-1] /= 2.0
    tang[first] = p[first + 1] - p[first]
    tang[last] = p[last] - p[last - 1]
    tx, ty = tang[:, 0], tang[:, 1]
    n = np.sqrt(tx * tx + ty * ty)
    np.maximum(n, 1e-9, out=n)
    out = np.empty_like(p)
    np.divide(ty, n, out=out[:, 0])
    np.negative(out[:, 0], out=out[:, 0])
    np.divide(tx, n, out=out[:, 1])
    return _cut(out, ends.tolist())


def _locate(points: np.ndarray, verts: np.ndarray, tris: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
    """Triangle index and barycentric coordinates of each point (nearest triangle outside).

    Per point, the barycentric coordinates in every triangle; the triangle whose smallest one
    is largest (>= 0 inside; the first such triangle on a tie). A point inside the mesh is
    only tested against the triangles whose box holds it (and the degenerate ones): every
    triangle that can give it a coordinate triple >= 0 is among them, so the winner and its
    coordinates are those of the test against every triangle; the points outside the mesh are
    tested against every triangle (:func:`_locate_all`)."""
    points = np.asarray(points, np.float64)
    corners = verts.take(tris, 0)  # (T, 3, 2): one gather (three fancy indexings cost more)
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    e1, e2 = b - a, c - a
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    det = np.where(np.abs(det) < 1e-12, 1e-12, det)
    n, T = len(points), len(tris)
    if n * T <= 40_000:  # few points: testing every triangle costs less than the pairing
        ti, bary = _locate_all(points, a, e1, e2, det)
        return ti.astype(np.int32), bary
    ti = np.zeros(n, np.int64)
    bary = np.zeros((n, 3))
    # candidate (point, triangle) pairs: the points in each triangle's box (grown by 1e-3 px:
    # rounding). The points are binned in horizontal bands and sorted by band, then x; per
    # triangle and band it spans, the band's points in (a hair more than) its x range: a
    # superset of the pairs, cut to exactly those by the box comparisons. (A sweep over x
    # alone paired each triangle with every point in its column: ~15 x the pairs.)
    lo = np.minimum(np.minimum(a, b), c) - 1e-3
    hi = np.maximum(np.maximum(a, b), c) + 1e-3
    px, py = np.ascontiguousarray(points[:, 0]), np.ascontiguousarray(points[:, 1])
    ymin, xmin = float(py.min()), float(px.min())
    hb = max(float(median(hi[:, 1] - lo[:, 1])), 1.0)  # band height: a typical triangle's
    band = np.floor((py - ymin) / hb)
    span = float(px.max()) - xmin + 2.0  # the bands' keys lie apart
    key = band * span + (px - xmin)
    order = np.argsort(key)  # (the pairs found do not depend on the order of equal keys)
    key = key[order]
    # the bands each triangle's y range spans (floor is monotonic: a point in the range lies
    # in one of them)
    tb0 = np.maximum(np.floor((lo[:, 1] - ymin) / hb), 0.0)
    tb1 = np.minimum(np.floor((hi[:, 1] - ymin) / hb), float(band.max()))
    nb = np.maximum(tb1 - tb0 + 1.0, 0.0).astype(np.intp)
    nb[np.abs(det) < 1.0] = 0  # (degenerate: added to every point below)
    tt = np.repeat(np.arange(T), nb)
    bb = np.repeat(tb0, nb) + (np.arange(len(tt)) - np.repeat(np.cumsum(nb) - nb, nb))
    # (x offsets held within the band's keys; +- 1e-6 px covers the keys' rounding)
    ka = bb * span + (np.clip(lo[tt, 0] - xmin, -1.0, span - 1.0) - 1e-6)
    kb = bb * span + (np.clip(hi[tt, 0] - xmin, -1.0, span - 1.0) + 1e-6)
    r0 = np.searchsorted(key, ka, "left")
    cnt = np.searchsorted(key, kb, "right") - r0
    pt_t = np.repeat(tt, cnt)
    pt_p = order[np.arange(len(pt_t)) - np.repeat(np.cumsum(cnt) - cnt - r0, cnt)]
    # (the columns gathered with take from contiguous copies: the same values, without the
    # cost of fancy indexing into (n, 2) arrays)
    qx, qy = px.take(pt_p), py.take(pt_p)
    keep = (qx >= np.ascontiguousarray(lo[:, 0]).take(pt_t)) & \
        (qx <= np.ascontiguousarray(hi[:, 0]).take(pt_t)) & \
        (qy >= np.ascontiguousarray(lo[:, 1]).take(pt_t)) & \
        (qy <= np.ascontiguousarray(hi[:, 1]).take(pt_t))
    pt_t, pt_p = pt_t[keep], pt_p[keep]
    thin = np.flatnonzero(np.abs(det) < 1.0)
    if len(thin):
        pt_t = np.concatenate([pt_t, np.repeat(thin, n)])
        pt_p = np.concatenate([pt_p, np.tile(np.arange(n), len(thin))])
    if len(thin) or n > 1 << 16:
        srt = np.argsort(pt_p * T + pt_t)  # by point, then triangle (unique keys)
    else:
        # (the pairs are listed by triangle, increasing: a stable sort by point alone puts
        # them in the same order, by point, then triangle; on 16-bit keys numpy's radix sort,
        # several times faster than a sort of the combined keys)
        srt = np.argsort(pt_p.astype(np.uint16), kind="stable")
    pt_t, pt_p = pt_t.take(srt), pt_p.take(srt)
    # the same arithmetic as _locate_all, pair by pair
    dx = px.take(pt_p) - np.ascontiguousarray(a[:, 0]).take(pt_t)
    dy = py.take(pt_p) - np.ascontiguousarray(a[:, 1]).take(pt_t)
    dt = det.take(pt_t)
    l1 = dx * np.ascontiguousarray(e2[:, 1]).take(pt_t)
    l1 -= dy * np.ascontiguousarray(e2[:, 0]).take(pt_t)
    l1 /= dt
    l2 = np.ascontiguousarray(e1[:, 0]).take(pt_t) * dy
    l2 -= np.ascontiguousarray(e1[:, 1]).take(pt_t) * dx
    l2 /= dt
    l0 = 1.0 - l1
    l0 -= l2
    worst = np.minimum(l0, l1)
    np.minimum(worst, l2, out=worst)
    done = np.zeros(n, bool)
    if len(pt_p):
        # (np.concatenate rather than np.r_: the same arrays, without its overhead)
        starts = np.flatnonzero(np.concatenate(([True], pt_p[1:] != pt_p[:-1])))
        best = np.maximum.reduceat(worst, starts)
        sizes = np.diff(np.concatenate((starts, [len(pt_p)])))
        hit = np.flatnonzero(worst == np.repeat(best, sizes))
        # the first hit per point
        first = hit[np.concatenate(([True], pt_p[hit[1:]] != pt_p[hit[:-1]]))]
        inside = worst[first] >= 0.0
        first = first[inside]
        pts = pt_p[first]
        ti[pts] = pt_t[first]
        bary[pts] = np.stack([l0[first], l1[first], l2[first]], 1)
        done[pts] = True
    rest = np.flatnonzero(~done)
    if len(rest):
        t_r, b_r = _locate_all(points[rest], a, e1, e2, det)
        ti[rest], bary[rest] = t_r, b_r
    return ti.astype(np.int32), bary


def _locate_all(points: np.ndarray, a: np.ndarray, e1: np.ndarray, e2: np.ndarray,
                det: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_locate` against every triangle (corner ``a``, edges ``e1``, ``e2``, their
    ``det``). In blocks of points (the (points, triangles) arrays stay in the cache), each
    coordinate a contiguous array."""
    ax, ay = np.ascontiguousarray(a[:, 0]), np.ascontiguousarray(a[:, 1])
    e1x, e1y = np.ascontiguousarray(e1[:, 0]), np.ascontiguousarray(e1[:, 1])
    e2x, e2y = np.ascontiguousarray(e2[:, 0]), np.ascontiguousarray(e2[:, 1])
    n = len(points)
    ti = np.zeros(n, np.int64)
    bary = np.zeros((n, 3))
    step = max(1, 32768 // max(len(a), 1))
    for i in range(0, n, step):
        px = points[i:i + step, 0:1]
        py = points[i:i + step, 1:2]
        dx = px - ax
        dy = py - ay
        l1 = dx * e2y
        l1 -= dy * e2x
        l1 /= det
        l2 = e1x * dy
        l2 -= e1y * dx
        l2 /= det
        l0 = 1.0 - l1
        l0 -= l2
        worst = np.minimum(l0, l1)
        np.minimum(worst, l2, out=worst)
        k = np.argmax(worst, axis=1)
        r = np.arange(len(k))
        ti[i:i + step] = k
        bary[i:i + step] = np.stack([l0[r, k], l1[r, k], l2[r, k]], 1)
    return ti, bary


@functools.lru_cache(maxsize=4)
def _skin_triangles(mesh) -> np.ndarray:
    """Indices of the triangles that carry folds: the skin, not the margin/border rings (per
    mesh; read-only)."""
    ok = ~np.isin(mesh.regions[mesh.triangles], ("margin", "border")).any(1)
    cand = np.flatnonzero(ok)
    cand.flags.writeable = False
    return cand


def _build_plan(face: Face) -> CreasePlan:
    mesh = face.mesh
    V = face.vertices.astype(np.float64)
    fr = face.frame
    iod = float(face.interocular)
    # only skin triangles carry folds (not the margin/border rings)
    cand = _skin_triangles(mesh)
    tris = mesh.triangles[cand]
    kinds, groups, gnames, starts = [], [], [], [0]
    all_tri, all_bary, all_probe, all_n, all_taper = [], [], [], [], []
    all_utaper = []
    # every point that is located on the mesh (the lines, their probes), in one batch
    queries: list[np.ndarray] = []
    lines = []
    layout = _fold_lines(face)
    # (every line's points, and every probe, to the image in one product each: a row's value
    # is that of the product of its line alone)
    ends = np.cumsum([len(ln.pts) for ln in layout])
    on_image = _cut(fr.to_image(np.concatenate([ln.pts for ln in layout]) * iod), ends.tolist())
    probed = [ln.probes for ln in layout if ln.probes is not None]
    probes = iter(_cut(fr.to_image(np.concatenate(probed) * iod),
                       np.cumsum([len(x) for x in probed]).tolist()) if probed else [])
    measures: dict[tuple[float, float], np.ndarray] = {}
    normals = _lines_normals(on_image)
    # which lines to reverse: the sign of the mean of their normals along their ridge side,
    # for all lines at once (a line whose mean is near zero, where the batched arithmetic's
    # rounding could tell, takes its own line's product as before)
    first = np.concatenate(([0], ends[:-1]))
    sides = np.repeat(np.array([ln.side for ln in layout], np.float64) @ fr.rot.T,
                      ends - first, 0)
    nrm_all = np.concatenate(normals)
    along = nrm_all[:, 0] * sides[:, 0] + nrm_all[:, 1] * sides[:, 1]
    mean = np.add.reduceat(along, first) / (ends - first)
    flip = (mean < 0).tolist()
    for i in np.flatnonzero(np.abs(mean) < 1e-6).tolist():
        flip[i] = float((normals[i] @ (fr.rot @ np.asarray(layout[i].side))).mean()) < 0
    for ln, pts, nrm, rev in zip(layout, on_image, normals, flip, strict=True):
        kind, group, taper = ln.kind, ln.group, ln.taper
        utaper = taper if ln.utaper is None else ln.utaper
        st = STYLES[kind]
        if rev:
            # orient the line so that its normal points to the ridge side (the reversed
            # line's normals are these, reversed and negated: its central differences are
            # the negated ones, exactly)
            pts, taper, utaper = pts[::-1].copy(), taper[::-1].copy(), utaper[::-1].copy()
            nrm = -nrm[::-1]
        q0 = len(queries)
        queries.append(pts)
        if ln.probes is None:
            queries += [pts + k * st.probe * iod * nrm for k in (-1.0, -0.33, 0.33, 1.0)]
        else:
            queries.append(next(probes))
            way = measures.get(ln.measure)
            if way is None:
                way = measures[ln.measure] = fr.rot @ np.asarray(ln.measure)
            nrm = np.repeat(way[None], len(pts), 0)
        lines.append((ln, kind, group, taper, utaper, pts, nrm, q0, len(queries)))
    cut = np.cumsum([0] + [len(q) for q in queries]).tolist()
    ti_all, bary_all = _locate(np.concatenate(queries), V, tris)
    tri_all = cand[ti_all]  # (every query's triangle at once: the same indices)
    for ln, kind, group, taper, utaper, pts, nrm, q0, q1 in lines:
        bary = bary_all[cut[q0]:cut[q0 + 1]]
        if ln.probes is None:
            # (the probe queries' blocks follow the line's, one per offset: np.stack of the
            # blocks along axis 1 is their (4, n) transposed)
            pt = tri_all[cut[q0 + 1]:cut[q1]].reshape(q1 - q0 - 1, len(pts)).T
        else:
            fixed = tri_all[cut[q0 + 1]:cut[q1]]
            pt = np.repeat(fixed[None], len(pts), 0)
        kinds.append(kind)
        if group not in gnames:
            gnames.append(group)
        groups.append(gnames.index(group))
        starts.append(starts[-1] + len(pts))
        all_tri.append(tri_all[cut[q0]:cut[q0 + 1]])
        all_bary.append(bary)
        all_probe.append(pt)
        all_n.append(nrm)
        all_taper.append(taper)
        all_utaper.append(utaper)
    T = V[mesh.triangles]
    E = np.stack([T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]], 2)  # (T, 2, 2) columns = edges
    det = E[:, 0, 0] * E[:, 1, 1] - E[:, 0, 1] * E[:, 1, 0]
    det = np.where(np.abs(det) < 1e-9, 1e-9, det)
    inv = np.stack([np.stack([E[:, 1, 1], -E[:, 0, 1]], 1),
                    np.stack([-E[:, 1, 0], E[:, 0, 0]], 1)], 1) / det[:, None, None]
    img = face.image
    grey = is_grey(img)
    tint = np.ones(3) if grey else np.array(SHADOW_TINT)
    fold = np.repeat(np.arange(len(kinds)), np.diff(starts))
    tri = np.concatenate(all_tri)
    bary = np.concatenate(all_bary)
    # skin colour around each fold in the photo: the median of a box around the line (the
    # majority of it is skin unless hair covers the place)
    t = mesh.triangles[tri]  # (the samples on the mesh: _on_mesh's sum, the same values)
    pos = _on_mesh(V, (t[:, 0], t[:, 1], t[:, 2]), (bary[:, 0:1], bary[:, 1:2], bary[:, 2:3]))
    h, w = img.shape[:2]
    m = 0.06 * iod
    # (each fold's samples are consecutive: every box at once)
    lo = clamp(np.floor(np.minimum.reduceat(pos, starts[:-1]) - m).astype(int), 0,
                 [w - 1, h - 1]).tolist()
    hi = clamp(np.ceil(np.maximum.reduceat(pos, starts[:-1]) + m).astype(int) + 1, 1,
                 [w, h]).tolist()
    skin = box_medians(img, [(x0, y0, x1, y1)
                             for (x0, y0), (x1, y1) in zip(lo, hi, strict=True)])
    return CreasePlan(kinds, np.array(groups), gnames, np.array(starts), tri, bary,
                      np.concatenate(all_probe), np.concatenate(all_n),
                      np.concatenate(all_taper), fold, inv, iod, tint, skin,
                      np.concatenate(all_utaper))


# ---------------------------------------------------------------------------- strength
@dataclass(eq=False)
class _Fast:
    """Flat per-sample constants and per-group ranges for the per-frame path."""

    used: np.ndarray  # (U,) triangles whose compression is read
    probe: np.ndarray  # (N, 4) indices into ``used``
    depth: np.ndarray  # (N,)
    c0: np.ndarray  # (N,)
    spread: np.ndarray  # (N,)
    edge: np.ndarray  # (N,) bool: first/last two samples of a fold (not smoothed)
    seg_a: np.ndarray  # (M,) first sample of each segment inside a fold (grouped)
    seg_rng: list[tuple[int, int]]  # per group: its slice of the segments
    sig: np.ndarray  # (G,) line half-width, px
    ridge: np.ndarray  # (G,) ridge brightening relative to the darkening
    off: np.ndarray  # (G,) ridge offset, px
    skin: np.ndarray  # (G, 3) float32 reference skin colour of each group
    dead: np.ndarray  # (N,) compression that does not fold yet
    # the samples of folds with FoldStyle.sign < 0 and what _spread reads for them: (3, M, 4)
    # vertex indices of their probe triangles, 4 x (M, 4) entries of those triangles' inverse
    # edge matrices and (M, 1) the line's tangent, both on the neutral mesh (the photo's, or
    # its neutralised face when it shows an expression: a smiling photo's neutral pushes the
    # lower lip back up, and is no pout)
    neg: np.ndarray = field(init=False)
    neg_tri: np.ndarray = field(init=False)
    neg_inv: tuple[np.ndarray, ...] = ()
    neg_t: tuple[np.ndarray, np.ndarray] = field(init=False)
    # (M,) their taper: a sample where the line fades out does not drive it (towards the
    # mouth corners a smile spreads that skin a little too)
    neg_fade: np.ndarray = field(init=False)
    # the samples of folds with FoldStyle.lift and what _lift_push reads for them: (U, 12)
    # vertices of the 4 probe triangles and (U, 2) the eye's corners of each of the U distinct
    # rows (a line's samples share their probes) and (K,) each sample's row, the frame's up
    # direction over the IOD, and (K,) the push measured on the photo's mesh (the frown
    # folds' on a photo with its own expression: from the neutral mesh's, see FoldStyle.frown)
    lift: np.ndarray = field(init=False)
    lift_v: np.ndarray = field(init=False)
    lift_a: np.ndarray = field(init=False)
    lift_row: np.ndarray = field(init=False)
    lift_up: np.ndarray = field(init=False)
    lift_base: np.ndarray = field(init=False)
    # the inner lips' middle (2.2, 2.3) and their gap on the neutral mesh, IOD: lips that part
    # are no pout (the mentalis pushes the lower lip up against the upper one)
    lips_mid: tuple[int, int] = (0, 0)
    lips_gap0: float = 0.0
    # the chin boss 2.10 and the chin 2.1 and their distance on the neutral mesh, IOD: the
    # groove needs the chin raiser (AU17: the boss pushed up over the chin)
    boss: tuple[int, int] = (0, 0)
    boss_gap0: float = 0.0
    iod: float = 1.0
    # brow effort (_brow_effort): the samples it drives and their weights, the inner brow
    # heads (4.1, 4.2) and inner eye corners (3.8, 3.11), the frame's up over the IOD, and
    # the inner brows' height over the eye corners and their gap (IOD) at rest
    effort_idx: np.ndarray = field(init=False)
    effort_w: np.ndarray = field(init=False)
    brow_v: np.ndarray = field(init=False)
    brow_rise0: float = 0.0
    brow_gap0: float = 0.0
    # the upper lids' raise (_add_lid_effort): the samples it drives and their weights, the
    # upper lids' middles (right, left) and eye corners, their opening at rest (IOD)
    lid_idx: np.ndarray = field(init=False)
    lid_w: np.ndarray = field(init=False)
    lid_v: np.ndarray = field(init=False)
    lid_open0: float = 0.0
    # the frown gate (_frown_gate): the samples of folds with FoldStyle.frown and their scale
    frown_idx: np.ndarray = field(init=False)
    frown_w: np.ndarray = field(init=False)
    # samples of folds that lie on the first samples of another fold of their group (the
    # upper_lip furrow on the nasolabial line) and those samples: one furrow, see _twins
    twin_a: np.ndarray = field(init=False)
    twin_b: np.ndarray = field(init=False)
    own_gap: np.ndarray | None = None  # (F,) photo's own compression per fold (None: neutral)
    own_w: np.ndarray | None = None  # (N,) log-spacing of the neutral mesh per sample (>= 0)
    own_sum: np.ndarray | None = None  # (F,) sum of own_w ** 2 per fold
    # (F,) the per-frame path's per-fold constants of the unfold share: its divisor and fade-in
    own_div: np.ndarray | None = None
    own_fade: np.ndarray | None = None
    # (2N,) ``edge`` twice and ``taper`` followed by ``utaper``: the fold and unfold strengths
    # smoothed and tapered as one array (see _strengths; set with the own fields)
    edge2: np.ndarray | None = None
    taper2: np.ndarray | None = None
    # per-face constants of the per-frame path (gathered once, not every frame; set by _fast)
    used_tri: np.ndarray = field(init=False)  # (3, U) vertex indices of the ``used`` triangles
    used_inv: tuple[np.ndarray, ...] = ()  # their inverse edge matrices: 4 x (U,) entries
    probe_t: np.ndarray = field(init=False)  # (4, N) ``probe`` transposed (contiguous)
    tx: np.ndarray = field(init=False)  # (N,) fold tangent x, y (the normal turned by -90 deg)
    ty: np.ndarray = field(init=False)
    sample_tri: tuple[np.ndarray, ...] = ()  # 3 x (N,) vertex indices of each sample's
    bary: tuple[np.ndarray, ...] = ()  # triangle and 3 x (N, 1) its barycentric coordinates
    keep: np.ndarray = field(init=False)  # (N,) 1 - spread
    seg_b: np.ndarray = field(init=False)  # (M,) seg_a + 1: the last sample of each segment
    # (G,) the drawn line's half-width, px: ``sig`` seen through the photo's own blur (a soft
    # photo, see _draw_sigma); ``sig`` itself on a sharp one
    dsig: np.ndarray = field(init=False)
    ref_l: np.ndarray = field(init=False)  # (G,) luminance of ``skin`` (at least 20)
    skin_shift: list[np.ndarray] = field(init=False)  # per group (3, 4) ``cv2.transform``: - skin
    # per group (3, 3) ``cv2.transform`` of (light, dark, 1) to the per-channel gain
    gain_mat: list[np.ndarray] = field(init=False)
    # what the per-frame path reads of the plan (its own arrays): each fold's first sample,
    # each sample's fold and its fade
    starts: np.ndarray = field(init=False)
    fold: np.ndarray = field(init=False)
    taper: np.ndarray = field(init=False)
    # looked up once per face on the first frame that needs them (the same objects as the
    # per-face caches' of :func:`_seg_constants`, :func:`_both_samples` and :func:`_photo_gain`)
    segc: _SegConstants | None = None
    both: tuple | None = None
    gains: dict = field(default_factory=dict)
    # per set of drawn groups (valleys', folds'): its :class:`_DrawnSegments`
    hits: dict = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class _LayoutStructure:
    """What :func:`_fast` takes from the fold layout alone (the folds' kinds, groups and
    sample counts: the same for every face, :func:`_fold_lines`); read-only arrays."""

    depth: np.ndarray  # (N,) per sample, its fold style's
    c0: np.ndarray
    spread: np.ndarray
    dead: np.ndarray
    neg: np.ndarray  # the samples of folds with FoldStyle.sign < 0
    edge: np.ndarray  # (N,) bool: first/last two samples of a fold
    seg_a: np.ndarray  # (M,) first sample of each segment inside a fold (grouped)
    seg_rng: list[tuple[int, int]]  # per group: its slice of the segments
    first: list[FoldStyle]  # per group: the style of its first fold
    count: np.ndarray  # (G,) folds per group
    lift: np.ndarray  # the samples of folds with FoldStyle.lift
    keep: np.ndarray  # (N,) 1 - spread
    seg_b: np.ndarray  # (M,) seg_a + 1
    twin_a: np.ndarray  # :func:`_twin_samples`
    twin_b: np.ndarray
    effort_idx: np.ndarray  # the samples of folds with FoldStyle.effort
    effort_w: np.ndarray  # (len(effort_idx),) their FoldStyle.effort (x effort_mid's profile)


#: the layouts' structures (one per distinct layout: in practice one per process)
_STRUCTURES: dict[tuple, _LayoutStructure] = {}


def _layout_structure(p: CreasePlan) -> _LayoutStructure:
    """:class:`_LayoutStructure` of ``p``'s layout (made once per layout: ~0.1 ms of small
    arrays per face before)."""
    key = (tuple(p.kinds), tuple(p.group_names), p.group.tobytes(), p.start.tobytes())
    got = _STRUCTURES.get(key)
    if got is not None:
        return got
    st = [STYLES[k] for k in p.kinds]
    spread = np.array([x.spread for x in st])[p.fold]
    effort = np.array([x.effort for x in st])[p.fold]
    mid = np.array([x.effort_mid for x in st])[p.fold]
    if (mid > 0).any():  # (the central profile along each line, where asked)
        first = p.start[:-1][p.fold]
        t = (np.arange(len(p.fold)) - first) / np.maximum(np.diff(p.start)[p.fold] - 1, 1)
        effort = np.where(mid > 0, effort * np.exp(-0.5 * ((t - 0.5)
                                                            / np.maximum(mid, 1e-6)) ** 2),
                          effort)
    effort_idx = np.flatnonzero(effort > 0)
    n = len(p.fold)
    edge = np.zeros(n, bool)
    for off in (0, 1):
        edge[clamp(p.start[:-1] + off, 0, n - 1)] = True
        edge[clamp(p.start[1:] - 1 - off, 0, n - 1)] = True
    seg_a = np.flatnonzero(p.fold[:-1] == p.fold[1:])
    seg_g = p.group[p.fold[seg_a]]
    order = np.argsort(seg_g, kind="stable")
    seg_a, seg_g = seg_a[order], seg_g[order]
    G = len(p.group_names)
    got = _LayoutStructure(
        np.array([x.depth for x in st])[p.fold], np.array([x.c0 for x in st])[p.fold], spread,
        np.array([x.dead for x in st])[p.fold],
        np.flatnonzero(np.array([x.sign for x in st])[p.fold] < 0), edge, seg_a,
        [(int(np.searchsorted(seg_g, g)), int(np.searchsorted(seg_g, g, "right")))
         for g in range(G)],
        [STYLES[p.kinds[int(np.flatnonzero(p.group == g)[0])]] for g in range(G)],
        np.bincount(p.group, minlength=G),
        np.flatnonzero(np.array([x.lift for x in st], bool)[p.fold]), 1.0 - spread, seg_a + 1,
        *_twin_samples(p), effort_idx, effort[effort_idx])
    for a in vars(got).values():
        if isinstance(a, np.ndarray):
            a.setflags(write=False)
    _STRUCTURES[key] = got
    return got


_FAST: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _unique_rows(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(x, axis=0, return_inverse=True)`` of a non-empty 2-D integer array, the
    same rows (in lexicographic order) and flat inverse, from one ``np.lexsort`` (np.unique's
    structured-view path costs ~60 us more on a face's 32 lift rows)."""
    order = np.lexsort(x.T[::-1])
    s = x[order]
    new = np.empty(len(s), bool)
    new[0] = True
    np.any(s[1:] != s[:-1], 1, out=new[1:])
    inv = np.empty(len(s), np.intp)
    inv[order] = np.cumsum(new) - 1
    return s[new], inv


def _fast(face: Face) -> _Fast:
    f = _FAST.get(face)
    if f is not None:
        return f
    p = crease_plan(face)
    # (np.unique's sorted values and inverse, from a mark per triangle: no sort)
    flat = p.probe_tri.reshape(-1)
    mark = np.zeros(len(p.tri_inv), bool)
    mark[flat] = True
    used = np.flatnonzero(mark).astype(p.probe_tri.dtype, copy=False)
    slot = np.zeros(len(mark), np.intp)
    slot[used] = np.arange(len(used))
    inv = slot[flat]
    ls = _layout_structure(p)
    depth, c0, spread, dead, neg, edge = ls.depth, ls.c0, ls.spread, ls.dead, ls.neg, ls.edge
    seg_a, rng, first, cnt = ls.seg_a, ls.seg_rng, ls.first, ls.count
    G = len(p.group_names)
    sig = np.array([max(x.sigma * p.iod, 0.6) for x in first])
    dsig = _draw_sigma(face, sig)
    # (each group's mean of its folds' skin colours, all groups at once: the colours are
    # medians of uint8 values, multiples of 0.5, whose few sums are exact in any order)
    skin = np.empty((G, 3))
    for ch in range(3):
        skin[:, ch] = np.bincount(p.group, p.skin[:, ch], minlength=G)
    skin = (skin / cnt[:, None]).astype(np.float32)
    f = _Fast(used, inv.reshape(p.probe_tri.shape), depth, c0, spread, edge, seg_a, rng, sig,
              np.array([x.ridge for x in first]), np.array([x.ridge_off for x in first]) * dsig,
              skin, dead)
    f.dsig = dsig
    f.neg = neg
    ptri = face.mesh.triangles[p.probe_tri[neg]]  # (M, 4, 3)
    f.neg_tri = np.ascontiguousarray(np.moveaxis(ptri, -1, 0))
    tang = np.stack([-p.normal[neg, 1], p.normal[neg, 0]], 1)  # (M, 2) on the photo's mesh
    pinv = p.tri_inv[p.probe_tri[neg]]  # (M, 4, 2, 2)
    # the neutral mesh: what deform(None) gives, the neutralised mesh itself (Face._neutralise
    # leaves it with lips and lids that meet but never cross and no folded triangle, so the
    # FAP model at f = 0 returns it as is; tests/test_plan_build.py checks it), without a
    # deformation's ~0.2 ms
    rest = face.neutral_vertices if face.has_expression else face.vertices
    if face.has_expression and len(neg):
        N = np.asarray(rest, np.float64)
        E = np.stack([N[ptri[..., 1]] - N[ptri[..., 0]], N[ptri[..., 2]] - N[ptri[..., 0]]],
                     -1)  # (M, 4, 2, 2) columns: the edges
        # the tangent carried onto the neutral mesh by the sample's first probe triangle
        tn = np.einsum("mij,mjk,mk->mi", E[:, 0], pinv[:, 0], tang)
        tang = tn / np.maximum(np.linalg.norm(tn, axis=1, keepdims=True), 1e-12)
        pinv = np.linalg.inv(E)
    f.neg_inv = tuple(np.ascontiguousarray(pinv[..., i, j]) for i in (0, 1) for j in (0, 1))
    f.neg_t = (np.ascontiguousarray(tang[:, :1]), np.ascontiguousarray(tang[:, 1:]))
    f.neg_fade = p.taper[neg]
    lift = ls.lift
    f.lift = lift
    lift_v = face.mesh.triangles[p.probe_tri[lift]].reshape(len(lift), -1)
    ix = face.mesh.index
    # (each lift fold's group is named after its side's eye: "lower_lid_r", "nasolabial_l")
    side = [p.group_names[g][-1] for g in p.group[p.fold[lift]].tolist()]
    corners = {sd: [ix(f"eye_{sd}_c0"), ix(f"eye_{sd}_c1")] for sd in set(side)}
    lift_a = np.array([corners[sd] for sd in side], np.intp).reshape(len(lift), 2)
    rows, f.lift_row = _unique_rows(np.concatenate([lift_v, lift_a], 1).reshape(len(lift), -1))
    f.lift_v = np.ascontiguousarray(rows[:, :lift_v.shape[1]])
    f.lift_a = np.ascontiguousarray(rows[:, lift_v.shape[1]:])
    f.lift_up = -face.frame.rot[:, 1] / float(face.interocular)
    f.lift_base = np.zeros(len(lift))  # (the push on the photo's mesh, measured from zero)
    f.lift_base = _lift_push(f, face.vertices)
    f.lips_mid = (face.mesh.fdp["2.2"], face.mesh.fdp["2.3"])
    f.iod = float(face.interocular)
    f.lips_gap0 = _gap(f, f.lips_mid, rest)
    f.boss = (face.mesh.fdp["2.10"], face.mesh.fdp["2.1"])
    f.boss_gap0 = _gap(f, f.boss, rest)
    f.effort_idx, f.effort_w = ls.effort_idx, ls.effort_w
    f.brow_v = np.array([face.mesh.fdp[k] for k in ("4.1", "4.2", "3.8", "3.11")])
    # (zero on the photo's mesh and on the neutral one: a photo's own effort is in its pixels)
    f.brow_rise0, f.brow_gap0 = _brow_pose(f, face.vertices)
    r, g = _brow_pose(f, rest)
    f.brow_rise0, f.brow_gap0 = max(f.brow_rise0, r), min(f.brow_gap0, g)
    lw = np.array([STYLES[k].effort_lid for k in p.kinds])[p.fold]
    f.lid_idx = np.flatnonzero(lw > 0)
    f.lid_w = lw[f.lid_idx]
    f.lid_v = np.array([ix(n) for n in ("eye_r_u3", "eye_l_u3", "eye_r_c0", "eye_r_c1",
                                        "eye_l_c0", "eye_l_c1")])
    # (the wider of the photo's and the neutral mesh's: a photo's own wide eyes are in it)
    f.lid_open0 = max(_lid_open(f, face.vertices), _lid_open(f, rest))
    fw = np.array([STYLES[k].frown for k in p.kinds])[p.fold]
    f.frown_idx = np.flatnonzero(fw > 0)
    f.frown_w = fw[f.frown_idx]
    if len(f.frown_idx) and face.has_expression:
        # (their push from the neutral mesh: a smiling photo's raised cheek brings no nose
        # wrinkles to carry, and a target that lifts the cheek less than the photo's smile
        # still lifts it above the neutral)
        on = np.isin(lift, f.frown_idx)
        f.lift_base[on] = (_lift_push(f, rest) + f.lift_base)[on]
    f.used_tri = np.ascontiguousarray(face.mesh.triangles[used].T)
    inv = p.tri_inv[used]
    f.used_inv = tuple(np.ascontiguousarray(inv[:, i, j]) for i in (0, 1) for j in (0, 1))
    f.probe_t = np.ascontiguousarray(f.probe.T)
    f.tx, f.ty = -p.normal[:, 1], p.normal[:, 0]
    tri = face.mesh.triangles[p.tri]
    f.sample_tri = tuple(np.ascontiguousarray(tri[:, k]) for k in range(3))
    f.bary = tuple(np.ascontiguousarray(p.bary[:, k, None]) for k in range(3))
    f.keep, f.seg_b, f.twin_a, f.twin_b = ls.keep, ls.seg_b, ls.twin_a, ls.twin_b
    # (per row, as ``max(float(x.mean()), 20.0)`` of each; the transforms (3, 4): identity
    # and the negated colour, views of one array)
    f.ref_l = np.maximum(skin.mean(1).astype(np.float64), 20.0)
    shift = np.zeros((G, 3, 4), np.float32)
    shift[:, [0, 1, 2], [0, 1, 2]] = 1.0
    shift[:, :, 3] = -skin
    f.skin_shift = list(shift)
    # the blurred line and ridge canvases integrate to their weights: scaled back by the
    # Gaussians' 1-D integrals (sqrt(2 pi) sigma; the ridge's is 1.6 times wider). With the
    # line's own sigma, not the drawn one: a soft photo's fold is as dark in all (its
    # integral), shallower and wider
    k1s, k2s = math.sqrt(2 * math.pi) * sig, math.sqrt(2 * math.pi) * (1.6 * sig)
    # (a negative ridge is a shadow beside the line: it takes the line's colour tint too)
    # (per group, rows ``[k2 * (t if ridge < 0 else 1), -k1 * t, 1]`` per tint t: all groups'
    # at once, the same products, views of one array)
    tint = np.asarray(p.tint, np.float64)[None, :]
    mats = np.empty((G, len(p.tint), 3), np.float32)
    mats[:, :, 0] = np.where((f.ridge < 0)[:, None], k2s[:, None] * tint, k2s[:, None])
    mats[:, :, 1] = -k1s[:, None] * tint
    mats[:, :, 2] = 1.0
    f.gain_mat = list(mats)
    f.starts, f.fold, f.taper = p.start[:-1], p.fold, p.taper
    if face.has_expression:  # the photo's own folds: how much its neutral spreads them
        g = np.log(np.maximum(_spacing(face, rest, f), 1e-6))
        f.own_gap = np.maximum.reduceat(g, p.start[:-1])
        f.own_w = np.maximum(g, 0.0)  # samples weighted by their own compression
        f.own_sum = np.add.reduceat(f.own_w * f.own_w, p.start[:-1])
        f.own_div = np.maximum(f.own_sum, 1e-9)
        f.own_fade = clamp((f.own_gap - _OWN_MIN) / (0.7 * _OWN_MIN), 0.0, 1.0)
        f.edge2 = np.concatenate([f.edge, f.edge])
        f.taper2 = np.concatenate([p.taper, p.utaper])
    # published only when complete: the editor's render thread and its GUI thread may ask for
    # the same face's constants at once (published before the own folds' fields were set, a
    # render on the other thread could draw no unfold: a rare preview differing from a
    # re-render of the same document)
    _FAST[face] = f
    return f


def _twin_samples(p: CreasePlan) -> tuple[np.ndarray, np.ndarray]:
    """The samples of every upper_lip fold and those of the nasolabial fold of its group it
    lies on (its line is that line's first samples, see :func:`_fold_lines`)."""
    a: list[np.ndarray] = []
    b: list[np.ndarray] = []
    for i, kind in enumerate(p.kinds):
        if kind != "upper_lip":
            continue
        j = next(j for j, k in enumerate(p.kinds)
                 if k == "nasolabial" and p.group[j] == p.group[i])
        n = int(p.start[i + 1] - p.start[i])
        a.append(np.arange(p.start[i], p.start[i] + n))
        b.append(np.arange(p.start[j], p.start[j] + n))
    empty = np.zeros(0, np.intp)
    return (np.concatenate(a), np.concatenate(b)) if a else (empty, empty)


def _twins(fa: _Fast, s: np.ndarray) -> np.ndarray:
    """Fold strengths ``s`` with each upper_lip sample reduced to what it adds to the
    nasolabial fold under it: the two lines are drawn into one canvas, whose sum is then the
    darker of the two (one furrow, deepened by the lip raiser or by a smile, not by both
    added: a smile's would be too dark)."""
    if len(fa.twin_a):
        s[fa.twin_a] = np.maximum(s[fa.twin_a] - s[fa.twin_b], 0.0)
    return s


#: parting of the lips (IOD, beyond the neutral's) at which the chin groove is gone
_POUT_OPEN = 0.04


#: rise of the chin boss over the chin (IOD, beyond the neutral's) at which the groove is full
_POUT_BOSS = 0.02


def _gap(fa: _Fast, pair: tuple[int, int], vertices: np.ndarray) -> float:
    """Distance (IOD) between two points of the mesh."""
    a, b = np.asarray(vertices, np.float64).take(pair, 0)
    return float(math.hypot(*(b - a))) / fa.iod


def _closed_lips(fa: _Fast, vertices: np.ndarray) -> float:
    """How much of a pout the mesh shows, for the folds of kind chin: the chin boss raised
    (up to full at :data:`_POUT_BOSS`) with the lips together (fading out as they part by
    :data:`_POUT_OPEN`: an open mouth is no pout)."""
    # (both pairs' points in one gather; :func:`_gap`'s arithmetic on Python floats, and the
    # smoothstep of :func:`smooth01` on them: the same float64 values without a dozen numpy
    # calls on scalars)
    i0, i1 = fa.lips_mid
    j0, j1 = fa.boss
    (ax, ay), (bx, by), (cx, cy), (dx, dy) = np.asarray(vertices).take(
        (i0, i1, j0, j1), 0).astype(np.float64).tolist()
    opened = (math.hypot(bx - ax, by - ay) / fa.iod - fa.lips_gap0) / _POUT_OPEN
    raised = (math.hypot(dx - cx, dy - cy) / fa.iod - fa.boss_gap0) / _POUT_BOSS
    return (1.0 - smooth01_float(opened)) * smooth01_float(raised)


def _neg_compression(fa: _Fast, vertices: np.ndarray) -> np.ndarray | float:
    """What the folds of kind chin take as their compression (``fa.neg``'s samples): the
    spread across them less 1 (:func:`_spread`), times their taper and the pout
    (:func:`_closed_lips`). Without a pout it is 0.0 and the spread is not measured (the
    product would be a zero of either sign, which the callers' :data:`_C_TOL` turns into 0.0:
    the same values)."""
    pout = _closed_lips(fa, vertices)
    if pout == 0.0:
        return 0.0
    return (_spread(fa, vertices) - 1.0) * (fa.neg_fade * pout)


#: inner brow rise (AU1) and closing-in (AU4) beyond rest (in inner eye corners' distances,
#: about 0.45 IOD) at which each reaches 63 % of its share of the brow effort
_EFFORT_RISE = 0.07
_EFFORT_SQUEEZE = 0.07
#: effort below this is none (a turned head's brows and eye corners are not foreshortened
#: exactly alike in the mesh: up to 0.03 on the bench's head rotation); the rest rescaled
_EFFORT_DEAD = 0.05


def _brow_pose(fa: _Fast, vertices: np.ndarray) -> tuple[float, float]:
    """The inner brow heads' mean height over the inner eye corners' line and their distance,
    both over the eye corners' distance: a turned, nodded, tilted or scaled head keeps them
    (the brows and the eye corners are foreshortened alike), or lowers the height (a nod)."""
    (blx, bly), (brx, bry), (elx, ely), (erx, ery) = np.asarray(vertices).take(
        fa.brow_v, 0).astype(np.float64).tolist()
    dx, dy = erx - elx, ery - ely
    d2 = dx * dx + dy * dy
    # (the corners' line turned a quarter, towards the frame's up)
    nx, ny = dy, -dx
    if nx * float(fa.lift_up[0]) + ny * float(fa.lift_up[1]) < 0.0:
        nx, ny = -nx, -ny
    rise = 0.5 * ((blx - elx + brx - erx) * nx + (bly - ely + bry - ery) * ny) / d2
    return rise, math.hypot(blx - brx, bly - bry) / math.sqrt(d2)


def _brow_effort(fa: _Fast, vertices: np.ndarray,
                 pose: tuple[float, float] | None = None) -> float:
    """How hard the inner brows are raised while drawn together (0..1): the product of the
    rise's and the closing-in's saturating shares beyond rest, less a dead zone. Fear and
    sadness (AU1 + 4) score 0.3-0.4 at 100 %, 0.5-0.6 at 150 %; surprise (no closing-in),
    anger and disgust (lowered brows) and a turned head score 0. ``pose``:
    :func:`_brow_pose` of ``vertices`` when already known."""
    rise, gap = _brow_pose(fa, vertices) if pose is None else pose
    r, q = rise - fa.brow_rise0, fa.brow_gap0 - gap
    if r <= 0.0 or q <= 0.0:
        return 0.0
    e = (1.0 - math.exp(-r / _EFFORT_RISE)) * (1.0 - math.exp(-q / _EFFORT_SQUEEZE))
    return max(e - _EFFORT_DEAD, 0.0) / (1.0 - _EFFORT_DEAD)


def _add_effort(fa: _Fast, c: np.ndarray, vertices: np.ndarray, e: float | None = None
                ) -> None:
    """Add the brow effort's compression to the samples it drives (in place; nothing when
    there is no effort: the same values). ``e``: :func:`_brow_effort` when already known."""
    if e is None:
        e = _brow_effort(fa, vertices)
    if e > 0.0:
        c[fa.effort_idx] += fa.effort_w * e


#: the upper lids' raise beyond rest (IOD) at which their share of the lid effort reaches 63 %
_LID_RAISE = 0.03


def _lid_open(fa: _Fast, vertices: np.ndarray) -> float:
    """The upper lids' middles' mean height over their eye corners' middle (IOD, along the
    frame's up)."""
    # (Python floats, as in :func:`_brow_pose`: a dozen numpy calls on scalars cost more)
    (urx, ury), (ulx, uly), (ax, ay), (bx, by), (cx, cy), (dx, dy) = np.asarray(
        vertices).take(fa.lid_v, 0).astype(np.float64).tolist()
    upx, upy = fa.lift_up.tolist()
    return ((0.5 * (urx + ulx) - 0.25 * (ax + bx + cx + dx)) * upx
            + (0.5 * (ury + uly) - 0.25 * (ay + by + cy + dy)) * upy)


def _add_lid_effort(fa: _Fast, c: np.ndarray, vertices: np.ndarray, e: float | None = None
                    ) -> None:
    """Add to the samples of folds with FoldStyle.effort_lid (in place) their weight times
    the brow effort times the upper lids' raise share ``1 - exp(-raise / _LID_RAISE)`` (raise
    beyond rest, IOD): raised, knitted brows over wide-open eyes (AU1 + 4 + 5, fear), not
    over lowered lids (sadness) nor wide eyes under brows that do not close in (surprise).
    Nothing without both: the same values. ``e``: :func:`_brow_effort` when already known."""
    if e is None:
        e = _brow_effort(fa, vertices)
    if e <= 0.0:
        return
    r = _lid_open(fa, vertices) - fa.lid_open0
    if r > 0.0:
        c[fa.lid_idx] += fa.lid_w * (e * (1.0 - math.exp(-r / _LID_RAISE)))


#: inner brow lowering below rest (in inner eye corners' distances, about 0.5 IOD) that opens
#: no frown gate yet: the ten JAFFE meshes' median at 100 % (presets): joy 0.022, disgust
#: 0.116, anger 0.135 (sadness, fear, surprise raise the inner brows)
_FROWN_DEAD = 0.04


def _frown_gate(fa: _Fast, c: np.ndarray, vertices: np.ndarray,
                pose: tuple[float, float] | None = None) -> None:
    """Multiply the samples of folds with FoldStyle.frown (in place) by how far the inner brows
    are lowered: ``smooth01((lowering - _FROWN_DEAD) / frown)``, the lowering below the inner
    brow heads' rest height over the inner eye corners (:func:`_brow_pose`; ``pose``: its
    value when already known)."""
    low = fa.brow_rise0 - (_brow_pose(fa, vertices) if pose is None else pose)[0] - _FROWN_DEAD
    if low <= 0.0:
        c[fa.frown_idx] = 0.0
        return
    c[fa.frown_idx] *= smooth01(low / fa.frown_w)


def _brow_terms(fa: _Fast, c: np.ndarray, vertices: np.ndarray) -> None:
    """The brow-driven terms of the compression ``c`` (in place, in this order): the frown
    gate (:func:`_frown_gate`), the brow effort (:func:`_add_effort`) and the lid effort
    (:func:`_add_lid_effort`), with the brow pose and the effort measured once for all three
    (the same values as the three calls each measuring them)."""
    if not (len(fa.frown_idx) or len(fa.effort_idx) or len(fa.lid_idx)):
        return
    pose = _brow_pose(fa, vertices)
    if len(fa.frown_idx):
        _frown_gate(fa, c, vertices, pose)
    if len(fa.effort_idx) or len(fa.lid_idx):
        e = _brow_effort(fa, vertices, pose)
        if e > 0.0:
            if len(fa.effort_idx):
                _add_effort(fa, c, vertices, e)
            if len(fa.lid_idx):
                _add_lid_effort(fa, c, vertices, e)


def _lift_push(fa: _Fast, vertices: np.ndarray) -> np.ndarray:
    """(K,) for the samples ``fa.lift``: how far up (IOD) the skin at their probes lies
    relative to their eye's corners, beyond ``fa.lift_base`` (where it lies on the photo's
    mesh; the frown folds' measured from the neutral mesh on a photo with its own expression)."""
    V = np.asarray(vertices, np.float64)
    # (``mean(1)``'s values: its sum along the axis over the count, without its Python layers;
    # rows gathered with take; each distinct row once, then given to its samples)
    d = np.add.reduce(V.take(fa.lift_v, 0), 1) / fa.lift_v.shape[1]
    d -= np.add.reduce(V.take(fa.lift_a, 0), 1) / fa.lift_a.shape[1]
    return (d @ fa.lift_up).take(fa.lift_row) - fa.lift_base


def _spread(fa: _Fast, vertices: np.ndarray) -> np.ndarray:
    """(M,) for the samples ``fa.neg`` (folds with FoldStyle.sign < 0): the spacing of skin
    lines parallel to the fold over the stretch along it, relative to the neutral mesh (see
    ``_Fast.neg_inv``), mean over the 4 probes: ``det(A) / |A t|^2`` (1 at rest and under any
    similarity; > 1 where the skin across the line is spread more than along it)."""
    V = np.asarray(vertices, np.float64)
    # (x and y rows together, as in :func:`_spacing`: a0 = (a00, a10), a1 = (a01, a11) and
    # at = A t, each (2, M, 4); the same arithmetic, value by value)
    T = V.T.take(fa.neg_tri, 1)  # (2, 3, M, 4)
    e1, e2 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
    i00, i01, i10, i11 = fa.neg_inv
    a0 = e1 * i00
    a0 += e2 * i10
    a1 = e1 * i01
    a1 += e2 * i11
    tx, ty = fa.neg_t
    at = a0 * tx
    at += a1 * ty
    at *= at
    n = at[0]
    n += at[1]
    r = (a0[0] * a1[1] - a1[0] * a0[1]) / np.maximum(n, 1e-12, out=n)
    return r.mean(1)


def _spacing(face: Face | None, vertices: np.ndarray, fa: _Fast | None = None) -> np.ndarray:
    """(N,) spacing of skin lines parallel to each fold on ``vertices``, relative to the photo's
    mesh (1 = as in the photo, < 1 compressed, > 1 stretched), mean over its probes (``fa``:
    the face's :class:`_Fast`, when known or while it is being built; then ``face`` is not
    read)."""
    if fa is None:
        assert face is not None
        fa = _fast(face)
    V = np.asarray(vertices, np.float64)
    # (laid out as (x / y, ..., triangle or sample): every operation below runs along one
    # contiguous last axis, the x and y rows of each entry of A together; the same
    # arithmetic, value by value, as entry by entry)
    T = V.T.take(fa.used_tri, 1)  # (2, 3, U)
    e1, e2 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]  # (2, U): x and y of the edges
    # deformed = A @ photo (linear part per triangle): A = [e1 e2] @ inverse photo edges;
    # its columns (a00, a10) and (a01, a11) per triangle, then gathered per probe (4, N)
    i00, i01, i10, i11 = fa.used_inv
    a0 = e1 * i00
    a0 += e2 * i10
    a1 = e1 * i01
    a1 += e2 * i11
    pr = fa.probe_t
    det = (a0[0] * a1[1] - a1[0] * a0[1]).take(pr)
    # spacing of material lines parallel to the fold: det(A) / |A t| (t its tangent); shear
    # along the fold and stretch along it do not change it
    at = a0.take(pr, 1)
    at *= fa.tx
    at += a1.take(pr, 1) * fa.ty  # (2, 4, N): A t
    at *= at
    n = at[0]
    n += at[1]
    r = np.divide(det, np.maximum(np.sqrt(n, out=n), 1e-6, out=n), out=det)
    # the mean over the 4 probes: ((r0 + r1) + r2) + r3, a reduction over the outer axis
    # adding the rows in order
    got = np.add.reduce(r, 0)
    got *= 0.25
    return got


def _smooth_taper(face: Face, s: np.ndarray, own: bool = False) -> np.ndarray:
    """Smoothed along each line (no triangle steps), times the fade of its ends (``own``: that
    of the photo's own fold)."""
    p = crease_plan(face)
    # (the first and last two samples of every line are not smoothed: the zero padding of
    # "same" never shows)
    sm = np.convolve(s, _SMOOTH, mode="same")
    return np.where(_fast(face).edge, s, sm) * (p.utaper if own else p.taper)


def fold_strength(face: Face, vertices: np.ndarray, spacing: np.ndarray | None = None
                  ) -> np.ndarray:
    """(N,) darkening of every fold sample for a deformed mesh (0 at rest); ``spacing``:
    :func:`_spacing` of that mesh when already known."""
    p = crease_plan(face)
    fa = _fast(face)
    c = 1.0 - (_spacing(face, vertices) if spacing is None else spacing)
    if len(fa.neg):
        c[fa.neg] = _neg_compression(fa, vertices)
    if len(fa.lift):
        c[fa.lift] = _lift_push(fa, vertices)
    _brow_terms(fa, c, vertices)
    c[c < _C_TOL] = 0.0  # rounding of a rigid motion is no compression
    # a fold forms along its whole length once the skin is pushed together somewhere on it
    cmax = np.maximum.reduceat(c, p.start[:-1])[p.fold]
    c = np.maximum(fa.keep * c + fa.spread * cmax - fa.dead, 0.0)
    s = fa.depth * (1.0 - np.exp(-((c / fa.c0) ** 2)))
    # smooth along each line (no triangle steps), then taper the ends; one furrow per line
    return _twins(fa, _smooth_taper(face, s))


def unfold_strength(face: Face, vertices: np.ndarray, spacing: np.ndarray | None = None
                    ) -> np.ndarray:
    """(N,) share in [0, 1] of the photo's own fold to smooth away at every fold sample.

    A photo that smiles shows its own folds (nasolabial, cheeks). Its neutral mesh
    (``face.deform(None)``) spreads that skin by ``g = log spacing(neutral)`` (> 0 where the
    photo compresses it). A target mesh that spreads it by ``e = log spacing(target)`` unfolds
    the photo's fold by ``e / g`` (per fold: ``sum(max(e, 0) g+) / sum(g+^2)``, the least-squares
    ratio over its samples, clipped to [0, 1], faded in above :data:`_OWN_MIN` of own compression
    so that the estimate's noise on a neutral photo is no fold): 1 on the neutralised face, 0 on
    the photo's own expression (the photo's mesh: exactly no change) and wherever the target
    compresses the skin as much or more (then :func:`fold_strength` draws the fold).
    """
    fa = _fast(face)
    n = len(fa.depth)
    if fa.own_gap is None or fa.own_w is None or fa.own_sum is None:  # set together by _fast
        return np.zeros(n)
    p = crease_plan(face)
    e = np.log(np.maximum(_spacing(face, vertices) if spacing is None else spacing, 1e-6))
    e[e < _C_TOL] = 0.0
    esum = np.add.reduceat(e * fa.own_w, p.start[:-1])
    u = np.clip(esum / np.maximum(fa.own_sum, 1e-9), 0, 1)
    # a fold the photo barely compresses (the estimate's noise on a neutral photo) is no fold:
    # the share ramps in between _OWN_MIN and 1.7 * _OWN_MIN of own compression
    u = u * np.clip((fa.own_gap - _OWN_MIN) / (0.7 * _OWN_MIN), 0.0, 1.0)
    return _smooth_taper(face, u[p.fold], own=True)


def _strengths(face: Face, vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`fold_strength` and :func:`unfold_strength` of ``vertices`` together (one
    :func:`_spacing`, the per-face constants looked up once): the same values."""
    s, un, _ = _both_strengths(_fast(face), vertices)
    return s, un


def _both_strengths(fa: _Fast, vertices: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """:func:`_strengths` of the face of ``fa``, and both as one array (``s`` then ``un``,
    of which the two are views; None when the photo has no own fold)."""
    # (float64 once: every measure below converts the vertices to it, or reads them as such)
    vertices = np.asarray(vertices, np.float64)
    sp = _spacing(None, vertices, fa)
    starts, fold = fa.starts, fa.fold
    # fold_strength
    c = 1.0 - sp
    if len(fa.neg):
        c[fa.neg] = _neg_compression(fa, vertices)
    if len(fa.lift):
        c[fa.lift] = _lift_push(fa, vertices)
    _brow_terms(fa, c, vertices)
    c[c < _C_TOL] = 0.0
    cmax = np.maximum.reduceat(c, starts).take(fold)
    c = fa.keep * c
    c += fa.spread * cmax
    c -= fa.dead
    np.maximum(c, 0.0, out=c)
    # depth (1 - exp(-(c / c0)^2)), in place
    c /= fa.c0
    c *= c
    np.negative(c, out=c)
    np.exp(c, out=c)
    np.subtract(1.0, c, out=c)
    s = np.multiply(fa.depth, c, out=c)
    if (fa.own_w is None or fa.own_div is None or fa.own_fade is None or fa.edge2 is None
            or fa.taper2 is None):
        s = _twins(fa, np.where(fa.edge, s, _correlate(s, _SMOOTH_REV, "same")) * fa.taper)
        return s, np.zeros(len(fa.depth)), None
    # unfold_strength (its per-fold constants taken once per face)
    e = np.log(np.maximum(sp, 1e-6))
    e[e < _C_TOL] = 0.0
    esum = np.add.reduceat(e * fa.own_w, starts)
    esum /= fa.own_div
    u = (np.minimum(np.maximum(esum, 0), 1, out=esum) * fa.own_fade).take(fold)
    # both smoothed along their lines and tapered as one array (s then u): each sample's
    # 5-tap sum is the one of its own array, but for the last two samples of s and the first
    # two of u, which are line ends (``edge``: not smoothed)
    su = np.concatenate((s, u))
    su = np.where(fa.edge2, su, _correlate(su, _SMOOTH_REV, "same"))
    su *= fa.taper2
    n = len(s)
    _twins(fa, su[:n])  # (in place)
    return su[:n], su[n:], su


#: the photo's own compression (log spacing of its neutral mesh) below which there is no fold
#: (JAFFE neutral photos: up to 0.07 from the estimate's noise; the sample's smile: 0.15-0.27)
_OWN_MIN = 0.07


_SMOOTH = np.array([1.0, 2.0, 3.0, 2.0, 1.0]) / 9.0
#: ``_SMOOTH`` reversed (contiguous): ``np.convolve(a, _SMOOTH, mode)`` is
#: ``_correlate(a, _SMOOTH_REV, mode)``, the compiled function it calls (for ``len(a) >= 5``)
_SMOOTH_REV = np.ascontiguousarray(_SMOOTH[::-1])


@functools.lru_cache(maxsize=64)
def _sub_steps(k: int) -> np.ndarray:
    """``(arange(k) + 0.5) / k``: where a segment's ``k`` sub-samples lie along it (kept
    read-only: k is at most 64, and three arrays a frame cost as much as their use)."""
    u = (np.arange(k) + 0.5) / k
    u.setflags(write=False)
    return u


# ---------------------------------------------------------------------------- drawing
def _splat2(shape: tuple[int, int], xy: np.ndarray, w: np.ndarray, xy2: np.ndarray,
            w2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two canvases with weights added at sub-pixel positions (bilinear), one bincount."""
    h, wd = shape
    P = np.concatenate([xy, xy2])
    W = np.concatenate([w, w2])
    x0 = np.floor(P[:, 0])
    y0 = np.floor(P[:, 1])
    fx, fy = P[:, 0] - x0, P[:, 1] - y0
    base = (y0.astype(np.int64) * wd + x0.astype(np.int64))
    base[len(xy):] += h * wd  # the second canvas follows the first
    idx = np.concatenate([base, base + 1, base + wd, base + wd + 1])
    ws = np.concatenate([W * (1 - fx) * (1 - fy), W * fx * (1 - fy), W * (1 - fx) * fy,
                         W * fx * fy])
    acc = np.bincount(idx, ws, minlength=2 * h * wd)[: 2 * h * wd].astype(np.float32)
    return acc[: h * wd].reshape(h, wd), acc[h * wd:].reshape(h, wd)


_MEAN3 = np.full((1, 3), 1.0 / 3.0, np.float32)
#: ``cv2.max`` with a scalar bound (OpenCV's stubs type its second argument as an array only;
#: on one channel a number is a bound for every element)
_cv_max = cast("Callable[..., np.ndarray]", cv2.max)


def apply_creases(face: Face, res: WarpResult, vertices: np.ndarray) -> WarpResult:
    """Darken the folds of the deformed mesh ``vertices`` into ``res.image`` (in place).

    Returns ``res`` unchanged when no fold is compressed (e.g. a zero FAP vector), else a
    result whose ``bbox`` also covers every pixel written.

    Every canvas of the frame (the unfold bands, each fold group's line and ridge) depends on
    the mesh only: they are laid out and splatted together first (:func:`_layout`), then
    drawn in the same order as one at a time (the unfold bands, then the folds).
    """
    fa = _fast(face)
    V = np.asarray(vertices, np.float64)
    s, un, su = _both_strengths(fa, V)
    any_fold = bool(np.count_nonzero(s > _MIN_STRENGTH))
    any_unfold = bool(np.count_nonzero(un > _MIN_UNFOLD))
    if not any_fold and not any_unfold:
        return res
    out = res.image
    bbox = res.bbox
    # the segments of the fold samples, followed by the valley's on the deformed mesh when
    # unfolds are drawn (both sets in one gather and one measurement: the same values row
    # by row)
    if any_unfold:
        if fa.both is None:
            fa.both = _both_samples(face)
        samples = fa.both
    else:
        samples = (fa.sample_tri, fa.bary, fa.seg_a, fa.seg_b)
    unfolds, folds, drawn = _layout(face, V, samples, s, un if any_unfold else None,
                                    out.shape[:2], res.maps, fa, su)
    if not drawn:
        return res
    q = _frame_blocks(face)
    if unfolds:
        bbox = _unfold_draw(face, out, unfolds, drawn, bbox, res.maps, res.interpolation, fa,
                            q)
    for g, box, k, f in folds:
        bbox = _fold_draw(fa, out, g, box, drawn[k], drawn[k + 1], bbox, f, q)
    if bbox is None or bbox == res.bbox:  # None: res.bbox is None and nothing was drawn
        return res
    return _rebox(res, bbox, {})


def _draw_sigma(face: Face, sig: np.ndarray) -> np.ndarray:
    """(G,) half-widths the folds are drawn with: ``sig`` on a sharp photo; on a soft one (a
    large face from an upscaled or defocused picture, whose edges span ``soft`` px 10-90 %,
    :attr:`layers.LayerPlan.soft`) the line seen through the same blur, a Gaussian of sigma
    ``soft / 2.56``: a fold one-third as wide as the photo's finest edge read as a drawn scratch
    (the nose bridge's line under anger at IOD 328 px: sigma 3.6 px on a photo blurred by 4)."""
    soft = layer_plan(face).soft
    if soft <= 1.0:
        return sig
    return np.sqrt(sig * sig + (soft / 2.56) ** 2)


@dataclass(frozen=True, eq=False)
class _SegConstants:
    """Per fast plan, what the frame's layout (:func:`_layout`) reads of the segments: the
    non-empty fold groups ``(group, first segment, end)`` and the first segment of each
    (their segments are consecutive, in order), and for the segments of the fold samples
    followed by the valley's (2M, the strengths ``s`` followed by ``un``): their end samples
    ``sa2``, ``sb2`` and the strength above which a segment is drawn ``thr2``."""

    nonempty: list[tuple[int, int, int]]
    starts: list[int]
    starts2: list[int]  # ``starts`` followed by the same shifted to the valley's segments
    sa2: np.ndarray
    sb2: np.ndarray
    thr2: np.ndarray



def _seg_constants(fa: _Fast) -> _SegConstants:
    """The segments' constants of a fast plan (kept on it: ``fa.segc``)."""
    nonempty = [(g, g0, g1) for g, (g0, g1) in enumerate(fa.seg_rng) if g1 > g0]
    n, m = len(fa.depth), len(fa.seg_a)
    starts = [g0 for _, g0, _ in nonempty]
    return _SegConstants(
        nonempty, starts, starts + [g0 + m for g0 in starts],
        np.concatenate([fa.seg_a, fa.seg_a + n]), np.concatenate([fa.seg_b, fa.seg_b + n]),
        np.concatenate([np.full(m, _MIN_STRENGTH), np.full(m, _MIN_UNFOLD)]))


@dataclass(frozen=True, eq=False)
class _Subsamples:
    """The sub-samples of a frame's canvases (:func:`_subsamples`), canvas after canvas, each
    segment's ``K`` ones in order: per sub-sample its segment ``si``, its place along it
    ``uu`` (``(k + 0.5) / K``), ``K`` itself as a float ``kk``, the
    ridge's offset from the line ``rm`` (0 off a ridge) and its weight factor ``wm``
    (1 off a ridge); per canvas its first sub-sample ``cut`` and its count ``count``, and per
    sub-sample its canvas ``cpt``."""

    si: np.ndarray
    uu: np.ndarray
    kk: np.ndarray
    rm: np.ndarray
    wm: np.ndarray
    cut: list[int]
    count: list[int]
    cpt: np.ndarray


@functools.lru_cache(maxsize=256)
def _subsamples(spec: tuple[tuple[int, int, int, float, float], ...]) -> _Subsamples:
    """:class:`_Subsamples` of canvases ``(first segment, end, K, ridge offset, ridge weight)``
    (kept: a frame's spec recurs from frame to frame; read-only arrays)."""
    si, uu, kk, rm, wm, count = [], [], [], [], [], []
    for s0, s1, K, off, wr in spec:
        n = (s1 - s0) * K
        si.append(np.arange(s0, s1).repeat(K))
        uu.append(np.tile(_sub_steps(K), s1 - s0))
        kk.append(np.full(n, float(K)))
        rm.append(np.full(n, off))
        wm.append(np.full(n, wr))
        count.append(n)
    cat = np.concatenate
    u = cat(uu)
    got = _Subsamples(cat(si), u, cat(kk), cat(rm), cat(wm),
                      list(itertools.accumulate([0, *count[:-1]])), count,
                      np.arange(len(spec)).repeat(count))
    for a in vars(got).values():
        if isinstance(a, np.ndarray):
            a.setflags(write=False)
    return got


def _layout(face: Face, V: np.ndarray, samples: tuple, s: np.ndarray,
            un: np.ndarray | None, shape: tuple[int, int],
            maps: tuple[np.ndarray, np.ndarray, tuple[int, int, int, int]] | None,
            fa: _Fast, su: np.ndarray | None
            ) -> tuple[list[tuple], list[tuple[int, tuple[int, int, int, int], int, int]],
                       list[np.ndarray]]:
    """Every canvas of the frame, laid out and splatted: the bands of :func:`_unfold_draw`
    (per group with a live own fold, ``(g, f, got, pts, w, d, L, K, M, box, canvas index)``:
    the band's sub-samples ``pts`` (every segment's ``K``, at most 0.5 ``f`` px apart) and
    weights ``w``, its segments ``d`` and lengths ``L``, ``M`` of them), then per fold group
    with a sample above :data:`_MIN_STRENGTH` its box and two canvases, the dark line's
    samples and the ridge's beside it (``(group, box, index of its first canvas, f)``,
    canvases at 1/f resolution, :func:`_fold_scale`); and the canvases splatted
    (:func:`_splat_many`'s values).

    ``samples``: ``(tri, bary, seg_a, seg_b)`` of the fold samples (:func:`_on_mesh`'s
    arguments and the segments between them, ``seg_a`` -> ``seg_b``), followed by those of the
    valley's when ``un`` is given (the unfold shares; None: no unfold is drawn), placed on the
    deformed mesh ``V`` (float64). All canvases' sub-samples are placed, weighted and
    splatted as one array (the same values, point by point, as canvas by canvas): the samples
    and the segments' data as rows (x, y along one contiguous axis; :func:`_on_mesh`'s values
    and each segment's start, direction and length ``sqrt(dx dx + dy dy)``), every
    segment's start, direction, normal, end strengths and length gathered per sub-sample in
    one ``take``. ``fa``: the face's :class:`_Fast`; ``su``: ``s`` followed by ``un`` as one
    array (of which both are views; None with ``un``)."""
    sc = fa.segc
    if sc is None:
        sc = fa.segc = _seg_constants(fa)
    if not sc.nonempty:
        return [], [], []
    H, W = shape
    m = len(fa.seg_a)
    thr: float | np.ndarray
    if un is None:  # (the fold segments only)
        sv, sa_i, sb_i, thr = s, fa.seg_a, fa.seg_b, _MIN_STRENGTH
        starts = sc.starts
    else:
        assert su is not None  # (given with un)
        sv = su
        sa_i, sb_i, thr = sc.sa2, sc.sb2, sc.thr2
        starts = sc.starts2
    end = sc.nonempty[-1][2] + (m if un is not None else 0)
    hit = np.logical_or.reduceat(
        (np.maximum(sv.take(sa_i), sv.take(sb_i)) > thr)[:end], starts).tolist()
    ng = len(sc.nonempty)
    # (hit: the fold groups', then the valley's when unfolds are drawn)
    folds = [grp for grp, h in zip(sc.nonempty, hit[:ng], strict=True) if h]
    valleys = [grp for grp, h in zip(sc.nonempty, hit[ng:], strict=False) if h]
    if not folds and not valleys:
        return [], [], []
    # the segments of the groups drawn (the valleys', then the folds'), as one array
    key = (tuple(g for g, _, _ in valleys), tuple(g for g, _, _ in folds))
    hl = fa.hits.get(key)
    if hl is None:
        hl = fa.hits[key] = _drawn_segments(
            samples,
            [(m + g0, m + g1) for _, g0, g1 in valleys] + [(g0, g1) for _, g0, g1 in folds])
    # their rows: start x y (0, 1), direction (2, 3), unit normal (-dy, dx) (4, 5), the
    # strengths at their ends (6, 7: start, end - start) and length (8)
    VT = V.T
    (t0, t1, t2), (b0, b1, b2) = hl.tri, hl.bary
    pos = VT.take(t0, 1) * b0 + VT.take(t1, 1) * b1 + VT.take(t2, 1) * b2
    Z = np.empty((9, len(hl.a)))
    pos.take(hl.a, 1, out=Z[0:2])
    np.subtract(pos.take(hl.b, 1), Z[0:2], out=Z[2:4])
    dx, dy = Z[2], Z[3]
    L = Z[8]
    np.sqrt(np.add(dx * dx, dy * dy, out=L), out=L)
    np.multiply(Z[3:1:-1], _TURN_COL, out=Z[4:6])
    Z[4:6] /= np.maximum(L, 1e-9)
    sv.take(hl.sa, out=Z[6])
    np.subtract(sv.take(hl.sb), Z[6], out=Z[7])
    # each drawn group's longest segment
    longest = np.maximum.reduceat(L, hl.starts).tolist()
    nv = len(valleys)
    # per canvas: (first segment, end, K, ridge offset, ridge weight); its job's data, and
    # the pad of its box around its points and its scale (1/f resolution)
    spec: list[tuple[int, int, int, float, float]] = []
    pads: list[float] = []
    fs: list[int] = []
    bands = []
    for i, (g, _, _) in enumerate(valleys):
        sb_ = max(2.5 * float(fa.sig[g]), 1.0)  # half-width of the band that is lifted
        if maps is None:
            got = None
        else:
            got = fa.gains.get(g, fa)
            if got is fa:
                got = fa.gains[g] = _photo_gain(face, g)
        # the band is smooth (a line blurred by sb): drawn at 1/f resolution on large faces
        f = 1 if got is None else max(1, int(sb_ / 1.5))
        K = int(min(max(math.ceil(longest[i] / (0.5 * f)), 1), 64))
        spec.append((*hl.ranges[i], K, 0.0, 1.0))
        bands.append((g, got, f, K))
        pads.append(3.0 * sb_)
        fs.append(f)
    lines = []
    for j, (g, _, _) in enumerate(folds):
        sig = float(fa.sig[g])
        f = _fold_scale(float(fa.dsig[g]))
        K = int(min(max(math.ceil(longest[nv + j] / (min(0.5, 0.5 * sig) * f)), 1), 64))
        g0, g1 = hl.ranges[nv + j]
        spec += [(g0, g1, K, 0.0, 1.0), (g0, g1, K, float(fa.off[g]), float(fa.ridge[g]))]
        lines.append((g, f))
        pads.append(3.0 * (1.6 * float(fa.dsig[g])) + 2.0)
        fs += [f, f]
    ss = _subsamples(tuple(spec))
    # every sub-sample at once: a + d u (+ the ridge's offset along the normal), its weight
    # (sa + (sb - sa) u) L / K (times the ridge's)
    Zs = Z.take(ss.si, 1)
    uu = ss.uu
    xy = Zs[2:4] * uu
    xy += Zs[0:2]
    xy += Zs[4:6] * ss.rm
    w = Zs[7] * uu
    w += Zs[6]
    w *= Zs[8] / ss.kk
    w *= ss.wm
    # the extent of each canvas's points in one pass
    (lx_, ly_), (hx_, hy_) = (np.minimum.reduceat(xy, ss.cut, 1).tolist(),
                              np.maximum.reduceat(xy, ss.cut, 1).tolist())
    nb = len(bands)
    boxes: list[tuple[int, int, int, int] | None] = []
    for c in range(nb):
        pad = pads[c]
        x0, y0 = max(int(lx_[c] - pad), 0), max(int(ly_[c] - pad), 0)
        x1, y1 = min(int(hx_[c] + pad) + 1, W), min(int(hy_[c] + pad) + 1, H)
        boxes.append(None if x1 - x0 < 4 or y1 - y0 < 4 else (x0, y0, x1, y1))
    for j in range(len(lines)):
        c = nb + 2 * j
        pad = pads[nb + j]
        x0 = max(int(min(lx_[c], lx_[c + 1]) - pad), 0)
        y0 = max(int(min(ly_[c], ly_[c + 1]) - pad), 0)
        x1 = min(int(max(hx_[c], hx_[c + 1]) + pad) + 1, W)
        y1 = min(int(max(hy_[c], hy_[c + 1]) + pad) + 1, H)
        box = None if x1 - x0 < 2 or y1 - y0 < 2 else (x0, y0, x1, y1)
        boxes += [box, box]
    if None in boxes:  # (a box off the image: its canvases left out; rare)
        keep = np.array([b is not None for b in boxes]).repeat(ss.count)
        ci = np.cumsum([b is not None for b in boxes]) - 1
        xy, w = xy[:, keep], w[keep]
        cpt = ci[ss.cpt[keep]]
        count = [n for n, b in zip(ss.count, boxes, strict=True) if b is not None]
        cut = list(itertools.accumulate([0, *count[:-1]]))
    else:
        cpt, count, cut = ss.cpt, ss.count, ss.cut
    # each canvas's shape and its points' shift into its pixels (see _on_canvas): at the
    # photo's resolution by the box's corner, whole pixels, which the splat takes as an
    # offset into its canvas (the same pixels and fractions as the shifted points')
    shapes: list[tuple[int, int]] = []
    sub: list[tuple[float, float]] = []
    div: list[float] = []
    post: list[float] = []
    safe = True
    coarse = max(fs) > 1
    for box, f in zip(boxes, fs, strict=True):
        if box is None:
            continue
        x0, y0, x1, y1 = box
        safe = safe and x0 > 0 and y0 > 0 and x1 < W and y1 < H
        if f == 1:
            shapes.append((y1 - y0 + 1, x1 - x0 + 1))
            sub.append((x0, y0))
            post.append(0.0)
        else:
            shapes.append((-(-(y1 - y0) // f) + 1, -(-(x1 - x0) // f) + 1))
            sub.append((x0 - 0.5, y0 - 0.5))
            post.append(0.5)
        div.append(float(f))
    # the jobs, their canvases' indices counted over the canvases kept
    unfolds, jobs, k = [], [], 0
    for c, (g, got, f, K) in enumerate(bands):
        if boxes[c] is None:
            continue
        s0, s1 = spec[c][:2]
        a, b = cut[k], cut[k] + count[k]
        unfolds.append((g, f, got, xy[:, a:b].T, w[a:b], Z[2:4, s0:s1].T, L[s0:s1], K,
                        s1 - s0, boxes[c], k))
        k += 1
    for j, (g, f) in enumerate(lines):
        box = boxes[nb + 2 * j]
        if box is None:
            continue
        jobs.append((g, box, k, f))
        k += 2
    if coarse or not safe:
        # (each canvas's origin x, y, scale and shift, gathered per point in one take)
        at = np.array([[x for x, _ in sub], [y for _, y in sub], div, post]).take(cpt, 1)
        q = xy - at[0:2]
        if coarse:
            q /= at[2]
            q -= at[3]
        if not safe:  # a box clipped by the image's edge: canvas by canvas
            return unfolds, jobs, _splat_many(
                [(sh, q[:, a:a + n].T, w[a:a + n])
                 for sh, a, n in zip(shapes, cut, count, strict=True)])
        return unfolds, jobs, _splat_rows(shapes, q, w, cpt)
    return unfolds, jobs, _splat_rows(shapes, xy, w, cpt, sub)


@dataclass(frozen=True, eq=False)
class _DrawnSegments:
    """The segments a frame's canvases read (:func:`_drawn_segments`), in order: per segment
    its start and end in the samples placed (``a``, ``b``) and in the strengths (``sa``,
    ``sb``); the samples placed, 3 x (n,) vertex indices ``tri`` and 3 x (1, n) barycentric
    weights ``bary``; per drawn group its first segment ``starts`` and range ``ranges``."""

    a: np.ndarray
    b: np.ndarray
    sa: np.ndarray
    sb: np.ndarray
    tri: tuple[np.ndarray, ...]
    bary: tuple[np.ndarray, ...]
    starts: list[int]
    ranges: list[tuple[int, int]]


def _drawn_segments(samples: tuple, ranges: list[tuple[int, int]]) -> _DrawnSegments:
    """:class:`_DrawnSegments` of the segments ``ranges`` (first, end) of ``samples``
    (:func:`_layout`'s; a segment's samples are also its strengths' indices), each sample
    they end at placed once (kept per fast plan and set of drawn groups: a frame draws the
    groups of the frames before it)."""
    tri, bary, seg_a, seg_b = samples
    segs = np.concatenate([np.arange(g0, g1) for g0, g1 in ranges])
    sa, sb = seg_a[segs], seg_b[segs]
    used, inv = np.unique(np.concatenate([sa, sb]), return_inverse=True)
    n = [g1 - g0 for g0, g1 in ranges]
    first = list(itertools.accumulate([0, *n[:-1]]))
    return _DrawnSegments(
        inv[:len(segs)], inv[len(segs):], sa, sb,
        tuple(np.ascontiguousarray(t[used]) for t in tri),
        tuple(np.ascontiguousarray(b[used, 0][None]) for b in bary), first,
        [(f, f + k) for f, k in zip(first, n, strict=True)])


#: the turn of a direction's rows (x, y) reversed, (dy, dx), to its normal (-dy, dx)
_TURN_COL = np.array([[-1.0], [1.0]])


def _splat_rows(shapes: list[tuple[int, int]], xy: np.ndarray, w: np.ndarray,
                cpt: np.ndarray, sub: list[tuple[float, float]] | None = None
                ) -> list[np.ndarray]:
    """float32 canvases of ``shapes`` with weights ``w`` (n,) added at sub-pixel positions
    given as rows ``xy`` (2, n) (x, y), canvas ``cpt`` (n,) each, all in one ``bincount``
    (bilinear, corner-major: per pixel the same sums in the same order as one bincount per
    canvas); every point lies at least a pixel inside its canvas. ``sub``: each canvas's
    origin, whole pixels, to be subtracted from its points (an offset of their pixels: their
    fractions are the same, a float's less a whole number below it being exact), else the
    points are the canvases' own. Every canvas is a contiguous block of its own in one array,
    ``h w`` long. (:func:`_splat_many` when a box was clipped by the image's edge.)"""
    P0 = np.floor(xy)
    F = xy - P0
    ip = P0.astype(np.int64)
    n = len(w)
    ws = _bilinear_weights(F.T, w)
    # per canvas its first element, row length and the offset of its points' pixels
    size = [h * wd for h, wd in shapes]
    first = list(itertools.accumulate([0, *size[:-1]]))
    total = first[-1] + size[-1]
    if sub is None:
        off = first
    else:
        off = [o - int(y0) * wd - int(x0)
               for o, (_, wd), (x0, y0) in zip(first, shapes, sub, strict=True)]
    # (each canvas's row length and offset, gathered per point in one take)
    wide, offp = np.array([[wd for _, wd in shapes], off]).take(cpt, 1)
    idx = np.empty((4, n), np.int64)
    base = idx[0]
    np.multiply(ip[1], wide, out=base)
    base += ip[0]
    base += offp
    np.add(base, 1, out=idx[1])
    np.add(base, wide, out=idx[2])
    np.add(idx[2], 1, out=idx[3])
    acc = np.bincount(idx.ravel(), ws, minlength=total)[:total].astype(np.float32)
    return [acc[o:o + h * wd].reshape(h, wd) for o, (h, wd) in zip(first, shapes, strict=True)]


def _blur_back(canvas: np.ndarray, sigma: float, f: int, h: int, w: int,
               scale: np.float32 | None = None, cap: float | None = None) -> np.ndarray:
    """A splatted canvas of :func:`_on_canvas` (without its extra row and column) blurred by
    ``sigma`` px of the photo and, when it is coarse (``f`` > 1), resized back to the box
    (``h`` x ``w``): float32, times ``scale`` and at most ``cap`` when given. The weight a
    line leaves per coarse pixel is ``f^2`` times the full-resolution one (the caller
    scales)."""
    if f == 1:
        out = np.asarray(_blur(canvas[:-1, :-1], sigma), np.float32)
        full = out
    else:
        hc, wc = canvas.shape[0] - 1, canvas.shape[1] - 1
        full = np.asarray(cv2.resize(_blur(canvas[:-1, :-1], sigma / f), (wc * f, hc * f),
                                     None, 0, 0, cv2.INTER_LINEAR), np.float32)
        out = full[:h, :w]
    # (scaled and capped over the whole resized canvas, then cropped: numpy's element-wise
    # passes over the crop's strided rows cost several times as much; the same values)
    if scale is not None:
        full *= scale
    if cap is not None:  # (min(full, cap) by OpenCV's truncation: the same values, faster)
        cv2.threshold(full, cap, 0.0, cv2.THRESH_TRUNC, dst=full)
    return out


#: A fold line is drawn at 1/f of the photo's resolution when its drawn half-width (sigma,
#: px) is at least this times f: a Gaussian that wide is smooth on the coarse grid, and its
#: linear interpolation back is within 2 % of its peak (at full resolution the blur of a fold on
#: a face 1000 px wide, sigma 9 px and 14 px for its ridge, cost 8 ms a frame)
FOLD_COARSE_SIGMA = 2.5


def _fold_scale(dsig: float) -> int:
    """The factor f of :data:`FOLD_COARSE_SIGMA` for a fold drawn with half-width ``dsig``
    (1: at the photo's resolution, every fold of a face up to ~150 px between the eyes)."""
    return max(1, int(dsig / FOLD_COARSE_SIGMA))


def _fold_draw(fa: _Fast, out: np.ndarray, g: int, box: tuple[int, int, int, int],
               dark: np.ndarray, light: np.ndarray, bbox: tuple[int, int, int, int] | None,
               f: int = 1, q: int = 1) -> tuple[int, int, int, int] | None:
    """Darken group ``g``'s fold line (and lighten its ridge) over ``box`` of ``out`` from
    its splatted canvases (in place; at 1/``f`` resolution when ``f`` > 1, see
    :func:`_fold_scale`); returns ``bbox`` grown by the box. ``q`` > 1: the face's work
    factor (:func:`_work_factor`), the gain computed on ``q x q`` blocks (:func:`_fold_blocks`)."""
    x0, y0, x1, y1 = box
    sig = float(fa.dsig[g])
    # (a line's weight per coarse pixel: f^2 times its own)
    k = np.float32(1.0 / (f * f)) if f > 1 else None
    H, W = out.shape[:2]
    hq, wq = -(-(y1 - y0) // q), -(-(x1 - x0) // q)
    if q > 1 and y0 + hq * q <= H and x0 + wq * q <= W:
        _fold_blocks(fa, out, g, box, _blur_blocks(dark, sig, f, q, y1 - y0, x1 - x0, k),
                     _blur_blocks(light, 1.6 * sig, f, q, y1 - y0, x1 - x0, k), q)
        return _union(bbox, box)
    dark = _blur_back(dark, sig, f, y1 - y0, x1 - x0, k)
    light = _blur_back(light, 1.6 * sig, f, y1 - y0, x1 - x0, k)
    view = out[y0:y1, x0:x1]
    patch = view.astype(np.float32)
    # skin-likeness: hair, brows, eyes and lashes are not folded (OpenCV calls: on these
    # small 3-channel boxes numpy's broadcasting over the channels costs more than the math)
    dif = cv2.transform(patch, fa.skin_shift[g])  # patch - skin
    wskin: np.ndarray = cv2.sqrt(cv2.transform(cv2.multiply(dif, dif), _MEAN3))
    wskin *= np.float32(-4.0 / float(fa.ref_l[g]))
    wskin += np.float32(1.8)  # (0.45 - distance / ref_l) * 4
    clip(wskin, 0.0, 1.0, out=wskin)
    # gain per channel 1 + wskin (k2 light - k1 tint dark), one transform of (light, dark)
    light *= wskin
    dark *= wskin
    gain = cv2.transform(cv2.merge([light, dark]), fa.gain_mat[g])
    cv2.multiply(patch, gain, view, 1.0, cv2.CV_8U)  # rounded, saturated
    return _union(bbox, box)


def _area_u8(a: np.ndarray, q: int) -> np.ndarray:
    """``cv2.resize(a, (w // q, h // q), None, 0, 0, cv2.INTER_AREA)`` of a uint8 frame box
    ``a`` (h, w, 3) whose sides are multiples of ``q``, the same values: for an odd ``q`` a
    normalised ``q x q`` box filter anchored at its corner, read every ``q`` px
    (``INTER_NEAREST`` by exactly ``1 / q``: pixel ``i`` reads ``q i``). Both round the block's
    sum over ``q q`` to the nearest integer (an odd divisor never ties). OpenCV's area
    reduction takes a slower path for any factor but 2: on the 4K bench face's fold boxes
    at ``q`` 3 (454 x 363 and 252 x 747) ~0.21 and ~0.35 ms, these two calls ~0.1 and ~0.11."""
    h, w = a.shape[:2]
    if q % 2 == 0 or a.dtype != np.uint8:
        return cv2.resize(a, (w // q, h // q), None, 0, 0, cv2.INTER_AREA)
    return cv2.resize(cv2.blur(a, (q, q), None, (0, 0), cv2.BORDER_REPLICATE),
                      (w // q, h // q), None, 0, 0, cv2.INTER_NEAREST)


def _block_means(a: np.ndarray, q: int) -> np.ndarray:
    """The means of ``a``'s ``q x q`` blocks, its last row and column repeated to whole
    blocks."""
    h, w = a.shape[:2]
    hq, wq = -(-h // q), -(-w // q)
    return cv2.resize(cv2.copyMakeBorder(a, 0, hq * q - h, 0, wq * q - w, cv2.BORDER_REPLICATE),
                      (wq, hq), None, 0, 0, cv2.INTER_AREA)


def _fold_blocks(fa: _Fast, out: np.ndarray, g: int, box: tuple[int, int, int, int],
                 dark: np.ndarray, light: np.ndarray, q: int) -> None:
    """:func:`_fold_draw`'s gain over ``box`` of ``out`` (in place) on a large face (work
    factor ``q`` > 1, see :func:`_unfold_blocks`): the line and ridge (``dark``, ``light``
    (hq, wq), blurred over several px, on the box's blocks: :func:`_blur_blocks`) and the
    skin-likeness are taken on the frame's ``q x q`` block means (the box grown to whole
    blocks), the gain upsampled bilinearly; only the product is per pixel. (On the soft large
    face the skin-likeness of a pixel and of its block differ at the brows' and the hair's
    edges only, by a fraction.)"""
    x0, y0, x1, y1 = box
    hb, wb = y1 - y0, x1 - x0
    hq, wq = -(-hb // q), -(-wb // q)
    patch = _area_u8(out[y0:y0 + hq * q, x0:x0 + wq * q], q).astype(np.float32)
    # (as _fold_draw, on the blocks)
    dif = cv2.transform(patch, fa.skin_shift[g])
    wskin: np.ndarray = cv2.sqrt(cv2.transform(cv2.multiply(dif, dif), _MEAN3))
    wskin *= np.float32(-4.0 / float(fa.ref_l[g]))
    wskin += np.float32(1.8)
    clip(wskin, 0.0, 1.0, out=wskin)
    light *= wskin
    dark *= wskin
    gain = cv2.transform(cv2.merge([light, dark]), fa.gain_mat[g])
    gain = cv2.resize(gain, (wq * q, hq * q), None, 0, 0, cv2.INTER_LINEAR)[:hb, :wb]
    view = out[y0:y1, x0:x1]
    cv2.multiply(view, gain, view, 1.0, cv2.CV_8U)  # rounded, saturated


def _splat_many(canvases: list[tuple[tuple[int, int], np.ndarray, np.ndarray]]
                ) -> list[np.ndarray]:
    """float32 canvases ``(h, w)`` with weights ``w`` (n,) added at sub-pixel positions
    ``xy`` (n, 2) (bilinear), canvas by canvas, for points that may leave their canvas (a box
    clipped by the image's edge): what leaves one is dropped (a corner past a row's end wraps
    into the next row, as on a canvas of its own). The same sums per pixel as
    :func:`_splat_rows`, which serves canvases every point lies inside.
    """
    n = [len(w) for _, _, w in canvases]
    xy = np.concatenate([c[1] for c in canvases])
    P0 = np.floor(xy)
    ip = P0.astype(np.int64)
    ws = _bilinear_weights(xy - P0, np.concatenate([c[2] for c in canvases]))
    got = []
    k = 0
    for ((h, wd), _, _), m in zip(canvases, n, strict=True):
        base = ip[k:k + m, 1] * wd + ip[k:k + m, 0]
        idx = (base[None, :] + np.array([0, 1, wd, wd + 1])[:, None]).ravel()
        w4 = ws.reshape(4, -1)[:, k:k + m].ravel()
        keep = (idx >= 0) & (idx < h * wd)  # (a corner above or below the canvas: dropped)
        if not keep.all():
            idx, w4 = idx[keep], w4[keep]
        got.append(np.bincount(idx, w4, minlength=h * wd)[: h * wd].astype(np.float32)
                   .reshape(h, wd))
        k += m
    return got


#: below this share a photo's own fold is left as it is
_MIN_UNFOLD = 0.02


def _skin_weight(patch: np.ndarray, ref: np.ndarray, tol: float = 0.45) -> np.ndarray:
    """Skin-likeness in [0, 1] of every pixel (hair, brows, eyes and lashes are not folded):
    1 up to ``tol - 0.25`` of relative colour distance to ``ref``, 0 from ``tol``."""
    ref_l = max(float(ref.mean()), 20.0)
    d = (patch - ref) ** 2
    dist = np.sqrt((d[..., 0] + d[..., 1] + d[..., 2]) * np.float32(1.0 / 3.0))
    return np.clip((np.float32(tol) - dist / np.float32(ref_l)) * 4.0, 0.0, 1.0)


_VALLEYS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _own_valleys(face: Face) -> tuple[np.ndarray, np.ndarray]:
    """``(tri, bary)`` (N,) / (N, 3): every fold sample moved across its line onto the photo's
    own valley (cached per face; depends on the photo only).

    The fold lines are laid out from feature points and need not sit on the dark valley a
    smiling photo shows (the sample's image-left nasolabial fold lies 1-3 px medial of its
    line). Per sample, the valley is searched across the line within :data:`_VALLEY_REACH`
    on the photo's smoothed luminance: the deepest point of its black top-hat (a closing
    wider than the fold minus the luminance: how far the skin dips below the shoulders on
    either side), slightly favouring the laid-out line; the offsets are smoothed along the
    line (weighted by the valley's depth) so that the band follows the valley, not the noise.
    """
    got = _VALLEYS.get(face)
    if got is not None:
        return got
    p = crease_plan(face)
    fa = _fast(face)
    V = face.vertices.astype(np.float64)
    pos = _on_mesh(V, fa.sample_tri, fa.bary)  # (the fold samples on the photo's mesh)
    tri, bary = p.tri.copy(), p.bary.copy()
    H, W = face.image.shape[:2]  # (the valleys are looked for on the sealed photo: the
    # mouth's dark corners are no valley; each fold's box only)
    todo: list[tuple[int, int, np.ndarray]] = []
    reach = max(_VALLEY_REACH * p.iod, 2.0)
    ds = np.arange(-reach, reach + 1e-6, 0.25)
    cand = _skin_triangles(face.mesh)
    wq = _work_factor(p.iod)
    found: list[tuple[int, int, np.ndarray, tuple[float, float], np.ndarray, int]] = []
    for f in range(p.n_folds):
        a, b = int(p.start[f]), int(p.start[f + 1])
        if fa.own_gap is None or fa.own_gap[f] < _OWN_MIN or not p.utaper[a:b].any():
            continue
        sig = max(STYLES[p.kinds[f]].sigma * p.iod, 0.6)
        r = int(math.ceil(_VALLEY_WIDTH * sig))
        q = pos[a:b]
        pad = reach + 2 * r + 3
        x0, y0 = clamp(np.floor(q.min(0) - pad).astype(int), 0, (W - 1, H - 1))
        x1, y1 = clamp(np.ceil(q.max(0) + pad).astype(int) + 1, 1, (W, H))
        # the luminance of this fold's box only (bit for bit the whole photo's, cut); on a
        # large face its wq x wq block means (the valley is then still >= ~3 px wide)
        if wq == 1:
            ls = cv2.GaussianBlur(luminance(sealed_box(face, (x0, y0, x1, y1))), (0, 0),
                                  0.7 * sig)
            org: tuple[float, float] = (x0, y0)
        else:
            x1, y1 = x0 + (x1 - x0) // wq * wq, y0 + (y1 - y0) // wq * wq
            ls = cv2.GaussianBlur(_block_mean(luminance(sealed_box(face, (x0, y0, x1, y1))),
                                              wq), (0, 0), 0.7 * sig / wq)
            org = (x0 + 0.5 * (wq - 1), y0 + 0.5 * (wq - 1))
            r = int(math.ceil(_VALLEY_WIDTH * sig / wq))
        found.append((a, b, q, org, ls, r))
    # (the folds' closings of one radius in one image: _close_many)
    closed: dict[int, np.ndarray] = {}
    for r in sorted({x[5] for x in found}):
        at = [i for i, x in enumerate(found) if x[5] == r]
        closed.update(zip(at, _close_many([found[i][4] for i in at], r), strict=True))
    for i, (a, b, q, org, ls, _r) in enumerate(found):
        hat = closed[i] - ls  # >= 0: depth below shoulders
        nrm = p.normal[a:b]
        xy = ((q[:, None, :] + ds[None, :, None] * nrm[:, None, :] - org) / wq
              ).astype(np.float32)
        prof = cv2.remap(hat, xy[..., 0], xy[..., 1], cv2.INTER_LINEAR,
                         None, cv2.BORDER_REPLICATE)
        score = prof * (1.0 - 0.3 * (ds / reach) ** 2)[None]
        k = np.argmax(score, 1)
        off, depth = ds[k], prof[np.arange(b - a), k]
        # a sample without a valley (or at the fold's faded ends, where the search may catch the
        # nose wing or the mouth corner) follows the others
        w = (np.maximum(depth - 1.0, 0.0) + 1e-3) * (p.utaper[a:b] + 1e-3)
        kern = _VALLEY_KERN
        num = np.convolve(pad_edge(off * w, 4), kern, mode="valid")
        den = np.convolve(pad_edge(w, 4), kern, mode="valid")
        off = clamp(num / den, -reach, reach)
        todo.append((a, b, q + off[:, None] * nrm))
    if todo:  # located on the mesh in one batch
        ti, bc = _locate(np.concatenate([t[2] for t in todo]), V, face.mesh.triangles[cand])
        k = 0
        for a, b, _q in todo:
            tri[a:b], bary[a:b] = cand[ti[k:k + b - a]], bc[k:k + b - a]
            k += b - a
    _VALLEYS[face] = (tri, bary)
    return tri, bary


#: the along-line smoothing of the valley offsets (a Gaussian of 2 samples, unnormalised)
_VALLEY_KERN = np.exp(-0.5 * (np.arange(-4, 5) / 2.0) ** 2)

#: how far across its laid-out line a photo's own fold is looked for (inter-ocular distances)
_VALLEY_REACH = 0.08
#: the most an own fold's pixel is brightened (a factor). A sharp fold's core may be 6-9 times
#: darker than the skin beside it (MK.HA of JAFFE: 13-20 grey levels in skin of ~120); at 4 it
#: stayed a thin dark line along the lifted fold
_MAX_GAIN = 8.0

#: the widest valley a fold is (radius of the closing, in line widths ``sigma``)
_VALLEY_WIDTH = 4.0


#: directions of the along-fold smoothing (every 180 / _N_DIR degrees) in a frame, and on the
#: photo (done once per face, so finer: the lift carried from the photo follows the valley
#: within 4 degrees)
_N_DIR = 6
_N_DIR_PHOTO = 24


@functools.lru_cache(maxsize=64)
def _line_kernel(angle: float, along: float, across: float) -> np.ndarray:
    """Normalised anisotropic Gaussian kernel, ``along`` px along ``angle`` (radians)."""
    h = int(math.ceil(3.0 * along))
    y, x = np.mgrid[-h:h + 1, -h:h + 1].astype(np.float64)
    c, s = math.cos(angle), math.sin(angle)
    u, v = x * c + y * s, -x * s + y * c
    k = np.exp(-0.5 * ((u / along) ** 2 + (v / across) ** 2))
    return (k / k.sum()).astype(np.float32)


def _lift_gain(S: np.ndarray, Cw: np.ndarray, frame: np.ndarray, interpolation: int
               ) -> np.ndarray:
    """The lift's per-channel gain ``Cw / S`` (h, w, 4; in place in ``S``, the skin level
    resampled as the warp resampled the photo; channel 3 the skin weight itself). A bicubic
    still keeps the valley's sharp core darker than a bilinear S: S is at most the ``frame``
    (RGB) plus the skin's grain, as on the photo (_lift_fields; MK: 43 levels)."""
    if interpolation != cv2.INTER_LINEAR:
        lim = cv2.cvtColor(frame, cv2.COLOR_RGB2RGBA).astype(np.float32)
        lim *= 1.0 + np.float32(_GRAIN) / np.maximum(Cw, 1.0)
        lim[..., 3] = np.inf
        np.minimum(S, lim, out=S)
    s1 = S.reshape(S.shape[0], -1)  # (OpenCV's maximum on the rows as one channel: faster)
    _cv_max(s1, 1.0, dst=s1)
    return np.divide(Cw, S, out=S)


def _unfold_draw(face: Face, out: np.ndarray, jobs: list[tuple], drawn: list[np.ndarray],
                 bbox: tuple[int, int, int, int] | None,
                 maps: tuple[np.ndarray, np.ndarray, tuple[int, int, int, int]] | None,
                 interpolation: int, fa: _Fast, q: int
                 ) -> tuple[int, int, int, int] | None:
    """Smooth the photo's own folds away where the target spreads their skin (in place).

    Along each fold's valley (:func:`_own_valleys`, carried by the deformed mesh; a band a few
    line widths wide, strength ``un``) the valley is lifted to its shoulders: per channel, the
    gain ``C(S) / S`` (``S`` the image lightly smoothed, ``C`` a closing wider than the fold:
    the skin level on either side of the valley, whatever the valley's exact place and shape
    inside the band) raised to the strength. It is >= 1 (nothing is darkened) and ~1 off the
    valley; the finer texture and the colour of the skin around the valley stay. Weighted by how
    skin-like that lifted level is (hair, brows, eyes are not).

    The gain and the skin weight depend on the photo only: with the warp's backward ``maps``
    (:class:`WarpResult`) they are computed once per face on the photo (:func:`_photo_gain`)
    and carried to the frame by the warp's own map (one ``cv2.remap`` of the band's box, so
    the gain lies on the valley exactly where the warp puts it); per frame only the band is
    drawn. Without ``maps`` they are computed on ``out``. ``fa``: the face's :class:`_Fast`,
    ``q`` its :func:`_frame_blocks`.
    """
    H, W = out.shape[:2]
    for g, f, got, pts, w, d, L, K, M, (x0, y0, x1, y1), ci in jobs:
        sig = float(fa.sig[g])
        sb = max(2.5 * sig, 1.0)
        # flat across the valley, falling off over the band's edge
        k = np.float32(1.6 * math.sqrt(2 * math.pi) * sb / (f * f))
        hq, wq = -(-(y1 - y0) // q), -(-(x1 - x0) // q)
        got_q = None if q == 1 or got is None else _photo_gain_q(face, g)
        if got_q is not None and maps is not None and y0 + hq * q <= H and x0 + wq * q <= W:
            bq = _blur_blocks(drawn[ci], sb, f, q, y1 - y0, x1 - x0, k, 1.0)
            _unfold_blocks(out, (x0, y0, x1, y1), q, bq, got_q, maps, interpolation, sig)
            bbox = _union(bbox, (x0, y0, x1, y1))
            continue
        band = _blur_back(drawn[ci], sb, f, y1 - y0, x1 - x0, k, 1.0)
        view = out[y0:y1, x0:x1]
        if got is None or maps is None:
            S, c4 = _lift_fields(fa, g, out, pts, w, d, L, K, M, (x0, y0, x1, y1))
            band *= c4[..., 3]
            gain = np.clip(c4[..., :3] / np.maximum(S, 1.0), 1.0, _MAX_GAIN)
        else:
            # S, C and the skin weight taken on the photo once and carried by the warp's own
            # map: S lands on the valley exactly where the warp puts it. C and the weight are
            # smooth (a closing blurred over ~2 line widths): on large faces they are carried
            # at 1/f resolution (the map averaged over f x f blocks) and resized
            (S, Cw), (px0, py0) = got
            hb, wb = y1 - y0, x1 - x0
            hc, wc = -(-hb // f), -(-wb // f)
            mx, my = box_maps(maps, (x0, y0, x0 + wc * f, y0 + hc * f), (px0, py0))
            if f > 1:
                Cw = cv2.remap(Cw, cv2.resize(mx, (wc, hc), None, 0, 0, cv2.INTER_AREA),
                               cv2.resize(my, (wc, hc), None, 0, 0, cv2.INTER_AREA),
                               cv2.INTER_LINEAR, None, cv2.BORDER_REPLICATE)
                Cw = cv2.resize(Cw, (wc * f, hc * f), None, 0, 0, cv2.INTER_LINEAR)
                mx, my = mx[:hb, :wb], my[:hb, :wb]
                Cw = Cw[:hb, :wb]
            else:
                Cw = cv2.remap(Cw, mx, my, cv2.INTER_LINEAR, None, cv2.BORDER_REPLICATE)
            # (all four channels at once: numpy is many times slower on a channel view; the
            # 4th channel of S is 0, so that of C / max(S, 1) is the skin weight itself).
            # S is resampled as the warp resampled the photo: a bicubic still keeps the
            # valley's sharp core darker than a bilinear S would, and the lift left it as a
            # thin dark scratch (the sample's neutralised smile: 41 levels below the
            # bilinear render's lifted skin)
            S = cv2.remap(S, mx, my, interpolation, None, cv2.BORDER_REPLICATE)
            g4 = _lift_gain(S, Cw, view, interpolation)
            band *= g4[..., 3]
            # (clipped to [1, _MAX_GAIN] below, with the cap)
            gain = cv2.cvtColor(g4, cv2.COLOR_RGBA2RGB)
        # never above the frame's own skin either side of the valley (its closing): the lift
        # level ramps between shoulders of different light (see _lift_fields), and a sharp
        # core pulls S down on its shoulders; over the lower shoulder the lifted band read
        # as a light outline where a neutralised smile's fold had been (up to 12 grey levels
        # above the skin's closing on the sample, 21-23 on JAFFE NA, MK, KM)
        hb, wb = view.shape[:2]
        # (max(view, 1) by OpenCV on the box's rows as one channel: a scalar bound is then
        # every channel's; numpy's on the strided 3-channel view costs 2-3 times as much)
        cap = cv2.divide(_frame_closing(view, int(math.ceil(_VALLEY_WIDTH * sig * 1.25))),
                         _cv_max(view.reshape(hb, -1), 1).reshape(view.shape), None, 1.0,
                         cv2.CV_32F)
        # min(clip(gain, 1, _MAX_GAIN), max(cap, 1)) - 1 as max(min(gain, cap, _MAX_GAIN) - 1,
        # 0): min and max distribute over each other, and x - 1 is exact for x >= 1 (the same
        # float32 values, two passes fewer; >= 1 before the - 1: never darkened)
        np.minimum(gain, cap, out=gain)
        g1 = gain.reshape(hb, -1)
        cv2.threshold(g1, _MAX_GAIN, 0.0, cv2.THRESH_TRUNC, dst=g1)
        gain -= 1.0
        _cv_max(g1, 0.0, dst=g1)
        gain *= spread3(band)
        gain += 1.0
        cv2.multiply(view, gain, view, 1.0, cv2.CV_8U)  # rounded, saturated
        bbox = _union(bbox, (x0, y0, x1, y1))
    return bbox


def _blur_blocks(canvas: np.ndarray, sigma: float, f: int, q: int, h: int, w: int,
                 scale: np.float32 | None = None, cap: float | None = None) -> np.ndarray:
    """:func:`_blur_back`'s band or line (``h`` x ``w``) on the box's ``q x q`` blocks (hq, wq) (the
    box grown to whole blocks), contiguous float32. From a coarse canvas (``f`` > 1) the
    blurred canvas is read at the blocks' centres (``cv2.resize`` by ``f / q``: output pixel
    ``i`` reads the canvas at ``(i + 1/2) q / f - 1/2``, block ``i``'s centre) instead of
    upsampled to every pixel and averaged over each block: the same where the band is linear
    over a block (its interpolation bends across the canvas's nodes, ``f`` px apart, and the
    cap clips its core) and beyond the box's last row and column (extrapolated, not repeated).
    On the 4K bench face the unfold bands (``f`` 20, ``q`` 3): the folds 0.33 ms less a
    frame (thread CPU, interleaved), the bench expression and the six presets at 100 and 150 %
    differ on 124-544 pixels, by 1 level; the fold lines and ridges of :func:`_fold_draw`
    (``f`` 3: the canvas's own pixels) 0.54 ms less, the renders differ on 748-15,563 pixels
    (0.2 % of the frame), by 1 level; the soft-blocks contract's mean (against per-pixel folds)
    0.009395 -> 0.008039. Else the block means of :func:`_blur_back`'s band (the last row and
    column repeated, :func:`_block_means`)."""
    if f == 1:
        return _block_means(_blur_back(canvas, sigma, f, h, w, scale, cap), q)
    hq, wq = -(-h // q), -(-w // q)
    blurred: np.ndarray = np.asarray(_blur(canvas[:-1, :-1], sigma / f), np.float32)
    # (rows and columns repeated below and right: the blocks past the canvas's last centre
    # read it as the clamped border would, and the output covers every block)
    e = 1 + 2 * -(-q // f)  # (the output then reaches 1.5 blocks past the canvas's end)
    blurred = cv2.copyMakeBorder(blurred, 0, e, 0, e, cv2.BORDER_REPLICATE)
    at = cv2.resize(blurred, None, None, f / q, f / q, cv2.INTER_LINEAR)
    if at.shape[0] < hq or at.shape[1] < wq:  # (never: the canvas covers the box)
        return _block_means(_blur_back(canvas, sigma, f, h, w, scale, cap), q)
    bq = np.array(at[:hq, :wq]) if scale is None else np.multiply(at[:hq, :wq], scale)
    if cap is not None:  # (as _blur_back's)
        cv2.threshold(bq, cap, 0.0, cv2.THRESH_TRUNC, dst=bq)
    return bq


def _unfold_blocks(out: np.ndarray, box: tuple[int, int, int, int], q: int, bq: np.ndarray,
                   got: tuple[tuple[np.ndarray, np.ndarray], tuple[float, float]],
                   maps: tuple[np.ndarray, np.ndarray, tuple[int, int, int, int]],
                   interpolation: int, sig: float) -> None:
    """:func:`_unfold_draw`'s lift of one band (``bq`` (hq, wq): the band over ``box`` of
    ``out`` on its ``q x q`` blocks, :func:`_blur_blocks`; in place) on a large face (a work
    factor ``q`` > 1, :func:`_work_factor`: the photo's fields ``got``,
    :func:`_photo_gain_q`, were made on its ``q x q`` block means, so they hold nothing finer
    than a block): the lift ``(gain - 1) band`` is computed on the frame's ``q x q`` blocks
    (the box grown to whole blocks; the frame averaged over each, the band as
    :func:`_blur_blocks` gives it, the warp's map read at an odd block's centre, averaged over
    an even one) and upsampled bilinearly; only the final product is per pixel.
    Per pixel the lift is then capped by the frame's own closing, as :func:`_unfold_draw`
    caps its gain (a pixel brighter than its block is not lifted above the skin either side).
    On the face 1000 px wide at 3840 x 2160 (q = 3) about 3 ms a fold instead of 5; the
    frame differs from the per-pixel lift's by 1.2 grey levels on average over the ~40,000
    pixels that change (at most 9 on a few hundred, the presets and the bench's expression;
    0.003 over the frame)."""
    x0, y0, x1, y1 = box
    hb, wb = y1 - y0, x1 - x0
    hq, wq = -(-hb // q), -(-wb // q)
    (S, Cw), (ox, oy) = got
    # (the maps' own memory where they cover the box: only read, by the block means)
    mx, my = box_maps(maps, (x0, y0, x0 + wq * q, y0 + hq * q), view=True)
    # each block's mean map: the map at its centre, where the block lies in one triangle;
    # read on the photo's fields at their blocks' resolution (the fields' own pixels, not
    # their upsampling: a ninth of the memory to read at q 3)
    k = np.float32(1.0 / q)
    if q % 2:
        # (an odd block's centre is its middle pixel: the map there instead of the block's
        # mean map, OpenCV's area reduction of both maps; the mean of a map bilinear over
        # the block is its value at the centre, they differ where the block straddles a bend
        # or an exact pixel of the warp's map. On the 4K bench face (q 3) the folds 0.55 ms
        # less a frame, thread CPU, interleaved; the bench expression and the six presets at
        # 100 and 150 % differ on 24-503 pixels, by 1.0-1.03 levels on average over them,
        # at most 3 (sadness 100 %, 2 pixels; 2 elsewhere); the soft-blocks contract's mean
        # 0.009395 -> 0.009392)
        c = q // 2
        mx = (mx[c::q, c::q] - np.float32(ox)) * k
        my = (my[c::q, c::q] - np.float32(oy)) * k
    else:
        mx = (np.asarray(cv2.resize(mx, (wq, hq), None, 0, 0, cv2.INTER_AREA), np.float32)
              - np.float32(ox)) * k
        my = (np.asarray(cv2.resize(my, (wq, hq), None, 0, 0, cv2.INTER_AREA), np.float32)
              - np.float32(oy)) * k
    Cw = cv2.remap(Cw, mx, my, cv2.INTER_LINEAR, None, cv2.BORDER_REPLICATE)
    S = cv2.remap(S, mx, my, interpolation, None, cv2.BORDER_REPLICATE)
    vq = _area_u8(out[y0:y0 + hq * q, x0:x0 + wq * q], q)
    g4 = _lift_gain(S, Cw, vq, interpolation)
    bq *= g4[..., 3]
    gain = np.asarray(cv2.cvtColor(g4, cv2.COLOR_RGBA2RGB), np.float32)
    # the frame's closing over the blocks (its radius in blocks)
    r = max(int(math.ceil(_VALLEY_WIDTH * sig * 1.25 / q)), 1)
    cap = cv2.divide(_frame_closing(vq, r), _cv_max(vq.reshape(hq, -1), 1).reshape(vq.shape),
                     None, 1.0, cv2.CV_32F)
    # min(clip(gain, 1, _MAX_GAIN), max(cap, 1)) - 1, as in _unfold_draw
    np.minimum(gain, cap, out=gain)
    g1 = gain.reshape(hq, -1)
    cv2.threshold(g1, _MAX_GAIN, 0.0, cv2.THRESH_TRUNC, dst=g1)
    gain -= 1.0
    _cv_max(g1, 0.0, dst=g1)
    gain *= spread3(bq)
    # (+ 1 over the whole resized blocks, then cropped: on the crop's strided rows numpy's
    # add costs 4 times as much)
    lift = np.asarray(cv2.resize(gain, (wq * q, hq * q), None, 0, 0, cv2.INTER_LINEAR),
                      np.float32)
    lift += 1.0
    lift = lift[:hb, :wb]
    view = out[y0:y1, x0:x1]
    # per pixel, never above the frame's own closing (where it is above the closing, the
    # frame itself): the blocks' cap holds for their means, not for a pixel brighter than its
    # block's mean
    top = cv2.max(view, _frame_closing(view, int(math.ceil(_VALLEY_WIDTH * sig * 1.25)), True))
    cv2.multiply(view, lift, view, 1.0, cv2.CV_8U)  # rounded, saturated
    cv2.min(view, top, view)


def _frame_closing(view: np.ndarray, r: int, whole: bool = False) -> np.ndarray:
    """The closing (radius ``r`` px) of a frame's box ``view`` (h, w, 3) uint8: on large faces
    (``r`` above 6) taken on ``q x q`` block means (``q = r // 6``, as the photo's own
    :func:`_closing`) and resized back, so that its cost does not grow with the kernel's area
    (a 4K face's 105 px ellipse cost ~110 ms a fold group at full resolution). ``whole``
    (:func:`_unfold_blocks`' per-pixel cap, large faces only): the means taken by
    :func:`_area_means` instead of OpenCV's area reduction (the same means but for a rare
    rounding tie)."""
    q = max(1, r // 6)
    if q == 1:
        return _close(view, r)
    h, w = view.shape[:2]
    if whole:
        small = _area_means(view, max(w // q, 1), max(h // q, 1))
    else:
        small = cv2.resize(view, (max(w // q, 1), max(h // q, 1)),
                           interpolation=cv2.INTER_AREA)
    small = _close(small, max(r // q, 1))
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)


def _area_means(img: np.ndarray, w: int, h: int) -> np.ndarray:
    """``cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA)`` of a uint8 image (H, W, C)
    reduced by a fractional factor (each output pixel the mean over its ``W / w x H / h`` px
    footprint, the pixels its edges cut weighed by the part inside), through the image's
    integral (``cv2.integral``, exact int32 sums): the footprints' sums are the integral's
    differences at their corners, bilinear between its nodes (the integral of a pixelwise
    constant image is so), in float64. The same values but where OpenCV's float32 weighted
    sum and this one round a mean near a half differently (1 of 4,860 values, by 1, on a
    blurred random box). OpenCV's generic area path costs ~3 ns a pixel: on the 4K bench
    face's 454 x 361 fold box (to 36 x 45) ~0.5 ms, this one ~0.26 (its two folds' caps:
    0.37 ms less a frame, thread CPU, interleaved; its renders, the bench expression and the
    six presets at 100 and 150 %, unchanged)."""
    H, W = img.shape[:2]
    I = cv2.integral(img, sdepth=cv2.CV_32S)  # (H + 1, W + 1, C)
    if I.ndim == 2:
        I = I[..., None]
    iy, fy = _lerp_at(H, h)
    ix, fx = _lerp_at(W, w)
    # the integral at the footprints' rows, then at their columns (lerp between nodes)
    a = I[iy].astype(np.float64)
    rows = I[iy + 1] - a
    rows *= fy[:, None, None]
    rows += a
    a = rows[:, ix]
    at = rows[:, ix + 1]
    at -= a
    at *= fx[None, :, None]
    at += a
    sums = at[1:, 1:] - at[:-1, 1:]
    sums -= at[1:, :-1]
    sums += at[:-1, :-1]
    sums *= w * h / (W * H)
    out = np.rint(sums).astype(np.uint8)
    return out if img.ndim == 3 else out[..., 0]


def _lerp_at(n: int, m: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``m + 1`` edges ``k n / m`` of ``m`` equal parts of ``[0, n]``: each one's node
    below (at most ``n - 1``) and its fraction past it."""
    p = np.arange(m + 1, dtype=np.float64) * (n / m)
    i = np.minimum(p.astype(np.intp), n - 1)
    return i, p - i


@functools.lru_cache(maxsize=16)
def _ellipse(r: int) -> np.ndarray:
    """The elliptic structuring element of radius ``r`` (kept: a face's radii recur)."""
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))


#: From this radius :func:`_close` goes through the ellipse's rectangles (below, OpenCV's
#: elliptic kernel costs less than their calls)
_CLOSE_STEPS_MIN = 8


def _close(img: np.ndarray, r: int) -> np.ndarray:
    """``cv2.morphologyEx(img, cv2.MORPH_CLOSE, _ellipse(r))``, the same values. From
    :data:`_CLOSE_STEPS_MIN` on, as a chain of lines (:func:`_ellipse_steps`): OpenCV's cost
    for an elliptic kernel grows with its area (each pixel reads every element), a line's
    with its length; the maxima and minima are exact (a 21 px ellipse on a 1080p face's
    nasolabial box: 0.42 -> 0.29 ms)."""
    if r < _CLOSE_STEPS_MIN:
        return cv2.morphologyEx(img, cv2.MORPH_CLOSE, _ellipse(r))
    steps = _ellipse_steps(r)
    return _by_steps(_by_steps(img, steps, cv2.dilate, cv2.max), steps, cv2.erode, cv2.min)


def _close_many(imgs: list[np.ndarray], r: int) -> list[np.ndarray]:
    """``[_close(x, r) for x in imgs]`` of 2-D float images, the same values: side by side in
    one image, ``r + 1`` columns apart and aligned at the top, padded with -inf for the
    dilation and +inf for the erosion (neither wins a maximum or a minimum over a
    neighbourhood that holds a pixel of the image, as the default border does not, and no
    neighbourhood of the ellipse reaches across the gap): the calls' fixed costs once for
    all (two 1080p nasolabial boxes: 0.39 -> 0.29 ms)."""
    if len(imgs) == 1:
        return [_close(imgs[0], r)]
    H = max(x.shape[0] for x in imgs)
    x0 = np.cumsum([0] + [x.shape[1] + r + 1 for x in imgs]).tolist()
    big = np.full((H, x0[-1] - r - 1), -np.inf, np.result_type(*imgs))
    free = np.ones(big.shape, bool)
    for x, c in zip(imgs, x0, strict=False):
        big[:x.shape[0], c:c + x.shape[1]] = x
        free[:x.shape[0], c:c + x.shape[1]] = False
    if r < _CLOSE_STEPS_MIN:
        big = cv2.dilate(big, _ellipse(r))
        big[free] = np.inf
        big = cv2.erode(big, _ellipse(r))
    else:
        steps = _ellipse_steps(r)
        big = _by_steps(big, steps, cv2.dilate, cv2.max)
        big[free] = np.inf
        big = _by_steps(big, steps, cv2.erode, cv2.min)
    return [big[:x.shape[0], c:c + x.shape[1]].copy() for x, c in zip(imgs, x0, strict=False)]


@functools.lru_cache(maxsize=16)
def _ellipse_steps(r: int) -> tuple[tuple[np.ndarray | None, np.ndarray | None], ...]:
    """:func:`_ellipse` (``r``) as the union of its centred rectangles, one per half-width
    ``w_k`` of its rows (increasing; ``h_k``, decreasing, the half-height of the rows at least
    that wide), as steps ``(horizontal line of half-length w_k - w_{k-1}, vertical line of
    half-length h_k - h_{k+1})`` (``h_{K+1} = 0``; None: no step): a dilation by the ellipse
    is then ``V_K(... V_2(V_1(H_1 x) | H_2 x) ... | H_K x)`` (``|``: the maximum,
    ``H_k x`` the dilation by the k-th horizontal line of the ones before: by ``2 w_k + 1``
    px; each vertical step dilates what has been gathered so far by the height it loses),
    the same as by the rectangles' union (dilations by lines add their lengths, and
    distribute over maxima; the default border never wins)."""
    K = _ellipse(r)
    half = [int(np.flatnonzero(row).max()) - r if row.any() else -1 for row in K]
    ws = sorted({x for x in half if x >= 0})
    hs = []
    for w in ws:
        rows = [i for i, x in enumerate(half) if x >= w]
        # (each row a centred run; the rows at least w wide a centred range of rows)
        assert rows == list(range(rows[0], rows[-1] + 1)) and rows[0] == 2 * r - rows[-1]
        hs.append(r - rows[0])
    assert all(np.flatnonzero(K[i]).tolist() == list(range(r - x, r + x + 1))
               for i, x in enumerate(half) if x >= 0)
    steps = []
    for k, (w, h) in enumerate(zip(ws, hs, strict=True)):
        dw = w - (ws[k - 1] if k else 0)
        dh = h - (hs[k + 1] if k + 1 < len(ws) else 0)
        steps.append((np.ones((1, 2 * dw + 1), np.uint8) if dw else None,
                      np.ones((2 * dh + 1, 1), np.uint8) if dh else None))
    return tuple(steps)


def _by_steps(img: np.ndarray, steps: tuple[tuple[np.ndarray | None, np.ndarray | None], ...],
              op: Callable[..., np.ndarray], combine: Callable[..., np.ndarray]) -> np.ndarray:
    """``img`` dilated (``op`` cv2.dilate, ``combine`` cv2.max) or eroded (cv2.erode,
    cv2.min) by the ellipse of :func:`_ellipse_steps`' ``steps``."""
    line = img
    acc = None
    for across, down in steps:
        if across is not None:
            line = op(line, across)
        acc = line if acc is None else combine(acc, line)
        if down is not None:
            acc = op(acc, down)
    assert acc is not None  # (a radius has one step at least)
    return acc


def _bilinear_weights(F: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(4 n,) corner-major bilinear weights of points with fractional parts ``F`` (n, 2) and
    weights ``w`` (n,): ``(1 - fy) w (1 - fx)``, ``(1 - fy) w fx``, ``fy w (1 - fx)``,
    ``fy w fx`` (into preallocated rows: ``np.stack`` costs more than the arithmetic)."""
    n = len(w)
    fx, fy = F[:, 0], F[:, 1]
    wx = np.empty((2, n))
    np.multiply(w, 1 - fx, out=wx[0])
    np.multiply(w, fx, out=wx[1])
    ws = np.empty((2, 2, n))
    np.multiply(1 - fy, wx, out=ws[0])
    np.multiply(fy, wx, out=ws[1])
    return ws.ravel()


_VALLEY_SAMPLES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
def _both_samples(face: Face) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...],
                                       np.ndarray, np.ndarray]:
    """The fold samples followed by the valley's (:func:`_valley_samples`) as one set for
    :func:`_on_mesh` (3 x (2N,) vertex indices, 3 x (2N, 1) weights) and the segments of both
    halves (``seg_a``, ``seg_b`` and the same shifted by N): a frame that draws folds and
    unfolds places and measures both in one pass (once per face: kept on its fast plan,
    ``fa.both``)."""
    fa = _fast(face)
    tri, bary = _valley_samples(face)
    n = len(fa.sample_tri[0])
    return (tuple(np.concatenate([a, b]) for a, b in zip(fa.sample_tri, tri, strict=True)),
            tuple(np.concatenate([a, b]) for a, b in zip(fa.bary, bary, strict=True)),
            np.concatenate([fa.seg_a, fa.seg_a + n]), np.concatenate([fa.seg_b, fa.seg_b + n]))


def _valley_samples(face: Face) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
    """:func:`_own_valleys` as 3 x (N,) vertex indices and 3 x (N, 1) barycentric coordinates
    (gathered once per face, not every frame)."""
    got = _VALLEY_SAMPLES.get(face)
    if got is None:
        tri, bary = _own_valleys(face)
        t = face.mesh.triangles[tri]
        got = (tuple(np.ascontiguousarray(t[:, k]) for k in range(3)),
               tuple(np.ascontiguousarray(bary[:, k, None]) for k in range(3)))
        _VALLEY_SAMPLES[face] = got
    return got


def _band_samples(pos: np.ndarray, ia: np.ndarray, un: np.ndarray, step: float = 0.5
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """Sub-samples ``pts`` (n, 2) of the segments ``ia`` -> ``ia + 1`` of the valley ``pos``
    (at most ``step`` px apart), their weights ``w`` (strength ``un`` x length), the segments
    ``d`` (M, 2), their lengths ``L`` and the sub-samples per segment ``K``."""
    a, d = pos[ia], pos[ia + 1] - pos[ia]
    L = np.sqrt((d * d).sum(1))
    K = int(min(max(np.ceil(L.max() / step), 1), 64))
    u = _sub_steps(K)
    pts = (a[:, None, :] + d[:, None, :] * u[None, :, None]).reshape(-1, 2)
    ua, ub = un[ia], un[ia + 1]
    w = ((ua[:, None] + (ub - ua)[:, None] * u[None]) * (L / K)[:, None]).ravel()
    return pts, w, d, L, K


_LIFT: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_GAIN: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
#: per face, per fold group: the photo's fields on its blocks (see _photo_gain_q)
_LIFT_Q: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_GAIN_Q: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _photo_gain(face: Face, g: int
                ) -> tuple[tuple[np.ndarray, np.ndarray], tuple[int, int]] | None:
    """``((S, Cw), (x0, y0))``: the fields of group ``g``'s own fold on the photo
    (:func:`_lift_fields`), contiguous float32: ``S`` (h, w, 4), its 4th channel zero, and
    ``Cw`` (h, w, 4), ``C`` with the skin weight, over the box at ``(x0, y0)`` (cached per
    face; None: no own fold). (Four channels: OpenCV resamples a 4-channel float image about
    twice as fast as a 3-channel one, with the same values per channel.)"""
    cache = _GAIN.get(face)
    if cache is None:
        cache = _GAIN.setdefault(face, {})
    if g not in cache:
        got = _photo_lift(face, g)
        if got is None:
            cache[g] = None
        else:
            (S, c4), org = got
            cache[g] = ((zero_alpha(S), np.ascontiguousarray(c4, np.float32)), org)
    return cache[g]


def _photo_lift(face: Face, g: int
                ) -> tuple[tuple[np.ndarray, np.ndarray], tuple[int, int]] | None:
    """``((S, C), (x0, y0))``: :func:`_lift_fields` of group ``g`` on the photo, around its own
    valley on the photo's mesh (cached per face; None if the group has no own fold)."""
    cache = _LIFT.setdefault(face, {})
    if g in cache:
        return cache[g]
    p = crease_plan(face)
    fa = _fast(face)
    V = face.vertices.astype(np.float64)
    pos = _on_mesh(V, *_valley_samples(face))  # (the own valleys on the photo's mesh)
    ia = fa.seg_a[slice(*fa.seg_rng[g])]
    un = p.utaper.astype(np.float64)  # the strength's shape along the line (its scale cancels)
    got = None
    if len(ia) and (np.maximum(un[ia], un[ia + 1]) > 0).any():
        H, W = face.image.shape[:2]
        sb = max(2.5 * float(fa.sig[g]), 1.0)
        pts, w, d, L, K = _band_samples(pos, ia, un)
        # wider than the band: the frame's band, mapped back to the photo, lies inside it
        lo, hi = pts.min(0) - 4.0 * sb - 2.0, pts.max(0) + 4.0 * sb + 2.0
        x0, y0 = max(int(lo[0]), 0), max(int(lo[1]), 0)
        x1, y1 = min(int(hi[0]) + 1, W), min(int(hi[1]) + 1, H)
        q = _work_factor(p.iod)
        if x1 - x0 >= 4 and y1 - y0 >= 4:
            # measured on the sealed photo (the mouth's dark corners are no fold to lift), cut
            # to what the fields read (>= their pads; clipped to the photo, so the fields
            # clip there as on the whole photo): the same values, the box shifted
            P = 2 * int(math.ceil(_VALLEY_WIDTH * float(fa.sig[g]) * 1.25)) + 2 + 2 * q
            R0, S0 = max(x0 - P, 0), max(y0 - P, 0)
            img = sealed_box(face, (R0, S0, min(x1 + P, W), min(y1 + P, H)))
            box, at = (x0 - R0, y0 - S0, x1 - R0, y1 - S0), pts - (R0, S0)
            if q == 1:
                got = (_lift_fields(fa, g, img, at, w, d, L, K, len(ia), box, n_dir=0),
                       (x0, y0))
            else:
                S_up, c4_up, (Sq, cq, (ux, uy)) = _lift_fields_q(fa, g, img, at, w, d, L, K,
                                                                 len(ia), box, q)
                got = ((S_up, c4_up), (x0, y0))
                _LIFT_Q.setdefault(face, {})[g] = (Sq, cq, (R0 + ux, S0 + uy))
    cache[g] = got
    return got


def _photo_gain_q(face: Face, g: int
                  ) -> tuple[tuple[np.ndarray, np.ndarray], tuple[float, float]] | None:
    """:func:`_photo_gain` on the photo's ``q x q`` blocks (a work factor ``q`` > 1): ``S``
    and ``Cw`` (4 channels) as :func:`_lift_fields_q` made them, and the photo position of
    their first block's centre (cached per face; None: no own fold, or a face analysed at
    full resolution)."""
    cache = _GAIN_Q.setdefault(face, {})
    if g not in cache:
        cache[g] = None
        if _photo_lift(face, g) is not None and g in _LIFT_Q.get(face, {}):
            S, c4, at = _LIFT_Q[face][g]
            cache[g] = ((zero_alpha(S), np.ascontiguousarray(c4, np.float32)), at)
    return cache[g]


def _lift_fields_q(fa: _Fast, g: int, img: np.ndarray, pts: np.ndarray, w: np.ndarray,
                   d: np.ndarray, L: np.ndarray, K: int, M: int,
                   box: tuple[int, int, int, int], q: int
                   ) -> tuple[np.ndarray, np.ndarray,
                              tuple[np.ndarray, np.ndarray, tuple[float, float]]]:
    """:func:`_lift_fields` of the photo (``closing``, :data:`_N_DIR_PHOTO` directions) run
    on its ``q x q`` block means around ``box`` and upsampled (bilinear) to ``box``: the
    fields are smooth at the fold's scale (its line width is ``q`` x the working one), while
    the filters' cost grows with the area times the kernels' (a 24 MP portrait: ~10 x less).
    Also the fields on the blocks, and the position on ``img`` of their first block's
    centre."""
    H, W = img.shape[:2]
    x0, y0, x1, y1 = box
    sig = float(fa.sig[g])
    pad = 2 * int(math.ceil(_VALLEY_WIDTH * sig * 1.25)) + 2 + 2 * q  # what _lift_fields reads
    a0, b0 = max(x0 - pad, 0), max(y0 - pad, 0)
    a1 = a0 + (min(x1 + pad, W) - a0) // q * q
    b1 = b0 + (min(y1 + pad, H) - b0) // q * q
    small = _block_mean(img[b0:b1, a0:a1], q)
    o = np.array([a0 + 0.5 * (q - 1), b0 + 0.5 * (q - 1)])  # small pixel (0, 0)'s centre
    # the small box: every small pixel whose block meets ``box``
    sx0, sy0 = (x0 - a0) // q, (y0 - b0) // q
    sx1 = min(-(-(x1 - a0) // q), small.shape[1])
    sy1 = min(-(-(y1 - b0) // q), small.shape[0])
    S, c4 = _lift_fields(fa, g, small, (pts - o) / q, w / q, d / q, L / q, K, M,
                         (sx0, sy0, sx1, sy1), n_dir=0, scale=1.0 / q)
    # (the fields themselves as well, and where their first pixel's block centre lies)
    at = (a0 + 0.5 * (q - 1) + q * sx0, b0 + 0.5 * (q - 1) + q * sy0)
    return (_upsample_box(S, (sx0, sy0), (a0, b0), q, box),
            _upsample_box(c4, (sx0, sy0), (a0, b0), q, box), (S, c4, at))


#: The inter-ocular distance (px) above which the per-face photo analyses of the folds
#: (:func:`_own_valleys`, :func:`_photo_lift`) run on block means (``iod // _WORK_IOD`` px
#: square): a 24 MP portrait's (IOD ~340 px) at half resolution; smaller faces at full.
_WORK_IOD = 150.0


def _frame_blocks(face: Face) -> int:
    """The block size (px) a frame's folds are drawn on (:func:`_unfold_blocks`,
    :func:`_fold_blocks`): the face's work factor (its fold fields on the photo are made on
    such blocks; 1, per pixel, up to 300 px between the eyes)."""
    return _work_factor(crease_plan(face).iod)


def _work_factor(iod: float) -> int:
    """The block size of the per-face fold analyses for a face of ``iod`` px (1: full size)."""
    return max(1, int(iod // _WORK_IOD))


def _block_mean(img: np.ndarray, q: int) -> np.ndarray:
    """float32 means of ``img``'s ``q x q`` blocks (its size a multiple of ``q``)."""
    h, w = img.shape[:2]
    return cv2.resize(img.astype(np.float32), (w // q, h // q), interpolation=cv2.INTER_AREA)


def _upsample_box(field: np.ndarray, at: tuple[int, int], origin: tuple[int, int], q: int,
                  box: tuple[int, int, int, int]) -> np.ndarray:
    """``field``, computed on ``q x q`` block means (its pixel (0, 0) the block at ``at`` of the
    grid whose first block starts at ``origin``), bilinearly upsampled over ``box`` of the
    photo (edge values held beyond the field), contiguous float32."""
    x0, y0, x1, y1 = box
    sx0, sy0 = at
    a0, b0 = origin
    # photo pixel x has block coordinate (x - a0 - (q - 1) / 2) / q
    gx = (np.arange(x0, x1, dtype=np.float32) - np.float32(a0 + 0.5 * (q - 1))) / q - sx0
    gy = (np.arange(y0, y1, dtype=np.float32) - np.float32(b0 + 0.5 * (q - 1))) / q - sy0
    mx = np.broadcast_to(gx[None, :], (y1 - y0, x1 - x0))
    my = np.broadcast_to(gy[:, None], (y1 - y0, x1 - x0))
    return np.ascontiguousarray(cv2.remap(field, np.ascontiguousarray(mx),
                                          np.ascontiguousarray(my), cv2.INTER_LINEAR,
                                          None, cv2.BORDER_REPLICATE), np.float32)


@overload
def _lift_fields(fa: _Fast, g: int, img: np.ndarray, pts: np.ndarray, w: np.ndarray,
                 d: np.ndarray, L: np.ndarray, K: int, M: int, box: tuple[int, int, int, int],
                 closing: Literal[True] = True, n_dir: int = _N_DIR, scale: float = 1.0
                 ) -> tuple[np.ndarray, np.ndarray]: ...
@overload
def _lift_fields(fa: _Fast, g: int, img: np.ndarray, pts: np.ndarray, w: np.ndarray,
                 d: np.ndarray, L: np.ndarray, K: int, M: int, box: tuple[int, int, int, int],
                 closing: Literal[False], n_dir: int = _N_DIR, scale: float = 1.0
                 ) -> tuple[np.ndarray, None]: ...
def _lift_fields(fa: _Fast, g: int, img: np.ndarray, pts: np.ndarray, w: np.ndarray,
                 d: np.ndarray, L: np.ndarray, K: int, M: int, box: tuple[int, int, int, int],
                 closing: bool = True, n_dir: int = _N_DIR, scale: float = 1.0
                 ) -> tuple[np.ndarray, np.ndarray | None]:
    """``S`` (h, w, 3) and ``C`` with the skin-likeness of that lifted level (h, w, 4), float32
    over ``box`` of ``img`` (see :func:`_unfold_draw`; the gain is ``C / S``), for the valley
    sub-sampled at ``pts`` (weights ``w``; ``M`` segments ``d`` of lengths ``L``, ``K``
    sub-samples each). ``closing=False``: ``S`` only (the second is None). ``n_dir``: the
    directions of the along-fold smoothing. ``scale``: ``img`` and the geometry are the
    photo's scaled by it (the group's line width too).
    """
    H, W = img.shape[:2]
    sig = float(fa.sig[g]) * scale
    sb = max(2.5 * sig, 1.0)
    r = int(math.ceil(_VALLEY_WIDTH * sig * 1.25))  # the target may widen the valley
    x0, y0, x1, y1 = box
    # the larger box the closing reads
    h = int(math.ceil(4.5 * max(1.5 * sig, 1.0)))
    pad = 2 * r + 2 if closing else h
    X0, Y0 = max(x0 - pad, 0), max(y0 - pad, 0)
    X1, Y1 = min(x1 + pad, W), min(y1 + pad, H)
    o = np.array([x0, y0], np.float64)
    big = img[Y0:Y1, X0:X1].astype(np.float32)
    # smoothed along the fold only: the valley keeps its profile across the line (its
    # sharp core is lifted too) while the skin's grain along it stays in ``patch / S``
    # (per pixel, the direction of the nearest part of the fold, in _N_DIR steps: a
    # nasolabial fold curves around the mouth)
    dd = d * (w.reshape(M, K).sum(1) / np.maximum(L, 1e-9))[:, None]
    c2 = np.repeat((dd[:, 0] ** 2 - dd[:, 1] ** 2) / np.maximum(L, 1e-9), K)
    s2 = np.repeat(2 * dd[:, 0] * dd[:, 1] / np.maximum(L, 1e-9), K)
    # (only over the written box; around it, where the closing finds the shoulders, an
    # isotropic blur does)
    # (a smooth field: splatted and blurred at 1/f resolution, then resized)
    f = max(1, int(sb / 1.5))
    hb, wb = y1 - y0, x1 - x0
    hc, wc = -(-hb // f), -(-wb // f)
    qb = (pts - o + 0.5) / f - 0.5
    fc, fs = _splat2((hc + 1, wc + 1), qb, c2 / K, qb, s2 / K)
    fc = cv2.GaussianBlur(fc[:-1, :-1], (0, 0), 2.0 * sb / f)
    fs = cv2.GaussianBlur(fs[:-1, :-1], (0, 0), 2.0 * sb / f)
    if f > 1:
        fc = cv2.resize(fc, (wc * f, hc * f), interpolation=cv2.INTER_LINEAR)[:hb, :wb]
        fs = cv2.resize(fs, (wc * f, hc * f), interpolation=cv2.INTER_LINEAR)[:hb, :wb]
    fc = fc * np.float32(f * f) + np.float32(1e-6 * c2.sum())
    fs = fs * np.float32(f * f) + np.float32(1e-6 * s2.sum())
    iy, ix = slice(y0 - Y0, y1 - Y0), slice(x0 - X0, x1 - X0)
    sub = big[max(y0 - Y0 - h, 0):y1 - Y0 + h, max(x0 - X0 - h, 0):x1 - X0 + h]
    cy, cx = min(y0 - Y0, h), min(x0 - X0, h)
    along = round(max(1.5 * sig, 1.0), 2)
    if n_dir == 0:
        Si = _along_taps(sub, (cx, cy), fc, fs, along)
    else:
        Si = _along_filters(sub, (cx, cy), fc, fs, along, n_dir, h)
    # the skin level either side of the valley; blurred so that between shoulders of
    # different brightness (a lit cheek beside a shaded upper lip) it ramps, not steps.
    # S is smooth at the fold's scale: on large faces the closing runs at 1/q resolution
    if not closing:
        return Si, None
    # (every pixel of the box was filtered along the fold; the isotropic blur feeds C)
    S = cv2.GaussianBlur(big, (0, 0), max(0.7 * sig, 0.5))
    S[iy, ix] = Si
    C4 = _closing(fa, g, S, r, iy, ix)
    # where the valley deepens quickly along the line (a nasolabial fold's elbow above the
    # mouth corner) the along-fold mean is lighter than its core, which then stayed a dark
    # stub after the lift (the sample: 110 against shoulders of ~195, lifted to 170): the
    # level the gain divides by is at most the lightly smoothed photo plus the skin's grain
    # (the grain in proportion to the light: GRAIN levels at the skin's level C, fewer in a
    # dark core, where 6 levels stayed a thin dark line after the gain ~C / S)
    # (C's colour as a contiguous copy: numpy's arithmetic on the strided channel view of
    # C4 costs several times more)
    C = cv2.cvtColor(C4, cv2.COLOR_RGBA2RGB)
    np.minimum(Si, big[iy, ix] * (1.0 + np.float32(_GRAIN) / np.maximum(C, 1.0)), out=Si)
    return Si, C4


#: grey levels by which a pixel in an own fold's valley may stay below its lightly smoothed
#: surroundings after the lift: the skin's grain along the valley (see :func:`_lift_fields`)
_GRAIN = 6.0

#: Steps (in units of the along-fold sigma) between the taps of :func:`_along_taps`
_TAP_STEP = 0.5


def _along_taps(sub: np.ndarray, at: tuple[int, int], fc: np.ndarray, fs: np.ndarray,
                along: float) -> np.ndarray:
    """``sub`` smoothed along the fold's own direction at every pixel (a Gaussian of sigma
    ``along`` px, truncated at 3 sigma, sampled by bilinear taps ``_TAP_STEP`` sigma apart
    along the line): float32 over the (h, w) of ``fc`` at ``at`` (x, y) in ``sub``.

    The direction is continuous (half the angle of the doubled-angle field ``(fc, fs)``),
    not quantised; each tap is one ``cv2.remap`` of the box, so the cost is the taps times
    the box, not the kernel's area times the box per direction used. (All taps' maps are
    made at once and resampled by one ``cv2.remap`` of the taps stacked as rows: the same
    values per tap, without a dozen small array operations and calls per tap.)"""
    hb, wb = fc.shape
    n = np.sqrt(fc * fc + fs * fs)
    np.maximum(n, np.float32(1e-30), out=n)
    c2 = fc / n
    ux = np.sqrt(clamp(0.5 + 0.5 * c2, 0.0, 1.0))
    uy = np.sqrt(clamp(0.5 - 0.5 * c2, 0.0, 1.0))
    np.copysign(uy, fs, out=uy)
    h = 3.0 * along
    step = _TAP_STEP * along
    nt = max(int(h / step), 1)
    ts = np.arange(-nt, nt + 1) * (h / nt)
    wts = np.exp(-0.5 * (ts / along) ** 2)
    wts /= wts.sum()
    bx = np.arange(wb, dtype=np.float32) + np.float32(at[0])
    by = (np.arange(hb, dtype=np.float32) + np.float32(at[1]))[:, None]
    nc = sub.shape[2]
    # (a 3-channel image resampled as four channels: OpenCV's 4-channel remap is faster, with
    # the same values per channel)
    src = cv2.cvtColor(sub, cv2.COLOR_RGB2RGBA) if nc == 3 else sub
    k = len(ts)
    t32 = ts.astype(np.float32)[:, None, None]
    mx = ux * t32
    mx += bx
    my = uy * t32
    my += by
    got = cv2.remap(src, mx.reshape(k * hb, wb), my.reshape(k * hb, wb), cv2.INTER_LINEAR,
                    None, cv2.BORDER_REPLICATE)
    acc = np.zeros((hb, wb, src.shape[2]), np.float32)
    for i, wt in enumerate(wts.tolist()):  # (accumulated in the taps' order, as before)
        cv2.scaleAdd(got[i * hb:(i + 1) * hb], wt, acc, dst=acc)
    # (back to 3 channels by OpenCV's RGBA-to-RGB copy: numpy's copy of the strided channel
    # view costs ten times more)
    return cv2.cvtColor(acc, cv2.COLOR_RGBA2RGB) if nc == 3 else acc


def _along_filters(sub: np.ndarray, at: tuple[int, int], fc: np.ndarray, fs: np.ndarray,
                   along: float, nd: int, h: int) -> np.ndarray:
    """``sub`` smoothed along the fold (per pixel, the line kernel of the direction of
    ``(fc, fs)`` rounded to ``nd`` steps; ``h``: the margin of ``sub``)."""
    cx, cy = at
    k = np.rint(np.arctan2(fs, fc) * (0.5 * nd / math.pi)).astype(np.int32) % nd
    Si = np.empty(fc.shape + (sub.shape[2],), np.float32)
    for j in np.flatnonzero(np.bincount(k.ravel(), minlength=nd)):
        m = k == j
        ker = _line_kernel(int(j) * math.pi / nd, along, 0.35)
        kh = min(ker.shape[0] // 2, h)  # how far the kernel reaches (h: the margin of sub)
        # filtered only over the rows/columns where this direction is used (+ the kernel)
        rows, cols = np.flatnonzero(m.any(1)), np.flatnonzero(m.any(0))
        r0, r1, c0, c1 = int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1
        sy0, sx0 = cy + r0, cx + c0
        part = sub[max(sy0 - kh, 0):sy0 + (r1 - r0) + kh,
                   max(sx0 - kh, 0):sx0 + (c1 - c0) + kh]
        oy, ox = min(sy0, kh), min(sx0, kh)
        filt = cv2.filter2D(part, -1, ker, borderType=cv2.BORDER_REPLICATE)
        np.copyto(Si[r0:r1, c0:c1], filt[oy:oy + r1 - r0, ox:ox + c1 - c0],
                  where=m[r0:r1, c0:c1, None])
    return Si


def _closing(fa: _Fast, g: int, S: np.ndarray, r: int, iy: slice, ix: slice) -> np.ndarray:
    """``C`` (the closing of ``S`` of radius ``r``, blurred) over ``[iy, ix]`` with the
    skin-likeness of that level as a 4th channel."""
    q = max(1, r // 6)
    if q > 1:
        rq = max(r // q, 1)
        small = cv2.resize(S, (max(S.shape[1] // q, 1), max(S.shape[0] // q, 1)),
                           interpolation=cv2.INTER_AREA)
        C = cv2.GaussianBlur(_close(small, rq), (0, 0), 0.6 * r / q)
        C = cv2.resize(C, (S.shape[1], S.shape[0]), interpolation=cv2.INTER_LINEAR)
    else:
        C = cv2.GaussianBlur(_close(S, r), (0, 0), 0.6 * r)
    # the lifted level is skin unless it is much darker than the skin or off its colour
    # (hair, brows, eyes); lighter is fine (the reference may be a shaded median)
    C = np.ascontiguousarray(C[iy, ix])
    ref = fa.skin[g]
    # (_skin_weight of min(C, ref + 0.3 (C - ref)), tolerance 0.6, in float32 and OpenCV's
    # per-pixel channel arithmetic: numpy's on channel views costs several times more)
    # (the reference as OpenCV's per-channel scalar, (4,) float64 holding float32 values:
    # subtracted in float32)
    sc = np.zeros(4)
    sc[:3] = np.asarray(ref, np.float32)
    d: np.ndarray = np.asarray(cv2.subtract(C, sc), np.float32)
    np.minimum(d, np.float32(0.3) * d, out=d)  # the level minus ref
    np.multiply(d, d, out=d)
    dist = np.sqrt(cv2.transform(d, np.full((1, 3), 1.0 / 3.0, np.float32)))
    ref_l = np.float32(1.0 / float(fa.ref_l[g]))  # (max(float(np.mean(ref)), 20.0))
    wgt = clamp((np.float32(0.6) - dist * ref_l) * np.float32(4.0), 0.0, 1.0)
    return cv2.merge([C, wgt.astype(np.float32)])


def creases_cost_ms(face: Face, faps: FapInput, n: int = 30, warm: int = 3) -> dict[str, float]:
    """Median time (ms) of ``face.render(faps)`` with and without creases (for the bench)."""
    vec = face.fap_vector(faps)
    crease_plan(face)
    ta, tb = [], []
    for i in range(warm + n):
        t0 = time.perf_counter()
        face.render(vec, creases=False)
        t1 = time.perf_counter()
        face.render(vec, creases=True)
        t2 = time.perf_counter()
        if i >= warm:
            ta.append(t1 - t0)
            tb.append(t2 - t1)
    a, b = float(np.median(ta) * 1000.0), float(np.median(tb) * 1000.0)
    return {"without_ms": round(a, 3), "with_ms": round(b, 3), "creases_ms": round(b - a, 3)}


def fold_lines(face: Face, vertices: np.ndarray) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """``(kind, points (n, 2), darkening (n,))`` of every fold on a deformed mesh."""
    p = crease_plan(face)
    s = fold_strength(face, vertices)
    V = np.asarray(vertices, np.float64)
    pos = (V[face.mesh.triangles[p.tri]] * p.bary[..., None]).sum(1)
    return [(p.kinds[f], pos[p.start[f]:p.start[f + 1]], s[p.start[f]:p.start[f + 1]])
            for f in range(p.n_folds)]
