"""Expression cloning (SPEC §6): a performer's expression onto any photo, two routes.

* **FAP route** - estimate the performer's FAPs (:mod:`.fap_estimate`, performer FAPU) and
  render them on the target (FAPU normalisation does the retargeting).
* **Laplacian route** - move the target's personalized mesh so that its landmarks follow the
  performer's landmark motion while every vertex keeps its Laplacian coordinate:
  mean-value (convex) weights w_ij = (tan(a_ij/2) + tan(b_ij/2)) / |v_j - v_i| normalised per row
  (one term on a boundary edge: eye/mouth openings, image border), L = I - W, delta = L V0 on the
  **neutral target** mesh; minimise |L V' - delta|^2 + mu^2 |S V' - U|^2, i.e.
  (L^T L + mu^2 S^T S) V' = L^T delta + mu^2 S^T U per coordinate, one sparse LU per target
  (``scipy.sparse.linalg.splu``). S holds one row per landmark: the barycentric coordinates of
  the landmark on the neutral target mesh (a plain selection row where a landmark is a vertex,
  SPEC's "S selects the constrained vertices" generalised to points inside triangles), weighted
  per landmark (:data:`CONSTRAINT_WEIGHTS`: upper jaw contour free, lower contour 1/2); U = the
  rest positions S V0 plus the transferred motion. The image-border ring is a hard constraint
  (eliminated: the background never moves). With U = S V0 the solution is V0 exactly. The
  result then goes through the lips/lids crossing rule and the project's fold guard
  (``deform.guard``) before the warp.

**Motion transfer** (performer -> target): head-free landmark displacements (similarity on
eye corners + nose, see :mod:`.fap_estimate`) are expressed in the performer's face frame,
scaled per region and axis by the target/performer FAPU ratio - mouth and jaw x MW, y MNS;
brows and nose x ES, y ENS; eyes x ES, y IRISD - the same normalisation the FAP route applies -
and rotated into the target's face frame. Expected target landmarks = target neutral landmarks
+ transferred motion: the Laplacian constraints, and the reference of the closed-loop error.

**Key models** (SPEC §6.2): source key vectors p_k (head-free displacements of the 68 landmarks
for anger, disgust, fear, joy, sadness, surprise; neutral p_0 = 0), target key meshes u_k. A new
source frame p gets w = NNLS argmin |p - sum w_k p_k| (``scipy.optimize.nnls``), the target
feature points U = S (u_0 + sum w_k (u_k - u_0)), then the Laplacian solve. Target keys come
from the transfer itself (each source key cloned by the Laplacian route) or from the emotion
presets rendered on the target. No PCA: 136 parameters against 6 keys is well posed for NNLS.
"""

from __future__ import annotations

import threading
import weakref
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.optimize import nnls
from scipy.sparse.linalg import splu

from editor.engine.deform import guard
from editor.errors import NoFaceError

from .fap_estimate import FapEstimator, remove_head_motion

MU = 10.0
#: Per-landmark constraint weight (x mu): the upper jaw contour is left free - on JAFFE it moves
#: ~9 % of the inter-ocular distance between a person's photos whatever the expression (pose and
#: dlib placement), and constraining it bloats the cheeks; the lower contour at 1/2.
CONSTRAINT_WEIGHTS = np.select([np.arange(68) < 4, np.arange(68) < 13, np.arange(68) < 17],
                               [0.0, 0.5, 0.0], 1.0)
#: Landmark ranges -> (FAPU along the face frame's x, along its y).
REGION_UNITS = ((range(0, 17), ("MW", "MNS")), (range(17, 27), ("ES", "ENS")),
                (range(27, 36), ("ES", "ENS")), (range(36, 48), ("ES", "IRISD")),
                (range(48, 68), ("MW", "MNS")))


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
    inside = (bary >= -1e-9).all(-1)
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


_DEFORMERS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def face_deformer(face, mu: float = MU) -> LaplacianDeformer:
    """The (cached) Laplacian deformer of a Face: landmark constraints, border ring fixed.

    It deforms the face's *neutral* mesh as rendered (``face.deform(None)``: the photo's own
    expression removed, including the small offset that makes f0 reproduce the photo exactly);
    the landmarks are tied to it by their barycentric coordinates on the photo's mesh.
    """
    key = (float(mu),)
    cache = _DEFORMERS.setdefault(face, {})
    if key not in cache:
        S = landmark_map(face.vertices, face.triangles, face.mesh.names, face.landmarks.points)
        cache[key] = LaplacianDeformer(face.deform(None), face.triangles, S,
                                       face.mesh.regions == "border", mu, CONSTRAINT_WEIGHTS)
    return cache[key]


