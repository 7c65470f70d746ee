"""The FAP panel: a slider + spin box for every FAP 3-68, grouped, filterable, resettable.

User actions on the rows become model calls here: a slider drag is one gesture (one undo
entry), spin-box steps and key presses on one FAP merge into one entry, and with *Link left /
right* on, the mirrored FAP (``Fap.mirror``) gets the same value in the same command. Model
changes come back through ``DocumentModel.changed`` and are written into the rows with their
signals blocked.
"""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QCheckBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QScrollArea,
    QVBoxLayout,
    QWidget,
)

from editor.engine.faps import FAPS

from .document_model import Document, DocumentModel
from .fap_group import FapGroup
from .fap_row import FapRow
from .qt_utils import settings

#: QSettings key of the *Link left/right* box (remembered between sessions).
LINK_KEY = "faps/linkLeftRight"


class FapPanel(QWidget):
    """Every low-level FAP by MPEG-4 group, with a filter, resets and a left/right link."""

    def __init__(self, model: DocumentModel, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.model = model
        self.filter = QLineEdit()
        self.filter.setPlaceholderText("Filter FAPs: name or number")
        self.filter.setClearButtonEnabled(True)
        self.link = QCheckBox("Link left/right")
        self.link.setChecked(settings().value(LINK_KEY, False, type=bool))
        self.link.toggled.connect(lambda on: settings().setValue(LINK_KEY, bool(on)))
        self.link.setToolTip("Move the mirrored FAP (left <-> right) together with the one you "
                             "edit")
        self.reset_all = QPushButton("Reset all")
        self.reset_all.setToolTip("Set every FAP to 0 (one undo step)")
        self.expand_all = QPushButton("Expand")
        self.collapse_all = QPushButton("Collapse")
        self.empty = QLabel("No FAP matches the filter.")
        self.empty.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.empty.hide()

        top = QHBoxLayout()
        top.addWidget(self.filter, 1)
        top.addWidget(self.link)
        bar = QHBoxLayout()
        bar.addWidget(self.expand_all)
        bar.addWidget(self.collapse_all)
        bar.addStretch(1)
        bar.addWidget(self.reset_all)

        self.groups = [FapGroup(g, faps) for g, faps in FAPS.groups().items()]
        self.rows: dict[int, FapRow] = {r.number: r for g in self.groups for r in g.rows}
        inner = QWidget()
        inner_lay = QVBoxLayout(inner)
        inner_lay.setContentsMargins(0, 0, 0, 0)
        inner_lay.setSpacing(2)
        for g in self.groups:
            inner_lay.addWidget(g)
        inner_lay.addWidget(self.empty)
        inner_lay.addStretch(1)
        self.scroll = QScrollArea()
        self.scroll.setWidgetResizable(True)
        self.scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        self.scroll.setWidget(inner)

        lay = QVBoxLayout(self)
        lay.setContentsMargins(4, 4, 4, 4)
        lay.addLayout(top)
        lay.addLayout(bar)
        lay.addWidget(self.scroll, 1)

        for r in self.rows.values():
            r.gestureStarted.connect(self._on_gesture_started)
            r.valuePreview.connect(self._on_preview)
            r.gestureFinished.connect(self._on_gesture_finished)
            r.valueEdited.connect(self._on_edited)
            r.editFinished.connect(lambda _n: self.model.seal())
            r.resetRequested.connect(self._on_reset)
        for g in self.groups:
            g.resetRequested.connect(self._on_reset_group)
        self.filter.textChanged.connect(self.apply_filter)
        self.reset_all.clicked.connect(lambda: self.model.reset_faps(None, "Reset all FAPs"))
        self.expand_all.clicked.connect(lambda: self._expand(True))
        self.collapse_all.clicked.connect(lambda: self._expand(False))
        model.changed.connect(self._on_changed)
        self.setEnabled(model.doc is not None)
        if model.doc is not None:
            self._on_changed(None, model.doc)

    # ------------------------------------------------------------------ rows -> model
    def linked(self, number: int, value: float) -> dict[int, float]:
        """The FAP values one edit sets: the FAP, and its mirror when linked."""
        out = {number: value}
        mirror = FAPS[number].mirror
        if self.link.isChecked() and mirror is not None:
            out[mirror] = value
        return out

    def _on_gesture_started(self, number: int) -> None:
        self.model.begin_gesture()

    def _on_preview(self, number: int, value: float) -> None:
        if not self.model.in_gesture:
            self.model.begin_gesture()
        self.model.preview_faps(self.linked(number, value))

    def _on_gesture_finished(self, number: int) -> None:
        self.model.commit_gesture(f"Set {self._label(number)}")

    def _on_edited(self, number: int, value: float) -> None:
        self.model.set_faps(self.linked(number, value), f"Set {self._label(number)}",
                            key=f"fap{number}{'+m' if self.link.isChecked() else ''}")

    def _on_reset(self, number: int) -> None:
        self.model.set_faps(self.linked(number, 0.0), f"Reset {self._label(number)}")

    def _on_reset_group(self, group: int) -> None:
        g = next(g for g in self.groups if g.group == group)
        self.model.reset_faps(g.numbers, f"Reset {g.name}")

    def _label(self, number: int) -> str:
        f = FAPS[number]
        m = f.mirror
        return f"{f.name} + {FAPS[m].name}" if self.link.isChecked() and m else f.name

    # ------------------------------------------------------------------ model -> rows
    def _on_changed(self, old: Document | None, new: Document) -> None:
        self.setEnabled(True)
        if old is None:
            idx = np.arange(2, 68)
        elif old.faps is new.faps:
            return
        else:
            idx = np.flatnonzero(old.faps != new.faps)
        for i in idx:
            row = self.rows.get(int(i) + 1)
            if row is not None:
                row.set_value(float(new.faps[i]))

    # ------------------------------------------------------------------ view
    def apply_filter(self, text: str) -> int:
        """Show the FAPs whose number or name matches ``text``; returns how many."""
        shown = sum(g.apply_filter(text) for g in self.groups)
        self.empty.setVisible(shown == 0)
        return shown

    def _expand(self, on: bool) -> None:
        for g in self.groups:
            g.set_expanded(on)
