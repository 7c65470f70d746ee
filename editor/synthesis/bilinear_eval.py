"""Metrics and the JAFFE evaluation of the bilinear model (SPEC §5, the paper's experiment adapted).

Protocol (ours, following issue 9): people are split into folds of ``test_size`` (default 3)
taken cyclically, so every person is tested at least once and every fold trains on exactly the
other people (7 with JAFFE; with 10 people and 4 folds, the first two people are tested twice).
Training uses the mean of each person's normalised images per expression (7 × 7 faces). Every
test image is translated on its own (a "new face"): ER_FP (eq. 17) of its reconstruction per
region and expression, and S_w of the first two coefficients of the mouth's expression vector
over the test images labelled neutral / surprise (per fold, then averaged over folds).

λ (λ1 = λ2, one value for all regions, as in the paper) is chosen per fold by leave-one-person-
out cross-validation on the training people only. ER_FP cannot choose λ (the unregularised fit
always reconstructs best), so the criterion is the *synthesis error*: translate the held-out
person's neutral images, swap in each trained expression vector ``a^s`` (after
:func:`~editor.synthesis.bilinear.fix_gauge`) and measure ER_FP against that person's real mean
shape for ``s``, averaged over the six non-neutral expressions and the four regions. The same
synthesis error is reported on the test people, beside two baselines that use no model.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from editor.errors import ModelError
from editor.synthesis.bilinear import BilinearModel, RegionModel, fix_gauge, translate
from editor.synthesis.bilinear_data import EXPRESSIONS, train_from_means
from editor.synthesis.jaffe import JAFFE_CODES
from editor.synthesis.landmark_scheme import STASM77, LandmarkSet, region_vectors

REGIONS = STASM77.regions  # the regions evaluated (the Stasm model's)

DEFAULT_GRID = tuple(float(x) for x in np.logspace(-4, 3, 15))
PAPER_MOUTH_EXPRESSIONS = ("neutral", "happy", "fear", "sad", "surprise")
PAPER_MOUTH_ER = {"plain": (4.25, 3.24, 1.68, 2.47, 3.44), "ridge": (7.26, 6.48, 5.75, 4.74, 8.32),
                  "mals": (5.33, 4.76, 2.98, 4.43, 4.41)}  # ×10⁻³, KDEF, one test person
PAPER_SW = {"plain": 0.190, "ridge": 0.103, "mals": 0.065}
PAPER_LAMBDA = {"plain": 0.0, "ridge": 15.0, "mals": 750.0}


def er_fp(z_syn: np.ndarray, z_inp: np.ndarray, d: float | np.ndarray = 1.0) -> np.ndarray:
    """ER_FP (eq. 17): ``sqrt(mean_i ‖v_i,syn − v_i,inp‖²) / d`` over the n points.

    z_syn, z_inp (..., 2n) interleaved x, y (broadcast); d scalar or (...) -> (...).
    """
    diff = np.asarray(z_syn, float) - np.asarray(z_inp, float)
    diff = diff.reshape(*diff.shape[:-1], -1, 2)
    return np.sqrt(np.mean(np.sum(diff**2, axis=-1), axis=-1)) / d


def s_within(x: np.ndarray, labels: np.ndarray) -> float:
    """Scalar within-class scatter ``Σ_i Σ_{x∈D_i} ‖x − m_i‖²``. x (N, p), labels (N,)."""
    x, labels = np.asarray(x, float), np.asarray(labels)
    return float(sum(np.sum((x[labels == c] - x[labels == c].mean(axis=0)) ** 2)
                     for c in np.unique(labels)))


def make_folds(people: tuple[str, ...], test_size: int = 3,
               n_folds: int | None = None) -> list[tuple[str, ...]]:
    """Test groups: fold f tests people ``f·t … f·t + t − 1`` (mod the number of people)."""
    n = len(people)
    if not 1 <= test_size < n:
        raise ModelError(f"test size {test_size} needs 1 ≤ size < {n} people")
    n_folds = math.ceil(n / test_size) if n_folds is None else int(n_folds)
    if n_folds < 1:
        raise ModelError("need at least one fold")
    return [tuple(people[(f * test_size + t) % n] for t in range(test_size))
            for f in range(n_folds)]


def synthesis_error_grid(reg: RegionModel, z_neutral: np.ndarray, target: np.ndarray,
                         method: str, lams: np.ndarray, tol: float = 1e-3,
                         max_iter: int = 50) -> np.ndarray:
    """Synthesis error of one person and region for several λ in one vectorised translation.

    z_neutral (n, K) neutral images, target (S, K) the person's real mean shapes,
    lams (L,) -> (L, S) ER_FP of the synthesized expression s (mean over the n images).
    """
    lams = np.atleast_1d(np.asarray(lams, dtype=np.float64))
    n, L = z_neutral.shape[0], lams.size
    tr = translate(reg, np.tile(z_neutral, (L, 1)), method, np.repeat(lams, n), tol, max_iter)
    _, b = fix_gauge(reg, tr.a, tr.b)
    syn = np.einsum("ikj,is,nj->nsk", reg.w3, reg.A, b)  # (L·n, S, K)
    return er_fp(syn, target[None]).reshape(L, n, -1).mean(axis=1)


def _neutral_images(pts: np.ndarray, data: LandmarkSet, person: str) -> np.ndarray:
    sel = (np.asarray(data.persons) == person) & (data.labels == 0)
    if not sel.any():
        raise ModelError(f"person {person} has no neutral image")
    return pts[sel]


def cross_validate(means: np.ndarray, neutrals: list[np.ndarray], people: tuple[str, ...],
                   methods: tuple[str, ...], grid: tuple[float, ...], I: int | None = None,  # noqa: E741
                   J: int | None = None, tol: float = 1e-3,
                   max_iter: int = 50) -> dict[str, np.ndarray]:
    """Leave-one-person-out synthesis error for every λ of ``grid``.

    means (C, S, 77, 2) of the training people, neutrals[c] (n_c, 77, 2) their neutral images.
    Returns method -> (L,) mean error over held-out people, regions and non-neutral targets.
    """
    scores = {m: np.zeros(len(grid)) for m in methods}
    for h in range(len(people)):
        rest = [c for c in range(len(people)) if c != h]
        model, _ = train_from_means(means[rest], tuple(people[c] for c in rest), I, J)
        for name, reg in model.regions.items():
            idx = model.region_indices[name]
            z, target = region_vectors(neutrals[h], idx), region_vectors(means[h], idx)
            for m in methods:
                err = synthesis_error_grid(reg, z, target, m, np.array(grid), tol, max_iter)
                scores[m] += err[:, 1:].mean(axis=1) / (len(people) * len(model.regions))
    return scores


@dataclass
class MethodResult:
    """Results of one translation method; (R, S) arrays are regions × expressions."""

    method: str
    lambdas: list[float] = field(default_factory=list)   # chosen λ per fold
    cv_scores: list[np.ndarray] = field(default_factory=list)  # per fold, (L,)
    er_sum: np.ndarray = field(default_factory=lambda: np.zeros((len(REGIONS), len(EXPRESSIONS))))
    er_n: np.ndarray = field(default_factory=lambda: np.zeros((len(REGIONS), len(EXPRESSIONS))))
    syn_sum: np.ndarray = field(default_factory=lambda: np.zeros((len(REGIONS), len(EXPRESSIONS))))
    syn_n: np.ndarray = field(default_factory=lambda: np.zeros((len(REGIONS), len(EXPRESSIONS))))
    s_w_raw: list[float] = field(default_factory=list)     # per fold
    s_w: list[float] = field(default_factory=list)         # per fold, gauge-fixed a
    s_ratio: list[float] = field(default_factory=list)     # per fold, S_w / S_total
    n_converged: int = 0
    n_translations: int = 0

    @property
    def er(self) -> np.ndarray:
        """Mean ER_FP of the test images, (R, S)."""
        return self.er_sum / np.maximum(self.er_n, 1)

    @property
    def er_all(self) -> np.ndarray:
        """Mean ER_FP over all test images per region, (R,)."""
        return self.er_sum.sum(axis=1) / np.maximum(self.er_n.sum(axis=1), 1)

    @property
    def synth(self) -> np.ndarray:
        """Mean synthesis error per region and target expression, (R, S)."""
        return self.syn_sum / np.maximum(self.syn_n, 1)


@dataclass
class EvalResult:
    """Everything :func:`format_report` prints."""

    folds: list[tuple[str, ...]]
    methods: dict[str, MethodResult]
    baselines: dict[str, np.ndarray]   # name -> (R, S) synthesis error without a model
    grid: tuple[float, ...]
    I: int | None  # noqa: E741
    J: int | None
    n_images: int
    n_test_images: int
    regions: tuple[str, ...] = tuple(REGIONS)


def evaluate(data: LandmarkSet, n_folds: int | None = None, test_size: int = 3,
             methods: tuple[str, ...] = ("plain", "ridge", "mals"),
             grid: tuple[float, ...] = DEFAULT_GRID, fixed_lambda: dict[str, float] | None = None,
             I: int | None = None, J: int | None = None,  # noqa: E741
             tol: float = 1e-3, max_iter: int = 50) -> EvalResult:
    """Run the rotated train/test evaluation (see the module docstring).

    ``fixed_lambda`` (method -> λ) skips the cross-validation for those methods.
    """
    pts, _, _ = STASM77.normalise_set(data)
    people, persons = data.people, np.asarray(data.persons)
    means = STASM77.mean_shapes(pts, data, people, EXPRESSIONS)
    neutrals = [_neutral_images(pts, data, p) for p in people]
    folds = make_folds(people, test_size, n_folds)
    fixed = dict(fixed_lambda or {})
    res = {m: MethodResult(m) for m in methods}
    base = {k: np.zeros((len(REGIONS), len(EXPRESSIONS)))
            for k in ("neutral copy", "neutral + mean change")}
    n_test = 0
    for test in folds:
        train = tuple(p for p in people if p not in test)
        ci = [people.index(p) for p in train]
        model, _ = train_from_means(means[ci], train, I, J)
        cv_methods = tuple(m for m in methods if m != "plain" and m not in fixed)
        cv = cross_validate(means[ci], [neutrals[c] for c in ci], train, cv_methods, grid, I, J,
                            tol, max_iter) if cv_methods else {}
        sel = np.isin(persons, test)
        labels, n_test = data.labels[sel], n_test + int(sel.sum())
        d = np.array([STASM77.inner_eye_distance(neutrals[people.index(p)]).mean()
                      for p in persons[sel]])
        for m in methods:
            r = res[m]
            lam = 0.0 if m == "plain" else fixed.get(m, grid[int(np.argmin(cv.get(m, [0])))])
            r.lambdas.append(lam)
            if m in cv:
                r.cv_scores.append(cv[m])
            _score_fold(r, model, pts[sel], labels, d, lam, tol, max_iter)
            for p in test:
                _synth_fold(r, model, neutrals[people.index(p)], means[people.index(p)], lam,
                            tol, max_iter)
        for p in test:
            _baselines(base, model, neutrals[people.index(p)], means[people.index(p)], means[ci])
    norm = len(folds) * len(folds[0])
    return EvalResult(folds, res, {k: v / norm for k, v in base.items()}, tuple(grid), I, J,
                      len(data.names), n_test)


def _score_fold(r: MethodResult, model: BilinearModel, pts: np.ndarray, labels: np.ndarray,
                d: np.ndarray, lam: float, tol: float, max_iter: int) -> None:
    """ER_FP of every test image and S_w (mouth, neutral vs surprise) for one fold."""
    for ri, (name, reg) in enumerate(model.regions.items()):
        z = region_vectors(pts, model.region_indices[name])
        tr = translate(reg, z, r.method, lam, tol, max_iter)
        e = er_fp(reg.reconstruct(tr.a, tr.b), z, d)
        np.add.at(r.er_sum[ri], labels, e)
        np.add.at(r.er_n[ri], labels, 1)
        r.n_converged += int(np.sum(tr.converged))
        r.n_translations += len(e)
        if name == "mouth":
            two = np.isin(labels, (0, 3))
            a_fixed, _ = fix_gauge(reg, tr.a, tr.b)
            r.s_w_raw.append(s_within(tr.a[two, :2], labels[two]))
            x = a_fixed[two, :2]
            r.s_w.append(s_within(x, labels[two]))
            r.s_ratio.append(r.s_w[-1] / max(float(np.sum((x - x.mean(axis=0)) ** 2)), 1e-300))


def _synth_fold(r: MethodResult, model: BilinearModel, neutral: np.ndarray, target: np.ndarray,
                lam: float, tol: float, max_iter: int) -> None:
    for ri, (name, reg) in enumerate(model.regions.items()):
        idx = model.region_indices[name]
        err = synthesis_error_grid(reg, region_vectors(neutral, idx), region_vectors(target, idx),
                                   r.method, np.array([lam]), tol, max_iter)[0]
        r.syn_sum[ri] += err
        r.syn_n[ri] += 1


def _baselines(base: dict[str, np.ndarray], model: BilinearModel, neutral: np.ndarray,
               target: np.ndarray, train_means: np.ndarray) -> None:
    """Synthesis without a model: the neutral shape itself, and neutral + mean change."""
    change = (train_means - train_means[:, :1]).mean(axis=0)  # (S, 77, 2)
    for ri, idx in enumerate(model.region_indices.values()):
        z, t = region_vectors(neutral, idx)[:, None], region_vectors(target, idx)[None]
        base["neutral copy"][ri] += er_fp(z, t).mean(axis=0)
        base["neutral + mean change"][ri] += er_fp(z + region_vectors(change, idx)[None],
                                                   t).mean(axis=0)


def _row(label: str, values: np.ndarray | Sequence[float | str], width: int = 7,
         fmt: str = "{:.2f}") -> str:
    return label + "".join(fmt.format(v).rjust(width) for v in values)


def format_report(res: EvalResult) -> str:
    """The evaluation as a plain-text table beside the paper's values."""
    codes = JAFFE_CODES
    out: list[str] = []
    add = out.append
    n_train = "the other"
    add("Bilinear identity × expression model on JAFFE (Stasm 77 landmarks, regions "
        + " / ".join(res.regions) + ")")
    add(f"{res.n_images} images; {len(res.folds)} fold(s); each trains on {n_train} people × 7 "
        "expressions (mean of each person's images per expression) and translates every test image")
    add("on its own (" + f"{res.n_test_images} test translations). Test people per fold: "
        + " | ".join(" ".join(f) for f in res.folds))
    add(f"I = {res.I or 'S = 7'}, J = {res.J or 'C (number of training people)'}.")
    add("λ (λ1 = λ2, all regions): fixed where given, else per fold by leave-one-person-out CV "
        f"on the training people over {len(res.grid)} values {min(res.grid):g} … "
        f"{max(res.grid):g} (criterion: synthesis error).")
    for m, r in res.methods.items():
        conv = 100.0 * r.n_converged / max(r.n_translations, 1)
        lam = " ".join(f"{v:g}" for v in r.lambdas) if m != "plain" else "-"
        add(f"  {m:6s} λ per fold: {lam:30s} paper: {PAPER_LAMBDA[m]:g}   "
            f"converged within max_iter: {conv:.0f} %")
    add("")
    add("ER_FP ×10⁻³ (eq. 17: RMS landmark error / neutral inner-eye-corner distance), "
        "mean over test images")
    add(_row("region  method ", codes + ("all",), fmt="{}"))
    for ri, region in enumerate(res.regions):
        for m, r in res.methods.items():
            add(_row(f"{region:8s}{m:7s}", list(1e3 * r.er[ri]) + [1e3 * r.er_all[ri]]))
    add("")
    add("Mouth ER_FP ×10⁻³, ours (JAFFE, all test images) / paper (KDEF, one test person)")
    add("method " + "".join(f"{e:>16s}" for e in PAPER_MOUTH_EXPRESSIONS))
    mouth = list(res.regions).index("mouth")
    for m, r in res.methods.items():
        cells = [f"{1e3 * r.er[mouth, EXPRESSIONS.index(e)]:.2f} / {p:.2f}"
                 for e, p in zip(PAPER_MOUTH_EXPRESSIONS, PAPER_MOUTH_ER[m], strict=True)]
        add(f"{m:7s}" + "".join(c.rjust(16) for c in cells))
    add("")
    add("S_w (mouth; neutral vs surprise test images; first two coefficients of a; "
        "mean over folds)")
    add("method     paper   ours, raw a   ours, gauge-fixed a   S_w / S_total (gauge-fixed)")
    for m, r in res.methods.items():
        add(f"{m:7s}{PAPER_SW[m]:9.3f}{np.mean(r.s_w_raw):14.4g}{np.mean(r.s_w):22.4g}"
            f"{np.mean(r.s_ratio):22.3f}")
    add("")
    add("Synthesis error ×10⁻³ (translate each neutral image, swap in a^s, ER_FP against the "
        "person's real mean shape for s)")
    add(_row("region  method                ", codes[1:] + ("mean",), fmt="{}"))
    for ri, region in enumerate(res.regions):
        rows = {m: r.synth[ri] for m, r in res.methods.items()} | {
            k: v[ri] for k, v in res.baselines.items()}
        for m, v in rows.items():
            add(_row(f"{region:8s}{m:22s}", list(1e3 * v[1:]) + [1e3 * v[1:].mean()]))
    return "\n".join(out)


def choose_lambdas(data: LandmarkSet, people: tuple[str, ...] | None = None,
                   methods: tuple[str, ...] = ("ridge", "mals"),
                   grid: tuple[float, ...] = DEFAULT_GRID, I: int | None = None,  # noqa: E741
                   J: int | None = None, tol: float = 1e-3,
                   max_iter: int = 50) -> dict[str, float]:
    """λ per method by leave-one-person-out CV over ``people`` (default all), as in
    :func:`evaluate`; used to store default λ values in a trained model."""
    people = data.people if people is None else tuple(people)
    pts, _, _ = STASM77.normalise_set(data)
    means = STASM77.mean_shapes(pts, data, people, EXPRESSIONS)
    scores = cross_validate(means, [_neutral_images(pts, data, p) for p in people], people,
                            methods, grid, I, J, tol, max_iter)
    return {m: float(grid[int(np.argmin(s))]) for m, s in scores.items()}
