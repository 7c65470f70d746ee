"""The default landmark detector: MediaPipe's face detector, mesh and iris models (issue 14)."""

from __future__ import annotations

import json
import subprocess
import sys

import cv2
import numpy as np
import pytest
from conftest import JAFFE, ROOT, SAMPLE, jaffe_images

from editor.engine.facemesh import (
    CONTOURS,
    FDP_FROM_MESH,
    MESH_TO_68,
    MediaPipeDetector,
    nose_position,
    points68_from_mesh,
)
from editor.engine.imageio import load_image
from editor.engine.landmarks import (
    FDP_FROM_68,
    MIRROR_68,
    LandmarkTracker,
    default_detector,
    detect_landmarks,
    dlib_available,
    get_detector,
)
from editor.errors import FapStudioError, NoFaceError
from editor.resources import MODEL_CREDITS, MODELS_DIR


@pytest.fixture(scope="module")
def sample_rgb() -> np.ndarray:
    return load_image(SAMPLE)


@pytest.fixture(scope="module")
def sample_lm(sample_rgb):
    return detect_landmarks(sample_rgb)


def test_default_is_the_shipped_mediapipe_models(sample_lm):
    assert isinstance(default_detector(), MediaPipeDetector)
    assert sample_lm.detector == "mediapipe-468" and sample_lm.mesh.shape == (468, 2)
    assert sample_lm.points.shape == (68, 2) and sample_lm.confidence > 0.9
    for name in ("face_detection_short_range.tflite", "face_landmark.tflite",
                 "iris_landmark.tflite", "LICENSE", "NOTICE"):
        assert (MODELS_DIR / name).is_file(), name
    assert "Apache License" in (MODELS_DIR / "LICENSE").read_text()
    assert all(lic == "Apache-2.0" for _, _, lic in MODEL_CREDITS[:3])


def test_sample_face_geometry(sample_lm):
    """The bundled sample (inter-ocular ~43 px): eyes level, irises inside the lid contours,
    the 68 points are the table's blend of the mesh, the lips ordered top to bottom."""
    lm = sample_lm
    assert 40 < lm.interocular < 47
    raw = points68_from_mesh(lm.mesh)
    moved = [61, 62, 63, 65, 66, 67]  # the inner-lip middles go onto the visible opening
    keep = np.setdiff1d(np.arange(68), moved)
    np.testing.assert_allclose(raw[keep], lm.points[keep])
    # the sample's smile shows teeth: the upper inner lip goes down from the model's contour
    # (on the upper lip) to the teeth's top edge, about 2 px, as dlib and iBUG's annotation
    # place it; the mesh's refined contour (lip_edges) is already there (within 0.6 px)
    model = points68_from_mesh(MediaPipeDetector(refine_lips=False).run(
        load_image(SAMPLE)).mesh)
    down = (lm.points[[61, 62, 63]] - model[[61, 62, 63]])[:, 1]
    assert (down > 0.5).all() and (down < 4).all(), down
    assert np.abs((lm.points - raw)[[61, 62, 63], 1]).max() < 0.6
    for iris, up, lo in ((lm.iris_right, "eye_r_upper", "eye_r_lower"),
                         (lm.iris_left, "eye_l_upper", "eye_l_lower")):
        poly = lm.mesh[list(CONTOURS[up]) + list(CONTOURS[lo])[::-1]].astype(np.float32)
        assert cv2.pointPolygonTest(poly, (iris.cx, iris.cy), False) > 0
        width = np.linalg.norm(poly[0] - poly[len(CONTOURS[up]) - 1])
        assert 0.15 * width < iris.r < 0.35 * width  # an iris is ~0.4 of the eye's width across
    m = lm.mesh
    assert m[0, 1] < m[13, 1] <= m[14, 1] < m[17, 1]  # upper lip, inner lips, lower lip
    assert m[152, 1] > m[17, 1] and m[10, 1] < m[168, 1]  # chin below, forehead above


def test_table_rows_are_convex_blends_and_mirror_symmetric():
    assert len(MESH_TO_68) == 68
    w = np.zeros((68, 468))
    for k, row in enumerate(MESH_TO_68):
        for v, wt in row:
            w[k, v] = wt
    assert np.allclose(w.sum(1), 1.0) and (w >= 0).all()
    # the inner-lip points come from the mesh's inner lip contour only
    inner = set(CONTOURS["lips_inner_upper"]) | set(CONTOURS["lips_inner_lower"])
    assert all(v in inner for k in range(60, 68) for v, _ in MESH_TO_68[k])
    # a row and its mirror partner use as many vertices
    assert all(len(MESH_TO_68[k]) == len(MESH_TO_68[MIRROR_68[k]]) for k in range(68))


