"""MOS rating GUI: keyboard-driven sessions, resume, revise rules, breaks, results, errors."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pytestqt")

from PySide6.QtCore import Qt  # noqa: E402
from PySide6.QtGui import QImage  # noqa: E402
from PySide6.QtWidgets import QMessageBox  # noqa: E402

from editor.resources import SAMPLE_FACE
from editor.study.mos import CANNOT_TELL, Study  # noqa: E402
from editor.study.mos_stats import analyse  # noqa: E402
from editor.study.stimuli import create_from_renders  # noqa: E402
from editor.ui.mos_rating import RatingWindow  # noqa: E402
from editor.ui.mos_results import ResultsWindow, ci, nat, pct  # noqa: E402

pytestmark = [pytest.mark.gui, pytest.mark.usefixtures("isolated_settings")]
SAMPLE = SAMPLE_FACE
LABELS = ["joy", "sadness", "fear"]
K = Qt.Key


def _image(i: int) -> np.ndarray:
    return np.random.default_rng(i).integers(0, 256, (40 + i, 30, 3), dtype=np.uint8)


def make_study(path: Path, allow_revise: bool = False, break_every: int = 0) -> Path:
    renders = [(face, lab, 1.0, _image(3 * f + e)) for f, face in enumerate(["Ann", "Bob"])
               for e, lab in enumerate(LABELS)]
    create_from_renders(path, "pilot", LABELS, renders, allow_revise, break_every).close()
    return path


@pytest.fixture
def boxes(monkeypatch) -> list[str]:
    shown: list[str] = []
    for kind in ("warning", "critical", "information"):
        monkeypatch.setattr(QMessageBox, kind,
                            lambda _p, _t, text, *a, **k: shown.append(text))
    return shown


def open_window(qtbot, path: Path, rater: str = "r1", seed: int | None = 7) -> RatingWindow:
    win = RatingWindow(str(path), rater, seed)
    qtbot.addWidget(win)
    win.show()
    return win


def plan(i: int, n_labels: int) -> tuple[int, str, int, int]:
    """Scripted answer for position i: (label key, label, naturalness, naturalness key)."""
    choice = i % (n_labels + 1)
    label_key = K.Key_0 if choice == n_labels else getattr(K, f"Key_{choice + 1}")
    label = CANNOT_TELL if choice == n_labels else LABELS[choice]
    score = i % 5 + 1
    score_key = getattr(K, f"Key_F{score}") if i % 2 else getattr(K, f"Key_{score}")
    return label_key, label, score, score_key


def rate_items(qtbot, win: RatingWindow, positions: range) -> dict[int, tuple[str, int]]:
    expected = {}
    for i in positions:
        stim = win.stimulus
        assert stim is not None and win.progress_label.text().startswith(f"{i + 1} / ")
        label_key, label, score, score_key = plan(i, len(LABELS))
        qtbot.keyClick(win, label_key)
        qtbot.keyClick(win, score_key)
        qtbot.keyClick(win, K.Key_Space if i % 2 else K.Key_Return)
        expected[stim.id] = (label, score)
    return expected


def test_whole_session_by_keyboard_commits_exactly_those_answers(qtbot, tmp_path, boxes):
    path = make_study(tmp_path / "s.db")
    win = open_window(qtbot, path)
    assert win.pages.currentIndex() == 0 and "Press Enter" in win.intro.text()
    qtbot.keyClick(win, K.Key_Return)
    order = win.session.order
    expected = rate_items(qtbot, win, range(6))
    assert win.pages.currentIndex() == 3 and "Thank you" in win.done_page.text()
    win.close()
    with Study.open(path) as study:
        answers = study.answers()
        assert tuple(study.start_session("r1").order) == order
    assert {a.stimulus_id: (a.label, a.naturalness) for a in answers} == expected
    assert [a.stimulus_id for a in answers] == list(order)
    assert all(a.response_ms > 0 and a.revisions == 0 for a in answers)
    assert any(a.label == CANNOT_TELL for a in answers) and not boxes


def test_incomplete_answer_is_not_committed_and_backspace_changes_the_label(qtbot, tmp_path):
    path = make_study(tmp_path / "s.db")
    win = open_window(qtbot, path)
    qtbot.keyClick(win, K.Key_Space)
    first = win.stimulus
    qtbot.keyClick(win, K.Key_Return)  # nothing chosen
    qtbot.keyClick(win, K.Key_2)  # label sadness, now in step 2
    qtbot.keyClick(win, K.Key_Return)  # no naturalness yet
    assert win.session.progress == (0, 6) and "first" in win.hint.text()
    qtbot.keyClick(win, K.Key_Backspace)  # back to step 1 of the same image
    qtbot.keyClick(win, K.Key_C)  # cannot tell
    qtbot.keyClick(win, K.Key_4)  # naturalness 4 (step 2)
    assert (win.label, win.naturalness) == (CANNOT_TELL, 4)
    qtbot.keyClick(win, K.Key_9)  # out of range: ignored
    qtbot.keyClick(win, K.Key_Return)
    assert win.session.progress == (1, 6) and win.stimulus != first
    win.close()
    with Study.open(path) as study:
        (a,) = study.answers()
    assert (a.stimulus_id, a.label, a.naturalness) == (first.id, CANNOT_TELL, 4)


def test_resume_after_closing_continues_in_the_same_order(qtbot, tmp_path):
    path = make_study(tmp_path / "s.db")
    win = open_window(qtbot, path, seed=11)
    qtbot.keyClick(win, K.Key_Return)
    order = win.session.order
    first = rate_items(qtbot, win, range(2))
    current = win.stimulus
    win.close()  # mid-session, image 3 shown but not answered
    win2 = open_window(qtbot, path, seed=None)
    assert win2.session.order == order and "Welcome back" in win2.intro.text()
    qtbot.keyClick(win2, K.Key_Return)
    assert win2.stimulus == current and win2.stimulus.id == order[2]
    assert win2.progress_label.text() == "3 / 6"
    rest = rate_items(qtbot, win2, range(2, 6))
    win2.close()
    with Study.open(path) as study:
        got = {a.stimulus_id: (a.label, a.naturalness) for a in study.answers("r1")}
    assert got == first | rest


def test_going_back_is_refused_unless_the_study_allows_revising(qtbot, tmp_path, boxes):
    path = make_study(tmp_path / "s.db")
    win = open_window(qtbot, path)
    qtbot.keyClick(win, K.Key_Return)
    rate_items(qtbot, win, range(2))
    current = win.stimulus
    qtbot.keyClick(win, K.Key_PageUp)
    assert win.stimulus == current and not win.revising and "not allow" in win.hint.text()
    qtbot.keyClick(win, K.Key_1)
    qtbot.keyClick(win, K.Key_F5)
    qtbot.keyClick(win, K.Key_Return)
    win.close()
    with Study.open(path) as study:
        answers = study.answers()
    assert len(answers) == 3 and all(a.revisions == 0 for a in answers) and not boxes


def test_revise_when_allowed_replaces_the_previous_answer_then_continues(qtbot, tmp_path):
    path = make_study(tmp_path / "s.db", allow_revise=True)
    win = open_window(qtbot, path)
    qtbot.keyClick(win, K.Key_Return)
    rate_items(qtbot, win, range(2))
    current, previous = win.stimulus, win.session.order[1]
    qtbot.keyClick(win, K.Key_PageUp)
    assert win.revising and win.stimulus.id == previous
    qtbot.keyClick(win, K.Key_3)
    qtbot.keyClick(win, K.Key_F2)
    qtbot.keyClick(win, K.Key_Return)
    assert win.stimulus == current and not win.revising
    win.close()
    with Study.open(path) as study:
        a = {x.stimulus_id: x for x in study.answers()}[previous]
    assert (a.label, a.naturalness, a.revisions) == ("fear", 2, 1)


def test_break_screen_every_n_items(qtbot, tmp_path):
    path = make_study(tmp_path / "s.db", break_every=2)
    win = open_window(qtbot, path)
    qtbot.keyClick(win, K.Key_Return)
    rate_items(qtbot, win, range(2))
    assert win.pages.currentIndex() == 2 and "2 of 6" in win.pause.text()
    qtbot.keyClick(win, K.Key_1)  # ignored on the break screen
    assert win.session.progress == (2, 6)
    qtbot.keyClick(win, K.Key_Return)
    assert win.pages.currentIndex() == 1 and win.progress_label.text() == "3 / 6"
    win.close()


def constructed_answers(path: Path) -> None:
    """Three raters with fixed answers: r1 always right, r2 half right, r3 'cannot tell'."""
    with Study.open(path) as study:
        for j, rater in enumerate(["r1", "r2", "r3"]):
            s = study.start_session(rater, seed=j)
            for i in range(6):
                stim = s.next_stimulus()
                label = (stim.label if j == 0 or (j == 1 and stim.id % 2)
                         else LABELS[(LABELS.index(stim.label) + 1) % 3] if j == 1
                         else CANNOT_TELL)
                s.answer(stim, label, 1 + (stim.id + j) % 5, 1000.0 + i)


def test_results_window_shows_the_statistics_of_the_study(qtbot, tmp_path, boxes):
    path = make_study(tmp_path / "s.db")
    constructed_answers(path)
    with Study.open(path) as study:
        report = analyse(study.answers(), study.labels, study.stimuli())
    win = ResultsWindow(path)
    qtbot.addWidget(win)
    win.show()
    table = win.tables["Per expression"]
    assert table.rowCount() == 3
    for row, (expr, s) in enumerate(report.per_expression.items()):
        cells = [table.item(row, c).text() for c in range(table.columnCount())]
        assert cells[:5] == [expr, str(s.n), pct(s.recognition), ci(s.recognition_ci, 100),
                             nat(s.naturalness)]
    overall = win.tables["Overall"]
    assert overall.item(0, 2).text() == pct(report.overall.recognition)
    assert overall.item(0, 2).text() == "50.0"  # r1 6/6, r2 3/6, r3 0/6 of 18
    t4 = win.tables["Face × expression"]
    c = report.cells[("Ann", "joy")]
    assert t4.item(0, 1).text() == f"{pct(c.recognition)} / {nat(c.naturalness)}"
    raters = win.tables["Raters"]
    assert [raters.item(i, 2).text() for i in range(3)] == ["100.0", "50.0", "0.0"]
    assert f"{report.kappa.kappa:.3f}" in win.summary_label.text()
    assert np.allclose(np.nan_to_num(win.confusion.image.image),
                       np.nan_to_num(report.confusion.normalised))
    assert [t.toPlainText().split()[0] for t in win.confusion.texts] == \
        [str(x) for x in report.confusion.counts.ravel()]
    assert np.allclose(win.nat_plot.values, [s.naturalness for s in
                                             report.per_expression.values()])
    assert "Table 6" in win.text and "Fleiss" in win.text
    out = tmp_path / "answers.csv"
    assert win.export_csv(str(out)) == 18
    with out.open() as f:
        assert len(list(csv.DictReader(f))) == 18
    png = tmp_path / "plots.png"
    assert win.save_plots(str(png))
    img = QImage(str(png))
    assert not img.isNull() and img.width() > 100 and not boxes
    win.close()


def test_results_of_an_unrated_study_show_dashes(qtbot, tmp_path, boxes):
    win = ResultsWindow(make_study(tmp_path / "s.db"))
    qtbot.addWidget(win)
    assert win.tables["Overall"].item(0, 1).text() == "0" and not boxes
    assert math.isnan(win.report.kappa.kappa)


@pytest.fixture
def main_window(qtbot, boxes):
    from editor.ui.main_window import MainWindow

    w = MainWindow()
    qtbot.addWidget(w)
    yield w
    w.close_without_prompt()


def test_corrupt_study_gives_a_message_not_a_crash(main_window, tmp_path, boxes):
    panel = main_window.extensions["mos_panel"]
    bad = tmp_path / "bad.db"
    bad.write_bytes(b"SQLite format 3\x00" + bytes(range(256)) * 8)
    assert not panel.open_study(str(bad))
    assert len(boxes) == 1 and "\n" not in boxes[0] and str(bad) in boxes[0]
    assert panel.path is None and not panel.act_rate.isEnabled()
    (tmp_path / "text.db").write_text("hello")
    assert not panel.open_study(str(tmp_path / "text.db")) and len(boxes) == 2
    good = make_study(tmp_path / "s.db")
    assert panel.open_study(str(good)) and panel.act_rate.isEnabled()
    good.write_bytes(b"garbage")  # broken after opening: rating must fail gracefully
    assert panel.rate(rater="x") is None and panel.results() is None and len(boxes) == 4


def test_menu_new_study_from_faces_rate_and_results(main_window, tmp_path, boxes):
    from editor.ui.mos_new import NewStudyDialog

    panel = main_window.extensions["mos_panel"]
    titles = [a.text() for a in main_window.menu("&Study").actions() if a.text()]
    assert titles == ["&New Study from Faces…", "&Open Study…", "&Rate…", "Re&sults…"]
    dialog = NewStudyDialog([str(SAMPLE)], main_window)
    dialog.presets["joy"].setChecked(False)
    dialog.paper_design()  # one click: the paper's five expressions at 100 %
    dialog.output.setText(str(tmp_path / "paper.db"))
    path = panel.create_study(dialog)
    assert path == tmp_path / "paper.db" and not boxes
    with Study.open(path) as study:
        assert study.labels == ("joy", "sadness", "anger", "fear", "surprise")
        assert [(s.face, s.intensity) for s in study.stimuli()] == [("sample_face", 1.0)] * 5
    win = panel.rate(rater="ann", seed=1)
    assert win is not None and win in panel.windows
    results = panel.results()
    assert results is not None and results.tables["Overall"].item(0, 1).text() == "0"
    win.close()
    results.close()
