"""The Action Units panel: a slider per supported FACS AU (upper / lower face, L and R where
FACS scores sides), kept consistent with the FAP sliders through the one document model; and
Animation > Import / Export CSV (Live Link Face, AU CSV).

The document holds FAPs only. The panel shows the AU intensities fitted to the current FAPs
(:func:`editor.formats.facs.faps_to_aus`, bounded least squares) whenever the document changes
from elsewhere (FAP sliders, presets, undo). Moving an AU slider adds that AU's FAP column
times the change of intensity to the FAPs (so the FAPs no AU touches, and the part of a
pattern the AUs cannot express, stay as they were): a drag is one gesture (one undo entry),
keyboard steps on one slider merge into one entry. Its own edits are not re-fitted, so a
slider stays where the user put it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFileDialog,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QScrollArea,
    QSlider,
    QVBoxLayout,
    QWidget,
)

from editor.errors import FapStudioError
from editor.formats.blends import EXPRESSIONS
from editor.formats.facs import au_table, faps_to_aus
from editor.formats.presets import apply_preset, get_preset

from .document_model import Document, DocumentModel
from .qt_utils import run_guarded, signals_blocked

STEPS = 100  # slider resolution: intensity in hundredths
NAME_WIDTH = 150  # pixels for "AU12 Lip Corner Puller" (longer names are elided)
CSV_FILTER = ("Live Link Face CSV (*.csv);;AU CSV, OpenFace style (*.csv);;"
              "MPEG-4 FAP files (*.fap)")
_KIND_OF_FILTER = {"Live Link": "arkit", "AU CSV": "au", "MPEG-4": "fap"}


def _letter(x: float) -> str:
    """The FACS letter of an intensity (the nearest of A-E at 0.2 steps; '' below A's half)."""
    letters = au_table().letters
    if x < 0.1:
        return ""
    return min(letters, key=lambda k: abs(letters[k] - x))


class AuSlider(QSlider):
    """A horizontal 0..100 slider for one AU column (no wheel steals while scrolling)."""

    def __init__(self, column: str) -> None:
        super().__init__(Qt.Orientation.Horizontal)
        self.column = column
        self.setRange(0, STEPS)
        self.setSingleStep(5)
        self.setPageStep(20)
        self.setMinimumWidth(70)
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)

    def wheelEvent(self, e) -> None:  # noqa: N802 - Qt override
        if self.hasFocus():
            super().wheelEvent(e)
        else:
            e.ignore()


