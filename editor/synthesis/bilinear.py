"""Symmetric bilinear identity × expression model (SPEC §5, seed 003), numpy only.

A region of the face is a K-vector ``z`` (its landmarks ``x0, y0, x1, y1, ...`` after shape
normalisation, see :mod:`editor.synthesis.bilinear_data`). For expression (style) ``s`` and identity
(content) ``c`` the model is ``z_k = sum_ij w_ijk a_i b_j`` with ``a`` in R^I, ``b`` in R^J.

Shapes (SPEC §5): ``A`` is I×S and ``B`` is J×C with orthonormal rows (columns are the trained
expression / identity vectors); ``W`` is IK×J with block (i, j) the K-vector ``w_ij``;
``(W b)^VT`` is K×I and ``(W^VT a)^VT`` is K×J. The training tensor ``Z`` is SK×C.

Translation of a new face: plain ALS, ridge or MALS (corrected eq. 16). The gauge
``(a, b) -> (c·a, b/c)`` leaves reconstructions unchanged; :func:`fix_gauge` pins it (our
addition, needed before swapping in a trained expression vector). Model files: ``.npz`` arrays
plus one JSON metadata string.
"""

from __future__ import annotations

import io
import json
import math
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from editor.errors import ModelError
from editor.safeio import atomic_file, read_bounded

#: Largest model file, and largest total of its unpacked arrays (bytes).
MAX_MODEL_BYTES = 256 * 1024 * 1024
#: Landmark indices of a model region are 0 .. MAX_LANDMARK - 1 (the 77-point layout).
MAX_LANDMARK = 77

FORMAT_NAME = "fap-studio-bilinear"
FORMAT_VERSION = 1
METHODS = ("plain", "ridge", "mals")


def vector_transpose(X: np.ndarray, K: int) -> np.ndarray:
    """Vector transpose ``X^VT`` (SPEC §5).

    Parameters
    ----------
    X : ndarray, shape (P*K, Q)
        P×Q blocks, each block a K-vector (block (p, q) is ``X[p*K:(p+1)*K, q]``).
    K : int
        Length of the vectors kept intact.

    Returns
    -------
    ndarray, shape (Q*K, P)
        Block (q, p) of the result is block (p, q) of ``X``. Applying it twice with the same
        ``K`` gives ``X`` back.
    """
    X = np.asarray(X)
    if X.ndim != 2:
        raise ValueError(f"vector_transpose needs a 2-D array, got shape {X.shape}")
    if K <= 0 or X.shape[0] % K:
        raise ValueError(f"vector_transpose: {X.shape[0]} rows are not a multiple of K={K}")
    P, Q = X.shape[0] // K, X.shape[1]
    return X.reshape(P, K, Q).transpose(2, 1, 0).reshape(Q * K, P)


