"""The chin moving over the neck: what lies below the jaw stays where it is. No Qt.

Between the jaw contour and the mesh's margin ring lies a band of triangles (the neck, the
collar's edge, hair or background below the jaw). When the jaw drops, the piecewise-affine warp
squeezes that band between the lowered chin and the static ring: the neck's shadow and the
collar's edge shrink into thin, kinked lines that follow the band's triangles (a zig-zag seam
under the chin), and the collar is dragged along.

A real chin moves *over* the neck, which does not move, and carries its own underside (with
its shadow). When the jaw moved outward (down or sideways, over what surrounds the face, by
more than :data:`_OUT` px somewhere, and nowhere inward by more than a fraction of that),
:func:`jaw_map` gives the warp a different backward map for the band's pixels: a strip just
below the jaw line rides with the chin, then the photo fades back to itself (the neck, the
collar). All of the band or none of it: a band partly remapped and partly warped would tear
along the triangle edge between the two (a head roll moves one side of the jaw in, the other
out). Where the jaw moves inward (a neutralised open mouth's chin comes up) the band keeps
stretching as before: what the chin uncovers is not in the photo. The map is continuous with
the chin's on the jaw line and with the still photo beyond the fade, so it needs no blending:
one map, one resampling (the warp's own).
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

import cv2
import numpy as np

from .fitting import interp

if TYPE_CHECKING:
    from .face import Face
    from .fitting import FaceFrame
    from .mesh import StandardMesh

#: the jaw moved outward when a vertex did by more than this (px), and none moved inward by
#: more than it or than _IN_SHARE of the largest outward motion (a fraction of a pixel of the
#: photo's old jaw edge may then show below the new one)
_OUT, _IN_SHARE = 0.25, 0.1
#: the strip below the jaw line that rides with the chin (its underside, its shadow), IOD
TAU = 0.08
#: spacing (frame px) of the jaw line's table along the frame's x
_STEP = 0.25
#: node spacing (px) of the band's shift on a band box larger than _COARSE_AREA pixels (a
#: 1080p face and up; the sample's and JAFFE's boxes are smaller: every pixel)
_COARSE, _COARSE_AREA = 4, 20_000


@dataclass(eq=False)
class _Band:
    verts: np.ndarray  # the band triangles' vertices (its box)
    idx: np.ndarray  # (k,) the jaw contour's vertex indices
    normal: np.ndarray  # (k, 2) their outward unit normals on the photo's mesh
    rest: np.ndarray  # (k, 2) their positions on the photo's mesh
    lut: np.ndarray  # (T + 4,) bool: a warp triangle id is one of the band's
    ring: np.ndarray  # the band's outer vertices (the margin ring below the jaw)
    tau: float  # :data:`TAU` in pixels (the interocular distance is not recomputed per frame)
    rest_frame: np.ndarray  # (k, 2) ``rest`` in the face frame


_PLANS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@lru_cache(maxsize=8)
def _zeros32(shape: tuple[int, ...]) -> np.ndarray:
    """A read-only float32 array of zeros (the band's box recurs from frame to frame)."""
    z = np.zeros(shape, np.float32)
    z.setflags(write=False)
    return z


def _band(face: Face) -> _Band:
    b = _PLANS.get(face)
    if b is not None:
        return b
    verts, idx, lut, ring_v, off_ring = _band_topology(face.mesh)
    p = face.vertices[idx].astype(np.float64)
    # outward normals: the contour's tangent turned, pointing away from the face's centre
    tan = np.gradient(p, axis=0)
    nrm = np.stack([tan[:, 1], -tan[:, 0]], 1)
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-9)
    centre = face.vertices.astype(np.float64)[off_ring].mean(0)
    nrm *= np.where(((p - centre) * nrm).sum(1) < 0, -1.0, 1.0)[:, None]
    b = _Band(verts, idx, nrm, p, lut, ring_v, TAU * face.interocular, face.frame.to_frame(p))
    _PLANS[face] = b
    return b


