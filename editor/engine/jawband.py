"""The chin moving over the neck: what lies below the jaw stays where it is. No Qt.

Between the jaw contour and the mesh's margin ring lies a band of triangles (the neck, the
collar's edge, hair or background below the jaw). When the jaw drops, the piecewise-affine warp
squeezes that band between the lowered chin and the static ring: the neck's shadow and the
collar's edge shrink into thin, kinked lines that follow the band's triangles (a zig-zag seam
under the chin), and the collar is dragged along.

A real chin moves *over* the neck, which does not move. :func:`apply_jawband` puts the photo
back on the band's triangles whose jaw vertices moved outward (down or sideways, over what
surrounds the face, by more than :data:`_OUT` px, and none of them inward): their pixels show
the photo as it is, the chin ends on the deformed jaw line. The weight is those triangles'
coverage (their outline filled anti-aliased), so at the jaw line's pixels the warped chin and
the photo's neck blend. Where the jaw moves inward (a neutralised open mouth's chin comes
up) the band keeps stretching as before: what the chin uncovers is not in the photo. The band's
outer edge (the margin ring) does not move, so the photo meets the warp there without a seam.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from .layers import _rebox, _to_uint8, _union
from .warp import WarpResult

if TYPE_CHECKING:
    from .face import Face

#: jaw vertices that moved outward by more than this (px) make their band triangles still; any
#: moving inward by more than it keeps them warped
_OUT = 0.25


@dataclass(eq=False)
class _Band:
    tris: np.ndarray  # (n,) the band's triangles
    jaw: np.ndarray  # (n, 3) per triangle: its vertices' rows in ``idx`` (-1: not on the jaw)
    idx: np.ndarray  # (k,) the jaw contour's vertex indices
    normal: np.ndarray  # (k, 2) their outward unit normals on the photo's mesh
    rest: np.ndarray  # (k, 2) their positions on the photo's mesh
    loop: np.ndarray | None  # the outline of all the band's triangles (vertex indices)


_PLANS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _band(face: Face) -> _Band:
    b = _PLANS.get(face)
    if b is not None:
        return b
    m = face.mesh
    names = np.array(m.names)
    on_jaw = np.char.startswith(names, "contour_")
    ring = np.char.startswith(names, "margin_") | np.char.startswith(names, "border_")
    tri = np.asarray(m.triangles)
    sel = on_jaw[tri].any(1) & ring[tri].any(1) & (on_jaw[tri] | ring[tri]).all(1)
    idx = np.array([m.index(f"contour_{k}") for k in range(int(on_jaw.sum()))])
    p = face.vertices[idx].astype(np.float64)
    # outward normals: the contour's tangent turned, pointing away from the face's centre
    tan = np.gradient(p, axis=0)
    nrm = np.stack([tan[:, 1], -tan[:, 0]], 1)
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-9)
    centre = face.vertices.astype(np.float64)[~ring].mean(0)
    nrm *= np.where(((p - centre) * nrm).sum(1) < 0, -1.0, 1.0)[:, None]
    row = np.full(len(names), -1)
    row[idx] = np.arange(len(idx))
    b = _Band(np.flatnonzero(sel), row[tri[sel]], idx, nrm, p, _outline(tri[sel]))
    _PLANS[face] = b
    return b


def _outline(tris: np.ndarray) -> np.ndarray | None:
    """The boundary of a set of triangles as one closed vertex loop, or None when it is not a
    single simple loop."""
    e = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), 1)
    u, n = np.unique(e, axis=0, return_counts=True)
    edges = u[n == 1]
    nxt: dict[int, list[int]] = {}
    for a, c in edges.tolist():
        nxt.setdefault(a, []).append(c)
        nxt.setdefault(c, []).append(a)
    if not edges.size or any(len(x) != 2 for x in nxt.values()):
        return None
    loop, prev = [int(edges[0, 0])], -1
    while True:
        a, c = nxt[loop[-1]]
        step = c if a == prev else a
        prev = loop[-1]
        if step == loop[0]:
            break
        loop.append(step)
    return np.array(loop) if len(loop) == len(nxt) else None


def still_triangles(face: Face, vertices: np.ndarray) -> np.ndarray | None:
    """The band triangles to keep as the photo for the deformed mesh ``vertices`` (V, 2), or
    None when the jaw did not move outward anywhere."""
    b = _band(face)
    out = ((np.asarray(vertices, np.float64)[b.idx] - b.rest) * b.normal).sum(1)
    if not (out > _OUT).any():
        return None
    o = np.append(out, 0.0)[b.jaw]  # (n, 3); a vertex off the jaw counts as not moving
    keep = (o > _OUT).any(1) & (o >= -_OUT).all(1)
    return b.tris[keep] if keep.any() else None


def apply_jawband(face: Face, res: WarpResult, vertices: np.ndarray) -> WarpResult:
    """The warp ``res`` with the photo put back under a jaw that moved outward (in place)."""
    still = still_triangles(face, vertices)
    if still is None:
        return res
    img = res.image
    H, W = img.shape[:2]
    tri = np.asarray(vertices, np.float64)[face.mesh.triangles[still]]  # (n, 3, 2)
    lo, hi = tri.reshape(-1, 2).min(0), tri.reshape(-1, 2).max(0)
    x0, y0 = max(math.floor(lo[0]) - 1, 0), max(math.floor(lo[1]) - 1, 0)
    x1, y1 = min(math.ceil(hi[0]) + 2, W), min(math.ceil(hi[1]) + 2, H)
    if x1 <= x0 or y1 <= y0:
        return res
    h, w = y1 - y0, x1 - x0
    b = _band(face)
    if b.loop is not None and len(still) == len(b.tris):
        # the whole band (a dropping jaw): its outline in one anti-aliased fill
        cov = np.zeros((h, w), np.uint8)
        q = np.rint((np.asarray(vertices, np.float64)[b.loop] - (x0, y0)) * 16.0)
        cv2.fillPoly(cov, [q.astype(np.int32)], 255, cv2.LINE_AA, 4)
    else:  # some triangles: each filled on a 4 x 4 supersampled canvas (no cracks between)
        canvas = np.zeros((h * 4, w * 4), np.uint8)
        # sample (i, j) of pixel (x, y) sits at x + (i + 0.5) / 4 - 0.5; 4 fractional bits
        q = np.rint(((tri - (x0, y0) + 0.5) * 4 - 0.5) * 16.0)
        for t in q.astype(np.int32):
            cv2.fillConvexPoly(canvas, t, 255, cv2.LINE_8, 4)
        cov = cv2.resize(canvas, (w, h), interpolation=cv2.INTER_AREA)
    if not cov.any():
        return res
    a = cov.astype(np.float32) * np.float32(1.0 / 255.0)
    view = img[y0:y1, x0:x1]
    warped = view.astype(np.float32)
    out = face.image[y0:y1, x0:x1].astype(np.float32) - warped
    out *= cv2.merge([a, a, a])
    out += warped
    _to_uint8(out, view)
    bbox = _union(res.bbox, (x0, y0, x1, y1))
    return res if bbox == res.bbox else _rebox(res, bbox, {})
