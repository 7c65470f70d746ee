"""Skin creases (editor/engine/creases.py): where, how strong, and the switches that turn them
off."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import SAMPLE, eye_frame, frame_sample, jaffe_changes, jaffe_images

from editor.core import Face, load_image
from editor.engine import face as face_module
from editor.engine.creases import _MIN_STRENGTH, STYLES, fold_lines, fold_strength
from editor.engine.layers import render_layers
from editor.engine.warp import warp

# Today's emotion presets (FAP number -> value in FAPU), fixed here so that tuning the presets
# does not move these tests; scaled by an intensity like apply_preset.
EMOTIONS = {
    "joy": {3: 100, 4: -50, 5: -100, 6: 120, 7: 120, 8: -40, 9: -40, 10: -90, 11: -90, 12: 150,
            13: 150, 19: 128, 20: 128, 21: 64, 22: 64, 35: 50, 36: 50, 41: 120, 42: 120,
            51: -50, 52: -100, 53: 120, 54: 120, 55: -40, 56: -40, 57: -90, 58: -90, 59: 150,
            60: 150},
    "surprise": {3: 360, 4: -60, 5: -60, 19: -200, 20: -200, 31: 220, 32: 220, 33: 240,
                 34: 240, 35: 180, 36: 180, 37: -40, 38: -40, 51: -60, 52: -60},
    "anger": {4: 40, 5: 60, 16: -80, 17: -80, 18: 100, 19: -100, 20: -100, 21: 60, 22: 60,
              31: -150, 32: -150, 33: -100, 34: -100, 35: 40, 36: 40, 37: 100, 38: 100},
    "disgust": {4: -120, 8: -140, 9: -140, 12: -60, 13: -60, 18: 200, 19: 60, 20: 60, 21: 80,
                22: 80, 31: -30, 32: -30, 37: 30, 38: 30, 51: -120, 55: -140, 56: -140,
                59: -60, 60: -60, 61: 50, 62: 50},
    "sadness": {6: 40, 7: 40, 12: -140, 13: -140, 18: 120, 19: 150, 20: 150, 31: 100, 32: 100,
                35: -80, 36: -80, 37: 30, 38: 30, 53: 40, 54: 40, 59: -140, 60: -140},
}


def apply_preset(name: str, k: float) -> dict[int, float]:
    return {n: k * v for n, v in EMOTIONS[name].items()}


def _lum(img: np.ndarray) -> np.ndarray:
    return img.astype(np.float64) @ np.array([0.299, 0.587, 0.114])


def _band(shape: tuple[int, int], pts: np.ndarray, radius: float) -> np.ndarray:
    """Pixels within ``radius`` of a polyline (dense samples are close enough)."""
    h, w = shape
    yy, xx = np.mgrid[0:h, 0:w]
    seg = np.concatenate([np.linspace(a, b, 8, endpoint=False) for a, b in zip(pts[:-1], pts[1:],
                                                                              strict=True)])
    lo = np.floor(seg.min(0) - radius - 1).astype(int)
    hi = np.ceil(seg.max(0) + radius + 1).astype(int)
    m = np.zeros((h, w), bool)
    sub_x, sub_y = xx[lo[1]:hi[1], lo[0]:hi[0]], yy[lo[1]:hi[1], lo[0]:hi[0]]
    d = np.min(np.hypot(sub_x[..., None] - seg[:, 0], sub_y[..., None] - seg[:, 1]), axis=2)
    m[lo[1]:hi[1], lo[0]:hi[0]] = d <= radius
    return m


def _drop(face, emotion: str, kind: str, k: float = 1.0) -> float:
    """Mean luminance drop (grey levels) in a band along the strongest active ``kind`` fold
    (its part at least half as strong as its peak)."""
    vec = face.fap_vector(apply_preset(emotion, k))
    v = face.deform(vec)
    lines = [(pts, s) for kk, pts, s in fold_lines(face, v) if kk == kind]
    pts, s = max(lines, key=lambda t: float(t[1].max()))
    pts = pts[s >= 0.5 * s.max()]
    band = _band(face.image.shape[:2], pts, max(0.02 * face.interocular, 1.0))
    off = _lum(face.render(vec, creases=False))[band]
    on = _lum(face.render(vec))[band]
    return float((off - on).mean())


def test_neutral_reproduces_the_photo_exactly(sample_neutral):
    assert np.array_equal(sample_neutral.render(None), sample_neutral.image)
    assert np.array_equal(sample_neutral.render(np.zeros(68, np.float32)), sample_neutral.image)
    for _kind, _pts, s in fold_lines(sample_neutral, sample_neutral.vertices):
        assert not s.any()  # no fold is even computed as compressed at rest


def test_creases_false_is_the_old_render(sample_neutral):
    f = sample_neutral
    vec = f.fap_vector(apply_preset("joy", 1.0))
    pts = f.plan.neutral.copy()
    from editor.engine.deform import deform_points

    pts = deform_points(f.plan, vec)
    V = f.plan.n_vertices
    v = pts[:V]
    tf = f.layer_transforms(v)
    from editor.engine.grain import apply_grain
    from editor.engine.jawband import jaw_map
    from editor.engine.lidskin import apply_lid_skin
    from editor.engine.liptone import apply_lip_tone

    # (the jaw band's map, the grain the resampling took, the lid skin and the stretched
    # lip's tone are part of the warp)
    base = apply_lip_tone(f, apply_lid_skin(f, apply_grain(f, warp(
        f.warp_plan, v, tf, cavity=False, hook=jaw_map(f, v))), v), v)
    old = render_layers(f, base, v, pts[V:], vec, tf).image
    assert np.array_equal(f.render(vec, creases=False), old)
    assert not np.array_equal(f.render(vec), old)


def test_joy_darkens_the_nasolabial_fold_but_not_the_mid_cheek(sample_neutral, monkeypatch):
    """The fold layer draws the nasolabial fold as a line, not a smear over the cheek (the
    smiling cheek's own shade, editor/engine/cheeks.py, is left out here: it has its tests)."""
    from editor.engine import face as face_module

    f = sample_neutral
    assert _drop(f, "joy", "nasolabial") > 4.0
    vec = f.fap_vector(apply_preset("joy", 1.0))
    monkeypatch.setattr(face_module, "apply_cheeks", lambda face, res, vertices: res)
    on, off = f.render(vec), f.render(vec, creases=False)
    v = f.deform(vec)
    r = max(2, int(0.06 * f.interocular))
    for name in ("cheek_l_2_2", "cheek_r_2_2", "cheek_l_1_2"):
        x, y = np.round(v[f.mesh.index(name)]).astype(int)
        assert np.array_equal(on[y - r:y + r, x - r:x + r], off[y - r:y + r, x - r:x + r]), name


def test_surprise_darkens_the_forehead_lines(sample_neutral):
    # the sample's fringe hides most of its forehead: the lines are kept off the hair
    assert _drop(sample_neutral, "surprise", "forehead") > 0.8


@pytest.mark.parametrize("emotion", ["anger", "sadness"])
def test_anger_and_sadness_darken_the_glabella(sample_neutral, emotion):
    assert _drop(sample_neutral, emotion, "glabella") > 2.0


def test_disgust_wrinkles_the_nose_joy_does_not(sample_neutral):
    """The nasal-root lines follow the inner brows pushed down (AU4 procerus, AU9): the shipped
    disgust and anger presets (inner brows -65 / -115 ENS; this file's old disgust lowers them by
    only 30) wrinkle the nose, a smile does not."""
    from editor.formats.presets import apply_preset as shipped

    f = sample_neutral

    def bridge(e: str, vec=None) -> float:
        vec = apply_preset(e, 1.0) if vec is None else vec
        return max(float(s.max()) for k, _p, s in fold_lines(f, f.deform(vec)) if k == "bridge")
    # (strengths are darkening fractions: the bridge style's depth is 0.03 since the grain
    # came back, 0.06 before, when these bounds were 0.05 and 0.02)
    assert bridge("disgust", shipped("disgust")) > 0.025
    assert bridge("joy", shipped("joy")) == 0.0
    # not drawn (below the 2-grey-level threshold): the smile does not lower the brows' inner
    # ends (the driver since the nasal-root lines follow AU4/AU9, not the lip); surprise
    # spreads that skin
    assert bridge("joy") < _MIN_STRENGTH and bridge("surprise") == 0.0
    assert bridge("anger") > 0.01  # the procerus (AU4) wrinkles the nasal root too


def _nose_side(f, vec) -> float:
    """The strongest darkening of the nose's side wrinkles (STYLES["nose_side"]) for ``vec``."""
    return max(float(s.max()) for k, _p, s in fold_lines(f, f.deform(vec)) if k == "nose_side")


def test_nose_wrinkler_lines_the_nose_sides_only_under_lowered_brows(sample_face, sample_neutral):
    """The oblique wrinkles on the sides of the nose (AU9: JAFFE's disgust, KA, KL; anger MK)
    follow the cheek beside the nose wing pushed up while the inner brows come down. Disgust
    draws them, deeper with intensity (the neutralised sample too, whose own smile lifts the
    cheek: pushed from its neutral mesh). Joy lifts the cheek as much (41/42 100) under brows
    that stay, anger lowers the brows over a cheek that stays, sadness, fear and surprise raise
    the inner brows, a turned head moves neither: none is drawn (below the 2-grey-level
    threshold). Before: no fold on the nose's sides at all ("the nose is too plain")."""
    from editor.bench import EXPRESSION
    from editor.bench_render import HEAD_ROTATION
    from editor.engine.faps import FAPS
    from editor.formats.presets import apply_preset as shipped

    for f in (sample_neutral, sample_face):
        d = [_nose_side(f, shipped("disgust", k)) for k in (0.5, 1.0, 1.5)]
        assert 0.0 <= d[0] < d[1] < d[2] <= 1.2 * STYLES["nose_side"].depth, d  # (uneven)
        assert d[1] > 0.035, d
        for name in ("joy", "anger", "sadness", "fear", "surprise"):
            # (at 150 % the neutralised sample's anger reaches 0.011: its raised mouth lifts
            # the cheek probes a little above the neutral mesh; real anger wrinkles the nose
            # too, JAFFE KA and MK)
            k = 1.5 if f is sample_neutral else 1.0
            assert _nose_side(f, shipped(name, k)) < _MIN_STRENGTH, name
    for vec in ({**EXPRESSION, **HEAD_ROTATION}, HEAD_ROTATION):
        assert _nose_side(sample_neutral, FAPS.clamp(FAPS.vector(vec))) == 0.0


@pytest.mark.skipif(not jaffe_images("*.NE1.*"), reason="needs ../shared/data/jaffe")
def test_jaffe_nose_side_wrinkles_only_for_disgust():
    """On the ten JAFFE neutral meshes the nose's side wrinkles are drawn for disgust
    (darkening 0.042-0.059 at 100 %) and not for joy, anger, sadness, fear or surprise at
    150 % (at most 0.005: anger's brows come down over a cheek that barely moves)."""
    from editor.formats.presets import apply_preset as shipped

    for ne in jaffe_images("*.NE1.*.tiff"):
        f = Face.from_image(ne, own_expression=False)
        assert _nose_side(f, shipped("disgust")) > 0.03, ne.name
        for name in ("joy", "anger", "sadness", "fear", "surprise"):
            assert _nose_side(f, shipped(name, 1.5)) < _MIN_STRENGTH, (ne.name, name)


def test_strength_grows_monotonically_with_intensity(sample_neutral):
    f = sample_neutral
    for emotion, kind in (("joy", "nasolabial"), ("surprise", "forehead"),
                          ("anger", "glabella")):
        peaks = []
        for k in (0.0, 0.25, 0.5, 0.75, 1.0, 1.25):
            lines = fold_lines(f, f.deform(apply_preset(emotion, k)))
            peaks.append(max(float(s.max()) for kk, _p, s in lines if kk == kind))
        assert peaks[0] == 0.0
        assert all(b > a for a, b in zip(peaks, peaks[1:], strict=False)), (emotion, peaks)


def test_stretching_and_pure_motion_make_no_fold(sample_neutral):
    f = sample_neutral
    # the whole mesh shifted, or scaled up: nothing is compressed
    for v in (f.vertices + np.float32([3.5, -2.0]), (f.vertices - 200) * 1.1 + 200):
        assert not fold_strength(f, v).any()


def test_width_follows_the_face_not_the_resolution():
    """The same face at twice the size: the fold band darkens alike (width in IOD units)."""
    import cv2


    img = load_image(SAMPLE)
    drops = []
    for s in (1, 2):
        f = Face.from_image(cv2.resize(img, None, fx=s, fy=s, interpolation=cv2.INTER_CUBIC),
                            own_expression=False)
        drops.append(_drop(f, "surprise", "forehead"))
    assert drops[1] == pytest.approx(drops[0], rel=0.35)


def test_cli_no_creases_flag(tmp_path, sample_face):
    # the CLI opens the photo as the product does (own expression estimated)
    from editor.cli import main
    from editor.formats.presets import apply_preset as shipped

    a, b = tmp_path / "on.png", tmp_path / "off.png"
    assert main(["render", str(SAMPLE), "--preset", "surprise", "-o", str(a)]) == 0
    assert main(["render", str(SAMPLE), "--preset", "surprise", "--no-creases", "-o",
                 str(b)]) == 0
    on, off = load_image(a), load_image(b)
    vec = sample_face.fap_vector(shipped("surprise", 1.0))
    assert np.array_equal(off, sample_face.render(vec, creases=False, sharp=True))
    assert np.array_equal(on, sample_face.render(vec, sharp=True))
    assert not np.array_equal(on, off)


def test_jaffe_surprise_forehead_and_joy_nasolabial():

    paths = jaffe_images("KA.NE*.tiff")
    if not paths:
        pytest.skip("../shared/data/jaffe is not available")
    f = Face.from_image(paths[0], own_expression=False)
    assert _drop(f, "surprise", "forehead") > 2.0
    assert _drop(f, "joy", "nasolabial") > 2.0
    assert np.array_equal(f.render(None), f.image)


def _forehead_dip(img: np.ndarray, f) -> float:
    """Deepest dip of the forehead's row profile (the mean of each row over 0.3 IOD either side
    of the face's middle, from 0.06 to 0.35 IOD above the photo's highest brow point) below a
    closing of 0.12 IOD, as a share of the closing: how dark its horizontal lines are."""
    import cv2

    v, m, io = f.vertices, f.mesh, f.interocular
    L = _lum(img).astype(np.float32)
    top = min(float(v[m.fdp[k]][1]) for k in ("4.1", "4.2", "4.3", "4.4", "4.5", "4.6"))
    cx = 0.5 * float(v[m.fdp["4.1"]][0] + v[m.fdp["4.2"]][0])
    prof = L[max(int(top - 0.35 * io), 0):int(top - 0.06 * io),
             int(cx - 0.3 * io):int(cx + 0.3 * io)].mean(1)
    clo = cv2.morphologyEx(prof[:, None], cv2.MORPH_CLOSE,
                           np.ones((int(0.12 * io) | 1, 1), np.uint8))[:, 0]
    return float(((clo - prof) / np.maximum(clo, 1.0)).max())


def test_jaffe_surprise_forehead_lines_as_dark_as_real_ones():
    """JAFFE's ten women: the horizontal lines surprise draws on each one's neutral forehead are
    as dark as her own surprised photo shows (the row profile's dip: real median 0.055, 0.03 on
    the neutral photos; drawn with the forehead's old depth 0.12: 0.020 at 100 %, 0.030 at
    150 %, fainter than the neutral photo's own texture; now 0.052 and 0.105), and at 150 %
    no darker than the darker real ones (their p90: 0.20)."""
    from editor.formats.presets import apply_preset as shipped

    real, ours, strong = [], [], []
    for ne in jaffe_images("*.NE1.*.tiff"):
        who = ne.name[:2]
        su = jaffe_images(f"{who}.SU*.tiff")
        if not su:
            continue
        f = Face.from_image(ne, own_expression=False)
        g = Face.from_image(su[0], own_expression=False)
        real.append(_forehead_dip(g.image, g))
        ours.append(_forehead_dip(f.render(shipped("surprise", 1.0)), f))
        strong.append(_forehead_dip(f.render(shipped("surprise", 1.5)), f))
    if len(real) < 8:
        pytest.skip("../shared/data/jaffe is not available")
    assert np.median(ours) >= 0.8 * np.median(real), (ours, real)
    assert np.median(strong) <= np.percentile(real, 90), (strong, real)


#: per fold kind, the valley's search window across its line (IOD): how far from the line its
#: bottom is looked for, the half-length of the profile and the bottom's own half-width
_WINDOWS = {"nasolabial": (0.1, 0.18, 0.035), "bridge": (0.03, 0.06, 0.015),
            "upper_lip": (0.06, 0.12, 0.03), "nose_side": (0.04, 0.08, 0.015)}


@pytest.mark.parametrize(("kind", "emotion", "code", "real_median"), [
    ("nasolabial", "joy", "HA", 0.17), ("bridge", "disgust", "DI", 0.02),
    ("upper_lip", "disgust", "DI", 0.17), ("upper_lip", "joy", "HA", 0.25),
    ("nose_side", "disgust", "DI", 0.064)])
def test_jaffe_folds_as_deep_as_real_ones(kind, emotion, code, real_median):
    """JAFFE's ten women: the folds an emotion draws on each one's neutral face are as deep as
    her own photos of it show. Depth: the valley below its shoulders across the middle of the
    fold line (:func:`_valley`, each kind's window) over the image's median luminance; at
    100 % the median over the women within 0.7-1.5 x the real photos' (two each), at 150 % no
    deeper than the deeper real ones (their p90). Real medians: joy's nasolabial folds 0.17,
    disgust's nasal-root lines 0.02, the furrow beside the nose wing 0.17 under disgust and
    0.25 in a smile, the oblique wrinkles on the nose's sides 0.064 under disgust (0.054 on
    the neutral photos, anger 0.054, sadness 0.059, joy 0.062). Before they were calibrated
    so: 0.043, 0.073 and 0.034 (a smile without its folds; scratches across the nose; a lip
    raiser without its furrow); the nose's sides had no fold (nothing to measure)."""

    _assert_as_deep_as_real(emotion, code, lambda f, img, v: _fold_depths(f, img, v, kind),
                            real_median)


def _assert_as_deep_as_real(emotion: str, code: str, depths, real_median: float) -> None:
    """``depths(face, image, vertices)`` (a list of fold depths) on JAFFE's real ``code`` photos
    (two per woman) and on ``emotion`` rendered at 100 and 150 % on each woman's neutral photo:
    the real median is ``real_median`` (the measure itself), ours at 100 % within 0.7-1.5 x
    it, at 150 % no deeper than the real p90. Skips without JAFFE."""
    real, ours, strong = _real_and_rendered(emotion, code, depths, (1.0, 1.5))
    assert np.median(real) == pytest.approx(real_median, abs=0.02)  # (the measure itself)
    assert 0.7 * np.median(real) <= np.median(ours) <= 1.5 * np.median(real), np.median(ours)
    assert np.median(strong) <= np.percentile(real, 90), np.median(strong)


def _real_and_rendered(emotion: str, code: str, depths, scales: tuple[float, ...],
                       per_woman: int | None = 2) -> tuple[list[float], ...]:
    """``depths(face, image, vertices)`` on JAFFE's real ``code`` photos (``per_woman`` per
    woman; None: all), then on ``emotion`` rendered at each of ``scales`` on each woman's
    neutral photo (one list per scale). Skips without JAFFE."""
    from editor.formats.presets import apply_preset as shipped

    real: list[float] = []
    rendered: list[list[float]] = [[] for _ in scales]
    for ne in jaffe_images("*.NE1.*.tiff"):
        photos = jaffe_images(f"{ne.name[:2]}.{code}*.tiff")
        if not photos:
            continue
        f = Face.from_image(ne, own_expression=False)
        for p in photos[:per_woman]:
            g = Face.from_image(p, own_expression=False)
            real += depths(g, g.image, g.vertices)
        for k, into in zip(scales, rendered, strict=True):
            vec = shipped(emotion, k)
            into += depths(f, f.render(vec), f.deform(vec))
    if len(real) < 16:
        pytest.skip("../shared/data/jaffe is not available")
    return (real, *rendered)


@pytest.mark.gui
def test_gui_skin_creases_action_toggles_the_preview(qtbot, sample_neutral, isolated_settings):
    pytest.importorskip("pytestqt")
    from editor.ui.main_window import MainWindow

    w = MainWindow()
    qtbot.addWidget(w)
    w.load_face(sample_neutral)
    w.show()
    qtbot.waitExposed(w)
    try:
        act = w.act_creases
        assert act.isCheckable() and act.isChecked()
        assert act in w.menu("&View").actions()
        vec = sample_neutral.fap_vector(apply_preset("surprise", 1.0))
        w.model.set_document(w.model.doc.with_fap_vector(vec))
        assert w.scheduler.wait(5000)
        on = w.canvas.preview_image().copy()
        assert np.array_equal(on, sample_neutral.render(vec))
        act.trigger()  # off
        assert not act.isChecked()
        assert w.scheduler.wait(5000)
        off = w.canvas.preview_image().copy()
        assert np.array_equal(off, sample_neutral.render(vec, creases=False))
        assert not np.array_equal(on, off)
        # a FAP change keeps following the switch
        vec2 = sample_neutral.fap_vector(apply_preset("anger", 1.0))
        w.model.set_document(w.model.doc.with_fap_vector(vec2))
        assert w.scheduler.wait(5000)
        assert np.array_equal(w.canvas.preview_image(), sample_neutral.render(vec2, creases=False))
        act.trigger()  # on again
        assert w.scheduler.wait(5000)
        assert np.array_equal(w.canvas.preview_image(), sample_neutral.render(vec2))
    finally:
        w.close_without_prompt()


# ---------------------------------------------------------------- the photo's own folds
def _own_fold_bands(face) -> list[np.ndarray]:
    """Bands along the nasolabial lines of the neutralised face (the photo's smile folds)."""
    v = face.deform(None)
    return [_band(face.image.shape[:2], pts[4:-4], 0.06 * face.interocular)
            for kind, pts, _s in fold_lines(face, v) if kind == "nasolabial"]


def test_own_folds_untouched_on_the_photos_own_expression(sample_face):
    """Rendering the photo's own expression changes nothing (the fade is exactly 0 there)."""
    from editor.engine.creases import unfold_strength

    assert sample_face.has_expression
    assert not unfold_strength(sample_face, sample_face.vertices).any()
    assert np.array_equal(sample_face.render(sample_face.expression), sample_face.image)


def test_own_smile_folds_fade_on_the_neutralised_face(sample_face):
    """The sample smiles: its nasolabial folds are shaded valleys. Neutralised, the skin there
    is spread, so the valleys are lifted towards the skin around them: brighter, less
    contrasted, and no more saturated than before (no coloured line left behind)."""
    from editor.engine.creases import unfold_strength

    v = sample_face.deform(None)
    u = unfold_strength(sample_face, v)
    assert u.max() > 0.9  # fully unfolded somewhere on the line
    off = sample_face.render(None, creases=False).astype(np.float64)
    on = sample_face.render(None).astype(np.float64)
    for band in _own_fold_bands(sample_face):
        lo, ln = _lum(off)[band], _lum(on)[band]
        valley = lo < np.percentile(lo, 25)
        assert (ln[valley] - lo[valley]).mean() > 8.0  # the valley is lifted (grey levels)
        assert ln.std() < 0.85 * lo.std()  # flatter: the fold's shading is reduced
        sat = [(x[band].max(1) - x[band].min(1)).mean() for x in (off, on)]
        assert sat[1] <= sat[0] + 0.5
    # outside every band nothing changes
    anyband = np.logical_or.reduce(_own_fold_bands(sample_face))
    far = ~_band(sample_face.image.shape[:2],
                 np.argwhere(anyband)[:, ::-1].astype(float)[::25], 0.5 * sample_face.interocular)
    assert np.array_equal(off[far], on[far])


def _lift_above_skin(face) -> float:
    """The most (grey levels) the neutralised face's own-fold bands rise above the skin either
    side of the valley: the creases-off frame's closing, of the lift's own radius."""
    import math

    import cv2

    off = _lum(face.render(None, creases=False)).astype(np.float32)
    on = _lum(face.render(None)).astype(np.float32)
    r = int(math.ceil(4 * 0.026 * face.interocular * 1.25))
    top = cv2.morphologyEx(off, cv2.MORPH_CLOSE,
                           cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1)))
    band = np.logical_or.reduce(_own_fold_bands(face))
    return float((on - top)[band].max())


