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

The layout is :data:`~editor.synthesis.landmark_scheme.STASM77` (mirror pairs and MPEG-4
feature points there). Normalisation conventions (SPEC §5): origin = the image's own nose tip
(52); coordinates are divided by the person's neutral inner-eye-corner distance ‖p30 − p40‖
(mean over that person's neutral images; the same scale for all of the person's expressions; a
face without a neutral image uses its own distance). Contour points (0–15) are not modelled.
The nose tip is left out of the nose region because it is the origin (identically zero).
Regions are brows / eyes / nose / mouth, modelled separately and joined by concatenation.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from editor.errors import ModelError
from editor.safeio import read_bounded

from .bilinear import BilinearModel, expression_alpha
from .jaffe import JAFFE_CODES
from .landmark_scheme import STASM77, LandmarkSet

__all__ = ["EXPRESSIONS", "LandmarkSet", "load_stasm77", "synthesize_shape", "train_from_means",
           "train_model"]

#: The Stasm model's expression names, label k = JAFFE_CODES[k].
EXPRESSIONS = ("neutral", "happy", "sad", "surprise", "angry", "disgust", "fear")


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
        if len(vals) != 2 * STASM77.n_points or not np.all(np.isfinite(vals)):
            raise ModelError(f"{feat}:{n}: expected {2 * STASM77.n_points} numbers, "
                             f"got {len(vals)}")
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
    pts = np.asarray(rows, dtype=np.float64).reshape(-1, STASM77.n_points, 2)
    return LandmarkSet(pts, persons, labels, names)


def train_from_means(means: np.ndarray, people: tuple[str, ...], I: int | None = None,  # noqa: E741
                     J: int | None = None, tol: float = 1e-10,
                     max_iter: int = 100) -> tuple[BilinearModel, dict[str, np.ndarray]]:
    """Train one bilinear model per Stasm region from mean shapes (C, 7, 77, 2). Returns the
    model and each region's error history."""
    return STASM77.train_from_means(
        means, people, EXPRESSIONS, {"training": "mean of each person's images per expression"},
        I, J, tol, max_iter)


def train_model(data: LandmarkSet, people: tuple[str, ...] | None = None, I: int | None = None,  # noqa: E741
                J: int | None = None, tol: float = 1e-10,
                max_iter: int = 100) -> tuple[BilinearModel, dict[str, np.ndarray]]:
    """Normalise ``data`` and train on ``people`` (default all) × the 7 expressions."""
    people = data.people if people is None else tuple(people)
    pts, _, _ = STASM77.normalise_set(data)
    return train_from_means(STASM77.mean_shapes(pts, data, people, EXPRESSIONS), people,
                            I, J, tol, max_iter)


def synthesize_shape(model: BilinearModel, points: np.ndarray, target: Any,
                     method: str = "mals", lam: float | None = None,
                     scale: float | None = None, tol: float = 1e-3,
                     max_iter: int = 50) -> np.ndarray:
    """Landmarks (77, 2) of the face ``points`` (77, 2) with the target expression.

    ``target``: see :func:`~editor.synthesis.bilinear.expression_alpha`; ``lam`` defaults to
    ``model.meta["lambda"][method]`` (:class:`ModelError` if neither is given for ridge/MALS);
    the synthesis itself is :meth:`LandmarkScheme.synthesize
    <editor.synthesis.landmark_scheme.LandmarkScheme.synthesize>`.
    """
    pts = STASM77.check_points(points)
    if lam is None and method != "plain":
        lam = model.meta.get("lambda", {}).get(method)
        if lam is None:
            raise ModelError(f"no λ given for {method} and none stored in the model")
    return STASM77.synthesize(model, pts, expression_alpha(model, target), method, lam or 0.0,
                              scale, tol=tol, max_iter=max_iter)
