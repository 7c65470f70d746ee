"""Landmark data for the bilinear model: Stasm 77-point layout, JAFFE loading, normalisation.

Stasm 77-point index map, determined by drawing the JAFFE landmarks on the images (several
people, neutral / happy / surprise). "Image-left" is the viewer's left (the subject's right):

======  ==============================================================================
0–12    jaw contour: image-left temple (0) → chin (6) → image-right temple (12)
13–15   forehead: 13 image-right, 14 centre, 15 image-left
16–21   image-left brow: 16, 17 upper edge (inner → outer), 18 outer end,
        19, 20 lower edge (outer → inner), 21 inner end
22–27   image-right brow: 22 inner end, 23, 24 upper edge (inner → outer), 25 outer end,
        26, 27 lower edge (outer → inner)
28, 29  upper-eyelid crease above the image-right (28) / image-left (29) eye
30–38   image-left eye: 30 inner corner, 31–33 upper lid (inner → outer), 34 outer corner,
        35–37 lower lid (outer → inner), 38 pupil
39–47   image-right eye: 39 pupil, 40 inner corner, 41–43 upper lid (inner → outer),
        44 outer corner, 45–47 lower lid (outer → inner)
48–58   nose: 48–50 across the lower nose bridge (image-right side, ridge, image-left side),
        51 / 53 image-left / image-right nostril, 52 nose tip, 54 / 58 image-right /
        image-left ala, 55 / 57 ala bases, 56 subnasale
59–76   mouth: 59 image-left corner, 60–64 outer upper lip (left → right, 62 centre),
        65 image-right corner, 66–68 inner upper lip (right → left), 69–71 inner lower lip
        (left → right), 72–76 outer lower lip (right → left, 74 centre)
======  ==============================================================================

Normalisation conventions (SPEC §5): origin = the image's own nose tip (52); coordinates are
divided by the person's neutral inner-eye-corner distance ‖p30 − p40‖ (mean over that person's
neutral images; the same scale for all of the person's expressions; a face without a neutral
image uses its own distance). Contour points (0–15) are not modelled. The nose tip is left out
of the nose region because it is the origin (identically zero). Regions are brows / eyes / nose
/ mouth, modelled separately and joined by concatenation.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from editor.errors import ModelError
from editor.safeio import read_bounded
from editor.synthesis.bilinear import (
    BilinearModel,
    RegionModel,
    fix_gauge,
    synthesize_region,
    train_bilinear,
    translate,
)
from editor.synthesis.jaffe import JAFFE_CODES

N_LANDMARKS = 77
NOSE_TIP = 52
INNER_EYE_CORNERS = (30, 40)
CONTOUR = tuple(range(0, 16))
REGIONS: dict[str, tuple[int, ...]] = {
    "brows": tuple(range(16, 28)),
    "eyes": tuple(range(28, 48)),
    "nose": tuple(i for i in range(48, 59) if i != NOSE_TIP),
    "mouth": tuple(range(59, 77)),
}
EXPRESSIONS = ("neutral", "happy", "sad", "surprise", "angry", "disgust", "fear")
NORMALISATION = {
    "layout": "stasm77",
    "origin": f"nose tip (landmark {NOSE_TIP}) of the same image",
    "scale": "person's mean neutral inner-eye-corner distance |p30 - p40| (own distance "
             "if no neutral image)",
    "vector": "x0, y0, x1, y1, ... of the region's landmarks, image coordinates, y down",
    "nose_tip": NOSE_TIP,
    "inner_eye_corners": list(INNER_EYE_CORNERS),
}


@dataclass(frozen=True)
class LandmarkSet:
    """Landmarks of N labelled images.

    points (N, 77, 2) float pixels; persons N person codes; labels (N,) int expression indices
    into :data:`EXPRESSIONS`; names N image names.
    """

    points: np.ndarray
    persons: tuple[str, ...]
    labels: np.ndarray
    names: tuple[str, ...]

    @property
    def people(self) -> tuple[str, ...]:
        """Distinct person codes in first-seen order."""
        return tuple(dict.fromkeys(self.persons))


def _read_lines(path: Path) -> list[str]:
    data = read_bounded(path, 256 * 1024 * 1024, error=ModelError, label=f"cannot read {path}",
                        what="a text file")
    try:
        return [ln for ln in data.decode("utf-8").splitlines() if ln.strip()]
    except UnicodeDecodeError as exc:
        raise ModelError(f"{path} is not a text file") from exc


def load_stasm77(path: str | Path) -> LandmarkSet:
    """Load a JAFFE-style ``landmarks_stasm77`` directory (or its ``all_features.txt``).

    ``all_features.txt``: one image a line, 154 integers ``x ,y ,x ,y ...``;
    ``all_names.txt``: ``PERSON.EXPRn.ID.tiff`` (person = text before the first dot);
    ``all_labels.txt`` (optional): 0 NE … 6 FE, else the label comes from the name.
    """
    path = Path(path)
    feat = path / "all_features.txt" if path.is_dir() else path
    if not feat.exists():
        raise ModelError(f"no landmark file at {feat}")
    rows = []
    for n, line in enumerate(_read_lines(feat), start=1):
        toks = [t for t in re.split(r"[\s,]+", line) if t]
        try:
            vals = [float(t) for t in toks]
        except ValueError as exc:
            raise ModelError(f"{feat}:{n}: non-numeric landmark value") from exc
        if len(vals) != 2 * N_LANDMARKS or not np.all(np.isfinite(vals)):
            raise ModelError(f"{feat}:{n}: expected {2 * N_LANDMARKS} numbers, got {len(vals)}")
        rows.append(vals)
    if not rows:
        raise ModelError(f"{feat} holds no landmarks")
    names_path = feat.parent / "all_names.txt"
    names = tuple(ln.strip() for ln in _read_lines(names_path)) if names_path.exists() else ()
    if len(names) != len(rows):
        raise ModelError(f"{names_path} must name each of the {len(rows)} images")
    persons = tuple(nm.split(".")[0] for nm in names)
    labels_path = feat.parent / "all_labels.txt"
    try:
        if labels_path.exists():
            labels = np.array([int(ln) for ln in _read_lines(labels_path)])
        else:
            labels = np.array([JAFFE_CODES.index(nm.split(".")[1][:2]) for nm in names])
    except (ValueError, IndexError) as exc:
        raise ModelError(f"cannot read the expression labels next to {feat}") from exc
    if labels.shape != (len(rows),) or labels.min() < 0 or labels.max() >= len(EXPRESSIONS):
        raise ModelError(f"{labels_path}: need one label 0–6 per image")
    pts = np.asarray(rows, dtype=np.float64).reshape(-1, N_LANDMARKS, 2)
    return LandmarkSet(pts, persons, labels, names)


def inner_eye_distance(points: np.ndarray) -> np.ndarray:
    """Inner-eye-corner distance; points (..., 77, 2) -> (...)."""
    i, j = INNER_EYE_CORNERS
    return np.linalg.norm(points[..., i, :] - points[..., j, :], axis=-1)


def person_scales(points: np.ndarray, persons: tuple[str, ...] | list[str],
                  labels: np.ndarray) -> np.ndarray:
    """Per-image scale (N,): the person's mean neutral inner-eye distance, or the image's own."""
    own = inner_eye_distance(points)
    scales = own.copy()
    persons_arr = np.asarray(persons)
    for p in np.unique(persons_arr):
        mine = persons_arr == p
        neutral = mine & (np.asarray(labels) == 0)
        if neutral.any():
            scales[mine] = own[neutral].mean()
    if np.any(scales <= 0):
        raise ModelError("a face has coincident inner eye corners (zero scale)")
    return scales


def normalise(points: np.ndarray, origin: np.ndarray, scale: np.ndarray | float) -> np.ndarray:
    """(points − origin) / scale; points (..., n, 2), origin (..., 2), scale (...)."""
    return (points - np.asarray(origin)[..., None, :]) / np.asarray(scale)[..., None, None]


def denormalise(points: np.ndarray, origin: np.ndarray, scale: np.ndarray | float) -> np.ndarray:
    """Inverse of :func:`normalise`."""
    return points * np.asarray(scale)[..., None, None] + np.asarray(origin)[..., None, :]


def normalise_set(data: LandmarkSet) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Normalise every image: returns points (N, 77, 2), origins (N, 2), scales (N,)."""
    scales = person_scales(data.points, data.persons, data.labels)
    origins = data.points[:, NOSE_TIP, :]
    return normalise(data.points, origins, scales), origins, scales


