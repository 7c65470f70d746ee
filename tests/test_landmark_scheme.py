"""The two landmark schemes of the bilinear model: their tables checked against real faces."""

from __future__ import annotations

import numpy as np
import pytest

from editor.engine.imageio import load_image
from editor.engine.landmarks import detect_landmarks
from editor.engine.transform import apply_affine, similarity
from editor.errors import ModelError
from editor.resources import checkout_jaffe_dir
from editor.synthesis.bilinear_data import load_stasm77
from editor.synthesis.landmark_scheme import DLIB68, STASM77, LandmarkScheme

JAFFE = checkout_jaffe_dir()
STASM_DIR = JAFFE / "landmarks_stasm77"
needs_jaffe = pytest.mark.skipif(not (STASM_DIR / "all_features.txt").exists()
                                 or not (JAFFE / "images").is_dir(),
                                 reason="JAFFE data set not available")


def _symmetry_error(scheme: LandmarkScheme, points: np.ndarray, mirror: np.ndarray | None = None
                    ) -> np.ndarray:
    """Per point, the distance (inner-eye units) between a face and its renumbered mirror image
    after the best similarity between them (a turned or tilted head moves the midline)."""
    p = np.asarray(points, np.float64)
    q = p / scheme.inner_eye_distance(p)
    m = q[scheme.mirror if mirror is None else mirror].copy()
    m[:, 0] *= -1
    m = apply_affine(similarity(m, q), m)
    return np.linalg.norm(m - q, axis=1)


def test_a_broken_mirror_table_or_index_is_refused():
    with pytest.raises(ValueError, match="mirror"):
        LandmarkScheme("bad", 3, 0, (1, 2), (), {"r": (1, 2)}, np.array([1, 1, 2]), {})
    with pytest.raises(ValueError, match="out of range"):
        LandmarkScheme("bad", 3, 0, (1, 2), (), {"r": (1, 5)}, np.arange(3), {})
    with pytest.raises(ModelError, match="68 finite"):
        DLIB68.check_points(np.zeros((77, 2)))


def test_dlib68_mirror_table_fits_the_sample_face(sample_neutral):
    pts = sample_neutral.landmarks.points
    err = _symmetry_error(DLIB68, pts)
    assert np.median(err) < 0.05 and err.max() < 0.25, np.round(err, 2)
    assert np.median(_symmetry_error(DLIB68, pts, np.arange(68))) > 0.3  # the check can fail
    m = DLIB68.mirrored(pts - pts[DLIB68.nose_tip])
    assert np.array_equal(DLIB68.mirrored(m), pts - pts[DLIB68.nose_tip])


@needs_jaffe
def test_stasm77_mirror_table_fits_the_jaffe_neutral_faces():
    data = load_stasm77(STASM_DIR)
    neutral = data.points[data.labels == 0]
    per_point = np.median([_symmetry_error(STASM77, p) for p in neutral], axis=0)
    # a point paired with the wrong partner would be ~1 inner-eye distance off its mirror image
    assert np.median(per_point) < 0.06 and per_point.max() < 0.2, np.round(per_point, 2)
    assert np.median([_symmetry_error(STASM77, p, np.arange(77)) for p in neutral]) > 0.3


@needs_jaffe
def test_stasm77_feature_points_match_the_detected_dlib68_ones():
    """The same MPEG-4 feature points from the JAFFE landmark files and from dlib on the image."""
    data = load_stasm77(STASM_DIR)
    common = sorted(set(STASM77.fdp) & set(DLIB68.fdp))
    assert len(common) >= 20
    worst = []
    for k in (0, 40, 120):  # three people, three expressions
        rgb = load_image(JAFFE / "images" / data.names[k])
        lm = detect_landmarks(rgb)
        a = STASM77.feature_points(data.points[k])
        b = DLIB68.feature_points(lm.points)
        iod = float(DLIB68.inner_eye_distance(np.asarray(lm.points, np.float64)))
        d = np.array([np.linalg.norm(a[f] - b[f]) / iod for f in common])
        worst.append(np.median(d))
        # no feature point mapped to the wrong part of the face (a swapped side is ~1 IOD off)
        assert d.max() < 0.5, dict(zip(common, np.round(d, 2), strict=True))
    assert max(worst) < 0.15


def test_scheme_normalisation_is_what_a_model_stores():
    meta = DLIB68.normalisation
    assert meta["layout"] == "dlib68" and meta["nose_tip"] == 30
    assert meta["inner_eye_corners"] == [39, 42]
    assert STASM77.normalisation["layout"] == "stasm77"