def test_own_folds_are_lifted_to_the_skin_not_beyond(sample_face):
    """The lift fills the valley up to the skin either side of it, never above (the level it
    aims at ramps between a lit cheek and the shaded skin by the mouth, and a sharp core pulls
    the smoothed valley down on its shoulders): at most 3 grey levels over the frame's own
    closing. Above it the lifted band read as a light outline where the smile's fold had been:
    12 on the sample, 21-23 on JAFFE NA, MK and KM (now 1.2 and 0-1)."""
    assert _lift_above_skin(sample_face) <= 3.0
    for who in ("NA", "MK", "KM"):
        paths = jaffe_images(f"{who}.HA1.*.tiff")
        if paths:
            assert _lift_above_skin(Face.from_image(paths[0])) <= 3.0, who


def _thin_line_depth(face, sharp: bool) -> float:
    """How dark a thin line the neutralised face keeps in its own-fold bands: the 99th
    percentile of the frame's closing (5 px disc: removes a line up to ~3 px wide) minus the
    frame, grey levels."""
    import cv2

    on = _lum(face.render(None, sharp=sharp)).astype(np.float32)
    band = np.logical_or.reduce(_own_fold_bands(face))
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))
    return float(np.percentile((cv2.morphologyEx(on, cv2.MORPH_CLOSE, k) - on)[band], 99))