def region_vectors(points: np.ndarray, indices: tuple[int, ...]) -> np.ndarray:
    """Region K-vectors: points (..., 77, 2) -> (..., 2·len(indices)) as x0, y0, x1, y1, ..."""
    sel = points[..., list(indices), :]
    return sel.reshape(*sel.shape[:-2], -1)


def mean_shapes(points: np.ndarray, persons: tuple[str, ...], labels: np.ndarray,
                people: tuple[str, ...]) -> np.ndarray:
    """Average the normalised images of each (person, expression): -> (C, S, 77, 2).

    Every person needs at least one image of each of the S = 7 expressions.
    """
    persons_arr, labels = np.asarray(persons), np.asarray(labels)
    out = np.empty((len(people), len(EXPRESSIONS), N_LANDMARKS, 2))
    for c, p in enumerate(people):
        for s, expr in enumerate(EXPRESSIONS):
            sel = (persons_arr == p) & (labels == s)
            if not sel.any():
                raise ModelError(f"person {p} has no {expr} image")
            out[c, s] = points[sel].mean(axis=0)
    return out


def training_matrix(means: np.ndarray, indices: tuple[int, ...]) -> np.ndarray:
    """Z (S·K, C) of one region from mean shapes (C, S, 77, 2); block (s, c) = z^{sc}."""
    v = region_vectors(means, indices)  # (C, S, K)
    C, S, K = v.shape
    return v.transpose(1, 2, 0).reshape(S * K, C)


