"""The photo's grain kept where the warp resamples it (issue 21). No Qt.

Resampling a photo at a fractional position averages neighbouring pixels: bilinear sampling
halfway between two pixels keeps half of the pixel noise's variance along each axis, and skin
that the deformation stretches spreads its grain over more pixels. So the skin that moves
comes out smoother than the photo around it, a patch that looks pasted on (the blind raters'
word for joy at 150 %). JAFFE's ten women, high-pass level of the skin beside the mouth and
over the upper lip against each one's neutral photo: her real expression photos 1.01-1.10
(median per expression); the presets at 100 % rendered on her neutral photo 0.58-0.68
(bilinear), 0.78-0.89 (bicubic).

* **Once per face** (:func:`grain_plan`): the photo's grain level ``g`` (std of the
  luminance high-pass over the face box, its edges left out) and how fine it is (the
  high-pass's correlation between neighbouring pixels); a static noise tile with that
  correlation, high-passed like the measure (no blotches) and scaled to std 1; and, per
  interpolation, the share ``r(f)`` of the grain's variance a resampling at fractional offset
  ``f`` along one axis keeps (measured on the tile's noise itself, at the 1/32 px steps of
  OpenCV's fixed-point maps; the tiles and tables are the same for every face, made once per
  process). A face larger than 3 x 3 patches of :data:`_PATCH` px is measured on such
  patches: the plan costs about 1 ms at the first render (a 24 MP photo's face measured
  whole: 150 ms).
* **Per frame** (:func:`apply_grain`): over the warp's map box, the share kept
  ``k = r(fx) r(fy) min(1, det J)`` (``fx``, ``fy`` the map's fractional parts, ``J`` its
  Jacobian: the photo's area per output pixel, below 1 where the skin is stretched), and the
  tile added to the three channels at ``g sqrt(1 - k)``: the lost variance back. ``k`` is
  computed on a grid :data:`_NODE` px apart and interpolated (``r`` is periodic and
  continuous in the map's value, so it interpolates across integer wraps), and added only to
  the pixels the warp resampled: 0.13 ms at 431 x 591 and 0.53 ms at 1920 x 1080 on the
  bench's faces with a film's grain (3-7 % of their render). Where the map is the identity
  nothing changes; an untouched face has no map at all (the photo, exactly).

The tile is fixed (seeded) and tied to the frame, as a camera's grain is: the same FAPs give
the same pixels, and a video's moving skin shows no flicker. A photo without grain (a clean
or upscaled one: level under :data:`MIN_LEVEL`) has no plan.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from .fitting import clip, median_binned
from .perface import per_face
from .warp import WarpResult

if TYPE_CHECKING:
    from .face import Face

#: below this grain level (grey levels, std of the high-pass) the photo is left as warped: the
#: grain put back would be a grey level or less (the sample photo's is 1.8-2.0, JAFFE's 4-5;
#: the sample upscaled 2 x keeps 1.1, blurred by 2.5 px 0.55: rounding and its edges)
MIN_LEVEL = 1.5
#: Gaussian sigma (px) of the high-pass that defines "grain" (as the measure in the tests)
HP_SIGMA = 1.0
#: side of the noise tile (px); it repeats
TILE = 128
#: blurs (sigma, px) the tile's noise may take, finest first; the one whose high-pass
#: neighbour correlation is nearest the photo's is used
_SIGMAS = (0.0, 0.35, 0.5, 0.65, 0.8, 1.0, 1.25)
#: OpenCV's fixed-point map resolution (INTER_TAB_SIZE): fractional offsets in 1/32 px
_STEPS = 32
#: a map value this close to its pixel's own place resamples nothing (half a map step)
_TAB = np.float32(0.5 / _STEPS)
#: a face box larger than 3 x 3 patches of this side (px) has its grain measured on such
#: patches spread over it
_PATCH = 128
#: the amplitude below which a pixel is left alone (grey levels)
_MIN_AMP = 0.05
#: spacing (px) of the grid the kept share is computed on, then interpolated
_NODE = 4


def _hp(a: np.ndarray, wrap: bool = False) -> np.ndarray:
    """High-pass ``a - GaussianBlur(a, HP_SIGMA)`` (float32), wrapped for a tile."""
    border = cv2.BORDER_WRAP if wrap else cv2.BORDER_REFLECT_101
    if wrap:  # (OpenCV's Gaussian has no wrap border: pad, blur, cut)
        p = int(math.ceil(4 * HP_SIGMA))
        big = cv2.copyMakeBorder(a, p, p, p, p, border)
        return a - cv2.GaussianBlur(big, (0, 0), HP_SIGMA)[p:-p, p:-p]
    return a - cv2.GaussianBlur(a, (0, 0), HP_SIGMA, borderType=border)


def _corr1(h: np.ndarray) -> float:
    """Correlation of ``h`` with itself one pixel to the right (and one down), averaged."""
    h = h - h.mean()
    v = float((h * h).mean())
    if v <= 0:
        return 0.0
    cx = float((h[:, :-1] * h[:, 1:]).mean())
    cy = float((h[:-1] * h[1:]).mean())
    return 0.5 * (cx + cy) / v


def _blurred_tile(noise: np.ndarray, sigma: float) -> np.ndarray:
    if sigma <= 0:
        return noise
    p = min(int(math.ceil(4 * sigma)), TILE)
    big = cv2.copyMakeBorder(noise, p, p, p, p, cv2.BORDER_WRAP)
    return np.ascontiguousarray(cv2.GaussianBlur(big, (0, 0), sigma)[p:-p, p:-p])


@dataclass(frozen=True, eq=False)
class GrainPlan:
    """A face's grain (see the module docstring)."""

    level: float  # g: std of the photo's luminance high-pass over the face (grey levels)
    sigma: float  # blur of the tile's noise (px), matching the photo's fineness

    @property
    def tile(self) -> np.ndarray:
        """(TILE, TILE) float32 high-passed noise of this fineness, std 1 (shared)."""
        return _tiles(self.sigma)[1]

    def keeps(self, interpolation: int) -> np.ndarray:
        """``r`` (float32, ``_STEPS + 1`` values at f = 0, 1/32, ..., 1): the share of the
        grain's high-pass variance a resampling with ``interpolation`` at fractional offset
        ``f`` along one axis keeps (r(0) = r(1) = 1)."""
        return _kept_table(self.sigma, interpolation)