def test_lifted_own_folds_leave_no_thin_dark_line(sample_face, monkeypatch):
    """The lift brings a fold's sharp core up with its valley, in the preview and in sharp
    stills: no scratch where a smile's fold was. The core may stay below the lifted level by
    the skin's grain in proportion to its light (6 levels at the skin's, fewer in a dark core;
    6 flat levels left a dark core ~20 % below after the gain), and sharp stills resample the
    level they divide by as they resample the photo and never above the frame plus that
    grain (the bilinear level under a bicubic core left a thin line on the sample's cheek).
    Thin-line depth (p99): the sample 7 / 11 (bilinear / sharp; were 8 / 18), JAFFE MK 14 / 24
    (32 / 58), NA 12 / 14 (16 / 35), KM 12 / 13 (15 / 38)."""
    # (the grain put back where the warp resampled (grain.py) is left out: it is isotropic
    # noise at the photo's level, which this closing reads as specks of every frame)
    monkeypatch.setattr(face_module, "apply_grain", lambda face, res: res)
    assert _thin_line_depth(sample_face, False) <= 10.0
    assert _thin_line_depth(sample_face, True) <= 14.0
    for who in ("NA", "MK", "KM"):
        paths = jaffe_images(f"{who}.HA1.*.tiff")
        if paths:
            f = Face.from_image(paths[0])
            assert _thin_line_depth(f, False) <= 20.0, who
            assert _thin_line_depth(f, True) <= 28.0, who