def train_from_means(means: np.ndarray, people: tuple[str, ...], I: int | None = None,  # noqa: E741
                     J: int | None = None, tol: float = 1e-10,
                     max_iter: int = 100) -> tuple[BilinearModel, dict[str, np.ndarray]]:
    """Train one bilinear model per region. Returns the model and each region's error history."""
    regions: dict[str, RegionModel] = {}
    errors: dict[str, np.ndarray] = {}
    for name, idx in REGIONS.items():
        res = train_bilinear(training_matrix(means, idx), 2 * len(idx), I, J, tol, max_iter)
        regions[name], errors[name] = res.model, res.errors
    model = BilinearModel(regions, dict(REGIONS), EXPRESSIONS, tuple(people),
                          {"normalisation": dict(NORMALISATION),
                           "training": "mean of each person's images per expression"})
    return model, errors


def train_model(data: LandmarkSet, people: tuple[str, ...] | None = None, I: int | None = None,  # noqa: E741
                J: int | None = None, tol: float = 1e-10,
                max_iter: int = 100) -> tuple[BilinearModel, dict[str, np.ndarray]]:
    """Normalise ``data`` and train on ``people`` (default all) × the 7 expressions."""
    people = data.people if people is None else tuple(people)
    pts, _, _ = normalise_set(data)
    return train_from_means(mean_shapes(pts, data.persons, data.labels, people), people,
                            I, J, tol, max_iter)


def expression_weights(model: BilinearModel, target: Any) -> np.ndarray:
    """α (S,) from an expression name, an index, a ``{name: weight}`` mix or an array."""
    S = len(model.expressions)
    if isinstance(target, str | int | np.integer):
        target = {target: 1.0}
    if isinstance(target, dict):
        alpha = np.zeros(S)
        for key, w in target.items():
            if isinstance(key, str):
                if key not in model.expressions:
                    raise ModelError(f"unknown expression {key!r} (model has "
                                     f"{', '.join(model.expressions)})")
                key = model.expressions.index(key)
            if not 0 <= int(key) < S:
                raise ModelError(f"expression index {key} out of range 0–{S - 1}")
            alpha[int(key)] += float(w)
        return alpha
    alpha = np.asarray(target, dtype=np.float64)
    if alpha.shape != (S,):
        raise ModelError(f"expression mix needs {S} weights, got shape {alpha.shape}")
    return alpha


def synthesize_shape(model: BilinearModel, points: np.ndarray, target: Any,
                     method: str = "mals", lam: float | None = None,
                     scale: float | None = None, tol: float = 1e-3,
                     max_iter: int = 50) -> np.ndarray:
    """Landmarks (77, 2) of the face ``points`` (77, 2) with the target expression.

    Each region is translated (``method``, ``lam``; default λ from ``model.meta["lambda"]``),
    its gauge pinned (:func:`~editor.synthesis.bilinear.fix_gauge`), its expression vector
    replaced by ``A α`` and rebuilt with its own identity vector; the scale (default the face's
    own inner-eye distance) is undone and the nose tip added back. Contour points are copied.
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.shape != (N_LANDMARKS, 2) or not np.all(np.isfinite(pts)):
        raise ModelError(f"need {N_LANDMARKS} finite landmarks, got shape {pts.shape}")
    if lam is None and method != "plain":
        lam = model.meta.get("lambda", {}).get(method)
        if lam is None:
            raise ModelError(f"no λ given for {method} and none stored in the model")
    alpha = expression_weights(model, target)
    origin = pts[NOSE_TIP]
    s = float(inner_eye_distance(pts)) if scale is None else float(scale)
    if s <= 0:
        raise ModelError("inner eye corners coincide: cannot normalise the face")
    norm = normalise(pts, origin, s)
    out = norm.copy()
    for name, reg in model.regions.items():
        idx = list(model.region_indices[name])
        tr = translate(reg, region_vectors(norm, tuple(idx)), method, lam or 0.0, tol, max_iter)
        _, b = fix_gauge(reg, tr.a, tr.b)
        out[idx] = synthesize_region(reg, b, alpha).reshape(-1, 2)
    return denormalise(out, origin, s)