@functools.cache
def _tiles(sigma: float) -> tuple[np.ndarray, np.ndarray, float]:
    """The fixed noise blurred by ``sigma`` (the grain before the high-pass), its high-pass
    scaled to std 1 (the tile added) and that high-pass's neighbour correlation: the same for
    every face (one of :data:`_SIGMAS`), made once per process."""
    noise = np.random.default_rng(20261129).standard_normal((TILE, TILE)).astype(np.float32)
    base = _blurred_tile(noise, sigma)
    tile = _hp(base, wrap=True)
    corr = _corr1(tile)
    tile *= np.float32(1.0 / max(float(tile.std()), 1e-6))
    for a in (base, tile):
        a.setflags(write=False)
    return base, np.ascontiguousarray(tile, np.float32), corr


@functools.cache
def _kept_table(sigma: float, interpolation: int) -> np.ndarray:
    """Resample the (wrapped) noise of fineness ``sigma`` by f = k / 32 px along x and compare
    the variance of the results' high-pass with the noise's own (once per process)."""
    base = _tiles(sigma)[0]
    p = 4
    big = cv2.copyMakeBorder(base, 0, 0, p, p, cv2.BORDER_WRAP)
    h, w = base.shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    v0 = float(_hp(base, wrap=True).var())
    out = np.ones(_STEPS + 1, np.float32)
    for k in range(1, _STEPS):
        m1, m2 = cv2.convertMaps(xx + np.float32(p + k / _STEPS), yy, cv2.CV_16SC2)
        shifted = cv2.remap(big, m1, m2, interpolation, borderMode=cv2.BORDER_WRAP)
        out[k] = min(float(_hp(shifted, wrap=True).var()) / max(v0, 1e-12), 1.0)
    out.setflags(write=False)
    return out


@per_face
def grain_plan(face: Face) -> GrainPlan | None:
    """The face's grain (cached for the face's lifetime); None on a photo without grain."""
    return _build(face)


