"""Issue 3: image loading, landmarks, the standard mesh, fitting and FAPU."""

from __future__ import annotations

import subprocess
import sys

import cv2
import numpy as np
import pytest
from conftest import JAFFE, SAMPLE, jaffe_images

from editor.core import Face, ImageError, NoFaceError, load_image, signed_areas, standard_mesh
from editor.engine.imageio import MAX_PIXELS
from editor.engine.landmarks import Iris, visible_iris_centre

# Reference points on the sample face, read by eye off a 6x zoom with a 5-px grid:
# eye corners, nose tip, mouth corners, chin (x, y) in pixels.
SAMPLE_REF = {36: (194, 100), 39: (212, 103), 42: (236, 104), 45: (255, 103), 30: (224, 126),
              48: (199, 139), 54: (245, 141), 8: (220, 178)}


def test_sample_landmarks_match_reference(sample_face):
    pts = sample_face.landmarks.points
    for i, ref in SAMPLE_REF.items():
        assert np.hypot(*(pts[i] - ref)) < 3.0, (i, pts[i], ref)


def test_sample_irises_inside_eyes_and_round(sample_face):
    lm = sample_face.landmarks
    for iris, eye in ((lm.iris_right, 0), (lm.iris_left, 1)):
        poly = lm.points[36 + 6 * eye: 42 + 6 * eye]
        assert poly[:, 0].min() < iris.cx < poly[:, 0].max()
        assert poly[:, 1].min() - 2 < iris.cy < poly[:, 1].max() + 2
        width = np.linalg.norm(poly[3] - poly[0])
        assert 0.15 * width < iris.r < 0.32 * width
    # checked by eye: iris centres at about (203.5, 100.5) and (246.7, 102.5)
    assert abs(lm.iris_right.cx - 203.5) < 2 and abs(lm.iris_left.cx - 246.7) < 2


def test_visible_iris_centre_follows_the_lids():
    """The pupil where the photo shows it: the centroid of the iris disc inside the opening."""
    iris = Iris(50.0, 40.0, 6.0)
    xs = np.linspace(30, 70, 9)
    open_up, open_lo = np.c_[xs, np.full(9, 20.0)], np.c_[xs, np.full(9, 60.0)]
    assert visible_iris_centre(iris, open_up, open_lo) == pytest.approx((50, 40), abs=1e-6)
    # an upper lid through the centre: a half disc, its centroid 4r/(3 pi) below the centre
    half = np.c_[xs, np.full(9, 40.0)]
    x, y = visible_iris_centre(iris, half, open_lo)
    assert x == pytest.approx(50, abs=1e-6) and y == pytest.approx(40 + 8 / np.pi, abs=0.03)
    # a lower lid over the bottom third moves it up; lids in either order give the same point
    lo = np.c_[xs, np.full(9, 42.0)]
    y_lo = visible_iris_centre(iris, open_up, lo)[1]
    assert y_lo < 40 and visible_iris_centre(iris, open_up[::-1], lo[::-1])[1] == y_lo
    # a rolled eye: the same half disc turned 30 degrees about the centre
    a = np.deg2rad(30)
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    turned = visible_iris_centre(iris, (half - (50, 40)) @ rot.T + (50, 40),
                                 (open_lo - (50, 40)) @ rot.T + (50, 40))
    want = np.array([50, 40]) + rot @ np.array([0, 8 / np.pi])
    np.testing.assert_allclose(turned, want, atol=0.03)
    # a closed eye shows nothing: the circle's centre
    shut = np.c_[xs, np.full(9, 50.0)]
    assert visible_iris_centre(iris, shut, shut) == (50.0, 40.0)