def test_own_folds_fade_only_as_far_as_the_skin_is_spread(sample_face):
    """Half-way between the photo's smile and the neutral face the fade is partial; a target
    that compresses the skin like the photo (or more: a broad smile) does not fade it."""
    from editor.engine.creases import unfold_strength

    f0 = sample_face.expression
    u_half = unfold_strength(sample_face, sample_face.deform(0.5 * f0)).max()
    u_zero = unfold_strength(sample_face, sample_face.deform(None)).max()
    assert 0.2 < u_half < 0.8 * u_zero
    assert unfold_strength(sample_face, sample_face.deform(1.3 * f0)).max() < 0.02


def test_a_neutral_photo_has_no_own_folds_to_fade(sample_neutral):
    from editor.engine.creases import unfold_strength

    for name in EMOTIONS:
        v = sample_neutral.deform(apply_preset(name, 1.0))
        assert not unfold_strength(sample_neutral, v).any()


def test_upper_lip_raiser_deepens_the_upper_nasolabial_furrow(sample_neutral):
    """AU10 (disgust's raised upper lip) pushes the skin below the nose wing up: the upper part
    of the nasolabial furrow darkens even without a smile; sadness and surprise do not."""
    from editor.formats.presets import apply_preset as shipped

    f = sample_neutral

    def upper(name: str) -> float:
        return max(float(s.max()) for k, _p, s in fold_lines(f, f.deform(shipped(name)))
                   if k == "upper_lip")
    assert upper("disgust") > 2 * _MIN_STRENGTH  # drawn: 0.05 on the sample (both detectors)
    assert upper("sadness") < _MIN_STRENGTH and upper("surprise") < _MIN_STRENGTH


def test_no_own_folds_faded_on_nearly_neutral_photos():
    """JAFFE neutral photos opened as the product does (own expression estimated): the estimate
    finds a trace of a smile on some (compression up to 0.07), which is no fold to fade; the
    sample's real smile (0.15-0.27) is faded fully (test above)."""
    from editor.engine.creases import unfold_strength
    from editor.formats.presets import apply_preset as shipped

    paths = [p for who in ("KA", "NA", "KR") for p in jaffe_images(f"{who}.NE*.tiff")[:1]]
    if len(paths) < 3:
        pytest.skip("JAFFE is not available")
    for path in paths:
        f = Face.from_image(path)
        for name in ("sadness", "surprise", "anger", "fear", "disgust"):
            assert unfold_strength(f, f.deform(shipped(name))).max() < 0.1, (path.name, name)


def _valley(L: np.ndarray, pts: np.ndarray, iod: float, reach: float = 0.1, half: float = 0.18,
            bottom: float = 0.035) -> tuple[float, float]:
    """Median depth and sharpness of the dark valley across a fold line in luminance ``L``.

    Profiles across the middle of the line (+-``half`` IOD, default 0.18); the valley's bottom
    is looked for within ``reach`` (0.1) IOD of the line (the laid-out line need not sit on the
    photo's valley). Depth: the lower of the brightest points either side (beyond ``bottom``,
    0.035 IOD) minus the bottom; sharpness: the profile 0.02-0.035 IOD either side of the
    bottom minus the bottom (a thin line)."""
    import cv2

    tang = np.gradient(pts, axis=0)
    tang /= np.linalg.norm(tang, axis=1, keepdims=True)
    nrm = np.stack([-tang[:, 1], tang[:, 0]], 1)
    step = half / 18.0
    ds = np.arange(-half, half + 0.01 * step, step)
    far = half * 8.0 / 9.0
    depth, sharp = [], []
    for i in range(int(0.3 * len(pts)), int(0.7 * len(pts)) + 1):
        q = (pts[i] + ds[:, None] * iod * nrm[i]).astype(np.float32)
        p = cv2.remap(L.astype(np.float32), q[None, :, 0], q[None, :, 1], cv2.INTER_LINEAR)[0]
        c = np.flatnonzero(np.abs(ds) <= reach + 1e-9)
        b = c[np.argmin(p[c])]
        r = ds - ds[b]
        sides = [p[(r < -bottom) & (r > -far)].max(), p[(r > bottom) & (r < far)].max()]
        depth.append(min(sides) - p[b])
        sharp.append(p[(np.abs(r) > 0.015) & (np.abs(r) <= 0.035)].mean() - p[b])
    return float(np.median(depth)), float(np.median(sharp))


def test_own_fold_is_lifted_where_the_photo_shows_it(sample_face):
    """The sample's image-left smile fold (the subject's right) lies 1-3 px medial of its laid-out
    line. Neutralised, its valley is lifted wherever it is: shallower than in the photo and no
    sharper than without creases (a lift beside it left a harsh thin line, outlined by brightened
    skin), and the fading never darkens the skin."""
    f = sample_face
    v = f.deform(None)
    on, off = f.render(None), f.render(None, creases=False)
    naso = [(pts, pts0) for (k, pts, _s), (_k, pts0, _s0) in zip(fold_lines(f, v),
                                                                  fold_lines(f, f.vertices),
                                                                  strict=True)
            if k == "nasolabial"]
    pts, pts0 = min(naso, key=lambda t: float(t[0][:, 0].mean()))  # image-left
    iod = f.interocular
    d_photo, s_photo = _valley(_lum(f.image), pts0, iod)
    d_off, s_off = _valley(_lum(off), pts, iod)
    d_on, s_on = _valley(_lum(on), pts, iod)
    assert d_photo > 40 and d_off > 40  # a real valley (71 / 56 grey levels)
    assert d_on < 0.3 * d_photo and d_on < 0.3 * d_off  # main: 41
    assert s_on < 0.6 * s_off  # main: 22.0 against 16.4 without creases
    # nothing darker than without creases along either fold (main: up to 17 grey levels)
    region = np.logical_or.reduce(_own_fold_bands(f))
    assert (_lum(off) - _lum(on))[region].max() <= 1.0


@pytest.mark.parametrize("emotion", [None, "sadness", "anger"])
def test_own_fold_leaves_no_dark_stub_above_the_mouth_corner(sample_face, emotion):
    """Along the whole of each own smile fold (its elbow above the mouth corner included,
    where the valley is a pixel or two wide and deepens quickly along the line), the
    neutralised face and closed-mouth presets keep no valley deeper than 23 grey levels below
    the skin around it (a closing of 9 px). The photo's own: 87 and 42; before the lift
    reached the valley's narrow core (the along-fold mean divided the gain): 29-35 on the
    image-left fold, a dark stub beside the mouth under every preset."""
    f = sample_face
    vec = None if emotion is None else apply_preset(emotion, 1.0)
    deepest = [float(d.max()) for d in _own_fold_dips(f, _lum(f.render(vec)), f.deform(vec),
                                                      middle=0.5)]
    assert len(deepest) == 2
    assert max(deepest) <= 23.0, deepest