def _build(face: Face) -> GrainPlan | None:
    img = face.image
    H, W = img.shape[:2]
    v = np.asarray(face.vertices, np.float64)
    x0, y0 = (max(int(math.floor(q)), 0) for q in v.min(0))
    x1, y1 = int(min(math.ceil(v[:, 0].max()) + 1, W)), int(min(math.ceil(v[:, 1].max()) + 1, H))
    if x1 - x0 < 8 or y1 - y0 < 8:
        return None
    # the face box, or on a face larger than 3 x 3 patches of _PATCH px those patches spread
    # over it (a 24 MP photo's face has millions of pixels: its medians cost ~150 ms of the
    # first render, the high-pass of a 1080p face's box ~3 ms)
    P = _PATCH // 2
    if x1 - x0 <= 3 * _PATCH and y1 - y0 <= 3 * _PATCH:
        boxes = [(x0, y0, x1, y1)]
    else:
        boxes = []
        for fy in (0.25, 0.5, 0.75):
            for fx in (0.25, 0.5, 0.75):
                cy, cx = int(y0 + fy * (y1 - y0)), int(x0 + fx * (x1 - x0))
                boxes.append((max(cx - P, 0), max(cy - P, 0), cx + P, cy + P))
    hs = [_hp(cv2.cvtColor(np.ascontiguousarray(img[b0:b1, a0:a1]),
                           cv2.COLOR_RGB2GRAY).astype(np.float32))
          for a0, b0, a1, b1 in boxes]
    win = hs[len(hs) // 2]  # (the centre patch, or the box)
    # (every other pixel: on a large face at most 9 x 64 x 64 values)
    sub = np.concatenate([x[::2, ::2].ravel() for x in hs])
    # the pixels where the high-pass is grain rather than an edge (lids, lips, brows: a
    # minority of the face's pixels, beyond 3 robust standard deviations) give its level and
    # its fineness (at the face's centre)
    # (median_binned: np.median's values, a zero's sign aside, which the absolute values
    # drop)
    mad = 1.4826 * median_binned(np.abs(sub - np.float32(median_binned(sub))))
    calm = np.abs(sub) < 3.0 * mad
    level = float(sub[calm].std()) if calm.any() else 0.0
    if level < MIN_LEVEL:
        return None
    want = _corr1(np.where(np.abs(win) < 3.0 * mad, win, 0.0).astype(np.float32))
    sigma = min(_SIGMAS, key=lambda sg: abs(_tiles(sg)[2] - want))
    return GrainPlan(level, sigma)


def apply_grain(face: Face, res: WarpResult) -> WarpResult:
    """Put the photo's grain back where the warp's resampling took it (in place on
    ``res.image``; see the module docstring). Returns ``res``."""
    if res.maps is None:
        return res
    plan = grain_plan(face)
    if plan is None:
        return res
    map_x, map_y, (bx0, by0, bx1, by1) = res.maps
    # the kept share on the nodes of a grid :data:`_NODE` px apart (the maps are smooth:
    # piecewise affine, and r periodic and continuous in their values)
    n = _NODE
    cx = map_x[::n, ::n]
    cy = map_y[::n, ::n]
    if cx.shape[0] < 2 or cx.shape[1] < 2:
        return res
    r = plan.keeps(res.interpolation)
    # the photo's area per output pixel, from the differences to the next node right and
    # down (each node's cell)
    x00, y00 = cx[:-1, :-1], cy[:-1, :-1]
    det = ((cx[:-1, 1:] - x00) * (cy[1:, :-1] - y00)
           - (cx[1:, :-1] - x00) * (cy[:-1, 1:] - y00)) * np.float32(1.0 / (n * n))
    k = r.take(np.rint((x00 - np.floor(x00)) * _STEPS).astype(np.intp))
    k *= r.take(np.rint((y00 - np.floor(y00)) * _STEPS).astype(np.intp))
    # (clip: np.clip's ufunc without its Python layers; count_nonzero: any's answer)
    k *= clip(det, 0.0, 1.0)
    amp = np.sqrt(clip(1.0 - k, 0.0, 1.0)) * np.float32(plan.level)
    # (the bounding box of the nodes above the threshold: one OpenCV call on the bytes of the
    # comparison's bool array; empty: nothing to add)
    cj, ci, cw, ch = cv2.boundingRect((amp > _MIN_AMP).view(np.uint8))
    if not cw:
        return res
    # the hot part of the box in pixels (node i at pixel n i), a node's margin either side
    # for the interpolation
    i0, i1 = max(ci - 1, 0), min(ci + ch + 1, amp.shape[0])
    j0, j1 = max(cj - 1, 0), min(cj + cw + 1, amp.shape[1])
    y0, y1 = by0 + n * i0, min(by0 + n * i1, by1)
    x0, x1 = bx0 + n * j0, min(bx0 + n * j1, bx1)
    if y1 <= y0 or x1 <= x0:
        return res
    a = cv2.resize(np.ascontiguousarray(amp[i0:i1, j0:j1], np.float32),
                   (n * (j1 - j0), n * (i1 - i0)), interpolation=cv2.INTER_LINEAR)
    a = a[:y1 - y0, :x1 - x0]
    # only the pixels the warp resampled (off their own place by OpenCV's map step or more:
    # nearer, the fixed-point remap copies the pixel): the nodes' interpolation must not
    # carry grain onto the still hair or background beside the moving skin
    # (|u| >= t or |w| >= t as max(|u|, |w|) >= t: in place, one comparison)
    u = map_x[y0 - by0:y1 - by0, x0 - bx0:x1 - bx0] - np.arange(x0, x1, dtype=np.float32)
    w = map_y[y0 - by0:y1 - by0, x0 - bx0:x1 - bx0] - np.arange(y0, y1, dtype=np.float32
                                                                 )[:, None]
    np.maximum(np.abs(u, out=u), np.abs(w, out=w), out=u)
    a *= u >= _TAB
    a *= _tiled(plan.sigma, x0, y0, x1 - x0, y1 - y0)
    _add_grey(res.image[y0:y1, x0:x1], a, plan.level * _tile_peak(plan.sigma) < _BIASED_MAX)
    return res


def _add_grey(out: np.ndarray, a: np.ndarray, small: bool) -> None:
    """Add the float32 (h, w) ``a`` to the three channels of the uint8 (h, w, 3) ``out`` in
    place as ``cv2.add(out, a3, out, None, cv2.CV_8U)`` adds it (the addend rounded to an
    integer first, half to even, the sum saturated). ``small``: ``|a| < 126`` is known; then
    ``a`` (overwritten) is rounded, biased by 128 into uint8 (convertScaleAbs: exact on those
    integers), spread over the channels as bytes and added with the bias taken off
    (addWeighted: exact on integers): the same pixels at about half the cost."""
    if small:
        b = cv2.convertScaleAbs(np.rint(a, out=a), None, 1.0, 128.0)
        cv2.addWeighted(out, 1.0, cv2.cvtColor(b, cv2.COLOR_GRAY2RGB), 1.0, -128.0, out)
    else:
        # (cvtColor's grey-to-RGB copy: cv2.merge's values at about half its cost)
        cv2.add(out, cv2.cvtColor(a, cv2.COLOR_GRAY2RGB), out, None, cv2.CV_8U)


#: :func:`apply_grain` adds its grain through a uint8 biased by 128 when the level times the
#: tile's largest magnitude is below this (room for the rounding)
_BIASED_MAX = 126.0


@functools.cache
def _tile_peak(sigma: float) -> float:
    """The largest magnitude of the tile of fineness ``sigma`` (once per process)."""
    return float(np.abs(_tiles(sigma)[1]).max())


def grain_over(face: Face, box: tuple[int, int, int, int]) -> np.ndarray | None:
    """(h, w) float32: the photo's grain over ``box`` (x0, y0, x1, y1) of the frame, at its
    full level, for what a layer draws from scratch (the mouth's teeth, tongue and cavity: a
    photo's opening has the grain of the skin around it; drawn without, the interior read as
    a smooth inlay). None on a photo without grain (no plan)."""
    plan = grain_plan(face)
    if plan is None:
        return None
    x0, y0, x1, y1 = box
    return _tiled(plan.sigma, x0, y0, x1 - x0, y1 - y0) * np.float32(plan.level)


def _tiled(sigma: float, x0: int, y0: int, w: int, h: int) -> np.ndarray:
    """The repeating tile of fineness ``sigma`` over the frame's window (x0, y0, w, h): a
    read-only view of the tile repeated (:func:`_repeated`; a box's size recurs from frame to
    frame, so the repeat is not redone and copied for every frame)."""
    ox, oy = x0 % TILE, y0 % TILE
    reps = ((oy + h + TILE - 1) // TILE, (ox + w + TILE - 1) // TILE)
    if reps[0] * reps[1] > _KEEP_REPS:  # (a box of megapixels: not kept)
        return np.tile(_tiles(sigma)[1], reps)[oy:oy + h, ox:ox + w]
    return _repeated(sigma, *reps)[oy:oy + h, ox:ox + w]


#: repeats of the tile kept by :func:`_repeated` (at most 64 tiles, 4 MB each, 4 kept)
_KEEP_REPS = 64


@functools.lru_cache(maxsize=4)
def _repeated(sigma: float, ry: int, rx: int) -> np.ndarray:
    """The tile of fineness ``sigma`` repeated ``ry`` x ``rx`` times (read-only, kept)."""
    t = np.tile(_tiles(sigma)[1], (ry, rx))
    t.setflags(write=False)
    return t