def test_standard_mesh_size_regions_and_holes():
    m = standard_mesh()
    face_v = int(np.isin(m.regions, ("margin", "border"), invert=True).sum())
    assert face_v >= 218 and len(m.triangles) >= 361
    for region in ("eye_contour", "eyebrow", "mouth", "nose", "cheek", "jaw", "forehead",
                   "contour", "ear"):
        assert (m.regions == region).sum() > 0, region
    # no triangle has all three vertices on one opening (nothing inside the holes)
    for loop in m.holes.values():
        on = np.isin(m.triangles, loop).all(1)
        centroid = m.template[m.triangles[on]].mean(1)
        poly = m.template[loop].astype(np.float32)
        inside = [cv2.pointPolygonTest(poly, tuple(map(float, c)), False) > 0 for c in centroid]
        assert not any(inside)
    # inner upper and lower lips are distinct vertices
    assert m.index("lipi_u4") != m.index("lipi_d4")
    for fdp in ("2.1", "2.2", "2.3", "3.1", "3.3", "4.1", "8.1", "8.3", "9.3", "9.15"):
        assert fdp in m.fdp
    # template mesh is fold-free
    assert (signed_areas(m.template.astype(np.float64), m.triangles) > 0).all()


def test_fapu_positive_and_plausible(sample_face):
    u = {k: v * 1024 for k, v in sample_face.fapu.items() if k != "AU"}
    assert all(v > 0 for v in u.values())
    es = u["ES"]
    assert 0.9 < es / sample_face.interocular < 1.15
    assert 0.7 < u["MW"] / es < 1.3
    assert 0.1 < u["IRISD"] / es < 0.3
    assert 0.15 < u["MNS"] / es < 0.6
    assert 0.5 < u["ENS"] / es < 1.1
    assert sample_face.fapu["AU"] == 1e-5


def test_sample_mesh_fold_free(sample_face):
    sig = signed_areas(sample_face.vertices.astype(np.float64), sample_face.triangles)
    assert (sig > 0).all()


@pytest.mark.slow
@pytest.mark.skipif(not jaffe_images(), reason="../shared/data/jaffe is not available")
def test_every_jaffe_image_fits_and_agrees_with_stasm():
    names = (JAFFE / "landmarks_stasm77" / "all_names.txt").read_text().split()
    lines = (JAFFE / "landmarks_stasm77" / "all_features.txt").read_text().strip().splitlines()
    feats = [np.array(line.replace(",", " ").split(), float).reshape(77, 2) for line in lines]
    by_key = {(p.name.split(".")[0], p.name.split(".")[2]): p for p in jaffe_images()}
    errors = []
    for name, f in zip(names, feats, strict=True):
        key = (name.split(".")[0], name.split(".")[2])
        face = Face.from_image(by_key[key])
        sig = signed_areas(face.vertices.astype(np.float64), face.triangles)
        assert (sig > 0).all(), name
        ours = face.landmarks.points[[36, 39, 42, 45, 48, 54]]
        stasm = f[[30, 34, 40, 44, 59, 65]]  # eye corners, mouth corners
        d = np.linalg.norm(ours[:, None] - stasm[None], axis=2).min(1)
        errors.append(d / np.linalg.norm(f[38] - f[39]))
    err = np.array(errors) * 100
    assert len(err) == 213
    assert err.mean() < 5.0, err.mean()  # measured: 3.2 % of the inter-ocular distance
    assert np.percentile(err, 95) < 10.0


def test_image_inputs(tmp_path):
    rgb = load_image(SAMPLE)
    grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    cv2.imwrite(str(tmp_path / "g.png"), grey)
    rgba = np.dstack([rgb[..., ::-1], np.full(rgb.shape[:2], 255, np.uint8)])
    cv2.imwrite(str(tmp_path / "a.png"), rgba)
    assert load_image(tmp_path / "g.png").shape == rgb.shape
    assert np.array_equal(load_image(tmp_path / "a.png"), rgb)
    big = cv2.resize(rgb[..., ::-1], (1920, 1920))
    cv2.imwrite(str(tmp_path / "big.jpg"), big)
    f = Face.from_image(tmp_path / "big.jpg")
    assert f.image.shape == (1920, 1920, 3)
    assert f.interocular > 100


