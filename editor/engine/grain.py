"""The photo's grain kept where the warp resamples it (issue 21). No Qt.

Resampling a photo at a fractional position averages neighbouring pixels: bilinear sampling
halfway between two pixels keeps half of the pixel noise's variance along each axis, and skin
that the deformation stretches spreads its grain over more pixels. So the skin that moves
comes out smoother than the photo around it, a patch that looks pasted on (the blind raters'
word for joy at 150 %). JAFFE's ten women, high-pass level of the skin beside the mouth and
over the upper lip against each one's neutral photo: her real expression photos 1.01-1.10
(median per expression); the presets at 100 % rendered on her neutral photo 0.58-0.70
(bilinear), 0.78-0.90 (bicubic).

* **Once per face** (:func:`grain_plan`): the photo's grain level ``g`` (std of the
  luminance high-pass over the face box, its edges left out) and how fine it is (the
  high-pass's correlation between neighbouring pixels); a static noise tile with that
  correlation, high-passed like the measure (no blotches) and scaled to std 1; and, per
  interpolation, the share ``r(f)`` of the grain's variance a resampling at fractional offset
  ``f`` along one axis keeps (measured on the tile's noise itself, at the 1/32 px steps of
  OpenCV's fixed-point maps). A large face (a 24 MP photo's) is measured on 3 x 3 patches
  of its box: the plan then costs ~20 ms instead of 150 at the first render.
* **Per frame** (:func:`apply_grain`): over the warp's map box, the share kept
  ``k = r(fx) r(fy) min(1, det J)`` (``fx``, ``fy`` the map's fractional parts, ``J`` its
  Jacobian: the photo's area per output pixel, below 1 where the skin is stretched), and the
  tile added to the three channels at ``g sqrt(1 - k)``: the lost variance back. ``k`` is
  computed on a grid :data:`_NODE` px apart and interpolated (``r`` is periodic and
  continuous in the map's value, so it interpolates across integer wraps), and added only to
  the pixels the warp resampled: 0.13 ms at 431 x 591 and 0.47 ms at 1920 x 1080 on the
  bench's faces with a film's grain (4-7 % of their render). Where the map is the identity
  nothing changes; an untouched face has no map at all (the photo, exactly).

The tile is fixed (seeded) and tied to the frame, as a camera's grain is: the same FAPs give
the same pixels, and a video's moving skin shows no flicker. A photo without grain (a clean
or upscaled one: level under :data:`MIN_LEVEL`) has no plan.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import cv2
import numpy as np

from .warp import WarpResult

if TYPE_CHECKING:
    from .face import Face

#: below this grain level (grey levels, std of the high-pass) the photo is left as warped: a
#: grain under a grey level does not show (the sample photo's is 2.0, JAFFE's 4-5; the
#: sample blurred by 2.5 px keeps 0.55 of rounding and its strongest edges)
MIN_LEVEL = 1.0
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
#: a face box of up to 4 x this many pixels has its grain measured on all of them, a larger
#: one on 3 x 3 patches of _WINDOW / 2 px; the fineness in a window of at most _WINDOW px at
#: its centre
_SAMPLES, _WINDOW = 250_000, 512
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


@dataclass(eq=False)
class GrainPlan:
    """A face's grain (see the module docstring)."""

    level: float  # g: std of the photo's luminance high-pass over the face (grey levels)
    sigma: float  # blur of the tile's noise (px), matching the photo's fineness
    tile: np.ndarray  # (TILE, TILE) float32 high-passed noise, std 1
    base: np.ndarray  # (TILE, TILE) float32 the noise before the high-pass (for r(f))
    kept: dict[int, np.ndarray] = field(default_factory=dict)  # interpolation -> r(f)

    def keeps(self, interpolation: int) -> np.ndarray:
        """``r`` (float32, ``_STEPS + 1`` values at f = 0, 1/32, ..., 1): the share of the
        grain's high-pass variance a resampling with ``interpolation`` at fractional offset
        ``f`` along one axis keeps (r(0) = r(1) = 1)."""
        r = self.kept.get(interpolation)
        if r is None:
            r = _kept_table(self.base, interpolation)
            self.kept[interpolation] = r
        return r


def _kept_table(base: np.ndarray, interpolation: int) -> np.ndarray:
    """Resample the (wrapped) noise ``base`` by f = k / 32 px along x and compare the variance
    of the results' high-pass with the noise's own."""
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
    return out


_PLANS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_NONE = object()


def grain_plan(face: Face) -> GrainPlan | None:
    """The face's grain (cached for the face's lifetime); None on a photo without grain."""
    got = _PLANS.get(face, _NONE)
    if got is _NONE:
        got = _build(face)
        _PLANS[face] = got
    return got