def _own_fold_dips(f, img_lum: np.ndarray, verts: np.ndarray, middle: float = 0.9
                   ) -> list[np.ndarray]:
    """Per own nasolabial fold of ``f`` (on the mesh ``verts``), at each sample of its part
    faded in above ``middle``: the deepest valley within 1.5 px of it in ``img_lum`` (grey
    levels below a closing of 9 px)."""
    import cv2

    from editor.engine.creases import _own_valleys, crease_plan

    p = crease_plan(f)
    tri, bary = _own_valleys(f)
    V = np.asarray(verts, np.float64)
    pos = (V[f.mesh.triangles[tri]] * bary[..., None]).sum(1).astype(np.float32)
    L = img_lum.astype(np.float32)
    dip = cv2.morphologyEx(L, cv2.MORPH_CLOSE,
                           cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (9, 9))) - L
    steps = np.linspace(-1.5, 1.5, 7, dtype=np.float32)
    out = []
    for k, kind in enumerate(p.kinds):
        if kind != "nasolabial":
            continue
        a, b = p.start[k], p.start[k + 1]
        q = pos[a:b][p.utaper[a:b] > middle]
        near = [cv2.remap(dip, (q[:, 0] + dx)[None], (q[:, 1] + dy)[None], cv2.INTER_LINEAR)[0]
                for dx in steps for dy in steps]
        out.append(np.max(near, 0))
    return out


def test_a_sharp_dark_own_fold_is_lifted_to_the_skin(sample_face):
    """A smile fold drawn sharp and dark (2 px at 15 % of the skin's light along the middle of
    the sample's own folds, as JAFFE's MK.HA shows them: 13-20 grey levels in skin of ~120) is
    lifted to the skin on the neutralised face: on average at most 60 grey levels below it
    (the painted photo: ~160). With the lift's gain capped at 4 the core stayed a thin dark
    line beside the lifted skin: 81 and 53 (now 46 and 35)."""
    import cv2

    from editor.engine.creases import _own_valleys, crease_plan

    f = sample_face
    p = crease_plan(f)
    tri, bary = _own_valleys(f)
    V = f.vertices.astype(np.float64)
    pos = (V[f.mesh.triangles[tri]] * bary[..., None]).sum(1)
    paint = np.zeros(f.image.shape[:2], np.float32)
    for k, kind in enumerate(p.kinds):
        if kind == "nasolabial":
            a, b = p.start[k], p.start[k + 1]
            q = pos[a:b][p.utaper[a:b] > 0.9]
            cv2.polylines(paint, [np.round(q * 16).astype(np.int32)], False, 1.0, 2,
                          cv2.LINE_AA, 4)
    paint = np.clip(cv2.GaussianBlur(paint, (0, 0), 0.5), 0.0, 1.0)[..., None]
    img = (f.image * (1.0 - 0.85 * paint)).astype(np.uint8)
    g = Face.from_image(img)
    painted = [float(d.mean()) for d in _own_fold_dips(g, _lum(img), g.vertices)]
    assert min(painted) > 120  # a deep valley
    dips = [float(d.mean()) for d in _own_fold_dips(g, _lum(g.render(None)), g.deform(None))]
    assert len(dips) == 2 and max(dips) <= 60.0, dips


def test_folds_on_a_soft_photo_are_no_sharper_than_its_own_edges():
    """On a soft photo (the sample upscaled 4x: its edges span 5.3 px 10-90 %, a Gaussian blur
    of sigma 2.07) anger's folds are drawn as if seen through the same blur: the darkening's
    steepest flank against its depth gives an effective line sigma (0.607 depth / slope) of at
    least 0.95 x the photo's. Drawn at their own width (the nose bridge's 0.011 IOD) they read
    as scratches on a large face: 1.65 (now 2.25), the steepest slope twice as steep."""
    import cv2

    from editor.engine.layers import layer_plan

    img = cv2.resize(load_image(SAMPLE), None, fx=4, fy=4, interpolation=cv2.INTER_CUBIC)
    f = Face.from_image(img, own_expression=False)
    psf = layer_plan(f).soft / 2.56
    assert psf > 1.5  # a soft photo
    vec = apply_preset("anger", 1.0)
    d = _lum(f.render(vec, creases=False)).astype(np.float32) - _lum(f.render(vec))
    d = cv2.GaussianBlur(d.astype(np.float32), (0, 0), 0.7)  # (the 8-bit rounding's noise)
    gy, gx = np.gradient(d)
    assert d.max() > 10  # folds are drawn
    assert 0.607 * d.max() / np.hypot(gx, gy).max() >= 0.95 * psf


def test_closing_the_eyes_makes_no_nasal_root_lines(sample_face):
    """The nasal-root lines follow the inner brows pushed down, not the upper lids: closed eyes
    (the lids and the ring above them move down) draw none (main: 0.13, as strong as anger)."""
    f = sample_face
    vec = f.fap_vector({"close_t_l_eyelid": 1080, "close_t_r_eyelid": 1080})
    assert not any(s.any() for k, _p, s in fold_lines(f, f.deform(vec)) if k == "bridge")


def test_own_fold_lift_carried_from_the_photo_matches_the_frame(sample_face):
    """The own folds' lift fields (the valley smoothed along the fold, the skin level either
    side, its skin weight), taken once on the photo and carried by the warp's backward map,
    lift the valley as taking them on the frame does.

    The two differ only where the valley is ragged (smoothing along the fold in the photo or in
    the frame sees slightly different pixels): a few single pixels up to ~25 grey levels, the
    total difference under a fifth of the lift itself. A map off by half a pixel gives 0.27-0.31
    of the lift (1 px: ~0.5), an extra 1 px blur of the smoothed valley 0.25-0.29."""
    import dataclasses

    from editor.engine.creases import apply_creases

    f = sample_face
    for faps in (None, f.fap_vector({"open_jaw": 600})):
        v = f.deform(faps)
        base = f.render_full(faps, creases=False)
        assert base.maps is not None
        a = apply_creases(f, dataclasses.replace(base, image=base.image.copy()), v).image
        b = apply_creases(f, dataclasses.replace(base, image=base.image.copy(), maps=None),
                          v).image
        d = np.abs(a.astype(int) - b.astype(int))
        lift = np.abs(b.astype(int) - base.image.astype(int))
        assert lift.sum() > 0
        assert d.sum() < 0.22 * lift.sum() and (d > 3).mean() < 0.001 and d.max() <= 32


@pytest.mark.parametrize("emotion", ["joy", "surprise", "anger"])
def test_strengths_together_equal_the_separate_ones(sample_face, emotion):
    """The per-frame path measures the skin's spacing once for the folds and the photo's own
    folds (creases._strengths): the same values as fold_strength and unfold_strength."""
    from editor.engine.creases import _strengths, unfold_strength

    v = sample_face.deform(apply_preset(emotion, 1.2))
    s, un = _strengths(sample_face, v)
    assert np.array_equal(s, fold_strength(sample_face, v))
    assert np.array_equal(un, unfold_strength(sample_face, v))
    assert s.max() > _MIN_STRENGTH  # each vector draws a fold


def test_splat_of_many_canvases_equals_one_canvas_at_a_time():
    """All of a frame's crease canvases are splatted in one bincount (stacked, or canvas by
    canvas when a box was clipped by the image's edge): per canvas, the bilinear splat of its
    own points, bit for bit, whatever else is splatted with it; weight off a canvas is dropped
    on the fallback path."""
    from editor.engine.creases import _splat_many, _splat_rows

    rng = np.random.default_rng(5)

    def alone(shape, xy, w):  # one canvas, the four corners in corner-major order
        h, wd = shape
        p0 = np.floor(xy)
        fx, fy = (xy - p0).T
        ip = p0.astype(np.int64)
        base = ip[:, 1] * wd + ip[:, 0]
        idx = np.concatenate([base, base + 1, base + wd, base + wd + 1])
        ws = np.concatenate([(1 - fy) * w * (1 - fx), (1 - fy) * w * fx, fy * w * (1 - fx),
                             fy * w * fx])
        keep = (idx >= 0) & (idx < h * wd)
        return np.bincount(idx[keep], ws[keep], minlength=h * wd).astype(np.float32) \
            .reshape(h, wd)

    shapes = [(12, 30), (25, 9), (7, 41)]
    cans = []
    for h, wd in shapes:
        n = int(rng.integers(20, 200))
        xy = np.stack([rng.uniform(1, wd - 2.01, n), rng.uniform(1, h - 2.01, n)], 1)
        cans.append(((h, wd), xy, rng.uniform(0, 1, n)))
    stacked = _splat_rows([c[0] for c in cans], np.concatenate([c[1] for c in cans]).T,
                          np.concatenate([c[2] for c in cans]),
                          np.arange(len(cans)).repeat([len(c[2]) for c in cans]))
    fallback = _splat_many(cans)
    for (shape, xy, w), a, b in zip(cans, stacked, fallback, strict=True):
        ref = alone(shape, xy, w)
        assert a.shape == b.shape == shape
        assert np.array_equal(a, ref) and np.array_equal(b, ref)
        assert ref.sum() > 0
    # a point beyond its canvas's last row: its weight is dropped, the others' stay
    (h, wd), xy, w = cans[0]
    out = np.vstack([xy, [[3.5, h + 4.0]]])
    got = _splat_many([((h, wd), out, np.append(w, 1.0)), cans[1]])
    assert np.array_equal(got[0], alone((h, wd), xy, w))
    assert np.array_equal(got[1], alone(*cans[1]))


