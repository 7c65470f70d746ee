"""The photo's own expression (issue 21 item 1): estimated, neutralised, exact at f0."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import JAFFE, SAMPLE, jaffe_images

from editor.core import Face, signed_areas
from editor.engine.own_expression import canonical, default_prior, estimate_own, symmetrize
from editor.formats.presets import apply_preset


def test_sample_smile_is_estimated_and_neutralised(sample_face):
    f = sample_face
    assert f.has_expression
    assert "smile" in f.expression_words and ("lips apart" in f.expression_words
                                              or "mouth open" in f.expression_words)
    e = f.expression
    assert e[2] > 100  # open_jaw: the lips are apart in the photo
    assert e[11] > 60 and e[12] > 60 and e[58] > 60 and e[59] > 60  # corners raised
    # the neutral mesh closes the lips: every inner-lip pair meets (or nearly)
    ey = f.frame.rot[:, 1]
    n = f.neutral_vertices
    up, lo = f.mesh.pairs[:, 0], f.mesh.pairs[:, 1]
    mouth = np.isin(up, f.mesh.holes["mouth"])
    gap = (n[lo[mouth]] - n[up[mouth]]) @ ey
    assert gap.min() >= 0 and gap.max() < 0.02 * f.interocular
    # and the photo's mouth is open
    p = f.vertices
    assert ((p[lo[mouth]] - p[up[mouth]]) @ ey).max() > 0.1 * f.interocular
    assert (signed_areas(n.astype(np.float64), f.triangles) > 0).all()


def test_untouched_expression_renders_the_photo_exactly(sample_face):
    assert np.array_equal(sample_face.render(sample_face.expression), sample_face.image)
    assert np.array_equal(sample_face.deform(sample_face.expression), sample_face.vertices)


def test_neutralise_then_own_estimate_gives_back_the_photo(sample_face):
    neutral = sample_face.render(None)
    assert np.abs(neutral.astype(int) - sample_face.image).max() > 40  # visibly neutralised
    back = sample_face.with_expression(None).with_own_expression()
    assert np.array_equal(back.expression, sample_face.expression)
    assert np.array_equal(back.render(back.expression), sample_face.image)


def test_presets_render_from_the_neutral_face(sample_face):
    """Anger on a smiling photo: the mouth corners go down from the neutral, not from the
    smile (the smile does not survive the preset)."""
    f = sample_face
    ey = f.frame.rot[:, 1]

    def corners_up(v: np.ndarray) -> float:
        """Mouth corners above the middle of the lips (face-frame y, pixels)."""
        mid = 0.5 * (v[f.fdp["8.1"]] + v[f.fdp["8.2"]]) @ ey
        return float(mid - 0.5 * (v[f.fdp["8.3"]] + v[f.fdp["8.4"]]) @ ey)

    photo, neutral = corners_up(f.vertices), corners_up(f.neutral_vertices)
    anger = corners_up(f.deform(apply_preset("anger")))
    assert photo - neutral > 0.03 * f.interocular  # the smile is taken out (part of it)
    assert anger < neutral + 0.02 * f.interocular  # anger adds no smile back
    kept = corners_up(f.deform(f.expression + apply_preset("anger")))
    assert kept > anger + 0.5 * (photo - neutral)  # --keep-expression keeps the smile


def test_a_smiles_neutral_mouth_is_no_narrower_than_real_smiles_imply(sample_face):
    """The sample smiles broadly; neutralised, her mouth (the mesh's outer corners) narrows by
    no more than real smiles widen one: JAFFE's 31 smiles widen the mouth 1.29 x (median), 1.43
    x at p90. The fit alone called most of her wide mouth smile: 1.44 x, lips blind raters
    called pinched (own_expression._smile_width); now 1.29 x."""
    f = sample_face
    n = f.mesh.names
    a, b = n.index("lipo_c0"), n.index("lipo_c1")

    def width(v: np.ndarray) -> float:
        return float(np.linalg.norm(v[a] - v[b]))

    ratio = width(f.vertices) / width(f.deform(None))
    assert 1.15 < ratio < 1.35, ratio


def test_neutral_photos_get_a_neutral_vector(jaffe_faces):
    """JAFFE neutral photos (detected, estimated against the prior) are mostly left alone."""
    moved = []
    for face in jaffe_faces:
        own = estimate_own(face)
        motion = face.deform(own.faps) - face.deform(None)
        moved.append(np.abs(motion).max() / face.interocular)
    assert np.median(moved) < 0.03, moved


def test_prior_is_symmetric_with_closed_lips():
    pr = default_prior()
    assert np.allclose(symmetrize(pr.mean), pr.mean, atol=1e-4)
    assert np.allclose(pr.mean[[61, 62, 63]], pr.mean[[67, 66, 65]])
    assert np.allclose(canonical(pr.mean)[[39, 42]], pr.mean[[39, 42]], atol=0.05)
    assert (pr.sigma > 0).all() and (pr.noise > 0).all()


@pytest.mark.slow
def test_jaffe_closed_loop_reproduces_real_expressions():
    """Estimate each real JAFFE expression against the woman's neutral, render on the neutral,
    re-detect: within 2.5 % of the inter-ocular distance on average, every region closer than
    doing nothing, and no estimated FAP of the closed loop's sign checks (jaw, upper lids, brows,
    mouth corners, lower lip) against the real motion of its feature point (the lip FAPs': relative
    to where the estimated jaw carries it)."""
    if len(jaffe_images("*.NE*.tiff")) < 10:
        pytest.skip("../shared/data/jaffe is not available")
    from editor.synthesis.closed_loop import SIGN_CHECKS, closed_loop

    # motion below 1.5 px is not sign-checked: re-detecting the same neutral photo shifted or
    # rescaled moves these points by 0.2 px RMS (0.9 px at most), see closed_loop's docstring
    res = closed_loop(JAFFE / "images", noise_px=1.5)
    # the issue's target (2.57 before: the brows' band moved the alignment point 27, and wide-open
    # mouths folded the chin against the margin ring, so the guard scaled whole renders down;
    # 2.45 since the estimator leaves 27 out and bounds open_jaw by what the mesh renders)
    assert res.mean("estimate", "inner") < 2.5, res.table()
    for region in ("brows", "lids", "lips", "jaw"):
        assert res.mean("estimate", region) < res.mean("nothing", region), res.table()
    for code in ("HA", "SA", "SU", "AN", "DI", "FE"):
        assert res.mean("estimate", "inner", code) < res.mean("nothing", "inner", code)
    # every check is exercised. Before the sign bounds one of 1303 was wrong (TM.HA1's inner
    # lower lip raised by the lip-pair prior); judged on absolute motion (the jaw's carriage not
    # taken out) 69 of 1031 looked wrong, all of them corners and lower lips of open mouths
    assert {s[2] for s in res.signs} == {c[0] for c in SIGN_CHECKS}
    assert len(res.signs) > 1000
    wrong = res.wrong_signs()
    assert not wrong, wrong


def test_cli_render_neutralises_unless_kept(cli, tmp_path):
    from editor.core import load_image

    run = ["render", str(SAMPLE)]
    kept = tmp_path / "kept.png"
    r = cli(*run, "--keep-expression", "-o", str(kept))
    assert r.returncode == 0 and "the photo shows: smile" in r.stderr
    assert np.array_equal(load_image(kept), load_image(SAMPLE))
    neutral = tmp_path / "neutral.png"
    r = cli(*run, "-o", str(neutral))
    assert r.returncode == 0
    assert np.abs(load_image(neutral).astype(int) - load_image(SAMPLE)).max() > 40
    plain = tmp_path / "plain.png"
    r = cli(*run, "--photo-is-neutral", "-o", str(plain))
    assert r.returncode == 0 and "photo shows" not in r.stderr
    assert np.array_equal(load_image(plain), load_image(SAMPLE))


@pytest.mark.gui
def test_editor_starts_at_the_photo_and_neutralizes_in_one_step(qtbot, sample_face, warnings):
    from editor.ui.main_window import MainWindow

    w = MainWindow()
    qtbot.addWidget(w)
    w.load_face(sample_face)
    m = w.model
    assert np.array_equal(m.doc.faps, sample_face.expression)
    assert "photo shows: smile" in w.expression_label.text()
    assert w.act_neutralize.isEnabled()
    n0 = m.undo_stack.count()
    w.act_neutralize.trigger()
    assert not m.doc.faps.any() and m.undo_stack.count() == n0 + 1
    w.act_photo_expression.trigger()
    assert np.array_equal(m.doc.faps, sample_face.expression)
    m.undo_stack.undo()
    assert not m.doc.faps.any()
    w.close_without_prompt()


def test_declared_neutral_photo_has_no_expression():
    f = Face.from_image(SAMPLE, own_expression=False)
    assert not f.has_expression and f.expression_words == "neutral"
    assert np.array_equal(f.neutral_vertices, f.vertices)
    assert np.array_equal(f.render(None), f.image)


@pytest.mark.gui
def test_declaring_the_photo_neutral_is_one_undoable_step_and_saved(qtbot, sample_face, warnings,
                                                                     tmp_path):
    from editor.formats.project import load_project
    from editor.ui.main_window import MainWindow

    w = MainWindow()
    qtbot.addWidget(w)
    w.docs.remember = False
    w.load_face(sample_face)
    m = w.model
    m.set_faps({"open_jaw": 600.0}, "open the jaw")  # an edit of the photo's expression
    edited = m.doc.faps.copy()
    n0 = m.undo_stack.count()
    w.act_photo_neutral.trigger()
    assert m.doc.photo_neutral and w.act_photo_neutral.isChecked()
    assert m.undo_stack.count() == n0 + 1
    assert w.expression_label.text() == "photo declared neutral"
    assert not w.act_neutralize.isEnabled()
    # the FAPs keep what they add to the photo: the photo's own estimate is subtracted
    from editor.core import FAPS

    np.testing.assert_allclose(m.doc.faps, FAPS.clamp(edited - sample_face.expression))
    assert m.doc.faps.any()
    assert not m.face.has_expression
    assert np.array_equal(m.face.render(np.zeros(68)), sample_face.image)
    path = tmp_path / "p.fapproj"
    assert w.docs.save_to(str(path))
    assert '"photo_is_neutral": true' in path.read_text()
    data = load_project(path, sample_face.mesh.names)
    assert data.photo_neutral and np.allclose(data.faps, m.doc.faps)
    m.undo_stack.undo()
    assert not m.doc.photo_neutral and not w.act_photo_neutral.isChecked()
    assert np.array_equal(m.doc.faps, edited)
    assert "photo shows: smile" in w.expression_label.text()
    w.close_without_prompt()


@pytest.mark.gui
def test_gui_opens_a_photo_declared_neutral(qtbot, warnings):
    from editor.ui.app import open_initial
    from editor.ui.main_window import MainWindow

    w = MainWindow()
    qtbot.addWidget(w)
    w.docs.remember = False
    assert open_initial(w, str(SAMPLE), photo_neutral=True)
    assert w.model.doc.photo_neutral and not w.model.doc.faps.any()
    assert w.act_photo_neutral.isChecked()
    assert np.array_equal(w.model.face.render(w.model.doc.faps), w.model.fitted.image)
    w.close_without_prompt()


def _corner_height(face, v: np.ndarray) -> float:
    """Mouth corners (8.3, 8.4) above the inner lip line (middle of 2.2 and 2.3), in IOD."""
    ey = face.frame.rot[:, 1]
    line = 0.5 * (v[face.fdp["2.2"]] + v[face.fdp["2.3"]]) @ ey
    return float(line - 0.5 * (v[face.fdp["8.3"]] + v[face.fdp["8.4"]]) @ ey) / face.interocular


def test_neutralised_sample_mouth_is_flat(sample_face):
    """The sample's open smile: corners 0.15 IOD above the lip line in the photo; the neutral
    (mesh and as rendered) has them within 0.03 IOD of it (a neutral mouth is close to flat:
    JAFFE neutrals -0.04..0.05), and no triangle folds."""
    f = sample_face
    assert _corner_height(f, f.vertices) > 0.12
    assert abs(_corner_height(f, f.neutral_vertices)) < 0.03
    assert abs(_corner_height(f, f.deform(None))) < 0.03
    assert (signed_areas(f.deform(None).astype(np.float64), f.triangles) > 0).all()


@pytest.mark.parametrize("name", ["sadness", "anger", "disgust"])
def test_presets_without_a_smile_do_not_smile_on_the_sample(sample_face, name):
    """Presets that do not raise the corners do not bring the photo's smile back: their corners
    stay at (or below) the neutral's, not the photo's."""
    f = sample_face
    # (disgust widens the mouth a little as the photo's smile does (FAPs 6/7/53/54 at 60, JAFFE's
    # disgust): 0.08 of it; the corners below stay down all the same)
    assert f.own_share(apply_preset(name)) < (0.1 if name == "disgust" else 0.05)
    h = _corner_height(f, f.deform(apply_preset(name)))
    assert h < _corner_height(f, f.deform(None)) + 0.005 and h < 0.03, h


def test_own_share_scales_the_photo_offset(sample_face):
    """The part of the photo's expression the FAP model does not render comes with the share
    of f0 a vector holds: all of it at f0 (the photo), none at 0, half way at f0 / 2."""
    f = sample_face
    f0 = f.expression
    assert f.own_share(f0) == 1.0 and f.own_share(np.zeros(68)) == 0.0
    assert abs(f.own_share(0.5 * f0) - 0.5) < 1e-6
    assert f.own_share(f0 + apply_preset("joy")) == 1.0  # clipped


def test_photo_lip_offset_follows_the_opening(sample_face):
    """The sample's FAP model opens its lips about as the photo (not exactly); the offset that
    makes f0 the photo must not close a smaller opening: half of f0 opens half the photo's
    gaps, joy opens every middle pair, p/b/m closes them, f0 is the photo."""
    f = sample_face

    def gaps(v):
        return _inner_lip_gaps(f, v)

    photo = gaps(f.vertices)
    assert np.abs(gaps(f.deform(f.expression)) - photo).max() < 1e-3
    np.testing.assert_allclose(gaps(f.deform(0.5 * f.expression)), 0.5 * photo, atol=0.15)
    assert (gaps(f.deform(apply_preset("joy")))[1:-1] > 0.02 * f.interocular).all()
    assert np.abs(gaps(f.deform(apply_preset("viseme_pbm")))).max() < 1e-3


def test_neutralising_moves_only_what_faps_move(sample_face):
    """The neutral mesh differs from the photo's only where FAPs act: the margin and the image
    border stay, so a frame re-warps the face region, not the whole photo."""
    f = sample_face
    V = f.plan.n_vertices
    moved = np.abs(f.deform(None) - f.vertices).max(1) > 1e-4
    still = ~np.abs(f.plan.basis[:, :V]).any(axis=(0, 2))
    assert still.any() and not moved[still].any()
    assert not moved[f.mesh.regions == "margin"].any()


def test_photo_lip_offset_scales_with_the_rendered_opening(sample_face):
    """A vector opens each inner-lip pair by its FAP model's gap (as deform renders it, the
    inner/outer lip pairs' shared part moved once) times the photo's gap over the model's at
    f0 (main before: joy's share was taken from the basis without that correction, 1.73 px in
    the middle where this gives 1.88, and the corner pairs lost more to the fold guard)."""
    from editor.engine.deform import deform_points

    f = sample_face

    def gaps(v):
        return _inner_lip_gaps(f, v)

    photo, model0 = gaps(f.vertices), gaps(deform_points(f.plan, f.expression))
    assert (model0 > 1e-3).all()  # the model opens every pair at f0 (as the photo)
    for k in (1.0, 1.5):
        joy = f.fap_vector(apply_preset("joy", k))
        model = gaps(deform_points(f.plan, joy))
        # beyond f0's opening the photo's whole offset comes with it (the share is clipped at 1)
        want = np.where(model < model0, model * photo / model0, model + photo - model0)
        np.testing.assert_allclose(gaps(f.deform(joy)), want, atol=0.03)


def test_photo_offset_folds_no_smile_corner(sample_face):
    """The offset must not turn the sliver triangles at the mouth corners inside out for a
    vector that opens them less than f0 (main before: joy folded both, the guard then took
    2-6 px of the corners' rise away, unevenly left and right)."""
    from editor.engine.deform import deform_points

    f = sample_face
    joy = f.fap_vector(apply_preset("joy"))
    got = f.deform(joy).astype(np.float64)
    lin = deform_points(f.plan, joy).astype(np.float64) + f.own_share(joy) * f._offset
    for n in ("lipi_c0", "lipo_c0", "lipi_c1", "lipo_c1"):
        i = f.mesh.index(n)
        assert np.abs(got[i] - lin[i]).max() < 0.5, (n, got[i] - lin[i])
    s0 = np.sign(signed_areas(f.neutral_vertices.astype(np.float64), f.triangles))
    assert (np.sign(signed_areas(got[: len(f.vertices)], f.triangles)) == s0).all()


def test_sample_own_expression_opens_the_lips_as_the_photo(sample_face):
    """The FAP model opens each inner-lip pair at f0 as the photo shows it (within 1 px), so the
    photo's offset does not pinch the sides of other openings (main before: the estimate fitted
    dlib's inner-lip points, 6-7 px apart where the mesh's lips, snapped to the lip/teeth edge,
    are 3.6-4.8: f0 opened the side pairs to 6.5-8.1 px and the offset scaled every vector's
    side opening by 0.45-0.55; joy showed teeth only across the middle third)."""
    from editor.engine.deform import deform_points

    f = sample_face

    def gaps(v):
        return _inner_lip_gaps(f, v)

    photo = gaps(f.vertices)
    assert np.abs(gaps(deform_points(f.plan, f.expression)) - photo).max() < 1.0
    for name, side in (("joy", 0.55), ("surprise", 0.65), ("viseme_aa", 0.65)):
        g = gaps(f.deform(apply_preset(name)))[1:-1]  # the corner pairs close by design
        assert g.min() > side * g.max(), (name, g.round(2))


def _inner_lip_gaps(face, v: np.ndarray) -> np.ndarray:
    """Gap (px, along the face's vertical) of each inner-lip vertex pair of the mesh ``v``."""
    ey = face.frame.rot[:, 1]
    pairs = [(u, lo) for u, lo in face.mesh.pairs if face.mesh.names[u].startswith("lipi")]
    return np.array([(v[lo] - v[u]) @ ey for u, lo in pairs])


def test_a_smiles_narrowed_eyes_open_when_neutralised(sample_face):
    """The sample smiles: its own expression holds the smile's narrowed eyes (the joy preset's
    lids, scaled by the smile), so the neutralised face opens them."""
    e = sample_face.expression
    assert e[20] > 30 and e[21] > 30  # close_b_l/r_eyelid: the lower lids pushed up
    assert e[18] > 30 and e[19] > 30  # close_t_l/r_eyelid: the upper lids a little down
    ey = sample_face.frame.rot[:, 1]
    m = sample_face.mesh
    for s in "lr":
        up, lo = m.index(f"eye_{s}_u3"), m.index(f"eye_{s}_d3")
        photo = (sample_face.vertices[lo] - sample_face.vertices[up]) @ ey
        neutral = (sample_face.neutral_vertices[lo] - sample_face.neutral_vertices[up]) @ ey
        assert neutral > photo + 0.01 * sample_face.interocular


@pytest.mark.skipif(not JAFFE.exists(), reason="needs ../shared/data/jaffe")
def test_neutralised_smiles_have_the_womens_neutral_eyes():
    """JAFFE's 31 smiling photos, neutralised: their lids (mesh points 3.1-3.4 against the eye
    corners) come closer to the same women's neutral photos than the smiles' own lids (without
    the smile's lids in the estimate they stayed as far: 0.0127 / 0.0115 IOD against the
    photos' 0.0119 / 0.0107; now 0.0108 / 0.0092)."""
    def lids(face: Face, V: np.ndarray) -> np.ndarray:
        m, ey = face.mesh, face.frame.rot[:, 1]
        c = [0.5 * (V[m.index(f"eye_{s}_c0")] + V[m.index(f"eye_{s}_c1")]) for s in "lr"]
        return np.array([[(V[m.index(f"eye_{s}_{k}3")] - c[i]) @ ey for k in "ud"]
                         for i, s in enumerate("lr")]) / face.interocular

    photo_err, neutral_err = [], []
    for who in sorted({p.name[:2] for p in jaffe_images("*.NE*.tiff")}):
        ref = np.mean([lids(g, g.vertices) for g in (Face.from_image(p, own_expression=False)
                                                     for p in jaffe_images(f"{who}.NE*.tiff"))],
                      0)
        for p in jaffe_images(f"{who}.HA*.tiff"):
            f = Face.from_image(p)
            photo_err.append(np.abs(lids(f, f.vertices) - ref))
            neutral_err.append(np.abs(lids(f, f.neutral_vertices) - ref))
    ph, ne = np.mean(photo_err, 0), np.mean(neutral_err, 0)  # (eye, upper/lower)
    assert len(photo_err) >= 30
    assert ne[:, 0].mean() < ph[:, 0].mean()  # upper lids
    assert ne[:, 1].mean() < 0.9 * ph[:, 1].mean()  # lower lids


def test_words_call_only_rising_corners_a_smile():
    """``"smile"`` needs the mouth corners to rise, not only to stand above the lip line's
    middle: a dropped jaw (lower lip down, corners a little down) is an open mouth, a smile
    is corners up (main called both a smile: rise against the inner lips' mean)."""
    from editor.engine.own_expression import _words

    rot, iod, t = np.eye(2), 100.0, 0.02
    jaw = np.zeros((68, 2))
    jaw[[48, 54], 1] = 3.0  # corners 0.03 IOD down
    jaw[[65, 66, 67], 1] = 15.0  # inner lower lip 0.15 down
    jaw[[56, 57, 58], 1] = 15.0
    words = _words(jaw, rot, iod, t)
    assert "smile" not in words and "mouth open" in words
    smile = np.zeros((68, 2))
    smile[[48, 54], 1] = -6.0  # corners 0.06 IOD up
    smile[48, 0], smile[54, 0] = -3.0, 3.0
    smile[[65, 66, 67], 1] = 5.0
    assert "smile" in _words(smile, rot, iod, t)


@pytest.mark.skipif(not JAFFE.exists(), reason="needs ../shared/data/jaffe")
def test_words_tell_a_smile_from_an_open_mouth_on_real_photos():
    """On JAFFE's real photos the words say "smile" for most smiles and almost never for
    surprise, fear or disgust (main: 24 of 31 smiles, but also 37 of the 91 others: a
    surprised open mouth read "smile, mouth open")."""
    from editor.engine.imageio import load_image

    said = {}
    for code in ("HA", "SU", "FE", "DI"):
        paths = jaffe_images(f"*.{code}1.*.tiff")  # (each woman's first)
        said[code] = sum("smile" in Face.from_image(load_image(p)).expression_words
                         for p in paths) / len(paths)
    assert said["HA"] >= 0.65, said
    assert max(said["SU"], said["FE"], said["DI"]) <= 0.1, said


def _seen_corner_height(img: np.ndarray) -> float:
    """The mouth corners' height above the inner lips' middle as a landmark detector sees them
    on an image (re-detected; along the eyes' perpendicular, IOD)."""
    from editor.engine.landmarks import detect_landmarks

    p = detect_landmarks(img).points.astype(np.float64)
    a, b = p[36:42].mean(0), p[42:48].mean(0)
    ex = (b - a) / np.linalg.norm(b - a)
    ey = np.array([-ex[1], ex[0]])
    y = p @ ey
    return float(0.5 * (y[62] + y[66]) - 0.5 * (y[48] + y[54])) / float(np.linalg.norm(b - a))


def test_neutralised_sample_mouth_does_not_smile_as_seen(sample_face):
    """The sample's neutral mouth, as a detector sees it on the render: its corners 0.028 IOD
    above the lip line before the smile's corners were completed (JAFFE's neutral photos: 0.006,
    p10..p90 -0.034..0.055), and blind raters named anger and fear on it joy; now 0.013."""
    assert _seen_corner_height(sample_face.render(None)) < 0.02


@pytest.mark.skipif(not JAFFE.exists(), reason="needs ../shared/data/jaffe")
def test_neutralised_smiles_have_the_womens_neutral_mouth_corners():
    """JAFFE's open smiles (lips apart) neutralised: their corners over the lip line as seen
    (re-detected) against the same women's own neutral photos. Median of the differences
    +0.018 IOD before the smile's corners were completed (own_expression.CORNER_LAG), +0.005
    now."""
    from editor.engine.imageio import load_image
    from editor.engine.landmarks import detect_landmarks

    diffs = []
    for who in sorted({p.name[:2] for p in jaffe_images("*.NE*.tiff")}):
        ref = np.mean([_seen_corner_height(load_image(p))
                       for p in jaffe_images(f"{who}.NE*.tiff")])
        for p in jaffe_images(f"{who}.HA*.tiff"):
            img = load_image(p)
            q = detect_landmarks(img).points
            if (q[66, 1] - q[62, 1]) / np.linalg.norm(q[36:42].mean(0) - q[42:48].mean(0)) < 0.05:
                continue
            diffs.append(_seen_corner_height(Face.from_image(p).render(None)) - ref)
    assert len(diffs) >= 15
    assert abs(float(np.median(diffs))) < 0.008, np.median(diffs)
