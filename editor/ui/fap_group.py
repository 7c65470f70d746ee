"""A collapsible group of FAP rows (one MPEG-4 FAP group) with a group reset button."""

from __future__ import annotations

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import QFrame, QHBoxLayout, QToolButton, QVBoxLayout, QWidget

from editor.engine.faps import Fap

from .fap_row import FapRow


class FapGroup(QWidget):
    """Header (arrow + group name, reset) over the rows of one FAP group."""

    resetRequested = Signal(int)

    def __init__(self, group: int, faps: list[Fap], parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.group = group
        self.name = faps[0].group_name
        self.header = QToolButton()
        self.header.setCheckable(True)
        self.header.setChecked(True)
        self.header.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextBesideIcon)
        self.header.setArrowType(Qt.ArrowType.DownArrow)
        self.header.setText(f"{self.name}  ({len(faps)})")
        self.header.setAutoRaise(True)
        self.header.setStyleSheet("QToolButton { font-weight: bold; border: none; }")
        self.reset = QToolButton()
        self.reset.setText("Reset")
        self.reset.setAutoRaise(True)
        self.reset.setToolTip(f"Reset every FAP of the group '{self.name}' to 0")
        head = QHBoxLayout()
        head.setContentsMargins(0, 0, 0, 0)
        head.addWidget(self.header)
        head.addStretch(1)
        head.addWidget(self.reset)
        self.body = QFrame()
        self.body.setFrameShape(QFrame.Shape.NoFrame)
        body_lay = QVBoxLayout(self.body)
        body_lay.setContentsMargins(8, 0, 0, 4)
        body_lay.setSpacing(1)
        self.rows = [FapRow(f) for f in faps]
        for r in self.rows:
            body_lay.addWidget(r)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.setSpacing(0)
        lay.addLayout(head)
        lay.addWidget(self.body)
        self._user_expanded = True
        self._filtering = False
        self.header.toggled.connect(self._on_toggled)
        self.reset.clicked.connect(lambda: self.resetRequested.emit(self.group))

    @property
    def numbers(self) -> list[int]:
        return [r.number for r in self.rows]

    def is_expanded(self) -> bool:
        return self.header.isChecked()

    def set_expanded(self, on: bool) -> None:
        self.header.setChecked(on)

    def _on_toggled(self, on: bool) -> None:
        self.body.setVisible(on)
        self.header.setArrowType(Qt.ArrowType.DownArrow if on else Qt.ArrowType.RightArrow)
        if not self._filtering:
            self._user_expanded = on

    def apply_filter(self, text: str) -> int:
        """Show only the matching rows; returns their number. While filtering, a group with
        matches opens; clearing the filter restores the user's open/closed state."""
        shown = 0
        for r in self.rows:
            ok = r.matches(text)
            r.setVisible(ok)
            shown += ok
        self.setVisible(shown > 0)
        if text.strip():
            self._filtering = True
            self.header.setChecked(True)
        else:
            self._filtering = False
            self.header.setChecked(self._user_expanded)
        return shown
