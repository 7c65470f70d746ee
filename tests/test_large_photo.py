"""Opening large photos (issue 15's 24 MP row): the analyses that run at a working resolution on
large faces agree with their full-size versions, and the ones reorganised for memory give the
same values. Small faces never take these paths (the goldens pin them)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from editor.engine import creases, facemesh, gaze, landmarks, warp
from editor.engine.face import Face
from editor.engine.faps import FAPS
from editor.engine.imageio import load_image
from editor.resources import SAMPLE_FACE as SAMPLE

#: the sample upscaled so that its inter-ocular distance (~44 px) is ~300 px: fold analyses at
#: half resolution, eyes ~125 px wide (iris search downsampled), irises ~27 px (white plate)
SCALE = 7


@pytest.fixture(scope="module")
def big_rgb() -> np.ndarray:
    rgb = load_image(SAMPLE)
    return cv2.resize(rgb, None, fx=SCALE, fy=SCALE, interpolation=cv2.INTER_CUBIC)


@pytest.fixture(scope="module")
def big_face(big_rgb) -> Face:
    return Face.from_image(big_rgb)


def test_detector_input_block_means_first(big_rgb, monkeypatch):
    small = big_rgb[:1000, :900]
    for size in ((128, 128), (200, 170)):  # at most 8x down: one resize, as before
        assert np.array_equal(facemesh._area_down(small, size),
                              cv2.resize(small, size, interpolation=cv2.INTER_AREA))
    # ~28x down: k x k block means first (k = 2 here), then the resize: within rounding of
    # one resize on average, and the same face
    one = cv2.resize(big_rgb, (128, 128), interpolation=cv2.INTER_AREA).astype(int)
    two = facemesh._area_down(big_rgb, (128, 128)).astype(int)
    assert np.abs(one - two).mean() < 0.3
    det = landmarks.get_detector("mediapipe")
    assert isinstance(det, facemesh.MediaPipeDetector)
    box, kp = det._detect_face(big_rgb)
    monkeypatch.setattr(facemesh, "_area_down", lambda img, size: cv2.resize(
        img, size, interpolation=cv2.INTER_AREA))
    box1, kp1 = det._detect_face(big_rgb)
    side = max(big_rgb.shape[:2])
    assert np.abs(box - box1).max() < 0.003 * side and np.abs(kp - kp1).max() < 0.003 * side



@pytest.mark.parametrize("k", [2, 3, 5, 7])
def test_block_means_in_two_halves_are_one_resize(big_rgb, k):
    # the rows split between two threads: each half's output rows read their own k input
    # rows (odd and even counts of output rows, grey too)
    for img in (big_rgb[:k * 301, :k * 211], big_rgb[:k * 300, :k * 7], big_rgb[:k * 3, :k * 5],
                np.ascontiguousarray(big_rgb[:k * 101, :k * 99, 1])):
        h, w = img.shape[:2]
        assert np.array_equal(facemesh._block_means(img, k),
                              cv2.resize(img, (w // k, h // k), interpolation=cv2.INTER_AREA))

def test_iris_search_on_large_eyes(big_rgb, big_face, monkeypatch):
    lm = big_face.landmarks
    for eye, iris in ((0, lm.iris_right), (1, lm.iris_left)):
        w = np.linalg.norm(lm.points[39 + 6 * eye] - lm.points[36 + 6 * eye])
        assert w > landmarks.IRIS_WORK_WIDTH  # the downsampled path is the one tested
        near = landmarks.Iris(iris.cx, iris.cy, 0.95 * iris.r)
        fast = landmarks.locate_iris(big_rgb, lm.points, eye, near)
        free = landmarks.locate_iris(big_rgb, lm.points, eye)
        with monkeypatch.context() as m:
            m.setattr(landmarks, "IRIS_WORK_WIDTH", 1e9)
            full = landmarks.locate_iris(big_rgb, lm.points, eye, near)
            free_full = landmarks.locate_iris(big_rgb, lm.points, eye)
        # at the model's centre: the discs and rings summed at that pixel only, the radius
        # the filters over the whole opening pick
        assert (fast.cx, fast.cy) == (near.cx, near.cy)
        assert fast.r == pytest.approx(full.r)
        # the free search: the same dark disc, to a few percent of the eye's width
        assert np.hypot(free.cx - free_full.cx, free.cy - free_full.cy) <= 0.04 * w
        assert abs(free.r - free_full.r) <= 0.05 * free_full.r


def test_white_plate_inpaint_downsampled():
    # a lit eyeball's white (a smooth gradient with a shadow under the lid) and a dark iris
    h, w, r = 140, 220, 34.0
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    white = 200.0 - 0.15 * xx - 40.0 * np.exp(-yy / 25.0)
    patch = np.clip(np.dstack([white, white * 0.95, white * 0.9]), 0, 255).astype(np.uint8)
    rho = np.hypot(xx - 110.0, yy - 72.0)
    patch[rho < r] = (60, 40, 30)
    disc = rho < r + max(1.5, 0.3 * r)
    assert r > gaze.PLATE_WORK_R
    fast = gaze._telea(patch, disc, r)
    full = cv2.inpaint(patch, disc.astype(np.uint8), 0.5 * r, cv2.INPAINT_TELEA).astype(np.float32)
    assert np.array_equal(fast[~disc], patch[~disc].astype(np.float32))  # the photo elsewhere
    d = np.abs(fast - full)[disc]
    assert d.mean() < 2.0 and d.max() < 12.0
    # no iris colour leaks into the plate (the dark disc is not "known" after downsampling)
    assert fast[disc].min() > 100.0


def _fold_fields(face: Face) -> tuple[dict, np.ndarray]:
    for cache in (creases._LIFT, creases._GAIN, creases._VALLEYS, creases._VALLEY_SAMPLES):
        cache.pop(face, None)
    groups = range(len(creases._fast(face).sig))
    lifts = {g: creases._photo_lift(face, g) for g in groups}
    tri, bary = creases._own_valleys(face)
    V = face.vertices.astype(np.float64)
    return lifts, (V[face.mesh.triangles[tri]] * bary[..., None]).sum(1)


def test_fold_analyses_at_working_resolution(big_face, monkeypatch):
    assert creases._work_factor(creases.crease_plan(big_face).iod) == 2
    fast, pos = _fold_fields(big_face)
    with monkeypatch.context() as m:
        m.setattr(creases, "_WORK_IOD", 1e9)
        full, pos_full = _fold_fields(big_face)
    _fold_fields(big_face)  # the module's face keeps the product's fields
    # the photo's own valleys: the same lines, to a fraction of a pixel at this scale (IOD
    # ~300 px; a few px where a fold fades out)
    d = np.hypot(*(pos - pos_full).T)
    assert d.mean() < 0.5 and d.max() < 0.015 * creases.crease_plan(big_face).iod
    n = 0
    for g, got in fast.items():
        assert (got is None) == (full[g] is None)
        if got is None:
            continue
        n += 1
        (S, C), (x0, y0) = got
        (S1, C1), (a0, b0) = full[g]
        # the boxes follow the valleys found (a pixel apart at most): compared where both are
        assert abs(x0 - a0) <= 1 and abs(y0 - b0) <= 1
        ux0, uy0 = max(x0, a0), max(y0, b0)
        ux1, uy1 = min(x0 + S.shape[1], a0 + S1.shape[1]), min(y0 + S.shape[0], b0 + S1.shape[0])
        S, C = S[uy0 - y0:uy1 - y0, ux0 - x0:ux1 - x0], C[uy0 - y0:uy1 - y0, ux0 - x0:ux1 - x0]
        S1 = S1[uy0 - b0:uy1 - b0, ux0 - a0:ux1 - a0]
        C1 = C1[uy0 - b0:uy1 - b0, ux0 - a0:ux1 - a0]
        assert S.shape[0] > 20 and S.shape[1] > 20
        # the along-fold level and the lifted one (the gain is C / S): within ~1 %
        assert np.abs(S - S1).mean() < 0.01 * S1.mean()
        assert np.abs(C[..., :3] - C1[..., :3]).mean() < 0.01 * C1[..., :3].mean()
        assert np.abs(C[..., 3] - C1[..., 3]).mean() < 0.03
    assert n >= 2  # the sample's own nasolabial folds


def test_warp_maps_in_bands_are_exact(sample_face, monkeypatch):
    vec = FAPS.clamp(FAPS.vector({"open_jaw": 400, "stretch_l_cornerlip_o": 200}))
    v = sample_face.deform(vec)[:sample_face.plan.n_vertices]
    tf = sample_face.layer_transforms(v)
    one = warp.warp(sample_face.warp_plan, v, tf)
    monkeypatch.setattr(warp, "_MAP_BAND_PX", 997)  # many bands of a few rows
    many = warp.warp(sample_face.warp_plan, v, tf)
    assert one.maps is not None and many.maps is not None
    assert np.array_equal(one.maps[0], many.maps[0]) and np.array_equal(one.maps[1],
                                                                         many.maps[1])
    assert np.array_equal(one.image, many.image)


def test_neutral_mouth_lookup(sample_face):
    plan = sample_face.warp_plan
    full = plan.neutral_mouth
    assert full.shape == plan.image.shape[:2] and full.sum() > 50
    ys, xs = np.mgrid[0:full.shape[0], 0:full.shape[1]]
    assert np.array_equal(plan.in_neutral_mouth(xs.ravel(), ys.ravel()), full.ravel())
