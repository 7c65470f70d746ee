"""The skin between the upper lid and the brow when it is stretched (surprise, fear). No Qt.

The piecewise-affine warp stretches the skin between the upper lid's edge and the brow's lower
edge uniformly. Real skin does not: when the brow rises and the lid opens (AU1+2, AU5), the lid
skin near the edge and the lid crease keep their size and ride with the lid, and the thin skin
under the brow takes the stretch. Uniformly stretched, the photo's lid crease and the orbital
shadow become a wide, blurred band (a "smear").

:func:`apply_lid_skin` resamples that strip of the warped image along frame-vertical columns:
at height ``d`` above the deformed lid (strip height ``Hd``, ``Hs`` in the photo), the pixel
shows the skin at source height ``f(d) = t Hs + m (Hd - Hs) t (1 - t)`` (``t = d / Hd``): rigid
at the lid (``f'(0) = 1`` for ``m = 1``), the stretch moving up towards the brow, exact at both
edges (``f(0) = 0``, ``f(Hd) = Hs``). That is for a rising brow; a closing lid (the lid pulled
down, the brow still) leaves the skin above its crease (the eye ring, which the deformation
keeps nearly still: :func:`~editor.engine.influence.closing_lid_share`), so its strip ends at
the ring; it keeps both ends rigid and stretches the middle, ``f = Hd (s t + lam (1 - s) t
(1 - t) (1 - 2 t))`` (``s = Hs / Hd``). ``m`` and ``lam`` fade to 0 towards
the ends of the strip (no seam with the warp beside it) and are bounded so that ``f`` stays
monotonic. Only columns stretched
by more than a tenth of a pixel are touched: at rest, on the photo's own expression and where
the brow comes down (compression) the warp is left exactly as it is. One ``cv2.remap`` of a
small box per eye; it runs between the warp and the layers (the lash line is drawn after it).

Where a closing lid stretches the strip to more than 1.4 x (it draws the photo's thin lid band
over the whole eyeball) its rows are evened out along x and the photo's grain is put back
(:func:`_even_out`): the stretched grain and lash roots would read as vertical streaks, and
the unfolded skin takes the tone of the lid skin above the crease. (A
rising brow's stretch under the brow is left as it is: side by side no difference showed at
surprise 150 %, and the evening-out costs ~0.4 ms a frame at 431 x 591.)
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field
from functools import lru_cache
from typing import TYPE_CHECKING

import cv2
import numpy as np

from .fitting import clamp, clip, interp, smooth01
from .gaze import remap_rgb, spread3
from .layers import _rebox, _to_uint8, _union, layer_plan
from .mouth import _lum
from .warp import WarpResult

if TYPE_CHECKING:
    from .face import Face

#: share of each strip's width over which the redistribution fades out towards its ends
END_FADE = 0.25
#: strips stretched by less than this (pixels) are left to the warp
_MIN_STRETCH = 0.1
#: spacing (frame pixels) of the per-column table of the strip (lid line, height, stretch)
_STEP = 0.25
#: a photo whose edges ramp over at least this many px (``layers.LayerPlan.soft``: a large
#: face from an upscaled picture, the bench's 4K face 15 px) has its lid skin's shift
#: evaluated on ``soft // BLOCK_SOFT`` px square blocks (:func:`_block_shift`)
BLOCK_SOFT = 6.0


@dataclass(eq=False)
class _Strip:
    lid: np.ndarray  # vertex indices of the upper lid edge, corner to corner (by frame x)
    brow: np.ndarray  # vertex indices of the brow's lower edge (by frame x)
    ring: np.ndarray  # vertex indices of the eye ring above the lid (the crease line, by x)
    lid_s: np.ndarray  # (n, 2) frame coordinates on the photo's mesh
    brow_s: np.ndarray  # (m, 2)
    ring_s: np.ndarray  # (r, 2)
    # (their frame heights as contiguous arrays: np.interp copies a strided column each call)
    lid_sy: np.ndarray = field(init=False)
    brow_sy: np.ndarray = field(init=False)
    ring_sy: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.lid_sy = np.ascontiguousarray(self.lid_s[:, 1])
        self.brow_sy = np.ascontiguousarray(self.brow_s[:, 1])
        self.ring_sy = np.ascontiguousarray(self.ring_s[:, 1])


_PLANS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _strips(face: Face) -> list[_Strip]:
    s = _PLANS.get(face)
    if s is not None:
        return s
    m = face.mesh
    P = face.frame.to_frame(face.vertices.astype(np.float64))
    out = []
    for side in "lr":
        lid = np.array([m.index(f"eye_{side}_c0"), m.index(f"eye_{side}_c1")]
                       + [m.index(f"eye_{side}_u{k}") for k in range(1, 6)])
        brow = np.array([m.index(f"brow_{side}_e0"), m.index(f"brow_{side}_e1")]
                        + [m.index(f"brow_{side}_d{k}") for k in range(1, 4)])
        ring = np.array([m.index(f"eyering_{side}_c0"), m.index(f"eyering_{side}_c1")]
                        + [m.index(f"eyering_{side}_u{k}") for k in range(1, 6)])
        lid, brow = lid[np.argsort(P[lid, 0])], brow[np.argsort(P[brow, 0])]
        ring = ring[np.argsort(P[ring, 0])]
        out.append(_Strip(lid, brow, ring, P[lid], P[brow], P[ring]))
    _PLANS[face] = out
    return out


_INDEX: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@lru_cache(maxsize=8)
def _rows(h: int) -> np.ndarray:
    """(h, 1) float32 row numbers 0 .. h - 1 (read-only: the boxes' height recurs from frame
    to frame)."""
    r = np.arange(h, dtype=np.float32)[:, None]
    r.setflags(write=False)
    return r


@lru_cache(maxsize=8)
def _job_rows(widths: tuple[int, ...], h: int) -> np.ndarray:
    """(h, sum(widths)) float32: per column of the boxes side by side, its box's number (the
    row of the strips' table it reads; read-only, kept as :func:`_rows`)."""
    r = np.ascontiguousarray(np.arange(len(widths), dtype=np.float32).repeat(widths)[None, :]
                             .repeat(h, 0))
    r.setflags(write=False)
    return r