def _build(face: Face) -> GrainPlan | None:
    img = face.image
    H, W = img.shape[:2]
    v = np.asarray(face.vertices, np.float64)
    x0, y0 = (max(int(math.floor(q)), 0) for q in v.min(0))
    x1, y1 = int(min(math.ceil(v[:, 0].max()) + 1, W)), int(min(math.ceil(v[:, 1].max()) + 1, H))
    if x1 - x0 < 8 or y1 - y0 < 8:
        return None
    if (x1 - x0) * (y1 - y0) <= 4 * _SAMPLES:
        h = _hp(cv2.cvtColor(np.ascontiguousarray(img[y0:y1, x0:x1]),
                             cv2.COLOR_RGB2GRAY).astype(np.float32))
        sub = h
        r0, c0 = max((h.shape[0] - _WINDOW) // 2, 0), max((h.shape[1] - _WINDOW) // 2, 0)
        win = h[r0:r0 + _WINDOW, c0:c0 + _WINDOW]
    else:  # a large face (a 24 MP photo's has millions of pixels): 3 x 3 patches of it
        P = _WINDOW // 4
        hs = []
        for fy in (0.25, 0.5, 0.75):
            for fx in (0.25, 0.5, 0.75):
                cy, cx = int(y0 + fy * (y1 - y0)), int(x0 + fx * (x1 - x0))
                patch = img[max(cy - P, 0):cy + P, max(cx - P, 0):cx + P]
                hs.append(_hp(cv2.cvtColor(np.ascontiguousarray(patch),
                                           cv2.COLOR_RGB2GRAY).astype(np.float32)))
        sub = np.concatenate([x.ravel() for x in hs])  # (at most 9 x 256 x 256 values)
        win = hs[4]
    # the pixels where the high-pass is grain rather than an edge (lids, lips, brows: a
    # minority of the face's pixels, beyond 3 robust standard deviations) give its level and
    # its fineness (in a window of at most _WINDOW px at the face's centre)
    mad = 1.4826 * float(np.median(np.abs(sub - np.median(sub))))
    calm = np.abs(sub) < 3.0 * mad
    level = float(sub[calm].std()) if calm.any() else 0.0
    if level < MIN_LEVEL:
        return None
    hh = np.where(np.abs(win) < 3.0 * mad, win, 0.0).astype(np.float32)
    want = _corr1(hh)
    noise = np.random.default_rng(20261129).standard_normal((TILE, TILE)).astype(np.float32)
    best = min(_SIGMAS, key=lambda s: abs(_corr1(_hp(_blurred_tile(noise, s), wrap=True))
                                          - want))
    base = _blurred_tile(noise, best)
    tile = _hp(base, wrap=True)
    tile *= np.float32(1.0 / max(float(tile.std()), 1e-6))
    return GrainPlan(level, best, np.ascontiguousarray(tile, np.float32), base)


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
    k *= np.clip(det, 0.0, 1.0)
    amp = np.sqrt(np.clip(1.0 - k, 0.0, 1.0)) * np.float32(plan.level)
    hot = amp > _MIN_AMP
    if not hot.any():
        return res
    rows = np.flatnonzero(hot.any(1))
    cols = np.flatnonzero(hot.any(0))
    # the hot part of the box in pixels (node i at pixel n i), a node's margin either side
    # for the interpolation
    i0, i1 = max(int(rows[0]) - 1, 0), min(int(rows[-1]) + 2, amp.shape[0])
    j0, j1 = max(int(cols[0]) - 1, 0), min(int(cols[-1]) + 2, amp.shape[1])
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
    u = map_x[y0 - by0:y1 - by0, x0 - bx0:x1 - bx0] - np.arange(x0, x1, dtype=np.float32)
    w = map_y[y0 - by0:y1 - by0, x0 - bx0:x1 - bx0] - np.arange(y0, y1, dtype=np.float32
                                                                 )[:, None]
    a *= (np.abs(u) >= _TAB) | (np.abs(w) >= _TAB)
    a *= _tiled(plan.tile, x0, y0, x1 - x0, y1 - y0)
    out = res.image[y0:y1, x0:x1]
    cv2.add(out, cv2.merge([a, a, a]), dst=out, dtype=cv2.CV_8U)
    return res


def _tiled(tile: np.ndarray, x0: int, y0: int, w: int, h: int) -> np.ndarray:
    """The repeating ``tile`` over the frame's window (x0, y0, w, h) (a new array)."""
    T = tile.shape[0]
    ox, oy = x0 % T, y0 % T
    reps = ((oy + h + T - 1) // T, (ox + w + T - 1) // T)
    return np.tile(tile, reps)[oy:oy + h, ox:ox + w]
