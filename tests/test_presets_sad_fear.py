"""Sad eyes and a fearful mouth as the real JAFFE photos show them (issue 21).

* Sadness looks down: the iris centre drops against the eye-corner line in the real sad photos
  (dlib landmarks and iris circles, each woman's sad photos against her neutral ones, head
  motion removed). The preset's eyeball pitch (FAPs 25/26) moves the mesh's iris centres
  (3.5/3.6) at least the real median's distance, inside the real band, and the upper lids follow
  the iris down (no white band above it).
* Fear stretches the mouth rather than smiling: measured on the image as on the real photos
  (dlib re-detected on our renders of the ten women, aligned to her neutral): the mouth widens
  at least as much as real fear's median, the corners drop no further than open real fear's
  (a tenth's margin), and the band of upper teeth that made raters read a smile or a snarl
  shows on no more women than real fear shows upper teeth on, with a margin.

Needs ../shared/data/jaffe and dlib (the instrument the presets were derived with); skipped
otherwise.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from conftest import JAFFE

from editor.engine.face import Face
from editor.engine.imageio import load_image
from editor.engine.landmarks import detect_landmarks, dlib_available, get_detector
from editor.formats.presets import apply_preset
from editor.synthesis import jaffe_stats as js
from editor.synthesis.fap_estimate import remove_head_motion

pytestmark = pytest.mark.skipif(
    not ((JAFFE / "images").is_dir() and dlib_available()),
    reason="needs dlib (pip install '.[dlib]') and ../shared/data/jaffe")

#: dlib-68 (corner, corner) per eye, image-left eye (the subject's right, iris 3.6) first
_CORNERS = ((36, 39), (42, 45))


def _iris_drop(row: np.ndarray, ref: np.ndarray) -> float:
    """Mean over both eyes of the iris centre's distance below its eye-corner line, pixels of
    ``ref`` (the woman's first neutral landmarks), of one cached detection row (68 points, box,
    irises) aligned to ``ref`` by a similarity on eye corners and nose."""
    pts = row[:136].reshape(68, 2).astype(np.float64)
    al, _ = remove_head_motion(ref, pts)
    m, *_ = np.linalg.lstsq(np.c_[pts, np.ones(68)], al, rcond=None)  # the same similarity
    out = []
    for (c0, c1), ir in zip(_CORNERS, (row[143:146], row[140:143]), strict=True):
        centre = np.r_[ir[:2], 1.0] @ m
        a, b = al[c0], al[c1]
        ex = (b - a) / np.linalg.norm(b - a)
        out.append((centre - 0.5 * (a + b)) @ np.array([-ex[1], ex[0]]))
    return float(np.mean(out))


@pytest.fixture(scope="module")
def real_sad_gaze() -> np.ndarray:
    """Per JAFFE sad photo: its iris drop minus the mean of her neutral photos', in her
    neutral irises' mean diameter (+ = down; not the photo's own iris, which lowered lids
    make look smaller)."""
    paths = sorted(Path(JAFFE, "images").glob("*.tiff"))
    det = js._detect_all(paths)
    out = []
    for who in sorted({p.name.split(".")[0] for p in paths}):
        ne = [p.name for p in paths if p.name.startswith(f"{who}.NE") and p.name in det]
        ref = det[ne[0]][:136].reshape(68, 2).astype(np.float64)
        base = np.mean([_iris_drop(det[n], ref) for n in ne])
        diam = 2 * np.mean([det[n][[142, 145]] for n in ne])
        out += [(_iris_drop(det[p.name], ref) - base) / diam for p in paths
                if p.name.startswith(f"{who}.SA") and p.name in det]
    return np.array(out)


@pytest.fixture(scope="module")
def faces() -> dict[str, Face]:
    return js.neutral_faces(JAFFE)


def _mesh_gaze(face: Face, vec: np.ndarray | None) -> tuple[float, float]:
    """(iris centre below the corner line, upper lid mid-point above the iris centre), mean
    over both eyes, in iris diameters, of the deformed mesh."""
    v, extra = face.deform_all(vec)
    v = v.astype(np.float64)
    d = face.fapu["IRISD"] * 1024.0
    drop, lid = [], []
    for c0, c1, top, iris in (("3.12", "3.8", "3.2", "3.6"), ("3.7", "3.11", "3.1", "3.5")):
        a, b = v[face.fdp[c0]], v[face.fdp[c1]]
        ex = (b - a) / np.linalg.norm(b - a)
        ey = np.array([-ex[1], ex[0]]) * (1 if ex[0] > 0 else -1)
        c = np.asarray(extra[iris], np.float64)
        drop.append((c - 0.5 * (a + b)) @ ey / d)
        lid.append((c - v[face.fdp[top]]) @ ey / d)
    return float(np.mean(drop)), float(np.mean(lid))


def test_sad_eyes_look_down_as_far_as_real_ones(real_sad_gaze, faces):
    """Real sad photos (31): the iris drops median +0.051 iris diameters, p10..p90
    +0.007..+0.088, max +0.130 (the neutral photos' noise p10..p90 -0.030..+0.034). Before,
    the preset left the eyeballs still (0.000): raters read 'relaxed face, heavy lids'."""
    st = {"median": np.median(real_sad_gaze), "p90": np.percentile(real_sad_gaze, 90),
          "max": real_sad_gaze.max()}
    assert len(real_sad_gaze) >= 25 and st["median"] > 0.03  # real sad gaze drops
    for k, lo, hi in ((1.0, st["median"], st["p90"]), (1.5, st["median"], st["max"])):
        vec = apply_preset("sadness", k)
        got, lids = [], []
        for face in faces.values():
            d0, l0 = _mesh_gaze(face, None)
            d1, l1 = _mesh_gaze(face, vec)
            got.append(d1 - d0)
            lids.append(l1 - l0)
        g = float(np.median(got))
        assert lo <= g <= hi, (k, g, st)
        # the upper lid comes down with the iris: its height above the iris centre shrinks
        assert float(np.median(lids)) < -0.05, (k, lids)


def _mouth(pts: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """(widening, corners' drop, inner lips' parting) of dlib points aligned to ``ref`` (her
    first neutral), in ``ref``'s IOD, absolute (subtract the neutral's)."""
    al, _ = remove_head_motion(ref, pts)
    iod = np.linalg.norm(ref[36:42].mean(0) - ref[42:48].mean(0))
    return np.array([np.linalg.norm(al[54] - al[48]), 0.5 * (al[48, 1] + al[54, 1]),
                     al[66, 1] - al[62, 1]]) / iod


def _upper_teeth(grey: np.ndarray, pts: np.ndarray) -> float:
    """Pixels inside the inner lips above their middle brighter than 0.9 of the skin between
    the nose and the upper lip, in the face's IOD squared x 1000."""
    h, w = grey.shape
    inside = np.zeros((h, w), np.uint8)
    cv2.fillPoly(inside, [np.round(pts[60:68] * 8).astype(np.int32)], 1, shift=3)
    y0, y1 = int(pts[33, 1] + 2), int(pts[51, 1] - 2)
    skin = np.median(grey[y0:max(y1, y0 + 1), int(pts[50, 0]):int(pts[52, 0])])
    upper = np.arange(h)[:, None] < 0.5 * (pts[62, 1] + pts[66, 1])
    iod = np.linalg.norm(pts[36:42].mean(0) - pts[42:48].mean(0))
    return float(((grey > 0.9 * skin) & (inside > 0) & upper).sum() / iod ** 2 * 1000)


