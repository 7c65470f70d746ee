"""Landmark schemes of the bilinear model: one description per layout, one set of operations.

The bilinear identity × expression model (:mod:`.bilinear`) is trained on 2-D landmarks of one
layout: Stasm's 77 points (the JAFFE landmark files, :mod:`.bilinear_data`) or the iBUG/dlib 68
points the photo pipeline detects (:mod:`.bilinear_photo`). A :class:`LandmarkScheme` says
what differs between them (point count, nose tip, inner eye corners, jaw contour, the modelled
regions, the left/right mirror partner of each point and the MPEG-4 feature points) and does
what is common: normalisation (origin = the nose tip; scale = the person's mean neutral
inner-eye-corner distance, or a face's own one), per-person mean shapes, training one model per
region and synthesis. :data:`STASM77` and :data:`DLIB68` are the two schemes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from editor.engine.landmarks import FDP_FROM_68, MIRROR_68
from editor.errors import ModelError

from .bilinear import (
    BilinearModel,
    RegionModel,
    fix_gauge,
    synthesize_region,
    train_bilinear,
    translate,
)


@dataclass(frozen=True)
class LandmarkSet:
    """Landmarks of N labelled images.

    points (N, P, 2) float pixels; persons N person codes; labels (N,) int expression indices
    (0 = neutral); names N image names.
    """

    points: np.ndarray
    persons: tuple[str, ...]
    labels: np.ndarray
    names: tuple[str, ...]

    @property
    def people(self) -> tuple[str, ...]:
        """Distinct person codes in first-seen order."""
        return tuple(dict.fromkeys(self.persons))


def normalise(points: np.ndarray, origin: np.ndarray, scale: np.ndarray | float) -> np.ndarray:
    """(points − origin) / scale; points (..., n, 2), origin (..., 2), scale (...)."""
    return (points - np.asarray(origin)[..., None, :]) / np.asarray(scale)[..., None, None]


def denormalise(points: np.ndarray, origin: np.ndarray, scale: np.ndarray | float) -> np.ndarray:
    """Inverse of :func:`normalise`."""
    return points * np.asarray(scale)[..., None, None] + np.asarray(origin)[..., None, :]


def region_vectors(points: np.ndarray, indices: Sequence[int]) -> np.ndarray:
    """Region K-vectors: points (..., P, 2) -> (..., 2·len(indices)) as x0, y0, x1, y1, ..."""
    sel = points[..., list(indices), :]
    return sel.reshape(*sel.shape[:-2], -1)


def training_matrix(means: np.ndarray, indices: Sequence[int]) -> np.ndarray:
    """Z (S·K, C) of one region from mean shapes (C, S, P, 2); block (s, c) = z^{sc}."""
    v = region_vectors(means, indices)  # (C, S, K)
    C, S, K = v.shape
    return v.transpose(1, 2, 0).reshape(S * K, C)


@dataclass(frozen=True, eq=False)
class LandmarkScheme:
    """A 2-D landmark layout and the bilinear model's conventions on it.

    Attributes
    ----------
    name : str
        Stored in a model's metadata (``normalisation.layout``); a model only works with points
        of its own scheme.
    n_points : int
        Landmarks per face.
    nose_tip : int
        The origin of the normalised shape (left out of every region: it is always zero).
    inner_eye_corners : (int, int)
        Their distance is the scale.
    contour : tuple of int
        The jaw (and forehead) contour: not modelled, synthesis keeps the input's.
    regions : dict
        Region name -> landmark indices, each modelled separately.
    mirror : numpy.ndarray
        (n_points,) index of each point's left/right partner (itself on the midline).
    fdp : dict
        MPEG-4 feature point -> the landmark indices whose mean it is.
    """

    name: str
    n_points: int
    nose_tip: int
    inner_eye_corners: tuple[int, int]
    contour: tuple[int, ...]
    regions: Mapping[str, tuple[int, ...]]
    mirror: np.ndarray = field(repr=False)
    fdp: Mapping[str, tuple[int, ...]] = field(repr=False)

    def __post_init__(self) -> None:
        m = np.asarray(self.mirror, np.int64)
        idx = np.arange(self.n_points)
        if m.shape != (self.n_points,) or not np.array_equal(m[m], idx):
            raise ValueError(f"{self.name}: the mirror table must pair up {self.n_points} points")
        used = [i for r in self.regions.values() for i in r] + list(self.contour)
        used += [i for v in self.fdp.values() for i in v] + [self.nose_tip,
                                                             *self.inner_eye_corners]
        if min(used) < 0 or max(used) >= self.n_points or self.nose_tip in set(
                i for r in self.regions.values() for i in r):
            raise ValueError(f"{self.name}: an index is out of range or the nose tip is modelled")
        m.flags.writeable = False
        object.__setattr__(self, "mirror", m)

    @property
    def normalisation(self) -> dict[str, Any]:
        """The conventions as stored in a model's metadata."""
        i, j = self.inner_eye_corners
        return {"layout": self.name,
                "origin": f"nose tip (landmark {self.nose_tip}) of the same image",
                "scale": f"person's mean neutral inner-eye-corner distance |p{i} - p{j}| (own "
                         "distance if no neutral image)",
                "vector": "x0, y0, x1, y1, ... of the region's landmarks, image coordinates, "
                          "y down",
                "nose_tip": self.nose_tip, "inner_eye_corners": [i, j]}

    def check_points(self, points: np.ndarray) -> np.ndarray:
        """(n_points, 2) float64 copy of one face's landmarks; :class:`ModelError` otherwise."""
        pts = np.array(points, np.float64)
        if pts.shape != (self.n_points, 2) or not np.all(np.isfinite(pts)):
            raise ModelError(f"need {self.n_points} finite landmarks, got shape {pts.shape}")
        return pts

    def check_model(self, model: BilinearModel) -> None:
        """:class:`ModelError` unless ``model`` was trained on this scheme."""
        layout = model.meta.get("normalisation", {}).get("layout")
        if layout != self.name:
            raise ModelError(f"the model was trained on {layout or 'an unknown'} landmarks, "
                             f"expected {self.name}")

    def mirrored(self, points: np.ndarray) -> np.ndarray:
        """The face reflected left/right about x = 0 with its points renumbered: (..., P, 2).

        On nose-tip-centred points of a symmetric face this is (close to) the face itself.
        """
        out = np.asarray(points, np.float64)[..., self.mirror, :].copy()
        out[..., 0] *= -1
        return out

    def feature_points(self, points: np.ndarray) -> dict[str, np.ndarray]:
        """MPEG-4 feature point -> (2,) position: the mean of its landmarks."""
        pts = np.asarray(points, np.float64)
        return {k: pts[list(v)].mean(0) for k, v in self.fdp.items()}

    def inner_eye_distance(self, points: np.ndarray) -> np.ndarray:
        """Inner-eye-corner distance; points (..., P, 2) -> (...)."""
        i, j = self.inner_eye_corners
        return np.linalg.norm(points[..., i, :] - points[..., j, :], axis=-1)

    def person_scales(self, data: LandmarkSet) -> np.ndarray:
        """Per-image scale (N,): the person's mean neutral inner-eye distance, or its own."""
        own = self.inner_eye_distance(data.points)
        scales = own.copy()
        persons, labels = np.asarray(data.persons), np.asarray(data.labels)
        for p in np.unique(persons):
            mine = persons == p
            neutral = mine & (labels == 0)
            if neutral.any():
                scales[mine] = own[neutral].mean()
        if np.any(scales <= 0):
            raise ModelError("a face has coincident inner eye corners (zero scale)")
        return scales

    def normalise_set(self, data: LandmarkSet) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Normalise every image: returns points (N, P, 2), origins (N, 2), scales (N,)."""
        scales = self.person_scales(data)
        origins = data.points[:, self.nose_tip, :]
        return normalise(data.points, origins, scales), origins, scales

    def mean_shapes(self, points: np.ndarray, data: LandmarkSet, people: Sequence[str],
                    expressions: Sequence[str]) -> np.ndarray:
        """(C, S, P, 2): the mean of the (normalised) ``points`` of each person and expression.

        Every person needs an image (label s) of each of the S ``expressions``
        (:class:`ModelError` naming the first one missing).
        """
        persons, labels = np.asarray(data.persons), np.asarray(data.labels)
        out = np.empty((len(people), len(expressions), self.n_points, 2))
        for c, p in enumerate(people):
            for s, expr in enumerate(expressions):
                sel = (persons == p) & (labels == s)
                if not sel.any():
                    raise ModelError(f"person {p} has no {expr} image")
                out[c, s] = points[sel].mean(axis=0)
        return out

    def train_from_means(self, means: np.ndarray, people: Sequence[str],
                         expressions: Sequence[str], meta: Mapping[str, Any],
                         I: int | None = None, J: int | None = None,  # noqa: E741
                         tol: float = 1e-10, max_iter: int = 100
                         ) -> tuple[BilinearModel, dict[str, np.ndarray]]:
        """One bilinear model per region from mean shapes (C, S, P, 2); also each region's
        training error history. ``meta`` is stored with the normalisation added."""
        regions: dict[str, RegionModel] = {}
        errors: dict[str, np.ndarray] = {}
        for name, idx in self.regions.items():
            res = train_bilinear(training_matrix(means, idx), 2 * len(idx), I, J, tol, max_iter)
            regions[name], errors[name] = res.model, res.errors
        model = BilinearModel(regions, dict(self.regions), tuple(expressions[:means.shape[1]]),
                              tuple(people), {"normalisation": self.normalisation, **meta})
        return model, errors

    def synthesize(self, model: BilinearModel, points: np.ndarray, alpha: np.ndarray,
                   method: str, lam: float, scale: float | None = None,
                   keep_residual: bool = False, tol: float = 1e-3, max_iter: int = 50
                   ) -> np.ndarray:
        """Landmarks (P, 2) of the face ``points`` (P, 2) with the expression mix ``alpha``.

        Each region is translated (``method``, ``lam``), its gauge pinned
        (:func:`~editor.synthesis.bilinear.fix_gauge`), its expression vector replaced by
        ``A α`` and rebuilt with its own identity vector; the scale (default the face's own
        inner-eye distance) is undone and the nose tip added back; the contour is the input's.
        ``keep_residual`` adds what the model does not reconstruct of the input (input −
        rebuilt input), keeping identity detail outside its span.
        """
        pts = self.check_points(points)
        origin = pts[self.nose_tip]
        s = float(self.inner_eye_distance(pts)) if scale is None else float(scale)
        if not s > 0:
            raise ModelError("inner eye corners coincide: cannot normalise the face")
        norm = normalise(pts, origin, s)
        out = norm.copy()
        for name, reg in model.regions.items():
            idx = list(model.region_indices[name])
            z = region_vectors(norm, idx)
            tr = translate(reg, z, method, lam, tol, max_iter)
            a, b = fix_gauge(reg, tr.a, tr.b)
            zs = synthesize_region(reg, b, alpha)
            if keep_residual:
                zs = zs + (z - reg.reconstruct(a, b))
            out[idx] = zs.reshape(-1, 2)
        return denormalise(out, origin, s)


def _pairs(n: int, pairs: Sequence[tuple[int, int]]) -> np.ndarray:
    m = np.arange(n)
    for a, b in pairs:
        m[a], m[b] = b, a
    return m


#: Stasm's 77 points (JAFFE landmark files); index map in :mod:`.bilinear_data`.
STASM77 = LandmarkScheme(
    name="stasm77", n_points=77, nose_tip=52, inner_eye_corners=(30, 40),
    contour=tuple(range(0, 16)),
    regions={"brows": tuple(range(16, 28)), "eyes": tuple(range(28, 48)),
             "nose": tuple(i for i in range(48, 59) if i != 52), "mouth": tuple(range(59, 77))},
    mirror=_pairs(77, [*((i, 12 - i) for i in range(6)), (13, 15),
                       (16, 23), (17, 24), (18, 25), (19, 26), (20, 27), (21, 22), (28, 29),
                       *((30 + i, 40 + i) for i in range(8)), (38, 39),
                       (48, 50), (51, 53), (54, 58), (55, 57),
                       (59, 65), (60, 64), (61, 63), (66, 68), (69, 71), (72, 76), (73, 75)]),
    # the face's own left is the image's right
    fdp={"2.1": (6,), "2.2": (67,), "2.3": (70,),
         "3.1": (42,), "3.2": (32,), "3.3": (46,), "3.4": (36,), "3.5": (39,), "3.6": (38,),
         "3.7": (44,), "3.8": (30,), "3.11": (40,), "3.12": (34,),
         "4.1": (22,), "4.2": (21,), "4.3": (23, 24), "4.4": (16, 17), "4.5": (25,), "4.6": (18,),
         "8.1": (62,), "8.2": (74,), "8.3": (65,), "8.4": (59,),
         "9.3": (52,), "9.15": (56,), "9.12": (49,)},
)

#: The iBUG/dlib 68 points the photo pipeline detects (:mod:`editor.engine.landmarks`).
DLIB68 = LandmarkScheme(
    name="dlib68", n_points=68, nose_tip=30, inner_eye_corners=(39, 42),
    contour=tuple(range(0, 17)),
    regions={"brows": tuple(range(17, 27)), "eyes": tuple(range(36, 48)),
             "nose": tuple(i for i in range(27, 36) if i != 30), "mouth": tuple(range(48, 68))},
    mirror=MIRROR_68, fdp=FDP_FROM_68,
)
