"""Would a recogniser of real faces name the presets? (JAFFE; issue 21 item 5.)

A classifier learns the six emotions from real expression photos and labels the renders of the
emotion presets. Features: the 68-point detector's landmarks of a photo moved into the pose of
the same woman's neutral photo (as in :mod:`closed_loop`), minus the neutral's, over the
inter-ocular distance, for points 17-67 (brows, eyes, nose, lips; the jaw contour is left out:
detectors place its sides loosely). Classifier: the features' first :data:`N_COMPONENTS`
principal components, then linear discriminant analysis (a mean per emotion, one pooled
covariance): small enough for 10 women x 3 photos per emotion.

Leave one woman out: trained on the other nine women's real photos, it labels her own real
photos (the classifier's accuracy on unseen people: what the presets can be measured against)
and each preset rendered on her neutral photo and detected again. It sees geometry only (no
creases, teeth or texture), so it tells whether a preset *moves* the face as real people with
that emotion do, not whether the picture looks real.

JAFFE is research-only: it is read from disk at run time, nothing derived from it is stored.
``python -m editor.synthesis.recognise [JAFFE_DIR] [SCALE]`` prints the two tables.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from editor.engine.face import Face
from editor.engine.fap_model import remove_head_motion
from editor.engine.imageio import load_image
from editor.engine.landmarks import detect_landmarks
from editor.errors import NoFaceError
from editor.formats.presets import apply_preset
from editor.resources import checkout_jaffe_dir

from .jaffe import JAFFE_EMOTIONS, jaffe_files

#: the emotions, in the tables' order (JAFFE codes)
CODES = tuple(JAFFE_EMOTIONS)
#: principal components kept before the discriminant analysis (183 photos, 102 features)
N_COMPONENTS = 12
#: the landmarks compared: brows, eyes, nose, lips (not the jaw contour)
POINTS = slice(17, 68)


def motion(neutral: np.ndarray, points: np.ndarray, iod: float) -> np.ndarray:
    """(102,) feature vector: ``points`` (68, 2) in the neutral's head pose minus ``neutral``,
    over ``iod``, for :data:`POINTS`."""
    aligned = remove_head_motion(np.asarray(neutral, np.float64),
                                 np.asarray(points, np.float64))[0]
    return ((aligned - neutral)[POINTS] / iod).reshape(-1)


@dataclass
class Classifier:
    """PCA then linear discriminant analysis over :data:`CODES` (see the module docstring)."""

    mean: np.ndarray  # (F,) feature mean
    axes: np.ndarray  # (K, F) principal axes
    centres: np.ndarray  # (C, K) class means in the reduced space
    inv_cov: np.ndarray  # (K, K) inverse pooled within-class covariance

    @classmethod
    def fit(cls, X: np.ndarray, labels: Sequence[str], k: int = N_COMPONENTS) -> Classifier:
        X = np.asarray(X, np.float64)
        y = np.asarray(labels)
        mean = X.mean(0)
        axes = np.linalg.svd(X - mean, full_matrices=False)[2][:k]
        Z = (X - mean) @ axes.T
        present = [c for c in CODES if np.any(y == c)]
        if len(present) < len(CODES):
            raise ValueError(f"no training photo of {sorted(set(CODES) - set(present))}")
        centres = np.array([Z[y == c].mean(0) for c in CODES])
        R = Z - centres[[CODES.index(c) for c in y]]
        cov = R.T @ R / max(len(Z) - len(CODES), 1)
        return cls(mean, axes, centres, np.linalg.inv(cov))

    def predict(self, X: np.ndarray) -> list[str]:
        """The emotion code of each row of ``X`` (nearest class mean, Mahalanobis)."""
        Z = (np.atleast_2d(np.asarray(X, np.float64)) - self.mean) @ self.axes.T
        D = Z[:, None, :] - self.centres[None]
        d2 = np.einsum("ncj,jk,nck->nc", D, self.inv_cov, D)
        return [CODES[i] for i in d2.argmin(1)]


@dataclass
class Recognition:
    """Confusion matrices (rows: true emotion, columns: label; :data:`CODES` order)."""

    real: np.ndarray  # the real photos, each labelled by the classifier of the other women
    presets: np.ndarray  # the presets rendered on each woman's neutral photo
    scale: float
    women: int

    @staticmethod
    def accuracy(m: np.ndarray) -> float:
        return float(np.trace(m) / max(m.sum(), 1))

    def hits(self, code: str) -> tuple[int, int]:
        """(labelled right, rendered) for the preset of ``code``."""
        i = CODES.index(code)
        return int(self.presets[i, i]), int(self.presets[i].sum())

    def table(self) -> str:
        """Both matrices as Markdown."""
        out = []
        for title, m in ((f"Real JAFFE photos, each labelled by a classifier of the other "
                          f"women ({self.women} women)", self.real),
                         (f"Presets at {self.scale:.0%} on each woman's neutral photo, labelled "
                          "by the classifier of the other women", self.presets)):
            out += [f"{title}: accuracy {self.accuracy(m):.2f}", "",
                    "| true \\ label | " + " | ".join(JAFFE_EMOTIONS[c] for c in CODES)
                    + " | right |", "|---|" + "---|" * (len(CODES) + 1)]
            for i, c in enumerate(CODES):
                n = max(int(m[i].sum()), 1)
                out.append(f"| {JAFFE_EMOTIONS[c]} | " + " | ".join(str(int(x)) for x in m[i])
                           + f" | {m[i, i] / n:.2f} |")
            out.append("")
        return "\n".join(out)


def recognise(images: Path, people: Sequence[str] | None = None, scale: float = 1.0,
              progress: Callable[[int, int], None] | None = None) -> Recognition:
    """Leave-one-woman-out labels of the real photos and of the presets (module docstring)."""
    files = jaffe_files(images)
    who = [p for p in (people or sorted(files)) if "NE" in files.get(p, {})]
    real: list[tuple[str, str, np.ndarray]] = []
    faces: dict[str, Face] = {}
    total = sum(len(files[p].get(c, [])) for p in who for c in CODES) + len(who)
    done = 0
    for p in who:
        face = Face.from_image(files[p]["NE"][0], own_expression=False)
        faces[p] = face
        neutral = face.landmarks.points.astype(np.float64)
        for c in CODES:
            for path in files[p].get(c, []):
                try:
                    q = detect_landmarks(load_image(path)).points
                except NoFaceError:
                    continue
                real.append((p, c, motion(neutral, q, face.interocular)))
                done += 1
                if progress:
                    progress(done, total)
    cm_real = np.zeros((len(CODES), len(CODES)), int)
    cm_presets = np.zeros_like(cm_real)
    for p in who:
        train = [r for r in real if r[0] != p]
        clf = Classifier.fit(np.array([r[2] for r in train]), [r[1] for r in train])
        mine = [r for r in real if r[0] == p]
        if mine:
            for r, got in zip(mine, clf.predict(np.array([r[2] for r in mine])), strict=True):
                cm_real[CODES.index(r[1]), CODES.index(got)] += 1
        face = faces[p]
        neutral = face.landmarks.points.astype(np.float64)
        feats, codes = [], []
        for c in CODES:
            try:
                q = detect_landmarks(face.render(apply_preset(JAFFE_EMOTIONS[c], scale))).points
            except NoFaceError:
                continue
            feats.append(motion(neutral, q, face.interocular))
            codes.append(c)
        if feats:
            for c, got in zip(codes, clf.predict(np.array(feats)), strict=True):
                cm_presets[CODES.index(c), CODES.index(got)] += 1
        done += 1
        if progress:
            progress(done, total)
    return Recognition(cm_real, cm_presets, scale, len(who))


if __name__ == "__main__":  # pragma: no cover - a development aid
    root = Path(sys.argv[1]) if len(sys.argv) > 1 else checkout_jaffe_dir()
    print(recognise(root / "images", scale=float(sys.argv[2]) if len(sys.argv) > 2 else 1.0)
          .table())