@lru_cache(maxsize=4)
def _band_topology(m: StandardMesh) -> tuple[np.ndarray, ...]:
    """What :func:`_band` needs of the mesh (once per mesh, not per face): the band
    triangles' vertices, the jaw contour's vertex indices, the warp ids' band LUT (triangles,
    the identity row, the 3 openings), the band's outer vertices and the vertices off the
    margin ring (read-only)."""
    names = np.array(m.names)
    on_jaw = np.char.startswith(names, "contour_")
    ring = np.char.startswith(names, "margin_") | np.char.startswith(names, "border_")
    tri = np.asarray(m.triangles)
    sel = on_jaw[tri].any(1) & ring[tri].any(1) & (on_jaw[tri] | ring[tri]).all(1)
    idx = np.array([m.index(f"contour_{k}") for k in range(int(on_jaw.sum()))])
    lut = np.zeros(len(tri) + 4, bool)
    lut[np.flatnonzero(sel)] = True
    out = (np.unique(tri[sel]), idx, lut, np.unique(tri[sel][ring[tri[sel]]]), ~ring)
    for a in out:
        a.setflags(write=False)
    return out


def _moved_out(b: _Band, vertices: np.ndarray) -> bool:
    """Whether the jaw line of ``vertices`` moved outward (somewhere by more than :data:`_OUT`
    px, nowhere inward by more than a fraction of that)."""
    # (rows gathered with take: numpy's fancy indexing of an (n, 2) array costs ~5 us more)
    d = np.asarray(vertices).take(b.idx, 0).astype(np.float64) - b.rest
    out = d[:, 0] * b.normal[:, 0] + d[:, 1] * b.normal[:, 1]
    # partly inward (a head roll, a jaw shifted sideways): none of the band
    o = out.tolist()  # (a few values: Python's max and min cost less than ndarray's)
    hi = max(o)
    return bool(hi > _OUT and min(o) >= -max(_OUT, _IN_SHARE * hi))


def jaw_map(face: Face, vertices: np.ndarray
            ) -> Callable[..., tuple[int, int, int, int] | None] | None:
    """A hook for :func:`~editor.engine.warp.warp` that gives the band's pixels the chin's
    map, or None when the jaw did not move outward (see :func:`_moved_out`).

    Per column of the face frame (the jaw line is a function of the frame's x), a pixel at
    height ``d`` below the deformed jaw line shows the photo at ``d`` below the photo's jaw
    line for ``d <= TAU`` (the jaw's underside and its shadow ride with the chin); then the
    shift fades (smoothstep over 1.5 x the largest drop: the neck squeezed by at most about 2)
    into the photo itself (the neck, the collar). Strip and fade fit into the room down to the
    margin ring (a photo cropped close under the chin), so the map meets the photo there. On
    the jaw line this is the chin's own map (both take the photo's jaw line, linear between its
    vertices), so the two meet without a seam.
    """
    b = _band(face)
    if not _moved_out(b, vertices):
        return None
    vv = np.asarray(vertices)
    vb = vv.take(b.verts, 0)
    # the band's extent (x0, y0, x1, y1)
    bx, by = vb[:, 0].tolist(), vb[:, 1].tolist()  # (Python's min/max: cheaper here)
    ext = (min(bx), min(by), max(bx), max(by))
    fr = face.frame
    new = fr.to_frame(vv.take(b.idx, 0))
    order = new[:, 0].argsort()
    new = new.take(order, 0)
    drop = new[:, 1] - b.rest_frame[:, 1].take(order)
    ring = fr.to_frame(vv.take(b.ring, 0))
    ring = ring.take(ring[:, 0].argsort(), 0)
    ramp = max(1.5 * max(drop.tolist()), 2.0)
    # the pixels the hook may read and write: the extent grown by the rasterizer's reach
    reach = (math.floor(ext[0]) - 1, math.floor(ext[1]) - 1, math.ceil(ext[2]) + 2,
             math.ceil(ext[3]) + 2)
    return _JawHook((fr, b, reach, new, drop, ring, ramp), reach, b.lut)


