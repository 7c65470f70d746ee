"""Results window of a MOS study: the paper's Tables 4-6, confusion heatmap, bar charts with
95 % CIs, rater agreement/screening, Fleiss' kappa, CSV and PNG export."""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from pathlib import Path

from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QAbstractItemView,
    QFileDialog,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QMessageBox,
    QPlainTextEdit,
    QPushButton,
    QTableWidget,
    QTableWidgetItem,
    QTabWidget,
    QVBoxLayout,
    QWidget,
)

from editor.errors import FapStudioError
from editor.safeio import atomic_file
from editor.study.mos import CANNOT_TELL, Study
from editor.study.mos_stats import StudyReport, Summary, analyse, format_report
from editor.study.mos_stats import format_ci as ci
from editor.study.qc import mos_answers, qc_summary, rater_qc
from editor.study.stimuli import export_answers_csv

from .plots import BarPlot, ConfusionPlot

SUMMARY_HEADER = ["n", "recognition %", "95 % CI", "naturalness", "95 % CI", "naturalness ≥ 3 %",
                  "naturalness = 5 %"]
SUMMARY_TIPS = ["answers", "share of answers naming the intended expression",
                "Wilson 95 % interval of the recognition rate",
                "mean naturalness score on the rating window's scale (1 = very unnatural … "
                "5 = very realistic)",
                "t-based 95 % interval of the mean naturalness",
                "share of naturalness scores of 3 or more", "share of naturalness scores of 5"]
RATER_HEADER = ["rater", "n", "recognition %", "naturalness", "r with panel", "n shared",
                "P (above)", "Q (below)", "BT.500 screening"]
RATER_TIPS = [
    "rater id", "answers given by this rater",
    "share of this rater's answers naming the intended expression",
    "this rater's mean naturalness score (1–5)",
    "Pearson correlation of this rater's naturalness scores with the mean of the other raters "
    "on the same stimuli ('-' with fewer than 3 shared stimuli)",
    "stimuli this rater shares with the other raters (the correlation's basis)",
    "ITU-R BT.500 screening: scores above the per-stimulus interval of the panel",
    "ITU-R BT.500 screening: scores below the per-stimulus interval of the panel",
    "ITU-R BT.500 observer screening outcome: REJECT when too many scores fall outside the "
    "panel's interval (indicative with fewer than 15 raters)"]
#: Tab name -> what it holds (its tooltip); the paper's table numbers are named there.
TAB_TIPS = {
    "Face × expression": "recognition % / mean naturalness of each face and expression (the "
                         "paper's Table 4)",
    "Per stimulus": "every stimulus on its own",
    "Per expression": "every expression over all faces (the paper's Table 5)",
    "Per face": "every face over all expressions (the paper's Table 6)",
    "Overall": "all answers together",
    "Raters": "agreement of each rater with the others and BT.500 screening",
}


def pct(x: float) -> str:
    return "-" if math.isnan(x) else f"{100 * x:.1f}"


def nat(x: float) -> str:
    return "-" if math.isnan(x) else f"{x:.2f}"


def summary_cells(s: Summary) -> list[str]:
    """The table cells of one summary (same columns as :data:`SUMMARY_HEADER`)."""
    return [str(s.n), pct(s.recognition), ci(s.recognition_ci, 100), nat(s.naturalness),
            ci(s.naturalness_ci, 1, 2), pct(s.share_ge3), pct(s.share_eq5)]


def make_table(header: Sequence[str], rows: Sequence[Sequence[str]],
               tips: Sequence[str] = ()) -> QTableWidget:
    """A read-only table; text columns left, numbers right-aligned; ``tips`` explain the
    columns (header tooltips)."""
    table = QTableWidget(len(rows), len(header))
    table.setHorizontalHeaderLabels(list(header))
    for j, tip in enumerate(tips):
        if tip and j < len(header):
            table.horizontalHeaderItem(j).setToolTip(tip)
    table.verticalHeader().setVisible(False)
    table.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
    for i, row in enumerate(rows):
        for j, text in enumerate(row):
            item = QTableWidgetItem(text)
            numeric = text[:1].isdigit() or text[:1] in "-[" and text != "-"
            if numeric:
                item.setTextAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
            table.setItem(i, j, item)
    table.resizeColumnsToContents()
    return table