@dataclass(frozen=True)
class RegionModel:
    """Trained bilinear model of one region.

    Attributes
    ----------
    W : ndarray, shape (I*K, J)
    A : ndarray, shape (I, S) -- column s is the trained expression vector a^s.
    B : ndarray, shape (J, C) -- column c is the trained identity vector b^c.
    K : int -- vector length (2 × number of landmarks of the region).
    """

    W: np.ndarray
    A: np.ndarray
    B: np.ndarray
    K: int

    @property
    def I(self) -> int:  # noqa: E743, N802 - the paper's symbol
        return int(self.A.shape[0])

    @property
    def J(self) -> int:  # noqa: N802
        return int(self.B.shape[0])

    @property
    def w3(self) -> np.ndarray:
        """``W`` as a tensor ``w[i, k, j]``, shape (I, K, J)."""
        return self.W.reshape(self.I, self.K, self.J)

    def G(self, b: np.ndarray) -> np.ndarray:  # noqa: N802
        """``(W b)^VT``: b (..., J) -> (..., K, I)."""
        return np.einsum("ikj,...j->...ki", self.w3, b)

    def H(self, a: np.ndarray) -> np.ndarray:  # noqa: N802
        """``(W^VT a)^VT``: a (..., I) -> (..., K, J)."""
        return np.einsum("ikj,...i->...kj", self.w3, a)

    def reconstruct(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """``z = (W b)^VT a``: a (..., I), b (..., J) -> z (..., K)."""
        return np.einsum("ikj,...i,...j->...k", self.w3, a, b)

    def reconstruct_training(self) -> np.ndarray:
        """All trained faces ``((W B)^VT A)^VT``, shape (S*K, C)."""
        return vector_transpose(vector_transpose(self.W @ self.B, self.K) @ self.A, self.K)


class TrainResult(NamedTuple):
    """Output of :func:`train_bilinear`: the model, relative errors per iteration, flag."""

    model: RegionModel
    errors: np.ndarray
    converged: bool


def train_bilinear(
    Z: np.ndarray,
    K: int,
    I: int | None = None,  # noqa: E741
    J: int | None = None,
    tol: float = 1e-10,
    max_iter: int = 100,
) -> TrainResult:
    """Fit a symmetric bilinear model by the iterated SVD of SPEC §5.

    Parameters
    ----------
    Z : ndarray, shape (S*K, C)
        Training faces; block (s, c) is the K-vector of expression s, identity c.
    K : int
        Vector length.
    I, J : int, optional
        Expression / identity dimensions (defaults S and C).
    tol, max_iter : float, int
        Stop when the relative reconstruction error ‖Z − Ẑ‖/‖Z‖ changes by at most ``tol``
        between iterations, or after ``max_iter`` iterations.
    """
    Z = np.asarray(Z, dtype=np.float64)
    if Z.ndim != 2 or K <= 0 or Z.shape[0] % K or 0 in Z.shape:
        raise ModelError(f"training matrix of shape {Z.shape} is not S*K × C with K={K}")
    if not np.all(np.isfinite(Z)):
        raise ModelError("training data contain NaN or infinite values")
    S, C = Z.shape[0] // K, Z.shape[1]
    I = S if I is None else int(I)  # noqa: E741
    J = C if J is None else int(J)
    if not (1 <= I <= min(S, J * K) and 1 <= J <= min(C, I * K)):
        raise ModelError(f"need 1 ≤ I ≤ S={S} and 1 ≤ J ≤ C={C}, got I={I}, J={J}")
    norm = max(float(np.linalg.norm(Z)), np.finfo(float).tiny)
    B = np.linalg.svd(Z, full_matrices=False)[2][:J]
    errors: list[float] = []
    converged, model = False, None
    for _ in range(max(int(max_iter), 1)):
        A = np.linalg.svd(vector_transpose(Z @ B.T, K), full_matrices=False)[2][:I]
        ZvA = vector_transpose(vector_transpose(Z, K) @ A.T, K)
        B = np.linalg.svd(ZvA, full_matrices=False)[2][:J]
        W = vector_transpose(vector_transpose(Z @ B.T, K) @ A.T, K)
        model = RegionModel(W=W, A=A, B=B, K=K)
        errors.append(float(np.linalg.norm(Z - model.reconstruct_training())) / norm)
        if (len(errors) > 1 and abs(errors[-2] - errors[-1]) <= tol) or errors[-1] <= 1e-13:
            converged = True
            break
    assert model is not None
    return TrainResult(model, np.asarray(errors), converged)


class Translation(NamedTuple):
    """Output of a translation: ``(a, b, costs, converged)``.

    For one face: a (I,), b (J,), costs (n_iter+1,) (cost at the start, then after every
    iteration), converged a bool. For a batch of N faces: a (N, I), b (N, J), costs (N, T)
    padded with NaN after each face stopped, converged (N,) bool.
    """

    a: np.ndarray
    b: np.ndarray
    costs: np.ndarray
    converged: Any


def _solve(M: np.ndarray, z: np.ndarray, lam: np.ndarray, prior: np.ndarray | None) -> np.ndarray:
    """Batched ``(MᵀM + λI)⁻¹(Mᵀz + λ·prior)``, pseudo-inverse where λ = 0.

    M (n, K, p), z (n, K), lam (n,), prior (n, p) or None -> (n, p)."""
    out = np.empty((M.shape[0], M.shape[2]))
    zero = lam == 0.0
    if zero.any():
        out[zero] = np.einsum("npk,nk->np", np.linalg.pinv(M[zero]), z[zero])
    if not zero.all():
        nz = ~zero
        Mz, lz = M[nz], lam[nz]
        MtM = np.einsum("nkp,nkq->npq", Mz, Mz) + lz[:, None, None] * np.eye(M.shape[2])
        rhs = np.einsum("nkp,nk->np", Mz, z[nz])
        if prior is not None:
            rhs = rhs + lz[:, None] * prior[nz]
        out[nz] = np.linalg.solve(MtM, rhs[..., None])[..., 0]
    return out


def translate(
    model: RegionModel,
    z: np.ndarray,
    method: str = "plain",
    lam: float | tuple[float, float] | np.ndarray = 0.0,
    tol: float = 1e-3,
    max_iter: int = 50,
    a0: np.ndarray | None = None,
    b0: np.ndarray | None = None,
) -> Translation:
    """Estimate expression ``a`` and identity ``b`` of new face(s) ``z`` (SPEC §5).

    Parameters
    ----------
    model : RegionModel
    z : ndarray, shape (K,) or (N, K)
    method : {"plain", "ridge", "mals"}
        plain: ``a = G⁺z, b = H⁺z``; ridge: ``a = (GᵀG + λ1I)⁻¹Gᵀz`` (same for b);
        MALS: ``a = (GᵀG + λ1I)⁻¹(Gᵀz + λ1 a_old)``, b likewise with the new ``a``.
        G = (W b)^VT, H = (W^VT a)^VT.
    lam : float, tuple (λ1, λ2), or ndarray of shape (N,) or (N, 2)
        Regularisation (ignored by plain); one value means λ1 = λ2. An ndarray gives every
        face of a batch its own λ (to scan a λ grid in one vectorised call).
    tol, max_iter : float, int
        Stop a face when its cost (eq. 5; eq. 8 for ridge) falls by at most ``tol``·f in one
        iteration (a-step then b-step), or after ``max_iter`` iterations.
    a0, b0 : ndarray, optional
        Start values, shape (I,) / (J,) or batched; default the means of the trained columns
        of A and B.
    """
    if method not in METHODS:
        raise ModelError(f"unknown translation method {method!r} (use {', '.join(METHODS)})")
    z = np.asarray(z, dtype=np.float64)
    single = z.ndim == 1
    Zb = np.atleast_2d(z)
    if Zb.ndim != 2 or Zb.shape[1] != model.K or not np.all(np.isfinite(Zb)):
        raise ModelError(f"face vector of shape {z.shape} does not match the model (K={model.K})")
    N = Zb.shape[0]
    if isinstance(lam, np.ndarray) and lam.ndim > 0:  # one λ (or λ1, λ2 pair) per face
        per_face = lam.astype(np.float64).reshape(N, -1)
        l1, l2 = per_face[:, 0].copy(), per_face[:, -1].copy()
    else:
        pair = np.broadcast_to(np.asarray(lam, dtype=np.float64), (2,))
        l1, l2 = np.full(N, pair[0]), np.full(N, pair[1])
    if method == "plain":
        l1[:], l2[:] = 0.0, 0.0
    if np.any(l1 < 0) or np.any(l2 < 0) or not np.all(np.isfinite(l1 + l2)):
        raise ModelError("λ must be finite and non-negative")
    a = np.broadcast_to(model.A.mean(axis=1) if a0 is None else a0, (N, model.I)).copy()
    b = np.broadcast_to(model.B.mean(axis=1) if b0 is None else b0, (N, model.J)).copy()
    mals = method == "mals"

    def cost(idx: np.ndarray) -> np.ndarray:
        f = np.sum((Zb[idx] - model.reconstruct(a[idx], b[idx])) ** 2, axis=-1)
        if method == "ridge":
            f = f + l1[idx] * np.sum(a[idx] ** 2, axis=-1) + l2[idx] * np.sum(b[idx] ** 2, axis=-1)
        return f

    costs = np.full((N, max_iter + 1), np.nan)
    costs[:, 0] = cost(np.arange(N))
    active = np.ones(N, dtype=bool)
    converged = np.zeros(N, dtype=bool)
    for it in range(1, max_iter + 1):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        a[idx] = _solve(model.G(b[idx]), Zb[idx], l1[idx], a[idx] if mals else None)
        b[idx] = _solve(model.H(a[idx]), Zb[idx], l2[idx], b[idx] if mals else None)
        costs[idx, it] = f = cost(idx)
        stop = costs[idx, it - 1] - f <= tol * costs[idx, it - 1]
        converged[idx[stop]] = True
        active[idx[stop]] = False
    if single:
        return Translation(a[0], b[0], costs[0][np.isfinite(costs[0])], bool(converged[0]))
    n_used = int(np.max(np.sum(np.isfinite(costs), axis=1)))
    return Translation(a, b, costs[:, :n_used], converged)


def fix_gauge(model: RegionModel, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pin the gauge ``(a, b) -> (c·a, b/c)`` to the scale and sign of the trained expressions.

    ``c`` makes ``a · ā = ‖ā‖²`` with ā the mean trained expression vector. With I = S every
    trained ``a^s`` and every mix ``A α`` with ``Σ α_s = 1`` satisfies this exactly (with
    I < S, the trained vectors on average), so swapping in ``a^s`` keeps the face's size.
    Reconstructions are unchanged. a (..., I), b (..., J) -> same shapes.
    """
    mean = model.A.mean(axis=1)
    proj = np.sum(a * mean, axis=-1, keepdims=True) / max(float(mean @ mean), 1e-300)
    c = 1.0 / np.where(np.abs(proj) < 1e-300, 1e-300, proj)
    return a * c, b / c


def synthesize_region(model: RegionModel, b: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Face with expression ``a⁰ = Σ_s α_s a^s = A α`` and identity ``b``.

    b (..., J), alpha (S,) or (..., S) -> z⁰ (..., K)."""
    a0 = np.einsum("is,...s->...i", model.A, np.asarray(alpha, dtype=np.float64))
    return model.reconstruct(a0, b)


@dataclass
class BilinearModel:
    """Bilinear models of the face regions, joined by concatenation.

    ``region_indices[name]`` lists the landmark indices (of the source layout) whose
    ``x, y`` make up that region's K-vector; ``meta`` holds the normalisation conventions.
    """

    regions: dict[str, RegionModel]
    region_indices: dict[str, tuple[int, ...]]
    expressions: tuple[str, ...]
    identities: tuple[str, ...]
    meta: dict[str, Any] = field(default_factory=dict)


#: Other names of the expressions: the Stasm model's (happy, sad, angry) and JAFFE's codes.
ALIASES = {"happy": "joy", "sad": "sadness", "angry": "anger", "ne": "neutral", "ha": "joy",
           "sa": "sadness", "su": "surprise", "an": "anger", "di": "disgust", "fe": "fear"}


def expression_alpha(model: BilinearModel, target: Any) -> np.ndarray:
    """α (S,): the expression weights of ``target`` for ``model``.

    ``target``: an expression name (case-insensitive, :data:`ALIASES` accepted: happy = joy),
    an index, a ``{name or index: weight}`` mix (weights add up; not all zero) or an (S,) array.
    Unknown names, indices out of range and non-finite weights raise :class:`ModelError`.
    """
    names = [n.lower() for n in model.expressions]
    reverse = {v: k for k, v in ALIASES.items() if len(k) > 2}  # joy -> happy (Stasm's names)

    def index(key: Any) -> int:
        if isinstance(key, (int, np.integer)) and not isinstance(key, bool):
            if 0 <= int(key) < len(names):
                return int(key)
            raise ModelError(f"expression index {key} out of range 0-{len(names) - 1}")
        k = str(key).strip().lower()
        for cand in (k, ALIASES.get(k, k), reverse.get(k, k)):
            if cand in names:
                return names.index(cand)
        raise ModelError(f"unknown expression {key!r} (model has {', '.join(model.expressions)})")

    if isinstance(target, (str, int, np.integer)):
        target = {target: 1.0}
    if isinstance(target, Mapping):
        alpha = np.zeros(len(names))
        for key, w in target.items():
            try:
                weight = float(w)
            except (TypeError, ValueError):
                weight = math.nan
            if not math.isfinite(weight):
                raise ModelError(f"weight of {key!r} is not a finite number")
            alpha[index(key)] += weight
        if not alpha.any():
            raise ModelError("the expression mix has no non-zero weight")
        return alpha
    alpha = np.asarray(target, np.float64)
    if alpha.shape != (len(names),) or not np.all(np.isfinite(alpha)):
        raise ModelError(f"expression mix needs {len(names)} finite weights, got shape "
                         f"{alpha.shape}")
    return alpha


def save_model(model: BilinearModel, path: str | Path) -> None:
    """Write ``model`` to an ``.npz`` archive (arrays + a JSON metadata string)."""
    meta = {
        "format": FORMAT_NAME,
        "version": FORMAT_VERSION,
        "regions": [{"name": n, "indices": list(model.region_indices[n]), "K": r.K, "I": r.I,
                     "J": r.J} for n, r in model.regions.items()],
        "expressions": list(model.expressions),
        "identities": list(model.identities),
        "meta": model.meta,
    }
    arrays = {f"{n}.{x}": getattr(r, x) for n, r in model.regions.items() for x in "WAB"}
    arrays["metadata"] = np.array(json.dumps(meta))
    with atomic_file(path, error=ModelError, label=f"model file {path}") as tmp, \
            open(tmp, "wb") as fh:
        np.savez(fh, **arrays)


def load_model(path: str | Path) -> BilinearModel:
    """Read a model written by :func:`save_model`; anything else raises :class:`ModelError`."""
    if not Path(path).exists():
        raise ModelError(f"model file {path} does not exist")
    data = read_bounded(path, MAX_MODEL_BYTES, error=ModelError, what="a model file (.npz)")
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as zf:  # sizes before anything is inflated
            if sum(i.file_size for i in zf.infolist()) > MAX_MODEL_BYTES:
                raise ModelError(f"{path}: its arrays unpack to more than {MAX_MODEL_BYTES} "
                                 "bytes; not a FAP Studio bilinear model")
        npz = np.load(io.BytesIO(data), allow_pickle=False)
        if not isinstance(npz, np.lib.npyio.NpzFile):
            raise ValueError("a plain .npy array")
        with npz:
            arrays = {k: npz[k] for k in npz.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, NotImplementedError) as exc:
        raise ModelError(f"{path} is not a FAP Studio bilinear model (.npz) file") from exc
    try:
        return _model_from_arrays(arrays)
    except ModelError as exc:
        raise ModelError(f"{path}: {exc}") from exc
    except (KeyError, TypeError, ValueError, AttributeError, OverflowError,
            RecursionError) as exc:
        raise ModelError(f"{path} is not a valid bilinear model ({str(exc)[:80]!r})") from None


def _model_from_arrays(arrays: dict[str, np.ndarray]) -> BilinearModel:
    if "metadata" not in arrays or arrays["metadata"].dtype.kind != "U":
        raise ModelError("not a FAP Studio bilinear model (no metadata)")
    meta = json.loads(str(arrays["metadata"][()]), parse_constant=_no_constant)
    if not isinstance(meta, dict) or meta.get("format") != FORMAT_NAME:
        raise ModelError("not a FAP Studio bilinear model (foreign metadata)")
    if meta.get("version") != FORMAT_VERSION:
        raise ModelError(f"unsupported bilinear model version {meta.get('version')!r}")
    expressions = tuple(str(e) for e in meta["expressions"])
    identities = tuple(str(e) for e in meta["identities"])
    regions: dict[str, RegionModel] = {}
    indices: dict[str, tuple[int, ...]] = {}
    for reg in meta["regions"] or [{}]:
        name, K, I, J = str(reg["name"]), int(reg["K"]), int(reg["I"]), int(reg["J"])  # noqa: E741
        idx = tuple(int(i) for i in reg["indices"])
        if not (K > 0 and I > 0 and J > 0) or any(  # noqa: E741
                isinstance(i, bool) or not isinstance(i, int) or not 0 <= i < MAX_LANDMARK
                for i in reg["indices"]):
            raise ModelError(f"region {name!r}: K, I, J must be positive and the landmark "
                             f"indices integers 0-{MAX_LANDMARK - 1}")
        try:
            W, A, B = (arrays[f"{name}.{x}"] for x in "WAB")
        except KeyError as exc:
            raise ModelError(f"bilinear model lacks array {exc.args[0]}") from exc
        want = {"W": (I * K, J), "A": (I, len(expressions)), "B": (J, len(identities))}
        for label, arr in zip("WAB", (W, A, B), strict=True):
            if arr.shape != want[label] or arr.dtype.kind != "f" or not np.all(np.isfinite(arr)):
                raise ModelError(f"region {name!r}: array {label} has shape {arr.shape} / dtype "
                                 f"{arr.dtype}, expected finite floats of shape {want[label]}")
        if K != 2 * len(idx):
            raise ModelError(f"region {name!r}: K={K} but {len(idx)} landmark indices")
        regions[name] = RegionModel(W=W.astype(np.float64), A=A.astype(np.float64),
                                    B=B.astype(np.float64), K=K)
        indices[name] = idx
    extra = meta.get("meta", {})
    lam = extra.get("lambda", {}) if isinstance(extra, dict) else None
    norm = extra.get("normalisation", {}) if isinstance(extra, dict) else None
    if (not isinstance(lam, dict) or not isinstance(norm, dict)
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                       and math.isfinite(v) and v >= 0 for v in lam.values())
            or not isinstance(norm.get("layout", ""), str)):
        raise ModelError("metadata \"meta\" must be an object; its \"lambda\" maps methods "
                         "to finite numbers >= 0, its \"normalisation\" is an object")
    return BilinearModel(regions, indices, expressions, identities, dict(extra))


def _no_constant(name: str) -> None:
    raise ValueError(f"{name} is not a number JSON allows")
