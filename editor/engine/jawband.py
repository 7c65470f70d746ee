"""The chin moving over the neck: what lies below the jaw stays where it is. No Qt.

Between the jaw contour and the mesh's margin ring lies a band of triangles (the neck, the
collar's edge, hair or background below the jaw). When the jaw drops, the piecewise-affine warp
squeezes that band between the lowered chin and the static ring: the neck's shadow and the
collar's edge shrink into thin, kinked lines that follow the band's triangles (a zig-zag seam
under the chin), and the collar is dragged along.

A real chin moves *over* the neck, which does not move. :func:`apply_jawband` puts the photo
back on the band when the jaw moved outward (down or sideways, over what surrounds the face, by
more than :data:`_OUT` px somewhere, and nowhere inward by more than a fraction of that): its
pixels show the photo as it is, the chin ends on the deformed jaw line. All of the band or none
of it: a band partly still and partly warped would tear along the triangle edge between the two
(a head roll moves one side of the jaw in, the other out). The weight is the band's coverage
(its outline filled anti-aliased), so at the jaw line's pixels the warped chin and the photo's
neck blend. Where the jaw moves inward (a neutralised open mouth's chin comes up) the band keeps
stretching as before: what the chin uncovers is not in the photo. The band's outer edge (the
margin ring) does not move, so the photo meets the warp there without a seam.
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

#: the jaw moved outward when a vertex did by more than this (px), and none moved inward by
#: more than it or than _IN_SHARE of the largest outward motion (a fraction of a pixel of the
#: photo's old jaw edge may then show below the new one)
_OUT, _IN_SHARE = 0.25, 0.1
#: the strip below the jaw line that rides with the chin (its underside, its shadow), IOD
TAU = 0.08


@dataclass(eq=False)
class _Band:
    tris: np.ndarray  # (n,) the band's triangles
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
    b = _Band(np.flatnonzero(sel), idx, nrm, p, _outline(tri[sel]))
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
    """The band's triangles, to keep as the photo for the deformed mesh ``vertices`` (V, 2),
    or None when the jaw did not move outward anywhere or moved inward somewhere."""
    b = _band(face)
    out = ((np.asarray(vertices, np.float64)[b.idx] - b.rest) * b.normal).sum(1)
    if not (out > _OUT).any():
        return None
    if out.min() < -max(_OUT, _IN_SHARE * out.max()):
        return None  # partly inward (a head roll, a jaw shifted sideways): none of it
    return b.tris


def apply_jawband(face: Face, res: WarpResult, vertices: np.ndarray) -> WarpResult:
    """The warp ``res`` with the photo put back under a jaw that moved outward (in place).

    Per column of the face frame (the jaw line is a function of the frame's x), a pixel at
    height ``d`` below the deformed jaw line shows the photo at ``d`` below the photo's jaw
    line for ``d <= TAU`` (the jaw's underside and its shadow ride with the chin), then the
    shift fades (smoothstep over ``R`` >= 1.5 x the largest drop, so the map stays monotonic)
    into the photo itself (the neck, the collar).
    """
    still = still_triangles(face, vertices)
    if still is None:
        return res
    img = res.image
    H, W = img.shape[:2]
    v = np.asarray(vertices, np.float64)
    tri = v[face.mesh.triangles[still]]  # (n, 3, 2)
    lo, hi = tri.reshape(-1, 2).min(0), tri.reshape(-1, 2).max(0)
    x0, y0 = max(math.floor(lo[0]) - 1, 0), max(math.floor(lo[1]) - 1, 0)
    x1, y1 = min(math.ceil(hi[0]) + 2, W), min(math.ceil(hi[1]) + 2, H)
    if x1 <= x0 or y1 <= y0:
        return res
    h, w = y1 - y0, x1 - x0
    b = _band(face)
    if b.loop is not None:  # the band's outline in one anti-aliased fill
        cov = np.zeros((h, w), np.uint8)
        q = np.rint((v[b.loop] - (x0, y0)) * 16.0)
        cv2.fillPoly(cov, [q.astype(np.int32)], 255, cv2.LINE_AA, 4)
    else:  # each triangle filled on a 4 x 4 supersampled canvas (no cracks between them)
        canvas = np.zeros((h * 4, w * 4), np.uint8)
        # sample (i, j) of pixel (x, y) sits at x + (i + 0.5) / 4 - 0.5; 4 fractional bits
        q = np.rint(((tri - (x0, y0) + 0.5) * 4 - 0.5) * 16.0)
        for t in q.astype(np.int32):
            cv2.fillConvexPoly(canvas, t, 255, cv2.LINE_8, 4)
        cov = cv2.resize(canvas, (w, h), interpolation=cv2.INTER_AREA)
    if not cov.any():
        return res
    # the jaw line now and in the photo, in the face frame, by x
    fr = face.frame
    new, old = fr.to_frame(v[b.idx]), fr.to_frame(b.rest)
    order = np.argsort(old[:, 0])
    drop = new[:, 1] - old[:, 1]
    tau = TAU * face.interocular
    ramp = max(1.5 * float(drop.max()), 2.0)
    R, org = fr.rot, fr.origin
    xs = np.arange(x0, x1, dtype=np.float64)[None, :] - org[0]
    ys = np.arange(y0, y1, dtype=np.float64)[:, None] - org[1]
    X = xs * R[0, 0] + ys * R[1, 0]  # frame coordinates of the box's pixels
    Y = xs * R[0, 1] + ys * R[1, 1]
    dy = np.interp(X, new[order, 0], drop[order])  # how far the jaw line dropped here
    d = Y - np.interp(X, new[order, 0], new[order, 1])  # height below the new jaw line
    u = np.clip((d - tau) / ramp, 0.0, 1.0)
    shift = dy * (1.0 - u * u * (3.0 - 2.0 * u))  # the chin's drop, then none
    mx = (X * R[0, 0] + (Y - shift) * R[0, 1] + org[0]).astype(np.float32)
    my = (X * R[1, 0] + (Y - shift) * R[1, 1] + org[1]).astype(np.float32)
    photo = cv2.remap(face.image, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    a = cov.astype(np.float32) * np.float32(1.0 / 255.0)
    view = img[y0:y1, x0:x1]
    warped = view.astype(np.float32)
    out = photo.astype(np.float32) - warped
    out *= cv2.merge([a, a, a])
    out += warped
    _to_uint8(out, view)
    bbox = _union(res.bbox, (x0, y0, x1, y1))
    return res if bbox == res.bbox else _rebox(res, bbox, {})
