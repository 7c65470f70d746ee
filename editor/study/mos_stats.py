"""Statistics of a MOS rating study (numpy; scipy.stats for the Wilson and t intervals).

Aggregation follows the paper (SPEC §4): a rating is correct when the chosen label is the
intended one ("cannot tell" is wrong). A face x expression cell is the mean over its stimuli;
per expression = mean over faces of the cell values; per face = mean over expressions; overall =
mean over all stimuli. 95 % intervals use the pooled ratings of the group: Wilson score interval
for recognition, Student t interval for naturalness (clipped to 1..5). They ignore that the same
raters rate every image: read them as indicative. With equal ratings per stimulus (a complete
study) the paper's means equal the pooled means.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from editor.study.mos import CANNOT_TELL


class Rating(Protocol):
    """What the statistics need of an answer (``mos.AnswerRecord`` satisfies it)."""

    @property
    def rater(self) -> str: ...
    @property
    def stimulus_id(self) -> int: ...
    @property
    def face(self) -> str: ...
    @property
    def true_label(self) -> str: ...
    @property
    def label(self) -> str: ...
    @property
    def naturalness(self) -> int: ...


class StimulusInfo(Protocol):
    """A stimulus (``mos.Stimulus`` satisfies it); lets unrated stimuli appear in a report."""

    @property
    def id(self) -> int: ...
    @property
    def face(self) -> str: ...
    @property
    def label(self) -> str: ...


def wilson_interval(k: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval for k successes in n trials (nan, nan when n == 0), from
    ``scipy.stats.binomtest(k, n).proportion_ci(method="wilson")``; exactly 0 / 1 at k = 0 / n.
    """
    if n <= 0:
        return math.nan, math.nan
    from scipy import stats  # scipy on first use: a quick start (issue 15)

    ci = stats.binomtest(int(k), int(n)).proportion_ci(confidence, method="wilson")
    return (0.0 if k == 0 else float(ci.low)), (1.0 if k == n else float(ci.high))


def t_interval(values: Sequence[float] | np.ndarray,
               confidence: float = 0.95) -> tuple[float, float]:
    """Student t interval of the mean, mean ± t(n-1) · s / sqrt(n) (s: ddof 1), from
    ``scipy.stats.t.interval``; nan if n < 2, the mean itself when all values are equal."""
    from scipy import stats  # scipy on first use: a quick start (issue 15)

    x = np.asarray(values, dtype=float)
    if x.size < 2:
        return math.nan, math.nan
    sem = float(stats.sem(x))
    if sem == 0.0:
        return float(x.mean()), float(x.mean())
    lo, hi = stats.t.interval(confidence, x.size - 1, loc=x.mean(), scale=sem)
    return float(lo), float(hi)


@dataclass(frozen=True)
class Summary:
    """Recognition and naturalness of one group (stimulus, cell, expression, face, overall).

    ``recognition`` and ``naturalness`` are the paper's means of sub-group values; the CIs, the
    counts and the shares of naturalness ratings >= 3 and == 5 use the pooled ratings.
    """

    n: int
    n_correct: int
    recognition: float
    recognition_ci: tuple[float, float]
    naturalness: float
    naturalness_ci: tuple[float, float]
    share_ge3: float
    share_eq5: float


@dataclass(frozen=True)
class _Group:
    rate: float
    nat: float
    k: int
    scores: np.ndarray

    @staticmethod
    def of_ratings(correct: list[bool], scores: list[int]) -> _Group:
        s = np.asarray(scores, dtype=float)
        return _Group(_mean(correct), _mean(s), int(sum(correct)), s)

    @staticmethod
    def combine(parts: Iterable[_Group]) -> _Group:
        parts = list(parts)
        return _Group(_mean([p.rate for p in parts]), _mean([p.nat for p in parts]),
                      sum(p.k for p in parts),
                      np.concatenate([p.scores for p in parts]) if parts else np.zeros(0))

    def summary(self, confidence: float) -> Summary:
        n, s = self.scores.size, self.scores
        lo, hi = t_interval(s, confidence)  # clipped to the 1..5 scale (nan stays nan)
        return Summary(n, self.k, self.rate, wilson_interval(self.k, n, confidence), self.nat,
                       (max(lo, 1.0), min(hi, 5.0)), _mean(s >= 3), _mean(s == 5))


