"""Tests of the bilinear identity × expression model (editor/synthesis/bilinear*.py, the CLI)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest

from editor.cli.bilinear import add_bilinear_parser
from editor.errors import ModelError
from editor.resources import checkout_jaffe_dir
from editor.synthesis.bilinear import (
    RegionModel,
    fix_gauge,
    load_model,
    save_model,
    synthesize_region,
    train_bilinear,
    translate,
    vector_transpose,
)
from editor.synthesis.bilinear_data import (
    EXPRESSIONS,
    LandmarkSet,
    load_stasm77,
    synthesize_shape,
    train_model,
)
from editor.synthesis.bilinear_eval import er_fp, evaluate, format_report, make_folds, s_within
from editor.synthesis.jaffe import JAFFE_CODES
from editor.synthesis.landmark_scheme import STASM77

JAFFE = checkout_jaffe_dir()
JAFFE_LM = JAFFE / "landmarks_stasm77"
needs_jaffe = pytest.mark.skipif(not (JAFFE_LM / "all_features.txt").exists(),
                                 reason="JAFFE data (../shared/data/jaffe) not available")


def random_model(rng: np.random.Generator, S: int = 6, C: int = 8, K: int = 30, I: int = 3,  # noqa: E741
                 J: int = 4) -> RegionModel:
    """A known bilinear model with arbitrary (not orthonormal) factors."""
    W = rng.normal(size=(I * K, J))
    return RegionModel(W=W, A=rng.normal(size=(I, S)), B=rng.normal(size=(J, C)), K=K)


def trained_synthetic(rng: np.random.Generator, **kw: int) -> RegionModel:
    true = random_model(rng, **kw)
    return train_bilinear(true.reconstruct_training(), true.K, true.I, true.J).model


# --- vector transpose --------------------------------------------------------------------------

def test_vector_transpose_blocks_shapes_and_involution() -> None:
    rng = np.random.default_rng(0)
    P, Q, K = 3, 4, 5
    X = rng.normal(size=(P * K, Q))
    Y = vector_transpose(X, K)
    assert Y.shape == (Q * K, P)
    for p in range(P):
        for q in range(Q):
            np.testing.assert_array_equal(Y[q * K:(q + 1) * K, p], X[p * K:(p + 1) * K, q])
    np.testing.assert_array_equal(vector_transpose(Y, K), X)
    # a single column of K-vectors (W b) becomes K × P: (W b)^VT
    np.testing.assert_array_equal(vector_transpose(X[:, :1], K), X[:, 0].reshape(P, K).T)
    with pytest.raises(ValueError):
        vector_transpose(X, 4)


# --- training ----------------------------------------------------------------------------------

def test_training_recovers_a_known_bilinear_model() -> None:
    rng = np.random.default_rng(1)
    true = random_model(rng, S=6, C=8, K=10, I=3, J=4)
    Z = true.reconstruct_training()
    res = train_bilinear(Z, 10, I=3, J=4)
    assert res.converged and res.errors[-1] < 1e-10
    m = res.model
    assert m.W.shape == (30, 4) and m.A.shape == (3, 6) and m.B.shape == (4, 8)
    np.testing.assert_allclose(m.A @ m.A.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(m.B @ m.B.T, np.eye(4), atol=1e-12)
    # same expression / identity subspaces as the generating model
    for est, ref in ((m.A, true.A), (m.B, true.B)):
        q = np.linalg.qr(ref.T)[0]
        np.testing.assert_allclose(est.T @ est, q @ q.T, atol=1e-8)
    # defaults I = S, J = C: exact, and every trained face is (W b^c)^VT a^s
    full = train_bilinear(Z, 10).model
    assert (full.I, full.J) == (6, 8)
    np.testing.assert_allclose(full.reconstruct_training(), Z, atol=1e-9)
    np.testing.assert_allclose(full.reconstruct(full.A[:, 2], full.B[:, 5]), Z[20:30, 5],
                               atol=1e-9)
    with pytest.raises(ModelError):
        train_bilinear(Z, 10, I=7)
    with pytest.raises(ModelError):
        train_bilinear(Z[:-1], 10)


# --- translation -------------------------------------------------------------------------------

def test_translation_recovers_a_and_b_up_to_the_gauge() -> None:
    rng = np.random.default_rng(2)
    m = trained_synthetic(rng)
    a_true, b_true = rng.normal(size=m.I), rng.normal(size=m.J)
    z = m.reconstruct(a_true, b_true)
    a, b, costs, converged = translate(m, z, "plain", 0.0, tol=1e-14, max_iter=500)
    assert converged and costs[-1] < 1e-20 * (z @ z) and costs[-1] <= costs[0]
    np.testing.assert_allclose(np.outer(a, b), np.outer(a_true, b_true), atol=1e-8)
    # with I = S, a mix of trained expressions (Σ α = 1) is recovered exactly by the gauge
    full = trained_synthetic(rng, I=6, J=4)  # I = S; I·J = 24 ≤ K = 30: identifiable
    a_mix = full.A @ np.array([0.1, 0.5, -0.1, 0.2, 0.1, 0.2])
    t = translate(full, full.reconstruct(a_mix, b_true), "plain", 0.0, tol=1e-14, max_iter=500)
    a_fixed, b_fixed = fix_gauge(full, t.a, t.b)
    np.testing.assert_allclose(a_fixed, a_mix, atol=1e-7)
    np.testing.assert_allclose(b_fixed, b_true, atol=1e-7)
    np.testing.assert_allclose(full.reconstruct(a_fixed, b_fixed), t_z := full.reconstruct(
        a_mix, b_true), atol=1e-9)
    assert np.linalg.norm(t_z) > 0
    # batched translation = one face at a time
    Z = np.stack([z, m.reconstruct(m.A[:, 0], rng.normal(size=m.J)), z * 0.5])
    batch = translate(m, Z, "ridge", 0.1)
    assert batch.a.shape == (3, m.I) and batch.costs.shape[0] == 3
    for n in range(3):
        one = translate(m, Z[n], "ridge", 0.1)
        np.testing.assert_allclose(batch.a[n], one.a, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(batch.b[n], one.b, rtol=1e-10, atol=1e-12)
        assert bool(batch.converged[n]) == one.converged
    with pytest.raises(ModelError):
        translate(m, z[:-1])
    with pytest.raises(ModelError):
        translate(m, z, "lasso")


def test_mals_with_tiny_lambda_equals_plain_als() -> None:
    rng = np.random.default_rng(3)
    m = trained_synthetic(rng)
    z = m.reconstruct(m.A[:, 1], rng.normal(size=m.J)) + 0.05 * rng.normal(size=m.K)
    plain = translate(m, z, "plain", 0.0, tol=1e-6, max_iter=40)
    mals = translate(m, z, "mals", 1e-12, tol=1e-6, max_iter=40)
    np.testing.assert_allclose(m.reconstruct(mals.a, mals.b), m.reconstruct(plain.a, plain.b),
                               rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(mals.costs, plain.costs, rtol=1e-7)


def test_mals_fixed_point_has_no_ridge_bias() -> None:
    rng = np.random.default_rng(4)
    m = trained_synthetic(rng)
    z = m.reconstruct(m.A[:, 3], rng.normal(size=m.J)) + 0.05 * rng.normal(size=m.K)
    lam = 20.0
    ridge = translate(m, z, "ridge", lam, tol=1e-14, max_iter=5000)
    mals = translate(m, z, "mals", lam, tol=1e-14, max_iter=5000)
    plain = translate(m, z, "plain", 0.0, tol=1e-14, max_iter=5000)
    assert mals.converged and ridge.converged
    assert np.all(np.diff(mals.costs) <= 1e-9 * mals.costs[0])  # proximal steps never go up

    def residual_gradient(t: tuple) -> np.ndarray:  # Gᵀ(z − G a): zero without ridge bias
        G = m.G(t[1])
        return G.T @ (z - G @ t[0])

    scale = np.linalg.norm(m.G(mals.b)) * np.linalg.norm(z)
    assert np.linalg.norm(residual_gradient(mals)) < 1e-7 * scale
    np.testing.assert_allclose(residual_gradient(ridge), lam * ridge.a, rtol=1e-3)
    assert np.linalg.norm(lam * ridge.a) > 1e-3 * scale  # ridge's fixed point is biased
    fit = {k: float(np.sum((z - m.reconstruct(t.a, t.b)) ** 2))
           for k, t in (("ridge", ridge), ("mals", mals), ("plain", plain))}
    assert fit["mals"] == pytest.approx(fit["plain"], rel=1e-6)
    assert fit["ridge"] > 5 * fit["mals"]
    shrink = np.linalg.norm(m.reconstruct(ridge.a, ridge.b)) / np.linalg.norm(z)
    assert shrink < 0.995  # ridge shrinks the face


def test_fix_gauge_and_synthesis_of_a_trained_face() -> None:
    rng = np.random.default_rng(5)
    m = trained_synthetic(rng)
    a, b = 3.0 * rng.normal(size=(4, m.I)), rng.normal(size=(4, m.J))
    a2, b2 = fix_gauge(m, a, b)
    np.testing.assert_allclose(m.reconstruct(a2, b2), m.reconstruct(a, b), atol=1e-10)
    mean = m.A.mean(axis=1)
    np.testing.assert_allclose(a2 @ mean, mean @ mean)  # the trained expressions' scale
    full = train_bilinear(random_model(rng).reconstruct_training(), 30).model
    z = synthesize_region(full, full.B[:, 2], np.eye(6)[4])
    np.testing.assert_allclose(z, full.reconstruct_training()[4 * 30:5 * 30, 2], atol=1e-9)


# --- metrics -----------------------------------------------------------------------------------

def test_er_fp_and_s_within_by_hand() -> None:
    inp = np.array([0.0, 0.0, 1.0, 1.0])
    syn = np.array([3.0, 4.0, 1.0, 1.0])  # point errors 5 and 0
    assert er_fp(syn, inp, 2.0) == pytest.approx(np.sqrt(12.5) / 2.0)
    assert er_fp(np.stack([syn, inp]), inp).tolist() == pytest.approx([np.sqrt(12.5), 0.0])
    x = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 1.0], [0.0, 3.0], [5.0, 5.0]])
    assert s_within(x, np.array([0, 0, 1, 1, 2])) == pytest.approx(4.0)
    assert make_folds(tuple("ABCDEFGHIJ"))[-1] == ("J", "A", "B")


# --- model files -------------------------------------------------------------------------------

def synthetic_set(n_people: int = 4, images: int = 1, seed: int = 6) -> LandmarkSet:
    """Faces = base + person deformation + expression deformation (+ a little noise), pixels."""
    rng = np.random.default_rng(seed)
    base = rng.uniform(60, 200, size=(77, 2))
    base[STASM77.inner_eye_corners[0]], base[STASM77.inner_eye_corners[1]] = (110, 120), (150, 120)
    base[STASM77.nose_tip] = (130, 160)
    person = rng.normal(0, 4, size=(n_people, 77, 2))
    expr = rng.normal(0, 2, size=(7, 77, 2))
    pts, persons, labels, names = [], [], [], []
    for c in range(n_people):
        for s in range(7):
            for k in range(images):
                pts.append(base + person[c] + expr[s] + rng.normal(0, 0.3, size=(77, 2)))
                persons.append(f"P{c}")
                labels.append(s)
                names.append(f"P{c}.{JAFFE_CODES[s]}{k + 1}.{len(names)}.tiff")
    return LandmarkSet(np.array(pts), tuple(persons), np.array(labels), tuple(names))


def write_set(data: LandmarkSet, folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "all_features.txt").write_text(
        "".join(" ,".join(f"{v:.2f}" for v in p.ravel()) + "\n" for p in data.points))
    (folder / "all_names.txt").write_text("\n".join(data.names) + "\n")
    (folder / "all_labels.txt").write_text("\n".join(str(v) for v in data.labels) + "\n")
    return folder


def test_save_load_round_trip(tmp_path: Path) -> None:
    model, errors = train_model(synthetic_set(), I=5, J=3)
    model.meta["lambda"] = {"ridge": 0.5, "mals": 7.0}
    path = tmp_path / "model.npz"
    save_model(model, path)
    back = load_model(path)
    assert back.expressions == EXPRESSIONS and back.identities == model.identities
    assert back.region_indices == model.region_indices == STASM77.regions
    assert back.meta == model.meta
    for name, reg in model.regions.items():
        for x in "WAB":
            np.testing.assert_array_equal(getattr(back.regions[name], x), getattr(reg, x))
        assert back.regions[name].K == reg.K == 2 * len(STASM77.regions[name])
    assert set(errors) == set(STASM77.regions)


def _npz(path: Path, **arrays: np.ndarray) -> Path:
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)
    return path


def test_malformed_model_files_raise_model_error(tmp_path: Path) -> None:
    model, _ = train_model(synthetic_set(), I=3, J=3)
    good = tmp_path / "good.npz"
    save_model(model, good)
    with np.load(good) as npz:
        arrays = {k: npz[k] for k in npz.files}
    meta = json.loads(str(arrays["metadata"]))
    text = tmp_path / "text.npz"
    text.write_text("hello")
    npy = tmp_path / "array.npz"
    np.save(npy.with_suffix(".npy"), np.zeros(3))
    npy.write_bytes(npy.with_suffix(".npy").read_bytes())
    truncated = tmp_path / "trunc.npz"
    truncated.write_bytes(good.read_bytes()[:200])
    bad = {
        "missing": tmp_path / "nope.npz",
        "text": text,
        "npy": npy,
        "truncated": truncated,
        "no metadata": _npz(tmp_path / "a.npz", x=np.zeros(3)),
        "foreign": _npz(tmp_path / "b.npz", **(arrays | {
            "metadata": np.array(json.dumps(meta | {"format": "other"}))})),
        "version": _npz(tmp_path / "c.npz", **(arrays | {
            "metadata": np.array(json.dumps(meta | {"version": 99}))})),
        "bad json": _npz(tmp_path / "d.npz", **(arrays | {"metadata": np.array("{oops")})),
        "shape": _npz(tmp_path / "e.npz", **(arrays | {"mouth.W": np.zeros((3, 3))})),
        "nan": _npz(tmp_path / "f.npz", **(arrays | {"nose.A": arrays["nose.A"] * np.nan})),
        "lacks array": _npz(tmp_path / "g.npz", **{k: v for k, v in arrays.items()
                                                    if k != "eyes.B"}),
    }
    for label, path in bad.items():
        with pytest.raises(ModelError) as info:
            load_model(path)
        assert str(path) in str(info.value), label


def test_synthesize_shape_api() -> None:
    data = synthetic_set()
    model, _ = train_model(data)
    face = data.points[0]  # P0 neutral
    out = synthesize_shape(model, face, "neutral", "plain", tol=1e-10, max_iter=300)
    assert out.shape == (77, 2)
    np.testing.assert_array_equal(out[list(STASM77.contour)], face[list(STASM77.contour)])
    np.testing.assert_allclose(out, face, atol=0.05)  # reconstruction of a trained face
    mix = synthesize_shape(model, face, {"happy": 0.5, "surprise": 0.5}, "ridge", lam=0.1)
    same = synthesize_shape(model, face, np.eye(7)[1] * 0.5 + np.eye(7)[3] * 0.5, "ridge", 0.1)
    np.testing.assert_allclose(mix, same)
    with pytest.raises(ModelError):
        synthesize_shape(model, face, "bored", "plain")
    with pytest.raises(ModelError):
        synthesize_shape(model, face, "happy", "mals")  # no λ given or stored


# --- CLI ---------------------------------------------------------------------------------------

def run_cli(*argv: str) -> int:
    parser = argparse.ArgumentParser(prog="fap-studio")
    add_bilinear_parser(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(list(argv))
    return args.func(args)


def test_cli_train_and_eval(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = write_set(synthetic_set(n_people=4), tmp_path / "landmarks_stasm77")
    out = tmp_path / "m.npz"
    assert run_cli("bilinear", "train", str(folder), "-o", str(out), "--grid", "0.1,1") == 0
    model = load_model(out)
    assert set(model.meta["lambda"]) == {"ridge", "mals"}
    assert "wrote" in capsys.readouterr().out
    assert run_cli("bilinear", "train", str(folder / "all_features.txt"), "-o", str(out),
                   "--no-cv", "-I", "3") == 0
    assert load_model(out).regions["mouth"].I == 3
    assert run_cli("bilinear", "eval", str(folder), "--folds", "1", "--test-size", "1",
                   "--grid", "0.1,1") == 0
    report = capsys.readouterr().out
    assert "ER_FP" in report and "S_w" in report and "0.190" in report


def test_cli_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert run_cli("bilinear", "train", str(tmp_path / "none"), "-o", str(tmp_path / "m")) == 2
    err = capsys.readouterr().err
    assert err.startswith("fap-studio: error: ") and err.count("\n") == 1
    folder = write_set(synthetic_set(n_people=3), tmp_path / "lm")
    (folder / "all_features.txt").write_text("1 ,2 ,3\n" * 21)
    assert run_cli("bilinear", "eval", str(folder)) == 2
    assert "expected 154 numbers" in capsys.readouterr().err


# --- JAFFE -------------------------------------------------------------------------------------

@needs_jaffe
def test_jaffe_layout_and_training() -> None:
    data = load_stasm77(JAFFE_LM)
    assert data.points.shape == (213, 77, 2) and len(data.people) == 10
    p = data.points.mean(axis=0)
    left, right = p[STASM77.inner_eye_corners[0]], p[STASM77.inner_eye_corners[1]]
    assert left[0] < p[STASM77.nose_tip, 0] < right[0] and p[STASM77.nose_tip, 1] > left[1]
    assert p[34, 0] < left[0] and p[44, 0] > right[0]  # outer eye corners lie outside
    assert p[16:28, 1].max() < p[30:48, 1].min()  # brows above eyes
    assert p[59:77, 1].min() > p[48:59, 1].max()  # mouth below nose
    assert p[6, 1] == p[:, 1].max()  # chin
    model, errors = train_model(data, data.people[:7])
    assert all(e[-1] < 1e-10 for e in errors.values())
    _, small = train_model(data, data.people[:7], I=3, J=3)
    assert all(e[-1] < 0.1 for e in small.values())


@needs_jaffe
def test_jaffe_one_fold_of_evaluation() -> None:
    data = load_stasm77(JAFFE_LM)
    res = evaluate(data, n_folds=1, grid=(0.01, 0.1, 1.0, 10.0))
    assert res.folds == [data.people[:3]] and res.n_test_images > 50
    for m, r in res.methods.items():
        assert np.all(np.isfinite(r.er)) and np.all(r.er > 0) and np.all(r.er < 0.2), m
        assert np.all(np.isfinite(r.s_w)) and r.s_w[0] > 0
    assert np.all(res.methods["plain"].er_all < res.methods["ridge"].er_all)  # LS fits best
    assert np.all(res.methods["plain"].er_all < 0.05)
    assert "Mouth ER_FP" in format_report(res)