class AuPanel(QWidget):
    """Sliders for the table's AUs; edits go to the :class:`DocumentModel` as FAP changes."""

    def __init__(self, model: DocumentModel, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.model = model
        self.table = au_table()
        self.weights = np.zeros(len(self.table.columns))
        self.sliders: dict[str, AuSlider] = {}
        self.values: dict[str, QLabel] = {}
        self._expected: Document | None = None  # the document our last edit made

        self.link = QCheckBox("Link L/R")
        self.link.setChecked(True)
        self.link.setToolTip("Move the left and right side of an AU together")
        self.preset_box = QComboBox()
        self.preset_box.addItems([n for i, n in EXPRESSIONS.items() if i])
        self.as_aus = QPushButton("Preset as AUs")
        self.as_aus.setToolTip("Set the FAPs to the chosen emotion preset expressed as AUs (the "
                               "AU fit of the preset; what AUs cannot express is dropped)")
        self.fit_label = QLabel("")
        self.fit_label.setWordWrap(True)
        top = QHBoxLayout()
        top.addWidget(self.link)
        top.addStretch(1)
        top.addWidget(self.preset_box)
        top.addWidget(self.as_aus)

        inner = QWidget()
        lay = QVBoxLayout(inner)
        lay.setContentsMargins(0, 0, 0, 0)
        for region, title in (("upper", "Upper face"), ("lower", "Lower face")):
            box = QGroupBox(title)
            grid = QGridLayout(box)
            grid.setContentsMargins(4, 2, 4, 2)
            grid.setVerticalSpacing(1)
            r = 0
            for col, stretch in ((2, 1), (5, 1)):  # the sliders take the spare width
                grid.setColumnStretch(col, stretch)
            for a in (a for a in self.table.aus if a.region == region):
                name = QLabel()
                fm = name.fontMetrics()
                name.setText(fm.elidedText(f"AU{a.number} {a.name}",
                                           Qt.TextElideMode.ElideRight, NAME_WIDTH))
                name.setFixedWidth(NAME_WIDTH + 4)
                name.setToolTip(f"AU{a.number} {a.name}: {a.source}")
                grid.addWidget(name, r, 0)
                sides = ("L", "R") if a.sided else ("",)
                for j, side in enumerate(sides):
                    col = f"{a.number}{side}"
                    s = AuSlider(col)
                    s.setToolTip(f"AU{a.number}{' ' + side if side else ''}: intensity 0-1 "
                                 "(A 0.2 ... E 1.0)" + ("; left = the subject's left"
                                                        if side == "L" else ""))
                    v = QLabel("")
                    v.setFixedWidth(v.fontMetrics().horizontalAdvance("0.00 E") + 4)
                    self.sliders[col], self.values[col] = s, v
                    if side:
                        grid.addWidget(QLabel(side), r, 1 + 3 * j)
                    grid.addWidget(s, r, 2 + 3 * j, 1, 1 if a.sided else 4)
                    grid.addWidget(v, r, 3 + 3 * j if a.sided else 6)
                    s.sliderPressed.connect(lambda c=col: self._begin(c))
                    s.sliderReleased.connect(lambda c=col: self._finish(c))
                    s.valueChanged.connect(lambda val, c=col: self._on_slider(c, val))
                r += 1
            lay.addWidget(box)
        lay.addStretch(1)
        scroll = QScrollArea()
        scroll.setWidgetResizable(True)
        scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        scroll.setWidget(inner)
        outer = QVBoxLayout(self)
        outer.setContentsMargins(4, 4, 4, 4)
        outer.addLayout(top)
        outer.addWidget(scroll, 1)
        outer.addWidget(self.fit_label)

        self.as_aus.clicked.connect(lambda: self.preset_as_aus(self.preset_box.currentText()))
        model.changed.connect(self._on_changed)
        self.setEnabled(model.doc is not None)
        if model.doc is not None:
            self._on_changed(None, model.doc)

    # ------------------------------------------------------------------ sliders -> model
    def columns_for(self, column: str) -> list[str]:
        """The columns one slider moves: itself, and its other side when linked."""
        if self.link.isChecked() and column[-1] in "LR":
            return [column[:-1] + "L", column[:-1] + "R"]
        return [column]

    def _faps_for(self, base: np.ndarray, column: str, value: float) -> np.ndarray:
        """``base`` FAPs with the column(s) of ``column`` moved from their weights to value."""
        out = np.asarray(base, np.float64).copy()
        for c in self.columns_for(column):
            k = self.table.column_index(c)
            out += (value - self.weights[k]) * self.table.matrix[:, k]
        return out

    def _begin(self, column: str) -> None:
        self.model.begin_gesture()

    def _finish(self, column: str) -> None:
        self.model.commit_gesture(f"Set {self._label(column)}")

    def _label(self, column: str) -> str:
        """``AU12`` for a linked pair, ``AU12L`` for one side, ``AU26`` for a midline AU."""
        cols = self.columns_for(column)
        return f"AU{column[:-1]}" if len(cols) == 2 else f"AU{column}"

    def _on_slider(self, column: str, v: int) -> None:
        doc = self.model.doc
        if doc is None:
            return
        value = v / STEPS
        slider = self.sliders[column]
        new = doc.with_fap_vector(self._faps_for(doc.faps, column, value))
        for c in self.columns_for(column):
            self.weights[self.table.column_index(c)] = value
            self._show(c)
        self._expected = new
        if slider.isSliderDown():
            self.model.preview(new)
        else:  # keyboard, wheel, a click on the track: one entry per slider
            self.model.push(new, f"Set {self._label(column)}",
                            key=f"au{column}{'+m' if len(self.columns_for(column)) > 1 else ''}")

    def _show(self, column: str) -> None:
        x = float(self.weights[self.table.column_index(column)])
        with signals_blocked(self.sliders[column]):
            self.sliders[column].setValue(int(round(x * STEPS)))
        self.values[column].setText(f"{x:.2f} {_letter(x)}".rstrip())

    # ------------------------------------------------------------------ model -> sliders
    def _on_changed(self, old: Document | None, new: Document) -> None:
        self.setEnabled(True)
        if new is self._expected or (old is not None and old.faps is new.faps):
            return  # our own edit (sliders already show it) or no FAP change
        self._expected = None
        self.refit(new.faps)

    def refit(self, faps: np.ndarray) -> None:
        """Show the AU intensities fitted to ``faps`` and how much of them AUs explain."""
        self.weights = faps_to_aus(faps)[0]
        for c in self.sliders:
            self._show(c)
        back = self.table.matrix @ self.weights
        f = np.asarray(faps, np.float64)
        used = np.abs(self.table.matrix).sum(axis=1) > 0
        rest = np.abs(f[~used]).max(initial=0.0)
        err = np.abs(back - f)[used].max(initial=0.0)
        self.fit_label.setText(f"AU fit of the FAPs: largest difference {err:.0f} FAPU"
                               + (f"; FAPs no AU moves (gaze, head, tongue, ...) up to "
                                  f"{rest:.0f}" if rest else ""))

    # ------------------------------------------------------------------ presets
    def preset_as_aus(self, name: str) -> None:
        """Set the FAPs to an emotion preset as the AU combination closest to it."""
        if self.model.doc is None:
            return
        target = apply_preset(get_preset(name), 1.0)
        weights = faps_to_aus(target)[0]
        faps = self.table.matrix @ weights
        kept = self.model.doc.faps.astype(np.float64).copy()
        used = np.abs(self.table.matrix).sum(axis=1) > 0
        kept[used] = faps[used]  # gaze, head, tongue: left as they are
        aus = ", ".join(f"AU{c} {w:.2f}" for c, w in zip(self.table.columns, weights,
                                                         strict=True) if w >= 0.05)
        self.model.push(self.model.doc.with_fap_vector(kept), f"{name} as AUs")
        self.fit_label.setToolTip(f"{name}: {aus}")


# ------------------------------------------------------------------ Animation > CSV
def import_csv(window, path: str | None = None) -> bool:
    """Animation > Import CSV: a Live Link Face or AU CSV (or .fap) into the playback panel."""
    panel = getattr(window, "playback_panel", None)
    if panel is None:
        return False
    if path is None:
        path, _ = QFileDialog.getOpenFileName(window, "Import animation CSV", "",
                                              "Face-tracking CSV (*.csv);;All files (*)")
        if not path:
            return False

    def load() -> None:
        from editor.formats.facecsv import read_animation  # the CSV readers: on first use

        seq, _kind, notes = read_animation(path)
        panel.load_sequence(seq, str(path))
        if notes:
            window.statusBar().showMessage("; ".join(notes), 8000)

    return run_guarded(window, "Import CSV", load)[0]


def export_csv(window, path: str | None = None, kind: str | None = None) -> bool:
    """Animation > Export CSV: the playback sequence (or the keyframes, built) as a Live Link
    Face CSV or AU CSV (``kind`` "arkit" / "au"; from the dialog's filter when None)."""
    panel = getattr(window, "playback_panel", None)
    if panel is None:
        return False
    if panel.seq is None and not panel.build_from_keys():
        return False
    if path is None:
        start = f"{Path(panel.path or panel.seq.name).stem}.csv"
        path, chosen = QFileDialog.getSaveFileName(window, "Export animation CSV", start,
                                                   CSV_FILTER)
        if not path:
            return False
        kind = next((k for p, k in _KIND_OF_FILTER.items() if chosen.startswith(p)), "arkit")
    seq = panel.seq

    def write() -> None:
        from editor.formats.facecsv import write_animation  # the CSV writers: on first use

        if kind not in ("arkit", "au", "fap"):
            raise FapStudioError(f"unknown CSV kind {kind!r}")
        write_animation(seq, path, kind)

    return run_guarded(window, "Export CSV", write)[0]


def install(window) -> AuPanel:
    """Add the "Action Units" dock and Animation > Import / Export CSV to the main window."""
    panel = AuPanel(window.model)
    window.au_panel = panel
    window.au_dock = window.add_panel_dock("Action Units", panel, "auDock")
    if getattr(window, "playback_panel", None) is not None:
        from PySide6.QtGui import QAction

        m = window.menu("&Animation")
        imp = QAction("Import CSV (Live Link Face / AUs)…", window)
        imp.setStatusTip("Open a Live Link Face (ARKit blendshapes) or OpenFace-style AU CSV "
                         "for playback")
        imp.triggered.connect(lambda _c=False: import_csv(window))
        exp = QAction("Export CSV (Live Link Face / AUs)…", window)
        exp.setStatusTip("Save the sequence as ARKit blendshapes (Live Link Face CSV) or AU "
                         "intensities (fitted; what they cannot express is lost)")
        exp.triggered.connect(lambda _c=False: export_csv(window))
        acts = m.actions()  # after Open/Save FAP Sequence
        save = getattr(window.playback_panel, "act_save", None)
        i = acts.index(save) + 1 if save in acts else 0
        m.insertActions(acts[i] if i < len(acts) else None, [imp, exp])
        window.act_import_csv, window.act_export_csv = imp, exp
    return panel

