"""The photo route of the bilinear model: dlib-68 training, synthesis on a Face, CLI synth."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from editor.cli import main
from editor.core import Face, load_image
from editor.engine.mesh import signed_areas
from editor.errors import ModelError
from editor.resources import SAMPLE_FACE, checkout_jaffe_dir
from editor.synthesis.bilinear import BilinearModel, load_model, save_model
from editor.synthesis.bilinear_photo import (
    EXPRESSIONS68,
    check_model68,
    detect_training_set,
    expression_alpha,
    faps_for_points,
    mesh_for_points,
    neutral_points68,
    parse_mix,
    synthesize_on_face,
    synthesize_points68,
    synthetic_model68,
    train_model68,
)
from editor.synthesis.landmark_scheme import DLIB68

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = SAMPLE_FACE
JAFFE_IMAGES = checkout_jaffe_dir() / "images"
METHODS = ("plain", "ridge", "mals")


@pytest.fixture(scope="module")
def toy_model(sample_face) -> BilinearModel:
    # the toy people are neutral faces, like the face synthesis starts from: built on the
    # smiling, open-mouthed photo's own points the model took the photo's opening for neutral,
    # and the lower lip's 0.45 inner-eye surprise field came out at 3.5 px of 11 (dlib) or
    # 1.5 px (MediaPipe, whose inner lips sit on the opening); from the neutralised points it
    # is 11.0 px with both detectors
    return synthetic_model68(neutral_points68(sample_face))


@pytest.fixture(scope="module")
def jaffe_model(tmp_path_factory) -> BilinearModel:
    if not JAFFE_IMAGES.is_dir():
        pytest.skip("../shared/data/jaffe is not available")
    people = ("KA", "KL", "KM", "KR", "MK", "NA")
    cache = tmp_path_factory.mktemp("dlib68_cache")
    data = detect_training_set(JAFFE_IMAGES, people, per_expression=2, cache_dir=cache)
    assert set(data.people) == set(people) and data.points.shape[1:] == (68, 2)
    again = detect_training_set(JAFFE_IMAGES, people, per_expression=2, cache_dir=cache)
    np.testing.assert_array_equal(again.points, data.points)  # from the cache
    return train_model68(data)


def _mouth_gap(p: np.ndarray) -> float:
    return float(p[[65, 66, 67], 1].mean() - p[[61, 62, 63], 1].mean())


def _check_result(face, res) -> None:
    V = len(face.vertices)
    assert res.vertices.shape == (V, 2) and res.points68.shape == (68, 2)
    area = signed_areas(res.vertices.astype(np.float64), face.triangles)
    assert (area > 0).all(), "folded triangles"
    np.testing.assert_allclose(res.points68[list(DLIB68.contour)],
                               neutral_points68(face)[list(DLIB68.contour)], atol=1e-4)
    border = face.mesh.regions == "border"
    np.testing.assert_allclose(res.vertices[border], face.vertices[border], atol=1e-4)


@pytest.mark.parametrize("method", METHODS)
def test_toy_model_synthesis_on_sample(sample_face, toy_model, method):
    face = sample_face
    mouth = [face.mesh.regions == r for r in ("mouth",)][0]
    neutral = face.landmarks.points.astype(np.float64)
    for expr in ("joy", "surprise"):
        res = synthesize_on_face(face, toy_model, expr, method)
        _check_result(face, res)
        moved = np.linalg.norm(res.vertices[mouth] - face.vertices[mouth], axis=1)
        assert moved.max() > 0.02 * face.interocular, f"{expr}: mouth did not move"
    if method == "plain":
        # plain ALS fits the photo exactly with an exploded identity vector (I·J ≥ K): the
        # direction of the synthesized motion is not reliable off the training set
        return
    neu, joy, sur = (synthesize_points68(toy_model, neutral, e, method)
                     for e in ("neutral", "joy", "surprise"))
    assert joy[[48, 54], 1].mean() < neu[[48, 54], 1].mean() - 0.03 * face.interocular
    assert _mouth_gap(sur) > _mouth_gap(neu) + 0.1 * face.interocular
    assert sur[17:27, 1].mean() < neu[17:27, 1].mean()  # brows up


def test_synthesis_starts_from_the_neutralised_photo(sample_face, toy_model):
    """The sample smiles with its mouth open: synthesis starts from its neutralised face."""
    face = sample_face
    assert face.has_expression
    neutral = face.deform(None)
    base = neutral_points68(face)
    # the landmarks follow the mesh to the neutral face: the open mouth closes
    assert _mouth_gap(base) < 0.5 * _mouth_gap(face.landmarks.points)
    # no landmark motion = the neutralised face (not the photo with its smile)
    v = mesh_for_points(face, base)
    assert np.abs(v - neutral).max() < 0.05
    assert np.abs(face.vertices - neutral).max() > 0.05 * face.interocular
    res = synthesize_on_face(face, toy_model, "anger", "ridge")
    _check_result(face, res)
    np.testing.assert_allclose(res.points68, synthesize_points68(toy_model, base, "anger",
                                                                 "ridge"), atol=1e-4)
    # the document's FAPs of the synthesized shape are relative to the neutralised face
    assert np.abs(faps_for_points(face, base)).max() < 20


def test_mix_and_residual_options(sample_face, toy_model):
    p = sample_face.landmarks.points
    half = synthesize_points68(toy_model, p, {"joy": 0.5, "surprise": 0.5}, "ridge", 0.01)
    joy = synthesize_points68(toy_model, p, "joy", "ridge", 0.01)
    sur = synthesize_points68(toy_model, p, "surprise", "ridge", 0.01)
    np.testing.assert_allclose(half, 0.5 * (joy + sur), atol=1e-6)  # linear in α (same b)
    kept = synthesize_points68(toy_model, p, "joy", "mals", keep_residual=True)
    assert np.isfinite(kept).all()
    res = synthesize_on_face(sample_face, toy_model, "joy", render=True)
    assert res.image is not None and res.image.shape == sample_face.image.shape


def test_targets_and_errors(toy_model, sample_face):
    assert toy_model.expressions == EXPRESSIONS68
    np.testing.assert_array_equal(expression_alpha(toy_model, "happy"),
                                  expression_alpha(toy_model, "joy"))
    assert expression_alpha(toy_model, {"joy": 0.5, "sadness": 0.5}).sum() == 1.0
    assert parse_mix("joy:0.5, surprise") == {"joy": 0.5, "surprise": 1.0}
    for bad in ("grin", {"joy": 0.0}):
        with pytest.raises(ModelError):
            expression_alpha(toy_model, bad)
    with pytest.raises(ModelError):
        parse_mix("joy:x")
    p = sample_face.landmarks.points
    with pytest.raises(ModelError):
        synthesize_points68(toy_model, p[:60], "joy")
    with pytest.raises(ModelError):
        synthesize_points68(toy_model, p, "joy", "lasso")
    stasm = BilinearModel(toy_model.regions, toy_model.region_indices, toy_model.expressions,
                          toy_model.identities, {"normalisation": {"layout": "stasm77"}})
    with pytest.raises(ModelError, match="dlib-68"):
        check_model68(stasm)


def test_model_file_round_trip_and_faps(tmp_path, toy_model, sample_face):
    path = tmp_path / "toy.npz"
    save_model(toy_model, path)
    m = load_model(path)
    check_model68(m)
    p = sample_face.landmarks.points
    np.testing.assert_allclose(synthesize_points68(m, p, "surprise"),
                               synthesize_points68(toy_model, p, "surprise"), atol=1e-9)
    res = synthesize_on_face(sample_face, m, "surprise", "mals")
    faps = faps_for_points(sample_face, res.points68)
    assert faps.shape == (68,)
    assert faps[4] < -200  # raise_b_midlip: the lower lip goes down (the jaw line is kept)
    assert (faps[30:36] > 100).all()  # brows raised


def test_cli_synth(tmp_path, toy_model, capsys):
    model = tmp_path / "toy.npz"
    save_model(toy_model, model)
    out = tmp_path / "out.png"
    preset = tmp_path / "joy.json"
    assert main(["bilinear", "synth", str(SAMPLE), "--model", str(model), "--expression",
                 "joy:0.7,surprise:0.3", "--method", "ridge", "--lambda", "0.02", "-o", str(out),
                 "--faps-json", str(preset)]) == 0
    assert load_image(out).shape == load_image(SAMPLE).shape
    assert preset.exists()
    capsys.readouterr()
    bad_model = tmp_path / "bad.npz"
    bad_model.write_bytes(b"not a model")
    cases = [
        [str(tmp_path / "missing.png"), "--model", str(model)],
        [str(SAMPLE), "--model", str(tmp_path / "missing.npz")],
        [str(SAMPLE), "--model", str(bad_model)],
        [str(SAMPLE), "--model", str(model), "--expression", "grin"],
        [str(preset), "--model", str(model)],  # not an image
    ]
    for args in cases:
        assert main(["bilinear", "synth", *args, "-o", str(tmp_path / "x.png")]) == 2, args
        err = capsys.readouterr().err.strip()
        assert err.startswith("fap-studio: error:") and "\n" not in err, err
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("method", METHODS)
def test_jaffe_model_on_sample_and_jaffe_face(jaffe_model, sample_face, method):
    from editor.core import Face

    other = Face.from_image(JAFFE_IMAGES / next(
        p.name for p in sorted(JAFFE_IMAGES.glob("YM.NE*.tiff"))))  # not a training person
    for face in (sample_face, other):
        mouth = face.mesh.regions == "mouth"
        results = {}
        for expr in ("joy", "surprise"):
            res = synthesize_on_face(face, jaffe_model, expr, method)
            _check_result(face, res)
            moved = np.linalg.norm(res.vertices[mouth] - face.vertices[mouth], axis=1)
            assert moved.max() > 0.02 * face.interocular, (expr, method)
            results[expr] = res.points68
        if method == "plain" and face is sample_face:
            # plain ALS's exploded identity vector (see the toy test): its direction is not
            # reliable far off the training set. Trained on MediaPipe's JAFFE detections the
            # sample's gaps are neutral 1.0, joy 4.2, surprise 1.5 px (ridge 1.6 / 8.8 / 12.1,
            # mals -0.2 / 18.1 / 31.1; the JAFFE face YM, plain: 4.2 / 10.4 / 13.4); with dlib's
            # detections plain happened to order them. Checked for ridge, mals and on YM.
            continue
        assert _mouth_gap(results["surprise"]) > _mouth_gap(results["joy"])


def test_cli_synth_writes_a_bicubic_still_unless_fast(tmp_path, toy_model):
    """``bilinear synth`` writes its still as ``render`` does (bicubic); ``--fast`` bilinear."""
    from editor.synthesis.bilinear_photo import synthesize_on_face

    model = tmp_path / "toy.npz"
    save_model(toy_model, model)
    args = ["bilinear", "synth", str(SAMPLE), "--model", str(model), "--expression", "joy",
            "--method", "ridge", "--lambda", "0.02"]
    a, b = tmp_path / "a.png", tmp_path / "b.png"
    assert main([*args, "-o", str(a)]) == 0 and main([*args, "--fast", "-o", str(b)]) == 0
    want = synthesize_on_face(Face.from_image(SAMPLE), toy_model, "joy", "ridge", 0.02,
                              render=True, sharp=True).image
    assert np.array_equal(load_image(a), want)
    assert not np.array_equal(load_image(a), load_image(b))