def _mean(values: Iterable[float] | np.ndarray) -> float:  # nan-ignoring, nan if empty
    x = np.asarray(list(values) if not isinstance(values, np.ndarray) else values, dtype=float)
    x = x[~np.isnan(x)]
    return float(x.mean()) if x.size else math.nan


@dataclass(frozen=True)
class Confusion:
    """Counts[i, j]: ratings of stimuli intended as ``rows[i]`` labelled ``columns[j]``.

    ``normalised`` divides each row by its total (nan rows where a label has no ratings).
    """

    rows: tuple[str, ...]
    columns: tuple[str, ...]
    counts: np.ndarray
    normalised: np.ndarray


def confusion_matrix(ratings: Iterable[Rating], labels: Sequence[str],
                     intended: Sequence[str] | None = None) -> Confusion:
    """Rows: ``intended`` labels (default ``labels``); columns: ``labels`` + "cannot tell"."""
    rows, cols = tuple(labels if intended is None else intended), (*labels, CANNOT_TELL)
    counts = np.zeros((len(rows), len(cols)), dtype=np.int64)
    for r in ratings:
        if r.true_label not in rows or r.label not in cols:
            raise ValueError(f"rating label {r.label!r} / {r.true_label!r} not in {cols}")
        counts[rows.index(r.true_label), cols.index(r.label)] += 1
    totals = counts.sum(axis=1, keepdims=True)
    normalised = np.where(totals > 0, counts / np.maximum(totals, 1), np.nan)
    return Confusion(rows, cols, counts, normalised)


@dataclass(frozen=True)
class Kappa:
    """Fleiss' kappa with its parts (see :func:`fleiss_kappa`)."""

    kappa: float
    p_bar: float
    p_e: float
    n_subjects: int
    n_ratings: int


def fleiss_kappa(counts: np.ndarray) -> Kappa:
    """Fleiss' kappa from a subjects x categories matrix of rating counts n_ij.

    Raters may rate subsets: subject i has its own n_i = sum_j n_ij (subjects with n_i < 2 are
    left out). P_i = sum_j n_ij (n_ij - 1) / (n_i (n_i - 1)); P_bar = mean_i P_i;
    p_j = sum_i n_ij / sum_i n_i; P_e = sum_j p_j²; kappa = (P_bar - P_e) / (1 - P_e), nan when
    P_e == 1. With equal n_i this is exactly Fleiss (1971).
    """
    c = np.asarray(counts, dtype=float)
    n_i = c.sum(axis=1)
    c, n_i = c[n_i >= 2], n_i[n_i >= 2]
    if c.shape[0] == 0:
        return Kappa(math.nan, math.nan, math.nan, 0, 0)
    p_i = (c * (c - 1)).sum(axis=1) / (n_i * (n_i - 1))
    p_j = c.sum(axis=0) / n_i.sum()
    p_bar, p_e = float(p_i.mean()), float((p_j**2).sum())
    kappa = (p_bar - p_e) / (1 - p_e) if p_e < 1 else math.nan
    return Kappa(float(kappa), p_bar, p_e, int(c.shape[0]), int(n_i.sum()))


@dataclass(frozen=True)
class RaterResult:
    """One rater's agreement with the panel and BT.500 screening outcome.

    ``r_panel``: Pearson r of the rater's naturalness scores with the mean of the *other*
    raters on the same stimuli (``n_panel`` stimuli; nan if < 3 or no variance). ``p``, ``q``:
    BT.500 counts of scores above / below the per-stimulus interval; ``rejected``: the rule.
    """

    rater: str
    n: int
    accuracy: float
    mean_naturalness: float
    r_panel: float
    n_panel: int
    p: int
    q: int
    rejected: bool


