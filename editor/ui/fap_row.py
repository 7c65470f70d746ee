"""One FAP's control: label, slider and spin box (in FAPU), reset button.

The row never touches the model: it reports what the user did through signals (a slider drag is
``gestureStarted`` / ``valuePreview`` ... / ``gestureFinished``; a spin-box step, a key press or
a click on the slider track is ``valueEdited``), and the panel turns them into model calls.
Model values come back through :meth:`FapRow.set_value` with the widgets' signals blocked.
Both widgets are limited to the FAP table's range, so no other value can be entered.
"""

from __future__ import annotations

from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QWheelEvent
from PySide6.QtWidgets import (
    QHBoxLayout,
    QLabel,
    QSizePolicy,
    QSlider,
    QSpinBox,
    QToolButton,
    QWidget,
)

from editor.engine.faps import Fap

from .qt_utils import signals_blocked


def _step(lo: float, hi: float, parts: int) -> int:
    """A round step of about ``(hi - lo) / parts``."""
    raw = max((hi - lo) / parts, 1.0)
    for nice in (1, 2, 5, 10, 20, 25, 50, 100, 200, 250, 500, 1000, 2000, 2500, 5000):
        if nice >= raw:
            return nice
    return int(raw)


class FapSlider(QSlider):
    """A horizontal slider that ignores the wheel unless it has focus (so the panel scrolls)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(Qt.Orientation.Horizontal, parent)
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)

    def wheelEvent(self, e: QWheelEvent) -> None:
        if self.hasFocus():
            super().wheelEvent(e)
        else:
            e.ignore()


class FapSpinBox(QSpinBox):
    """A spin box that ignores the wheel unless it has focus."""

    def wheelEvent(self, e: QWheelEvent) -> None:
        if self.hasFocus():
            super().wheelEvent(e)
        else:
            e.ignore()


class FapRow(QWidget):
    """Slider + spin box + reset for one FAP (values in FAPU, integers)."""

    gestureStarted = Signal(int)
    valuePreview = Signal(int, float)
    gestureFinished = Signal(int)
    valueEdited = Signal(int, float)
    editFinished = Signal(int)
    resetRequested = Signal(int)

    def __init__(self, fap: Fap, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.fap = fap
        lo, hi = int(round(fap.range[0])), int(round(fap.range[1]))
        self.label = QLabel(f"{fap.number:>2} {fap.name}")
        self.label.setMinimumWidth(150)
        self.label.setSizePolicy(QSizePolicy.Policy.Preferred, QSizePolicy.Policy.Preferred)
        self.slider = FapSlider()
        self.slider.setRange(lo, hi)
        self.slider.setSingleStep(_step(lo, hi, 200))
        self.slider.setPageStep(_step(lo, hi, 20))
        self.slider.setMinimumWidth(90)
        self.spin = FapSpinBox()
        self.spin.setRange(lo, hi)
        self.spin.setSingleStep(_step(lo, hi, 100))
        self.spin.setKeyboardTracking(False)
        self.spin.setAccelerated(True)
        self.spin.setSuffix(f" {fap.unit}")
        self.spin.setFixedWidth(96)
        self.spin.setAlignment(Qt.AlignmentFlag.AlignRight)
        self.reset = QToolButton()
        self.reset.setText("\u21ba")
        self.reset.setAutoRaise(True)
        self.reset.setToolTip(f"Reset {fap.name} to 0")
        for w in (self.label, self.slider, self.spin):
            w.setToolTip(fap.tooltip)
        lay = QHBoxLayout(self)
        lay.setContentsMargins(4, 0, 2, 0)
        lay.setSpacing(4)
        lay.addWidget(self.label, 3)
        lay.addWidget(self.slider, 4)
        lay.addWidget(self.spin)
        lay.addWidget(self.reset)
        self._value = 0.0
        self.slider.sliderPressed.connect(lambda: self.gestureStarted.emit(fap.number))
        self.slider.sliderReleased.connect(lambda: self.gestureFinished.emit(fap.number))
        self.slider.valueChanged.connect(self._on_slider)
        self.spin.valueChanged.connect(self._on_spin)
        self.spin.editingFinished.connect(lambda: self.editFinished.emit(fap.number))
        self.reset.clicked.connect(lambda: self.resetRequested.emit(fap.number))

    @property
    def number(self) -> int:
        return self.fap.number

    def value(self) -> float:
        """The value shown (FAPU)."""
        return self._value

    def set_value(self, value: float) -> None:
        """Show a model value (no signals are emitted)."""
        self._value = float(value)
        iv = int(round(value))
        with signals_blocked(self.slider, self.spin):
            self.slider.setValue(iv)
            self.spin.setValue(iv)
        bold = value != 0
        if self.label.font().bold() != bold:
            f = self.label.font()
            f.setBold(bold)
            self.label.setFont(f)

    def matches(self, text: str) -> bool:
        """Filter: the FAP number (exact) or a part of its name or description."""
        t = text.strip().lower()
        if not t:
            return True
        if t.isdigit():
            return int(t) == self.fap.number
        return t in self.fap.name.lower() or t in self.fap.description.lower()

    def _on_slider(self, v: int) -> None:
        with signals_blocked(self.spin):
            self.spin.setValue(v)
        if self.slider.isSliderDown():
            self.valuePreview.emit(self.fap.number, float(v))
        else:  # keyboard, wheel or a click on the track
            self.valueEdited.emit(self.fap.number, float(v))

    def _on_spin(self, v: int) -> None:
        with signals_blocked(self.slider):
            self.slider.setValue(v)
        self.valueEdited.emit(self.fap.number, float(v))