def test_exif_orientation_is_applied(tmp_path):
    # a JPEG stored rotated with EXIF orientation 6 must come back upright
    rgb = load_image(SAMPLE)[:, :400]
    stored = np.ascontiguousarray(np.rot90(rgb, 1))  # what a camera would store
    ok, jpg = cv2.imencode(".jpg", stored[..., ::-1])
    data = jpg.tobytes()
    exif = (b"Exif\x00\x00MM\x00*\x00\x00\x00\x08\x00\x01\x01\x12\x00\x03\x00\x00\x00\x01"
            b"\x00\x06\x00\x00\x00\x00\x00\x00")
    app1 = b"\xff\xe1" + (len(exif) + 2).to_bytes(2, "big") + exif
    (tmp_path / "r.jpg").write_bytes(data[:2] + app1 + data[2:])
    out = load_image(tmp_path / "r.jpg")
    assert out.shape == rgb.shape
    # upright again (JPEG is lossy: compare the mean difference, and against the wrong turn)
    right = np.abs(out.astype(int) - rgb).mean()
    assert right < 6.0
    assert np.abs(np.rot90(out, 2).astype(int) - rgb).mean() > 3 * right


def test_bad_inputs(tmp_path):
    with pytest.raises(ImageError, match="no such file"):
        load_image(tmp_path / "missing.png")
    (tmp_path / "empty.png").write_bytes(b"")
    with pytest.raises(ImageError, match="empty"):
        load_image(tmp_path / "empty.png")
    (tmp_path / "text.jpg").write_text("not an image at all")
    with pytest.raises(ImageError, match="not an image"):
        load_image(tmp_path / "text.jpg")
    data = (SAMPLE).read_bytes()
    (tmp_path / "trunc.png").write_bytes(data[: len(data) // 3])
    with pytest.raises(ImageError):
        load_image(tmp_path / "trunc.png")
    # a PNG header that declares a huge image is refused before decoding
    side = int(np.sqrt(MAX_PIXELS)) + 100
    head = bytearray(data[:33])
    head[16:24] = side.to_bytes(4, "big") + side.to_bytes(4, "big")
    (tmp_path / "huge.png").write_bytes(bytes(head) + data[33:])
    with pytest.raises(ImageError, match="megapixels"):
        load_image(tmp_path / "huge.png")
    # a PNG signature whose first chunk is not IHDR (two signatures, then the file): corrupt,
    # not "13 x 1229472850 pixels" (the chunk's length and type read as a size)
    (tmp_path / "twice.png").write_bytes(data[:8] + data[:5000])
    with pytest.raises(ImageError, match="not an image, or a corrupt or truncated one"):
        load_image(tmp_path / "twice.png")
    cv2.imwrite(str(tmp_path / "flat.png"), np.full((300, 300, 3), 127, np.uint8))
    with pytest.raises(NoFaceError):
        Face.from_image(tmp_path / "flat.png")


def test_cli_errors_are_one_line(cli, tmp_path):
    (tmp_path / "bad.png").write_bytes(b"\x00garbage")
    for args in (["mesh", str(tmp_path / "bad.png"), "-o", str(tmp_path / "o.png")],
                 ["landmarks", str(tmp_path / "nope.png")],
                 ["render", str(SAMPLE), "--fap", "nonsense=3", "-o", str(tmp_path / "o.png")]):
        r = cli(*args)
        assert r.returncode == 2, args
        assert r.stderr.strip().count("\n") == 0 and r.stderr.startswith("fap-studio: error:")
        assert "Traceback" not in r.stderr


def test_cli_mesh_and_landmarks_outputs(cli, tmp_path):
    import json

    r = cli("mesh", str(SAMPLE), "-o", str(tmp_path / "m.png"), "--json",
            str(tmp_path / "m.json"))
    assert r.returncode == 0, r.stderr
    d = json.loads((tmp_path / "m.json").read_text())
    assert {"vertices", "triangles", "fdp", "fapu"} <= d.keys()
    assert len(d["vertices"]) == standard_mesh().n_vertices
    assert load_image(tmp_path / "m.png").shape == (512, 512, 3)
    r = cli("landmarks", str(SAMPLE), "--json", str(tmp_path / "l.json"))
    assert r.returncode == 0, r.stderr
    d = json.loads((tmp_path / "l.json").read_text())
    assert len(d["points"]) == 68 and "3.5" in d["iris"] and "2.1" in d["fdp"]


def test_core_does_not_import_qt():
    code = ("import sys, editor.core, editor.engine.deform, editor.engine.warp;"
            "bad=[m for m in sys.modules if m.startswith(('PySide6','pyqtgraph'))];"
            "print(bad); sys.exit(1 if bad else 0)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout
