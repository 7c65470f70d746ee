"""The eyeball layer behind the eye openings (SPEC §3.2): gaze, pupils, thrust. No Qt.

Per eye, once per face (:class:`EyePlan`), from the neutral photo and the detected iris circle:

* the **white plate**: the photo inside the eye opening with the iris disc filled from the white
  beside it (rows) and, near the lids, from the lids' shadow (inpainting), and continued beyond
  the opening, so that shifted or stretched samples never pick up iris remnants or lid skin;
* the **iris sprite**: the photo's iris disc, its parts hidden by the lids completed (vertical
  mirror when visible there, else the mean colour at the same radius).

Per frame (:meth:`EyePlan.render`), in the neutral eye's coordinates (the eyeball follows the
eye corners, the similarity ``warp`` uses for the opening):

* horizontal gaze Δx (the iris centre 3.5/3.6 as moved by FAPs 23/24 and the head): the white
  right of the split line moves right rigidly, the triangle (left corner, a', b') is filled
  affinely from (left corner, a, b), a/b the points 1/5 along the lids from the left corner
  (mirrored with c/d for gaze left). When the photo's iris reaches into that corner triangle (the
  eye does not look straight ahead), the vertical tangent at the iris edge replaces the a-b line.
  Δx is clamped so that the iris centre does not cross the line c-d (a-b for gaze left; see
  :meth:`EyePlan.gaze_shift` for why not the whole iris as SPEC §3.2 says);
* vertical gaze (FAPs 25/26) moves the iris only (no stretch), the lids clip it;
* the iris is drawn round at its new centre with radius ``r'`` (thrust, FAPs 27/28) and the
  pupil scaled radially to ``p'`` (FAPs 29/30): the iris annulus [p0, r0] maps to [p', r'];
  a dilated pupil also gets a dark disc of the photo's pupil colour (brown irises show
  little of their own pupil), catch-lights spared.

Returns colours only; the caller composites them behind the deformed lids with anti-aliasing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from .fitting import (
    catmull_rom,
    clamp,
    clip,
    gather_px,
    interp,
    linspace,
    masked_rows,
    median,
    pad_edge,
    percentile,
    smooth01,
)
from .warp import bilinear_reach

#: FAP indices (0-based) per eye: yaw, pitch, thrust, dilate; eye_l = FDP 3.5, eye_r = 3.6
EYE_FAPS = {"eye_l": (22, 24, 26, 28), "eye_r": (23, 25, 27, 29)}
EXTRA_INDEX = {"eye_l": 0, "eye_r": 1}  # position among deform's extra points (3.5, 3.6)
_ONES3 = (1.0, 1.0, 1.0)  # (cv2 calls below take their arguments positionally: keywords cost
# a few microseconds of parsing per call, as much as the work on an eye's box)


def spread3(a: np.ndarray) -> np.ndarray:
    """``cv2.merge([a, a, a])`` of a float32 (or uint8, or float64) (h, w) array: the same
    values, for a float32 or uint8 one through ``cv2.cvtColor``'s grey-to-RGB copy, which
    costs about half a merge's call on the layers' small boxes (per-pixel weights spread over
    3 channels: numpy's broadcasting of an (h, w, 1) array is several times slower there)."""
    if a.dtype == np.float64:  # (cvtColor takes no float64)
        return cv2.merge([a, a, a])
    return cv2.cvtColor(a, cv2.COLOR_GRAY2RGB)


_ONES4 = (1.0, 1.0, 1.0, 1.0)


def _rgb(rgba: np.ndarray, dst: np.ndarray | None = None) -> np.ndarray:
    """The first 3 channels of a float32 (h, w, 4) array as a new (or ``dst``'s) contiguous
    (h, w, 3) one."""
    return np.asarray(cv2.cvtColor(rgba, cv2.COLOR_RGBA2RGB, dst), np.float32)


#: Maps of fewer pixels than this resample a 3-channel texture (:func:`sample_rgb`): the eye
#: boxes of a face ~40 px between the eyes (~150-300 px) in one 3-channel remap, where the
#: 4-channel remap and its copy back to 3 channels cost ~0.5 us more; larger ones (the 1080p
#: bench face's eyes, ~1100 px) through the 4 channels, vectorised
REMAP3_PX = 768


def sample_rgb(tex3: np.ndarray, tex4: np.ndarray, mx: np.ndarray, my: np.ndarray,
            dst: np.ndarray | None = None) -> np.ndarray:
    """``cv2.remap`` (bilinear) of a float32 texture given as 3 channels ``tex3`` and as 4
    (:func:`zero_alpha`, ``tex4``) at float32 maps: (h, w, 3) float32 (into ``dst`` when
    given). Without ``dst`` the border replicates; with it (the lids' bands) it is ones. The
    same values either way (the same arithmetic per channel)."""
    if dst is None:
        if mx.size < REMAP3_PX:
            return cv2.remap(tex3, mx, my, cv2.INTER_LINEAR, None, cv2.BORDER_REPLICATE)
        return _rgb(cv2.remap(tex4, mx, my, cv2.INTER_LINEAR, None, cv2.BORDER_REPLICATE))
    if mx.size < REMAP3_PX:
        return cv2.remap(tex3, mx, my, cv2.INTER_LINEAR, dst, cv2.BORDER_CONSTANT, _ONES3)
    return _rgb(cv2.remap(tex4, mx, my, cv2.INTER_LINEAR, None, cv2.BORDER_CONSTANT, _ONES4),
                dst)


def warp_rgb(tex3: np.ndarray, tex4: np.ndarray, M: np.ndarray, dsize: tuple[int, int]
             ) -> np.ndarray:
    """:func:`sample_rgb` (no ``dst``: the border replicated) at an affine map ``M`` (2, 3)
    from the output's pixels to the texture's (``cv2.warpAffine``, inverse map) over
    ``dsize`` (w, h): from REMAP3_PX pixels through the 4-channel copy, the same values."""
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    if dsize[0] * dsize[1] < REMAP3_PX:
        return cv2.warpAffine(tex3, M, dsize, None, flags, cv2.BORDER_REPLICATE)
    return _rgb(cv2.warpAffine(tex4, M, dsize, None, flags, cv2.BORDER_REPLICATE))


def zero_alpha(rgb: np.ndarray) -> np.ndarray:
    """(h, w, 4) float32: a float32 (h, w, 3) array with a 4th channel of zeros (what OpenCV
    resamples faster than 3 channels), through ``cv2.cvtColor``'s RGB-to-RGBA copy: the same
    values as writing the 3 channels into zeros, without numpy's strided copy into every
    4th-channel gap (several times slower)."""
    out = cv2.cvtColor(rgb, cv2.COLOR_RGB2RGBA)
    out[..., 3] = 0.0
    return out


def _lid_point(lid: np.ndarray, f: float) -> np.ndarray:
    """Point on a lid polyline (frame coords, corner to corner) at fraction f of the x span."""
    u = lid[0, 0] + f * (lid[-1, 0] - lid[0, 0])
    order = np.argsort(lid[:, 0])
    return np.array([u, interp(u, lid[order, 0], lid[order, 1])])


def _line_u(p: np.ndarray, q: np.ndarray, w: np.ndarray | float) -> np.ndarray | float:
    """u of the line through p, q (frame coords) at height w."""
    dw = q[1] - p[1]
    if abs(dw) < 1e-6:
        return p[0] + 0.0 * np.asarray(w)
    return p[0] + (np.asarray(w) - p[1]) * (q[0] - p[0]) / dw


def _eye_profile(patch: np.ndarray, mask: np.ndarray, cx: float, cy: float, r: float,
                 ex: np.ndarray, ey: np.ndarray, reach: float, rows: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The luminance along the eye's horizontal through the iris centre, every 0.25 px over
    ``reach`` r either side, averaged over 7 rows within ``rows`` r of the centre (pixels of
    ``mask`` only): the positions ``us``, the profile and where two or more rows saw it."""
    g = cv2.cvtColor(patch, cv2.COLOR_RGB2GRAY).astype(np.float32)
    m = mask.astype(np.float32)
    us = np.arange(-reach * r, reach * r + 1e-6, 0.25)
    ws = linspace(-rows * r, rows * r, 7)
    U, W = us[None, :], ws[:, None]  # (np.meshgrid's values, broadcast)
    mx = (cx + U * ex[0] + W * ey[0]).astype(np.float32)
    my = (cy + U * ex[1] + W * ey[1]).astype(np.float32)
    lum = cv2.remap(g, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    vis = cv2.remap(m, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT) > 0.99
    cnt = vis.sum(0)
    return us, (lum * vis).sum(0) / np.maximum(cnt, 1), cnt >= 2


def _iris_edges(patch: np.ndarray, opening: np.ndarray, cx: float, cy: float, r: float,
                ex: np.ndarray, ey: np.ndarray) -> tuple[float, float, float]:
    """Refine the iris from its left and right edges (the paper's Canny edge points).

    The luminance is averaged over the rows near the centre (pixels inside the opening only)
    along the eye's horizontal; the left edge is the strongest bright-to-dark step left of the
    centre, the right edge the strongest dark-to-bright step right of it. Kept only when both
    are clear and give a radius within 0.75-1.7 of the detector's; else the circle is unchanged.
    """
    us, prof, ok = _eye_profile(patch, opening, cx, cy, r, ex, ey, 2.0, 0.4)
    if ok.sum() < 8:
        return cx, cy, r
    prof = interp(us, us[ok], prof[ok])
    # smoothed over 1.25 px, or a tenth of the radius on a large eye: on the 4K bench face's
    # soft eyes (edges ramping over ~15 px) a bump of the sclera's texture steeper than the
    # limbus's ramp outbid it by 5 %, and eye_r's iris was drawn 18 % too large (52 px
    # against 44), its outer band the photo's white: a light ring with a hard rim
    k = max(2, int(round(0.2 * r)))
    prof = np.convolve(pad_edge(prof, k), np.ones(2 * k + 1) / (2 * k + 1), mode="valid")
    grad = np.gradient(prof, us)
    left = (us > -1.8 * r) & (us < -0.5 * r) & ok
    right = (us < 1.8 * r) & (us > 0.5 * r) & ok
    if not left.any() or not right.any():
        return cx, cy, r
    il = np.flatnonzero(left)[np.argmin(grad[left])]
    ir = np.flatnonzero(right)[np.argmax(grad[right])]
    spread = float(np.ptp(prof[ok])) + 1e-6
    strong = min(-grad[il], grad[ir]) * r / spread > 0.35
    re = 0.5 * (us[ir] - us[il])
    if not strong or not 0.75 * r <= re <= 1.7 * r:
        return cx, cy, r
    uc = 0.5 * (us[ir] + us[il])
    return cx + uc * ex[0], cy + uc * ex[1], float(re)


def limbus_widths(patch: np.ndarray, opening: np.ndarray, cx: float, cy: float, r: float,
                  ex: np.ndarray, ey: np.ndarray) -> list[float]:
    """How soft the photo draws edges: the 10-90 % width (px) of the iris's left and right
    edge (the limbus, sclera to iris) where both sides are clearly visible.

    The luminance is averaged over the rows near the centre (pixels one clear of the lids)
    along the eye's horizontal, every 0.25 px. Per side the iris level is the median over
    0.45-0.75 r from the centre, the white's over 1.25-1.6 r; an edge is measured only with
    at least 15 grey levels between them, from the last crossing of 10 % to the first of 90 %
    inside 0.6-1.4 r. A sharp photo gives about a pixel (the limbus is a little soft itself);
    an upscaled or defocused one proportionally more. Empty when no edge is clear.
    """
    clear = cv2.erode(opening.astype(np.uint8), np.ones((3, 3), np.uint8))
    us, prof, ok = _eye_profile(patch, clear, cx, cy, r, ex, ey, 1.7, 0.3)
    a = np.abs(us)
    widths = []
    for side in (us < 0, us > 0):
        inner = ok & side & (a > 0.45 * r) & (a < 0.75 * r)
        outer = ok & side & (a > 1.25 * r) & (a < 1.6 * r)
        if inner.sum() < 2 or outer.sum() < 2:
            continue
        li, lo = float(median(prof[inner])), float(median(prof[outer]))
        if lo - li < 15.0:
            continue
        idx = np.flatnonzero(ok & side & (a >= 0.6 * r) & (a <= 1.4 * r))
        # (np.diff's values as a slice difference, without its Python-level overhead)
        if len(idx) < 4 or np.any(idx[1:] - idx[:-1] != 1):
            continue
        order = np.argsort(a[idx])
        u, t = a[idx][order], (prof[idx][order] - li) / (lo - li)
        s10, s90 = np.sign(t - 0.1), np.sign(t - 0.9)
        c10 = np.flatnonzero(s10[1:] - s10[:-1] != 0)
        c90 = np.flatnonzero(s90[1:] - s90[:-1] != 0)
        if not len(c10) or not len(c90):
            continue
        k1, k9 = int(c10[-1]), int(c90[0])
        x1 = u[k1] + (0.1 - t[k1]) * (u[k1 + 1] - u[k1]) / (t[k1 + 1] - t[k1] + 1e-9)
        x9 = u[k9] + (0.9 - t[k9]) * (u[k9 + 1] - u[k9]) / (t[k9 + 1] - t[k9] + 1e-9)
        if x9 > x1:
            widths.append(float(x9 - x1))
    return widths


def edge_ramp(widths: list[float], r: float | None = None) -> float:
    """The ramp (px) over which the layers blend their edges into a photo whose edges have
    the 10-90 % ``widths`` (:func:`limbus_widths`): their median less a pixel's own sampling
    (in quadrature), over 0.8 (a linear ramp's 10-90 % share); 1 (a pixel, the layers' edges
    before) when that is below 1.5 or nothing was measured, so sharp photos are unchanged.
    With the iris radius ``r``: at most half of it (a badly defocused photo or a misread edge
    must not fade an eye or a mouth away)."""
    if not widths:
        return 1.0
    w = float(median(np.asarray(widths, np.float64)))
    s = math.sqrt(max(w * w - 1.0, 0.0)) / 0.8
    if s < SOFT_MIN:
        return 1.0
    return s if r is None else min(s, max(1.0, 0.5 * r))


#: Below this edge ramp (px) the layers keep their one-pixel edges (see :func:`edge_ramp`)
SOFT_MIN = 1.5


def _white_plate(patch: np.ndarray, opening: np.ndarray, rho: np.ndarray, r_fill: float,
                 radius: float, soft: float = 1.0, d_lid: np.ndarray | None = None
                 ) -> np.ndarray:
    """The white of the eye without the iris, continued beyond the opening (float32).

    Inside the disc ``rho < r_fill``: away from the lids, each row is interpolated between the
    white left and right of the disc; towards the lids this blends into an inpainting (OpenCV
    Telea) of the disc from its surroundings, which carries the lids' shadow; the result is
    smoothed so that no lash texture shows, and feathered into the photo over the disc's last
    pixel. Outside the opening each column repeats its nearest value inside (shifted samples
    near the lids then stay eye-coloured).
    """
    outside_iris = rho >= r_fill
    disc = opening & ~outside_iris
    out = patch.astype(np.float32)
    # the distance to the lids (read by the fill and by the lid margin below)
    if d_lid is None:  # (the caller's when it has it: :meth:`EyePlan.build` reads it too)
        d_lid = cv2.distanceTransform(opening.astype(np.uint8), cv2.DIST_L2, 3)
    if disc.any():
        tel = _telea(patch, disc, radius)
        known = opening & outside_iris & (d_lid > 1.0)  # the white, clear of the lash line
        # only the disc changes (its weight w is 0 elsewhere): the fill is made and blurred
        # over the disc's box and the blur's reach (the blur's values there are those of the
        # whole patch's; the rows are interpolated over the whole width)
        sigma = max(0.6, 0.25 * radius)
        reach = (int(round(sigma * 4 * 2 + 1)) | 1) // 2 + 1  # OpenCV's float kernel, + 1
        ys, xs = np.flatnonzero(disc.any(1)), np.flatnonzero(disc.any(0))
        ph, pw = disc.shape
        r0, r1 = max(int(ys[0]) - reach, 0), min(int(ys[-1]) + 1 + reach, ph)
        c0, c1 = max(int(xs[0]) - reach, 0), min(int(xs[-1]) + 1 + reach, pw)
        rows, wrow = _row_interp(tel[r0:r1], out[r0:r1], known[r0:r1], disc[r0:r1])
        box = (slice(r0, r1), slice(c0, c1))
        wv = spread3(clamp((d_lid[box] - 0.5) / 2.0, 0.0, 1.0) * wrow[:, c0:c1])
        fill = wv * rows[:, c0:c1] + (1.0 - wv) * tel[box]
        fill = cv2.GaussianBlur(fill, (0, 0), sigma)
        w = spread3((clamp(r_fill - rho[box], 0.0, 1.0) * opening[box]).astype(np.float32))
        out[box] = w * fill + (1.0 - w) * out[box]
    # the lid margin (the opening's outer pixel and a half) is lid, lashes and their shadow:
    # it stays with the lid, so the eyeball's white there continues the nearest white inside
    # (else a rotated eyeball carries the lash line into view: a dark stripe beside the iris);
    # on a soft photo the margin's blur reaches ``soft`` times as far
    inner = opening & (d_lid > 1.5 * soft)
    margin = opening & ~inner
    if inner.any() and margin.any():
        _, lab = cv2.distanceTransformWithLabels((~inner).astype(np.uint8), cv2.DIST_L2, 3,
                                                 labelType=cv2.DIST_LABEL_PIXEL)
        iy, ix = np.nonzero(inner)  # labels number the zero pixels in this (row-major) order
        near = lab[margin] - 1
        out[margin] = gather_px(out, iy[near], ix[near])
    ph, pw = opening.shape
    full = np.flatnonzero(opening.any(0))
    if len(full):
        # each column above / below its opening repeats its first / last row inside, a column
        # without opening the nearest column with one (the smaller on a tie)
        top = np.argmax(opening, 0)
        bot = ph - 1 - np.argmax(opening[::-1], 0)
        src = full[np.abs(np.arange(pw)[:, None] - full[None, :]).argmin(1)]
        yy = np.arange(ph)[:, None]
        out = gather_px(out, clamp(yy, top[src][None, :], bot[src][None, :]), src[None, :])
    return out


#: The largest iris radius (px) at which :func:`_white_plate` inpaints; larger eyes (a 24 MP
#: portrait's iris is ~30 px) inpaint a copy downsampled to it, the result upsampled.
PLATE_WORK_R = 16.0


def _telea(patch: np.ndarray, disc: np.ndarray, radius: float) -> np.ndarray:
    """``patch`` (uint8) with ``disc`` inpainted (OpenCV Telea, radius half the iris's), float32.

    The inpainting is smooth and then blurred by a quarter of the iris radius, while its cost
    grows with the disc's area times the radius squared: above :data:`PLATE_WORK_R` it runs on
    the patch downsampled to that iris radius (the disc grown by one pixel there, so no iris
    pixel mixed in by the downsampling counts as known), and the disc's pixels take the
    upsampled result; the other pixels stay the photo's."""
    if radius <= PLATE_WORK_R:
        return cv2.inpaint(patch, disc.astype(np.uint8), max(2.0, 0.5 * radius),
                           cv2.INPAINT_TELEA).astype(np.float32)
    f = PLATE_WORK_R / radius
    ph, pw = disc.shape
    sw, sh = max(1, round(pw * f)), max(1, round(ph * f))
    small = cv2.resize(patch, (sw, sh), interpolation=cv2.INTER_AREA)
    cover = cv2.resize(disc.astype(np.float32), (sw, sh), interpolation=cv2.INTER_AREA) > 0
    sdisc = cv2.dilate(cover.astype(np.uint8), np.ones((3, 3), np.uint8))
    tel_s = cv2.inpaint(small, sdisc, max(2.0, 0.5 * PLATE_WORK_R), cv2.INPAINT_TELEA)
    up = cv2.resize(tel_s.astype(np.float32), (pw, ph), interpolation=cv2.INTER_LINEAR)
    return np.where(disc[..., None], up, patch.astype(np.float32))


def _row_interp(tel: np.ndarray, out: np.ndarray, known: np.ndarray, disc: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """``tel`` (h, w, 3) with, in each row whose disc pixels have known pixels on both sides,
    the disc interpolated linearly between its nearest known pixels of ``out`` left and
    right (``np.interp``'s arithmetic, float64, stored as float32), and the weight (h, w)
    that is 1 there. All rows at once: the nearest known column either side of each pixel is
    a running max / min along the row."""
    h, w = disc.shape
    rows = tel.copy()
    wrow = np.zeros((h, w), np.float32)
    cols = np.arange(w)
    left = np.maximum.accumulate(np.where(known, cols, -1), axis=1)
    right = np.minimum.accumulate(np.where(known, cols, w)[:, ::-1], axis=1)[:, ::-1]
    # rows whose disc lies between known pixels (np.interp would else hold the end values)
    dmin = np.where(disc, cols, w).min(1)
    dmax = np.where(disc, cols, -1).max(1)
    kmin = np.where(known, cols, w).min(1)
    kmax = np.where(known, cols, -1).max(1)
    ok = disc.any(1) & (kmin <= dmin) & (kmax >= dmax)
    iy, ix = np.nonzero(disc & ok[:, None])
    if len(iy):
        kl, kr = left[iy, ix], right[iy, ix]  # kl < ix < kr: the disc is not known
        yl = gather_px(out, iy, kl).astype(np.float64)
        yr = gather_px(out, iy, kr).astype(np.float64)
        x, xl, xr = ix.astype(np.float64), kl.astype(np.float64), kr.astype(np.float64)
        slope = (yr - yl) / (xr - xl)[:, None]
        rows[iy, ix] = slope * (x - xl)[:, None] + yl
        wrow[iy, ix] = 1.0
    return rows, wrow

def _column_percentile(vals: np.ndarray, valid: np.ndarray, q: float) -> np.ndarray:
    """Per column, the ``q``-th percentile of ``vals[valid]`` (h, w) -> (w,): the values of
    ``np.nanpercentile(np.where(valid, vals, nan), q, axis=0)`` bit for bit (its linear
    interpolation, in the same order and precision), with one sort for all columns instead of
    one call per column. A column without valid values gives NaN."""
    n = valid.sum(0)
    s = np.sort(np.where(valid, vals, np.inf), axis=0)  # the invalid ones last
    vi = (n - 1) * np.true_divide(q, 100)
    prev_f = np.floor(vi)
    gamma = vi - prev_f
    prev = prev_f.astype(np.intp)
    nxt = prev + 1
    last = np.maximum(n - 1, 0)
    top = vi >= n - 1
    prev[top], nxt[top] = last[top], last[top]
    low = vi < 0
    prev[low], nxt[low] = 0, 0
    jj = np.arange(s.shape[1])  # (s[prev[j], j]: np.take_along_axis's values, less overhead)
    a = s[prev, jj]
    b = s[nxt, jj]
    with np.errstate(invalid="ignore"):  # (inf - inf in a column without valid values)
        d = b - a
        out = a + d * gamma.astype(vals.dtype)
        hi = gamma >= 0.5
        out[hi] = (b - d * (1.0 - gamma).astype(vals.dtype))[hi]
    out[n == 0] = np.nan
    return out


#: How much darker the white gets far above / below the lids' bands (a lit ball's top)
BALL_SHADE = 0.05


def _ball_white(plate: np.ndarray, opening: np.ndarray, r: float, band_up: float,
                band_low: float) -> np.ndarray:
    """The white continued past the lids as the rest of a ball, float32 (h, w, 3).

    Per column of the opening, the reference rows lie one lid-shadow band (``band_up`` below
    the upper lid, ``band_low`` above the lower one) inside the opening; the reference colour
    is the mean of the column's brighter 20 % between them (the plate has no iris; smoothed
    along the eye). Above / below the reference rows the column repeats that colour, darkening
    with the distance like the top and bottom of a lit ball (up to :data:`BALL_SHADE`, 1/e
    at the iris radius). Between the two references the plate is kept. Columns without
    opening take the nearest column's values. Built once per face.
    """
    ph, pw = opening.shape
    cols = np.flatnonzero(opening.any(0))
    out = plate.copy()
    if len(cols) == 0:
        return out
    top = np.argmax(opening, 0)
    bot = ph - 1 - np.argmax(opening[::-1], 0)
    mid = 0.5 * (top + bot)
    ref_t = np.minimum(np.rint(top + band_up), np.floor(mid)).astype(np.int64)
    ref_b = np.maximum(np.rint(bot - band_low), np.ceil(mid)).astype(np.int64)
    # (integers: np.clip's values without its overhead)
    ref_t = np.minimum(np.maximum(ref_t, 0), ph - 1)
    ref_b = np.minimum(np.maximum(ref_b, 0), ph - 1)
    jj = np.arange(pw)

    # the white of each column: its brighter part between the lids' shadow bands (the plate
    # has no iris), as bright as the sclera near the eye's middle
    yy = np.arange(ph, dtype=np.float32)[:, None]
    mid_rows = opening & (yy >= ref_t[None, :]) & (yy <= ref_b[None, :])
    mid_rows |= opening & ~mid_rows.any(0)[None, :]
    lum = plate @ np.array([0.299, 0.587, 0.114], np.float32)
    thr = _column_percentile(lum[:, cols], mid_rows[:, cols], 80)
    sel = np.zeros_like(opening)
    sel[:, cols] = mid_rows[:, cols] & (lum[:, cols] >= thr[None, :] - 1e-3)
    cnt = sel.sum(0)
    ok = cnt > 0
    ref = np.zeros((pw, 3), np.float32)
    ref[ok] = (plate * spread3(sel.view(np.uint8))).sum(0)[ok] / cnt[ok, None]
    for ch in range(3):
        ref[:, ch] = interp(jj, jj[ok], ref[ok, ch])
    ref = cv2.GaussianBlur(ref[None], (0, 0), max(0.8, 0.3 * r))[0]
    c_t = ref
    near = cols[np.abs(jj[:, None] - cols[None, :]).argmin(1)]
    ref_t, ref_b = ref_t[near], ref_b[near]
    # (the float64 colours rounded to float32 where they go, as before; the distance to the
    # reference row, float64: above the upper one, below the lower one, 0 between them,
    # where the plate is kept; whole-patch arithmetic, no gathers)
    d = np.maximum(np.maximum(ref_t[None, :] - yy, yy - ref_b[None, :]), 0.0)
    shade = 1.0 - BALL_SHADE * (1.0 - np.exp(-d / max(r, 1.0)))
    side = (yy < ref_t[None, :]) | (yy > ref_b[None, :])
    # (the float64 products rounded into ``out`` where ``side`` only, as a copy of the whole
    # product there would; the shade and the mask spread over the channels first: numpy's
    # broadcasting of (h, w, 1) arrays costs several times more)
    np.multiply(c_t[None, :, :], spread3(shade), out=out,
                where=spread3(side.view(np.uint8)) > 0, casting="same_kind")
    return out


def _complete_iris(src: np.ndarray, keep: np.ndarray, vis: np.ndarray, rho: np.ndarray,
                   r: float, r_fill: float, cy: float, soft: float = 1.0,
                   lum: np.ndarray | None = None) -> np.ndarray:
    """The iris disc with its hidden pixels completed from the visible ones (``vis``).

    Kept: the pixels in ``keep`` (the opening) and, inside the radius ``r``, photo pixels that
    look like the iris (no brighter than a third of the way from the iris's median luminance
    to the white's): the iris often shows a little above the detected lid line. The others
    take their vertical mirror about the iris centre row when that is visible and iris-like,
    else the mean of the iris-like visible pixels at the same radius (beyond ``r``: of all
    visible pixels there, the limbus and the white). On a soft photo (``soft`` > 1 px, the
    edge ramp of :func:`edge_ramp`) the lids' margins are dark gradients that wide, which
    look like iris: the disc is completed from the radial means alone (smoothed along the
    radius) and the photo's ``keep`` pixels fade into it over ``soft`` px.
    """
    ph, pw = vis.shape
    out = src.copy()
    if lum is None:  # (``src``'s luminance; the caller's when it has it)
        lum = src @ np.array([0.299, 0.587, 0.114], np.float32)
    core = vis & (rho <= 0.8 * r)
    if core.sum() >= 3 and vis.sum() >= 6:
        med, white = float(median(lum[core])), float(percentile(lum[vis], 90))
        like = lum <= med + max(white - med, 0.0) / 3.0
    else:
        like = np.ones(vis.shape, bool)
    disc = rho <= r
    strict = soft > 1.0
    near = rho <= r_fill + 1.5
    need = near if strict else near & ~keep & ~(like & disc)
    if not need.any():
        return out
    # (the mirror row of each row, broadcast over the columns: np.mgrid's values)
    if strict:
        mirror_ok = np.zeros_like(need)
    else:
        my = np.broadcast_to(clamp(np.rint(2 * cy - np.arange(ph)[:, None]), 0, ph - 1)
                             .astype(np.int64), (ph, pw))
        xx = np.broadcast_to(np.arange(pw)[None, :], (ph, pw))
        mirror_ok = need & vis[my, xx] & (like[my, xx] | ~disc)
        out[mirror_ok] = src[my[mirror_ok], xx[mirror_ok]]
    rest = need & ~mirror_ok
    if rest.any():
        bins = np.minimum((rho * 2).astype(np.int64), int(2 * (r_fill + 2)))
        nb = int(bins.max()) + 1
        sel = vis & (rho <= r_fill + 1.5) & (like | ~disc)
        cnt = np.bincount(bins[sel], minlength=nb)
        mean = np.zeros((nb, 3), np.float32)
        if cnt.any():
            okb = cnt > 0
            for ch in range(3):
                sm = np.bincount(bins[sel], src[..., ch][sel], minlength=nb)
                mean[:, ch] = interp(np.arange(nb), np.flatnonzero(okb), sm[okb] / cnt[okb])
            if strict:  # (smooth along the radius: half-pixel bins of a few samples each ring)
                mean[:] = cv2.GaussianBlur(mean[:, None, :], (1, 0), soft)[:, 0, :]
        else:
            mean[:] = np.percentile(src.reshape(-1, 3), 10, axis=0)
        out[rest] = mean[bins[rest]]
    if strict:
        # the photo's own iris where visible, handing over to the smooth completion across
        # the lids' blurred margins (a hard switch reads as a flat cut across the iris)
        # (over the box of ``near`` only: beyond it ``out`` is still the photo, as is the
        # blend's value; on the 1080p bench face's eyes ~15 % of the patch)
        rows, cols = np.flatnonzero(near.any(1)), np.flatnonzero(near.any(0))
        b = (slice(int(rows[0]), int(rows[-1]) + 1), slice(int(cols[0]), int(cols[-1]) + 1))
        dist = cv2.distanceTransform(keep.astype(np.uint8), cv2.DIST_L2, 3)[b]
        w = spread3(np.minimum(dist / soft, 1.0).astype(np.float32))
        o, s = out[b], src[b]
        out[b] = np.where(near[b][..., None], o + w * (s - o), s)
    return out


def _ramp(d: np.ndarray, sk: float) -> np.ndarray:
    """``d * sk + 0.5`` (the same values: on a sharp photo ``sk`` is 1, by which a product is
    exact, and the multiplication is skipped)."""
    if sk == 1.0:
        d += 0.5
        return d
    d *= sk
    d += 0.5
    return d


def _lid_bands(src: np.ndarray, plate: np.ndarray, iris: np.ndarray, rho: np.ndarray,
               r: float, soft: float, lids: tuple[np.ndarray, np.ndarray],
               org: tuple[float, float], axes: tuple[np.ndarray, np.ndarray],
               widths: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Two (h, w, 3) float32 maps, the upper lid's and the lower lid's: the photo over the bare
    eyeball (the completed iris over the white plate, at rest), per channel and clipped to
    [0, 1], in the band along that lid (``widths`` below the upper lid, above the lower one)
    and fading to 1 over the edge ramp ``soft``; 1 elsewhere. What the lid's margin, its lashes
    and their shadow take from the eyeball, to move with the lid when it opens. (Real sclera
    under the upper lid, JAFFE and the sample: 0.5 of its brightest over the first fifth of an
    iris radius, 0.87 over the next; the photo's mesh puts the lid line inside the lash band,
    so its lower half lies in the opening.) The lower lid's band ends at the upper lid's line,
    and across the iris it is completed from beside it, at the same height above the lid (see
    the comments below)."""
    ph, pw = rho.shape
    cover = clamp((r + 0.5 - rho) / soft + 0.5, 0.0, 1.0) if soft > 1.0 else \
        clamp(r + 1.0 - rho, 0.0, 1.0)
    a = spread3(cover.astype(np.float32))
    bare = plate + a * (iris - plate)
    # both smoothed (a shading field; the completed iris's edge is not exactly the photo's:
    # unsmoothed, the ratio along it carried black specks up over the white)
    sig = max(1.0, 0.5 * soft)
    src = cv2.GaussianBlur(src, (0, 0), sig)
    bare = cv2.GaussianBlur(bare, (0, 0), sig)
    # per channel (the lashes keep their brown over the white), its hue held within a quarter
    # of the luminance ratio (where the completed iris and the photo's differ in hue, free
    # channel ratios tinted the iris yellow)
    lum = np.array([0.299, 0.587, 0.114], np.float32)
    rl = spread3(clamp((src @ lum) / np.maximum(bare @ lum, 1.0), 0.0, 1.0))
    ratio = clamp(src / np.maximum(bare, 1.0), 0.75 * rl, np.minimum(1.25 * rl, 1.0))
    ex, ey = axes
    xs = np.arange(pw, dtype=np.float64) + org[0]
    ys = np.arange(ph, dtype=np.float64) + org[1]
    U = xs[None, :] * ex[0] + ys[:, None] * ex[1]
    W = xs[None, :] * ey[0] + ys[:, None] * ey[1]
    up, low = lids
    d_up = W - interp(U, up[:, 0], up[:, 1])  # depth below the upper lid
    d_lo = interp(U, low[:, 0], low[:, 1]) - W  # height above the lower lid
    ramp = max(soft, 1.0)
    # (one map per lid: each is sampled with its own lid's shift, which would carry the
    # other lid's band too)
    w_up = clamp((widths[0] + ramp - d_up) / ramp, 0.0, 1.0)
    # (the lower band ends at the upper lid's line: towards a corner the opening is narrower
    # than the band, which reached over the upper lid's lashes there, and a lowered lower lid
    # carried them down, a second shadow along a diagonal from the outer corner: the 4K bench
    # face's surprise)
    w_lo = clamp((widths[1] + ramp - d_lo) / ramp, 0.0, 1.0) \
        * clamp(d_up / ramp + 0.5, 0.0, 1.0)
    dark = 1.0 - ratio  # (float32, shared by both maps)
    dark_lo = dark
    b = r + ramp
    if low[0, 0] < -b and b < low[-1, 0]:
        # the lower lid's shading across the iris as beside it, at the same height above the
        # lid: the completed iris's edge is not exactly the photo's, and what the lid carries
        # down from there (the limbus read as shade) drew a dark streak or a yellow speck in
        # the white it uncovers under the iris (JAFFE YM at 4 x, the 4K bench face)
        near = (np.abs(U) < b) & (d_lo > -ramp) & (w_lo > 0.0)
        if near.any():
            rr, cc = np.flatnonzero(near.any(1)), np.flatnonzero(near.any(0))
            bx = (slice(int(rr[0]), int(rr[-1]) + 1), slice(int(cc[0]), int(cc[-1]) + 1))
            across = _beside_iris(np.ascontiguousarray(dark), low, org, axes, b, U[bx],
                                  -d_lo[bx])
            dark_lo = dark.copy()
            dark_lo[bx] = np.where(near[bx][..., None], across, dark[bx])
    return _band_map(w_up, dark), _band_map(w_lo, dark_lo)


def _band_map(wt: np.ndarray, dark: np.ndarray) -> np.ndarray:
    """``(1.0 - wt[..., None] * dark).astype(np.float32)`` (``wt`` (h, w) float64 in [0, 1],
    ``dark`` (h, w, 3) finite float32): computed over the box where ``wt`` is non-zero, 1
    beyond it (the same value: 1 - 0 x dark). A lid's band and what lies beyond the lid fill
    about half of an eye's patch."""
    out = np.ones(dark.shape, np.float32)
    rows = np.flatnonzero(wt.any(1))
    if len(rows):
        cols = np.flatnonzero(wt.any(0))
        b = (slice(int(rows[0]), int(rows[-1]) + 1), slice(int(cols[0]), int(cols[-1]) + 1))
        out[b] = 1.0 - spread3(wt[b]) * dark[b]
    return out


#: How far below the photo's lower lid (in edge ramps, at least :data:`MARGIN_MIN_PX`) the
#: iris's blur reaches into the lid's margin: :func:`_margin_diff` replaces it out to this
#: depth, fading out over as much again
MARGIN_DEPTH = 1.0
MARGIN_MIN_PX = 1.5


def _beside_iris(img: np.ndarray, low: np.ndarray, org: tuple[float, float],
                 axes: tuple[np.ndarray, np.ndarray], b: float, U: np.ndarray, e: np.ndarray
                 ) -> np.ndarray:
    """``img`` (h, w, 3) float32 over an eye's patch as it is beside the iris, at the points of
    frame coordinates ``U`` and depth ``e`` below the lower lid ``low`` (arrays of one shape;
    ``org``, ``axes`` as :func:`_lid_bands`'): per point, ``img`` at the same depth below the
    lid at ``u = -b`` and ``u = +b``, interpolated linearly in ``U`` between them."""
    ex, ey = axes
    side = []
    for u in (-b, b):
        w = float(interp(np.array([u]), low[:, 0], low[:, 1])[0]) + e
        mx = (u * ex[0] + w * ey[0] - org[0]).astype(np.float32)
        my = (u * ex[1] + w * ey[1] - org[1]).astype(np.float32)
        side.append(cv2.remap(img, mx, my, cv2.INTER_LINEAR, None, cv2.BORDER_REPLICATE))
    t = spread3(((U + b) / (2.0 * b)).astype(np.float32))
    return side[0] + t * (side[1] - side[0])


def _margin_diff(src: np.ndarray, low: np.ndarray, org: tuple[float, float],
                 axes: tuple[np.ndarray, np.ndarray], r: float, soft: float
                 ) -> tuple[np.ndarray, tuple[int, int]] | None:
    """What the photo's lower lid margin under the iris lacks of a margin under the white:
    (h, w, 3) float32 over the box of the eye's patch ``src`` (h', w', 3) float32 where it is
    not zero, and that box's top-left corner on the patch; or None (the
    iris too near a corner to see the margin on both sides of it).

    Where the iris reaches down to the lower lid, the photo's blur mixes its dark brown into
    the lid's margin below it (over about the edge ramp ``soft``); the warp carries that
    margin down with a lowered lid, and under the white it then uncovers the margin reads as
    a grey-brown seam (the 4K bench face's surprise at 150 %: a dip of 16 % of the white
    where the photo's own lower lid beside the iris shows 8-10 %; 7 % with this and the lower
    band's completion across the iris in :func:`_lid_bands`). The margin the white would
    meet is the one either side of the iris: per depth ``e`` below the lid (frame
    coordinates, ``low`` the lower lid's (7, 2) points about the iris centre, ``org`` the
    patch's top-left corner in them, ``axes`` the frame's (ex, ey)), the photo at
    ``u = -b`` and ``u = +b`` (``b = r + max(soft, 1)``, clear of the iris's blur), interpolated
    linearly along ``u`` in between, both smoothed along the image rows by 0.3 ``r`` (the
    stain is as wide as the iris; the margin's own finer texture, its lower lashes, stays:
    the frame's u is the rows' direction up to the head's roll). The difference to the photo
    is kept down to :data:`MARGIN_DEPTH` ramps below the lid, fading out over as much again,
    and over one pixel above it (inside the opening, the iris itself: the eyeball covers
    it). :func:`layers._lower_margin` carries it through the warp once the lid is lowered."""
    b = r + max(soft, 1.0)
    lu = low[:, 0]
    if not (lu[0] < -b and b < lu[-1]):
        return None
    ph, pw = src.shape[:2]
    ex, ey = axes
    xs = np.arange(pw, dtype=np.float64) + org[0]
    ys = np.arange(ph, dtype=np.float64) + org[1]
    U = xs[None, :] * ex[0] + ys[:, None] * ex[1]
    W = xs[None, :] * ey[0] + ys[:, None] * ey[1]
    e = W - interp(U, lu, low[:, 1])  # depth below the photo's lower lid
    reach = max(MARGIN_DEPTH * soft, MARGIN_MIN_PX)
    wt = clamp(np.minimum(2.0 - e / reach, 1.0 + e), 0.0, 1.0) * (np.abs(U) < b)
    rows, cols = np.flatnonzero(wt.any(1)), np.flatnonzero(wt.any(0))
    if not len(rows):
        return None
    bx = (slice(int(rows[0]), int(rows[-1]) + 1), slice(int(cols[0]), int(cols[-1]) + 1))
    Ub, eb = U[bx], e[bx]
    # (along the lid only the iris's stain is replaced, which is as wide as the iris: the
    # margin's finer texture, lower lashes and pores, stays; across it the margin's profile)
    sig = max(1.0, 0.3 * r)
    lp = cv2.GaussianBlur(src, (2 * int(math.ceil(3.0 * sig)) + 1, 1), sig)
    clean = _beside_iris(lp, low, org, axes, b, Ub, eb)
    out = (clean - lp[bx]) * spread3(wt[bx].astype(np.float32))  # (the support's box only)
    return np.ascontiguousarray(out, np.float32), (int(cols[0]), int(rows[0]))


@dataclass(eq=False)
class EyePlan:
    """Precomputed eyeball of one eye (see module docstring)."""

    name: str
    hole: np.ndarray  # vertex loop of the opening
    detected: np.ndarray  # (2,) iris centre of the landmarks (= neutral FDP 3.5/3.6)
    r_det: float  # iris radius of the landmarks (the one deform.eye_state scales)
    centre: np.ndarray  # (2,) iris centre refined from its edges, image px
    r0: float  # iris radius refined from its edges
    p0: float  # neutral pupil radius (deform.eye_state with zero FAPs)
    ex: np.ndarray
    ey: np.ndarray
    off: np.ndarray  # (2,) image position of plate[0, 0]
    plate: np.ndarray  # (h, w, 3) float32 white of the eye
    photo: np.ndarray  # (h, w, 3) float32 the photo over the same patch
    iris: np.ndarray  # (h, w, 3) float32 completed iris (valid inside r_fill + 1)
    split_r: tuple[np.ndarray, np.ndarray]  # split line for gaze right (frame, iris-centred)
    split_l: tuple[np.ndarray, np.ndarray]
    corner_l: np.ndarray  # image-left eye corner (frame, iris-centred)
    corner_r: np.ndarray
    lim_r: float  # u of the clamp line c-d at the iris height
    lim_l: float
    pupil: np.ndarray  # (3,) colour of the photo's pupil
    iris_lum: float  # median luminance of the visible iris
    ball: np.ndarray  # (h, w, 3) float32 the white continued past the lids (_ball_white)
    band_up: float  # width of the upper lid's shadow band inside the opening, px
    lash: np.ndarray  # (3,) colour of the upper lash line (dark end along the upper lid)
    area0: float  # neutral area of the opening, px^2
    band_low: float
    lid_up: np.ndarray  # (7, 2) neutral upper lid c0, u1..u5, c1 (frame, iris-centred)
    lid_low: np.ndarray  # (7, 2) neutral lower lid c0, d1..d5, c1
    widths: tuple[float, ...] = ()  # this eye's limbus_widths
    #: (h, w, 3) float32 x 2, the upper and the lower lid's: the photo's band along that lid
    #: (the lashes and margin hanging over the eyeball, their shadow) as a share of the bare
    #: eyeball (<= 1), 1 elsewhere (see :func:`_lid_bands`): the shadow an opened lid casts
    bands: tuple[np.ndarray, ...] = ()
    #: (h, w, 3) float32 or None: :func:`_margin_diff`, the lower lid margin under the iris
    #: as it would be under the white (a difference to the photo), over the box of the image
    #: whose top-left corner is :attr:`margin_at`
    margin: np.ndarray | None = None
    margin_at: tuple[int, int] = (0, 0)

    def __post_init__(self) -> None:
        self._exy = np.stack([self.ex, self.ey], 1)  # image offset -> frame (u, w)
        # (per-face constants of :meth:`render`, shaped for its stacked arrays)
        self._ex3, self._ey4 = self.ex[:, None, None], self.ey[:, None, None, None]
        self._o3 = (self.centre - self.off)[:, None, None]  # the iris centre on the patch
        self._band_off = np.array([self.band_up, self.band_low])[:, None, None]
        # the neutral lids' heights between the corners (:meth:`lid_opening`)
        self._lid_w = (self.lid_up[1:-1, 1].tolist(), self.lid_low[1:-1, 1].tolist())
        # the neutral lower lid's segment under the iris centre (u = 0): its first vertex
        # (:meth:`lowered`)
        self._mid_seg = j = int(np.clip(np.searchsorted(self.lid_low[:, 0], 0.0) - 1, 0,
                                        len(self.lid_low) - 2))
        # and its height at u = 0
        (r0, s0), (r1, s1) = self.lid_low[j:j + 2].tolist()
        self._low_rest = s0 + (s1 - s0) * (0.0 - r0) / (r1 - r0) if r1 != r0 else s0
        # the patches :meth:`_render` resamples, as 4 channels (zero_alpha: the 4th never
        # read; :func:`_rgb` drops it): OpenCV's 4-channel float remap plus the copy back to
        # 3 channels costs about half its 3-channel remap (the same values per channel;
        # ~12 vs 23 us on the 4K bench face's eye blocks)
        # (and as 3 channels: on small boxes one 3-channel remap costs less, :func:`sample_rgb`)
        self._plate3, self._photo3, self._ball3, self._iris3 = (
            np.ascontiguousarray(a, np.float32)
            for a in (self.plate, self.photo, self.ball, self.iris))
        self._plate4, self._photo4, self._ball4, self._iris4 = (
            zero_alpha(a) for a in (self._plate3, self._photo3, self._ball3, self._iris3))
        self._bands3 = tuple(np.ascontiguousarray(b, np.float32) for b in self.bands)
        self._bands4 = tuple(zero_alpha(b) for b in self._bands3)

    @classmethod
    def build(cls, image: np.ndarray, vertices: np.ndarray, hole: np.ndarray, name: str,
              iris: tuple[float, float, float], frame_rot: np.ndarray) -> EyePlan:
        cx, cy, r = (float(x) for x in iris)
        r = max(r, 1.0)
        detected, r_det = np.array([cx, cy]), r
        ex, ey = frame_rot[:, 0].astype(np.float64), frame_rot[:, 1].astype(np.float64)
        poly = vertices[hole].astype(np.float64)
        h, w = image.shape[:2]
        m = int(np.ceil(2.0 * r)) + 4
        x0 = int(max(0, np.floor(poly[:, 0].min()) - m))
        y0 = int(max(0, np.floor(poly[:, 1].min()) - m))
        x1 = int(min(w, np.ceil(poly[:, 0].max()) + m + 1))
        y1 = int(min(h, np.ceil(poly[:, 1].max()) + m + 1))
        patch = np.ascontiguousarray(image[y0:y1, x0:x1])
        ph, pw = patch.shape[:2]
        opening = np.zeros((ph, pw), np.uint8)
        cv2.fillPoly(opening, [np.round((poly - (x0, y0)) * 16).astype(np.int32)], 1,
                     cv2.LINE_8, 4)
        cx, cy, r = _iris_edges(patch, opening, cx - x0, cy - y0, r, ex, ey)
        widths = tuple(limbus_widths(patch, opening, cx, cy, r, ex, ey))
        soft = edge_ramp(list(widths), r)  # (this eye's; the face's pooled one renders)
        cx, cy = cx + x0, cy + y0
        rho = np.hypot((np.arange(pw, dtype=np.float64) + x0 - cx)[None, :],
                       (np.arange(ph, dtype=np.float64) + y0 - cy)[:, None])
        r_fill = r + max(1.5, 0.3 * r)  # the limbus and its blur go too (no ring remnant)
        inside = opening > 0
        d_lid = cv2.distanceTransform(opening, cv2.DIST_L2, 3)  # (the plate's and the margin's)
        plate = _white_plate(patch, inside, rho, r_fill, r, soft, d_lid)
        # iris sprite: visible = inside the opening, one pixel clear of the lid edge
        vis = cv2.erode(opening, np.ones((3, 3), np.uint8)) > 0
        src = patch.astype(np.float32)
        # (on a soft photo the lids' blurred margins inside the opening are hidden too)
        e = int(math.ceil(0.5 * soft))
        kept = opening > 0 if soft <= 1.0 else \
            cv2.erode(opening, np.ones((2 * e + 1, 2 * e + 1), np.uint8)) > 0
        lum = src @ np.array([0.299, 0.587, 0.114], np.float32)
        out = _complete_iris(src, kept, vis & kept, rho, r, r_fill, cy - y0, soft, lum)
        # for a raised lid: the bands along the lids (their shadow, the lashes) replaced too
        band_up, band_low = max(2.5, 0.5 * r), max(1.5, 0.25 * r)
        ball = _ball_white(plate, inside, r, band_up, band_low)
        if soft > 1.0:
            # the photo's white hands over to the ball over the lid margin's blur (a hard
            # switch at the photo's opening shows as a line where the lid was)
            m = np.minimum(d_lid / soft, 1.0)
            plate = ball + spread3(m.astype(np.float32)) * (plate - ball)
        else:
            plate = np.where(inside[..., None], plate, ball)
        # corner / 1/5 points in frame coordinates centred on the iris
        names_u = [0, 1, 2, 3, 4, 5, 6]
        loop = poly
        up = loop[names_u]  # c0, u1..u5, c1
        lo = loop[[0, 11, 10, 9, 8, 7, 6]]  # c0, d1..d5, c1
        c = np.array([cx, cy])

        def fr(p: np.ndarray) -> np.ndarray:
            d = np.atleast_2d(p) - c
            f = np.empty(d.shape)  # (np.stack's values without its overhead)
            f[:, 0], f[:, 1] = d @ ex, d @ ey
            return f

        upf, lof = fr(up), fr(lo)
        a, b = _lid_point(upf, 0.2), _lid_point(lof, 0.2)
        cc, dd = _lid_point(upf, 0.8), _lid_point(lof, 0.8)
        # the paper's 1/5 points, or the iris edge when the iris reaches into a corner triangle
        split_r = (a, b) if _line_u(a, b, 0.0) <= -r else (
            np.array([-r, a[1]]), np.array([-r, b[1]]))
        split_l = (cc, dd) if _line_u(cc, dd, 0.0) >= r else (
            np.array([r, cc[1]]), np.array([r, dd[1]]))
        p0 = r / 3.0
        core = vis & (rho <= 0.6 * r)
        ring = vis & (rho <= r)
        if core.sum() >= 3 and ring.sum() >= 3:
            k = core & (lum <= percentile(lum[core], 25))
            pupil = masked_rows(src, k).mean(0)
            iris_l = float(median(lum[ring]))
        else:
            pupil, iris_l = np.full(3, 20.0, np.float32), 60.0
        # the lash line: the darkest fifth of a 2-px band along the upper lid, above it
        up_mask = np.zeros((ph, pw), np.uint8)
        upl = np.round((up - (x0, y0)) * 16).astype(np.int32)
        cv2.polylines(up_mask, [upl], False, 1, max(2, int(round(0.3 * r))), cv2.LINE_8, 4)
        band = (up_mask > 0) & (opening == 0)
        if band.sum() >= 5:
            lb = lum[band]
            lash = masked_rows(src, band)[lb <= percentile(lb, 20)].mean(0)
        else:
            lash = np.full(3, 30.0, np.float32)
        x, y = poly[:, 0], poly[:, 1]
        yn, xn = np.concatenate((y[1:], y[:1])), np.concatenate((x[1:], x[:1]))  # (np.roll)
        area0 = 0.5 * abs(float(np.dot(x, yn) - np.dot(y, xn)))
        bands = _lid_bands(src, plate, out, rho, r, soft, (upf, lof),
                           (x0 - cx, y0 - cy), (ex, ey), (band_up, band_low))
        got = _margin_diff(src, lof, (x0 - cx, y0 - cy), (ex, ey), r, soft)
        margin, margin_at = (None, (0, 0)) if got is None else \
            (got[0], (got[1][0] + x0, got[1][1] + y0))
        return cls(bands=bands, margin=margin, margin_at=margin_at, ball=ball,
                   lash=lash.astype(np.float32), area0=area0, band_up=band_up,
                   band_low=band_low, lid_up=upf, lid_low=lof,
                   pupil=pupil.astype(np.float32), iris_lum=iris_l, name=name,
                   hole=np.asarray(hole), detected=detected, r_det=r_det, centre=c,
                   r0=r, p0=p0, ex=ex, ey=ey, off=np.array([x0, y0], np.float64), plate=plate,
                   photo=src,  # (the float32 patch: nothing above changes it)
                   iris=out, split_r=split_r, split_l=split_l, corner_l=upf[0],
                   corner_r=upf[-1], lim_r=float(_line_u(cc, dd, 0.0)),
                   lim_l=float(_line_u(a, b, 0.0)), widths=widths)

    # ------------------------------------------------------------------ per frame
    def gaze_shift(self, iris_dst: np.ndarray, sim: np.ndarray) -> np.ndarray:
        """(Δu, Δw) of the iris in the neutral eye's frame, Δu clamped at c-d / a-b.

        The clamp holds the iris *centre* on the near side of the line c-d (a-b for gaze
        left), so the iris may enter the corner triangle by up to its radius, where the lids
        clip it. SPEC §3.2 keeps the whole iris out; on real photos (the irises sit nasally,
        converging on the camera) that leaves 0.4-2.5 px of travel, different for the two
        eyes, and a common gaze then makes the eyes diverge.
        """
        inv = cv2.invertAffineTransform(np.asarray(sim, np.float64))
        n = inv[:, :2] @ np.asarray(iris_dst, np.float64) + inv[:, 2]
        d = n - self.detected
        du, dw = float(d @ self.ex), float(d @ self.ey)
        if du > 0:
            du = min(du, max(0.0, self.lim_r))
        elif du < 0:
            du = max(du, min(0.0, self.lim_l))
        return np.array([du, dw])

    def lid_frame(self, poly: np.ndarray, sim: np.ndarray, inv: np.ndarray | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
        """Deformed opening ``poly`` (output px) as upper / lower lid lines (7, 2) in the
        neutral eye's frame (iris-centred), through the inverse of ``sim`` (``inv`` when the
        caller has it already)."""
        if inv is None:
            inv = cv2.invertAffineTransform(np.asarray(sim, np.float64))
        n = np.asarray(poly, np.float64) @ inv[:, :2].T + inv[:, 2] - self.centre
        f = n @ self._exy
        # (one take of both lids' rows: fancy indexing of rows costs more)
        lids = f.take(_UP_LOW, 0)
        return lids[:7], lids[7:]

    def lid_opening(self, poly: np.ndarray, sim: np.ndarray,
                    lids: tuple[np.ndarray, np.ndarray] | None = None) -> float:
        """How far (px, neutral frame) the lids moved away from the eye's centre at most:
        > 0 when an upper lid was raised or a lower lid lowered. ``lids``: the
        :meth:`lid_frame` of ``poly`` and ``sim`` when the caller has it already."""
        up, low = self.lid_frame(poly, sim) if lids is None else lids
        # (five values a lid: Python floats, the same float64 differences and maximum)
        return max(max(a - b, c - d) for a, b, c, d in zip(
            self._lid_w[0], up[1:-1, 1].tolist(), low[1:-1, 1].tolist(), self._lid_w[1],
            strict=True))

    def lowered(self, low: np.ndarray) -> float:
        """How far (px, neutral frame) the deformed lower lid ``low`` (:meth:`lid_frame`'s)
        lies below the neutral one under the iris centre: each lid's height at u = 0 on the
        neutral lid's segment there (Python floats: ``np.interp``'s calls cost more)."""
        j = self._mid_seg
        (u0, w0), (u1, w1) = low[j:j + 2].tolist()
        now = w0 + (w1 - w0) * (0.0 - u0) / (u1 - u0) if u1 != u0 else w0
        return now - self._low_rest

    def render(self, box: tuple[int, int, int, int], sim: np.ndarray, shift: np.ndarray,
               r_new: float, p_new: float, poly: np.ndarray | None = None,
               lids: tuple[np.ndarray, np.ndarray] | None = None,
               inv: np.ndarray | None = None, soft: float = 1.0, q: int = 1,
               whole: tuple[int, int, int, int] | None = None) -> np.ndarray:
        """Colours (h, w, 3) float32 of the eyeball over ``box`` of the output image (see
        :meth:`_render`); ``q`` > 1: evaluated at the centres of the box's ``q x q`` blocks
        and upsampled bilinearly (a soft photo's eye, whose edges ramp over several times
        ``q`` px: the bench's 4K face, 15 px, at ``q`` 2 in a third of the time). ``whole``
        (with ``q`` 1): the box that ``box`` is part of; its pixels decide whether each lid
        moved (:meth:`_render`), so that the part's colours are the whole's there."""
        x0, y0, x1, y1 = box
        if q <= 1:
            return self._render(np.arange(x0, x1, dtype=np.float64),
                                np.arange(y0, y1, dtype=np.float64), sim, shift, r_new, p_new,
                                poly, lids, inv, soft, whole)
        hq, wq = -(-(y1 - y0) // q), -(-(x1 - x0) // q)
        c = 0.5 * (q - 1)  # (block k's centre: pixel x0 + k q + c, where cv2.resize puts it)
        col = self._render(x0 + c + q * np.arange(wq, dtype=np.float64),
                           y0 + c + q * np.arange(hq, dtype=np.float64), sim, shift, r_new,
                           p_new, poly, lids, inv, soft)
        up = cv2.resize(col, (wq * q, hq * q), None, 0, 0, cv2.INTER_LINEAR)
        return np.ascontiguousarray(up[:y1 - y0, :x1 - x0], np.float32)

    def _render(self, xs: np.ndarray, ys: np.ndarray, sim: np.ndarray, shift: np.ndarray,
                r_new: float, p_new: float, poly: np.ndarray | None = None,
                lids: tuple[np.ndarray, np.ndarray] | None = None,
                inv: np.ndarray | None = None, soft: float = 1.0,
                whole: tuple[int, int, int, int] | None = None) -> np.ndarray:
        """Colours (h, w, 3) float32 of the eyeball at the points (``xs``, ``ys``: the output
        image's columns and rows, float64).

        ``r_new``, ``p_new``: iris and pupil radii from :func:`deform.eye_state` (they are
        rescaled to the edge-refined iris radius). ``poly``: the deformed opening (output px);
        where its upper lid is above the neutral one (a raised lid) or its lower lid below, the
        white is continued there (:attr:`ball`; the iris sprite is complete anyway): the
        photo's shadow band along that lid is replaced by it as well (the shadow travels with
        the lid; the iris keeps its own pixels and catch-lights) and the raised upper lid casts
        a soft shadow on what it uncovers. Each column fades in over its lid's first
        pixel of motion. ``lids``: :meth:`lid_frame` of ``poly`` and ``sim`` if already known,
        ``inv`` the inverse of ``sim``. ``soft``: the face's edge ramp (px,
        ``layers.LayerPlan.soft``) over which the iris and the white's lid bands blend.
        ``whole``: the output box the points are part of (:meth:`render`).
        """
        k = self.r0 / self.r_det
        r_new, p_new = r_new * k, p_new * k
        if inv is None:
            inv = cv2.invertAffineTransform(np.asarray(sim, np.float64))
        ex, ey = self.ex, self.ey
        du, dw = float(shift[0]), float(shift[1])
        still = not abs(du) > 1e-6  # the white is not stretched
        # (u, w) of every pixel: affine in x and y, so one row plus one column each (u and
        # w stacked: rows (2, w), columns (2, h); the same values as each alone)
        cu = self._exy.T @ inv[:, :2]  # (u, w) per unit of x (column 0) and of y (column 1)
        c0 = (inv[:, 2] - self.centre) @ self._exy
        if still:
            # an unmoved white is the photo patch through the inverse similarity (ex, ey are
            # orthonormal: centre + U ex + W ey is the inverse-mapped pixel): its (x, y) on
            # the patch, affine too, stacked with (u, w) (rows (4, w), columns (4, h))
            cu = np.concatenate((cu, inv[:, :2]))
            c0 = np.concatenate((c0, inv[:, 2] - self.off))
        grid = (cu[:, 0, None] * xs + c0[:, None])[:, None, :] + (cu[:, 1, None] * ys)[:, :, None]
        U, W = grid[0], grid[1]
        ox = self.centre[0] - self.off[0]
        oy = self.centre[1] - self.off[1]
        if not still:
            # the white: stretch / translate horizontally
            p, q = self.split_r if du > 0 else self.split_l
            corner = self.corner_l if du > 0 else self.corner_r
            bound = _line_u(p, q, W) + du
            moved = (U >= bound) if du > 0 else (U <= bound)
            dst = np.array([corner, p + (du, 0.0), q + (du, 0.0)], np.float32)
            src = np.array([corner, p, q], np.float32)
            A = cv2.getAffineTransform(dst, src).astype(np.float64)
            Ua = A[0, 0] * U + A[0, 1] * W + A[0, 2]
            Wa = A[1, 0] * U + A[1, 1] * W + A[1, 2]
            Us = np.where(moved, U - du, Ua)
            Ws = np.where(moved, W, Wa)
            mx = (ox + Us * ex[0] + Ws * ey[0]).astype(np.float32)
            my = (oy + Us * ex[1] + Ws * ey[1]).astype(np.float32)
        else:  # (the patch's x and y, computed with u and w)
            mx, my = grid[2:].astype(np.float32)
        # at rest the white is the photo itself (the composite is then exactly the photo); it
        # turns into the clean plate within the first pixel of motion or radius change
        t = max(abs(du), abs(dw), 2.0 * abs(r_new - self.r0))
        # (a plate weight below 1e-18, i.e. a change under 1e-9 px such as the radius rescaled
        # to the refined one with a rounding error of 1e-16 px: the photo, without a blend)
        t = t * t * (3.0 - 2.0 * t) if t < 1.0 else 1.0
        if t < 1e-18:
            t = 0.0
        # (the plate and the photo's white mixed in the channel count :func:`sample_rgb` reads)
        plate, photo = ((self._plate3, self._photo3) if mx.size < REMAP3_PX
                        else (self._plate4, self._photo4))
        mixed = plate if t >= 1.0 else photo if t <= 0.0 else photo + t * (plate - photo)
        white = sample_rgb(mixed, mixed, mx, my)
        # opened lids: per pixel, how far its column's lid moved away and the weight of the
        # photo / plate there (0 in the shadow band of a moved lid and beyond the old lid)
        keep = None
        band3: np.ndarray | None = None  # (h, w, 3) the photo's lid bands, moved
        below_fade = None  # (h, w) the iris's weight under the photo's lowered lower lid
        if poly is not None:
            up, low = self.lid_frame(poly, sim, inv) if lids is None else lids
            su, sl = self.lid_up, self.lid_low
            w_up = interp(U, up[:, 0], up[:, 1])
            w_up0 = interp(U, su[:, 0], su[:, 1])
            w_lo0 = interp(U, sl[:, 0], sl[:, 1])
            w_lo = interp(U, low[:, 0], low[:, 1])
            # both lids at once, rows (upper, lower) (the same values as lid by lid): how far
            # each column's lid moved away (frame px) and its fade-in
            dd = np.empty((2, *U.shape))
            np.subtract(w_up0, w_up, out=dd[0])
            np.subtract(w_lo, w_lo0, out=dd[1])
            # (smooth01's values, its clamp one clip ufunc; dd itself is read below)
            ss = clip(dd, 0.0, 1.0)
            ss = ss * ss * (3.0 - 2.0 * ss)
            up_moved, low_moved = bool(np.count_nonzero(ss[0])), bool(np.count_nonzero(ss[1]))
            if whole is not None and not (up_moved and low_moved):
                # a lid counts as moved when it moved over any pixel of the whole box (it
                # decides the blend of every pixel), not only over these
                up_moved, low_moved = self._moved_over(whole, cu, c0, (up, low),
                                                       (up_moved, low_moved))
            if low_moved:
                # the iris that a lowered lower lid uncovers (hidden under the photo's lid, the
                # completed sprite's) fades in over the lid's first pixel of motion, as the
                # white does: a lid lowered by a fraction of a pixel in its middle uncovered a
                # dark speck of its limbus under the iris (the sample's fear)
                below_fade = np.where(W > w_lo0, ss[1], 1.0)
            if up_moved or low_moved:
                # per lid 1 - s (1 - the white's weight past the lid's band), the moved lids'
                # product (a lid that did not open contributes a factor of exactly 1: skipped)
                kk = np.empty_like(dd)
                np.subtract(W, w_up0, out=kk[0])
                np.subtract(w_lo0, W, out=kk[1])
                kk -= self._band_off  # (band_up, band_low)
                # 1 - ss (1 - clip(ramp)), in place (the same float64 operations)
                clip(_ramp(kk, 1.0 / soft), 0.0, 1.0, out=kk)
                np.subtract(1.0, kk, out=kk)
                kk *= ss
                np.subtract(1.0, kk, out=kk)
                keep = (kk[0] * kk[1] if low_moved else kk[0]) if up_moved else kk[1]
                keep = keep.astype(np.float32)
                ball = sample_rgb(self._ball3, self._ball4, mx, my)
                # (weights spread over the channels with cv2.merge: numpy's broadcasting of
                # (h, w, 1) over 3 channels is several times slower on these small boxes)
                white -= ball
                white *= spread3(keep)
                white += ball
                # the photo's own bands ride with their lids: a pixel at depth d below the
                # raised upper lid (above the lowered lower one) takes the band's share at depth
                # d below the photo's lid (the lashes' lower half, which lay inside the photo's
                # opening, and their shadow; not wiped off with the white). The pixel's image
                # position is ox + U ex + Wb ey: its U part is the same for both lids
                # (x and y stacked, then both lids: the U part (2, h, w), the maps (2, 2, h, w))
                bu = U * self._ex3 + self._o3  # (ox, oy)
                wb = np.empty_like(dd)  # rows: W + d_up, W - d_lo (both lids' maps at once)
                np.add(W, dd[0], out=wb[0])
                np.subtract(W, dd[1], out=wb[1])
                bx, by = (bu[:, None] + wb * self._ey4).astype(np.float32)
                # the moved lids' bands sampled into one (n, h, w, 3) array, then for all n at
                # once 1 - s (1 - got) in float64, s spread over the channels with one
                # cv2.merge of the lids' rows (numpy's broadcasting of (h, w, 1) is several
                # times slower here); the lids' minimum (the same values as lid by lid)
                lids_moved = [j for j, m in enumerate((up_moved, low_moved)) if m]
                n, (h, w) = len(lids_moved), U.shape
                got = np.empty((n, h, w, 3), np.float32)
                for i, j in enumerate(lids_moved):
                    sample_rgb(self._bands3[j], self._bands4[j], bx[j], by[j], got[i])
                np.subtract(1.0, got, out=got)
                s_rows = (ss if n == 2 else ss[lids_moved[0]]).reshape(n * h, w)
                s3 = spread3(s_rows)
                s3 *= got.reshape(n * h, w, 3)
                got = np.subtract(1.0, s3, out=s3).astype(np.float32).reshape(n, h, w, 3)
                band3 = got[0] if n == 1 else np.minimum(got[0], got[1])
        # the iris: rigid, round, radially rescaled for thrust and pupil size
        Di = U - du if du else U
        Dw = W - dw if dw else W
        rho = np.sqrt(Di * Di + Dw * Dw)
        # the limbus blur is part of the iris: a ramp of ``soft`` px centred half a pixel out
        a = clip(r_new + 1.0 - rho, 0.0, 1.0) if soft == 1.0 else \
            clamp((r_new + 0.5 - rho) / soft + 0.5, 0.0, 1.0)
        if below_fade is not None:
            a = a * below_fade
        if not np.count_nonzero(a):
            return white if band3 is None else white * band3
        pn, pn0 = p_new / max(r_new, 1e-6), self.p0 / self.r0
        pn = min(max(pn, 0.02), 0.95)
        if du == 0.0 and dw == 0.0 and abs(r_new - self.r0) <= 1e-9 * self.r0 \
                and abs(pn - pn0) <= 1e-12:
            # the iris as in the photo (no gaze, thrust or pupil change): the radial map is
            # the identity, the sprite is sampled where the white is
            ix, iy = mx, my
        else:
            rn = rho / max(r_new, 1e-6)
            rs = np.where(rn < pn, rn * pn0 / pn,
                          pn0 + (rn - pn) * (1.0 - pn0) / (1.0 - pn)) * self.r0
            k = rs / np.maximum(rho, 1e-6)
            ix = (ox + k * (Di * ex[0] + Dw * ey[0])).astype(np.float32)
            iy = (oy + k * (Di * ex[1] + Dw * ey[1])).astype(np.float32)
        iris = sample_rgb(self._iris3, self._iris4, ix, iy)
        p_rest = self.p0 * r_new / self.r0
        if p_new > p_rest:
            # a dilated pupil: the photo's pupil, radially stretched, may be faint (brown
            # irises); a dark disc of the pupil's colour fades in, sparing the catch-lights
            w = min((p_new - p_rest) / max(1.0, 0.3 * p_rest), 1.0)
            ap: np.ndarray = clamp(p_new + 0.5 - rho, 0.0, 1.0).astype(np.float32) * w
            # catch-lights are reflections on the cornea: they keep their size while the
            # pupil grows, so they are found on the iris without the pupil's radial stretch
            # (the stretched sprite spreads a central catch-light over the new pupil)
            k0 = (self.r0 / max(r_new, 1e-6))
            plain = _rgb(cv2.remap(self._iris4,
                                   (ox + k0 * (Di * ex[0] + Dw * ey[0])).astype(np.float32),
                                   (oy + k0 * (Di * ex[1] + Dw * ey[1])).astype(np.float32),
                                   cv2.INTER_LINEAR, None, cv2.BORDER_REPLICATE))
            lum = plain @ np.array([0.299, 0.587, 0.114], np.float32)
            ap *= 1.0 - np.clip((lum - 1.3 * self.iris_lum) / (0.3 * self.iris_lum + 1.0),
                                0.0, 1.0)
            ap = spread3(ap)
            iris = iris * (1.0 - ap) + self.pupil * ap
        a = a.astype(np.float32)
        col = iris - white  # a iris + (1 - a) white (white is this frame's own array)
        col *= spread3(a)
        col += white
        if band3 is not None:
            col *= band3
        return col

    def _moved_over(self, box: tuple[int, int, int, int], cu: np.ndarray, c0: np.ndarray,
                    lids: tuple[np.ndarray, np.ndarray], seen: tuple[bool, bool]
                    ) -> tuple[bool, bool]:
        """Whether the upper and the lower lid moved over some pixel of ``box`` (``seen``:
        already found moving over a part of it): :meth:`_render`'s test (``ss`` non-zero),
        over the box's frame u (``cu``, ``c0``: its row and column parts, the same values)."""
        x0, y0, x1, y1 = box
        U = (cu[0, 0] * np.arange(x0, x1, dtype=np.float64) + c0[0])[None, :] \
            + (cu[0, 1] * np.arange(y0, y1, dtype=np.float64))[:, None]
        out = list(seen)
        for k, (now, rest) in enumerate(zip(lids, (self.lid_up, self.lid_low), strict=True)):
            if out[k]:
                continue
            w, w0 = interp(U, now[:, 0], now[:, 1]), interp(U, rest[:, 0], rest[:, 1])
            ss = clip(w0 - w if k == 0 else w - w0, 0.0, 1.0)
            out[k] = bool(np.count_nonzero(ss * ss * (3.0 - 2.0 * ss)))
        return out[0], out[1]

    def lash_fade(self, poly: np.ndarray) -> float:
        """How far the lash line of the opening ``poly`` (its 12 vertices, deformed) has faded
        in: 0 up to a closure c (1 - its area over the neutral one) of 0.6, 1 from 0.9."""
        x, y = poly[:, 0].astype(np.float64), poly[:, 1].astype(np.float64)
        nxt = _NEXT if len(poly) == len(_NEXT) else np.roll(np.arange(len(poly)), -1)
        area = 0.5 * abs(float(np.dot(x, y[nxt]) - np.dot(y, x[nxt])))
        c = 1.0 - area / max(self.area0, 1e-6)
        if c <= 0.6:
            return 0.0
        return float(smooth01(np.array((c - 0.6) / 0.3)))

    def lash_line(self, box: tuple[int, int, int, int], poly: np.ndarray, soft: float = 1.0
                  ) -> tuple[np.ndarray, np.ndarray] | None:
        """A closing eye's lash line over ``box``: (alpha (h, w) float32, colour (3,)), or None.

        The opening's area against the neutral one gives the closure c; from c = 0.6 to 0.9
        a dark line fades in along the deformed upper lid's edge (where the lids meet when
        closed; a Catmull-Rom curve through its vertices: the polyline's corners showed on large
        faces), ``0.35 r`` thick in the middle (at least 1.2 px) tapering to 40 % at the
        corners, in the photo's lash colour, its edges as soft as the photo's (``soft``: the
        photo's edge ramp, px; anti-aliased over a pixel on a sharp photo). It replaces the
        stretched, broken lash and lid-margin texture of the warp by one clean, curved line.
        """
        fade = self.lash_fade(poly)
        if fade <= 0.0:  # no closure yet: no lash line
            return None
        x0, y0, x1, y1 = box
        up = np.asarray(poly, np.float64)[_UP]
        # the upper lid's margin (where the lids meet once closed), three segments per edge
        line = catmull_rom(up, 3 * (len(up) - 1) + 1)
        px = np.arange(x0, x1, dtype=np.float64)[:, None, None]
        py = np.arange(y0, y1, dtype=np.float64)[None, :, None]
        a, b = line[:-1], line[1:]  # segments
        d = b - a
        L2 = np.maximum((d * d).sum(1), 1e-9)
        tt = clamp(((px - a[:, 0]) * d[:, 0] + (py - a[:, 1]) * d[:, 1]) / L2, 0.0, 1.0)
        qx = a[:, 0] + tt * d[:, 0] - px
        qy = a[:, 1] + tt * d[:, 1] - py
        dist = np.sqrt(qx * qx + qy * qy)  # (w, h, segments)
        k = dist.argmin(-1)
        s = (k + np.take_along_axis(tt, k[..., None], -1)[..., 0]) / len(a)  # 0..1 along
        thick = max(1.2, 0.35 * self.r0) * (0.4 + 0.6 * np.sin(np.pi * s))
        ramp = max(1.0, 0.5 * soft)  # the edge's width, px
        alpha = clamp((0.5 * thick + 0.5 * ramp - dist.min(-1)) / ramp, 0.0, 1.0) * fade
        return alpha.T.astype(np.float32), self.lash


_UP = np.array([0, 1, 2, 3, 4, 5, 6])  # opening loop -> upper lid c0, u1..u5, c1
_LOW = np.array([0, 11, 10, 9, 8, 7, 6])  # -> lower lid c0, d1..d5, c1
_UP_LOW = np.concatenate([_UP, _LOW])  # both, for one gather
_NEXT = np.roll(np.arange(12), -1)  # next vertex along the opening's loop


#: From this many pixels :func:`remap_rgb` reads a 4-channel copy of the part of the frame
#: its maps reach (the 1080p bench face's lid boxes, ~4600 px, and eye boxes, ~1100 px, are
#: resampled directly; the 4K face's, ~96000 and ~15000 px, through the copy: its two still
#: eyes, :func:`photo_through`, 0.27 -> 0.21 ms)
RESAMPLE4_PX = 8192


def remap_rgb(img: np.ndarray, mx: np.ndarray, my: np.ndarray) -> np.ndarray:
    """``cv2.remap(img, mx, my, cv2.INTER_LINEAR, None, cv2.BORDER_REPLICATE)`` of a uint8
    RGB frame at float32 maps, the same values. On maps of :data:`RESAMPLE4_PX` pixels and
    more it resamples a 4-channel (RGBA) copy of the part of the frame the maps reach (their
    extent, 2 px more, inside the frame: the replicated border is the frame's own there) with
    the maps moved to it by whole pixels (exact in float32: every value minus an integer no
    larger than it, the region's origin clamped at 0 aside, which subtracts nothing), and
    keeps the first 3 channels: OpenCV 5's float-map bilinear remap of 8-bit images is
    vectorised for 4 channels and not for 3 (per channel the same arithmetic: the same
    values; the 4K bench face's lid boxes, 96000 px: ~0.23 ms instead of ~0.6 ms, the copy
    and the maps' moves ~0.05 ms)."""
    if mx.size < RESAMPLE4_PX:
        return cv2.remap(img, mx, my, cv2.INTER_LINEAR, None, cv2.BORDER_REPLICATE)
    lo_x, hi_x = cv2.minMaxLoc(mx)[:2]
    lo_y, hi_y = cv2.minMaxLoc(my)[:2]
    x0, y0, x1, y1 = bilinear_reach(img.shape, (lo_x, lo_y), (hi_x, hi_y))
    src = cv2.cvtColor(img[y0:y1, x0:x1], cv2.COLOR_RGB2RGBA)
    got = cv2.remap(src, mx - np.float32(x0) if x0 else mx, my - np.float32(y0) if y0 else my,
                    cv2.INTER_LINEAR, None, cv2.BORDER_REPLICATE)
    return cv2.cvtColor(got, cv2.COLOR_RGBA2RGB)


def photo_through(img: np.ndarray, sim: np.ndarray, box: tuple[int, int, int, int]
                  ) -> np.ndarray:
    """The photo seen through the opening, moved by ``sim`` (source -> destination)."""
    x0, y0, x1, y1 = box
    inv = cv2.invertAffineTransform(np.asarray(sim, np.float64))
    xs = np.arange(x0, x1, dtype=np.float32)[None, :]
    ys = np.arange(y0, y1, dtype=np.float32)[:, None]
    mx = (inv[0, 0] * xs + inv[0, 1] * ys + inv[0, 2]).astype(np.float32)
    my = (inv[1, 0] * xs + inv[1, 1] * ys + inv[1, 2]).astype(np.float32)
    return remap_rgb(img, mx, my).astype(np.float32)
