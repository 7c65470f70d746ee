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

import weakref
from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls

from editor.engine.deform import guard
from editor.engine.landmarks import detect_landmarks
from editor.engine.laplacian import (
    CONSTRAINT_WEIGHTS,
    MU,
    LaplacianDeformer,
    landmark_map,
)
from editor.errors import NoFaceError
from editor.formats.presets import apply_preset

from .fap_estimate import FapEstimator, remove_head_motion

#: Landmark ranges -> (FAPU along the face frame's x, along its y).
REGION_UNITS = ((range(0, 17), ("MW", "MNS")), (range(17, 27), ("ES", "ENS")),
                (range(27, 36), ("ES", "ENS")), (range(36, 48), ("ES", "IRISD")),
                (range(48, 68), ("MW", "MNS")))


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
          estimator: FapEstimator | None = None, sharp: bool = False) -> CloneResult:
    """Clone the expression ``source_expr`` of the performer onto ``target``.

    source_neutral : Face of the performer's neutral photo
    source_expr : (68, 2) landmarks of the performer's expression photo (or its Landmarks / Face)
    target : Face of the target photo
    method : ``"fap"`` or ``"laplacian"``; ``keys`` (Laplacian route) blends key models instead
    of transferring the landmark motion directly.
    sharp : resample the photo bicubically, as a still is (see ``Face.render``).
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
        return CloneResult(target.render(faps, sharp=sharp), v, expected, faps, None, method)
    if method != "laplacian":
        raise ValueError(f"method must be 'fap' or 'laplacian', got {method!r}")
    w = None
    if keys is not None:
        w = keys.weights(d)
        U = deformer.S @ keys.blend(w)
    else:
        U = expected
    v = finish(target, deformer.solve(U))
    return CloneResult(render_vertices(target, v, sharp), v, expected, None, w, method)


def render_vertices(face, vertices: np.ndarray, sharp: bool = False) -> np.ndarray:
    """The photo warped onto a deformed mesh, rendered like ``Face.render`` (layers included;
    ``sharp``: bicubic)."""
    return face.render_mesh(vertices, sharp=sharp).image


def closed_loop_error(image: np.ndarray, expected: np.ndarray, target, detector=None
                      ) -> dict[str, float]:
    """Detect landmarks on a result and compare with the expected ones (% of the target IOD).

    Keys: ``all`` (68 points), ``inner`` (17-67: brows, eyes, nose, mouth), ``mouth`` (48-67);
    NaN when no face is found on the result. Detection runs on the region of the target's face
    (its landmark box grown by 60 % of its width), so that another face-like thing in the photo
    (a badge, a poster) cannot be taken instead.
    """
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
    est = estimator or FapEstimator(face)
    out = []
    for v in np.atleast_2d(np.asarray(vectors, np.float32)):
        try:
            lm = detect_landmarks(face.render(v), detector)
            out.append(est.estimate(lm.points).faps.astype(np.float64))
        except NoFaceError:
            out.append(np.full(68, np.nan))
    return np.array(out)
