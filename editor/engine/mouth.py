"""The mouth interior behind the inner lips (SPEC §3.1, eqs. 6-8). No Qt.

Layers, back to front: dark cavity (softly shaded), tongue (depth 3), lower teeth (2), upper
teeth (1); the warped face (0) is composited over them by :mod:`layers`.

Sizes and placement (eqs. 6-8), on the deformed mesh, in the face frame turned with the skull:

* ``D`` = the paper's mouth-nose distance, lip line minus y(9.3) on the neutral mesh. The FAPU
  MNS0 of this project is measured from 9.15 (MPEG-4 convention, SPEC §1.4) and is ~0.62 D;
  with it the lower teeth of eq. 8 would stay behind the lower lip for every jaw opening
  (exposure 0 px on all ten JAFFE faces), so eqs. 6-8 use the paper's own quantity;
* teeth height D/2, widths from the textures' aspect ratio; upper teeth: top edge at
  y(9.3) + 0.25 D, centred on x(9.3) (fixed to the skull); lower teeth: bottom edge at
  0.25 y(2.1) + 0.75 y(2.3), centred on x(2.1) (follow the jaw);
* tongue: width MW0, aspect kept, centred on x(2.1), top edge level with the top of the lower
  teeth; the tongue FAPs (43-47) bend it through the displacements of its points 6.1-6.4
  (smooth partition-of-unity field, root fixed; tip and sides ride on the body 6.2).

The photo's own mouth interior (when its mouth is open, e.g. smiling teeth) is kept: per column
of the photo's opening, the bright teeth run from the top follows the skull, the rest (lower
teeth, the lower lip's edge) follows the jaw anchor of eq. 8; the synthetic layers show only
where neither covers (``layers._own_interior`` analyses the photo, :meth:`attach_own`).
Textures (``editor/data/mouth``) are tinted to the photo: saturation and brightness from the
cheeks' skin, teeth colour from the photo's own teeth when it shows some; what is drawn takes
the photo's grain (:func:`grain.grain_over`: drawn smooth, the interior of a grainy photo read
as an inlay; JAFFE, robust high-pass level of a wide-open mouth's interior 0.3-0.4 of the
photo's grain without it, 1.1-1.2 with it).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from functools import cached_property, lru_cache

import cv2
import numpy as np

from editor.resources import MOUTH_DIR

from .deform import DeformPlan
from .fitting import clamp, clip, interp
from .gaze import spread3, warp_rgb
from .mesh import StandardMesh

TEXTURES = MOUTH_DIR
NAMES = ("upper_teeth", "lower_teeth", "tongue")
#: upper incisors' edge below the neutral lip line, in units of D (mouth-nose distance)
UPPER_TIP = 0.10
#: lower incisors' edge above the neutral lip line (overbite), and the tongue's top above
#: theirs, in units of D
LOWER_OVERBITE, TONGUE_RISE = 0.05, 0.2
#: the tongue's mean luminance relative to the lit skin: it lies deep behind the opening, lit
#: at a grazing angle under the upper lip (the lower part of real wide-open JAFFE mouths,
#: tongue and lower teeth: median 0.48 of the skin over 13 surprise photos; it was 0.8; at 0.5
#: a pale lower lip met it with a hard dark edge)
TONGUE_L = 0.55
#: the lower teeth's light relative to the upper ones (below and behind them, under the upper
#: lip's and teeth's shadow): 0.75 of the skin's luminance (0.68 x 1.1, set when the upper
#: teeth were drawn at 1.1; at 0.8 x 1.1 a wide-open mouth ended in a white block of lower
#: teeth)
LOWER_SHADE = 0.79
#: depth behind the lips (units of D) of the teeth: light reaches them through the local gap
#: g between the lips as g / sqrt(g^2 + z^2) (the narrow corners of an opening stay dark:
#: real JAFFE fear photos' outer columns 0.22 of the skin, renders 0.38, before 0.56)
APERTURE_TEETH = 0.1
#: the tongue seen through a wider opening is its part further back, lit at a more grazing
#: angle: its light falls as z / sqrt(g^2 + z^2) with the local gap g (z in units of D). Real
#: JAFFE mouths, lower third of the opening relative to the skin: smiles 0.65, fear 0.48,
#: wide-open surprise 0.34; renders of the same photos' estimated FAPs: 0.79 / 0.42 / 0.42
#: (before: 0.97 / 0.55 / 0.50, a tongue as light in a gaping mouth as in a slit)
TONGUE_RECEDE = 1.2
#: the dental arch's half-width (units of half the mouth width MW0) and the light its sides
#: still get (ambient) where they face sideways: the lower teeth's (deeper, behind the lower
#: lip) and the upper teeth's. A smile shows its upper teeth far towards the corners: the
#: bright share of the opening's outer thirds in real JAFFE smiles is 0.18 (median of ten
#: women), the renders of joy gave 0.06 with the lower teeth's arch (dark wedges at the
#: corners), 0.18 with the upper one (the whole opening 0.48, real 0.40)
ARCH_W, ARCH_AMBIENT = 0.7, 0.2
ARCH_W_UP, ARCH_AMBIENT_UP = 1.0, 0.3
#: teeth luminance relative to the lit skin, and how much of the skin's colour cast they take.
#: JAFFE's ten women, the 90th percentile of the luminance inside the inner lips over the skin
#: around the mouth: real open smiles 1.21 (21 photos), joy drawn on their neutral photos
#: 1.32 at 1.1 (the teeth's middle rows 1.33 where real ones are 1.17; 1.58 at 150 %: white
#: blocks the blind raters called pasted on), 1.23 at 0.95
TEETH_L, TEETH_CAST = 0.95, 0.35
#: the photo's upper teeth continued above its opening: crown height (central incisor,
#: units of D; the drawn teeth are D/2 tall with their gum band) before they turn into gum,
#: over a fade of GUM_FADE D; and the upper lip's shadow on them at contact
CROWN, GUM_FADE, EXT_LIP_SHADOW = 0.42, 0.12, 0.12
#: on a large face (the photo's edge ramp ``soft`` over 1 px; in full from 1 + SOFT_FULL):
#: the back of the cavity darkens with the depth behind the lips (exp(-depth / (BACK_LEN
#: D))) down to 1 - BACK_DEEP of its light, and the lips' inner surface turns into it over
#: RIM_SOFT * soft px more.
SOFT_FULL, BACK_LEN, BACK_DEEP, RIM_SOFT = 3.0, 0.15, 0.6, 0.5
#: on a large face, the upper teeth show lit only where their edge lies this many edge ramps
#: below the upper lip (a thinner sliver stays in the lip's shadow)
SLIVER_SOFT = 2.0
#: on a large face, the tongue lit at its front: darker by up to TONGUE_BACK_DARK from the
#: lower lip up over TONGUE_BACK D (its layer's top 0.4 darkened instead, the tongue behind
#: a surprised mouth's lower lip was its dark back: 0.13 of the skin on the 4K bench face,
#: real wide-open JAFFE mouths' lower part 0.34-0.48)
TONGUE_BACK, TONGUE_BACK_DARK = 0.3, 0.4
#: cavity colour (RGB) for a neutral skin of luminance 200; its luminance scaled per photo,
#: its hue :func:`cavity_hue` (this one's, desaturated by the skin's saturation, only where
#: the skin's colour is unknown)
CAVITY_RGB = np.array([70, 26, 30], np.float32)
#: the light that reaches the back of an open mouth has bounced off its walls, tissue of the
#: skin's hue, several times: the cavity's hue is the skin's (colour over luminance) to this
#: power. The sample photo's own dark interior (its smile's buccal corridor, the darkest 5 %
#: of its opening), colour over luminance: 1.92 0.68 0.22 (landmarks' inner-lip polygon; 1.85
#: 0.71 0.24 upscaled 4 x; 1.83 0.72 0.29 inside the mesh's opening); its skin's hue 1.15
#: 0.96 0.81 to the 6th: 1.95 0.66 0.25. CAVITY_RGB desaturated by the skin's saturation gave
#: the rendered opening's darkest 5 % 1.44 0.82 0.79 (surprise 100 %): a purple-black; now
#: 1.65 0.77 0.47 (the lips' inner surface mixed in, :data:`INNER_BOUNCES`). A grey photo's
#: cavity stays grey (JAFFE renders unchanged).
CAVITY_BOUNCES = 6.0
#: the lips' inner surface turned into the mouth (its light RIM_LIGHT of the lips' colour
#: beside the opening) and the tongue are lit by light that bounced off the mouth's walls
#: fewer times: the skin's hue to INNER_BOUNCES. Chosen by eye on the 4K bench face between
#: 0 (the lips' own pink darkened: a purple-black interior) and 3-4 (the darkest 5 % of the
#: opening then match the photo's own hue, 1.8-2.0 0.64-0.74 0.21-0.48, but the lips' inner
#: surface turns an orange-red band, as if painted; at 1.5 dark red-brown)
RIM_LIGHT = 0.45
INNER_BOUNCES = 1.5
_LUM = np.array([0.299, 0.587, 0.114], np.float32)


@lru_cache(maxsize=1)
def load_textures() -> dict[str, np.ndarray]:
    """The three textures as straight RGBA float32 (colour 0-255, alpha 0-1)."""
    out = {}
    for name in NAMES:
        path = TEXTURES / f"{name}.png"
        bgra = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if bgra is None or bgra.ndim != 3 or bgra.shape[2] != 4:
            raise FileNotFoundError(f"missing or not RGBA: {path} "
                                    "(run scripts/draw_mouth_textures.py)")
        rgba = bgra[..., [2, 1, 0, 3]].astype(np.float32)
        rgba[..., 3] /= 255.0
        out[name] = rgba
    return out


def _lum(rgb: np.ndarray) -> np.ndarray:
    return np.asarray(rgb, np.float32) @ _LUM


def _sat(rgb: np.ndarray) -> float:
    c = np.asarray(rgb, np.float64)
    return float((c.max() - c.min()) / max(c.max(), 1e-6))


@lru_cache(maxsize=1)
def _texture_parts() -> dict[str, tuple[np.ndarray, ...]]:
    """Per texture, what :func:`_tint` and :func:`_opaque_mean` take from it whatever the
    photo, in channel planes: the luminance (h, w), the chroma ``colour - luminance``
    (3, h, w) and the alpha (h, w); over the opaque pixels (alpha > 0.9; for the teeth, their
    crowns without the gum) their luminance (n,) and chroma (3, n), and the same of the gum
    band (the upper teeth's top eighth, alpha > 0.5). (The same values as
    computed on the (h, w, 3) colours; planes, because numpy is several times slower
    spreading an (h, w, 1) array over 3 channels.)"""
    out = {}
    for name, rgba in load_textures().items():
        c = rgba[..., :3]
        lum = _lum(c)[..., None]
        opaque = rgba[..., 3] > 0.9
        if name.endswith("_teeth"):  # the crowns only: the pink gum band is not the teeth's
            opaque &= c[..., 0] - c[..., 1] < 0.15 * 255.0  # colour (it gave them a cyan cast)
        co = c[opaque]
        lum_o = _lum(co)[:, None]
        a = rgba[..., 3:4]
        # premultiplied (c a, a): what a face's small copy is resized from
        pre = np.concatenate([c * a, a], 2).astype(np.float32)
        # any tint's value is between lum and the colour: at most this per channel
        seen = rgba[..., 3] > 0
        bound = np.maximum(c[seen], lum[seen]).max(0) if seen.any() else np.zeros(3)
        # the gum band (the upper teeth's top eighth, alpha > 0.5): its pixels' lum and chroma
        top = rgba[: max(1, rgba.shape[0] // 8)].reshape(-1, 4)
        top = top[top[:, 3] > 0.5, :3].astype(np.float64)
        lum_t = _lum(top)[:, None]
        out[name] = tuple(np.ascontiguousarray(x) for x in (
            lum[..., 0], (c - lum).transpose(2, 0, 1), rgba[..., 3], lum_o[:, 0],
            (co - lum_o).T, pre, np.asarray(bound, np.float64),
            np.array([lum_o.mean(dtype=np.float64)]), (co - lum_o).mean(0, dtype=np.float64),
            lum_t[:, 0], (top - lum_t).T))
    return out


def _tinted_at(name: str, sat: float, gain: np.ndarray, size: tuple[int, int]
               ) -> np.ndarray:
    """``cv2.resize(_tint(name, sat, gain), size, INTER_AREA)``: the premultiplied texture
    ``(c a, a)`` resized first, then tinted: ``((1 - sat) lum + sat c) a gain``, linear in
    ``c a`` (``lum`` is) where nothing is clipped at 255, which :func:`_texture_parts`'
    per-channel bound rules out (else the full texture is tinted and resized)."""
    parts = _texture_parts()[name]
    g = np.asarray(gain, np.float32)
    fg = _gap_factor(name, size)
    if np.any(g.astype(np.float64) * parts[6] * (1.0 if fg is None else float(fg.max()))
              > 255.0):
        return np.asarray(cv2.resize(_with_gaps(_tint(name, sat, gain), name, size), size,
                                     interpolation=cv2.INTER_AREA), np.float32)
    small = _premul_at(name, size)
    ca = small[..., :3]
    c = ca * np.float32(sat)
    c += (np.float32(1.0 - sat) * _lum(ca))[..., None]
    c *= g
    return np.concatenate([c, small[..., 3:4]], 2)


@lru_cache(maxsize=16)
def _premul_at(name: str, size: tuple[int, int]) -> np.ndarray:
    """The premultiplied texture ``name`` (with :func:`_with_gaps`) resized to ``size``
    (INTER_AREA), float32, read-only: it depends on the texture and the size only (kept, as
    :func:`_gap_factor`: a face's size recurs when its plans are rebuilt, ~0.3-0.6 ms a
    texture at 1920x1080)."""
    small = np.asarray(cv2.resize(_with_gaps(_texture_parts()[name][5], name, size), size,
                                  interpolation=cv2.INTER_AREA), np.float32)
    small.setflags(write=False)
    return small


#: the width (output pixels) the gaps between drawn teeth keep when the texture is shrunk.
#: JAFFE's 25 open mouths showing upper teeth: the central incisors' contact, rows 1-2 under
#: the upper lip, is 0.63 of the row's median light (p10..p90 0.35..0.83); at 0.6 px the
#: drawn ones gave 0.74 (joy and viseme aa on the ten women), at 1.5 px 0.65
GAP_PX = 1.5


@lru_cache(maxsize=16)
def _gap_factor(name: str, size: tuple[int, int]) -> np.ndarray | None:
    """Per texture pixel (h, w, 4) float32 ``(f, f, f, 1)``: how much to darken the colour of
    the teeth texture ``name`` (its alpha kept) so
    that shrunk to ``size`` its dark gaps between the teeth stay :data:`GAP_PX` wide, or None
    (the lower teeth and the tongue; sizes near the texture's). Averaged away, a row of teeth
    60 px wide (a JAFFE face) read as one smooth slab with a seam in the middle (the gaps'
    contrast along a row, mean |row - its Gaussian blur (2 px)| / mean: real JAFFE smiles
    0.115, drawn 0.056 with 0.6 px gaps, 0.075 with 1.5 px). The factor is
    the luminance's grey erosion along x over its own value: one scale per pixel, so the tint
    (linear in the colour) commutes with it and a face's copy may be resized before it is
    tinted (:func:`_tinted_at`)."""
    if name != "upper_teeth":  # (the lower teeth sit in the upper ones' shadow: kept smooth)
        return None
    pre = _texture_parts()[name][5]
    k = int(round(GAP_PX * pre.shape[1] / max(size[0], 1)))
    if k < 2:
        return None
    lum = np.ascontiguousarray(_lum(pre[..., :3]))
    f = cv2.erode(lum, np.ones((1, k), np.uint8)) / np.maximum(lum, np.float32(1e-3))
    # the crowns' mean light kept (the teeth's colour is matched to the photo's on it): the
    # gaps darken, the teeth between them brighten a little
    alpha = pre[..., 3]
    crowns = alpha > 0.9
    f /= max(float((f[crowns] * lum[crowns]).sum() / max(float(lum[crowns].sum()), 1e-6)), 1e-3)
    f4 = np.ones(f.shape[:2] + (4,), np.float32)
    f4[..., :3] = np.asarray(f, np.float32)[..., None]
    f4.setflags(write=False)
    return f4


def _with_gaps(pre: np.ndarray, name: str, size: tuple[int, int]) -> np.ndarray:
    """``pre`` (h, w, 4, premultiplied) with :func:`_gap_factor` on its colour (one contiguous
    multiply by ``(f, f, f, 1)``: the same values as ``out[..., :3] *= f`` on a copy, alpha
    times 1 itself, ~20x faster than numpy's broadcast over a channel view)."""
    f4 = _gap_factor(name, size)
    if f4 is None:
        return pre
    return np.multiply(pre, f4, dtype=np.float32)


def _tint(name: str, sat: float, gain: np.ndarray) -> np.ndarray:
    """Texture ``name`` desaturated to ``sat`` and scaled per channel: premultiplied RGBA
    (h, w, 4) float32, ``clip((lum + sat (c - lum)) gain, 0, 255) alpha`` per channel."""
    lum, chroma, alpha = _texture_parts()[name][:3]
    c = sat * chroma
    c += lum
    c *= np.asarray(gain, np.float32)[:, None, None]
    np.clip(c, 0, 255, out=c)
    c *= alpha
    return np.asarray(cv2.merge([c[0], c[1], c[2], alpha]), np.float32)


def _opaque_mean(name: str, sat: float) -> np.ndarray:
    """Mean colour (3,) float32 of texture ``name``'s opaque pixels desaturated to ``sat``:
    the values of ``(lum + sat (c - lum)).mean(0)`` over the (n, 3) pixels, whose float32
    sums run through the pixels in order (here a cumulative sum per channel plane)."""
    ml, mc = _texture_parts()[name][7:9]
    return (ml + sat * mc).astype(np.float32)


def teeth_colour(skin_l: float, skin: np.ndarray | None, teeth: np.ndarray | None
                 ) -> np.ndarray:
    """Colour (3,) of lit teeth in this photo.

    The photo's own teeth when it shows some (their saturation limited to the skin's and their
    hue pulled towards it: a cast from the lips or a compression artefact must not turn the
    drawn teeth green or blue); otherwise a light grey at ``TEETH_L`` of the skin's luminance
    with ``TEETH_CAST`` of the skin's chroma (the photo's white balance and light colour).
    """
    if skin is None:
        skin = np.full(3, skin_l, np.float64)
    skin = np.asarray(skin, np.float64)
    chroma = skin - float(_lum(skin))
    if teeth is not None:
        t = np.asarray(teeth, np.float64)
        lt = float(_lum(t))
        tc = t - lt
        # keep the teeth's brightness; chroma: half their own, half the skin's cast
        c = 0.5 * tc + 0.5 * TEETH_CAST * chroma * (lt / max(float(_lum(skin)), 1.0))
        lim = float(np.abs(chroma).max()) * TEETH_CAST * 1.5 + 1e-6
        c = c * min(1.0, lim / max(float(np.abs(c).max()), 1e-6))
        return clamp(lt + c, 0.0, 255.0)
    lt = TEETH_L * skin_l
    return clamp(lt + TEETH_CAST * chroma * (lt / max(float(_lum(skin)), 1.0)), 0.0, 255.0)


def cavity_hue(skin: np.ndarray) -> np.ndarray:
    """(3,) float64 of unit luminance: the hue of an open mouth's dark interior for a skin of
    colour ``skin`` (RGB): the skin's hue raised to :data:`CAVITY_BOUNCES` (light bounced
    off the mouth's walls that many times), normalised."""
    s = np.maximum(np.asarray(skin, np.float64), 1.0)
    return _hue_power(s / float(s @ _LUM.astype(np.float64)), CAVITY_BOUNCES)


def _hue_power(hue: np.ndarray, n: float) -> np.ndarray:
    """(3,) float64: ``hue`` (colour over luminance) to the power ``n``, normalised to unit
    luminance (all ones for a grey hue)."""
    h = np.power(np.maximum(np.asarray(hue, np.float64), 1e-3), n)
    return h / float(h @ _LUM.astype(np.float64))


def _poly_mask(shape: tuple[int, int], poly: np.ndarray, off: np.ndarray) -> np.ndarray:
    m = np.zeros(shape, np.uint8)
    cv2.fillPoly(m, [np.round((poly - off) * 16).astype(np.int32)], 1, cv2.LINE_8, 4)
    return m


@dataclass(eq=False)
class MouthPlan:
    """Precomputed mouth interior of one face (see module docstring)."""

    hole: np.ndarray
    i93: int
    i21: int
    i23: int
    upper_lip: np.ndarray  # vertex indices of the inner upper lip, corner to corner
    ex: np.ndarray  # neutral face frame axes (image coords)
    ey: np.ndarray
    mouth_nose: float  # D, px
    mw: float  # MW0, px
    tex: dict[str, np.ndarray]  # premultiplied RGBA at the neutral pixel size
    size: dict[str, tuple[float, float]]  # neutral (width, height) px of each layer
    anchor0: np.ndarray  # neutral jaw anchor (eq. 8 point), image px
    cavity: np.ndarray  # (3,) float32
    tongue_basis: np.ndarray  # (4 FAPs, 4 points, 2) px per unit, image coords
    tongue_roll: float  # px at full roll, see deform._nonlinear
    lip_pairs: np.ndarray  # (7, 2) inner upper / lower lip vertices
    lower_lip: np.ndarray  # vertex indices of the inner lower lip, corner to corner
    gap0: np.ndarray  # (7,) their neutral gaps, px
    gum: np.ndarray  # (3,) tinted gum colour
    tip_up: float = 0.0  # neutral px below y(9.3) of the upper incisors' edge (frame y)
    low_off: float = 0.0  # lower incisors' edge minus the eq. 8 anchor, neutral px
    mns: float = 0.0  # px per MNS unit (FAPs 16/17 push the lips forward by f * mns)
    bounce: np.ndarray | None = None  # (3,) the skin's hue (colour / luminance): bounced light
    # the photo's own interior (attach_own)
    own_off: np.ndarray | None = None  # (2,) image position of own[0, 0]
    own: np.ndarray | None = None  # (h, w, 2) float32: photo interior following skull / jaw
    own_rgb: np.ndarray | None = None  # (h, w, 6) float32: its colours
    photo_upper: bool = False  # the photo shows its own upper teeth: they replace the texture
    photo_lower: bool = False  # likewise for the lower teeth
    sliver: np.ndarray | None = None  # (w,) columns where the opening is a closed lip line
    tex_pad: int = 0  # blank pixels around each texture in :attr:`tex` (:meth:`soften`)
    soft: float = 1.0  # the photo's edge ramp, px (:meth:`soften`)
    ext: np.ndarray | None = None  # (h, w) where the photo's upper teeth were continued

    def attach_own(self, off, own, own_rgb, has_up, has_low, sliver, ext) -> None:
        """Add the photo's own interior (see ``layers._own_interior``)."""
        self.own_off, self.own, self.own_rgb = off, own, own_rgb
        self.photo_upper, self.photo_lower, self.sliver, self.ext = has_up, has_low, sliver, ext
        self._own_a = [np.ascontiguousarray(own[..., k]) for k in (0, 1)]
        # (four channels, the 4th zero: OpenCV resamples 4-channel float images about twice
        # as fast as 3-channel ones, with the same values per channel; the channels copied
        # by cv2.mixChannels: numpy's strided copy between channel views costs 4x more)
        self._own_c = []
        for k in (0, 1):
            c4 = np.zeros(own_rgb.shape[:2] + (4,), np.float32)
            cv2.mixChannels([np.asarray(own_rgb, np.float32)], [c4],
                            [3 * k, 0, 3 * k + 1, 1, 3 * k + 2, 2])
            self._own_c.append(c4)
        # (and as 3 contiguous channels: small boxes resample them in one call, :meth:`_own_at`)
        self._own_c3 = [np.ascontiguousarray(own_rgb[..., 3 * k:3 * k + 3], np.float32)
                        for k in (0, 1)]
        self._own_keep = [a * (1.0 - sliver[None, :]) for a in self._own_a]
        self._own_parts()

    def _own_parts(self) -> None:
        """Per part of the photo's interior (skull, jaw): its coverage minus the kept part
        (``_own_span``) and whether it covers anything at all (``_own_has``: a part that does
        not, often the jaw's, samples as zeros everywhere: :meth:`_own_at` skips it)."""
        self._own_span = [a - b for a, b in zip(self._own_a, self._own_keep, strict=True)]
        self._own_has = [bool(np.count_nonzero(a) or np.count_nonzero(b))
                         for a, b in zip(self._own_a, self._own_keep, strict=True)]

    def soften(self, soft: float) -> None:
        """Ramp the photo's own interior parts (upper teeth with the skull, the rest with the
        jaw) in over ``soft`` px (the photo's edge ramp, ``layers.LayerPlan.soft``): on a soft
        photo their masks' one-pixel edges cut the teeth from the dark cavity with a step
        harder than anything in the photo. Their colours are the photo's own on both sides.
        The drawn teeth and tongue are blurred as much (premultiplied, fading to nothing at
        their rectangles' edges): crisp, their gaps read as black slits between grey blocks
        on a face whose own edges ramp over 10 px."""
        if soft <= 1.0:
            return
        self.soft = float(soft)
        sigma = 0.31 * soft  # (a Gaussian's 10-90 % width, 2.56 sigma, as 0.8 soft)
        # each image padded by the blur's reach first (coverage zero, colours repeated): the
        # drawn teeth's crowns and the photo's opening reach their images' edges, and blurred
        # up to an edge they stopped there at ~0.5, a one-pixel step to the cavity (the 4K
        # bench face under surprise: the photo's upper teeth 98 -> 35 grey levels in a pixel,
        # the drawn lower teeth's tips 52 -> 96 in two, on a face whose edges ramp over 15 px)
        p = int(math.ceil(3.0 * sigma))
        zero = cv2.BORDER_CONSTANT

        def pad(a: np.ndarray, border: int = zero) -> np.ndarray:
            return cv2.copyMakeBorder(np.ascontiguousarray(a), p, p, p, p, border)

        self.tex = {k: cv2.GaussianBlur(pad(t), (0, 0), sigma, borderType=zero)
                    for k, t in self.tex.items()}
        self.tex_pad = p
        if self.own is None or self.own_off is None:
            return

        self.own_off = self.own_off - p
        self._own_c = [pad(c, cv2.BORDER_REPLICATE) for c in self._own_c]
        self._own_c3 = [pad(c, cv2.BORDER_REPLICATE) for c in self._own_c3]
        if self.ext is not None:
            self.ext = pad(np.asarray(self.ext, np.float32))
        self._own_a = [cv2.GaussianBlur(pad(a), (0, 0), sigma, borderType=zero)
                       for a in self._own_a]
        self._own_keep = [cv2.GaussianBlur(pad(a), (0, 0), sigma, borderType=zero)
                          for a in self._own_keep]
        self._own_parts()

    @classmethod
    def build(cls, vertices: np.ndarray, mesh: StandardMesh, plan: DeformPlan, skin_l: float,
              sat: float, teeth: np.ndarray | None, skin: np.ndarray | None = None,
              neutral: np.ndarray | None = None) -> MouthPlan:
        """Sizes, anchors and tinted textures; the photo's own interior is added by
        :meth:`attach_own` (``layers.layer_plan`` analyses the photo).

        ``skin_l``, ``sat``: luminance and relative saturation of the photo's skin; ``skin``
        its colour (the teeth take its colour cast); ``teeth``: colour of the photo's own
        visible teeth, or None. ``neutral``: the neutral mesh (default ``vertices``): sizes and
        the upper teeth's height come from it, the jaw anchor from the photo's mesh.
        """
        v = vertices.astype(np.float64)
        vn = v if neutral is None else np.asarray(neutral, np.float64)
        ex, ey = plan.frame_rot[:, 0].copy(), plan.frame_rot[:, 1].copy()
        fdp = mesh.fdp
        i93, i21, i22, i23 = fdp["9.3"], fdp["2.1"], fdp["2.2"], fdp["2.3"]
        yf = vn @ ey
        D = max(0.5 * (yf[i22] + yf[i23]) - yf[i93], 4.0)
        # the upper incisors' edge a little below the neutral lip line (the lower lip covers it
        # at rest; a smile's raised upper lip uncovers it), not 0.25 D above it (eq. 7 put the
        # teeth's top edge at 0.25 D, their tips then hid behind the upper lip in every smile)
        tip_up = D + UPPER_TIP * D
        low_off = D * (1.0 - LOWER_OVERBITE) - (0.25 * yf[i21] + 0.75 * yf[i23] - yf[i93])
        mw = max(plan.fapu["MW"] * 1024.0, 4.0)
        hole = np.asarray(mesh.holes["mouth"])
        # ---- textures, tinted and scaled to the face
        raw = load_textures()
        H = 0.5 * D
        size = {}
        for name in ("upper_teeth", "lower_teeth"):
            th, tw = raw[name].shape[:2]
            size[name] = (H * tw / th, H)
        th, tw = raw["tongue"].shape[:2]
        size["tongue"] = (mw, mw * th / tw)
        ivory = _opaque_mean("upper_teeth", sat)
        target = teeth_colour(skin_l, skin, teeth)
        gain_t = (target / np.maximum(ivory, 1.0)).astype(np.float32)
        tongue_mean = _opaque_mean("tongue", sat)
        # (in the hue of the light bounced inside the mouth, INNER_BOUNCES; its mean luminance
        # kept at TONGUE_L of the skin's)
        hue_g = np.ones(3, np.float32) if skin is None else _hue_power(
            np.asarray(skin, np.float64) / max(float(_lum(skin)), 1.0), INNER_BOUNCES
        ).astype(np.float32)
        gain_g = np.full(3, TONGUE_L * skin_l / max(float(_lum(tongue_mean * hue_g)), 1.0),
                         np.float32) * hue_g
        # (no channel tinted past 255 at the texture's brightest pixel: the bounced light's red
        # (1.16 on the sample) would clip a few highlight pixels, and the exact tint of a
        # clipped texture is the full-size texture's, 0.55 ms more a face at 1080p; held
        # under it the tongue's red is at most ~1.5 % darker)
        gain_g = np.minimum(gain_g, (254.5 / _texture_parts()["tongue"][6]).astype(np.float32))
        tex = {}
        for name, gain, shade in (("upper_teeth", gain_t, 1.0),
                                  ("lower_teeth", gain_t, LOWER_SHADE), ("tongue", gain_g, 1.0)):
            wpx, hpx = size[name]
            tw_, th_ = max(int(round(wpx)), 2), max(int(round(hpx)), 2)
            tex[name] = _tinted_at(name, sat, gain * shade, (tw_, th_))
        # the gum: the tinted upper teeth's top band (alpha > 0.5), unpremultiplied
        lum_g, chroma_g = _texture_parts()["upper_teeth"][9:11]
        if len(lum_g):
            # (lum + sat chroma) gain clipped, per channel plane; its mean over the band's
            # pixels summed one after the other, as numpy's mean over the first axis of the
            # (n, 3) pixels sums them (a running sum: its last value; numpy's mean over a
            # plane's contiguous axis would sum pairwise)
            g = sat * chroma_g
            g += lum_g
            g *= gain_t.astype(np.float64)[:, None]
            gum_rgb = np.cumsum(clamp(g, 0.0, 255.0), axis=1)[:, -1] / len(lum_g)
        else:
            gum_rgb = 0.6 * target
        cav_l = float(_lum(CAVITY_RGB))
        if skin is None:
            cavity = (cav_l + sat * (CAVITY_RGB - cav_l)) * (skin_l / 200.0)
        else:
            cavity = cav_l * (skin_l / 200.0) * cavity_hue(skin)
        anchor0 = _jaw_anchor(v, i21, i23, ex, ey)
        V = plan.n_vertices
        tongue_basis = plan.basis[42:46, V + 2:V + 6].astype(np.float64)  # FAPs 43-46
        lip_pairs = np.array([[mesh.index(f"lipi_u{k}"), mesh.index(f"lipi_d{k}")]
                              for k in range(1, 8)])
        gap0 = (v[lip_pairs[:, 1]] - v[lip_pairs[:, 0]]) @ ey
        up_lip = np.concatenate([[mesh.index("lipi_c0")],
                                 [mesh.index(f"lipi_u{k}") for k in range(1, 8)],
                                 [mesh.index("lipi_c1")]])
        lo_lip = np.concatenate([[mesh.index("lipi_c0")],
                                 [mesh.index(f"lipi_d{k}") for k in range(1, 8)],
                                 [mesh.index("lipi_c1")]])
        return cls(hole=hole, i93=i93, i21=i21, i23=i23, upper_lip=up_lip, ex=ex, ey=ey,
                   mouth_nose=float(D), mw=float(mw), tex=tex, size=size, anchor0=anchor0,
                   cavity=cavity.astype(np.float32), tongue_basis=tongue_basis,
                   tongue_roll=float(plan.tongue_roll_scale), lip_pairs=lip_pairs,
                   lower_lip=lo_lip, gap0=gap0,
                   gum=gum_rgb.astype(np.float32), tip_up=float(tip_up), low_off=float(low_off),
                   mns=float(plan.fapu["MNS"]),
                   bounce=(np.asarray(skin, np.float32) / max(float(_lum(skin)), 1.0)
                           if skin is not None else np.ones(3, np.float32)))

    # ------------------------------------------------------------------ per frame
    def render(self, box: tuple[int, int, int, int], v: np.ndarray, faps: np.ndarray,
               skull: np.ndarray, rim: np.ndarray | None = None,
               depth: np.ndarray | None = None, alpha: np.ndarray | None = None,
               grain: np.ndarray | None = None) -> np.ndarray:
        """Colours (h, w, 3) float32 of the mouth interior over ``box`` of the output.

        ``rim`` (h, w, 3): colour of the nearest lip pixel, ``depth`` (h, w): distance (px) to
        the lips (``layers._mouth_rim``); with them the cavity is shaded from the lips' inner
        surface (their colour, darkened) into a dark back over a depth of ~0.1 D. ``alpha``
        (h, w): the opening's coverage; where it is a thin gap the interior stays in shadow.
        ``grain`` (h, w): the photo's grain over the box (:func:`grain.grain_over`), added
        where the interior is drawn (not where it is the photo's own, which carries its grain).
        """
        x0, y0, x1, y1 = box
        S = np.asarray(skull, np.float64)
        L = S[:, :2]
        # the frame axes turned with the skull (E's columns), normalised (in Python floats: a
        # few numbers, numpy's calls cost more than their arithmetic)
        (l00, l01, _), (l10, l11, _) = S.tolist()
        sc = math.sqrt(abs(l00 * l11 - l01 * l10)) or 1.0
        (n00, n01), (n10, n11) = self._exy.tolist()
        c0x, c0y, c1x, c1y = (l00 * n00 + l01 * n10, l10 * n00 + l11 * n10,
                              l00 * n01 + l01 * n11, l10 * n01 + l11 * n11)
        r0, r1 = math.hypot(c0x, c0y), math.hypot(c1x, c1y)
        (e00, e01), (e10, e11) = (c0x / r0, c1x / r1), (c0y / r0, c1y / r1)
        E = np.array([[e00, e01], [e10, e11]])
        ex, ey = E[:, 0], E[:, 1]
        O = v[self.i93].astype(np.float64)
        # the frame coordinates of the box's pixel (i, j): affine in i and j (frame x: per i,
        # per j, at (0, 0); frame y likewise), a row's and a column's terms broadcast (no
        # per-size pixel grid: the box's size changes as the mouth moves); the textures below
        # are sampled at affine functions of them too
        ox_, oy_ = O.tolist()
        ax = (e00, e10, (x0 - ox_) * e00 + (y0 - oy_) * e10)
        ay = (e01, e11, (x0 - ox_) * e01 + (y0 - oy_) * e11)
        cols = np.arange(x1 - x0, dtype=np.float64)
        rows = np.arange(y1 - y0, dtype=np.float64)[:, None]
        Qx = (ax[0] * cols + ax[1] * rows) + ax[2]
        Qy = (ay[0] * cols + ay[1] * rows) + ay[2]

        # the points the layers follow, in that frame (one gather): 2.1, 2.3, the inner
        # upper lip, the opening's loop
        vf = v.take(self._frame_idx, 0)  # (take: cheaper rows)
        fp = (vf.astype(np.float64) - O) @ E
        q21, q23 = fp[0], fp[1]
        n_lip = len(self.upper_lip)
        D = self.mouth_nose * sc
        # shading of the synthetic layers: shadow under the upper lip, darker corners
        lip = fp[2:2 + n_lip]
        lip = lip.take(lip[:, 0].argsort(), 0)
        y_up = interp(Qx, lip[:, 0], lip[:, 1])
        low = fp[2 + n_lip:2 + 2 * n_lip]
        low = low.take(low[:, 0].argsort(), 0)
        # light on the teeth through the opening: the local gap between the lips (per column)
        # against how deep behind them the teeth lie
        y_lo = interp(Qx, low[:, 0], low[:, 1])
        gap = np.maximum(y_lo - y_up, 0.0)
        g2 = gap * gap
        zt = (APERTURE_TEETH * D) ** 2
        a_t = (gap / np.sqrt(g2 + zt + 1e-9)).astype(np.float32)
        zg = TONGUE_RECEDE * D
        a_g = (zg / np.sqrt(g2 + zg * zg)).astype(np.float32)
        hole = fp[2 + 2 * n_lip:]
        hx, hy = hole[:, 0].tolist(), hole[:, 1].tolist()  # (a few values: Python's min/max)
        lo_h, lo_v, hi_h, hi_v = min(hx), min(hy), max(hx), max(hy)
        cxm = 0.5 * (lo_h + hi_h)
        hw = max(0.5 * float(hi_h - lo_h), 1.0)
        hh = max(0.5 * float(hi_v - lo_v), 1.0)
        cym = 0.5 * (lo_v + hi_v)
        side = np.minimum(np.abs(Qx - cxm) / hw, 1.0)  # (clamped above only: >= 0)
        side2 = side * side
        # (exp(-max(Qy - y_up, 0) / ...): the same values, one negation fewer)
        lip_sh = np.exp(np.minimum(y_up - Qy, 0.0) / (0.05 * D + 0.5))
        corner = 1.0 - 0.35 * side2  # the darker corners
        shade = (1.0 - 0.3 * lip_sh).astype(np.float32)
        # the dental arch turns away from the light towards the corners (and into the cheeks'
        # shadow): lit like the normal of an arch of half-width ARCH_W MW / 2 facing the camera
        arch = _arch_light(Qx, ARCH_W * self.mw * sc, ARCH_AMBIENT)
        # (per-pixel weights are spread over the 3 channels with cv2.merge / cv2.transform:
        # numpy's broadcasting of (h, w, 1) over 3 channels is several times slower here)
        cav_rgb = self.cavity.reshape(3, 1)
        if rim is None or depth is None:
            rr = np.sqrt(((Qx - cxm) / hw) ** 2 + ((Qy - cym) / hh) ** 2)
            # the cavity: dark in the middle, reddish towards the lips (lit inner surfaces)
            cav = (0.3 + 0.7 * np.clip(rr, 0.0, 1.0) ** 1.5).astype(np.float32)
            out = np.asarray(cv2.transform(cav, cav_rgb), np.float32)
        else:
            # the lips' inner surface turns away from the light (their colour, darkened), the
            # cavity behind darkens with depth and towards the corners (cheeks' shadow)
            # (with the drawn layers' falloff below: both at once, the same values as each)
            back = (0.5 * (1.0 - 0.4 * side2)).astype(np.float32)
            t_soft = min(max((self.soft - 1.0) / SOFT_FULL, 0.0), 1.0)
            if t_soft > 0.0:
                # a large face: the back of the mouth darkens further with depth (the
                # cavity's light falls from the lips' inner surface into the throat)
                g, g1, g2 = np.exp(-np.asarray(depth, np.float32) / np.array(
                    [0.08 * D + 0.5 + RIM_SOFT * self.soft, 0.05 * D + 0.5, BACK_LEN * D],
                    np.float32)[:, None, None])
                k = BACK_DEEP * t_soft
                g2 *= np.float32(k)
                g2 += np.float32(1.0 - k)
                back *= g2
            else:
                # (-d / l as d / -l, each over its float32 length: no broadcast of stacked
                # lengths, no negation)
                depth32 = np.asarray(depth, np.float32)
                g = np.exp(np.divide(depth32, np.float32(-(0.08 * D + 0.5))))
                g1 = np.exp(np.divide(depth32, np.float32(-(0.05 * D + 0.5))))
            # (spread, then times the cavity's colour as a per-channel scalar: the same float32
            # products as cv2.transform's 3 x 1 matrix, at a fraction of its cost)
            deep = np.asarray(cv2.multiply(spread3(back), self._cavity_scalar), np.float32)
            # (the gain as OpenCV's per-channel scalar: numpy's broadcast of a (3,) row over
            # (h, w, 3) runs an inner loop of 3 a pixel, several times slower on larger boxes;
            # the same float32 products)
            out = np.asarray(cv2.multiply(np.asarray(rim, np.float32), self._rim_scalar),
                             np.float32) - deep
            out *= spread3(g)
            out += deep
            # drawn teeth and tongue in the lips' shadow: a thin band of them along a lip
            # reads as a dark edge, not as a bright sliver
            shade *= 1.0 - 0.3 * g1
        shade_g = (a_g * shade) * corner.astype(np.float32)
        shade_g = spread3(shade_g)
        shade *= a_t
        shade_up = None
        if not self.photo_upper:
            s_up = shade * _arch_light(Qx, ARCH_W_UP * self.mw * sc, ARCH_AMBIENT_UP)
            if self.soft > 1.0:
                # a large face: where the lip leaves only a sliver of the upper teeth (their
                # edge less than SLIVER_SOFT ramps below it) the sliver stays in the lip's
                # shadow: lit, its light line under the lip read as a drawn outline
                u = (self.tip_up * sc - y_up) * (1.0 / (SLIVER_SOFT * self.soft))
                u = np.clip(u, 0.0, 1.0)
                s_up *= (u * u * (3.0 - 2.0 * u)).astype(np.float32)
            shade_up = spread3(s_up)
        shade *= arch
        shade = spread3(shade)
        cav = out
        # lower teeth and tongue (jaw), upper teeth (skull)
        y_lb = 0.25 * q21[1] + 0.75 * q23[1]
        (wl, hl), (wu, hu), (wt, ht) = self._sizes
        wl, hl, wu, hu, wt, ht = wl * sc, hl * sc, wu * sc, hu * sc, wt * sc, ht * sc
        # eq. 8's anchor moves the lower teeth with the jaw; at rest their tips sit just above
        # the lip line behind the upper teeth (eq. 8's own rest height varies with the chin:
        # 0.2 D above the lip line on JAFFE faces, below the lower lip on the sample)
        top_l = y_lb + self.low_off * sc
        # the tongue's dorsum rises behind the lower teeth: seen over them in an open mouth
        top_t = top_l - TONGUE_RISE * D
        if self.soft > 1.0:
            # a large face: the tongue lit at its front only (just behind the lower lip), its
            # back further up the opening fading into the cavity's dark (lit evenly, its top
            # edge read as a cut-out)
            u = np.clip((y_lo - Qy) * (1.0 / (TONGUE_BACK * D)), 0.0, 1.0)
            u = 1.0 - TONGUE_BACK_DARK * (u * u * (3.0 - 2.0 * u))
            shade_g *= spread3(u.astype(np.float32))
        dlt = self._tongue_shift(faps, ex, ey)
        tongue = ("tongue", q21[0] - 0.5 * wt, top_t, wt, ht)
        # (a texture placed in the frame is sampled at an affine function of the box's pixel
        # (its frame coordinates ``ax``, ``ay`` are): one cv2.warpAffine each, no sampling
        # maps. A bent tongue and the gum row (clamped to the texture's top row) are not
        # affine: sampled through maps)
        dsize = (x1 - x0, y1 - y0)
        if dlt is not None:
            tx, ty = self._tongue_field(Qx, Qy, dlt, *tongue[1:3], wt, ht)
            out = self._over(out, "tongue", self._layer_map(tx, ty, tongue), shade_g)
        else:
            out = self._over_at(out, "tongue", self._place(tongue, ax, ay), dsize, shade_g)
        if not self.photo_lower:
            out = self._over_at(out, "lower_teeth", self._place(
                ("lower_teeth", q21[0] - 0.5 * wl, top_l, wl, hl), ax, ay), dsize, shade)
        # the photo's own interior: jaw part, then upper teeth, then the skull part
        Si = cv2.invertAffineTransform(S)
        # where each pixel samples the photo's own interior (its patch's pixels): skull part
        if self.own_off is None or self.ext is None:
            raise RuntimeError("MouthPlan.render needs the photo's interior (attach_own)")
        # (affine in the box's pixel: the skull's inverse from the box's corner, less the
        # patch's offset)
        (s00, s01, s02), (s10, s11, s12) = Si.tolist()
        offx, offy = self.own_off.tolist()
        M_own = np.array([[s00, s01, s00 * x0 + s01 * y0 + s02 - offx],
                          [s10, s11, s10 * x0 + s11 * y0 + s12 - offy]])
        if not self.photo_upper:  # gum row continued upwards (a raised lip shows gum)
            gum_maps = self._layer_map(Qx, Qy, ("upper_teeth", -0.5 * wu,
                                                self.tip_up * sc - hu, wu, hu))
            out = self._over(out, "upper_teeth", gum_maps, shade_up, gum=True)
        # the two photo parts share each pixel (skull part in front where they overlap); a
        # closed mouth's lip line fades out over the first two pixels the lips part
        # (the inner lips' pairs: rows of the frame's gather above; their gaps along ey in
        # Python floats, seven pairs)
        lp_u, lp_d = self._lip_rows
        ey0, ey1 = ey.tolist()
        opened = max(dx * ey0 + dy * ey1 - g0 for (dx, dy), g0 in zip(
            (vf[lp_d] - vf[lp_u]).tolist(), self._gap0_list, strict=True))
        fade = 1.0 - _smoothstep1(opened / 2.0)
        a_up, p_up = self._own_at(M_own, dsize, 0, fade)
        a_lo = p_lo = None
        if self._own_has[1]:  # the jaw part, moved with the jaw anchor (eq. 8)
            anchor = O + q21[0] * ex + y_lb * ey
            tj = anchor - (L @ self.anchor0 + S[:, 2])
            M_jaw = M_own.copy()
            M_jaw[:, 2] -= Si[:, :2] @ tj
            a_lo, p_lo = self._own_at(M_jaw, dsize, 1, fade)
        if a_up is not None and self.photo_upper:
            # the continued teeth: a light shadow right under the lip (the photo's own top
            # row, which they repeat, already carries the photo's lip shadow) and the drawn
            # layers' darker corners
            e = cv2.warpAffine(self.ext, M_own, dsize, None, _AFFINE)  # (zeros outside)
            k = (1.0 - EXT_LIP_SHADOW * lip_sh) * corner
            m = np.asarray(1.0 - e * (1.0 - k.astype(np.float32)), np.float32)  # (no copy)
            p_up *= spread3(m)  # (p_up: _own_at's own array)
        if grain is not None:  # the drawn share (1 - the photo's parts')
            drawn = np.ones(grain.shape, np.float32) if a_up is None else 1.0 - a_up
        if a_up is not None:
            p_up -= out  # out (1 - a) + p a
            p_up *= spread3(a_up)
            p_up += out  # (the sum out + p_up, in place)
            out = p_up
        if a_lo is not None:
            if a_up is not None:  # (else no skull part: the jaw part's weight is a_lo itself)
                rest = 1.0 - a_up
                a_lo = np.minimum(a_lo, rest)
                a_lo /= np.maximum(rest, 1e-6)
            out = out + (p_lo - out) * spread3(a_lo)
            if grain is not None:
                drawn *= 1.0 - a_lo
        if alpha is not None:
            light = self._aperture_light(faps, hw, hh, sc)
            out = _thin_gap(out, cav, alpha, D, self._shadow_gain(light) if light < 1.0 else None)
        if grain is not None:
            out += spread3(np.asarray(drawn * grain, np.float32))
        return out

    def _shadow_gain(self, light: float) -> np.ndarray:
        """(3,) per-channel gain of what lies behind the lips in their shadow: ``light`` times
        the skin's hue to the power ``1 - light`` (the light that still gets in has bounced
        off lips and cheeks: shadowed teeth turn a warm grey, not a cold blue-grey)."""
        b = self.bounce if self.bounce is not None else np.ones(3, np.float32)
        return (light * np.power(b, 1.0 - light)).astype(np.float32)

    def _aperture_light(self, faps: np.ndarray, hw: float, hh: float, sc: float) -> float:
        """How much light reaches the teeth and tongue through lips pushed forward.

        Protruded lips (FAPs 16/17, e.g. the rounded u/o) put the opening a distance ``z`` in
        front of the teeth: through an aperture of half-size ``a`` (the opening's smaller
        half-axis) the light falls off as ``a / sqrt(a^2 + z^2)``. A small rounded opening
        then shows dim teeth in a dark hole, not a bright block of them; lips that are not
        pushed forward (smiles, open jaws) change nothing.
        """
        z = max(float(faps[15]), float(faps[16]), 0.0) * self.mns * sc
        if z <= 0.0:
            return 1.0
        a = max(min(hw, hh), 0.5)
        return a / math.sqrt(a * a + z * z)

    @cached_property
    def _sizes(self) -> tuple[tuple[float, float], ...]:
        """(width, height) of the lower teeth, upper teeth and tongue at the neutral scale."""
        return tuple((float(w), float(h)) for w, h in
                     (self.size[k] for k in ("lower_teeth", "upper_teeth", "tongue")))

    @cached_property
    def _rim_gain(self) -> np.ndarray:
        """(3,) float32: the lips' inner surface, turned into the mouth, against their colour
        beside the opening: RIM_LIGHT of it, in the hue of light bounced off the mouth's
        walls :data:`INNER_BOUNCES` times (1 on a grey photo)."""
        b = np.ones(3) if self.bounce is None else np.asarray(self.bounce, np.float64)
        return (RIM_LIGHT * _hue_power(b, INNER_BOUNCES)).astype(np.float32)

    @cached_property
    def _rim_scalar(self) -> np.ndarray:
        """:attr:`_rim_gain` as OpenCV's per-channel scalar (see :attr:`_cavity_scalar`; its
        float32 values, exact in float64)."""
        return self._rim_gain.astype(np.float64)

    @cached_property
    def _cavity_scalar(self) -> np.ndarray:
        """:attr:`cavity` as OpenCV's per-channel scalar (a (3,) float64 array: 3 x 1, one
        value a channel of a 3-channel image)."""
        return self.cavity.astype(np.float64)

    @cached_property
    def _exy(self) -> np.ndarray:
        """(2, 2) the neutral frame axes ex, ey as columns."""
        return np.stack([self.ex, self.ey], 1).astype(np.float64)

    @cached_property
    def _lip_idx(self) -> tuple[np.ndarray, np.ndarray]:
        """The inner upper and lower lip vertices of :attr:`lip_pairs` (contiguous)."""
        return (np.ascontiguousarray(self.lip_pairs[:, 0]),
                np.ascontiguousarray(self.lip_pairs[:, 1]))

    @cached_property
    def _lip_rows(self) -> tuple[slice | np.ndarray, slice | np.ndarray]:
        """:attr:`_lip_idx` as rows of :attr:`_frame_idx` (slices where they are runs of it:
        the lips' vertices between their corners, in order)."""
        idx = self._frame_idx.tolist()
        rows: list[slice | np.ndarray] = []
        for want in self._lip_idx:
            at = [idx.index(int(i)) for i in want]
            run = all(b == a + 1 for a, b in itertools.pairwise(at))
            rows.append(slice(at[0], at[-1] + 1) if at and run else np.array(at, np.intp))
        return rows[0], rows[1]

    @cached_property
    def _gap0_list(self) -> list[float]:
        """:attr:`gap0` as Python floats."""
        return [float(g) for g in np.asarray(self.gap0, np.float64)]

    @cached_property
    def _frame_idx(self) -> np.ndarray:
        """Vertices :meth:`render` reads in the layer frame: 2.1, 2.3, upper lip, opening."""
        return np.concatenate([[self.i21, self.i23], self.upper_lip, self.lower_lip,
                               self.hole]).astype(np.intp)

    def _layer_map(self, qx: np.ndarray, qy: np.ndarray,
                   place: tuple[str, float, float, float, float]
                   ) -> tuple[np.ndarray, np.ndarray]:
        """Where pixels at frame coordinates ``qx``, ``qy`` (h, w) sample the texture placed at
        ``place`` (name, left, top, width, height in the layer frame): (mx, my) (h, w)
        float32, for a placement that is not affine in the pixels (a bent tongue, the gum row
        clamped to the texture's top); an affine one is :meth:`_place`."""
        _, left, top, _, _ = place
        kx, ky, c = self._tex_scale(place)
        return (((qx - left) * kx + c).astype(np.float32),
                ((qy - top) * ky + c).astype(np.float32))

    def _tex_scale(self, place: tuple[str, float, float, float, float]
                   ) -> tuple[float, float, float]:
        """Texture ``place``'s pixels per frame unit across and down, inside its blank margin
        (the textures' own pixels), and the margin's offset: frame x maps to texture column
        ``(x - left) kx + c``."""
        name, _, _, ww, hh = place
        p = self.tex_pad
        th, tw = self.tex[name].shape[:2]
        return (tw - 2 * p) / ww, (th - 2 * p) / hh, p - 0.5

    def _over(self, out, name, maps, shade, gum=False):
        """``out`` under texture ``name`` sampled at ``maps`` (:meth:`_layer_map`)."""
        t = self.tex[name]
        mx, my = maps
        if gum:  # (the texture's top row, inside its blank margin)
            my = np.maximum(my, np.float32(self.tex_pad))
        # (zeros outside: OpenCV's default border)
        return _under(out, cv2.remap(t, mx, my, cv2.INTER_LINEAR), shade)

    def _place(self, place: tuple[str, float, float, float, float],
               ax: tuple[float, float, float], ay: tuple[float, float, float]) -> np.ndarray:
        """(2, 3) float64: from a box's pixel (i, j) to the pixel of texture ``place`` (name,
        left, top, width, height in the layer frame) it samples (as :meth:`_layer_map`: the
        texture's pixels per frame unit inside its blank margin). ``ax``, ``ay``: the frame
        x and y of the box's pixels, per i, per j and at (0, 0)."""
        _, left, top, _, _ = place
        kx, ky, c = self._tex_scale(place)
        return np.array([[ax[0] * kx, ax[1] * kx, (ax[2] - left) * kx + c],
                         [ay[0] * ky, ay[1] * ky, (ay[2] - top) * ky + c]])

    def _over_at(self, out, name, M, dsize, shade):
        """:meth:`_over` of texture ``name`` sampled at the affine ``M`` (:meth:`_place`)
        over a box of ``dsize`` (w, h)."""
        # (zeros outside)
        return _under(out, cv2.warpAffine(self.tex[name], M, dsize, None, _AFFINE), shade)

    def _own_at(self, M, dsize, k, fade):
        """Coverage (h, w) and colours (h, w, 3) of the photo's skull (k=0) or jaw (k=1) part
        at the affine ``M`` from a box's pixels to the own interior's patch, over a box of
        ``dsize`` (w, h); (None, None) where the part covers none of them. ``fade``: how far
        a closed mouth's lip line is kept (1: all of it, 0: none; :attr:`_own_span`)."""
        if not self._own_has[k]:
            return None, None
        src = self._own_a[k] if fade >= 1.0 else self._own_keep[k] if fade <= 0.0 else \
            self._own_keep[k] + fade * self._own_span[k]
        a = cv2.warpAffine(src, M, dsize, None, _AFFINE)  # (zeros outside)
        if not np.count_nonzero(a):
            return None, None
        # (the colours' border replicated)
        return a, warp_rgb(self._own_c3[k], self._own_c[k], M, dsize)

    def _tongue_shift(self, faps: np.ndarray, ex: np.ndarray, ey: np.ndarray):
        """Displacements (4, 2) in the layer frame of the tongue points 6.1-6.4, or None."""
        if not np.count_nonzero(faps[42:47]):  # FAPs 43-47 (before any conversion)
            return None
        f = np.asarray(faps, np.float64)
        d = np.tensordot(f[42:46], self.tongue_basis, 1)  # (4, 2) image px
        lift = self.tongue_roll * np.sin(f[46] * 1e-5 * 100.0)
        d[2:] -= lift * self.ey
        # the tip and the sides ride on the body (6.2): raise_tongue lifts the whole dorsum
        d[[0, 2, 3]] += d[1]
        return np.stack([d @ ex, d @ ey], -1)

    @staticmethod
    def _tongue_field(Qx, Qy, dlt, left, top, ww, hh):
        """Sampling positions for the tongue bent by the displacements of its points."""
        # 6.1 tip, 6.2 body, 6.3 image-right side, 6.4 image-left side; root fixed
        uv = np.array([[0.5, 0.06], [0.5, 0.45], [0.8, 0.3], [0.2, 0.3], [0.5, 1.3],
                       [0.0, 1.1], [1.0, 1.1]])
        pts = np.stack([left + uv[:, 0] * ww, top + uv[:, 1] * hh], 1)
        dd = np.vstack([dlt, np.zeros((3, 2))])
        s2 = 2.0 * (0.28 * ww) ** 2
        num_x = np.zeros_like(Qx)
        num_y = np.zeros_like(Qx)
        den = np.zeros_like(Qx)
        for (px, py), (dx, dy) in zip(pts, dd, strict=True):
            phi = np.exp(-((Qx - px) ** 2 + (Qy - py) ** 2) / s2)
            num_x += phi * dx
            num_y += phi * dy
            den += phi
        den = np.maximum(den, 1e-12)
        return Qx - num_x / den, Qy - num_y / den


def _under(out: np.ndarray, s: np.ndarray, shade: np.ndarray) -> np.ndarray:
    """A sampled RGBA texture ``s`` (h, w, 4) float32, its colours times ``shade`` (h, w, 3),
    over ``out`` (h, w, 3): :meth:`MouthPlan._over`'s and ``_over_at``'s composite."""
    # (the colour channels as one contiguous array: numpy is several times slower on a
    # channel view)
    res = cv2.cvtColor(s, cv2.COLOR_RGBA2RGB)
    res *= shade
    # (the alpha channel extracted contiguous, the under-layer's weight in place)
    a3 = spread3(np.subtract(1.0, cv2.extractChannel(s, 3), dtype=np.float32))
    a3 *= out
    res += a3
    return res


#: cv2.warpAffine's flags for sampling a texture at an affine function of the box's pixels
_AFFINE = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP


def _thin_gap(out: np.ndarray, cav: np.ndarray, alpha: np.ndarray, D: float,
              gain: np.ndarray | None = None) -> np.ndarray:
    """Teeth and tongue fade into the lips' shadow where the opening is a thin gap.

    Light barely enters a slit of a pixel or two: whatever lies behind it (the photo's teeth,
    the drawn ones) reads as a dark line, not as a run of bright teeth. The local height of
    the opening is its coverage summed over a short vertical window (3 columns averaged):
    up to ``lo`` = max(1 px, 0.05 D) nothing but the shadow shows, from ``lo`` + max(1.5
    px, 0.08 D) everything. ``gain`` (3,), when given, darkens what shows (lips pushed
    forward: :meth:`MouthPlan._aperture_light`, :meth:`MouthPlan._shadow_gain`).
    """
    lo, ramp = max(1.0, 0.05 * D), max(1.5, 0.08 * D)
    k = 2 * math.ceil(lo + ramp) + 3
    h: np.ndarray = cv2.boxFilter(np.asarray(alpha, np.float32), -1, (3, k), None, (-1, -1),
                                  False, cv2.BORDER_CONSTANT)  # (not normalised)
    # ((h / 3 - lo) / ramp as one scale and offset, float32)
    h = cv2.addWeighted(h, 1.0 / (3.0 * ramp), h, 0.0, -lo / ramp)
    vis = clip(h, 0.0, 1.0, out=h)  # (smooth01's values, float32: its clamp one ufunc)
    vis = vis * vis * (3.0 - 2.0 * vis)
    if gain is not None:  # in shadow: darker and warmer (not greyed towards the cavity)
        # (as OpenCV's per-channel scalar: the same float32 products as numpy's broadcast of
        # the (3,) float32 gain, without its inner loop of 3 a pixel)
        out = np.asarray(cv2.multiply(out, np.asarray(gain, np.float32).astype(np.float64)),
                         np.float32)
    res = out - cav
    res *= spread3(vis)
    res += cav
    return res


def _arch_light(qx: np.ndarray, width: float, ambient: float) -> np.ndarray:
    """The light (float32) on a dental arch of ``width`` (px, both sides) facing the camera,
    at frame x ``qx`` from its middle: ``ambient`` where its sides face sideways."""
    u = qx * (2.0 / width)
    return (ambient + (1.0 - ambient) * np.sqrt(np.maximum(1.0 - u * u, 0.0))).astype(np.float32)


def _smoothstep1(t: float) -> np.float64:
    """:func:`~editor.engine.fitting.smooth01` of one number in Python arithmetic (the same
    value, as a float64)."""
    t = min(max(t, 0.0), 1.0)
    return np.float64(t * t * (3.0 - 2.0 * t))


def _jaw_anchor(v: np.ndarray, i21: int, i23: int, ex: np.ndarray, ey: np.ndarray) -> np.ndarray:
    """Eq. 8 point: x(2.1), 0.25 y(2.1) + 0.75 y(2.3), in the frame given by ex, ey."""
    p21, p23 = v[i21], v[i23]
    x = p21 @ ex
    y = 0.25 * (p21 @ ey) + 0.75 * (p23 @ ey)
    return x * ex + y * ey