def test_per_face_constants_are_published_only_when_complete(monkeypatch):
    """The editor's GUI and render threads may ask for a face's crease constants at once: the
    cached entry appears only after the photo's own folds' fields are set (published before,
    the other thread could render without the unfold: a rare preview differing from a
    re-render of the same document, test_ui_window's project round trip)."""
    from editor.engine import creases

    f = Face.from_image(SAMPLE)
    assert f.has_expression
    seen = []
    spacing = creases._spacing

    def watching(face, vertices, fa=None):
        seen.append(f in creases._FAST)
        return spacing(face, vertices, fa)

    # (the own folds' fields are computed from the neutral mesh's spacing)
    monkeypatch.setattr(creases, "_spacing", watching)
    fa = creases._fast(f)
    assert seen and not any(seen)
    assert fa.own_gap is not None and creases._FAST[f] is fa


def test_wide_folds_drawn_at_a_coarser_resolution_look_the_same(monkeypatch):
    """On a large face (the sample at 8x, about 350 px between the eyes) folds as wide as
    several pixels are blurred on a grid f times coarser and resized back: the render is within
    one grey level of drawing them at full resolution (a wrong weight per coarse pixel, f^2,
    or a half-pixel shift of the grid shows as tens of grey levels along the lines)."""
    import cv2

    from editor.engine import creases

    img = cv2.resize(load_image(SAMPLE), None, fx=8, fy=8, interpolation=cv2.INTER_CUBIC)
    f = Face.from_image(img, own_expression=False)
    fa = creases._fast(f)
    assert max(creases._fold_scale(float(s)) for s in fa.dsig) > 1  # drawn coarsely here
    for emotion in ("anger", "surprise"):
        vec = apply_preset(emotion, 1.5)
        coarse = f.render(vec).astype(np.int16)
        monkeypatch.setattr(creases, "_fold_scale", lambda dsig: 1)
        fine = f.render(vec).astype(np.int16)
        monkeypatch.undo()
        assert (_lum(f.render(vec, creases=False)) - _lum(fine)).max() > 10  # folds are drawn
        assert np.abs(coarse - fine).max() <= 1, emotion


def _chin_groove(f: Face, img: np.ndarray, v: np.ndarray) -> float:
    """Deepest dip of the luminance down the band from the lower lip's middle (8.2) to the
    chin (2.1), over the image's median light: seven profiles 0.12 IOD apart across the
    mouth's middle, each from 15 to 80 % of the way, its dip below the lower of the brightest
    points above and below it; the median over the profiles (wherever the groove lies)."""
    import cv2

    L = _lum(img).astype(np.float32)
    a = v[f.mesh.fdp["8.2"]].astype(np.float64)
    b = v[f.mesh.fdp["2.1"]].astype(np.float64)
    t = np.linspace(0.05, 0.85, 33)
    dips = []
    for dx in np.linspace(-0.12, 0.12, 7) * f.interocular:
        q = (a + t[:, None] * (b - a) + [dx, 0.0]).astype(np.float32)
        p = cv2.remap(L, q[None, :, 0], q[None, :, 1], cv2.INTER_LINEAR)[0]
        dips.append(max(min(p[:i].max(), p[i:].max()) - p[i] for i in range(4, len(p) - 4)))
    return float(np.median(dips)) / max(float(np.median(L)), 1.0)


def test_chin_groove_only_under_a_pushed_up_lower_lip(sample_neutral):
    """The mentolabial groove (kind "chin") is drawn where the lower lip is pushed up over the
    still chin (anger's chin raiser and lip presser), not for a dropped jaw (surprise, fear),
    a lowered lower lip (disgust), sadness's pout or a smile."""
    from editor.formats.presets import apply_preset as shipped

    f = sample_neutral

    def chin(vec) -> float:
        return max(float(s.max()) for k, _p, s in fold_lines(f, f.deform(vec)) if k == "chin")
    assert chin(shipped("anger")) > 0.05
    for name in ("joy", "sadness", "surprise", "fear", "disgust"):
        assert chin(shipped(name)) < _MIN_STRENGTH, name
    assert chin(f.fap_vector({"open_jaw": 600})) < _MIN_STRENGTH


def test_jaffe_anger_chin_groove_as_deep_as_real_ones():
    """JAFFE's ten women: anger drawn on each one's neutral face shows the groove under the
    pushed-up lower lip as deep as her own anger photos (two each) do (:func:`_chin_groove`):
    real median 0.18 (0.04 on the neutral photos); at 100 % the median over the women within
    0.7-1.5 x, at 150 % no deeper than the deeper real ones (p90). Before the groove was
    drawn: 0.02 (measured now: 0.187, 0.217 at 150 %, the groove across the lip's width and
    the chin boss's shade broad; 0.183, 0.264 with the short groove and the narrow shade and no
    light ridge; 0.213 and 0.292 before that, 0.154 and 0.243 before the pressed lips
    pouted, 52/57/58 above 5/10/11)."""
    _assert_as_deep_as_real("anger", "AN", lambda f, img, v: [_chin_groove(f, img, v)], 0.178)


def test_jaffe_anger_chin_groove_spans_the_mouth_as_real_ones():
    """The real groove under an angry pout runs across the lower lip's width, following the
    chin boss's round top (JAFFE's anger photos: :func:`_chin_groove`'s dip on four profiles
    0.16 and 0.24 IOD either side of the middle, their median: 0.124 real, 0.04-0.06 on the
    neutral photos). The groove drawn over 0.34 of the mouth's width either side, ends 0.05
    IOD up, measured 0.084 there at 100 % (0.68 x real; 0.079 at 150 %): a short dash under
    the lip's middle that raters read as a smudge. Over 0.5 of the width, its ends 0.08 IOD up
    and softer (sigma 0.022, depth 0.34): 0.148 (1.19 x; 0.176 at 150 %, real p90 0.214), the
    middle (:func:`test_jaffe_anger_chin_groove_as_deep_as_real_ones`) 0.187 for the real
    0.178. Within 0.8-1.3 x the real median at 100 %, no deeper than the real p90 at 150 %."""
    import cv2

    def sides(f: Face, img: np.ndarray, v: np.ndarray) -> list[float]:
        L = _lum(img).astype(np.float32)
        a = v[f.mesh.fdp["8.2"]].astype(np.float64)
        b = v[f.mesh.fdp["2.1"]].astype(np.float64)
        t = np.linspace(0.05, 0.85, 33)
        dips = []
        for dx in np.array([-0.24, -0.16, 0.16, 0.24]) * f.interocular:
            q = (a + t[:, None] * (b - a) + [dx, 0.0]).astype(np.float32)
            p = cv2.remap(L, q[None, :, 0], q[None, :, 1], cv2.INTER_LINEAR)[0]
            dips.append(max(min(p[:i].max(), p[i:].max()) - p[i] for i in range(4, len(p) - 4)))
        return [float(np.median(dips)) / max(float(np.median(L)), 1.0)]

    real, ours, strong = _real_and_rendered("anger", "AN", sides, (1.0, 1.5))
    assert np.median(real) == pytest.approx(0.124, abs=0.02)  # (the measure itself)
    assert 0.8 * np.median(real) <= np.median(ours) <= 1.3 * np.median(real), np.median(ours)
    assert np.median(strong) <= np.percentile(real, 90), np.median(strong)


@pytest.mark.parametrize("up", [0.05, 0.3])
def test_a_photo_cut_through_the_forehead_renders_every_preset(up):
    """A tight headshot: the photo's top edge runs through the forehead, so the forehead
    lines' canvases are clipped by it and some of their points' corners fall above the photo.
    Those corners are dropped; they used to reach ``np.bincount`` as negative indices and every
    preset with forehead lines (surprise, fear, sadness) raised a ValueError."""
    from editor.formats.presets import apply_preset

    img = load_image(SAMPLE)
    f0 = Face.from_image(img, own_expression=False)
    y0 = int(f0.landmarks.points[17:27, 1].min() - up * f0.interocular)
    face = Face.from_image(np.ascontiguousarray(img[y0:]))
    for e in ("surprise", "fear", "sadness", "anger"):
        out = face.render(apply_preset(e, 1.5))
        assert out.shape == face.image.shape
    lines = [s for k, _p, s in fold_lines(face, face.deform(apply_preset("surprise", 1.5)))
             if k == "forehead"]
    assert lines and max(float(s.max()) for s in lines) > 0.05  # the lines are drawn


def _lid_strength(face, emotion: str, k: float = 1.0) -> float:
    vec = face.fap_vector(apply_preset(emotion, k))
    return max(float(s.max()) for kk, _, s in fold_lines(face, face.deform(vec))
               if kk == "lower_lid")