class ResultsWindow(QWidget):
    """Reads the study once (:meth:`reload`), shows tables and plots; the file stays closed
    in between, so raters can keep rating while the results are open."""

    def __init__(self, study_path: str | Path, parent: QWidget | None = None) -> None:
        super().__init__(parent, Qt.WindowType.Window)
        self.path = Path(study_path)
        self.report: StudyReport | None = None
        self.text = ""
        self.tabs = QTabWidget()
        self.summary_label = QLabel()
        self.summary_label.setWordWrap(True)
        buttons = QHBoxLayout()
        for text, slot in (("Reload", self.reload_guarded), ("Export CSV…", self.export_csv),
                           ("Save Plots PNG…", self.save_plots)):
            b = QPushButton(text)
            b.clicked.connect(slot)
            buttons.addWidget(b)
        buttons.addStretch(1)
        self.status = QLabel()  # what the last export wrote
        buttons.addWidget(self.status)
        lay = QVBoxLayout(self)
        lay.addWidget(self.summary_label)
        lay.addWidget(self.tabs, 1)
        lay.addLayout(buttons)
        self.plots = QWidget()
        grid = QGridLayout(self.plots)
        self.confusion = ConfusionPlot()
        self.nat_plot = BarPlot("Mean naturalness per expression (95 % CI)", "naturalness 1–5",
                                (0.0, 5.0))
        self.rec_plot = BarPlot("Recognition per expression (95 % CI)", "recognition %",
                                (0.0, 100.0))
        grid.addWidget(self.confusion, 0, 0, 1, 2)
        grid.addWidget(self.rec_plot, 1, 0)
        grid.addWidget(self.nat_plot, 1, 1)
        grid.setRowStretch(0, 3)
        grid.setRowStretch(1, 2)
        self.tables: dict[str, QTableWidget] = {}
        self.resize(1100, 850)
        self.reload()

    # ------------------------------------------------------------------ data
    def reload(self) -> None:
        """Re-read the study and rebuild every tab (raises :class:`FapStudioError`)."""
        with Study.open(self.path) as study:
            answers, stimuli, labels = mos_answers(study), study.stimuli(), study.labels
            name, n_raters = study.name, len(study.raters())
            qc = qc_summary(rater_qc(study))  # P.808-style QC: excluded raters are not in MOS
        report = analyse(answers, labels, stimuli)
        title = (f"Study {name!r}: {len(stimuli)} stimuli, {n_raters} "
                 f"rater{'s' if n_raters != 1 else ''}, "
                 f"{len(answers)} answers")
        self.setWindowTitle(f"Results – {name}")
        self.report, self.text = report, format_report(report, title)
        k = report.kappa
        if math.isnan(k.kappa) or k.n_subjects == 0:
            kappa = ("Fleiss' kappa: not available yet, it needs stimuli rated by at least two "
                     f"raters ({n_raters} rater{'s' if n_raters != 1 else ''} so far)")
        else:
            kappa = (f"Fleiss' kappa (labels incl. '{CANNOT_TELL}') {k.kappa:.3f} over "
                     f"{k.n_subjects} stimuli")
        o = report.overall
        self.summary_label.setText(
            f"<b>{title}</b><br>Overall recognition {pct(o.recognition)} % "
            f"{ci(o.recognition_ci, 100)}, naturalness {nat(o.naturalness)} "
            f"{ci(o.naturalness_ci, 1, 2)}; {kappa}<br>{html.escape(qc)}")
        self._fill(report)

    def reload_guarded(self) -> None:
        try:
            self.reload()
        except FapStudioError as e:
            QMessageBox.warning(self, "Cannot read the study", str(e))

    def _fill(self, r: StudyReport) -> None:
        current = self.tabs.currentIndex()
        while self.tabs.count():
            w = self.tabs.widget(0)
            self.tabs.removeTab(0)
            if w is not self.plots:
                w.deleteLater()
        t4 = [[f, *(f"{pct(c.recognition)} / {nat(c.naturalness)}"
                    if (c := r.cells.get((f, e))) else "" for e in r.labels)] for f in r.faces]
        stim = [[str(s.stimulus_id), s.face, s.true_label, *summary_cells(s.summary)]
                for s in r.stimuli]
        expr = [[e, *summary_cells(s)] for e, s in r.per_expression.items()]
        face = [[f, *summary_cells(s)] for f, s in r.per_face.items()]
        overall = [["all", *summary_cells(r.overall)]]
        raters = [[x.rater, str(x.n), pct(x.accuracy), nat(x.mean_naturalness),
                   "-" if math.isnan(x.r_panel) else f"{x.r_panel:.2f}", str(x.n_panel),
                   str(x.p), str(x.q), "REJECT" if x.rejected else "keep"] for x in r.raters]
        cell_tip = "recognition % / mean naturalness (1–5)"
        self.tables = {
            "Face × expression": make_table(["face", *r.labels], t4,
                                            ["face", *[cell_tip] * len(r.labels)]),
            "Per stimulus": make_table(["id", "face", "expression", *SUMMARY_HEADER], stim,
                                       ["", "", "", *SUMMARY_TIPS]),
            "Per expression": make_table(["expression", *SUMMARY_HEADER], expr,
                                         ["", *SUMMARY_TIPS]),
            "Per face": make_table(["face", *SUMMARY_HEADER], face, ["", *SUMMARY_TIPS]),
            "Overall": make_table(["", *SUMMARY_HEADER], overall, ["", *SUMMARY_TIPS]),
            "Raters": make_table(RATER_HEADER, raters, RATER_TIPS),
        }
        self.tabs.addTab(self.plots, "Plots")
        self.tabs.setTabToolTip(0, "confusion matrix, recognition and naturalness per "
                                   "expression with 95 % intervals")
        for name, table in self.tables.items():
            self.tabs.addTab(table, name)
            self.tabs.setTabToolTip(self.tabs.count() - 1, TAB_TIPS[name])
        text = QPlainTextEdit(self.text)
        text.setReadOnly(True)
        text.setStyleSheet("font-family: monospace;")
        self.tabs.addTab(text, "Report text")
        self.tabs.setCurrentIndex(max(current, 0))
        self.confusion.set_confusion(r.confusion)
        names = list(r.per_expression)
        sums = list(r.per_expression.values())
        self.nat_plot.set_data(names, [s.naturalness for s in sums],
                               [s.naturalness_ci for s in sums])
        self.rec_plot.set_data(names, [100 * s.recognition for s in sums],
                               [(100 * s.recognition_ci[0], 100 * s.recognition_ci[1])
                                for s in sums])

    # ------------------------------------------------------------------ export
    def export_csv(self, path: str | None = None) -> int | None:
        """Write all answers in long format; returns the number of rows (None if cancelled)."""
        if not path:
            path, _ = QFileDialog.getSaveFileName(self, "Export answers",
                                                  str(self.path.with_suffix(".csv")),
                                                  "CSV (*.csv)")
        if not path:
            return None
        try:
            with Study.open(self.path) as study:
                n = export_answers_csv(study, path)
            self.status.setText(f"Exported {n} answers to {path}")
            return n
        except FapStudioError as e:
            QMessageBox.warning(self, "Cannot export the answers", str(e))
            return None

    def save_plots(self, path: str | None = None) -> bool:
        """Save a PNG of the plots tab (confusion + bar charts) as shown."""
        if not path:
            path, _ = QFileDialog.getSaveFileName(self, "Save plots",
                                                  str(self.path.with_suffix(".png")),
                                                  "PNG (*.png)")
        if not path:
            return False
        shown = self.tabs.currentWidget()
        self.tabs.setCurrentWidget(self.plots)  # a hidden tab may have no valid geometry
        image = self.plots.grab()
        self.tabs.setCurrentWidget(shown)
        try:  # atomically: a failed save leaves no partial PNG
            with atomic_file(path) as tmp:
                if not image.save(str(tmp), "PNG"):
                    raise FapStudioError(f"{path}: cannot write PNG")
            ok = True
            self.status.setText(f"Saved the plots to {path}")
        except FapStudioError:
            ok = False
        if not ok:
            QMessageBox.warning(self, "Cannot save the plots", f"{path}: cannot write PNG")
        return ok
