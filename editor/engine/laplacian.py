"""Laplacian editing of a mesh with landmark constraints, shared by the fitted mesh
(:meth:`editor.engine.face.Face`'s untangling) and expression cloning
(:mod:`editor.synthesis.cloning`, whose module docstring gives the maths).

* :func:`landmark_map` - each dlib-68 landmark as barycentric coordinates on the closest
  triangle of a mesh (inner lips and lids kept on their own side);
* :func:`mean_value_weights` - the mesh's mean-value (convex) weights;
* :class:`LaplacianDeformer` - one sparse LU per neutral mesh, then a solve per set of targets.
"""

from __future__ import annotations

import threading
from collections import OrderedDict

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

MU = 10.0
#: Per-landmark constraint weight (x mu): the upper jaw contour is left free - on JAFFE it moves
#: ~9 % of the inter-ocular distance between a person's photos whatever the expression (pose and
#: dlib placement), and constraining it bloats the cheeks; the lower contour at 1/2.
CONSTRAINT_WEIGHTS = np.select([np.arange(68) < 4, np.arange(68) < 13, np.arange(68) < 17],
                               [0.0, 0.5, 0.0], 1.0)


# ---------------------------------------------------------------------------- landmarks
# landmarks tied only to triangles that touch vertices with one of these name prefixes
_SIDES = {**{i: "lipi_u" for i in (61, 62, 63)}, **{i: "lipi_d" for i in (65, 66, 67)},
          **{i: "eye_r_u" for i in (37, 38)}, **{i: "eye_r_d" for i in (40, 41)},
          **{i: "eye_l_u" for i in (43, 44)}, **{i: "eye_l_d" for i in (46, 47)}}
_OPPOSITE = {"lipi_u": "lipi_d", "lipi_d": "lipi_u", "eye_r_u": "eye_r_d",
             "eye_r_d": "eye_r_u", "eye_l_u": "eye_l_d", "eye_l_d": "eye_l_u"}


def _closest_on_triangles(p: np.ndarray, tri_pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance from p to each triangle (T,) and barycentric coords of the closest point (T, 3).

    ``p`` may also be a batch of points (L, 2): then (L, T) distances and (L, T, 3) coords.
    """
    p = np.asarray(p, np.float64)[..., None, :]  # (..., 1, 2) against (T, 2)
    A, B, C = tri_pts[:, 0], tri_pts[:, 1], tri_pts[:, 2]
    v0, v1, v2 = B - A, C - A, p - A
    d00, d01, d11 = (v0 * v0).sum(-1), (v0 * v1).sum(-1), (v1 * v1).sum(-1)
    d20, d21 = (v2 * v0).sum(-1), (v2 * v1).sum(-1)
    den = np.where(np.abs(d00 * d11 - d01 * d01) > 1e-12, d00 * d11 - d01 * d01, 1e-12)
    v = (d11 * d20 - d01 * d21) / den
    w = (d00 * d21 - d01 * d20) / den
    bary = np.stack([1.0 - v - w, v, w], -1)
    inside = np.asarray((bary >= -1e-9).all(-1))
    best = np.where(inside, 0.0, np.inf)
    out = np.where(inside[..., None], bary, 0.0)
    for i, j in ((0, 1), (1, 2), (2, 0)):
        a, b = tri_pts[:, i], tri_pts[:, j]
        e = b - a
        t = np.clip(((p - a) * e).sum(-1) / np.maximum((e * e).sum(-1), 1e-12), 0.0, 1.0)
        dist = np.linalg.norm(p - (a + t[..., None] * e), axis=-1)
        upd = ~inside & (dist < best)
        nb = np.zeros(t.shape + (3,))
        nb[..., i], nb[..., j] = 1.0 - t, t
        best = np.where(upd, dist, best)
        out = np.where(upd[..., None], nb, out)
    return best, out


#: the last few landmark maps by content (opening a photo with its own expression asks for
#: the same map of its photo mesh several times: each neutralisation round's face and each
#: estimator); keys are the inputs' bytes, never object ids
_LANDMARK_MAPS: OrderedDict[tuple, sp.csr_matrix] = OrderedDict()
_LANDMARK_LOCK = threading.Lock()


def landmark_map(vertices: np.ndarray, triangles: np.ndarray, names: tuple[str, ...],
                 points68: np.ndarray) -> sp.csr_matrix:
    """(68, V) sparse barycentric map: landmark l = row l @ vertices (on the neutral mesh)."""
    key = (np.asarray(vertices, np.float64).tobytes(), np.asarray(triangles, np.int64).tobytes(),
           tuple(names), np.asarray(points68, np.float64).tobytes())
    with _LANDMARK_LOCK:  # (photos may be opened from worker threads)
        hit = _LANDMARK_MAPS.get(key)
        if hit is not None:
            _LANDMARK_MAPS.move_to_end(key)
            return hit.copy()
    hit = _landmark_map(vertices, triangles, names, points68)
    with _LANDMARK_LOCK:
        _LANDMARK_MAPS[key] = hit
        while len(_LANDMARK_MAPS) > 8:
            _LANDMARK_MAPS.popitem(last=False)
    return hit.copy()


def _landmark_map(vertices: np.ndarray, triangles: np.ndarray, names: tuple[str, ...],
                  points68: np.ndarray) -> sp.csr_matrix:
    V = np.asarray(vertices, np.float64)
    tri = np.asarray(triangles, np.int64)
    tri_pts = V[tri]
    nm = np.array(names)
    # triangles touching a vertex of each side prefix (per vertex once, not per corner and
    # landmark)
    touch = {k: np.char.startswith(nm, k)[tri].any(1) for k in _OPPOSITE}
    rows, cols, vals = [], [], []
    dists, barys = _closest_on_triangles(np.asarray(points68, np.float64), tri_pts)
    for l, (dist, bary) in enumerate(zip(dists, barys, strict=True)):
        side = _SIDES.get(l)
        if side:
            dist = np.where(touch[side] & ~touch[_OPPOSITE[side]], dist, np.inf)
        k = int(np.argmin(dist))
        rows += [l] * 3
        cols += list(tri[k])
        vals += list(bary[k])
    return sp.csr_matrix((vals, (rows, cols)), shape=(68, len(V)))


# ---------------------------------------------------------------------------- Laplacian
def mean_value_weights(vertices: np.ndarray, triangles: np.ndarray) -> sp.csr_matrix:
    """(V, V) row-stochastic mean-value weights: w_ij > 0 on mesh edges, rows sum to 1."""
    v = np.asarray(vertices, np.float64)
    t = np.asarray(triangles, np.int64)
    rows, cols, vals = [], [], []
    for c in range(3):
        i, j, k = t[:, c], t[:, (c + 1) % 3], t[:, (c + 2) % 3]
        a, b = v[j] - v[i], v[k] - v[i]
        la, lb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
        cross = np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
        half_tan = cross / np.maximum(la * lb + (a * b).sum(1), 1e-12)  # tan(angle at i / 2)
        rows += [i, i]
        cols += [j, k]
        vals += [half_tan / np.maximum(la, 1e-12), half_tan / np.maximum(lb, 1e-12)]
    n = len(v)
    W = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(n, n)).tocsr()  # duplicates (the two triangles of an edge) add up
    s = np.asarray(W.sum(1)).ravel()
    return sp.diags(1.0 / np.maximum(s, 1e-300)) @ W


class LaplacianDeformer:
    """Laplacian editing of one neutral mesh with soft landmark constraints (one LU).

    Parameters
    ----------
    vertices : (V, 2) neutral mesh; triangles : (T, 3)
    constraints : (m, V) sparse rows (barycentric or selection) of the constrained points
    fixed : (V,) bool, vertices held at rest exactly (eliminated from the system)
    mu : soft-constraint weight; ``weights`` (m,) scales it per constraint (0 = unconstrained)
    """

    def __init__(self, vertices: np.ndarray, triangles: np.ndarray, constraints: sp.spmatrix,
                 fixed: np.ndarray | None = None, mu: float = MU,
                 weights: np.ndarray | None = None) -> None:
        self.v0 = np.asarray(vertices, np.float64)
        n = len(self.v0)
        self.W = mean_value_weights(self.v0, triangles)
        self.L = (sp.identity(n, format="csr") - self.W).tocsr()
        self.delta = self.L @ self.v0
        self.S = sp.csr_matrix(constraints)
        self.mu = float(mu)
        if not 0 < self.mu < 1e6:  # NaN, infinite, zero or negative weights: no valid solve
            raise ValueError(f"mu must be a finite number in (0, 1e6), got {mu!r}")
        m = self.S.shape[0]
        self.c = np.ones(m) if weights is None else np.asarray(weights, np.float64).reshape(m)
        Sw = (sp.diags(self.c) @ self.S).tocsr()
        fixed = np.zeros(n, bool) if fixed is None else np.asarray(fixed, bool)
        self.free = np.flatnonzero(~fixed)
        self.fixed = np.flatnonzero(fixed)
        Lf, Sf = self.L[:, self.free], Sw[:, self.free]
        self._LfT, self._SfT = Lf.T.tocsr(), Sf.T.tocsr()
        x_fix = self.v0[self.fixed]
        self._delta_eff = self.delta - self.L[:, self.fixed] @ x_fix
        self._s_fix = Sw[:, self.fixed] @ x_fix
        A = (Lf.T @ Lf + self.mu ** 2 * (Sf.T @ Sf)).tocsc()
        self._lu = splu(A)
        self.rest_targets = self.S @ self.v0

    def solve(self, targets: np.ndarray) -> np.ndarray:
        """Deformed vertices (V, 2) for constraint targets (m, 2)."""
        U = np.asarray(targets, np.float64)
        rhs = self._LfT @ self._delta_eff + self.mu ** 2 * (
            self._SfT @ (self.c[:, None] * U - self._s_fix))
        out = self.v0.copy()
        out[self.free] = self._lu.solve(np.ascontiguousarray(rhs))
        return out