def test_a_raised_cheek_rolls_the_skin_under_the_lower_lids(sample_neutral):
    """The cheek raiser pushes the skin under the eye up against the lid: a furrow (joy,
    disgust's raised cheeks), none where the lids open and the skin goes down (surprise),
    and it grows with the push."""
    f = sample_neutral
    assert _lid_strength(f, "joy") > 0.04
    assert _lid_strength(f, "joy", 1.5) > _lid_strength(f, "joy")
    assert _lid_strength(f, "surprise") == 0.0
    assert _lid_strength(f, "surprise", 1.5) == 0.0
    for kk, _, s in fold_lines(f, f.deform(None)):
        assert float(s.max()) == 0.0, kk


def _under_lid_profile(img: np.ndarray) -> np.ndarray:
    """Luminance under the lower lids (the iris column +-0.08 IOD) at 0.04-0.12 IOD below the
    detected lid, over the cheek 0.22-0.30 IOD below it, both eyes averaged."""
    import cv2

    from editor.engine.landmarks import detect_landmarks

    p = detect_landmarks(img).points.astype(np.float64)
    Y = cv2.GaussianBlur(cv2.cvtColor(img, cv2.COLOR_RGB2GRAY).astype(np.float32), (0, 0), 0.7)
    iod = np.linalg.norm(p[36:42].mean(0) - p[42:48].mean(0))
    out = []
    for lo in ((41, 40), (47, 46)):
        x, y = 0.5 * (p[lo[0]] + p[lo[1]])
        xs = np.arange(int(x - 0.08 * iod), int(x + 0.08 * iod) + 1)
        row = [float(Y[int(round(y + d * iod)), xs].mean())
               for d in (0.04, 0.06, 0.08, 0.10, 0.12, 0.22, 0.24, 0.26, 0.28, 0.30)]
        out.append(np.array(row[:5]) / np.median(row[5:]))
    return np.mean(out, 0)


@pytest.mark.skipif(not jaffe_images("*.NE1.*"), reason="needs ../shared/data/jaffe")
def test_jaffe_smiles_furrow_under_the_lower_lids_as_real_ones():
    """JAFFE's ten women, the profile under the lower lids at 0.04-0.12 IOD (over the cheek
    below): real smiles 0.73 0.75 0.73 0.77 0.82 (a roll, then a furrow), their neutral photos
    0.65 0.74 0.78 0.81 0.86; the renders of joy 0.74 0.74 0.74 0.76 0.81, without the fold
    0.73 0.75 0.78 0.84 0.88 (the smooth rise of a face whose eyes do not smile)."""
    from editor.formats.presets import apply_preset as real_preset

    real = np.array([0.73, 0.75, 0.73, 0.77, 0.82])
    on, off = [], []
    for path in jaffe_images("*.NE1.*"):
        f = Face.from_image(path, own_expression=False)
        vec = real_preset("joy", 1.0)
        on.append(_under_lid_profile(f.render(vec)))
        off.append(_under_lid_profile(f.render(vec, creases=False)))
    on_m, off_m = np.median(on, 0), np.median(off, 0)
    assert np.abs(on_m - real).max() < 0.04, np.round(on_m, 3)
    assert off_m[2:].mean() - on_m[2:].mean() > 0.015, (np.round(on_m, 3), np.round(off_m, 3))


def test_smile_fold_is_shaded_on_the_nose_side_with_no_light_edge(sample_neutral):
    """Across a real smile's nasolabial fold (JAFFE, 31 photos) the nose side stays in shadow and
    the cheek side has no highlight. On the sample declared neutral, joy at 100 %, the creases'
    change across the fold's upper middle (median of the profiles at 0.3-0.5 of the line, grey
    levels against the render without creases): the cheek side 0.035-0.1 IOD out not lighter
    (the light ridge beside the line lifted it by 17: a scratch with a bright edge; now 0), the
    nose side 0.03-0.07 IOD in darkened by more than 10 (7.5 before; now 15)."""
    import cv2

    from editor.formats.presets import apply_preset as shipped

    f = sample_neutral
    vec = shipped("joy", 1.0)
    v = f.deform(vec)
    d = _lum(f.render(vec)).astype(np.float32) - _lum(f.render(vec, creases=False))
    u = np.linspace(-0.12, 0.12, 49)
    ex = f.frame.rot[:, 0]
    profiles = []
    for kind, pts, _s in fold_lines(f, v):
        if kind != "nasolabial":
            continue
        tang = np.gradient(pts, axis=0)
        for i in range(int(0.3 * len(pts)), int(0.5 * len(pts)) + 1):
            t = tang[i] / np.linalg.norm(tang[i])
            n = np.array([-t[1], t[0]])
            if ((pts[i] - f.frame.origin) @ ex) * (n @ ex) < 0:
                n = -n  # away from the face's midline: towards the cheek
            q = (pts[i] + u[:, None] * f.interocular * n).astype(np.float32)
            profiles.append(cv2.remap(d, q[None, :, 0], q[None, :, 1], cv2.INTER_LINEAR)[0])
    p = np.median(profiles, 0)
    assert p[(u > 0.035) & (u < 0.1)].max() <= 2.0, np.round(p, 1)
    assert p[(u < -0.03) & (u > -0.07)].mean() < -10.0, np.round(p, 1)


def test_jaffe_anger_furrow_beside_the_nose_no_deeper_than_real():
    """JAFFE anger's mouth rises (the chin pushes it up) and compresses the skin under the nose
    wing nearly as much as disgust's lip raise; real anger photos deepen the furrow there far
    less (0.108 against 0.168, :func:`_valley` over the image median, two photos per woman).
    The renders at 100 %: anger at most 1.1 x its real depth (1.24 x before, as deep as the
    renders of disgust at 0.90 x: the two read alike), disgust at least 0.95 x its own (0.98
    and 1.01 with the furrow drawn from the lip's rise; now, from the cheek's, 0.73 and
    1.07)."""
    def ratio(emotion: str, code: str) -> float:
        real, ours = _real_and_rendered(
            emotion, code, lambda f, img, v: _fold_depths(f, img, v, "upper_lip"), (1.0,))
        return float(np.median(ours) / np.median(real))

    assert ratio("anger", "AN") <= 1.1
    assert ratio("disgust", "DI") >= 0.95


def _fold_depths(f, img, v, kind: str) -> list[float]:
    """The depths of the ``kind`` folds across the middle of their lines (:func:`_valley`, the
    kind's window) over the image's median luminance."""
    lum = _lum(img)
    return [_valley(lum, pts, f.interocular, *_WINDOWS[kind])[0] / max(float(np.median(lum)), 1.0)
            for k, pts, _s in fold_lines(f, v) if k == kind]


def _fine_lines(img: np.ndarray, box: tuple[float, float, float, float]) -> float:
    """Dark fine-line energy of a face region: the black top-hat (a closing of 0.1 IOD less
    the image, over the closing) averaged over ``box`` (x0, x1, y0, y1 in IOD from the eyes'
    middle, y down), on re-detected landmarks."""
    import cv2


    L = cv2.GaussianBlur(_lum(img).astype(np.float32), (0, 0), 0.6)
    frame = eye_frame(img)
    k = max(3, int(round(0.10 * frame[3])) | 1)
    clo = cv2.morphologyEx(L, cv2.MORPH_CLOSE,
                           cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k)))
    th = (clo - L) / np.maximum(clo, 1)
    return float(frame_sample(th, frame, np.arange(box[0], box[1], 0.008),
                              np.arange(box[2], box[3], 0.008)).mean())


@pytest.mark.skipif(not jaffe_images("*.NE1.*"), reason="needs ../shared/data/jaffe")
@pytest.mark.parametrize(("emotion", "code"), [("fear", "FE"), ("sadness", "SA")])
def test_jaffe_glabellar_lines_of_raised_knitted_brows_as_real_ones(emotion, code):
    """JAFFE's ten women: the fine lines between the brows (:func:`_fine_lines`, x +-0.22 IOD,
    0.08-0.5 IOD above the eyes; each photo less her neutral one). Fear and sadness raise the
    inner brows while drawing them together (AU1 + 4); the real photos' lines are the deepest
    of the six expressions (x 1000: fear 7.5, sadness 6.2; anger 2.6), the landmarks barely
    move. Drawn from the mesh's compression alone: fear 1.9, sadness 3.2; with the brow
    effort (creases._brow_effort) 3.8 and 5.8 (sharp renders). At 100 % at least 45 % of the
    real median; at 150 % no more than the real p90."""
    box = (-0.22, 0.22, -0.50, -0.08)
    real, ours, strong = jaffe_changes(lambda img: _fine_lines(img, box), code, emotion)
    assert np.median(ours) >= 0.45 * np.median(real), (np.median(ours), np.median(real))
    assert np.median(strong) <= np.percentile(real, 90), (np.median(strong),
                                                          np.percentile(real, 90))


