"""Piecewise-affine texture mapping (SPEC §2.4, eq. 5): backward, bilinear, vectorised.

Per frame: find the triangles with a moved vertex; rasterize their ids (destination mesh)
into the bounding box they cover; fit each one's inverse affine map (destination -> source) in
one batched solve; gather the coefficients per pixel; one ``cv2.remap`` of the box; every
other pixel is the photo's own. A zero FAP vector therefore reproduces the photo exactly.

Fill rule: triangles are drawn one after another with ``cv2.fillConvexPoly`` (sub-pixel
vertices); a pixel on a shared edge takes the id of the last triangle drawn there, and because
neighbouring affine maps agree on their shared edge the map is continuous: no holes, no seams.

Openings: pixels inside the deformed eye and mouth openings are not covered by any triangle.
The eyes show the photo's own pixels there; the mouth shows the photo's own pixels where the
photo's mouth was already open and a dark, softly shaded cavity elsewhere (the layered mouth
interior of SPEC §3.1 draws over it when available). The openings are returned as masks.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol, cast, runtime_checkable

import cv2
import numpy as np

from .prefault import copy_of, empty_of

_SHIFT = 4
_ONE = 1 << _SHIFT

#: Colour of the mouth cavity (RGB) before shading.
CAVITY_RGB = np.array([58, 22, 24], np.float32)


@dataclass(eq=False)
class WarpPlan:
    """Per-mesh precomputation for :func:`warp`.

    Attributes
    ----------
    image : (H, W, 3) uint8 RGB photo (read-only)
    src : (V, 2) float32 neutral vertices
    triangles : (T, 3) int32
    holes : dict name -> vertex loop (int32)
    """

    image: np.ndarray
    src: np.ndarray
    triangles: np.ndarray
    holes: dict[str, np.ndarray]
    #: (V,) bool or None: the band, vertices whose motion (e.g. the head's margin on a head
    #: rotation) makes the warp cover the whole frame through a few large triangles; when one
    #: of them moves, :func:`warp` interpolates those triangles' map from a coarse grid
    band: np.ndarray | None = None
    #: node spacing (px) of the backward map (see :func:`map_step`): 1, the exact per-pixel
    #: map; s > 1, the map evaluated on nodes s px apart and interpolated bilinearly where it
    #: bends gently (:func:`_maps_coarse`: within :data:`MAP_KINK_PX` of the exact map)
    map_step: int = 1
    #: bool mask of the photo's own mouth opening over its box, and the box's corner (x, y)
    #: (computed by __post_init__; :attr:`neutral_mouth` is the whole image's)
    _mouth_local: np.ndarray = field(init=False, repr=False)
    _mouth_at: tuple[int, int] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.image = np.ascontiguousarray(self.image)
        self.image.setflags(write=False)
        self.src = np.asarray(self.src, np.float32)
        self.triangles = np.asarray(self.triangles, np.int32)
        self._tri_cols = tuple(np.ascontiguousarray(self.triangles[:, k]) for k in range(3))
        h, w = self.image.shape[:2]
        # the opening over its box only (no image-sized mask: 24 MB at 24 MP)
        loop = self.src[self.holes["mouth"]]
        (lx, ly), (hx, hy) = loop.min(0).tolist(), loop.max(0).tolist()
        # (np.clip's values, on Python numbers)
        mx0 = min(max(math.floor(lx) - 1, 0), w)
        my0 = min(max(math.floor(ly) - 1, 0), h)
        mx1 = min(max(math.ceil(hx) + 2, mx0), w)
        my1 = min(max(math.ceil(hy) + 2, my0), h)
        m = np.zeros((my1 - my0, mx1 - mx0), np.uint8)
        poly = np.round((loop - np.array([mx0, my0], np.float32)) * _ONE).astype(np.int32)
        cv2.fillPoly(m, [poly], 1, cv2.LINE_8, _SHIFT)
        self._mouth_local, self._mouth_at = m.astype(bool), (mx0, my0)
        st = self.src[self.triangles].astype(np.float64)  # (T, 3, 2) source triangles
        # (6, T) what _table reads of each source triangle, one contiguous row per term: its
        # edges f1 = s1 - s0, f2 = s2 - s0 (x, y) and its first corner s0 (x, y)
        self._src_terms = np.ascontiguousarray(np.stack(
            [st[:, 1, 0] - st[:, 0, 0], st[:, 1, 1] - st[:, 0, 1], st[:, 2, 0] - st[:, 0, 0],
             st[:, 2, 1] - st[:, 0, 1], st[:, 0, 0], st[:, 0, 1]]))
        # the identity rows of every table (_table starts from a copy)
        self._table0 = np.zeros((len(self.triangles) + 1 + 3, 6), np.float32)
        self._table0[:, 0] = 1.0
        self._table0[:, 4] = 1.0
        if self.map_step > 1:  # (only the interpolated map looks at the edges' bends)
            self._edge_v, self._edge_t = _edges(self.triangles)
        self._band_tri = (np.zeros(len(self.triangles), bool) if self.band is None
                          else np.asarray(self.band, bool)[self.triangles].any(1))
        # source bounding box of every triangle (+1 px), to clamp the edge pixels that the
        # rasterizer assigns to a triangle although their centre is just outside it: for a
        # thin, stretched triangle the affine map would extrapolate them far away (speckles)
        se = st[:, 1:] - st[:, :1]
        self._src_area = np.maximum(
            np.abs(se[:, 0, 0] * se[:, 1, 1] - se[:, 0, 1] * se[:, 1, 0]), 1e-9)
        # (the corners' minimum and maximum two at a time: numpy's reduction over the middle
        # axis of (T, 3, 2) costs several times more; min and max are exact either way)
        lo = np.minimum(np.minimum(st[:, 0], st[:, 1]), st[:, 2]) - 1.0
        hi = np.maximum(np.maximum(st[:, 0], st[:, 1]), st[:, 2]) + 1.0
        full = np.array([[-1.0, -1.0, w + 1.0, h + 1.0]] * (1 + 3))  # identity row + layers
        self._src_box = np.vstack([np.hstack([lo, hi]), full]).astype(np.float32)
        self._src_box_t = np.ascontiguousarray(self._src_box.T)  # (4, rows): its columns
        # the scratch frame of :func:`_rgba_buffer`
        self._rgba: np.ndarray | None = None
        self._rgba_lock = threading.Lock()

    @property
    def neutral_mouth(self) -> np.ndarray:
        """(H, W) bool: the photo's own mouth opening (a new array)."""
        m = np.zeros(self.image.shape[:2], bool)
        (x0, y0), loc = self._mouth_at, self._mouth_local
        m[y0:y0 + loc.shape[0], x0:x0 + loc.shape[1]] = loc
        return m

    def in_neutral_mouth(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """bool per pixel ``(xs, ys)`` (int, inside the image): in the photo's own opening."""
        (x0, y0), loc = self._mouth_at, self._mouth_local
        u, v = xs - x0, ys - y0
        ok = (u >= 0) & (v >= 0) & (u < loc.shape[1]) & (v < loc.shape[0])
        hit = np.zeros(len(xs), bool)
        hit[ok] = loc[v[ok], u[ok]]
        return hit


def _edges(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The mesh's edges: (E, 2) vertex pairs and (E, 2) the triangles on either side (``T``,
    the identity row of :func:`_table`, where there is none: outside the mesh, an opening)."""
    T = len(triangles)
    e = np.sort(triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    t = np.repeat(np.arange(T, dtype=np.int32), 3)
    order = np.lexsort((e[:, 1], e[:, 0]))
    e, t = e[order], t[order]
    first = np.ones(len(e), bool)
    first[1:] = (e[1:] != e[:-1]).any(1)
    start = np.flatnonzero(first)
    side = np.full((len(start), 2), T, np.int32)
    side[:, 0] = t[start]
    # an interior edge appears twice in a row: its second triangle
    pos = np.cumsum(first) - 1
    second = np.flatnonzero(~first)
    side[pos[second], 1] = t[second]
    return np.ascontiguousarray(e[start], dtype=np.int32), side


@dataclass
class WarpResult:
    """Output of :func:`warp`.

    image : (H, W, 3) uint8 warped photo
    bbox : (x0, y0, x1, y1) region that was recomputed, or None when nothing moved
    mouth_local, eyes_local : bool masks of the openings inside ``bbox`` (None if unchanged)
    maps : ``(map_x, map_y, box)``: the warp's backward map (destination pixel -> photo
        position, float32) over ``box`` (x0, y0, x1, y1; identity outside it), or None
    interpolation : how the photo was resampled through ``maps`` (OpenCV flag): what else
        the layers carry from the photo through the same map is resampled alike
    """

    image: np.ndarray
    bbox: tuple[int, int, int, int] | None
    mouth_local: np.ndarray | None = None
    eyes_local: np.ndarray | None = None
    maps: tuple[np.ndarray, np.ndarray, tuple[int, int, int, int]] | None = None
    interpolation: int = cv2.INTER_LINEAR

    def _full(self, local: np.ndarray | None) -> np.ndarray | None:
        if local is None or self.bbox is None:
            return None
        m = np.zeros(self.image.shape[:2], bool)
        x0, y0, x1, y1 = self.bbox
        m[y0:y1, x0:x1] = local
        return m

    @property
    def mouth_mask(self) -> np.ndarray | None:
        """(H, W) bool: the mouth opening of the deformed face."""
        return self._full(self.mouth_local)

    @property
    def eye_mask(self) -> np.ndarray | None:
        """(H, W) bool: the eye openings of the deformed face."""
        return self._full(self.eyes_local)


LAYERS = ("eye_l", "eye_r", "mouth")
_IDENTITY = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def warp(plan: WarpPlan, dst: np.ndarray, layers: dict[str, np.ndarray] | None = None,
         tol: float = 1e-3, cavity: bool = True,
         hook: Callable[..., tuple[int, int, int, int] | None] | None = None,
         interpolation: int = cv2.INTER_LINEAR) -> WarpResult:
    """Warp the photo so that the neutral mesh ``plan.src`` lands on ``dst`` (V, 2).

    Only triangles with a vertex that moved by more than ``tol`` pixels are re-filled (on a
    large face's interpolated map at least :data:`MAP_TOL`).
    ``layers`` optionally gives, for each opening (``eye_l``, ``eye_r``, ``mouth``), the 2x3
    affine map (source -> destination) of what lies behind it: the eyeball follows its eye's
    corners, the mouth interior follows the skull. Without it the openings are static.
    ``cavity=False`` skips the flat dark cavity (the caller composites its own mouth interior,
    see :mod:`layers`). ``hook(ids, map_x, map_y, box)``, when given, may change the backward
    map of the box in place before it is applied (e.g. :func:`jawband.jaw_map`) and returns the
    box (x0, y0, x1, y1) it changed, None when it changed nothing; the band path of a moving
    margin (head rotation) does not call it. A hook that is also a :class:`NodeHook` (its map
    at any points) joins the interpolated map of a large face (:attr:`WarpPlan.map_step` > 1)
    on its nodes instead (see :func:`_maps_coarse`); it is not called then. On the exact map
    the pixels of the ids a hook's ``lut`` marks (if it has one) carry the identity when it is
    called: it replaces their map wherever that differs from the identity.
    ``interpolation``: how the photo is resampled (``cv2.INTER_LINEAR``, the live preview's;
    ``cv2.INTER_CUBIC`` keeps the moved skin as sharp as the photo's, at ~1.3 x the render's
    cost: stills for export).
    """
    img = plan.image
    h, w = img.shape[:2]
    dst = np.asarray(dst, np.float32)
    V = len(plan.src)
    if plan.map_step > 1:
        tol = max(tol, MAP_TOL)
    # (the reductions over the small axes as element-wise maxima and ors of their columns,
    # the box's bounds on Python numbers: the same values, several times cheaper)
    d = np.abs(dst[:V] - plan.src)
    moved_v = np.maximum(d[:, 0], d[:, 1]) > tol
    if not moved_v.any():
        return WarpResult(copy_of(img), None)
    tris = plan.triangles
    t0, t1, t2 = plan._tri_cols
    moved_t = np.flatnonzero(moved_v.take(t0) | moved_v.take(t1) | moved_v.take(t2))
    tri_pts = dst[tris[moved_t]]  # (n, 3, 2)
    p = tri_pts.reshape(-1, 2)
    x0 = min(max(math.floor(float(p[:, 0].min())) - 1, 0), w)
    y0 = min(max(math.floor(float(p[:, 1].min())) - 1, 0), h)
    x1 = min(max(math.ceil(float(p[:, 0].max())) + 2, 0), w)
    y1 = min(max(math.ceil(float(p[:, 1].max())) + 2, 0), h)
    if x1 <= x0 or y1 <= y0:
        return WarpResult(copy_of(img), None)
    if (plan.band is not None and min(x1 - x0, y1 - y0) >= 4 * BAND_STEP
            and moved_v[plan.band].any()):
        inner = _inner_box(plan, dst, moved_t, w, h)
        inner = (max(inner[0], x0), max(inner[1], y0), min(inner[2], x1), min(inner[3], y1))
        if 2 * _area(inner) < _area((x0, y0, x1, y1)):
            return _warp_band(plan, dst, layers, cavity, moved_t, tri_pts, inner,
                              (x0, y0, x1, y1), interpolation)
    s = plan.map_step
    if s > 1 and min(x1 - x0, y1 - y0) >= 8 * s:
        # (where the hook reads the triangle ids: its ``box`` if it tells, else anywhere)
        hook_box = None if hook is None else getattr(hook, "box", None)
        reads = [] if hook is None else None if hook_box is None else [hook_box]
        # a hook that gives its map at any points joins the map on its nodes (its pixels'
        # ids are then read nowhere)
        # (its attributes looked up: isinstance of a runtime-checkable Protocol costs 0.1 ms)
        node_hook = (cast(NodeHook, hook) if hasattr(hook, "nodes") and hasattr(hook, "lut")
                     and hasattr(hook, "points") and hasattr(hook, "box") else None)
        if node_hook is not None:
            reads, hook = [], None
        # (without a hook to call on the whole map, the map is interpolated strip by strip as
        # the photo is resampled: see :func:`_resample_strips`)
        ids, map_x, map_y, moving, pending = _maps_coarse(
            plan, dst, layers, moved_t, tri_pts, x0, y0, x1 - x0, y1 - y0, s, reads, node_hook,
            defer=hook is None)
    else:
        s = 1
        # (a hook that names the ids whose map it replaces (``lut``) replaces it at every such
        # pixel where it differs from the identity: their points carry the identity, their
        # affine maps are not evaluated, see :func:`_evaluate_clamped`)
        ids, map_x, map_y = _maps(plan, dst, layers, moved_t, tri_pts, x0, y0, x1 - x0,
                                  y1 - y0, skip=getattr(hook, "lut", None))
    touched = None if hook is None else hook(ids, map_x, map_y, (x0, y0, x1, y1))
    if s > 1:
        if touched is not None:  # (the hook's pixels are resampled too)
            _mark(moving, touched, s, x0, y0)
        if pending is not None:
            # (the photo copied part by part as it is resampled, see _resample_strips)
            out = empty_of(img)
            _resample_strips(plan, out, pending, moving, s, x0, y0, y1 - y0, x1 - x0,
                             interpolation)
        else:
            out = copy_of(img)
            _remap_moving(img, out, map_x, map_y, moving, s, x0, y0, interpolation)
    else:
        # (resampled straight into the copy's box: no temporary box and second copy)
        out = copy_of(img)
        cv2.remap(img, map_x, map_y, interpolation, dst=out[y0:y1, x0:x1],
                  borderMode=cv2.BORDER_REPLICATE)
    return _finish(plan, dst, out, ids, map_x, map_y, (x0, y0, x1, y1), cavity,
                   interpolation=interpolation)


#: Rows per strip of :func:`_remap_moving`
_STRIP_PX = 32


def _remap_moving(img: np.ndarray, out: np.ndarray, map_x: np.ndarray, map_y: np.ndarray,
                  moving: np.ndarray, s: int, x0: int, y0: int,
                  interpolation: int = cv2.INTER_LINEAR,
                  rows: tuple[int, int] | None = None,
                  extent: tuple[list[int], list[int]] | None = None,
                  src4: np.ndarray | None = None, scratch: np.ndarray | None = None
                  ) -> None:
    """``out``'s box at ``(x0, y0)`` (a copy of ``img``) resampled through the interpolated map
    ``map_x, map_y``, strip by strip of :data:`_STRIP_PX` rows, between the first and the last
    column a moving node (``moving``: the grid of :func:`_maps_coarse`, its nodes whose pixels
    were written exactly and those of a hook marked) reaches. The columns outside map every
    pixel to itself, exactly: each of their pixels interpolates four nodes on the identity
    (each node's value its own position, as is the pixel's: with :data:`MAP_STEP` 2 multiples
    of 1 / 2 and weights of 1 / 4 and 3 / 4, whose products and sums float32 holds exactly;
    they were checked pixel by pixel, 4 ms of the 4K face's render), and ``out``
    already holds them. On the face 1000 px wide at 3840 x 2160 23 % of its box (the corners
    outside the mesh; 31 % for joy at 150 %) is skipped: the remap of the whole box cost
    21 ms. (Another 17 % of the box maps to itself exactly too, the outer ring's triangles
    moving by less than float32 resolves there, but inside the strips' ranges.) Identical to
    resampling the whole box (each pixel is resampled from its own map values). The map is
    off by a fraction of a pixel already: without ``src4`` it is applied through OpenCV's
    fixed-point maps (what it converts a float map to internally, block by block; converted
    once, the remap costs 40 % less; ±1 on < 1 % of the values). ``rows``: only the box's
    rows ``[r0, r1)`` (``r0`` a multiple of :data:`_STRIP_PX`); ``extent``:
    :func:`_moving_extent` of ``moving``; ``src4``: the photo as RGBA (:func:`_rgba_buffer`,
    converted where these rows read it: :func:`_to_rgba`), resampled instead through the
    float maps themselves, then made RGB (see :func:`_resample_strips`); ``scratch``: a
    (:data:`_STRIP_PX`, ``nx``, 4) uint8 buffer for that RGBA strip (else one per strip)."""
    ny, nx = map_x.shape
    gy, gx = moving.shape
    first, last = _moving_extent(moving) if extent is None else extent
    lo, hi = (0, ny) if rows is None else rows
    for r0 in range(lo, hi, _STRIP_PX):
        r1 = min(r0 + _STRIP_PX, hi)
        # pixel (x, y) interpolates nodes x // s .. x // s + 2 (and y alike; see _maps_coarse)
        j0, j1 = r0 // s, min((r1 - 1) // s + 3, gy)
        k0, k1 = min(first[j0:j1]), max(last[j0:j1])
        if k1 < k0:
            continue
        a = min(max((k0 - 2) * s, 0), nx)
        b = max(min((k1 + 1) * s, nx), a)
        if b > a and src4 is not None:
            got = cv2.remap(src4, map_x[r0:r1, a:b], map_y[r0:r1, a:b], interpolation,
                            dst=None if scratch is None else scratch[:r1 - r0, :b - a],
                            borderMode=cv2.BORDER_REPLICATE)
            cv2.cvtColor(got, cv2.COLOR_RGBA2RGB, dst=out[y0 + r0:y0 + r1, x0 + a:x0 + b])
        elif b > a:
            m1, m2 = cv2.convertMaps(map_x[r0:r1, a:b], map_y[r0:r1, a:b], cv2.CV_16SC2)
            cv2.remap(img, m1, m2, interpolation, dst=out[y0 + r0:y0 + r1, x0 + a:x0 + b],
                      borderMode=cv2.BORDER_REPLICATE)


@dataclass(eq=False)
class _Pending:
    """The interpolated maps of :func:`_maps_coarse` still to be written: the coarse maps
    ``cx, cy`` (gy, gx) to interpolate into ``full_x, full_y`` (gy s, gx s; the box's maps at
    offset ``(s, s)``), then the exact map's pixels: ``mx, my`` at the flat indices ``at``
    (n, s s) of the full maps, one row per node, the nodes' rows ``nj`` (n,) ascending (with
    ``by_offset``: (s s, n), one column per node, when no two of them write the same pixel)."""

    cx: np.ndarray
    cy: np.ndarray
    full_x: np.ndarray
    full_y: np.ndarray
    at: np.ndarray | None = None
    nj: np.ndarray | None = None
    mx: np.ndarray | None = None
    my: np.ndarray | None = None
    #: each node's lowest x, y and highest x, y of ``mx, my`` ((n,) each)
    ext: tuple[np.ndarray, ...] | None = None
    #: ``at, mx, my`` are (s s, n)
    by_offset: bool = False


def _resize_rows(p: _Pending, s: int, r0: int, r1: int) -> None:
    """Rows ``[r0, r1)`` of the box's interpolated maps (``r0`` a multiple of ``s``) written
    into ``p.full_x, p.full_y``: ``cv2.resize`` (x ``s``) of the coarse rows they read, in
    place, the same values as the whole grid's resize (the same weights; its first and last
    rows, where a part's edge clamps, are those of the whole grid's edge or lie outside the
    rows asked for). The rows it also writes above them (the ``s`` rows before, the first one
    clamped) are kept as they were; the rows below are written again by the next part."""
    gy = p.cx.shape[0]
    c0, c1 = r0 // s, min(r1 // s + 2, gy)
    fw = p.full_x.shape[1]
    for c, full in ((p.cx, p.full_x), (p.cy, p.full_y)):
        keep = full[c0 * s:s + r0].copy()
        cv2.resize(c[c0:c1], (fw, (c1 - c0) * s), dst=full[c0 * s:c1 * s],
                   interpolation=cv2.INTER_LINEAR)
        full[c0 * s:s + r0] = keep


#: Rows of the maps interpolated at a time by :func:`_resample_strips` (a multiple of
#: :data:`_STRIP_PX`)
_RESIZE_PX = 128


def _resample_strips(plan: WarpPlan, out: np.ndarray, p: _Pending, moving: np.ndarray,
                     s: int, x0: int, y0: int, ny: int, nx: int,
                     interpolation: int = cv2.INTER_LINEAR) -> None:
    """:func:`_maps_coarse`'s deferred maps written (``p``: the same maps as written whole)
    and ``out`` (of the photo's shape, its values undefined) made the photo (copied part by
    part, each part's rows just before they are resampled: in the cache then) with the box at
    ``(x0, y0)`` (``nx`` x ``ny``) resampled through them as :func:`_remap_moving` does, part
    by part of
    :data:`_RESIZE_PX` rows: each part's rows interpolated (:func:`_resize_rows`), its exact
    pixels written, then resampled while its maps are in the cache (written whole first, the
    4K face's 23 MB of maps were read back from memory). With ``cv2.INTER_LINEAR`` the photo
    is resampled as RGBA through the float maps themselves (OpenCV's vectorised path for 4
    channels and float maps, 2.1 ns a pixel against 3.2 for 3 channels through fixed-point
    maps, plus their conversion), each part's source (the range of its nodes' and exact
    pixels' maps) converted to RGBA first (:func:`_to_rgba`: 2.4 MP a frame on the 4K bench
    face, in the cache for the remap), then back to RGB into ``out``. On the 4K bench face the
    warp costs 2.5 ms less (thread CPU, 28.1 -> 25.6 ms, interleaved). Pixels: OpenCV's float
    path weighs the taps by the map's exact fraction, the fixed-point one by its nearest 1/32:
    ±1 on ~1 % of the resampled pixels; the renders (the bench expression and the six presets
    at 100 and 150 %) differ on 45,000-57,000 pixels (0.5-0.7 % of the frame), by 1.0 level
    on average over them, at most 4 (on at most 9 pixels beside a mouth corner, where later
    stages amplify it; at most 3 elsewhere)."""
    # the exact pixels' nodes by part (node row j: box rows [(j - 1) s, j s))
    starts = list(range(0, ny, _RESIZE_PX))
    cut = ([0] * (len(starts) + 1) if p.nj is None else
           [*np.searchsorted(p.nj, [r // s + 1 for r in starts]).tolist(), len(p.nj)])
    extent = _moving_extent(moving)
    src4 = None
    if interpolation == cv2.INTER_LINEAR:
        src4 = _rgba_buffer(plan)
        # the range of each node row's displacements (a pixel's map is its position plus an
        # interpolation of four nodes' of two rows: within their range) and of each part's
        # exact pixels' maps: what the part's pixels read
        gy, gx = p.cx.shape
        ex = None
        if p.ext is not None:
            have = [b > a for a, b in zip(cut[:-1], cut[1:], strict=True)]
            # (each part's from its nodes': a part without a node is not read; one more
            # value after the last node, so that every part's start is an index)
            inf = np.float32(np.inf)
            ex = [f.reduceat(np.append(e, v), cut[:-1]).tolist() for f, e, v in
                  zip((np.minimum, np.minimum, np.maximum, np.maximum), p.ext,
                      (inf, inf, -inf, -inf), strict=True)]
    fx, fy = p.full_x.reshape(-1), p.full_y.reshape(-1)
    img = plan.image
    # (every strip's RGBA resampled into the same buffer: in the cache, no allocation)
    scratch = None if src4 is None else np.empty((_STRIP_PX, nx, 4), np.uint8)
    out[:y0] = img[:y0]
    for i, r0 in enumerate(starts):
        r1 = min(r0 + _RESIZE_PX, ny)
        # (the part's rows of the photo copied first: in the cache for what reads them)
        out[y0 + r0:y0 + r1] = img[y0 + r0:y0 + r1]
        _resize_rows(p, s, r0, r1)
        a, b = cut[i], cut[i + 1]
        if b > a:
            assert p.at is not None and p.mx is not None and p.my is not None
            if p.by_offset:  # (each offset's run of the part's nodes: contiguous copies)
                at = p.at[:, a:b].reshape(-1)
                fx[at] = p.mx[:, a:b].reshape(-1)
                fy[at] = p.my[:, a:b].reshape(-1)
            else:
                at = p.at[a:b].reshape(-1)
                fx[at] = p.mx[a:b].reshape(-1)
                fy[at] = p.my[a:b].reshape(-1)
        if src4 is not None:
            # the part's columns resampled (see _remap_moving) and the photo they read
            j0, j1 = r0 // s, min((r1 - 1) // s + 3, gy)
            k0, k1 = min(extent[0][j0:j1]), max(extent[1][j0:j1])
            if k1 < k0:  # (nothing moves: no exact pixel either)
                continue
            # (a pixel of the columns [(k0 - 2) s, (k1 + 1) s) interpolates nodes k0 - 2 to
            # k1 + 2, its map within theirs)
            kk0, kk1 = max(k0 - 2, 0), min(k1 + 3, gx)
            lx, hx = cv2.minMaxLoc(p.cx[j0:j1, kk0:kk1])[:2]
            ly, hy = cv2.minMaxLoc(p.cy[j0:j1, kk0:kk1])[:2]
            b4 = [lx, ly, hx, hy]
            if ex is not None and have[i]:
                b4 = [min(b4[0], ex[0][i]), min(b4[1], ex[1][i]), max(b4[2], ex[2][i]),
                      max(b4[3], ex[3][i])]
            _to_rgba(plan, src4, (b4[0], b4[1]), (b4[2], b4[3]))
        _remap_moving(img, out, p.full_x[s:s + ny, s:s + nx],
                      p.full_y[s:s + ny, s:s + nx], moving, s, x0, y0, interpolation, (r0, r1),
                      extent, src4, scratch)
    out[y0 + ny:] = img[y0 + ny:]


def _rgba_buffer(plan: WarpPlan) -> np.ndarray:
    """The plan's (H, W, 4) uint8 scratch frame for :func:`_resample_strips` (allocated once;
    its pages take memory where they are written only). Every render converts the part it
    reads first (:func:`_to_rgba`), then reads it from the cache: a copy kept converted from
    frame to frame is read from memory, the 4K face's warp 1.9 ms slower. Thread-safe: every
    render writes the same values (the photo as RGBA) into the part it reads, before reading
    it."""
    with plan._rgba_lock:
        if plan._rgba is None:
            h, w = plan.image.shape[:2]
            plan._rgba = np.empty((h, w, 4), np.uint8)
        return plan._rgba


def bilinear_reach(shape: tuple[int, ...], lo: tuple[float, float], hi: tuple[float, float]
                   ) -> tuple[int, int, int, int]:
    """``(x0, y0, x1, y1)``: the pixels of an image of ``shape`` that a bilinear sample at any
    position in ``[lo, hi]`` (x, y each) reads, a pixel more each side, inside the image and
    never empty (a region resampled on its own gives the whole image's values there, its
    replicated border included)."""
    h, w = shape[:2]
    x0 = min(max(math.floor(lo[0]) - 2, 0), w - 1)
    y0 = min(max(math.floor(lo[1]) - 2, 0), h - 1)
    x1 = max(min(math.floor(hi[0]) + 3, w), x0 + 1)
    y1 = max(min(math.floor(hi[1]) + 3, h), y0 + 1)
    return x0, y0, x1, y1


def _to_rgba(plan: WarpPlan, buf: np.ndarray, lo: tuple[float, float],
             hi: tuple[float, float]) -> None:
    """``buf`` (:func:`_rgba_buffer`) made the photo as RGBA (alpha 255) over every pixel a
    bilinear sample (border replicated) at a position in ``[lo, hi]`` (x, y each) reads."""
    x0, y0, x1, y1 = bilinear_reach(plan.image.shape, lo, hi)
    cv2.cvtColor(plan.image[y0:y1, x0:x1], cv2.COLOR_RGB2RGBA, dst=buf[y0:y1, x0:x1])


def _moving_extent(moving: np.ndarray) -> tuple[list[int], list[int]]:
    """Each node row's first and last moving node (``gx`` and -1: none), as Python ints (the
    strips take the extremes of a few rows each). (The last from the first of the rows
    mirrored by ``cv2.flip``: numpy's argmax over a reversed view takes a slow strided path,
    0.24 ms on the 4K bench face's grid, mirrored and then searched 0.06 ms)"""
    gx = moving.shape[1]
    some = moving.any(1)
    flipped = cv2.flip(moving.view(np.uint8), 1).view(bool)
    return (np.where(some, moving.argmax(1), gx).tolist(),
            np.where(some, gx - 1 - flipped.argmax(1), -1).tolist())


def _mark(moving: np.ndarray, box: tuple[int, int, int, int], s: int, x0: int, y0: int
          ) -> None:
    """Mark as moving (in place) the nodes of :func:`_maps_coarse`'s grid whose pixels (node
    ``(j, k)``: the box's pixels ``[(k - 1) s, k s)`` and rows alike) meet ``box`` (image
    pixels; the grid's box at ``(x0, y0)``)."""
    gy, gx = moving.shape
    u0, v0, u1, v1 = box[0] - x0, box[1] - y0, box[2] - x0, box[3] - y0
    if u1 > u0 and v1 > v0:
        moving[max(v0 // s + 1, 0):min((v1 - 1) // s + 2, gy),
               max(u0 // s + 1, 0):min((u1 - 1) // s + 2, gx)] = True


def _area(box: tuple[int, int, int, int]) -> int:
    return max(box[2] - box[0], 0) * max(box[3] - box[1], 0)


#: :func:`_maps_coarse` interpolates the backward map across an edge between two triangles
#: where ``g s`` is at most this (``g``: the largest change of a map coefficient across the
#: edge, ``s`` the node spacing; the interpolation cuts such a kink by up to about ``g s / 2``
#: px); along sharper edges the map is exact. Measured on a face 1000 px wide and the presets:
#: at most 0.3 px from the exact map, 0.001 px on average
MAP_KINK_PX = 0.5

#: Along an edge whose bend ``g s`` (see :data:`MAP_KINK_PX`) is at most this, the exact map
#: is taken over the nodes within one node of it (the pixels whose four nodes straddle it and
#: a pixel more), beyond it over those within two nodes (as along an opening's edge, where the
#: map jumps and the coarse and the fine rasterizer may differ by a pixel). On the 4K bench
#: face 22 % fewer pixels take the exact map (114,000 instead of 146,000): the warp 0.5-1.7 ms
#: less (thread CPU, interleaved runs). Its renders (the bench expression and the six presets
#: at 100 and 150 %) differ from the two-node band's on 75-359 pixels, by at most 2 levels
#: (1.0 on average)
MAP_KINK_NEAR_PX = 1.0

#: A face whose inter-ocular distance is at least this (px), in a photo larger than
#: :data:`COARSE_MIN_PX` pixels, is warped through the interpolated map of :func:`_maps_coarse`
#: (nodes :data:`MAP_STEP` px apart); smaller faces and photos up to 1920 x 1080 through the
#: exact per-pixel one (their renders are unchanged by it)
COARSE_IOD = 200.0
COARSE_MIN_PX = 1920 * 1080
#: Node spacing (px) of that map
MAP_STEP = 2
#: On such a face a vertex that moves by at most this (px, along x and y) is left where it
#: is (:func:`warp`'s ``tol``): its triangles' maps would move the photo by at most as much
#: (each point's motion a convex combination of its triangle's vertices'), within the
#: interpolated map's own error (:data:`MAP_KINK_PX`), and where only such vertices move
#: (the outer ring beside the face, the wings by the ears) nothing is resampled. On the face
#: 1000 px wide at 3840 x 2160 the bench's expression moves 213 vertices instead of 234 and
#: its box loses 43 px of width: 1.4 ms of the render (thread CPU, 50.7 -> 49.3 ms). Its
#: frame differs by at most 1 grey level on 698 pixels; the presets joy, fear, anger and
#: surprise at 100 % and 150 %: at most 2 levels (anger 150 %), on at most 1,251 pixels
#: (0.015 % of the frame; none at joy 150 %, whose box is the same)
MAP_TOL = 0.2


def map_step(iod: float, shape: tuple[int, ...]) -> int:
    """:attr:`WarpPlan.map_step` for a face of inter-ocular distance ``iod`` px in a photo of
    ``shape`` (H, W, ...): :data:`MAP_STEP` for a large face in a large photo (the map's cost
    grows with the face's area, the bends it interpolates are the same), else 1 (exact)."""
    return MAP_STEP if iod >= COARSE_IOD and shape[0] * shape[1] > COARSE_MIN_PX else 1


#: Node spacing (px) of the coarse backward map of the band (see :func:`_warp_band`)
BAND_STEP = 4


def _inner_box(plan: WarpPlan, dst: np.ndarray, moved_t: np.ndarray, w: int, h: int
               ) -> tuple[int, int, int, int]:
    """The box of the moved triangles outside the band (the face and its openings) and of the
    band's own vertices (where its triangles meet, their maps differ most), grown by one band
    node spacing."""
    inner_t = moved_t[~plan._band_tri[moved_t]]
    p = np.vstack([dst[plan.triangles[inner_t]].reshape(-1, 2), dst[:len(plan.src)][plan.band]])
    pad = BAND_STEP + 2
    return (int(np.clip(np.floor(p[:, 0].min()) - pad, 0, w)),
            int(np.clip(np.floor(p[:, 1].min()) - pad, 0, h)),
            int(np.clip(np.ceil(p[:, 0].max()) + pad + 1, 0, w)),
            int(np.clip(np.ceil(p[:, 1].max()) + pad + 1, 0, h)))


def _warp_band(plan: WarpPlan, dst: np.ndarray, layers: dict[str, np.ndarray] | None,
               cavity: bool, moved_t: np.ndarray, tri_pts: np.ndarray,
               inner: tuple[int, int, int, int], box: tuple[int, int, int, int],
               interpolation: int = cv2.INTER_LINEAR) -> WarpResult:
    """The box ``box`` of the moved triangles when the band (``plan.band``: e.g. the head's
    margin on a head rotation) moves: its few large triangles stretch smoothly, so their
    backward map is evaluated exactly on a grid of nodes ``BAND_STEP`` px apart and
    interpolated bilinearly between them (exact wherever a grid cell lies in one triangle;
    across a band edge the interpolation differs from the piecewise-affine map by a fraction of
    a pixel). Inside ``inner`` (the face, its openings and a margin of one cell) and along the
    box's edges the map is the exact per-pixel one of :func:`warp`. One ``cv2.remap`` of the
    box (the band ends at the mesh's outer ring: outside it the photo does not move)."""
    img = plan.image
    bx0, by0, bx1, by1 = box
    w, h = bx1 - bx0, by1 - by0
    s = BAND_STEP
    nx, ny = -(-w // s) + 2, -(-h // s) + 2
    # node k of the grid sits where cv2.resize (x s) puts the centre of coarse pixel k:
    # box x = k * s - s / 2 - 1 / 2, i.e. pixel x <- resized column x + s
    o = -0.5 * s - 0.5
    # only the band's triangles matter on the grid: every node of another moved triangle lies
    # in ``inner``, more than a cell inside its edge, and is overwritten there
    bt = plan._band_tri[moved_t]
    _ids, cx, cy = _maps(plan, dst, layers, moved_t[bt], tri_pts[bt], bx0 + o, by0 + o, nx, ny,
                         s)
    # where the box ends on the photo's edge, the nodes beyond it are extrapolated from the two
    # nearest inside (exact within one triangle; evaluated there they would fall outside the
    # mesh, on the identity) and the pixels along that edge take the exact map (where the
    # extrapolation and the source-box clamp of :func:`_maps` differ most). Elsewhere the box
    # ends where the moved triangles do: the nodes beyond it are the identity, as the map is
    H, W = img.shape[:2]
    at_edge = (bx0 == 0, by0 == 0, bx1 == W, by1 == H)  # left, top, right, bottom
    for c in (cx, cy):
        for ax, n_px, lo_edge, hi_edge in ((1, w, at_edge[0], at_edge[2]),
                                           (0, h, at_edge[1], at_edge[3])):
            v = np.moveaxis(c, ax, 0)
            if lo_edge:
                v[0] = 2.0 * v[1] - v[2]
            if hi_edge:
                last = int((n_px - 1 - o) // s)  # the last node inside the box
                for k in range(last + 1, v.shape[0]):
                    v[k] = v[last] + (k - last) * (v[last] - v[last - 1])
    size = (nx * s, ny * s)
    map_x = cv2.resize(cx, size, interpolation=cv2.INTER_LINEAR)[s:s + h, s:s + w]
    map_y = cv2.resize(cy, size, interpolation=cv2.INTER_LINEAR)[s:s + h, s:s + w]
    # exact: the box's edges on the photo's edge and, last, the inner box
    e = s + 2
    ix0, iy0, ix1, iy1 = inner[0] - bx0, inner[1] - by0, inner[2] - bx0, inner[3] - by0
    ids = None
    strips = [b for b, on in zip(((0, e, e, h - e), (0, 0, w, e), (w - e, e, w, h - e),
                                  (0, h - e, w, h)), at_edge, strict=True) if on]
    for ex0, ey0, ex1, ey1 in (*strips, (ix0, iy0, ix1, iy1)):
        ex0, ey0, ex1, ey1 = max(ex0, 0), max(ey0, 0), min(ex1, w), min(ey1, h)
        if ex1 > ex0 and ey1 > ey0:
            ids, mx, my = _maps(plan, dst, layers, moved_t, tri_pts, bx0 + ex0, by0 + ey0,
                                ex1 - ex0, ey1 - ey0)
            map_x[ey0:ey1, ex0:ex1] = mx
            map_y[ey0:ey1, ex0:ex1] = my
    out = copy_of(img)
    out[by0:by1, bx0:bx1] = cv2.remap(img, map_x, map_y, interpolation,
                                      borderMode=cv2.BORDER_REPLICATE)
    mouth = np.zeros((h, w), bool)
    eyes = np.zeros((h, w), bool)
    if ix1 > ix0 and iy1 > iy0 and ids is not None:
        res = _finish(plan, dst, out, ids, mx, my, inner, cavity)
        mouth[iy0:iy1, ix0:ix1] = res.mouth_local
        eyes[iy0:iy1, ix0:ix1] = res.eyes_local
    return WarpResult(out, box, mouth, eyes, (map_x, map_y, box), interpolation)


def _maps(plan: WarpPlan, dst: np.ndarray, layers: dict[str, np.ndarray] | None,
          moved_t: np.ndarray, tri_pts: np.ndarray, x0: float, y0: float, nx: int, ny: int,
          step: int = 1, skip: np.ndarray | None = None
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Triangle ids (ny, nx) and the backward maps (destination -> photo) at the points
    ``(x0 + i * step, y0 + j * step)``; ``step`` 1 (and integer ``x0, y0``): every pixel of
    a box. ``skip`` (rows,) bool: the ids whose points the caller overwrites (a hook's band,
    see :func:`_evaluate`)."""
    if step == 1:
        moved_t, tri_pts = _reaching(moved_t, tri_pts, x0, y0, nx, ny)
    ids = _ids(plan, dst, moved_t, tri_pts, x0, y0, nx, ny, step)
    map_x, map_y = _evaluate(plan, ids, _table(plan, layers, moved_t, tri_pts), x0, y0, step,
                             drawn=(dst, moved_t, tri_pts), skip=skip)
    return ids, map_x, map_y


def _ids(plan: WarpPlan, dst: np.ndarray, moved_t: np.ndarray, tri_pts: np.ndarray,
         x0: float, y0: float, nx: int, ny: int, step: int = 1,
         out: np.ndarray | None = None) -> np.ndarray:
    """The id image (ny, nx) int16 or int32 at the points ``(x0 + i * step, y0 + j * step)``:
    the moved triangle there (its row in :func:`_table`), ``T`` the identity (static
    triangles, uncovered pixels), ``T + 1 + k`` the opening ``LAYERS[k]``; in ``out`` when
    given (a view of a larger id image)."""
    T = len(plan.triangles)
    # int16 while the ids fit (half the memory of int32 to fill, gather and compare: the 4K
    # face's box is 3 MP)
    if out is None:
        ids = np.full((ny, nx), T, np.int16 if T + len(LAYERS) < 1 << 15 else np.int32)
    else:
        ids = out
        ids.fill(T)
    off = np.array([x0, y0], np.float32)
    for k, name in enumerate(LAYERS):
        poly = np.round((dst[plan.holes[name]] - off) * (_ONE / step)).astype(np.int32)
        cv2.fillPoly(ids, [poly], T + 1 + k, cv2.LINE_8, _SHIFT)
    # Draw the most compressed triangles first: the rasterizer also gives a triangle the pixels
    # its edges touch, and the last triangle drawn keeps them. Well-conditioned neighbours drawn
    # later then own the shared boundary pixels, so a squashed triangle's large inverse gain
    # never extrapolates them (which shows as one-pixel lines along its edges).
    e = tri_pts[:, 1:] - tri_pts[:, :1]
    dst_area = np.abs(e[:, 0, 0] * e[:, 1, 1] - e[:, 0, 1] * e[:, 1, 0])
    order = np.argsort(dst_area / plan._src_area[moved_t], kind="stable")
    fill = cv2.fillConvexPoly
    q_all = np.round((tri_pts[order] - off) * (_ONE / step)).astype(np.int32)
    for q, t in zip(q_all, moved_t[order].tolist(), strict=True):
        fill(ids, q, t, cv2.LINE_8, _SHIFT)
    return ids


def _table(plan: WarpPlan, layers: dict[str, np.ndarray] | None, moved_t: np.ndarray,
           tri_pts: np.ndarray) -> np.ndarray:
    """(T + 1 + len(LAYERS), 6) float32: the backward affine map of every id of
    :func:`_ids` (rows of the triangles not in ``moved_t``: the identity)."""
    T = len(plan.triangles)
    table = plan._table0.copy()  # (the identity rows)
    for k, name in enumerate(LAYERS):
        fwd = layers.get(name, _IDENTITY) if layers else _IDENTITY
        table[T + 1 + k] = cv2.invertAffineTransform(np.asarray(fwd, np.float64)).reshape(-1)
    # inverse affine per moved triangle (destination -> source), closed form: with edge
    # vectors e1 = d1 - d0, e2 = d2 - d0 (destination) and f1, f2 (source),
    # src(p) = s0 + [f1 f2] [e1 e2]^-1 (p - d0). (Each term a contiguous row: the corners'
    # coordinates (6, n), the source's terms taken from the plan's; strided columns of the
    # (n, 3, 2) corners cost twice as much, for the same float64 values)
    d0x, d0y, d1x, d1y, d2x, d2y = tri_pts.reshape(-1, 6).T.astype(np.float64)
    f1x, f1y, f2x, f2y, s0x, s0y = plan._src_terms.take(moved_t, 1)
    e1x, e1y, e2x, e2y = d1x - d0x, d1y - d0y, d2x - d0x, d2y - d0y
    det = e1x * e2y - e1y * e2x
    ok = np.abs(det) > 1e-9  # degenerate destinations are never produced by the guard
    inv = 1.0 / np.where(ok, det, 1.0)
    # [e1 e2]^-1 = [[e2y, -e2x], [-e1y, e1x]] / det
    a11, a12, a21, a22 = e2y * inv, -e2x * inv, -e1y * inv, e1x * inv
    m00 = f1x * a11 + f2x * a21
    m01 = f1x * a12 + f2x * a22
    m10 = f1y * a11 + f2y * a21
    m11 = f1y * a12 + f2y * a22
    m02 = s0x - m00 * d0x - m01 * d0y
    m12 = s0y - m10 * d0x - m11 * d0y
    M = np.stack([m00, m01, m02, m10, m11, m12], 1)
    if ok.all():
        table[moved_t] = M
    else:
        table[moved_t[ok]] = M[ok]
    return table


def _evaluate(plan: WarpPlan, ids: np.ndarray, table: np.ndarray, x0: float, y0: float,
              step: int = 1, grow: float = 0.0,
              drawn: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
              skip: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The backward maps (float32, ``ids``' shape) at the points of :func:`_ids`: each
    point's affine map (its id's row of ``table``), clamped to its triangle's source box
    (grown by ``grow`` px). ``drawn``: what :func:`_ids` drew (``dst``, the moved triangles
    and their points; None: any row may be anywhere), see :func:`_risky`. ``skip``: (rows,)
    bool, the rows whose points the caller overwrites (a node hook's band): with ``drawn``,
    the maps are then evaluated only over the columns the other moved triangles and the
    openings reach (:func:`_spans`), the identity elsewhere."""
    ny, nx = ids.shape
    # per-pixel coefficients: each point's record of the table's row gathered with one
    # ``take`` (on the 1920 x 1080 and 3840 x 2160 faces cheaper than nearest-neighbour remaps
    # of the table's planes or channels, strided arithmetic on the records included), in bands
    # of rows, so the gathered coefficients never exist for the whole box (a 24 MP face's box:
    # ~200 MB of temporaries, each page faulted in on first use)
    tb = plan._src_box
    if grow:
        tb = tb + np.array([-grow, -grow, grow, grow], np.float32)
    # (boxes not grown, e.g. the exact per-pixel map's: most rows may leave theirs by the
    # rasterizer's reach, every point is clamped)
    risky = _risky(plan, table, tb, x0, y0, step, ids.shape, drawn) if grow else None
    if risky is None:
        own = skip if skip is not None and drawn is not None and step == 1 else None
        return _evaluate_clamped(ids, table, tb, x0, y0, step,
                                 None if own is None or drawn is None
                                 or ids.size < _SKIP_MIN_PX else
                                 _skip_blocks(plan, drawn, own, x0, y0, *ids.shape), own)
    xs, ys, map_x, map_y, rows = _map_grid(ids.shape, x0, y0, step)
    # (each coefficient taken from its own contiguous row of the table's transpose, by the
    # band's ids made indices once: contiguous operands throughout, the same float32
    # arithmetic; on the 4K face's coarse grid ~1 ms less than one ``take`` of 24-byte
    # records and arithmetic on their strided fields. The ids are rows of the table: the takes
    # here and below in mode "wrap", the same values without the bounds' checks of "raise",
    # 20 % faster)
    tp = np.ascontiguousarray(table.T)  # (6, rows)
    if skip is None or drawn is None:
        bands = [(r0, min(r0 + rows, ny), 0, nx) for r0 in range(0, ny, rows)]
    else:
        bands = _spans(plan, drawn, skip, x0, y0, step, ny, nx)
    for r0, r1, k0, k1 in bands:
        yr = ys[r0:r1]
        _identity_beside(map_x, map_y, xs, yr, r0, r1, k0, k1)
        if k1 <= k0:
            continue
        at = ids[r0:r1, k0:k1].astype(np.intp)
        xk = xs[:, k0:k1]
        whole = k0 == 0 and k1 == nx
        for full, k in ((map_x, 0), (map_y, 3)):
            # (a part of the rows: computed contiguous and copied in once, numpy's passes
            # over strided rows cost several times as much)
            out = np.multiply(tp[k].take(at, mode="wrap"), xk,
                              out=full[r0:r1] if whole else None)
            c = tp[k + 1].take(at, mode="wrap")
            c *= yr
            out += c
            out += tp[k + 2].take(at, mode="wrap")
            if not whole:
                full[r0:r1, k0:k1] = out
    if risky.any():
        _clamp_rows(ids, tb, x0, y0, step, map_x, map_y, risky, drawn)
    return map_x, map_y


#: Rows of points per band of :func:`_spans` (each band evaluated over its own columns: the
#: wider the band, the more columns outside the moving part it spans; the narrower, the more
#: calls per frame)
_SPAN_ROWS = 32


def _spans(plan: WarpPlan, drawn: tuple[np.ndarray, np.ndarray, np.ndarray], skip: np.ndarray,
           x0: float, y0: float, step: int, ny: int, nx: int) -> list[tuple[int, int, int, int]]:
    """Bands of :data:`_SPAN_ROWS` rows of the grid of :func:`_ids` (``ny`` x ``nx`` points
    ``(x0 + i step, y0 + j step)``), each ``(r0, r1, k0, k1)`` with the columns ``[k0, k1)``
    that the moved triangles not in ``skip`` (bool per table row) and the openings may reach
    (their boxes grown by two points, twice the rasterizer's reach): every other point of the
    band carries the identity's row or a skipped one. On the 4K face the hook's band (a fifth
    of the grid) and the box's corners outside the mesh: 40 % of the grid's points, 1.4 ms of
    the coarse map's evaluation."""
    dst, moved_t, tri_pts = drawn
    keep = ~skip.take(moved_t)
    lo, hi = _corner_extremes(tri_pts[keep])
    loops = [dst[plan.holes[name]] for name in LAYERS]
    lo = np.vstack([lo, *[p.min(0, keepdims=True) for p in loops]]).astype(np.float64)
    hi = np.vstack([hi, *[p.max(0, keepdims=True) for p in loops]]).astype(np.float64)
    # each box in points (grown by 2), clipped to the grid; its first and last band
    k_lo = np.clip(np.floor((lo[:, 0] - x0) / step) - 2, 0, nx).astype(np.intp)
    k_hi = np.clip(np.ceil((hi[:, 0] - x0) / step) + 3, 0, nx).astype(np.intp)
    j_lo = np.clip(np.floor((lo[:, 1] - y0) / step) - 2, 0, ny - 1).astype(np.intp)
    j_hi = np.clip(np.ceil((hi[:, 1] - y0) / step) + 2, 0, ny - 1).astype(np.intp)
    B = _SPAN_ROWS
    nb = -(-ny // B)
    b0, b1 = j_lo // B, j_hi // B
    cnt = b1 - b0 + 1
    which = np.repeat(np.arange(len(cnt)), cnt)  # (box, band) pairs
    band = np.repeat(b0, cnt) + (np.arange(len(which)) - np.repeat(np.cumsum(cnt) - cnt, cnt))
    first = np.full(nb, nx, np.intp)
    last = np.zeros(nb, np.intp)
    np.minimum.at(first, band, k_lo.take(which))
    np.maximum.at(last, band, k_hi.take(which))
    return [(b * B, min(b * B + B, ny), k0, k1)
            for b, (k0, k1) in enumerate(zip(first.tolist(), last.tolist(), strict=True))]


def _map_grid(shape: tuple[int, ...], x0: float, y0: float, step: int
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """The evaluations' common frame: the node columns' x (1, nx) and rows' y (ny, 1), the
    empty maps (ny, nx) and the rows per band (:data:`_MAP_BAND_PX`)."""
    ny, nx = shape
    xs = (x0 + step * np.arange(nx)).astype(np.float32)[None, :]
    ys = (y0 + step * np.arange(ny)).astype(np.float32)[:, None]
    return (xs, ys, np.empty((ny, nx), np.float32), np.empty((ny, nx), np.float32),
            max(1, _MAP_BAND_PX // max(nx, 1)))


def _evaluate_clamped(ids: np.ndarray, table: np.ndarray, tb: np.ndarray, x0: float,
                      y0: float, step: int,
                      blocks: list[tuple[int, int, int, int]] | None = None,
                      own: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_evaluate` with every point clamped to its row's box ``tb``: the six
    coefficients and the four bounds of each point's row gathered in one ``take`` of a
    (rows, 10) table (a 40-byte record per point: on the 1920 x 1080 face's box half the cost
    of three nearest-neighbour remaps of 3, 3 and 4 channels), then the same float32
    arithmetic on its channels. ``blocks`` (:func:`_blocks`): evaluated only over their
    columns, the identity beside them (see :func:`_evaluate_blocks`). ``own`` (rows,) bool:
    the rows a hook overwrites (its ``lut``) take the identity's record, so that their points
    carry their own position wherever they are evaluated or not (the hook then writes only
    where its map differs from that: the jaw's shift, whose fade ends above the band's lower
    part)."""
    ny, nx = ids.shape
    rec = np.concatenate([table, tb], axis=1)  # (rows, 10): a b c (x), d e f (y), box
    if own is not None:
        rec[own] = rec[len(table) - 1 - len(LAYERS)]
    xs, ys, map_x, map_y, rows = _map_grid(ids.shape, x0, y0, step)
    if blocks is not None:
        _evaluate_blocks(ids, rec, xs, ys, map_x, map_y, blocks)
        return map_x, map_y
    for r0 in range(0, ny, rows):
        r1 = min(r0 + rows, ny)
        _apply_records(rec.take(ids[r0:r1], 0, mode="wrap"), xs, ys[r0:r1], map_x[r0:r1],
                       map_y[r0:r1])
    return map_x, map_y


def _identity_beside(map_x: np.ndarray, map_y: np.ndarray, xs: np.ndarray, yr: np.ndarray,
                     r0: int, r1: int, k0: int, k1: int) -> None:
    """Rows ``[r0, r1)`` of the maps outside the columns ``[k0, k1)``: the points' own x and
    y (``xs`` (1, cols), ``yr`` (rows, 1)), what the identity's row (1 x + 0 y + 0 and
    0 x + 1 y + 0) evaluates to there exactly: the columns no evaluated point reaches."""
    if k0 > 0 or k1 < xs.shape[1]:
        map_x[r0:r1, :k0] = xs[:, :k0]
        map_x[r0:r1, k1:] = xs[:, k1:]
        map_y[r0:r1, :k0] = yr
        map_y[r0:r1, k1:] = yr


def _apply_records(g: np.ndarray, xs: np.ndarray, yr: np.ndarray, mx: np.ndarray,
                   my: np.ndarray) -> None:
    """The points' maps from their gathered records ``g`` (rows, cols, 10: a b c, d e f, the
    box), in place into ``mx``, ``my``: ``a x + b y + c`` and ``d x + e y + f`` clamped to the
    box, in float32 (``xs`` (1, cols), ``yr`` (rows, 1) the points' coordinates)."""
    np.multiply(g[..., 0], xs, out=mx)
    mx += g[..., 1] * yr
    mx += g[..., 2]
    np.multiply(g[..., 3], xs, out=my)
    my += g[..., 4] * yr
    my += g[..., 5]
    np.clip(mx, g[..., 6], g[..., 8], out=mx)
    np.clip(my, g[..., 7], g[..., 9], out=my)


def _evaluate_blocks(ids: np.ndarray, rec: np.ndarray, xs: np.ndarray, ys: np.ndarray,
                     map_x: np.ndarray, map_y: np.ndarray,
                     blocks: list[tuple[int, int, int, int]]) -> None:
    """:func:`_evaluate_clamped`'s maps (in place) block by block of rows ``(r0, r1, k0,
    k1)``: its points evaluated over the columns ``[k0, k1)``, the identity beside them (the
    points there carry the identity's row, whose map gives exactly their own x and y inside
    its box, the photo's, or a row the caller overwrites: a hook's band). On the 1080p bench
    face the jaw's band beside the face and below the chin: 30 % of the exact map's box."""
    for r0, r1, k0, k1 in blocks:
        yr = ys[r0:r1]
        _identity_beside(map_x, map_y, xs, yr, r0, r1, k0, k1)
        if k1 <= k0:
            continue
        _apply_records(rec.take(ids[r0:r1, k0:k1], 0, mode="wrap"), xs[:, k0:k1], yr,
                       map_x[r0:r1, k0:k1], map_y[r0:r1, k0:k1])


#: The exact map's box skips the points a hook overwrites (:func:`_skip_blocks`) from this
#: many pixels: the blocks' own cost (~0.1 ms) exceeds what they save on a smaller box (the
#: sample's at 431 x 591, 20 000 px: +0.08 ms a frame; the 1080p face's 127 000: -0.18 ms)
_SKIP_MIN_PX = 60_000

#: :func:`_blocks` joins bands of rows into one block while that evaluates at most this many
#: more points than the bands apart (a block's dozen numpy calls cost as much as ~3000 points)
_BLOCK_JOIN_PX = 3000


def _skip_blocks(plan: WarpPlan, drawn: tuple[np.ndarray, np.ndarray, np.ndarray],
                 skip: np.ndarray, x0: float, y0: float, ny: int, nx: int
                 ) -> list[tuple[int, int, int, int]]:
    """:func:`_spans` of the exact per-pixel map (the box's pixels ``(x0 + i, y0 + j)``),
    each band's columns from every box at once (a (bands, boxes) overlap: the bands' few
    dozen numpy calls of :func:`_spans` cost 0.15 ms on the 1080p face's, more than the
    evaluation it saves), joined into blocks (:func:`_blocks`)."""
    dst, moved_t, tri_pts = drawn
    B = _SPAN_ROWS
    nb = -(-ny // B)
    lo, hi = _corner_extremes(tri_pts)
    # the openings' loops' boxes too (their ids are evaluated: a layer's own map)
    starts, k = [], 0
    for name in LAYERS:
        starts.append(k)
        k += len(plan.holes[name])
    loops = dst.take(np.concatenate([plan.holes[name] for name in LAYERS]), 0)
    org = np.array([x0, y0], np.float64)
    # (boxes in pixels of the grid: a triangle draws pixels within a pixel of it; grown by 2)
    L = np.floor(np.concatenate([lo, np.minimum.reduceat(loops, starts)]) - org)
    H = np.ceil(np.concatenate([hi, np.maximum.reduceat(loops, starts)]) - org)
    keep = np.concatenate([~skip.take(moved_t), np.ones(len(LAYERS), bool)])
    rb = (B * np.arange(nb))[:, None]
    meet = (L[:, 1] < rb + (B + 2)) & (H[:, 1] >= rb - 2) & keep
    first = np.where(meet, L[:, 0], np.inf).min(1).tolist()
    last = np.where(meet, H[:, 0], -np.inf).max(1).tolist()
    spans = []
    for b, (a, c) in enumerate(zip(first, last, strict=True)):
        k0 = min(max(int(a) - 2, 0), nx) if a != np.inf else nx
        k1 = min(max(int(c) + 3, 0), nx) if c != -np.inf else 0
        spans.append((b * B, min(b * B + B, ny), k0, k1))
    return _blocks(spans)


def _blocks(spans: list[tuple[int, int, int, int]]) -> list[tuple[int, int, int, int]]:
    """:func:`_spans`' bands of rows joined into blocks ``(r0, r1, k0, k1)`` (consecutive
    bands, their columns' union) while that adds at most :data:`_BLOCK_JOIN_PX` points."""
    out: list[tuple[int, int, int, int]] = []
    cost = 0
    for r0, r1, k0, k1 in spans:
        if k1 <= k0:
            k0 = k1 = 0
        if out:
            a0, a1, c0, c1 = out[-1]
            if c1 <= c0:
                c0, c1 = k0, k1
            elif k1 > k0:
                c0, c1 = min(c0, k0), max(c1, k1)
            own = (r1 - r0) * (k1 - k0)
            joined = (r1 - a0) * (c1 - c0)
            if joined - cost - own <= _BLOCK_JOIN_PX:
                out[-1] = (a0, r1, c0, c1)
                cost += own
                continue
        out.append((r0, r1, k0, k1))
        cost = (r1 - r0) * (k1 - k0)
    return out


#: The rasterizer (``cv2.fillConvexPoly``/``fillPoly``, sub-pixel vertices) gives a polygon
#: only pixels within this distance (its pixels, each axis) of it: the pixels its edges touch
#: (at most 0.71 px away on 20 000 random and squashed triangles) and 1/32 px of rounding
_RASTER_REACH = 1.0


def _risky(plan: WarpPlan, table: np.ndarray, tb: np.ndarray, x0: float, y0: float,
           step: int, shape: tuple[int, int],
           drawn: tuple[np.ndarray, np.ndarray, np.ndarray] | None) -> np.ndarray | None:
    """(rows,) bool: the rows of ``table`` whose affine map may leave their source box ``tb``
    at a point of :func:`_ids` that carries them (None: clamp every point, most rows may).

    A triangle's points lie within :data:`_RASTER_REACH` rasterizer pixels of it (an
    opening's of its loop): its map takes them to its source triangle (the map of its
    destination vertices, computed here with the table's float32 coefficients) moved by at
    most that reach times the map's gain, plus what float32 arithmetic may err; the identity
    row's points span the grid, its map is extreme at the grid's corners. On a face the
    coarse map's rows all stay inside (their boxes are grown by two nodes); the exact map's
    (grown by one pixel) mostly do not."""
    ny, nx = shape
    n = len(table)
    T = n - 1 - len(LAYERS)
    if drawn is None:
        return None
    dst, moved_t, tri_pts = drawn
    c = table.astype(np.float64)
    b = tb.astype(np.float64)
    risky = np.zeros(n, bool)
    xa, ya = x0 + step * (nx - 1), y0 + step * (ny - 1)
    groups = [(np.array([T]), np.array([[[x0, y0], [xa, y0], [x0, ya], [xa, ya]]]), 0.0),
              (moved_t, tri_pts.astype(np.float64), _RASTER_REACH * step)]
    groups += [(np.array([T + 1 + k]), dst[plan.holes[name]][None].astype(np.float64),
                _RASTER_REACH * step) for k, name in enumerate(LAYERS)]
    for rows, pts, reach in groups:
        if not len(rows):
            continue
        big = np.abs(pts).max(1)  # (m, 2)
        for k in (0, 1):
            a0, a1, a2 = c[rows, 3 * k, None], c[rows, 3 * k + 1, None], c[rows, 3 * k + 2, None]
            v = a0 * pts[..., 0] + a1 * pts[..., 1] + a2
            g0, g1 = np.abs(a0[:, 0]), np.abs(a1[:, 0])
            err = (1e-6 * (g0 * big[:, 0] + g1 * big[:, 1] + np.abs(a2[:, 0]) + 1.0)
                   + (g0 + g1) * reach)
            risky[rows] |= ((v.min(1) - err < b[rows, k]) | (v.max(1) + err > b[rows, k + 2]))
    # (the identity's and the openings' rows: every point of the grid, of an opening's box)
    return None if risky[T:].any() or 4 * np.count_nonzero(risky) > n else risky


#: :func:`_clamp_rows` looks for the points of up to this many triangles box by box
_CLAMP_EACH = 16


def _clamp_rows(ids: np.ndarray, tb: np.ndarray, x0: float, y0: float, step: int,
                map_x: np.ndarray, map_y: np.ndarray, risky: np.ndarray,
                drawn: tuple[np.ndarray, np.ndarray, np.ndarray] | None) -> None:
    """:func:`_evaluate`'s maps clamped to the source boxes ``tb`` (in place) at the points
    whose row is ``risky`` (looked for in those triangles' boxes only, grown by two
    rasterizer pixels). Up to :data:`_CLAMP_EACH` such triangles, each in its own box (the
    union of a few squashed triangles' boxes spans much of a face: on the 4K bench face
    four lip triangles', 190,000 of the coarse grid's nodes looked up, 0.4 ms)."""
    ny, nx = ids.shape
    assert drawn is not None
    _, moved_t, tri_pts = drawn
    hit = risky[moved_t]
    if not hit.any():
        return
    fx, fy = map_x.reshape(-1), map_y.reshape(-1)
    each = np.flatnonzero(hit)
    if len(each) <= _CLAMP_EACH:
        los, his = tri_pts[each].min(1).tolist(), tri_pts[each].max(1).tolist()
        for r, lo_t, hi_t in zip(moved_t[each].tolist(), los, his, strict=True):
            i0 = max(math.floor((lo_t[0] - x0) / step) - 2, 0)
            j0 = max(math.floor((lo_t[1] - y0) / step) - 2, 0)
            i1 = min(math.ceil((hi_t[0] - x0) / step) + 3, nx)
            j1 = min(math.ceil((hi_t[1] - y0) / step) + 3, ny)
            if i1 <= i0 or j1 <= j0:
                continue
            jj, ii = np.nonzero(ids[j0:j1, i0:i1] == r)
            if not len(jj):
                continue
            at = (jj + j0) * nx + (ii + i0)
            b = tb[r]
            fx[at] = np.clip(fx.take(at), b[0], b[2])
            fy[at] = np.clip(fy.take(at), b[1], b[3])
        return
    pts = tri_pts[hit]
    lo, hi = pts.min((0, 1)), pts.max((0, 1))
    i0 = max(int(np.floor((lo[0] - x0) / step)) - 2, 0)
    j0 = max(int(np.floor((lo[1] - y0) / step)) - 2, 0)
    i1 = min(int(np.ceil((hi[0] - x0) / step)) + 3, nx)
    j1 = min(int(np.ceil((hi[1] - y0) / step)) + 3, ny)
    if i1 <= i0 or j1 <= j0:
        return
    sub = ids[j0:j1, i0:i1]
    k = np.flatnonzero(risky.take(sub, mode="wrap"))
    if not len(k):
        return
    rid = sub.reshape(-1).take(k)
    jj, ii = np.divmod(k, i1 - i0)
    at = (jj + j0) * nx + (ii + i0)
    box = tb.take(rid, 0)
    fx[at] = np.clip(fx.take(at), box[:, 0], box[:, 2])
    fy[at] = np.clip(fy.take(at), box[:, 1], box[:, 3])


def _maps_coarse(plan: WarpPlan, dst: np.ndarray, layers: dict[str, np.ndarray] | None,
                 moved_t: np.ndarray, tri_pts: np.ndarray, x0: int, y0: int, nx: int, ny: int,
                 s: int, reads: list[tuple[int, int, int, int]] | None = None,
                 hook: NodeHook | None = None, defer: bool = False
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, _Pending | None]:
    """:func:`_maps` of the box ``(x0, y0, x0 + nx, y0 + ny)`` with the map evaluated on
    nodes ``s`` px apart and interpolated bilinearly (``cv2.resize``): the ids are exact (the
    openings' masks, the hook's band come from them) where they are read: in the openings'
    boxes, at the exact map's pixels and in ``reads`` (boxes, image pixels; None: everywhere),
    elsewhere they may say ``T`` (see :func:`_reaching_boxes`) or, outside the box of those
    pixels, anything (not drawn); the map is exact wherever a
    pixel's four
    nodes lie in one triangle (it is affine there) and continuous across triangle edges,
    where the interpolation cuts the kink of the piecewise-affine map by a fraction of a pixel
    (see :func:`map_step`). Where it jumps (an opening's edge: the eyeball and the mouth
    interior move on their own), every pixel near the jump takes the exact per-pixel map.
    ``hook`` (see :class:`NodeHook`): its map replaces the map at the nodes it gives (the
    jaw's band: the chin riding over the neck, :mod:`jawband`; its shift is smooth, the
    interpolation between nodes 2 px apart is off by < 0.25 px against the hook's pixel by
    pixel map: 0.21 px at most, 0.0004 px on average on the 4K bench face) and at the exact
    map's pixels; the edges between its triangles and other moved ones take the exact map (its
    map does not meet theirs with the table's bends: up to 3.7 px off along the band's ends
    when interpolated). Also returns the grid's nodes (gy, gx) bool that lie in a moved
    triangle or an opening, except those a hook put on the identity,
    or whose pixels took the exact map (node ``(j, k)`` at box pixel ``((k - 1) s + (s - 1) / 2,
    (j - 1) s + (s - 1) / 2)``, the nearest node of the pixels ``[(k - 1) s, k s)``).
    ``defer``: the maps are returned unwritten, with what :func:`_resample_strips` writes
    into them (the returned :class:`_Pending`; None without ``defer``)."""
    T = len(plan.triangles)
    table = _table(plan, layers, moved_t, tri_pts)
    # node k sits where cv2.resize (x s) puts the centre of coarse pixel k: box x =
    # k s - s / 2 - 1 / 2, i.e. pixel x <- resized column x + s (as the band's grid)
    o = -0.5 * s - 0.5
    gx, gy = -(-nx // s) + 2, -(-ny // s) + 2
    nid = _ids(plan, dst, moved_t, tri_pts, x0 + o, y0 + o, gx, gy, s)
    # (a node the coarse rasterizer gives a triangle lies up to s px outside it: its source
    # box is grown by as much; nodes near a squashed triangle are replaced below)
    # (the hook's band is overwritten by its own map below: not evaluated)
    cx, cy = _evaluate(plan, nid, table, x0 + o, y0 + o, s, 2.0 * s, (dst, moved_t, tri_pts),
                       None if hook is None else hook.lut)
    # the hook's map at its nodes (those it leaves on the identity: still, see below)
    still = None if hook is None else _hook_nodes(hook, nid, cx, cy, x0 + o, y0 + o, s)
    size = (gx * s, gy * s)
    full_x: np.ndarray
    full_y: np.ndarray
    if defer:  # (interpolated strip by strip by :func:`_resample_strips`)
        full_x = np.empty((gy * s, gx * s), np.float32)
        full_y = np.empty_like(full_x)
    else:
        full_x = cv2.resize(cx, size, interpolation=cv2.INTER_LINEAR)
        full_y = cv2.resize(cy, size, interpolation=cv2.INTER_LINEAR)
    map_x, map_y = full_x[s:s + ny, s:s + nx], full_y[s:s + ny, s:s + nx]
    pending = _Pending(cx, cy, full_x, full_y) if defer else None
    # the nodes near an edge where the map jumps (an opening's) or bends by more than the
    # interpolation may cut (:data:`MAP_KINK_PX`; a squashed triangle, e.g. the closed lips of
    # a photo whose mouth is open, bends it by its whole source across a pixel or two), grown
    # by two nodes (a pixel's cell is within one node of its nearest node; the coarse and the
    # fine rasterizer differ by a pixel); along an edge that bends it by at most
    # :data:`MAP_KINK_NEAR_PX` by one node (``near``; the others in ``far``)
    jac = table[:T + 1][:, [0, 1, 3, 4]]
    et = plan._edge_t
    bend = np.abs(jac[et[:, 0]] - jac[et[:, 1]]).max(1)
    kinked = bend > MAP_KINK_PX / s
    strong = bend > MAP_KINK_NEAR_PX / s
    if hook is not None:
        # the hook's map against the moved triangles' beside it (the chin's along the jaw
        # line): its bends are not the table's, those edges take the exact map (two nodes)
        lut = hook.lut
        moved = np.zeros(T + 1, bool)
        moved[moved_t] = True
        strong |= (lut.take(et[:, 0]) != lut.take(et[:, 1])) & moved.take(et).all(1)
    org = np.array([x0 + o, y0 + o], np.float32)
    lines = [np.round((dst[plan.holes[name]] - org) * (_ONE / s)).astype(np.int32)
             for name in LAYERS]
    near = np.zeros((gy, gx), np.uint8)
    far = np.zeros((gy, gx), np.uint8)
    cv2.polylines(far, lines, True, 1, 1, cv2.LINE_8, _SHIFT)
    for grid, which in ((near, kinked & ~strong), (far, strong)):
        sharp = plan._edge_v[which]
        if len(sharp):
            seg = np.round((dst[sharp] - org) * (_ONE / s)).astype(np.int32)
            cv2.polylines(grid, seg, False, 1, 1, cv2.LINE_8, _SHIFT)
            lines.append(seg.reshape(-1, 2))
    # dilated and searched over the lines' box only (grown by the dilation's reach and a node
    # for the rounding): the openings and the sharp edges lie in the face, the grid spans its
    # whole box (dilate + nonzero of the grid: 4 ms on the face 1000 px wide)
    drawn = np.concatenate(lines)
    (gx0, gy0), (gx1, gy1) = drawn.min(0) >> _SHIFT, drawn.max(0) >> _SHIFT
    gx0, gy0 = max(int(gx0) - 3, 0), max(int(gy0) - 3, 0)
    gx1, gy1 = min(int(gx1) + 4, gx), min(int(gy1) + 4, gy)
    moving = nid != T
    if still is not None:
        moving[still[0], still[1]] &= ~still[2]
    if gx1 <= gx0 or gy1 <= gy0:
        nj = nk = np.zeros(0, np.intp)
    else:
        # (OpenCV's list of the nonzero points: the same points in the same order as
        # np.nonzero's, 3 times faster)
        grown = cv2.dilate(far[gy0:gy1, gx0:gx1], np.ones((5, 5), np.uint8))
        cv2.bitwise_or(grown, cv2.dilate(near[gy0:gy1, gx0:gx1], np.ones((3, 3), np.uint8)),
                       dst=grown)
        pts = cv2.findNonZero(grown)
        if pts is None:
            nj = nk = np.zeros(0, np.intp)
        else:
            pts = pts.reshape(-1, 2)  # (x, y) each
            nk = pts[:, 0].astype(np.intp) + gx0
            nj = pts[:, 1].astype(np.intp) + gy0
            # (their pixels are written below: moving, as the dilated lines' nodes are)
            sub = moving[gy0:gy1, gx0:gx1]
            np.logical_or(sub, grown.view(bool), out=sub)
    # the exact ids where they are read (the rasterizer's cost grows with the area it fills:
    # the forehead and the cheeks beside the face's features are not drawn)
    near_t = None
    if reads is None:
        where = [(x0, y0, x0 + nx, y0 + ny)]
    else:
        where = [*reads, *_opening_boxes(plan, dst)]
        if len(nj) and _NEAR_TILE:
            # (the triangles near the exact map's nodes themselves, not near their box)
            near_t = _reaching_nodes(tri_pts, nj, nk, s, x0, y0, (gy, gx))
        elif len(nj):
            where.append((x0 + (int(nk.min()) - 1) * s, y0 + (int(nj.min()) - 1) * s,
                          x0 + int(nk.max()) * s, y0 + int(nj.max()) * s))
    # drawn over the box of the pixels read only, the rest of the box left undefined (the
    # rasterizer's cost follows the area it fills, clipped to the image): on the 4K bench face
    # the neck below the jaw line, the wings by the ears and the top of the forehead are not
    # filled, 0.6 ms of the warp (thread CPU, warp alone). The ids inside are those of the
    # whole box but for a few pixels along the triangles' edges that cross the drawn box's
    # edge (OpenCV draws a polygon's outline as lines clipped to the image, their steps
    # differ): 25 ids of the 4K bench face, the map at 3 of its pixels; its renders (the
    # bench expression, the six presets at 100 and 150 %) differ by 1 grey level on at most
    # 3 pixels (9 in all), 8 of the 13 not at all. Only a large face's map draws a part
    # (``reads`` given): the exact per-pixel map's ids are unchanged
    if reads is None:
        a0, b0, a1, b1 = 0, 0, nx, ny
    else:
        a0, b0, a1, b1 = nx, ny, 0, 0
        for c0, r0, c1, r1 in where:
            a0, b0 = min(a0, max(c0 - x0, 0)), min(b0, max(r0 - y0, 0))
            a1, b1 = max(a1, min(c1 - x0, nx)), max(b1, min(r1 - y0, ny))
        if len(nj):  # (the exact map's pixels)
            a0 = min(a0, max((int(nk.min()) - 1) * s, 0))
            b0 = min(b0, max((int(nj.min()) - 1) * s, 0))
            a1, b1 = max(a1, min(int(nk.max()) * s, nx)), max(b1, min(int(nj.max()) * s, ny))
    ids = np.empty((ny, nx), np.int16 if T + len(LAYERS) < 1 << 15 else np.int32)
    if a1 > a0 and b1 > b0:
        _ids(plan, dst, *_reaching_boxes(moved_t, tri_pts, where, (x0, y0, nx, ny), near_t),
             x0 + a0, y0 + b0, a1 - a0, b1 - b0, out=ids[b0:b1, a0:a1])
    if not len(nj):
        return ids, map_x, map_y, moving, pending
    # node (j, k) is the nearest node of the pixels x in [(k - 1) s, k s) (and y alike):
    # its first pixel's flat index (of the ids, of the resized maps) and position per node,
    # its s x s pixels at fixed offsets from it (2-d fancy indexing and a mask of the (n, s, s)
    # pixels cost 3 ms more), offset by offset: (s s, n) (the (n, s s) layout's short rows
    # cost numpy 4 times as much); only the nodes on the box's edge have pixels outside it
    d = np.arange(s)
    dx, dy = np.tile(d, s), np.repeat(d, s)
    fw = full_x.shape[1]
    aligned = bool((nk >= 1).all() and (nk * s <= nx).all() and (nj >= 1).all()
                   and (nj * s <= ny).all())
    if aligned:
        px0, py0 = (nk - 1) * s, (nj - 1) * s
        flat = (dy * nx + dx)[:, None] + (py0 * nx + px0)
        at = (dy * fw + dx)[:, None] + (nj * (s * fw) + nk * s)
        # (float32 sums: the same either way round)
        xs = dx.astype(np.float32)[:, None] + (px0 + x0).astype(np.float32)
        ys = dy.astype(np.float32)[:, None] + (py0 + y0).astype(np.float32)
    elif pending is not None:
        # (the (s s, n) layout kept for the deferred maps: a pixel outside the box takes the
        # nearest one inside, written again with its own exact map)
        px = np.clip(dx[:, None] + (nk - 1) * s, 0, nx - 1)
        py = np.clip(dy[:, None] + (nj - 1) * s, 0, ny - 1)
        flat, at = py * nx + px, (py + s) * fw + (px + s)
        xs, ys = (px + x0).astype(np.float32), (py + y0).astype(np.float32)
    else:
        px = ((nk - 1) * s)[:, None] + dx
        py = ((nj - 1) * s)[:, None] + dy
        inside = (px >= 0) & (px < nx) & (py >= 0) & (py < ny)
        px, py = px[inside], py[inside]
        flat, at = py * nx + px, (py + s) * fw + (px + s)
        xs, ys = (px + x0).astype(np.float32), (py + y0).astype(np.float32)
    if flat.size:
        pid = ids.reshape(-1).take(flat.ravel(), mode="wrap")
        xs, ys = xs.ravel(), ys.ravel()
        mx, my = _evaluate_at(plan, pid, table, xs, ys)
        if hook is not None:  # (the hook's pixels take its map)
            k = np.flatnonzero(hook.lut.take(pid, mode="wrap"))
            if len(k):
                mx[k], my[k] = hook.points(xs.take(k), ys.take(k))
        if pending is not None:
            # (written part by part after each part's interpolation: node by node, each
            # part's nodes' pixels contiguous, the nodes in the order of their rows)
            mx, my = mx.reshape(at.shape), my.reshape(at.shape)
            pending.nj = nj
            if aligned:
                # (no two nodes share a pixel: the order of the writes is free, the (s s, n)
                # layout kept; its transpose, element by element, cost 0.35 ms on the 4K
                # bench face)
                pending.at, pending.mx, pending.my = at, mx, my
                pending.by_offset = True
            else:
                pending.at = np.ascontiguousarray(at.T)
                pending.mx, pending.my = np.ascontiguousarray(mx.T), np.ascontiguousarray(my.T)
            pending.ext = (mx.min(0), my.min(0), mx.max(0), my.max(0))
        else:
            at = at.ravel()
            full_x.reshape(-1)[at] = mx
            full_y.reshape(-1)[at] = my
    return ids, map_x, map_y, moving, pending


def _hook_nodes(hook: NodeHook, nid: np.ndarray, cx: np.ndarray, cy: np.ndarray,
               x0: float, y0: float, s: int) -> tuple[slice, slice, np.ndarray] | None:
    """The hook's map at the nodes ``nid`` gives it (``hook.lut``) in ``cx, cy`` (in place;
    node ``(j, k)`` at ``(x0 + k s, y0 + j s)``), looked for in ``hook.box`` (grown by two
    nodes); returns the part of the grid looked at and its nodes the hook put on the identity
    (each exactly at its own position: the pixels that interpolate such nodes and the
    identity's map to themselves), None when it has no node."""
    gy, gx = nid.shape
    k0, j0 = max(int((hook.box[0] - x0) // s) - 2, 0), max(int((hook.box[1] - y0) // s) - 2, 0)
    k1 = min(int((hook.box[2] - x0) // s) + 3, gx)
    j1 = min(int((hook.box[3] - y0) // s) + 3, gy)
    if k1 <= k0 or j1 <= j0:
        return None
    sub = (slice(j0, j1), slice(k0, k1))
    band = hook.lut.take(nid[sub], mode="wrap")
    if not band.any():
        return None
    mx, my = hook.nodes(x0 + s * k0, y0 + s * j0, s, k1 - k0, j1 - j0)
    m8 = band.view(np.uint8)
    cv2.copyTo(mx, m8, cx[sub])
    cv2.copyTo(my, m8, cy[sub])
    # (the nodes' positions as _map_grid's)
    same = mx == (x0 + s * np.arange(k0, k1)).astype(np.float32)[None, :]
    same &= my == (y0 + s * np.arange(j0, j1)).astype(np.float32)[:, None]
    same &= band
    return sub[0], sub[1], same


@runtime_checkable
class NodeHook(Protocol):
    """A hook (see :func:`warp`) that also gives its map at any points, for the interpolated
    map of :func:`_maps_coarse`: its ids (``lut``: (T + 4,) bool, True for the ids whose map it
    replaces), ``box`` (image pixels) where they lie, ``points(xs, ys)`` its map there."""

    box: tuple[int, int, int, int]
    lut: np.ndarray

    def points(self, xs: np.ndarray, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...

    def nodes(self, x0: float, y0: float, s: int, nx: int, ny: int
              ) -> tuple[np.ndarray, np.ndarray]: ...


def _reaching(moved_t: np.ndarray, tri_pts: np.ndarray, x0: float, y0: float, nx: int,
              ny: int) -> tuple[np.ndarray, np.ndarray]:
    """The moved triangles (ids, points) that reach the box (the others draw nothing in it)."""
    if not len(moved_t):
        return moved_t, tri_pts
    lo, hi = _corner_extremes(tri_pts)
    keep = ((hi[:, 0] >= x0 - 1) & (lo[:, 0] <= x0 + nx + 1)
            & (hi[:, 1] >= y0 - 1) & (lo[:, 1] <= y0 + ny + 1))
    return (moved_t, tri_pts) if keep.all() else (moved_t[keep], tri_pts[keep])


def _corner_extremes(tri_pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each triangle's (n, 3, 2) lowest and highest x and y, (n, 2) each: ``min(1)`` and
    ``max(1)`` as element-wise minima and maxima of the corners (a reduction over an axis of
    3 costs several times more)."""
    a, b, c = tri_pts[:, 0], tri_pts[:, 1], tri_pts[:, 2]
    return np.minimum(np.minimum(a, b), c), np.maximum(np.maximum(a, b), c)


def _reaching_boxes(moved_t: np.ndarray, tri_pts: np.ndarray,
                    boxes: list[tuple[int, int, int, int]], grid: tuple[int, int, int, int],
                    more: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The moved triangles (ids, points) that reach one of ``boxes`` (image pixels, x0, y0,
    x1, y1) and the box of ``grid`` (x0, y0, nx, ny), or are kept by ``more`` (bool per
    triangle): drawn alone, in the same order, they give every pixel of those boxes the id all
    the moved triangles give it (a triangle draws only pixels within :data:`_RASTER_REACH` of
    it, and so only those it can take from another; the others lie more than two pixels
    away)."""
    if not len(moved_t):
        return moved_t, tri_pts
    gx0, gy0, gnx, gny = grid
    lo, hi = _corner_extremes(tri_pts)
    keep = np.zeros(len(moved_t), bool) if more is None else more.copy()
    for a0, b0, a1, b1 in boxes:
        a0, b0, a1, b1 = max(a0, gx0), max(b0, gy0), min(a1, gx0 + gnx), min(b1, gy0 + gny)
        if a1 > a0 and b1 > b0:
            keep |= ((hi[:, 0] >= a0 - 2) & (lo[:, 0] <= a1 + 1)
                     & (hi[:, 1] >= b0 - 2) & (lo[:, 1] <= b1 + 1))
    return (moved_t, tri_pts) if keep.all() else (moved_t[keep], tri_pts[keep])


#: Nodes per side of the tiles in which :func:`_reaching_nodes` looks for the exact map's
#: nodes (the smaller, the fewer triangles drawn beside the sharp edges' thin bands; the
#: more tiles to sum)
_NEAR_TILE = 8


def _reaching_nodes(tri_pts: np.ndarray, nj: np.ndarray, nk: np.ndarray, s: int, x0: int,
                    y0: int, shape: tuple[int, int]) -> np.ndarray:
    """(n,) bool: the moved triangles (points ``tri_pts``) that may reach a pixel of the nodes
    ``(nj, nk)`` of :func:`_maps_coarse`'s grid (``shape``; node ``(j, k)``: the box's pixels
    ``[(k - 1) s, k s)``, the box at ``(x0, y0)``), looked up by tiles of
    :data:`_NEAR_TILE` nodes (a triangle's pixels lie within two pixels of its corners' box,
    as :func:`_reaching_boxes` reads it; a superset: every triangle that reaches such a pixel
    is kept). On the 4K face the exact map's nodes are thin bands along the sharp edges, the
    openings and the jaw line, whose box spans the face: about a sixth of the triangles drawn
    for it reach none of them (the rasterizer's cost, ~5 us a triangle at that size, follows
    the triangles it draws)."""
    gy, gx = shape
    T = _NEAR_TILE
    ty, tx = -(-gy // T), -(-gx // T)
    # the tiles holding a node, as a summed-area table (a zero row and column first)
    sat = np.zeros((ty + 1, tx + 1), np.int32)
    sat[1:, 1:][nj // T, nk // T] = 1
    sat = sat.cumsum(0).cumsum(1)
    lo, hi = _corner_extremes(tri_pts)
    # each triangle's pixels, grown by two, as nodes (pixel p of the box: node p // s + 1)
    kl = (np.floor(lo[:, 0] - x0).astype(np.intp) - 2) // s + 1
    kh = (np.ceil(hi[:, 0] - x0).astype(np.intp) + 2) // s + 1
    jl = (np.floor(lo[:, 1] - y0).astype(np.intp) - 2) // s + 1
    jh = (np.ceil(hi[:, 1] - y0).astype(np.intp) + 2) // s + 1
    inside = (kh >= 0) & (kl < gx) & (jh >= 0) & (jl < gy)
    a0, a1 = np.clip(kl, 0, gx - 1) // T, np.clip(kh, 0, gx - 1) // T + 1
    b0, b1 = np.clip(jl, 0, gy - 1) // T, np.clip(jh, 0, gy - 1) // T + 1
    hits = sat[b1, a1] - sat[b0, a1] - sat[b1, a0] + sat[b0, a0]
    return inside & (hits > 0)


def _opening_boxes(plan: WarpPlan, dst: np.ndarray) -> list[tuple[int, int, int, int]]:
    """Each opening's box in ``dst`` (image pixels), as :func:`_finish` reads its ids."""
    out = []
    for name in LAYERS:
        loop = dst[plan.holes[name]]
        lo, hi = loop.min(0).tolist(), loop.max(0).tolist()
        out.append((math.floor(lo[0]) - 1, math.floor(lo[1]) - 1, math.ceil(hi[0]) + 2,
                    math.ceil(hi[1]) + 2))
    return out


def _evaluate_at(plan: WarpPlan, ids: np.ndarray, table: np.ndarray, xs: np.ndarray,
                 ys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_evaluate` at scattered pixels ``(xs, ys)`` (int) of ids ``ids``: the same
    float32 arithmetic, so the same values (the coefficients taken one contiguous column of
    the table at a time: the strided columns of gathered rows cost twice as much)."""
    i = ids.astype(np.intp)
    tp = np.ascontiguousarray(table.T)
    bp = plan._src_box_t
    x = xs.astype(np.float32, copy=False)
    y = ys.astype(np.float32, copy=False)
    out = []
    for k in (0, 1):
        m = tp[3 * k].take(i, mode="wrap")
        m *= x
        c = tp[3 * k + 1].take(i, mode="wrap")
        c *= y
        m += c
        m += tp[3 * k + 2].take(i, mode="wrap")
        # (np.clip to the source box, as two contiguous passes: the box's low <= its high)
        np.maximum(m, bp[k].take(i, mode="wrap"), out=m)
        np.minimum(m, bp[k + 2].take(i, mode="wrap"), out=m)
        out.append(m)
    return out[0], out[1]


#: Pixels per band of rows in which :func:`_maps` gathers its per-pixel coefficients.
_MAP_BAND_PX = 1 << 18


def _finish(plan: WarpPlan, dst: np.ndarray, out: np.ndarray, ids: np.ndarray,
            map_x: np.ndarray, map_y: np.ndarray, bbox: tuple[int, int, int, int],
            cavity: bool, maps: tuple[np.ndarray, np.ndarray] | None = None,
            interpolation: int = cv2.INTER_LINEAR) -> WarpResult:
    """Opening masks and the mouth cavity of the box ``bbox`` (``ids``, ``map_x/y`` its
    own); ``maps``: the result's maps over ``bbox`` when they are not ``map_x, map_y``;
    ``interpolation``: how ``out`` was resampled through them."""
    T = len(plan.triangles)
    h, w = out.shape[:2]
    x0, y0, x1, y1 = bbox

    # each opening's id lies within its loop's box only (compared there, not over the whole
    # box: 2 ms of the face 1000 px wide's 3 MP box)
    eyes = np.zeros(ids.shape, bool)
    mouth = np.zeros(ids.shape, bool)
    at = (0, 0, 0, 0)
    ny, nx = ids.shape
    for k, (a0, b0, a1, b1) in enumerate(_opening_boxes(plan, dst)):
        # (the loop's box as Python ints, clipped to the ids: numpy's clip of a scalar costs
        # several us, twelve of them a frame)
        a0, b0 = min(max(a0 - x0, 0), nx), min(max(b0 - y0, 0), ny)
        a1, b1 = min(max(a1 - x0, a0), nx), min(max(b1 - y0, b0), ny)
        name = LAYERS[k]
        here = ids[b0:b1, a0:a1] == T + 1 + k
        if name == "mouth":
            mouth[b0:b1, a0:a1] = here
            at = (a0, b0, a1, b1)
        else:
            eyes[b0:b1, a0:a1] |= here
    # mouth pixels whose source lies outside the photo's own opening: the dark cavity
    yy = xx = np.zeros(0, np.intp)
    if cavity:
        a0, b0, a1, b1 = at
        yy, xx = np.nonzero(mouth[b0:b1, a0:a1])
        yy, xx = yy + b0, xx + a0
    if len(yy):
        sx = np.clip(np.rint(map_x[yy, xx]).astype(np.int32), 0, w - 1)
        sy = np.clip(np.rint(map_y[yy, xx]).astype(np.int32), 0, h - 1)
        dark = ~plan.in_neutral_mouth(sx, sy)
        if dark.any():
            yy, xx = yy[dark], xx[dark]
            out[y0 + yy, x0 + xx] = _cavity(dst, plan.holes["mouth"], x0 + xx, y0 + yy)
    mx, my = (map_x, map_y) if maps is None else maps
    return WarpResult(out, (x0, y0, x1, y1), mouth, eyes, (mx, my, (x0, y0, x1, y1)),
                      interpolation)


def _cavity(dst: np.ndarray, loop: np.ndarray, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Colours (n, 3) of a dark mouth cavity at pixels (xs, ys): lighter near the lips."""
    poly = dst[loop]
    cx, cy = poly.mean(0)
    half_w = max(float(np.ptp(poly[:, 0])) / 2.0, 1.0)
    half_h = max(float(np.ptp(poly[:, 1])) / 2.0, 1.0)
    r = np.sqrt(((xs - cx) / half_w) ** 2 + ((ys - cy) / half_h) ** 2)
    shade = np.clip(0.35 + 0.65 * r, 0.35, 1.0)[:, None]
    return (CAVITY_RGB * shade).astype(np.uint8)


def box_maps(maps: tuple[np.ndarray, np.ndarray, tuple[int, int, int, int]],
             box: tuple[int, int, int, int], shift: tuple[int, int] = (0, 0),
             view: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The warp's backward map over ``box`` (identity where the warp did not write), minus
    ``shift`` (new arrays; ``view``: read-only, the maps' own memory when ``box`` lies in
    theirs and there is no shift, not copied)."""
    x0, y0, x1, y1 = box
    map_x, map_y, (a0, b0, a1, b1) = maps
    if view and shift == (0, 0) and a0 <= x0 and b0 <= y0 and x1 <= a1 and y1 <= b1:
        return (map_x[y0 - b0:y1 - b0, x0 - a0:x1 - a0],
                map_y[y0 - b0:y1 - b0, x0 - a0:x1 - a0])
    if a0 <= x0 and b0 <= y0 and x1 <= a1 and y1 <= b1:
        return (map_x[y0 - b0:y1 - b0, x0 - a0:x1 - a0] - np.float32(shift[0]),
                map_y[y0 - b0:y1 - b0, x0 - a0:x1 - a0] - np.float32(shift[1]))
    mx = np.empty((y1 - y0, x1 - x0), np.float32)
    my = np.empty_like(mx)
    mx[:] = np.arange(x0, x1, dtype=np.float32)[None]
    my[:] = np.arange(y0, y1, dtype=np.float32)[:, None]
    c0, r0, c1, r1 = max(x0, a0), max(y0, b0), min(x1, a1), min(y1, b1)
    if c1 > c0 and r1 > r0:
        mx[r0 - y0:r1 - y0, c0 - x0:c1 - x0] = map_x[r0 - b0:r1 - b0, c0 - a0:c1 - a0]
        my[r0 - y0:r1 - y0, c0 - x0:c1 - x0] = map_y[r0 - b0:r1 - b0, c0 - a0:c1 - a0]
    if shift != (0, 0):
        mx -= np.float32(shift[0])
        my -= np.float32(shift[1])
    return mx, my