def _strip_index(strips: list[_Strip]) -> tuple[np.ndarray, list[tuple[slice, slice, slice]]]:
    """Every strip's lid, brow and ring vertices concatenated, and each strip's three slices
    of it."""
    got = _INDEX.get(strips[0]) if strips else None
    if got is None:
        idx, parts, k = [], [], 0
        for st in strips:
            n, m, r = len(st.lid), len(st.brow), len(st.ring)
            idx += [st.lid, st.brow, st.ring]
            parts.append((slice(k, k + n), slice(k + n, k + n + m),
                          slice(k + n + m, k + n + m + r)))
            k += n + m + r
        got = (np.concatenate(idx) if idx else np.zeros(0, np.intp), parts)
        if strips:
            _INDEX[strips[0]] = got
    return got


def apply_lid_skin(face: Face, res: WarpResult, vertices: np.ndarray) -> WarpResult:
    """Redistribute the stretch of the lid-to-brow strips of ``res.image`` (in place).

    With ``t = d / Hd`` the source height is ``f = t Hs + m ex t (1 - t)`` (``ex = Hd - Hs``)
    and the warp put it at ``e = f Hd / Hs = d + k t (1 - t)``, ``k = m ex Hd / Hs``: the pixel
    at frame height ``Y`` shows the warped strip at ``Y - k t (1 - t)``, ``t`` clipped to
    [0, 1] (outside the strip nothing moves). ``k`` and the lid line depend on the frame's x
    only: they are tabulated along x (every :data:`_STEP` px, exact there) and read per pixel
    with one ``cv2.remap`` of the table; where ``k = 0`` the map is the identity and the
    resampling returns the pixel itself. Both eyes' boxes are processed side by side in one
    set of arrays (one table lookup, one resampling of the frame).
    """
    fr = face.frame
    strips = _strips(face)
    # only the strips' vertices in the frame (row by row: the same values as all of them)
    idx, parts = _strip_index(strips)
    # (rows gathered with take: numpy's fancy indexing of an (n, 2) array costs several us more)
    P = fr.to_frame(np.asarray(vertices).take(idx, 0).astype(np.float64))
    # each strip's image box from its points mapped back (one mapping, one reduction each)
    C = fr.to_image(P)
    starts = [a.start for a, _, _ in parts]
    c_lo = np.minimum.reduceat(C, starts).tolist() if starts else []
    c_hi = np.maximum.reduceat(C, starts).tolist() if starts else []
    img = res.image
    H, W = img.shape[:2]
    R, org = fr.rot, fr.origin
    o0, o1, r00, r10 = float(org[0]), float(org[1]), float(R[0, 0]), float(R[1, 0])
    # per strip that spans enough: its box, its first frame x, its table's length and the
    # frame x of its ends (the frame coordinates as contiguous columns, the ends as Python
    # floats); the table itself is computed for both strips at once (one array of their u's)
    Px, Py = np.ascontiguousarray(P[:, 0]), np.ascontiguousarray(P[:, 1])
    px = Px.tolist()
    cand = []
    for si, ((sl_lid, sl_brow, _), (ix0, iy0), (ix1, iy1)) in enumerate(
            zip(parts, c_lo, c_hi, strict=True)):
        x_lo = max(px[sl_lid.start], px[sl_brow.start])
        x_hi = min(px[sl_lid.stop - 1], px[sl_brow.stop - 1])
        if x_hi - x_lo < 2.0:
            continue
        # image box of the strip
        x0, y0 = max(math.floor(ix0) - 1, 0), max(math.floor(iy0) - 1, 0)
        x1, y1 = min(math.ceil(ix1) + 2, W), min(math.ceil(iy1) + 2, H)
        if x1 - x0 < 2 or y1 - y0 < 2:
            continue
        # the frame's x over the box (its extremes are at the box's corners; Python floats:
        # the same float64 arithmetic as on arrays, without their cost for four values)
        ax, ay = (x0 - o0) * r00, (x1 - 1 - o0) * r00
        by, cy = (y0 - o1) * r10, (y1 - 1 - o1) * r10
        bx = (ax + by, ay + by, ax + cy, ay + cy)
        lo = min(bx)
        cand.append(((x0, y0, x1, y1), lo, math.ceil((max(bx) - lo) / _STEP) + 2, x_lo, x_hi,
                     si))
    if not cand:
        return res
    # the table along the frame's x over each box (u, every _STEP px from its first frame x):
    # lid and brow lines now and in the photo, the eye ring now and in the photo (one
    # interpolation each, written into the rows of one array: both strips' u side by side)
    n_u = [c[2] for c in cand]
    tab = np.empty((7, sum(n_u)))
    a = 0
    for _, lo, n, _, _, si in cand:
        st, (sl_lid, sl_brow, sl_ring) = strips[si], parts[si]
        u = tab[0, a:a + n]
        np.multiply(np.arange(n), _STEP, out=u)
        u += lo
        Lx, Bx, Rx = Px[sl_lid], Px[sl_brow], Px[sl_ring]
        tab[1, a:a + n] = interp(u, Lx, Py[sl_lid])
        tab[2, a:a + n] = interp(u, Bx, Py[sl_brow])
        tab[3, a:a + n] = interp(u, Lx, st.lid_sy)
        tab[4, a:a + n] = interp(u, Bx, st.brow_sy)
        tab[5, a:a + n] = interp(u, Rx, Py[sl_ring])
        tab[6, a:a + n] = interp(u, Rx, st.ring_sy)
        a += n
    u, lid_y, brow_y, lid_s, brow_s, ring_y, ring_s = tab
    if len(cand) == 1:
        x_lo, x_hi = cand[0][3], cand[0][4]
    else:  # (both rows in one call)
        x_lo, x_hi = np.array([[c[3] for c in cand], [c[4] for c in cand]]).repeat(n_u, 1)
    Hd = lid_y - brow_y
    Hs = lid_s - brow_s
    ex = Hd - Hs
    span = END_FADE * (x_hi - x_lo)
    # the fades from both ends in one array (rows: u - x_lo, x_hi - u; the same values)
    q = np.empty((2, len(u)))
    np.subtract(u, x_lo, out=q[0])
    np.subtract(x_hi, u, out=q[1])
    q /= span
    q = smooth01(q)
    fade = q[0] * q[1]
    # which end pulled: a rising brow (AU1+2) stretches the thin skin under the brow (rigid at
    # the lid); a closing lid unfolds the lid's own skin between its margin and the brow
    # (rigid at both ends: the lashes stay a thin line on the lid's edge, and the brow's lower
    # edge is not dragged down over the eye into an "M"; rigid at the brow alone froze the
    # lid's edge row, and the lashes smeared into a dark band over the closed eye)
    brow_up, lid_down = brow_s - brow_y, lid_y - lid_s
    pull = np.minimum(np.maximum(
        (brow_up - lid_down) / (np.abs(brow_up) + np.abs(lid_down) + 1e-6), -1.0), 1.0)
    hs = np.maximum(Hs, 1e-6)
    # rising brow: f = t Hs + m ex t (1 - t), rigid at the lid
    m = np.maximum(pull, 0.0) * fade * clamp(Hs / np.maximum(ex, 1e-6), 0.0, 1.0)
    # closing lid: rigid at both ends, f' = s + lam (1 - s) (1 - 6 t (1 - t)) (s = Hs / Hd the
    # mean slope), f = Hd (s t + lam (1 - s) t (1 - t) (1 - 2 t)); lam <= 2 s / (1 - s) keeps
    # it monotonic (f' >= 0 at t = 1/2)
    # (a closing lid leaves the skin above its crease, the eye ring, where it is
    # (influence.closing_lid_share): its strip ends at the ring, which the warp kept still)
    closing = pull < 0.0
    if np.count_nonzero(closing):  # (ndarray.any's Python-level wrapper costs more)
        Hd = np.where(closing, lid_y - ring_y, Hd)
        Hs = np.where(closing, lid_s - ring_s, Hs)
        ex = Hd - Hs
        hs = np.maximum(Hs, 1e-6)
        s_bar = Hs / np.maximum(Hd, 1e-6)
        lam = np.maximum(-pull, 0.0) * fade * clamp(
            2.0 * s_bar / np.maximum(1.0 - s_bar, 1e-6), 0.0, 1.0)
        live = (ex > _MIN_STRETCH) & (Hs > 0.5) & ((m != 0) | (lam != 0))
        k2 = np.where(live, lam * ex * Hd / hs, 0.0)
        closing = bool(np.count_nonzero(k2))
    else:
        # (no lid closes: lam and k2 are 0 throughout, the table carries no k2 channel and
        # the pixels' k2 (1 - 2 t) term, 0, is not added: the same values, fewer calls)
        live = (ex > _MIN_STRETCH) & (Hs > 0.5) & (m != 0)
        closing = False
    k = np.where(live, m * ex * Hd / hs, 0.0)
    tab_all = np.empty((len(u), 4 if closing else 3))
    tab_all[:, 0] = lid_y
    tab_all[:, 1] = 1.0 / np.maximum(Hd, 1e-6)
    tab_all[:, 2] = k
    if closing:
        tab_all[:, 3] = k2
    jobs = []  # per stretched strip: box, table, its first frame x
    a = 0
    sides = []  # each job's strip (0 left eye, 1 right)
    for cd, n in zip(cand, n_u, strict=True):
        if closing:
            if np.count_nonzero(live[a:a + n]):
                jobs.append((cd[0], tab_all[a:a + n], cd[1]))
                sides.append(cd[5])
        else:
            hot = np.flatnonzero(k[a:a + n])
            box = _stretched_columns(cd[0], cd[1], int(hot[0]), int(hot[-1]), o0, o1, r00,
                                     r10) if len(hot) else None
            if box is not None:
                jobs.append((box, tab_all[a:a + n], cd[1]))
                sides.append(cd[5])
        a += n
    if not jobs:
        return res
    # the boxes side by side: per column its image x, first row, table row and first frame x
    hmax = max(b[3] - b[1] for b, _, _ in jobs)
    n_tab = max(len(t) for _, t, _ in jobs)
    # (4 channels: lid line, 1 / Hd, k, k2 (3 without k2); one more row, a copy of the last,
    # which the rows' exact integer positions weigh by 0: without it every pixel of the last
    # strip takes OpenCV's slow border path)
    table = np.zeros((len(jobs) + 1, n_tab, tab_all.shape[1]), np.float32)
    widths, shifts, y0s, los = [], [], [], []
    c = 0
    for j, ((x0, y0, x1, _y1), tab, lo) in enumerate(jobs):
        table[j, :len(tab)] = tab
        table[j, len(tab):] = tab[-1]
        widths.append(x1 - x0)
        shifts.append(x0 - c)
        y0s.append(y0)
        los.append(lo)
        c += x1 - x0
    table[-1] = table[-2]
    # per column (the boxes side by side): its image x, first row, table row and first frame x
    sh_c, y0c, lo_c = np.array([shifts, y0s, los], np.float64).repeat(widths, 1)
    xc = np.arange(c, dtype=np.float64) + sh_c
    rows_f = _rows(hmax)
    above = None
    block = 1 if closing else int(layer_plan(face).soft // BLOCK_SOFT)
    if block > 1:
        t = _block_shift(table, jobs, R, org, hmax, block)
    else:
        t, above = _shift(table, xc, y0c, lo_c, rows_f, tuple(widths), R, org, closing)
    mx = xc.astype(np.float32)[None, :] - np.float32(R[0, 1]) * t
    my = (y0c.astype(np.float32)[None, :] + rows_f) - np.float32(R[1, 1]) * t
    new = remap_rgb(img, mx, my)
    if above is not None:  # a closing lid (the evening-out is for its band over the eye)
        # the lashes' band kept above the lid's edge, per column: LASH_KEEP of the interocular
        # distance while the eye is open, none once it is closed (from a closure of 0.6 to 0.9
        # the drawn lash line fades in, layers / gaze.EyePlan.lash_line; the band goes as its
        # square, so that a half-drawn line still has the photo's lashes behind it)
        eyes = layer_plan(face).eyes  # (built for the layers anyway)
        v = np.asarray(vertices)
        fades = [eyes[name].lash_fade(v[face.mesh.holes[name]])
                 for name in ("eye_l", "eye_r")]
        band = np.repeat(np.array([LASH_KEEP * float(face.interocular) * (1.0 - fades[si] ** 2)
                                   for si in sides], np.float32),
                         [b[2] - b[0] for b, _, _ in jobs])
        new = _even_out(face, res, new, mx, my, [b for b, _, _ in jobs], above, band)
    bbox = res.bbox
    c = 0
    for (x0, y0, x1, y1), _, _ in jobs:
        img[y0:y1, x0:x1] = new[:y1 - y0, c:c + x1 - x0]
        c += x1 - x0
        bbox = _union(bbox, (x0, y0, x1, y1))
    if bbox is None or bbox == res.bbox:  # None: res.bbox is None and nothing was drawn
        return res
    return _rebox(res, bbox, {})


def _shift(table: np.ndarray, xc: np.ndarray, y0c: np.ndarray, lo_c: np.ndarray,
           rows: np.ndarray, widths: tuple[int, ...], R: np.ndarray, org: np.ndarray,
           closing: bool) -> tuple[np.ndarray, np.ndarray | None]:
    """The frame-vertical shift ``k t (1 - t)`` (+ ``k2 t (1 - t) (1 - 2 t)`` for a closing
    lid) (h, w) float32 at the points of the boxes side by side (per column: its image x
    ``xc``, its box's first row ``y0c``, its table's first frame x ``lo_c``; ``rows`` (h, 1)
    float32: the rows' offsets from the first; ``widths``: the boxes' columns, each reading
    its own row of ``table``), and for a closing lid the height above the lid's edge (None
    else)."""
    # the points in the frame (``fr.to_frame``): X (in table steps) and the height Y, each a
    # per-column term plus the row times a constant (float32: sub-1e-4 px here)
    xo, yo = xc - org[0], y0c - org[1]
    tx = (xo * R[0, 0] + yo * R[1, 0] - lo_c) * (1.0 / _STEP)
    tx = tx.astype(np.float32)[None, :] + rows * np.float32(R[1, 0] / _STEP)
    ty = _job_rows(widths, len(rows))
    got = cv2.remap(table, tx, ty, cv2.INTER_LINEAR, None, cv2.BORDER_REPLICATE)
    ly, inv_hd, kk, *kk2 = cv2.split(got)
    ly -= (xo * R[0, 1] + yo * R[1, 1]).astype(np.float32)[None, :]
    ly -= rows * np.float32(R[1, 1])  # lid line - Y
    above = ly.copy() if closing else None  # px above the lid's edge (its lashes: kept)
    t = ly
    t *= inv_hd
    clip(t, 0.0, 1.0, out=t)  # (one pass: on a box, faster than maximum then minimum)
    if kk2:
        kk2[0] *= 1.0 - 2.0 * t
        kk += kk2[0]  # k + k2 (1 - 2 t)
    t -= t * t  # t (1 - t)
    t *= kk
    return t, above


def _block_shift(table: np.ndarray, jobs: list, R: np.ndarray, org: np.ndarray, h: int,
                 q: int) -> np.ndarray:
    """:func:`_shift` of a rising brow (no closing lid) over the boxes of ``jobs`` side by
    side (``h`` rows), evaluated at the centres of their ``q x q`` blocks (each box's width
    and ``h`` rounded up to whole blocks) and upsampled bilinearly: a soft photo's lid skin
    (:data:`BLOCK_SOFT`), whose shift is smooth but for its kinks at the lid's edge and the
    brow (t clipped to [0, 1]). The resampling of the frame stays per pixel. On the 4K bench
    face (``q`` 2) the stage takes ~0.4 ms less; the bench expression and surprise 100/150 %
    change by at most 2 grey levels (1 on average over the changed pixels; 3 and 4 at ``q``
    3 and 4); faces up to 1080p (softness below ~3 px) are evaluated per pixel as before."""
    nb = [-(-(b[2] - b[0]) // q) for b, _, _ in jobs]  # block columns per box
    hb = -(-h // q)
    starts = np.cumsum([0] + nb[:-1])
    c = 0.5 * (q - 1)  # (block k's centre: pixel k q + c, where cv2.resize puts it)
    # per block column its centre's image x, its box's first row and its table's first x
    sh, y0c, lo_c = np.array([[b[0] + c - q * s for (b, _, _), s in zip(jobs, starts,
                                                                       strict=True)],
                              [b[1] + c for b, _, _ in jobs],
                              [lo for _, _, lo in jobs]], np.float64).repeat(nb, 1)
    xb = q * np.arange(sum(nb), dtype=np.float64) + sh
    t, _ = _shift(table, xb, y0c, lo_c, _rows(hb) * np.float32(q), tuple(nb), R, org, False)
    up = cv2.resize(t, (q * t.shape[1], q * hb), None, 0, 0, cv2.INTER_LINEAR)
    widths = [b[2] - b[0] for b, _, _ in jobs]
    if all(w == q * n for w, n in zip(widths, nb, strict=True)):
        return up[:h]
    cols = np.concatenate([np.arange(q * s, q * s + w) for s, w in zip(starts, widths,
                                                                        strict=True)])
    return up[:h].take(cols, 1)


def _stretched_columns(box: tuple[int, int, int, int], lo: float, i0: int, i1: int, o0: float,
                       o1: float, r00: float, r10: float) -> tuple[int, int, int, int] | None:
    """The columns of a strip's image ``box`` whose pixels may read a nonzero ``k`` from its
    table (first frame x ``lo``, nonzero from entry ``i0`` to ``i1``; frame origin ``o0, o1``,
    rotation ``r00, r10``): the box narrowed to them (None: no column). Beyond them the table
    lookup reads two zero entries, the shift is exactly 0 and the resampling returns each
    pixel itself (on the 4K bench face 40 % of the boxes' columns). The frame x of a column
    spans its values at the box's first and last row; the columns are those whose span meets
    the nonzero entries grown by two table steps (a lookup reads the entry on either side),
    plus a pixel. The box itself when the frame is rolled by more than about 80 degrees."""
    x0, y0, x1, y1 = box
    if r00 < 0.2:
        return box
    ya, yb = (y0 - o1) * r10, (y1 - 1 - o1) * r10
    lo_x, hi_x = lo + (i0 - 2) * _STEP, lo + (i1 + 2) * _STEP
    c0 = max(math.floor(o0 + (lo_x - max(ya, yb)) / r00) - 1, x0)
    c1 = min(math.ceil(o0 + (hi_x - min(ya, yb)) / r00) + 2, x1)
    return (c0, y0, c1, y1) if c1 - c0 >= 1 else None


#: vertical stretch (photo rows per output row, inverted) from which a lid's skin is evened
#: out (:func:`_even_out`) and from which it is evened out fully
STRETCH_FROM, STRETCH_FULL = 1.4, 2.2
#: side of the static grain tile (px)
_TILE = 128
#: the grain's smallest blur (px) and its share of the photo's grain level: the stretched
#: skin keeps part of its own grain along the columns; the noise adds the rest
GRAIN_SIGMA, GRAIN_SHARE = 0.6, 0.6
#: blur of the evening-out weight: a share of the interocular distance, at least (px)
WEIGHT_BLUR, WEIGHT_BLUR_MIN = 0.025, 0.8
#: the band above a closing lid's edge that keeps the photo's texture (its lashes) while the
#: eye is open, a share of the interocular distance: untouched over its first half, fully
#: evened out above it
LASH_KEEP = 0.08
#: the stretch from which the closing lid's skin takes the colour of the skin above it, and
#: from which fully (:data:`TONE_SHARE` of the way)
TONE_FROM, TONE_FULL = 1.15, 1.6
#: how far the stretched lid skin goes towards the tone of the skin above the crease
TONE_SHARE = 0.9
_GRAIN: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _grain(face: Face) -> tuple[float, np.ndarray]:
    """The photo's edge ramp (:func:`layers.layer_plan`) and a static noise tile blurred as
    the photo is, at :data:`GRAIN_SHARE` of the skin's grain around the upper lids (robust std
    of the luminance's high-pass, grey levels), repeated 2 x 2 (any window up to the tile's
    side is one slice; kept per face)."""
    got = _GRAIN.get(face)
    if got is not None:
        return got
    from .layers import layer_plan  # (built for the layers anyway; imported late: a cycle)

    soft = float(layer_plan(face).soft)
    img = face.image
    H, W = img.shape[:2]
    vals = []
    for st in _strips(face):
        C = face.frame.to_image(np.vstack([st.lid_s, st.brow_s]))
        x0, y0 = max(int(C[:, 0].min()), 0), max(int(C[:, 1].min()), 0)
        x1, y1 = min(int(C[:, 0].max()) + 1, W), min(int(C[:, 1].max()) + 1, H)
        if x1 - x0 < 4 or y1 - y0 < 4:
            continue
        L = _lum(img[y0:y1, x0:x1])
        vals.append(np.abs(L - cv2.GaussianBlur(L, (0, 0), max(1.0, soft / 2.56))).ravel())
    g = 1.4826 * float(np.median(np.concatenate(vals))) if vals else 0.0
    tile = np.random.default_rng(20261128).standard_normal((_TILE, _TILE)).astype(np.float32)
    # grain as soft as the photo's, and never finer than a pixel and a half (white noise at
    # the photo's level reads as speckle on a smooth skin); wrapped: the tile repeats
    sig = max(soft / 2.56, GRAIN_SIGMA)
    p = min(int(math.ceil(4 * sig)), _TILE)
    blurred = np.asarray(cv2.GaussianBlur(np.pad(tile, p, mode="wrap"), (0, 0), sig),
                         np.float32)[p:-p, p:-p]
    tile = blurred * np.float32(GRAIN_SHARE * g / max(float(blurred.std()), 1e-6))
    got = (soft, np.ascontiguousarray(np.tile(tile, (2, 2)), np.float32))
    _GRAIN[face] = got
    return got


def _tone_above(new: np.ndarray, hot: np.ndarray, r0: int, c0: int, rw: int
                ) -> tuple[np.ndarray, np.ndarray]:
    """Per column of ``hot`` (the window of ``new`` at ``r0, c0``): the mean colour (n, 3) of
    the ``rw + 2`` rows of ``new`` above the window's first hot row, past the weight's blur
    (``rw`` rows), smoothed along x over the columns that have one, and how much of it to use
    (n,) in [0, 1]: 1 over the hot columns, fading out beside them (0 where none is near)."""
    n = hot.shape[1]
    has: np.ndarray = np.asarray(hot.any(0))
    top = r0 + hot.argmax(0) - rw - 1  # the first row past the blur, per column
    k = rw + 2
    ok = has & (top - k >= 0)
    if not ok.any():
        return np.zeros((n, 3), np.float32), np.zeros(n, np.float32)
    cs = np.zeros((new.shape[0] + 1, n, 3), np.float32)
    np.cumsum(new[:, c0:c0 + n].astype(np.float32), 0, out=cs[1:])
    cols = np.arange(n)
    t = np.clip(top, k, None)
    mean = (cs[t, cols] - cs[t - k, cols]) * np.float32(1.0 / k)
    okf = ok.astype(np.float32)[:, None]
    sig = max(2.0, 2.0 * rw)
    num = cv2.GaussianBlur((mean * okf)[None], (0, 0), sig)[0]
    den = cv2.GaussianBlur(np.repeat(okf, 3, 1)[None], (0, 0), sig)[0]
    tone = np.where(den > 1e-3, num / np.maximum(den, 1e-3), 0.0).astype(np.float32)
    # the share: 1 over the hot columns and as far beside them as the weight's blur reaches,
    # fading out further (a step where the hot columns end showed as a seam)
    reach = int(math.ceil(rw + sig))
    wide = cv2.dilate(has.astype(np.uint8)[None], np.ones((1, 2 * reach + 1), np.uint8))[0]
    share = cv2.GaussianBlur(wide.astype(np.float32)[None], (0, 0), 0.5 * sig)[0]
    np.maximum(share, has, out=share)
    share *= den[:, 0] > 1e-3
    return tone, share.astype(np.float32)


def _even_out(face: Face, res: WarpResult, new: np.ndarray, mx: np.ndarray, my: np.ndarray,
              boxes: list[tuple[int, int, int, int]], above: np.ndarray | None = None,
              band: np.ndarray | None = None) -> np.ndarray:
    """The lid strips ``new`` (uint8, the image ``boxes`` side by side; ``mx, my`` where each
    pixel was read in the warped image) with the skin evened out where it is stretched
    vertically by more than :data:`STRETCH_FROM`; ``above`` (the pixels' height over the lid's
    edge) and ``band`` (per column) keep the lashes' band above a closing lid's edge as the
    photo shows it.

    A closing lid draws the photo's thin band of lid skin (between its margin and the crease
    or the brow) over the whole eyeball, two to three times taller: the skin's grain and the
    lashes' roots become vertical streaks, a combed curtain over a closed eye (JAFFE: the
    closed lid's horizontal gradient energy 1.4-3.6 x its vertical one, the photo's lid skin
    0.3-1.4). Where stretched, each row is smoothed along x (streaks go, horizontal lines such
    as the lash line and the crease stay) and the photo's own grain level comes back as a
    static noise (isotropic, as soft as the photo's), faded in from 1.4 to 2.2 x stretch. The
    stretched skin also takes :data:`TONE_SHARE` of the way to the colour of the skin just
    above it, column by column (the crease's skin, which the closing lid leaves in place;
    smoothed along x): the unfolded skin is that skin, while the photo's band above the lashes
    is the shadowed edge of the fold (stretched, a dark bag over the eye)."""
    if res.maps is None:
        return new
    map_y, (a0, b0, a1, b1) = res.maps[1], res.maps[2]
    # the photo row each output pixel shows (the warp's backward map read where the strip
    # resampling reads the warped image); outside the warp's box the map is the identity
    sy = cv2.remap(map_y, mx - np.float32(a0), my - np.float32(b0), cv2.INTER_LINEAR,
                   None, cv2.BORDER_REPLICATE)
    d = np.empty_like(sy)
    d[:-1] = sy[1:] - sy[:-1]
    d[-1] = d[-2] if len(d) > 1 else 1.0
    # w = (1 / |d| - STRETCH_FROM) / (STRETCH_FULL - STRETCH_FROM), in [0, 1]
    np.abs(d, out=d)
    np.maximum(d, np.float32(0.05), out=d)
    stretch = np.float32(1.0) / d
    inside = (mx >= a0) & (mx <= a1 - 1) & (my >= b0) & (my <= b1 - 1)
    # w = (stretch - STRETCH_FROM) / (STRETCH_FULL - STRETCH_FROM), in [0, 1]; wt the same
    # from TONE_FROM to TONE_FULL (the colour of the skin above comes in at a lower stretch)
    w = np.clip((stretch - np.float32(STRETCH_FROM))
                * np.float32(1.0 / (STRETCH_FULL - STRETCH_FROM)), 0.0, 1.0) * inside
    wt = np.clip((stretch - np.float32(TONE_FROM))
                 * np.float32(1.0 / (TONE_FULL - TONE_FROM)), 0.0, 1.0) * inside
    if above is not None and band is not None:
        # the lid's edge (its lashes: ``band`` px above it, per column) keeps the photo's own
        # texture: evened out and toned, a half-closed eye lost its lash line
        near = np.clip(above / np.maximum(band, np.float32(1e-3))[None, :] - np.float32(0.5),
                       0.0, 1.0)
        w *= near
        wt *= near
    # (only the rows and columns that are stretched, with the blurs' margins)
    hot = wt >= np.float32(0.02)
    hit_r, hit_c = np.flatnonzero(hot.any(1)), np.flatnonzero(hot.any(0))
    if not len(hit_r):
        return new
    soft, tile2 = _grain(face)
    sx = max(1.0, 0.5 * soft)
    # the weight changes from triangle to triangle of the warp: blurred over a share of the
    # face's size (a 3 x 3 box left polygon edges on a 700 px face)
    sw = max(WEIGHT_BLUR_MIN, WEIGHT_BLUR * float(face.interocular))
    rw = int(math.ceil(3.0 * sw))
    pad = max(int(math.ceil(3.0 * sx)), rw) + 3
    h, wd = w.shape
    r0, r1 = max(int(hit_r[0]) - rw - 1, 0), min(int(hit_r[-1]) + rw + 2, h)
    c0, c1 = max(int(hit_c[0]) - pad, 0), min(int(hit_c[-1]) + pad + 1, wd)
    kw = 2 * rw + 1
    wb, wtb = (np.asarray(cv2.GaussianBlur(np.ascontiguousarray(a[r0:r1, c0:c1]), (kw, kw), sw,
                                           borderType=cv2.BORDER_REPLICATE), np.float32)
               for a in (w, wt))
    f = new[r0:r1, c0:c1].astype(np.float32)
    # towards the skin above the stretched band: f + share (tone - f), per column
    tone, share = _tone_above(new, wt[r0:r1, c0:c1] >= np.float32(0.5), r0, c0, rw)
    wtb *= np.float32(TONE_SHARE) * share[None, :]
    f += (tone[None] - f) * wtb[..., None]
    k = cv2.getGaussianKernel(int(round(8 * sx + 1)) | 1, sx, cv2.CV_32F)
    sm: np.ndarray = np.asarray(cv2.sepFilter2D(f, -1, k, np.ones((1, 1), np.float32),
                                                borderType=cv2.BORDER_REFLECT), np.float32)
    # the grain, static in the image: each box's window of the repeated tile
    noise = np.empty((r1 - r0, c1 - c0), np.float32)
    T = _TILE
    c = 0
    for x0, y0, x1, _y1 in boxes:
        lo, hi = max(c, c0), min(c + x1 - x0, c1)
        if hi > lo:
            ys = (y0 + r0) % T
            xs = (x0 + lo - c) % T
            if r1 - r0 <= T and hi - lo <= T:
                noise[:, lo - c0:hi - c0] = tile2[ys:ys + r1 - r0, xs:xs + hi - lo]
            else:  # (a window larger than the tile: gathered)
                iy = (y0 + np.arange(r0, r1))[:, None] % T
                ix = (x0 + np.arange(lo - c, hi - c))[None, :] % T
                noise[:, lo - c0:hi - c0] = tile2[iy, ix]
        c += x1 - x0
    # (the single-channel grain and weight spread over the 3 channels: gaze.spread3)
    sm += spread3(noise)
    sm -= f
    sm *= spread3(wb)
    f += sm
    out = new.copy()
    _to_uint8(f, out[r0:r1, c0:c1])
    return out