def _glabella_light(img: np.ndarray) -> float:
    """The glabella's light between and beside the brow heads: the mean of the luminance
    (blurred 0.015 IOD) over x +-0.16 IOD, 0.15-0.3 IOD above the eyes' middle, over the
    image's median, on re-detected landmarks."""
    import cv2


    frame = eye_frame(img)
    L = _lum(img).astype(np.float32)
    med = float(np.median(L))
    L = cv2.GaussianBlur(L, (0, 0), 0.015 * frame[3])
    return float(frame_sample(L, frame, np.linspace(-0.16, 0.16, 5),
                              np.linspace(-0.3, -0.15, 4)).mean()) / max(med, 1.0)


@pytest.mark.skipif(not jaffe_images("*.NE1.*"), reason="needs ../shared/data/jaffe")
def test_jaffe_knitted_brows_shade_the_glabella_as_real_ones():
    """JAFFE's lowered, knitted brows (AU4) shade the skin between and beside the brow heads
    (:func:`_glabella_light`, each photo less her neutral one): anger -0.086 (median, p10
    -0.18), disgust -0.11, sadness -0.05, fear -0.04. The warp alone brightened it (anger
    +0.020: the forehead's lighter skin slides down; disgust -0.020) and the two furrows are
    too thin to shade it: a frown that raters called relaxed brows. With the knitted brows'
    shade (kind "knit"): anger -0.063 (150 %: -0.078), disgust -0.098; fear and sadness keep
    -0.030 and -0.036 (their inner brows are raised: no knit). At 100 % anger within 0.6-1.3 x
    the real change, at 150 % no darker than the real p10; disgust no darker than its real
    median."""
    real, ours, strong = jaffe_changes(_glabella_light, "AN", "anger")
    want = float(np.median(real))
    assert want < -0.02  # (the measure itself: real angry glabellas darken)
    assert 1.3 * want <= float(np.median(ours)) <= 0.6 * want, (np.median(ours), want)
    assert float(np.median(strong)) >= float(np.percentile(real, 10)), np.median(strong)
    real_d, ours_d, _ = jaffe_changes(_glabella_light, "DI", "disgust")
    assert float(np.median(ours_d)) >= float(np.median(real_d)), (np.median(ours_d),
                                                                   np.median(real_d))


def test_knit_only_for_lowered_brows(sample_neutral):
    """The knitted brows' shade (kind "knit") is drawn for anger's and disgust's lowered
    brows, not for fear's and sadness's raised inner brows, surprise or the neutral face."""
    from editor.formats.presets import apply_preset as shipped

    f = sample_neutral

    def knit(vec) -> float:
        return max(float(s.max()) for k, _p, s in fold_lines(f, f.deform(vec)) if k == "knit")
    assert knit(shipped("anger")) > 0.03 and knit(shipped("disgust")) > 0.03
    for name in ("fear", "sadness", "surprise"):
        assert knit(shipped(name)) < _MIN_STRENGTH, name
    assert knit(np.zeros(68, np.float32)) < _MIN_STRENGTH


def test_brow_effort_only_for_raised_knitted_brows_not_a_turned_head(sample_neutral):
    """The brow effort (AU1 + 4) is there for fear and sadness, not for surprise's raised
    brows without closing-in, anger's and disgust's lowered ones, the neutral face, nor a
    turned, nodded and tilted head (FAPs 48-50, whose foreshortening brings the brows closer
    in the image) with raised brows."""
    from editor.bench import EXPRESSION
    from editor.bench_render import HEAD_ROTATION
    from editor.engine.creases import _brow_effort, _fast
    from editor.engine.faps import FAPS
    from editor.formats.presets import apply_preset as shipped

    f = sample_neutral
    fa = _fast(f)

    def effort(vec) -> float:
        return _brow_effort(fa, f.deform(vec)[: f.plan.n_vertices])
    for name in ("fear", "sadness"):
        assert 0.2 < effort(shipped(name)) < effort(shipped(name, 1.5)) <= 1.0, name
    for name in ("surprise", "anger", "disgust", "joy"):
        assert effort(shipped(name)) == 0.0, name
    assert effort(np.zeros(68, np.float32)) == 0.0
    for vec in ({**EXPRESSION, **HEAD_ROTATION}, HEAD_ROTATION):
        assert effort(FAPS.clamp(FAPS.vector(vec))) == 0.0


@pytest.mark.skipif(not jaffe_images("*.NE1.*"), reason="needs ../shared/data/jaffe")
@pytest.mark.parametrize(("emotion", "code"), [("fear", "FE"), ("sadness", "SA")])
def test_jaffe_central_forehead_lines_of_raised_knitted_brows_as_real_ones(emotion, code):
    """JAFFE's ten women: the short horizontal lines of the central forehead that the inner
    brow raiser (AU1) folds in fear and sadness (:func:`_fine_lines`, x +-0.3 IOD, 0.55-0.95
    IOD above the eyes; each photo less her neutral one; x 1000: real median fear 4.1,
    sadness 2.2). From the mesh's compression alone the presets drew 0.84 and 0.81 (a
    smooth forehead under raised inner brows); with the brow effort driving the lines'
    middle (STYLES["forehead"].effort, effort_mid) 2.9 and 2.3, fear 7.4 with its wide eyes
    (effort_lid; real p90 28.5). At 100 % at least half the real median; at 150 % the
    forehead's row profile (:func:`_forehead_dip`) no darker than the real p90 (fear 0.157,
    sadness 0.040; ours 0.073, 0.035)."""

    box = (-0.3, 0.3, -0.95, -0.55)
    real, ours, _ = jaffe_changes(lambda img: _fine_lines(img, box), code, emotion)
    assert np.median(ours) >= 0.5 * np.median(real), (np.median(ours), np.median(real))
    dips_real, (dips_strong,) = _forehead_dips(code, emotion, (1.5,))
    assert np.median(dips_strong) <= np.percentile(dips_real, 90), (np.median(dips_strong),
                                                                   np.percentile(dips_real, 90))


def _forehead_dips(code: str, emotion: str, scales: tuple[float, ...]
                   ) -> tuple[list[float], list[list[float]]]:
    """:func:`_forehead_dip` of every JAFFE photo of ``code`` (the real ones) and of the
    shipped preset ``emotion`` at each of ``scales`` on each woman's neutral photo."""
    real, *drawn = _real_and_rendered(emotion, code, lambda f, img, v: [_forehead_dip(img, f)],
                                      scales, per_woman=None)
    return real, drawn


def test_jaffe_fear_forehead_lines_as_dark_as_real_ones():
    """JAFFE's ten women: fear's forehead lines as dark as her own fear photos show (the row
    profile's dip, :func:`_forehead_dip`: real median 0.038, p90 0.157; sadness's 0.025).
    Fear folds the forehead across its width too (fine lines x +-0.7 IOD: real fear 7.5,
    sadness 1.7, x 1000 over the neutral photo), where the mesh barely compresses it (its
    outer brows stay down): the brow effort times the upper lids' raise (AU5,
    creases._add_lid_effort) drives the whole lines. Before: 0.028 at 100 % (0.020 from the
    mesh alone); now 0.040, 0.073 at 150 %."""
    real, (ours, strong) = _forehead_dips("FE", "fear", (1.0, 1.5))
    if len(ours) < 8:
        pytest.skip("../shared/data/jaffe is not available")
    assert np.median(ours) >= 0.8 * np.median(real), (np.median(ours), np.median(real))
    assert np.median(strong) <= np.percentile(real, 90), (np.median(strong),
                                                          np.percentile(real, 90))


def test_lid_effort_only_for_knitted_brows_over_wide_eyes(sample_neutral):
    """The forehead's lid effort (AU1 + 4 with the upper lids raised, AU5) is there for fear
    and grows with it; not for sadness (lowered lids), surprise (brows that do not close in),
    anger, disgust, joy nor the neutral face."""
    from editor.engine.creases import STYLES, _add_lid_effort, _fast
    from editor.formats.presets import apply_preset as shipped

    f = sample_neutral
    fa = _fast(f)
    assert len(fa.lid_idx) and STYLES["forehead"].effort_lid > 0

    def added(vec) -> float:
        c = np.zeros(len(fa.depth))
        _add_lid_effort(fa, c, f.deform(vec)[: f.plan.n_vertices])
        return float(c.max())
    assert 0.0 < added(shipped("fear")) < added(shipped("fear", 1.5))
    for name in ("sadness", "surprise", "anger", "disgust", "joy"):
        assert added(shipped(name)) == 0.0, name
    assert added(np.zeros(68, np.float32)) == 0.0
