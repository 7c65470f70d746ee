"""The bilinear model on photos: dlib-68 training data and synthesis on a :class:`Face` (issue 9).

The photo pipeline detects iBUG/dlib-68 landmarks, so the photo route trains the same symmetric
bilinear model (:func:`editor.synthesis.bilinear.train_bilinear`, SPEC §5) on dlib-68 points
detected on the training images instead of the Stasm-77 points of
:mod:`editor.synthesis.bilinear_data`. The layout is
:data:`~editor.synthesis.landmark_scheme.DLIB68`; conventions (stored in the model's metadata):

* origin = the image's nose tip (68-point index 30); scale = the person's mean neutral
  inner-eye-corner distance ``|p39 - p42|`` (a single photo: its own distance);
* regions: brows 17–26, eyes 36–47, nose 27–35 without the tip (it is the origin), mouth
  48–67; the jaw contour 0–16 is not modelled (synthesis keeps the input's contour);
* expressions are named like the presets: neutral, joy, sadness, surprise, anger, disgust,
  fear (JAFFE's NE HA SA SU AN DI FE); the Stasm model's names (happy, sad, angry) are
  accepted as aliases.

Synthesis on a photo (:func:`synthesize_on_face`) starts from the neutralised face (a smiling
photo's own smile removed, :func:`neutral_points68`): translate its 68 points (plain /
ridge / MALS), pin the gauge, replace ``a`` by the target mix ``A α``, rebuild with the face's
own ``b``, undo the normalisation, keep the jaw contour; then fit the personalized mesh to the
synthesized points (:func:`editor.engine.fitting.fit_vertices`) and apply the
displacement between that fit and the fit of the neutral points to the face's neutral mesh as
rendered (``face.deform(None)``), through the crossing rule and the fold guard
(:func:`editor.synthesis.cloning.finish`).

Training images are research data (JAFFE): detections are cached in the user's cache
directory (:func:`default_cache_dir`), never in the repository.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from editor.engine.fitting import fit_vertices
from editor.engine.imageio import load_image
from editor.engine.landmarks import default_detector
from editor.engine.laplacian import landmark_map
from editor.errors import ModelError, NoFaceError
from editor.resources import user_cache_dir
from editor.safeio import atomic_file

from .bilinear import BilinearModel, expression_alpha
from .cloning import finish
from .fap_estimate import FapEstimator
from .jaffe import JAFFE_CODES
from .landmark_scheme import DLIB68, LandmarkSet, normalise

#: The dlib-68 model's expression names (as the presets), label k = JAFFE_CODES[k].
EXPRESSIONS68 = ("neutral", "joy", "sadness", "surprise", "anger", "disgust", "fear")
#: λ used when the model stores none (normalised units; see the module docstring).
DEFAULT_LAMBDA = {"ridge": 0.01, "mals": 0.01}


# ---------------------------------------------------------------------------- training data
def default_cache_dir() -> Path:
    """``$FAP_STUDIO_CACHE``, else the per-OS cache folder (``~/.cache/fap-studio`` on Linux;
    :func:`editor.resources.user_cache_dir`)."""
    return user_cache_dir()


def _jaffe_label(name: str) -> int:
    parts = name.split(".")
    if len(parts) < 2 or parts[1][:2].upper() not in JAFFE_CODES:
        raise ModelError(f"{name}: not a JAFFE-style name PERSON.EXPRn.ID.ext")
    return JAFFE_CODES.index(parts[1][:2].upper())


def detect_training_set(images_dir: str | os.PathLike[str], people: tuple[str, ...] | None = None,
                        per_expression: int | None = None, cache_dir: str | Path | None = None,
                        detector: Any = None,
                        progress: Callable[[int, int], object] | None = None) -> LandmarkSet:
    """dlib-68 landmarks of JAFFE-style images ``PERSON.EXPRn.ID.tiff`` as a LandmarkSet.

    ``people`` restricts the person codes; ``per_expression`` keeps at most that many images per
    (person, expression). Detections are cached (one ``.npz`` per image list) in ``cache_dir``
    (default :func:`default_cache_dir`; ``""`` disables). Images without a face are skipped.
    """
    root = Path(images_dir)
    if not root.is_dir():
        raise ModelError(f"{root}: not a directory of training images")
    exts = {".tif", ".tiff", ".png", ".jpg", ".jpeg", ".bmp"}
    files = sorted(p for p in root.iterdir() if p.suffix.lower() in exts)
    chosen: list[Path] = []
    count: dict[tuple[str, int], int] = {}
    for p in files:
        person, label = p.name.split(".")[0], _jaffe_label(p.name)
        if people is not None and person not in people:
            continue
        k = count.get((person, label), 0)
        if per_expression is not None and k >= per_expression:
            continue
        count[(person, label)] = k + 1
        chosen.append(p)
    if not chosen:
        raise ModelError(f"{root}: no JAFFE-style training images found")
    det = detector or default_detector()  # its name is part of the key
    key = hashlib.sha1("\n".join([det.name] + [f"{p.name}:{p.stat().st_size}" for p in chosen])
                       .encode())
    cache = None
    if cache_dir != "":
        cache = Path(cache_dir or default_cache_dir()) / f"dlib68_{key.hexdigest()[:16]}.npz"
        if cache.exists():
            try:
                with np.load(cache, allow_pickle=False) as z:
                    pts, names = z["points"], [str(n) for n in z["names"]]
                return _landmark_set(pts, names)
            except (OSError, ValueError, KeyError):
                pass
    pts_l, names_l = [], []
    for i, p in enumerate(chosen):
        try:
            points = det.detect(load_image(p))[0]
            pts_l.append(np.asarray(points, np.float64).reshape(DLIB68.n_points, 2))
            names_l.append(p.name)
        except NoFaceError:
            pass
        if progress is not None:
            progress(i + 1, len(chosen))
    if not pts_l:
        raise ModelError(f"{root}: no face found in any training image")
    pts = np.array(pts_l)
    if cache is not None:
        try:
            with atomic_file(cache, error=ModelError) as tmp, open(tmp, "wb") as fh:
                np.savez(fh, points=pts, names=np.array(names_l))
        except ModelError:  # a cache that cannot be written is only slower next time
            pass
    return _landmark_set(pts, names_l)


def _landmark_set(points: np.ndarray, names: list[str]) -> LandmarkSet:
    persons = tuple(n.split(".")[0] for n in names)
    labels = np.array([_jaffe_label(n) for n in names])
    return LandmarkSet(np.asarray(points, np.float64), persons, labels, tuple(names))


def train_from_means68(means: np.ndarray, people: tuple[str, ...], I: int | None = None,  # noqa: E741
                       J: int | None = None, source: str = "") -> BilinearModel:
    """One bilinear model per dlib-68 region from mean shapes (C, S, 68, 2)."""
    return DLIB68.train_from_means(
        means, people, EXPRESSIONS68,
        {"lambda": dict(DEFAULT_LAMBDA), "lambda_selection": "fixed default",
         "training": f"dlib-68 detections {source}".strip()}, I, J)[0]


def train_model68(data: LandmarkSet, people: tuple[str, ...] | None = None,
                  I: int | None = None, J: int | None = None) -> BilinearModel:  # noqa: E741
    """Train the dlib-68 model on ``people`` (default: everyone with all 7 expressions)."""
    if people is None:
        people = tuple(p for p in data.people
                       if set(data.labels[np.asarray(data.persons) == p]) >= set(range(7)))
    if not people:
        raise ModelError("no person has a detected image of every expression")
    pts, _, _ = DLIB68.normalise_set(data)
    means = DLIB68.mean_shapes(pts, data, tuple(people), EXPRESSIONS68)
    return train_from_means68(means, tuple(people), I, J, "")


# ---------------------------------------------------------------------------- synthesis
def check_model68(model: BilinearModel) -> None:
    """Raise ModelError unless ``model`` was trained on the dlib-68 layout."""
    try:
        DLIB68.check_model(model)
    except ModelError as e:
        raise ModelError(f"{e}: the photo route needs a dlib-68 model (bilinear train --detect "
                         "IMAGES)") from None


def parse_mix(text: str) -> dict[str, float]:
    """``"joy:0.5, surprise:0.5"`` (or a single name) -> ``{name: weight}``."""
    out: dict[str, float] = {}
    for part in (t.strip() for t in text.split(",")):
        if not part:
            continue
        name, _, w = part.partition(":") if ":" in part else part.partition("=")
        try:
            out[name.strip()] = out.get(name.strip(), 0.0) + (float(w) if w.strip() else 1.0)
        except ValueError as exc:
            raise ModelError(f"bad weight in expression mix: {part!r}") from exc
    if not out:
        raise ModelError("empty expression mix")
    return out


def synthesize_points68(model: BilinearModel, points68: np.ndarray,
                        target: str | Mapping[str, float] | np.ndarray, method: str = "mals",
                        lam: float | None = None, scale: float | None = None,
                        keep_residual: bool = False, tol: float = 1e-3,
                        max_iter: int = 50) -> np.ndarray:
    """(68, 2) landmarks of the face ``points68`` with the target expression.

    ``keep_residual`` adds the part of the input the model does not reconstruct (input −
    rebuilt input) to the synthesized shape, so identity detail outside the model's span is kept
    (our option; the paper's synthesis is ``keep_residual=False``).
    """
    check_model68(model)
    if method not in ("plain", "ridge", "mals"):
        raise ModelError(f"unknown method {method!r} (use plain, ridge or mals)")
    if lam is None and method != "plain":
        lam = model.meta.get("lambda", {}).get(method, DEFAULT_LAMBDA[method])
    if lam is not None and (not np.isfinite(lam) or lam < 0):
        raise ModelError(f"λ must be a non-negative number, got {lam}")
    return DLIB68.synthesize(model, points68, expression_alpha(model, target), method,
                             lam or 0.0, scale, keep_residual, tol, max_iter)


@dataclass
class PhotoSynthesis:
    """A synthesized expression on a photo."""
    vertices: np.ndarray  # (V, 2) float32 deformed mesh (fold-free)
    points68: np.ndarray  # (68, 2) synthesized landmarks
    image: np.ndarray | None = None  # (H, W, 3) uint8 render, if asked for


def neutral_points68(face: Any) -> np.ndarray:
    """(68, 2) the photo's landmarks on the neutralised face, where FAPs and synthesis start.

    A photo that shows an expression (:attr:`Face.expression`) is first neutralised: each
    landmark keeps its barycentric place in the photo's mesh and follows that mesh to the
    neutral face as rendered (``face.deform(None)``). A neutral photo's landmarks are returned
    as they are.
    """
    pts = np.asarray(face.landmarks.points, np.float64)
    if not face.has_expression:
        return pts

    A = landmark_map(face.vertices, face.triangles, face.mesh.names, pts)
    return np.asarray(A @ face.deform(None).astype(np.float64))


def mesh_for_points(face: Any, points68: np.ndarray, base68: np.ndarray | None = None
                    ) -> np.ndarray:
    """The face's neutral mesh moved so that it follows ``points68`` (fold-free), (V, 2)
    float32. ``base68`` are the landmarks of that neutral mesh (default
    :func:`neutral_points68`): the mesh moves by the fitted displacement base68 -> points68."""
    base = neutral_points68(face) if base68 is None else np.asarray(base68, np.float64)
    h, w = face.image.shape[:2]
    names = face.mesh.names
    fit_new, _ = fit_vertices(np.asarray(points68, np.float64), (w, h))
    fit_old, _ = fit_vertices(base, (w, h))
    D = np.array([fit_new[n] - fit_old[n] for n in names], np.float64)
    D[face.mesh.regions == "border"] = 0.0
    return finish(face, face.deform(None).astype(np.float64) + D)


def synthesize_on_face(face: Any, model: BilinearModel,
                       target: str | Mapping[str, float] | np.ndarray, method: str = "mals",
                       lam: float | None = None, keep_residual: bool = False,
                       render: bool = False, sharp: bool = False) -> PhotoSynthesis:
    """Synthesize ``target`` on a :class:`~editor.engine.face.Face` (see the module docstring).

    The synthesis starts from the neutralised face (:func:`neutral_points68`), so a smiling
    photo synthesized as anger shows anger, not anger over its smile. Returns the fold-free
    deformed mesh, the synthesized 68 points and (``render``) the image (``sharp``: resampled
    bicubically, as a still is).
    """
    base = neutral_points68(face)
    pts = synthesize_points68(model, base, target, method, lam, keep_residual=keep_residual)
    v = mesh_for_points(face, pts, base)
    img = face.render_mesh(v, sharp=sharp).image if render else None
    return PhotoSynthesis(v, pts.astype(np.float32), img)


def faps_for_points(face: Any, points68: np.ndarray) -> np.ndarray:
    """(68,) FAP vector (the face's FAPU) that best reproduces the landmark motion from the
    neutralised face (:func:`neutral_points68`) to ``points68``: the document's FAPs."""
    return FapEstimator(face).estimate(np.asarray(points68, np.float64),
                                       neutral68=neutral_points68(face)).faps


def synthetic_model68(points68: np.ndarray, n_people: int = 6, seed: int = 0) -> BilinearModel:
    """A toy dlib-68 model (tests and demos without training data).

    People are ``points68`` (normalised) with random per-region scalings and shifts; the seven
    expressions are hand-made displacement fields in inner-eye units (joy: corners up and out,
    lower lip down; surprise: brows up, jaw open; sadness: corners down, inner brows up; anger:
    brows down and together, lips pressed; disgust: upper lip up; fear: brows up, corners back).
    """
    rng = np.random.default_rng(seed)
    p68 = DLIB68.check_points(points68)
    base = normalise(p68, p68[DLIB68.nose_tip], float(DLIB68.inner_eye_distance(p68)))
    fields = np.zeros((7, DLIB68.n_points, 2))
    lower = [55, 56, 57, 58, 59, 65, 66, 67]
    fields[1, [48, 60], 0], fields[1, [54, 64], 0] = -0.12, 0.12
    fields[1, [48, 54, 60, 64], 1] = -0.15
    fields[1, lower, 1] += 0.12
    fields[2, [48, 54, 60, 64], 1], fields[2, [21, 22], 1] = 0.12, -0.1
    fields[3, 17:27, 1] = -0.25
    fields[3, lower + [5, 6, 7, 8, 9, 10, 11], 1] += 0.45
    fields[3, [50, 51, 52, 61, 62, 63], 1] = -0.05
    fields[4, 17:27, 1], fields[4, 19:22, 0], fields[4, 22:25, 0] = 0.1, 0.08, -0.08
    fields[4, [61, 62, 63], 1], fields[4, [65, 66, 67], 1] = 0.04, -0.04
    fields[5, [49, 50, 51, 52, 53, 61, 62, 63], 1] = fields[6, 17:27, 1] = -0.12
    fields[6, [48, 60], 0], fields[6, [54, 64], 0] = -0.08, 0.08
    means = np.empty((n_people, 7, DLIB68.n_points, 2))
    for c in range(n_people):
        person = base.copy()
        for idx in DLIB68.regions.values():
            i = list(idx)
            ctr = person[i].mean(0)
            person[i] = ctr + rng.normal(0, 0.03, 2) + (person[i] - ctr) * rng.uniform(0.9, 1.1, 2)
        for s in range(7):
            means[c, s] = person + fields[s] * rng.uniform(0.8, 1.2)
    return train_from_means68(means, tuple(f"P{c}" for c in range(n_people)),
                              source="(synthetic toy model)")