@pytest.mark.skipif(not dlib_available(), reason="dlib (optional extra) is not installed")
def test_sample_points_agree_with_dlib(sample_rgb, sample_lm):
    """Issue 14: on the sample the mesh's 68 points lie within ~2 px of dlib's."""
    dl = detect_landmarks(sample_rgb, get_detector("dlib"))
    d = np.linalg.norm(sample_lm.points - dl.points, axis=1)
    assert d.mean() < 2.0 and np.median(d) < 2.0, d.round(1)
    inner = [36, 39, 42, 45, 48, 54]  # eye and mouth corners
    assert d[inner].max() < 1.5, d[inner].round(1)


def test_mirrored_photo_gives_mirrored_points(sample_rgb, sample_lm):
    """Pixel conventions: the crops map pixel centres correctly, so a mirrored photo gives the
    mirrored points (a half-pixel slip in the crop mapping showed as a 1.3 px mean shift on
    JAFFE; the model itself is not exactly mirror-symmetric: ~0.5 px here)."""
    w = sample_rgb.shape[1]
    b = detect_landmarks(np.ascontiguousarray(sample_rgb[:, ::-1]))
    back = b.points[MIRROR_68].copy()
    back[:, 0] = w - 1 - back[:, 0]
    d = (sample_lm.points - back)[17:]  # inner points (the jaw line slides along the cheeks)
    assert abs(d[:, 0].mean()) < 0.8 and np.linalg.norm(d, axis=1).mean() < 1.2, d.round(1)
    assert abs(sample_lm.iris_left.cx - (w - 1 - b.iris_right.cx)) < 0.5
    # the visible irises' centres mirror too (the lids' frame does not depend on the side)
    mx, my = b.pupils()["3.6"]
    np.testing.assert_allclose(sample_lm.pupils()["3.5"], (w - 1 - mx, my), atol=0.6)


def test_rolled_and_enlarged_photos(sample_rgb, sample_lm):
    """Roll is taken out before the mesh: the photo rotated by 25 degrees gives the rotated
    points; 3x enlarged gives 3x the points (pixel centres: 3x + 1)."""
    h, w = sample_rgb.shape[:2]
    rot = cv2.getRotationMatrix2D((w / 2, h / 2), 25, 1.0)
    rolled = cv2.warpAffine(sample_rgb, rot, (w, h), flags=cv2.INTER_CUBIC,
                            borderMode=cv2.BORDER_REPLICATE)
    got = detect_landmarks(rolled).points
    want = sample_lm.points @ rot[:, :2].T + rot[:, 2]
    err = np.linalg.norm(got - want, axis=1)
    assert np.median(err[17:]) < 1.5, err.round(1)  # inner points (the jaw line slides)
    big = cv2.resize(sample_rgb, (3 * w, 3 * h), interpolation=cv2.INTER_CUBIC)
    got = detect_landmarks(big).points
    err = np.linalg.norm(got - (3 * sample_lm.points + 1), axis=1) / 3
    assert np.median(err[17:]) < 1.0, err.round(1)


def test_tracking_follows_a_moving_face(sample_rgb, sample_lm):
    """The tracker crops each frame from the previous points: a face moving 6 px a frame is
    followed as detection would find it; a frame without a face raises and the next detects."""
    tracker = LandmarkTracker()
    for k in range(5):
        frame = np.roll(sample_rgb, 6 * k, axis=1)
        lm = tracker(frame)
        err = np.linalg.norm(lm.points - (sample_lm.points + (6 * k, 0)), axis=1)
        assert np.median(err[17:]) < 1.0, (k, err.round(1))
        assert lm.mesh is not None
    with pytest.raises(NoFaceError):
        tracker(np.full_like(sample_rgb, 128))
    assert np.median(np.linalg.norm(tracker(sample_rgb).points - sample_lm.points, axis=1)) < 1


def test_no_face_too_small_and_profile(sample_rgb, sample_lm):
    with pytest.raises(NoFaceError, match="no face"):
        detect_landmarks(np.full((300, 400, 3), 200, np.uint8))
    rng = np.random.default_rng(1)
    with pytest.raises(NoFaceError):
        detect_landmarks(rng.integers(0, 256, (256, 256, 3), dtype=np.uint8))
    # the sample at a quarter of its size: ~11 px between the eyes
    small = cv2.resize(sample_rgb, (128, 128), interpolation=cv2.INTER_AREA)
    with pytest.raises(NoFaceError, match="too small"):
        detect_landmarks(small)
    # the profile rule on the sample's mesh: frontal ~0.5, the nose tip moved out past an eye
    assert 0.4 < nose_position(sample_lm.mesh) < 0.6
    turned = sample_lm.mesh.copy()
    turned[1] = turned[33] + 0.1 * (turned[263] - turned[33])
    assert nose_position(turned) < 0.22


def test_cli_landmarks_json_and_detector_option(tmp_path):
    out = tmp_path / "p.json"
    r = subprocess.run([sys.executable, "-m", "editor", "landmarks", "sample", "--json",
                        str(out), "--detector", "mediapipe"], capture_output=True, text=True,
                       cwd=ROOT)
    assert r.returncode == 0, r.stderr
    data = json.loads(out.read_text())
    assert {"fdp", "iris", "mesh"} <= set(data) and len(data["mesh"]) == 468
    assert set(data["iris"]) == {"3.5", "3.6"} and {"3.12", "8.4", "2.2"} <= set(data["fdp"])
    # the visible irises' centres: within a quarter radius of the circles' centres on the
    # sample's open eyes (its lids cover little of the irises)
    for k, (cx, cy, r) in data["iris"].items():
        assert np.hypot(data["pupils"][k][0] - cx, data["pupils"][k][1] - cy) < 0.25 * r
    # every feature point the 68 points give, plus the mesh's inner-lip mid-points
    assert set(FDP_FROM_68) | {"2.6", "2.7", "2.8", "2.9", "3.5", "3.6"} == set(data["fdp"])
    mesh = np.array(data["mesh"])
    for k, idx in FDP_FROM_MESH.items():
        np.testing.assert_allclose(data["fdp"][k], mesh[list(idx)].mean(0), atol=0.02)
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((200, 200, 3), 90, np.uint8))
    r = subprocess.run([sys.executable, "-m", "editor", "landmarks", str(blank)],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "no face" in r.stderr, r.stderr
    if not dlib_available():
        r = subprocess.run([sys.executable, "-m", "editor", "landmarks", "sample",
                            "--detector", "dlib"], capture_output=True, text=True, cwd=ROOT)
        assert r.returncode == 2 and "fap-studio[dlib]" in r.stderr, r.stderr
    with pytest.raises(FapStudioError, match="unknown landmark detector"):
        get_detector("hog")


@pytest.mark.slow
@pytest.mark.skipif(not (JAFFE / "landmarks_stasm77").is_dir() or not jaffe_images(),
                    reason="../shared/data/jaffe is not available")
def test_jaffe_accuracy_against_stasm():
    """Issue 14's bars on JAFFE (Stasm points, % of the inter-ocular distance): eye corners
    <= 2.8 and mouth corners <= 4.0 (dlib's figures); measured 2.50 / 3.24. Lids closer than
    dlib's 1.76 / 1.79 (measured 1.30 / 1.30); inner lips closer than dlib's 2.01 (measured
    1.70; the model's own contour 2.03), on closed mouths closer than dlib's 1.76 (measured
    1.29), on open mouths near dlib's 2.58 (measured 2.64; the model's own contour 3.31, on
    the lips' bodies: editor/engine/lip_edges.py; Stasm's lower inner lip sits high on wide
    open mouths, see scripts/landmark_accuracy.py).
    Pupils (the visible irises' centres, Stasm's definition) closer than dlib's 1.87: measured
    1.65; the full circles' centres 2.16 (the lids' cover moves Stasm's pupils down)."""
    r = subprocess.run([sys.executable, str(ROOT / "scripts" / "landmark_accuracy.py"),
                        str(JAFFE), "--detector", "mediapipe", "--json"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    got = json.loads(r.stdout)["mediapipe"]
    assert got["images"] == 213
    assert got["eye corners"] <= 2.8 and got["mouth corners"] <= 4.0, got
    assert got["upper lids"] < 1.7 and got["lower lids"] < 1.7 and got["inner lips"] < 1.9, got
    assert got["inner lips (open mouths)"] < 2.9, got  # the model's own contour: 3.31
    assert got["pupils"] < 1.8 < got["pupils (circle centre)"], got  # dlib: 1.87
    assert got["inner lips (closed mouths)"] < 1.5, got  # dlib: 1.76 (measured 1.29)