#: :class:`_JawHook`'s ``args``
_HookArgs = tuple["FaceFrame", _Band, tuple[int, int, int, int], np.ndarray, np.ndarray,
                  np.ndarray, float]


class _JawHook:
    """:func:`jaw_map`'s hook (:func:`_hook`) and ``box``, the pixels (x0, y0, x1, y1) whose
    triangle ids it reads and whose map it may change (the warp needs its ids nowhere else);
    ``lut`` (T + 4,) bool: the warp's ids whose map it replaces (the band's triangles), and
    ``points(xs, ys)``: that map at any points (float32 arrays; of the band, inside ``box``)
    and ``nodes(x0, y0, s, nx, ny)`` on a grid of nodes, for a warp that evaluates its map on
    a grid of nodes (:func:`_points`, :func:`_nodes`). ``args``: the frame's band (the face
    frame, the band, ``box``, the jaw line, its drop, the ring below it, the fade's length),
    the functions' first arguments. (A plain class: made every frame, a frozen dataclass's
    initialisation and three partials cost more.)"""

    __slots__ = ("args", "box", "lut")

    def __init__(self, args: _HookArgs, box: tuple[int, int, int, int], lut: np.ndarray
                 ) -> None:
        self.args = args
        self.box = box
        self.lut = lut

    def __call__(self, ids: np.ndarray, map_x: np.ndarray, map_y: np.ndarray,
                 box: tuple[int, int, int, int]) -> tuple[int, int, int, int] | None:
        return _hook(*self.args, ids, map_x, map_y, box)

    def points(self, xs: np.ndarray, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return _points(*self.args, xs, ys)

    def nodes(self, x0: float, y0: float, s: int, nx: int, ny: int
              ) -> tuple[np.ndarray, np.ndarray]:
        return _nodes(*self.args, x0, y0, s, nx, ny)


def _nodes(fr: FaceFrame, b: _Band, reach: tuple[int, int, int, int], new: np.ndarray,
           drop: np.ndarray, ring: np.ndarray, ramp: float, x0: float, y0: float, s: int,
           nx: int, ny: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_hook`'s map (ny, nx) at the nodes ``(x0 + k s, y0 + j s)`` (of the band's:
    the others' values are meaningless): the shift evaluated on nodes ``2 s`` apart and
    interpolated bilinearly (x 2, ``cv2.resize``), as :func:`_hook` interpolates it to the
    pixels from nodes :data:`_COARSE` px apart."""
    o0, o1, _, _, r01, r11 = _frame_numbers(fr)
    # coarse node m at node k = 2 m - 3 / 2: the resize's pixel i at node i - 2
    mw, mh = (nx + 2) // 2 + 2, (ny + 2) // 2 + 2
    cx0, cy0 = x0 - 1.5 * s, y0 - 1.5 * s
    box = (math.floor(cx0) - 1, math.floor(cy0) - 1, math.ceil(cx0 + 2 * s * mw) + 1,
           math.ceil(cy0 + 2 * s * mh) + 1)
    tab = _jaw_table(fr, b, box, new, drop, ring, ramp)
    # the coarse rows from image row _fade_rows(.., 0, 2 s, ..) down have a shift of 0 (past
    # the fade; on the 4K bench face the lower third of the grid): evaluated are the rows above
    # it and one of those, so that the resize (x 2 exactly: each output row reads the same two
    # coarse rows, the last one replicated below) gives the whole grid's values on the output
    # rows it covers, and the rows below them are the nodes themselves (a shift of 0)
    mh = min(mh, max(math.ceil((_fade_rows(fr, tab, 0, 2 * s, new, b.tau, ramp) - cy0)
                               / (2 * s)), 0) + 1)
    rows = min(ny, 2 * mh - 2)
    xs = (cx0 + 2 * s * np.arange(mw, dtype=np.float64) - o0).astype(np.float32)[None, :]
    ys = (cy0 + 2 * s * np.arange(mh, dtype=np.float64) - o1).astype(np.float32)[:, None]
    shift = _table_shift(fr, tab, xs, ys)
    shift = cv2.resize(shift, (2 * mw, 2 * mh), None, 0, 0, cv2.INTER_LINEAR)[2:2 + rows, 2:2 + nx]
    gx = (x0 + s * np.arange(nx)).astype(np.float32)[None, :]
    gy = (y0 + s * np.arange(ny)).astype(np.float32)[:, None]
    mx = np.empty((ny, nx), np.float32)
    my = np.empty((ny, nx), np.float32)
    np.multiply(shift, np.float32(-r01), out=mx[:rows])
    mx[:rows] += gx
    mx[rows:] = gx
    np.multiply(shift, np.float32(-r11), out=my[:rows])
    my[:rows] += gy[:rows]
    my[rows:] = gy[rows:]
    return mx, my


#: Points per row of the (rows, _ROW) maps through which :func:`_points` reads the jaw table
#: (OpenCV's remap takes maps up to 32767 wide)
_ROW = 4096


def _points(fr: FaceFrame, b: _Band, reach: tuple[int, int, int, int], new: np.ndarray,
            drop: np.ndarray, ring: np.ndarray, ramp: float, xs: np.ndarray, ys: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_hook`'s map at the points ``(xs, ys)`` (float32, image pixels, inside
    ``reach``): the chin's map evaluated at each point (not interpolated from the nodes of a
    coarser grid, as :func:`_hook` does over a large box)."""
    n = len(xs)
    if not n:
        return xs.copy(), ys.copy()
    # (the table over the box grown by a few pixels: a node the warp's coarse rasterizer gives
    # a band triangle lies up to a node spacing outside it)
    grown = (reach[0] - 8, reach[1] - 8, reach[2] + 8, reach[3] + 8)
    o0, o1, _, _, r01, r11 = _frame_numbers(fr)
    shift = _table_shift(fr, _jaw_table(fr, b, grown, new, drop, ring, ramp),
                         xs - np.float32(o0), ys - np.float32(o1))
    mx = shift * np.float32(-r01)
    mx += xs
    my = shift * np.float32(-r11)
    my += ys
    return mx, my


def _hook(fr: FaceFrame, b: _Band, reach: tuple[int, int, int, int], new: np.ndarray,
          drop: np.ndarray, ring: np.ndarray, ramp: float, ids: np.ndarray,
          map_x: np.ndarray, map_y: np.ndarray, box: tuple[int, int, int, int]
          ) -> tuple[int, int, int, int] | None:
    """:func:`jaw_map`'s hook: the band's pixels of the warp's box ``box`` (triangle ids
    ``ids``) take the chin's map in ``map_x``, ``map_y`` (in place). ``new`` the jaw line in
    the frame by its x, ``drop`` its drop there, ``ring`` the margin ring below it, ``ramp``
    the fade's length, ``reach`` the pixels the band may touch (:attr:`_JawHook.box`).
    Returns the box (x0, y0, x1, y1, image pixels) it wrote in, None when it wrote nothing."""
    bx0, by0, bx1, by1 = box
    x0, y0 = max(reach[0], bx0), max(reach[1], by0)
    x1, y1 = min(reach[2], bx1), min(reach[3], by1)
    if x1 <= x0 or y1 <= y0:
        return None
    w, h = x1 - x0, y1 - y0
    # a small box: each pixel its own node (s = 1), the shift evaluated at the band's pixels
    # only; a large one: the shift is smooth, evaluated on nodes _COARSE px apart and resized
    # (node k where cv2.resize puts it: pixel (k + 0.5) s - 0.5; off by far less than a
    # tenth of a pixel)
    small = w * h <= _COARSE_AREA
    s = 1 if small else _COARSE
    tab = _jaw_table(fr, b, (x0, y0, x1, y1), new, drop, ring, ramp)
    # the warp gave the band's pixels the identity (see warp.warp): the rows below the fade's
    # end, where the shift is 0 (x - 0 r01 is x), keep it; the first h rows' nodes and shifts
    # are the whole box's (the same nodes; a pixel reads the two nodes about it, both in the
    # grid). On the 431 x 591 bench face 50 of the box's 66 rows (3089 of its 3763 band
    # pixels) are below it, on the 1080p one a third of the box
    h = min(h, _fade_rows(fr, tab, y0, s, new, b.tau, ramp))
    if h <= 0:
        return None
    sub = (slice(y0 - by0, y0 - by0 + h), slice(x0 - bx0, x1 - bx0))
    sel = b.lut.take(ids[sub])  # the band's pixels (as the warp's rasterizer gave them)
    if small:
        # (their flat indices: np.nonzero of a 2-d mask costs several times more)
        k = sel.ravel().nonzero()[0]
        if not len(k):
            return None
        _hook_pixels(fr, tab, sel, k, sub, (x0, y0, x1, y0 + h), map_x, map_y)
        return x0, y0, x1, y0 + h
    if not np.count_nonzero(sel):
        return None
    o0, o1, _, _, r01, r11 = _frame_numbers(fr)
    nw, nh = -(-w // s) + 1, -(-h // s) + 1
    off = 0.5 * s - 0.5
    xs = (x0 + off + s * np.arange(nw, dtype=np.float32) - np.float32(o0))[None, :]
    ys = (y0 + off + s * np.arange(nh, dtype=np.float32) - np.float32(o1))[:, None]
    shift = _table_shift(fr, tab, xs, ys)
    shift = cv2.resize(shift, (nw * s, nh * s), None, 0, 0, cv2.INTER_LINEAR)[:h, :w]
    # x - shift r01 as shift (-r01) + x: the same float32 values (IEEE negation is exact),
    # one temporary of the box fewer each
    mx = np.multiply(shift, np.float32(-r01))
    mx += np.arange(x0, x1, dtype=np.float32)[None, :]
    my = np.multiply(shift, np.float32(-r11))
    my += np.arange(y0, y0 + h, dtype=np.float32)[:, None]
    # (OpenCV's masked copy, into the maps' own memory: np.copyto with where= costs 3 times
    # more on this box, many times more on a ragged mask)
    m8 = sel.view(np.uint8)
    cv2.copyTo(mx, m8, map_x[sub])
    cv2.copyTo(my, m8, map_y[sub])
    return x0, y0, x1, y0 + h


def _fade_rows(fr: FaceFrame, tab: tuple[np.ndarray, float], y0: int, s: int,
               new: np.ndarray, tau: float, ramp: float) -> int:
    """How many rows from image row ``y0`` down may carry a shift (:func:`_hook`'s, its
    nodes ``s`` px apart, over the box of the jaw table ``tab``): the shift is 0 at a node
    whose frame height is past the jaw line, strip and fade of its column (``Y >= jaw +
    strip + fade``), so at every pixel whose two nodes above and below are; those lie below
    the lowest image row of that curve (its image y ``o1 + r10 X + r11 (jaw + strip +
    fade)``, bounded by the jaw line's lowest vertex ``new``, the strip's and the fade's
    largest values, ``tau`` and ``max(ramp, 0.5)`` (see :func:`_jaw_table`), and the frame
    x's extremes, the grid's nodes reaching ``2 s`` px beyond the table's), plus a node
    spacing and a pixel (the table's float32 rounding). All rows when the frame is rolled by
    more than 60 degrees. (:func:`_nodes` reads it from row 0 for its coarse grid, nodes
    ``2 s`` apart.)"""
    table, lo_x = tab
    _, o1, _, r10, _, r11 = _frame_numbers(fr)
    if r11 < 0.5:
        return 1 << 30
    reach = 2 * s + 2
    hi_x = lo_x + _STEP * (table.shape[1] - 1)
    y_max = o1 + r11 * (max(new[:, 1].tolist()) + tau + max(ramp, 0.5)) + max(
        r10 * (lo_x - reach), r10 * (hi_x + reach))
    return math.ceil(y_max) + s + 3 - y0


def _frame_numbers(fr: FaceFrame) -> tuple[float, float, float, float, float, float]:
    """The frame's origin and rotation as Python floats: o0, o1, r00, r10, r01, r11."""
    R, org = fr.rot, fr.origin
    return (float(org[0]), float(org[1]), float(R[0, 0]), float(R[1, 0]), float(R[0, 1]),
            float(R[1, 1]))


def _jaw_table(fr: FaceFrame, b: _Band, box: tuple[int, int, int, int], new: np.ndarray,
               drop: np.ndarray, ring: np.ndarray, ramp: float) -> tuple[np.ndarray, float]:
    """The jaw line now, its drop, the strip and the fade along the frame's x over ``box``,
    tabulated every _STEP px (3, n, 4) float32, its rows alike (read per pixel with one
    cv2.remap on row 0: np.interp per pixel costs several times more), and the frame x of its
    first entry."""
    x0, y0, x1, y1 = box
    o0, o1, r00, r10, _, _ = _frame_numbers(fr)
    # the frame's x over the box is extreme at its corners (Python floats: the same float64
    # arithmetic as on arrays, without their cost for four values)
    ax, ay = (x0 - o0) * r00, (x1 - 1 - o0) * r00
    by, cy = (y0 - o1) * r10, (y1 - 1 - o1) * r10
    bx = (ax + by, ay + by, ax + cy, ay + cy)
    lo_x = min(bx)
    u = lo_x + _STEP * np.arange(math.ceil((max(bx) - lo_x) / _STEP) + 2)
    # (3 rows, read on row 0: OpenCV's vectorised remap takes a sample whose row below its
    # two lies inside the source too; with 2 rows every sample took the slow border path,
    # 3 x the time, for the same values)
    table = np.empty((3, len(u), 4), np.float32)
    jaw = interp(u, new[:, 0], new[:, 1])
    table[:, :, 0] = jaw
    table[:, :, 1] = interp(u, new[:, 0], drop)
    # the room below the jaw line down to the margin ring: the strip and the fade fit in
    # it, so that the map is the photo's own where the band meets the ring
    room = interp(u, ring[:, 0], ring[:, 1])
    room -= table[0, :, 0]
    np.maximum(room, 1.0, out=room)
    t_strip = np.minimum(b.tau, 0.3 * room)
    table[:, :, 2] = t_strip
    room -= t_strip
    table[:, :, 3] = np.maximum(np.minimum(ramp, room, out=room), 0.5, out=room)
    return table, lo_x


def _table_shift(fr: FaceFrame, tab: tuple[np.ndarray, float], u: np.ndarray, v: np.ndarray
                 ) -> np.ndarray:
    """The band's shift at image offsets ``u = x - o0``, ``v = y - o1`` from the frame's
    origin (float32, broadcast against each other: a grid's row and column, or two lists of
    points): each one's frame x, in table steps, reads the jaw table ``tab``
    (:func:`_jaw_table`) with one cv2.remap, its frame y gives the shift (:func:`_shift`)."""
    table, lo_x = tab
    _, _, r00, r10, r01, r11 = _frame_numbers(fr)
    tx = (u * np.float32(r00 / _STEP) - np.float32(lo_x / _STEP)) + v * np.float32(r10 / _STEP)
    n = tx.size
    if tx.ndim == 1:  # (a list of points: rows of _ROW, OpenCV's maps are at most 32767 wide)
        tx = np.concatenate([tx, np.zeros(-n % _ROW, np.float32)]).reshape(-1, _ROW)
    # (the four channels read as views: cheaper than splitting them into new arrays)
    got = cv2.remap(table, tx, _zeros32(tx.shape), cv2.INTER_LINEAR, None,
                    cv2.BORDER_REPLICATE)
    if u.ndim == 1:
        got = got.reshape(-1, 4)[:n]
    return _shift(u * np.float32(r01) + v * np.float32(r11), got)


def _shift(d: np.ndarray, got: np.ndarray) -> np.ndarray:
    """The band's shift along the frame's y at pixels of frame height ``d`` (float32, changed
    in place) from their rows of the jaw table ``got`` (jaw line, drop, strip, fade)."""
    d -= got[..., 0]  # ... below the new jaw line
    d -= got[..., 2]  # past the strip
    d /= got[..., 3]  # over the fade
    np.minimum(np.maximum(d, 0.0, out=d), 1.0, out=d)  # (np.clip: the same, slower)
    shift = np.multiply(d, np.float32(-2.0))  # smoothstep (3 - 2 d) d d, in place
    shift += np.float32(3.0)
    shift *= d
    shift *= d
    np.subtract(1.0, shift, out=shift)
    shift *= got[..., 1]  # the chin's drop over its underside, then none
    return shift


def _hook_pixels(fr: FaceFrame, tab: tuple[np.ndarray, float], sel: np.ndarray,
                 k: np.ndarray, sub: tuple[slice, slice], box: tuple[int, int, int, int],
                 map_x: np.ndarray, map_y: np.ndarray) -> None:
    """:func:`_hook` at every pixel of a small band box ``box`` (``sel``: the band's pixels
    in it, ``k`` their flat indices, ``sub`` its slices of the warp's maps; ``tab``
    :func:`_jaw_table`): the table is read and the shift evaluated at the band's pixels only
    (about half the box), each with the float32 arithmetic of a whole-box evaluation (its
    row and column terms, then their sum), so with its values."""
    x0, y0, x1, y1 = box
    table, lo_x = tab
    o0, o1, r00, r10, r01, r11 = _frame_numbers(fr)
    yi = k // (x1 - x0)
    xi = k - yi * (x1 - x0)
    xs = x0 + np.arange(x1 - x0, dtype=np.float32) - np.float32(o0)
    ys = y0 + np.arange(y1 - y0, dtype=np.float32) - np.float32(o1)
    # the pixel's frame x in table steps, and its frame y
    tx = (xs * np.float32(r00 / _STEP) - np.float32(lo_x / _STEP)).take(xi)
    tx += (ys * np.float32(r10 / _STEP)).take(yi)
    d = (xs * np.float32(r01)).take(xi)
    d += (ys * np.float32(r11)).take(yi)
    got = cv2.remap(table, tx[None], np.zeros((1, len(tx)), np.float32), cv2.INTER_LINEAR,
                    None, cv2.BORDER_REPLICATE)[0]
    shift = _shift(d, got)
    mx = np.arange(x0, x1, dtype=np.float32).take(xi)
    mx -= shift * np.float32(r01)
    my = np.arange(y0, y1, dtype=np.float32).take(yi)
    my -= shift * np.float32(r11)
    if map_x.flags.c_contiguous and map_y.flags.c_contiguous:
        # (by flat indices into the whole maps: a boolean mask of a 2-d window costs more)
        flat = (yi + sub[0].start) * map_x.shape[1] + (xi + sub[1].start)
        map_x.reshape(-1)[flat] = mx
        map_y.reshape(-1)[flat] = my
    else:
        map_x[sub][sel] = mx
        map_y[sub][sel] = my
