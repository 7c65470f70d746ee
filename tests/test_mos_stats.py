"""Statistics of MOS studies (editor.study.mos_stats) against hand-computed values and the paper."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from editor.study.mos import CANNOT_TELL
from editor.study.mos_stats import (
    analyse,
    bt500_screening,
    confusion_matrix,
    fleiss_kappa,
    format_report,
    rater_agreement,
    t_interval,
    wilson_interval,
)

EXPRESSIONS = ["joy", "sadness", "anger", "fear", "surprise"]
# SPEC §4 Table 4: recognition % / mean naturalness per image (Male1-sadness corrected to 3.9).
TABLE4 = {
    "Male1": [(100, 3.9), (60, 3.9), (40, 4.0), (40, 3.4), (100, 3.6)],
    "Female2": [(100, 4.2), (40, 3.6), (90, 3.3), (50, 3.5), (60, 3.7)],
    "Female3": [(100, 3.9), (70, 3.9), (60, 3.3), (30, 2.9), (100, 3.4)],
    "Child4": [(100, 3.4), (70, 4.0), (70, 3.9), (30, 3.7), (90, 3.8)],
}
TABLE5 = {"joy": (100, 3.85), "sadness": (60, 3.85), "anger": (65, 3.625),
          "fear": (37.5, 3.375), "surprise": (87.5, 3.625)}
TABLE6 = {"Male1": (68, 3.76), "Female2": (68, 3.66), "Female3": (72, 3.48),
          "Child4": (72, 3.76)}
# Per image (in TABLE4 order): how many of the 10 scores are 5 and how many are 2, chosen so that
# the paper's shares hold too (47 fives = 23.5 %, 20 scores below 3 -> 90 % >= 3).
FIVES_TWOS = [(2, 1)] * 5 + [(2, 0)] + [(2, 1)] * 7 + [(0, 1), (2, 1), (2, 1), (3, 1), (5, 1),
                                                      (4, 1), (5, 2)]


@dataclass(frozen=True)
class R:
    rater: str
    stimulus_id: int
    face: str
    true_label: str
    label: str
    naturalness: int


def _scores(total: int, fives: int, twos: int) -> list[int]:
    """10 integer scores with the given sum, number of 5s and 2s (the rest 3s and 4s)."""
    rest = 10 - fives - twos
    fours = total - 5 * fives - 2 * twos - 3 * rest
    assert 0 <= fours <= rest
    return [5] * fives + [2] * twos + [4] * fours + [3] * (rest - fours)


def table4_ratings() -> list[R]:
    """10 raters x 20 images reproducing Table 4 exactly (counts and integer scores)."""
    out, sid = [], 0
    for face, row in TABLE4.items():
        for expr, (rec, nat) in zip(EXPRESSIONS, row, strict=True):
            scores = _scores(round(nat * 10), *FIVES_TWOS[sid])
            wrong = [CANNOT_TELL, *(e for e in EXPRESSIONS if e != expr)]
            for j in range(10):
                rater = (j + 3 * sid) % 10  # spread correct answers and scores over raters
                label = expr if j < rec // 10 else wrong[j % len(wrong)]
                out.append(R(f"r{rater}", sid, face, expr, label, scores[(j + sid) % 10]))
            sid += 1
    return out


def test_wilson_interval_hand_values() -> None:
    z = 1.959963984540054
    p, n = 0.7, 10
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    lo, hi = wilson_interval(7, 10)
    assert (lo, hi) == pytest.approx((centre - half, centre + half), abs=1e-12)
    assert (lo, hi) == pytest.approx((0.3968, 0.8922), abs=1e-4)  # published value for 7/10
    assert wilson_interval(0, 10) == pytest.approx((0.0, z * z / (10 + z * z)), abs=1e-12)
    assert wilson_interval(10, 10)[1] == 1.0
    assert wilson_interval(7, 10, 0.99)[0] < lo
    assert all(math.isnan(x) for x in wilson_interval(0, 0))


def test_t_interval_hand_values() -> None:
    half = 2.7764451051977987 * math.sqrt(0.5) / math.sqrt(5)  # t(0.975, 4) * s / sqrt(n)
    assert t_interval([3, 4, 5, 4, 4]) == pytest.approx((4 - half, 4 + half), abs=1e-9)
    assert t_interval([4, 4, 4]) == (4.0, 4.0)
    assert all(math.isnan(x) for x in t_interval([3]))


def test_confusion_matrix_small() -> None:
    ratings = [R("a", 1, "F", "joy", "joy", 3), R("b", 1, "F", "joy", "fear", 3),
               R("c", 1, "F", "joy", CANNOT_TELL, 3), R("a", 2, "F", "fear", "fear", 3),
               R("b", 2, "F", "fear", "joy", 3), R("c", 3, "F", "joy", "joy", 3)]
    cm = confusion_matrix(ratings, ["joy", "fear", "anger"])
    assert cm.columns == ("joy", "fear", "anger", CANNOT_TELL)
    np.testing.assert_array_equal(cm.counts, [[2, 1, 0, 1], [1, 1, 0, 0], [0, 0, 0, 0]])
    np.testing.assert_allclose(cm.normalised[:2], [[0.5, 0.25, 0, 0.25], [0.5, 0.5, 0, 0]])
    assert np.isnan(cm.normalised[2]).all()
    with pytest.raises(ValueError):
        confusion_matrix([R("a", 1, "F", "joy", "disgust", 3)], ["joy"])


def test_fleiss_kappa_wikipedia_example() -> None:
    # Fleiss (1971) / Wikipedia "Fleiss' kappa" worked example: 10 subjects, 14 raters, 5 cats.
    counts = np.array([[0, 0, 0, 0, 14], [0, 2, 6, 4, 2], [0, 0, 3, 5, 6], [0, 3, 9, 2, 0],
                       [2, 2, 8, 1, 1], [7, 7, 0, 0, 0], [3, 2, 6, 3, 0], [2, 5, 3, 2, 2],
                       [6, 5, 2, 1, 0], [0, 2, 2, 3, 7]])
    k = fleiss_kappa(counts)
    assert k.p_bar == pytest.approx(0.378, abs=5e-4)
    assert k.p_e == pytest.approx(0.213, abs=5e-4)
    assert k.kappa == pytest.approx(0.210, abs=5e-4)
    assert (k.n_subjects, k.n_ratings) == (10, 140)


def test_fleiss_kappa_unequal_raters_hand_value() -> None:
    # n_i = 2, 2, 3 (the last row, one rating only, is left out): P = (1, 0, 1), P_bar = 2/3,
    # p = (6/7, 1/7), P_e = 37/49, kappa = (2/3 - 37/49) / (12/49) = -13/36.
    k = fleiss_kappa(np.array([[2, 0], [1, 1], [3, 0], [0, 1]]))
    assert (k.p_bar, k.p_e, k.kappa) == pytest.approx((2 / 3, 37 / 49, -13 / 36))
    assert k.n_subjects == 3
    assert fleiss_kappa(np.array([[3, 0], [0, 3]])).kappa == pytest.approx(1.0)
    assert math.isnan(fleiss_kappa(np.array([[3, 0], [3, 0]])).kappa)  # P_e == 1


def test_fleiss_kappa_equals_statsmodels_on_equal_counts() -> None:
    """With every subject rated equally often ours is Fleiss (1971): statsmodels agrees."""
    inter_rater = pytest.importorskip("statsmodels.stats.inter_rater")
    rng = np.random.default_rng(7)
    for raters, cats in ((3, 2), (10, 6), (14, 5)):
        counts = np.array([rng.multinomial(raters, rng.dirichlet(np.ones(cats)))
                           for _ in range(25)])
        assert fleiss_kappa(counts).kappa == pytest.approx(
            inter_rater.fleiss_kappa(counts, method="fleiss"), abs=1e-12)


def test_intervals_equal_statsmodels() -> None:
    proportion = pytest.importorskip("statsmodels.stats.proportion")
    weightstats = pytest.importorskip("statsmodels.stats.weightstats")
    for k, n in ((7, 10), (1, 30), (140, 200)):
        want = proportion.proportion_confint(k, n, alpha=0.05, method="wilson")
        assert wilson_interval(k, n) == pytest.approx(want, abs=1e-12)
    x = [3, 4, 5, 4, 4, 2, 5, 3]
    want = weightstats.DescrStatsW(np.array(x, float)).tconfint_mean(alpha=0.05)
    assert t_interval(x) == pytest.approx(want, abs=1e-12)


def test_table4_reproduces_tables_5_6_and_overall() -> None:
    ratings = table4_ratings()
    assert len(ratings) == 200 and len({r.rater for r in ratings}) == 10
    rep = analyse(ratings, EXPRESSIONS)
    for face, row in TABLE4.items():
        for expr, (rec, nat) in zip(EXPRESSIONS, row, strict=True):
            cell = rep.cells[(face, expr)]
            assert (cell.n, cell.recognition, cell.naturalness) == pytest.approx(
                (10, rec / 100, nat))
    for expr, (rec, nat) in TABLE5.items():
        s = rep.per_expression[expr]
        assert (s.n, s.recognition, s.naturalness) == pytest.approx((40, rec / 100, nat))
    for face, (rec, nat) in TABLE6.items():
        s = rep.per_face[face]
        assert (s.n, s.recognition, s.naturalness) == pytest.approx((50, rec / 100, nat))
    o = rep.overall
    assert (o.n, o.n_correct, o.recognition, o.naturalness) == pytest.approx((200, 140, 0.70,
                                                                              3.665))
    assert (o.share_ge3, o.share_eq5) == pytest.approx((0.90, 0.235))
    assert o.recognition_ci == pytest.approx(wilson_interval(140, 200))
    all_scores = [r.naturalness for r in ratings]
    assert o.naturalness_ci == pytest.approx(t_interval(all_scores))
    assert o.naturalness_ci[0] < 3.665 < o.naturalness_ci[1]
    np.testing.assert_array_equal(np.diag(rep.confusion.counts), [40, 24, 26, 15, 35])
    np.testing.assert_array_equal(rep.confusion.counts.sum(axis=1), [40] * 5)
    assert rep.kappa.n_subjects == 20 and -1 <= rep.kappa.kappa <= 1
    assert [r.n for r in rep.raters] == [20] * 10


def _section(text: str, title: str) -> list[str]:
    lines = text.splitlines()
    start = next(i for i, x in enumerate(lines) if x.startswith(title))
    end = next((i for i in range(start + 1, len(lines)) if not lines[i].strip()), len(lines))
    return lines[start + 3:end]  # skip title, header and rule


def test_format_report_prints_paper_tables() -> None:
    text = format_report(analyse(table4_ratings(), EXPRESSIONS), "Table 4 fixture")
    assert text.startswith("Table 4 fixture\n")
    table4 = {x.split()[0]: x.split()[1:] for x in _section(text, "Table 4:")}
    assert table4["Male1"] == ["100/3.9", "60/3.9", "40/4", "40/3.4", "100/3.6"]
    assert table4["Child4"] == ["100/3.4", "70/4", "70/3.9", "30/3.7", "90/3.8"]
    table5 = {x.split()[0]: x.split() for x in _section(text, "Table 5:")}
    assert table5["fear"][1:3] == ["40", "37.5"] and table5["fear"][5] == "3.375"
    table6 = {x.split()[0]: x.split() for x in _section(text, "Table 6:")}
    assert table6["Female3"][1:3] == ["50", "72"] and table6["Female3"][5] == "3.48"
    overall = _section(text, "Overall")[0].split()
    assert overall[:3] == ["all", "200", "70"] and overall[5] == "3.665"
    assert overall[-2:] == ["90", "23.5"]
    confusion = {x.split()[0]: x for x in _section(text, "Confusion")}
    assert confusion["joy"].split()[1:3] == ["40", "(100)"]


def test_rater_correlation_with_panel_hand_value() -> None:
    scores = {"A": [1, 2, 3, 4, 5], "B": [2, 2, 3, 4, 4], "C": [5, 4, 3, 2, 1]}
    ratings = [R(k, j, "F", "joy", "joy" if k != "C" else "fear", v)
               for k, vs in scores.items() for j, v in enumerate(vs)]
    res = {r.rater: r for r in rater_agreement(ratings)}
    # A vs mean(B, C) = (3.5, 3, 3, 3, 2.5): cov sum -2, sum dx^2 10, sum dy^2 0.5
    assert res["A"].r_panel == pytest.approx(-2 / math.sqrt(5))
    # C vs mean(A, B) = (1.5, 2, 3, 4, 4.5): cov sum -8, sum dx^2 10, sum dy^2 6.5
    assert res["C"].r_panel == pytest.approx(-8 / math.sqrt(65))
    assert math.isnan(res["B"].r_panel)  # mean(A, C) = 3 everywhere: no variance
    assert res["A"].accuracy == 1.0 and res["C"].accuracy == 0.0
    assert res["A"].n_panel == 5 and res["A"].mean_naturalness == 3.0


def test_bt500_hand_computed_column() -> None:
    # (1,1,1,1,1,1,2,2,2,3): mean 1.5, S = sqrt(4.5 / 9), beta2 = 0.5625 / 0.45^2 = 2.78 (normal)
    # -> band 1.5 ± 2 S = [0.086, 2.914]: only the 3 is outside (P).
    col = np.array([1, 1, 1, 1, 1, 1, 2, 2, 2, 3], float)[:, None]
    p, q, _ = bt500_screening(col)
    assert p.tolist() == [0] * 9 + [1] and q.tolist() == [0] * 10
    # (1 x 9, 3): beta2 = 1.0512 / 0.36^2 = 8.1 (not normal) -> band ± sqrt(20) S = ± 2.83:
    # the 3 (1.8 above the mean, > 2 S = 1.26) is NOT counted.
    p, q, _ = bt500_screening(np.array([1] * 9 + [3], float)[:, None])
    assert p.sum() == 0 and q.sum() == 0


def test_bt500_rejects_inconsistent_rater_not_biased_one() -> None:
    low, high = [1, 1, 1, 1, 1, 1, 2, 2, 2], [5, 5, 5, 5, 5, 5, 4, 4, 4]
    cols, biased = [], []
    for j in range(20):  # rater 9 says 3 everywhere: above the band on "low" stimuli, below on
        cols.append((low if j % 2 == 0 else high) + [3])  # "high" ones -> P = Q = 10
        biased.append((low + [3]) if j % 2 == 0 else (high + [5]))  # P = 10, Q = 0
    p, q, rejected = bt500_screening(np.array(cols, float).T)
    assert (p[9], q[9], rejected[9]) == (10, 10, True)
    assert not rejected[:9].any() and p[:9].sum() == q[:9].sum() == 0
    p, q, rejected = bt500_screening(np.array(biased, float).T)
    assert (p[9], q[9], rejected[9]) == (10, 0, False)  # |P - Q| / (P + Q) = 1 >= 0.3
    u = np.array(cols, float).T
    u[9, 1::2] = np.nan  # rater 9 rated only the "low" half: P = 10 of 10, Q = 0 -> kept
    p, q, rejected = bt500_screening(u)
    assert (p[9], q[9], rejected[9]) == (10, 0, False)


def test_analyse_keeps_unrated_stimuli_and_empty_groups() -> None:
    @dataclass(frozen=True)
    class S:
        id: int
        face: str
        label: str

    ratings = [R("a", 1, "F", "joy", "joy", 5), R("b", 1, "F", "joy", "joy", 4)]
    rep = analyse(ratings, ["joy", "anger", "fear"], [S(1, "F", "joy"), S(2, "G", "fear")])
    assert [s.summary.n for s in rep.stimuli] == [2, 0]
    assert rep.labels == ("joy", "fear") and list(rep.per_expression) == ["joy", "fear"]
    assert rep.confusion.rows == ("joy", "fear")  # no stimulus is meant as anger ...
    assert rep.confusion.columns == ("joy", "anger", "fear", CANNOT_TELL)  # ... but choosable
    assert t_interval([5, 4])[1] > 5 and rep.stimuli[0].summary.naturalness_ci == (1.0, 5.0)
    assert math.isnan(rep.per_expression["fear"].recognition)
    assert rep.overall.recognition == 1.0 and rep.overall.naturalness == 4.5
    assert "G" in rep.faces and math.isnan(rep.per_face["G"].naturalness)
    text = format_report(rep)
    assert "fear" in text and "-" in _section(text, "Table 5:")[1]


def test_report_of_an_unrated_study_has_no_nan_kappa():
    """With no stimulus rated by two raters the report says why kappa is missing (not 'nan')."""
    text = format_report(analyse([], EXPRESSIONS))
    line = next(x for x in text.splitlines() if x.startswith("Fleiss' kappa"))
    assert "nan" not in line and "at least two raters" in line