def test_fear_stretches_the_mouth_rather_than_smiling():
    """Real JAFFE fear (32 photos): widening median +0.035 IOD; the 20 open ones' corners drop
    +0.057 (mean); upper teeth on 13 of 32. Ours, mean over the ten women (one re-detection
    each, so means rather than medians: dlib's corners jitter by ~0.01 IOD): before (jaw 220,
    corners -120, stretch 25, upper lip -10) +0.029, +0.081, upper teeth on 9 of 10; now
    +0.040, +0.054, 5 of 10."""
    paths = sorted(Path(JAFFE, "images").glob("*.tiff"))
    det = js._detect_all(paths)
    dlib = get_detector("dlib")
    real, ours, teeth_real, teeth_ours = [], [], [], []
    for who in ("KA", "KL", "KM", "KR", "MK", "NA", "NM", "TM", "UY", "YM"):
        ne = [p for p in paths if p.name.startswith(f"{who}.NE") and p.name in det]
        ref = det[ne[0].name][:136].reshape(68, 2).astype(np.float64)
        base = np.mean([_mouth(det[p.name][:136].reshape(68, 2).astype(np.float64), ref)
                        for p in ne], 0)
        for p in paths:
            if p.name.startswith(f"{who}.FE") and p.name in det:
                pts = det[p.name][:136].reshape(68, 2).astype(np.float64)
                real.append(_mouth(pts, ref) - base)
                teeth_real.append(_upper_teeth(cv2.imread(str(p), 0).astype(np.float32), pts)
                                  - _upper_teeth(cv2.imread(str(ne[0]), 0).astype(np.float32),
                                                 ref))
        rgb = load_image(ne[0])
        out = Face.from_image(rgb, own_expression=False).render(apply_preset("fear"))
        pts = detect_landmarks(out, dlib).points.astype(np.float64)
        ours.append(_mouth(pts, ref) - base)
        grey = cv2.cvtColor(out, cv2.COLOR_RGB2GRAY).astype(np.float32)
        teeth_ours.append(_upper_teeth(grey, pts)
                          - _upper_teeth(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
                                         .astype(np.float32), ref))
    real_a, ours_a = np.array(real), np.array(ours)
    open_ = real_a[:, 2] > 0.05
    wid, drop = ours_a[:, 0].mean(), ours_a[:, 1].mean()
    assert len(real_a) >= 30 and open_.sum() >= 12
    assert wid >= np.median(real_a[:, 0]), (wid, np.median(real_a[:, 0]))
    assert drop <= 1.1 * real_a[open_, 1].mean(), (drop, real_a[open_, 1].mean())
    share = float(np.mean(np.array(teeth_real) > 0.5))  # real: 13 of 32
    shown = int((np.array(teeth_ours) > 0.5).sum())
    assert shown <= round(10 * share) + 2, (shown, share, teeth_ours)