def finish(face, vertices: np.ndarray) -> np.ndarray:
    """Crossing rule (lips/lids meet, never cross) and fold guard on a deformed mesh."""
    plan = face.plan
    v = np.asarray(vertices, np.float64).copy()
    up, lo = plan.pairs[:, 0], plan.pairs[:, 1]
    ey = plan.frame_rot[:, 1]
    cross = v[lo] @ ey < v[up] @ ey
    if cross.any():
        mean = 0.5 * (v[up[cross]] + v[lo[cross]])
        v[up[cross]], v[lo[cross]] = mean, mean
    v0 = plan.neutral64[: plan.n_vertices]
    D = guard(plan, (v - v0)[None])[0]
    return (v0 + D).astype(np.float32)


# ---------------------------------------------------------------------------- transfer
def transfer_motion(source_face, displacement: np.ndarray, target_face) -> np.ndarray:
    """Performer landmark motion (68, 2, performer pixels, head-free) -> target pixels."""
    d = np.asarray(displacement, np.float64) @ source_face.frame.rot  # performer frame
    for idx, (ux, uy) in REGION_UNITS:
        i = np.fromiter(idx, int)
        d[i, 0] *= target_face.fapu[ux] / source_face.fapu[ux]
        d[i, 1] *= target_face.fapu[uy] / source_face.fapu[uy]
    return d @ target_face.frame.rot.T


@dataclass
class KeyModels:
    """Key expressions for NNLS blending (SPEC §6.2)."""

    names: tuple[str, ...]
    source: np.ndarray  # (K, 136) head-free source key displacements, performer pixels
    target: np.ndarray  # (K, V, 2) target key meshes
    target_neutral: np.ndarray  # (V, 2)

    def weights(self, displacement: np.ndarray) -> np.ndarray:
        """(K,) non-negative weights: NNLS fit of a (68, 2) displacement by the keys."""
        w, _ = nnls(self.source.T, np.asarray(displacement, np.float64).ravel())
        return w

    def blend(self, w: np.ndarray) -> np.ndarray:
        """Target mesh u_0 + sum w_k (u_k - u_0), (V, 2)."""
        return self.target_neutral + np.tensordot(w, self.target - self.target_neutral, 1)


def key_models(source_face, key_points: dict[str, np.ndarray], target_face,
               target: str = "transfer", mu: float = MU) -> KeyModels:
    """Key models from the performer's key expressions (name -> 68 landmarks of the photo).

    ``target="transfer"``: each target key is the Laplacian clone of the source key;
    ``"presets"``: the target's key is its emotion preset (names must be preset names).
    """
    from editor.formats.expressions import apply_preset

    names = tuple(key_points)
    neutral = np.asarray(source_face.landmarks.points, np.float64)
    src, tgt = [], []
    deformer = face_deformer(target_face, mu)
    for n in names:
        aligned, _ = remove_head_motion(neutral, np.asarray(key_points[n], np.float64))
        d = aligned - neutral
        src.append(d.ravel())
        if target == "presets":
            tgt.append(target_face.deform(apply_preset(n)).astype(np.float64))
        else:
            tgt.append(deformer.solve(deformer.rest_targets
                                      + transfer_motion(source_face, d, target_face)))
    return KeyModels(names, np.array(src), np.array(tgt),
                     target_face.deform(None).astype(np.float64))


# ---------------------------------------------------------------------------- clone
@dataclass
class CloneResult:
    """A cloned expression on the target photo."""

    image: np.ndarray  # (H, W, 3) uint8
    vertices: np.ndarray  # (V, 2) deformed target mesh (after the fold guard)
    expected: np.ndarray  # (68, 2) target neutral landmarks + transferred motion
    faps: np.ndarray | None  # (68,) FAPs (FAP route; performer FAPU = target FAPU)
    key_weights: np.ndarray | None = None  # NNLS weights (with key models)
    method: str = "fap"


def clone(source_neutral, source_expr, target, method: str = "fap", *,
          keys: KeyModels | None = None, mu: float = MU,
          estimator: FapEstimator | None = None) -> CloneResult:
    """Clone the expression ``source_expr`` of the performer onto ``target``.

    source_neutral : Face of the performer's neutral photo
    source_expr : (68, 2) landmarks of the performer's expression photo (or its Landmarks / Face)
    target : Face of the target photo
    method : ``"fap"`` or ``"laplacian"``; ``keys`` (Laplacian route) blends key models instead
    of transferring the landmark motion directly.
    """
    pts = getattr(source_expr, "landmarks", source_expr)
    pts = np.asarray(getattr(pts, "points", pts), np.float64)
    if pts.shape != (68, 2):
        raise ValueError(f"source_expr: expected 68 landmarks, got shape {pts.shape}")
    neutral = np.asarray(source_neutral.landmarks.points, np.float64)
    aligned, _ = remove_head_motion(neutral, pts)
    d = aligned - neutral
    deformer = face_deformer(target, mu)
    base = deformer.rest_targets  # the target's landmarks on its neutralised face
    expected = base + transfer_motion(source_neutral, d, target)
    if method == "fap":
        est = estimator or FapEstimator(source_neutral)
        faps = est.estimate(pts).faps
        v = target.deform(faps)
        return CloneResult(target.render(faps), v, expected, faps, None, method)
    if method != "laplacian":
        raise ValueError(f"method must be 'fap' or 'laplacian', got {method!r}")
    w = None
    if keys is not None:
        w = keys.weights(d)
        U = deformer.S @ keys.blend(w)
    else:
        U = expected
    v = finish(target, deformer.solve(U))
    return CloneResult(render_vertices(target, v), v, expected, None, w, method)


def render_vertices(face, vertices: np.ndarray) -> np.ndarray:
    """The photo warped onto a deformed mesh, rendered like ``Face.render`` (layers included)."""
    return face.render_mesh(vertices).image


def closed_loop_error(image: np.ndarray, expected: np.ndarray, target, detector=None
                      ) -> dict[str, float]:
    """Detect landmarks on a result and compare with the expected ones (% of the target IOD).

    Keys: ``all`` (68 points), ``inner`` (17-67: brows, eyes, nose, mouth), ``mouth`` (48-67);
    NaN when no face is found on the result. Detection runs on the region of the target's face
    (its landmark box grown by 60 % of its width), so that another face-like thing in the photo
    (a badge, a poster) cannot be taken instead.
    """
    from editor.engine.landmarks import detect_landmarks

    img = np.asarray(image)
    p = target.landmarks.points
    (x0, y0), (x1, y1) = p.min(0), p.max(0)
    m = 0.6 * (x1 - x0)
    bx0, by0 = int(max(0, x0 - m)), int(max(0, y0 - m))
    bx1, by1 = int(min(img.shape[1], x1 + m)), int(min(img.shape[0], y1 + m))
    try:
        got = detect_landmarks(np.ascontiguousarray(img[by0:by1, bx0:bx1]), detector).points
        got = got.astype(np.float64) + (bx0, by0)
    except NoFaceError:
        return {"all": float("nan"), "inner": float("nan"), "mouth": float("nan")}
    e = np.linalg.norm(got - np.asarray(expected, np.float64), axis=1) * 100.0 / target.interocular
    return {"all": float(e.mean()), "inner": float(e[17:].mean()), "mouth": float(e[48:].mean())}


def round_trip(face, vectors: np.ndarray, estimator: FapEstimator | None = None,
               detector=None) -> np.ndarray:
    """FAP recovery check: render each (68,) vector on ``face``, detect landmarks, estimate.

    Returns the estimated vectors (n, 68); NaN rows where no face is found on the render.
    """
    from editor.engine.landmarks import detect_landmarks

    est = estimator or FapEstimator(face)
    out = []
    for v in np.atleast_2d(np.asarray(vectors, np.float32)):
        try:
            lm = detect_landmarks(face.render(v), detector)
            out.append(est.estimate(lm.points).faps.astype(np.float64))
        except NoFaceError:
            out.append(np.full(68, np.nan))
    return np.array(out)