def bt500_screening(scores: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ITU-R BT.500 observer screening (BT.500-13 Annex 2 §2.3.1) of a raters x stimuli matrix.

    ``scores`` holds naturalness ratings with nan where a rater did not rate a stimulus. Per
    stimulus j with scores u (N_j of them): mean ū_j, S_j = std with ddof = 1, kurtosis
    β2_j = m4 / m2² with m_k = sum (u - ū_j)^k / N_j. The band is ū_j ± 2 S_j if 2 <= β2_j <= 4
    (normal) else ū_j ± sqrt(20) S_j. P_i counts rater i's scores u >= upper, Q_i scores
    u <= lower. Rater i is rejected if (P_i + Q_i) / n_i > 0.05 and
    |P_i - Q_i| / (P_i + Q_i) < 0.3, n_i = the number of scores of rater i. Our additions:
    stimuli with S_j == 0 (all scores equal, no outlier possible) or N_j < 2 are skipped.
    BT.500 asks for at least 15 observers; with fewer the result is indicative.

    Returns
    -------
    P, Q, rejected : arrays of length n_raters.
    """
    u = np.asarray(scores, dtype=float)
    have = ~np.isnan(u)
    n_j = have.sum(axis=0)
    ok = n_j >= 2
    filled = np.where(have, u, 0.0)
    mean = np.divide(filled.sum(axis=0), n_j, out=np.zeros(u.shape[1]), where=n_j > 0)
    dev = np.where(have, u - mean, 0.0)
    m2 = np.divide((dev**2).sum(axis=0), n_j, out=np.zeros(u.shape[1]), where=ok)
    m4 = np.divide((dev**4).sum(axis=0), n_j, out=np.zeros(u.shape[1]), where=ok)
    s = np.sqrt(np.divide(m2 * n_j, n_j - 1, out=np.zeros(u.shape[1]), where=ok))
    beta2 = np.divide(m4, m2**2, out=np.zeros(u.shape[1]), where=m2 > 0)
    k = np.where((beta2 >= 2) & (beta2 <= 4), 2.0, np.sqrt(20.0))
    used = have & (ok & (s > 0))[None, :]
    p = (used & (u >= mean + k * s)).sum(axis=1)
    q = (used & (u <= mean - k * s)).sum(axis=1)
    n_i, pq = have.sum(axis=1), p + q
    rejected = (pq > 0) & (pq / np.maximum(n_i, 1) > 0.05) & (
        np.abs(p - q) / np.maximum(pq, 1) < 0.3)
    return p, q, rejected


def rater_agreement(ratings: Iterable[Rating]) -> list[RaterResult]:
    """Per-rater accuracy, mean naturalness, correlation with the panel and BT.500 screening."""
    ratings = list(ratings)
    raters = list(dict.fromkeys(r.rater for r in ratings))
    stims = sorted({r.stimulus_id for r in ratings})
    u = np.full((len(raters), len(stims)), np.nan)
    correct: dict[str, list[bool]] = {r: [] for r in raters}
    for r in ratings:
        u[raters.index(r.rater), stims.index(r.stimulus_id)] = r.naturalness
        correct[r.rater].append(r.label == r.true_label)
    have = ~np.isnan(u)
    col_sum, col_n = np.where(have, u, 0).sum(axis=0), have.sum(axis=0)
    p, q, rejected = bt500_screening(u)
    out = []
    for i, name in enumerate(raters):
        mine = have[i] & (col_n > 1)
        x = u[i, mine]
        y = (col_sum[mine] - x) / (col_n[mine] - 1)
        r_panel = math.nan
        if x.size >= 3 and x.std() > 0 and y.std() > 0:
            r_panel = float(np.corrcoef(x, y)[0, 1])
        out.append(RaterResult(name, int(have[i].sum()), _mean(correct[name]),
                               _mean(u[i, have[i]]), r_panel, int(x.size), int(p[i]), int(q[i]),
                               bool(rejected[i])))
    return out


@dataclass(frozen=True)
class StimulusResult:
    """Summary of one stimulus."""

    stimulus_id: int
    face: str
    true_label: str
    summary: Summary


@dataclass(frozen=True)
class StudyReport:
    """Everything :func:`format_report` prints. ``labels``: the expressions that have stimuli
    (in study order); ``cells`` is keyed by (face, expression)."""

    confidence: float
    labels: tuple[str, ...]
    faces: tuple[str, ...]
    stimuli: list[StimulusResult]
    cells: dict[tuple[str, str], Summary]
    per_expression: dict[str, Summary]
    per_face: dict[str, Summary]
    overall: Summary
    confusion: Confusion
    kappa: Kappa
    raters: list[RaterResult]


def analyse(ratings: Iterable[Rating], labels: Sequence[str] | None = None,
            stimuli: Sequence[StimulusInfo] | None = None,
            confidence: float = 0.95) -> StudyReport:
    """Compute the whole report (aggregation rules: see the module docstring).

    ``labels``: the study's labels in display order (default: the intended labels in order of
    appearance); ``stimuli`` lets stimuli without any rating appear (with n = 0). Raises
    ValueError if a rating's label is neither in ``labels`` nor "cannot tell".
    """
    ratings = list(ratings)
    info = {s.id: (s.face, s.label) for s in stimuli or ()}
    for r in ratings:
        info.setdefault(r.stimulus_id, (r.face, r.true_label))
    labels = tuple(labels) if labels is not None else tuple(
        dict.fromkeys(lab for _, lab in info.values()))
    faces = tuple(dict.fromkeys(face for face, _ in info.values()))
    per_stim: dict[int, tuple[list[bool], list[int]]] = {sid: ([], []) for sid in info}
    for r in ratings:
        per_stim[r.stimulus_id][0].append(r.label == r.true_label)
        per_stim[r.stimulus_id][1].append(int(r.naturalness))
    groups = {sid: _Group.of_ratings(*v) for sid, v in per_stim.items()}
    cells = {(f, e): _Group.combine(g for sid, g in groups.items() if info[sid] == (f, e))
             for f in faces for e in labels if (f, e) in info.values()}
    shown = tuple(e for e in labels if any(ce == e for _, ce in cells))  # with stimuli
    by_expr = {e: _Group.combine(g for (_, ce), g in cells.items() if ce == e) for e in shown}
    by_face = {f: _Group.combine(g for (cf, _), g in cells.items() if cf == f) for f in faces}
    names = (*labels, CANNOT_TELL)
    counts = np.zeros((len(info), len(names)), dtype=np.int64)
    rows = {sid: i for i, sid in enumerate(info)}
    for r in ratings:
        counts[rows[r.stimulus_id], names.index(r.label)] += 1
    return StudyReport(
        confidence, shown, faces,
        [StimulusResult(sid, *info[sid], groups[sid].summary(confidence)) for sid in sorted(info)],
        {key: g.summary(confidence) for key, g in cells.items()},
        {e: g.summary(confidence) for e, g in by_expr.items()},
        {f: g.summary(confidence) for f, g in by_face.items()},
        _Group.combine(groups.values()).summary(confidence),
        confusion_matrix(ratings, labels, shown), fleiss_kappa(counts), rater_agreement(ratings))


def _pct(x: float) -> str:
    return "-" if np.isnan(x) else f"{round(100 * x, 1):g}"


def _nat(x: float) -> str:
    return "-" if np.isnan(x) else f"{round(x, 3):g}"


def format_ci(ci: tuple[float, float], scale: float = 1.0, digits: int = 1) -> str:
    """A confidence interval as ``[lo, hi]`` (times ``scale``, ``digits`` decimals); - if NaN."""
    return "-" if np.isnan(ci[0]) else f"[{ci[0] * scale:.{digits}f}, {ci[1] * scale:.{digits}f}]"


def _table(header: Sequence[str], rows: Iterable[Sequence[str]], left: int = 1) -> list[str]:
    """Columns padded to width; the first ``left`` (text) columns left-aligned, others right."""
    rows = [list(header)] + [list(r) for r in rows]
    widths = [max(len(r[i]) for r in rows) for i in range(len(header))]
    lines = ["  ".join(c.ljust(w) if i < left else c.rjust(w) for i, (c, w) in
                       enumerate(zip(r, widths, strict=True))).rstrip() for r in rows]
    return [lines[0], "-" * len(lines[0]), *lines[1:]]


def _summary_row(key: str, s: Summary) -> list[str]:
    return [key, str(s.n), _pct(s.recognition), format_ci(s.recognition_ci, 100),
            _nat(s.naturalness), format_ci(s.naturalness_ci, 1, 2), _pct(s.share_ge3),
            _pct(s.share_eq5)]


def format_report(report: StudyReport, title: str = "") -> str:
    """Plain-text tables like the paper's Tables 4-6, plus confusion, kappa and raters."""
    pc = f"{round(100 * report.confidence, 1):g} % CI"
    head = ["n", "recog %", pc, "natural", pc, ">=3 %", "=5 %"]
    out = [title, ""] if title else []
    out += ["Table 4: recognition % / mean naturalness per face and expression"]
    out += _table(["face", *report.labels], (
        [f, *(f"{_pct(c.recognition)}/{_nat(c.naturalness)}" if (c := report.cells.get((f, e)))
              else "" for e in report.labels)] for f in report.faces))
    out += ["", "Per stimulus"]
    out += _table(["id", "face", "expression", *head], (
        [str(s.stimulus_id), s.face, *_summary_row(s.true_label, s.summary)]
        for s in report.stimuli), left=3)
    out += ["", "Table 5: per expression (mean over faces)"]
    out += _table(["expression", *head], (_summary_row(e, s)
                                          for e, s in report.per_expression.items()))
    out += ["", "Table 6: per face (mean over expressions)"]
    out += _table(["face", *head], (_summary_row(f, s) for f, s in report.per_face.items()))
    out += ["", "Overall (mean over stimuli)"]
    out += _table(["", *head], [_summary_row("all", report.overall)])
    cm = report.confusion
    out += ["", "Confusion matrix: rows intended, columns chosen; count (row %)"]
    out += _table(["intended", *cm.columns], (
        [row, *(f"{cm.counts[i, j]} ({_pct(cm.normalised[i, j])})" for j in range(len(cm.columns)))]
        for i, row in enumerate(cm.rows)))
    k = report.kappa
    kappa = (f"Fleiss' kappa (labels incl. '{CANNOT_TELL}'): {k.kappa:.3f} "
             f"(P_bar {k.p_bar:.3f}, P_e {k.p_e:.3f}; {k.n_subjects} stimuli, "
             f"{k.n_ratings} ratings)") if math.isfinite(k.kappa) else (
        "Fleiss' kappa: not available yet, it needs stimuli rated by at least two raters")
    out += ["", kappa, "", "Raters (r: Pearson with mean of the other raters; "
            "BT.500 screening on naturalness)"]
    out += _table(["rater", "n", "recog %", "mean nat", "r panel", "P", "Q", "screening"], (
        [r.rater, str(r.n), _pct(r.accuracy), f"{r.mean_naturalness:.2f}",
         "-" if np.isnan(r.r_panel) else f"{r.r_panel:.2f}", str(r.p), str(r.q),
         "REJECT" if r.rejected else "keep"] for r in report.raters))
    return "\n".join(out) + "\n"
