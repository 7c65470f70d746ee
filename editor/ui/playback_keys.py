"""Keyframe authoring: (time, FAP vector) keys taken from the current FAP state.

The widget shows the document's keys (:class:`~editor.formats.document.Animation`, sorted by
time) and reports every edit with ``edited(text)``: its owner pushes the new keys, fps and
interpolation into the document as one undo command and calls :meth:`show_animation` back.
"Add key" stores the document's low-level FAPs at the time in the spin box (the playhead's
time while a sequence is loaded), "Remove" drops the selected key, and
:meth:`KeyframeEditor.build` interpolates them (linear or smoothstep) into a
:class:`~editor.formats.fapfile.FapSequence` with
:func:`~editor.formats.expressions.sequence_from_keyframes`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from PySide6.QtCore import Signal
from PySide6.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QGridLayout,
    QGroupBox,
    QListWidget,
    QPushButton,
    QWidget,
)

from editor.errors import FapStudioError
from editor.formats.document import Animation

if TYPE_CHECKING:
    from editor.formats.fapfile import FapSequence


def low_level(vector: np.ndarray) -> np.ndarray:
    """A (68,) float64 copy with FAP 1/2 zeroed (what a keyframe stores)."""
    v = np.array(vector, np.float64).reshape(68)
    v[:2] = 0
    return v


class KeyframeEditor(QGroupBox):
    """Keys list + time / fps / interpolation and the add, remove, clear, build buttons.

    Signals
    -------
    addRequested(float)
        "Add key" at this time: the owner answers with :meth:`add_key` and the current FAPs.
    buildRequested()
        "Build" was pressed.
    edited(str)
        The keys, fps or interpolation were changed by the user (the text names the edit).
    """

    addRequested = Signal(float)
    buildRequested = Signal()
    edited = Signal(str)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__("Keyframes", parent)
        self.keys: list[tuple[float, np.ndarray]] = []
        self.time = QDoubleSpinBox()
        self.time.setRange(0.0, 600.0)
        self.time.setDecimals(2)
        self.time.setSingleStep(0.25)
        self.time.setSuffix(" s")
        self.time.setToolTip("Time of the next key (follows the playhead)")
        self.fps = QDoubleSpinBox()
        self.fps.setRange(1.0, 120.0)
        self.fps.setDecimals(1)
        self.fps.setValue(25.0)
        self.fps.setSuffix(" fps")
        self.interp = QComboBox()
        self.interp.addItems(["linear", "smoothstep"])
        self.list = QListWidget()
        self.list.setMaximumHeight(90)
        self.add_button = QPushButton("Add key")
        self.add_button.setToolTip("Store the current FAPs as a key at the time on the left")
        self.remove_button = QPushButton("Remove")
        self.clear_button = QPushButton("Clear")
        self.build_button = QPushButton("Build")
        self.build_button.setToolTip("Interpolate the keys into a sequence and load it")

        g = QGridLayout(self)
        g.setContentsMargins(4, 4, 4, 4)
        g.addWidget(self.time, 0, 0)
        g.addWidget(self.add_button, 0, 1)
        g.addWidget(self.remove_button, 0, 2)
        g.addWidget(self.clear_button, 0, 3)
        g.addWidget(self.list, 1, 0, 1, 4)
        g.addWidget(self.interp, 2, 0)
        g.addWidget(self.fps, 2, 1)
        g.addWidget(self.build_button, 2, 2, 1, 2)

        self.add_button.clicked.connect(lambda: self.addRequested.emit(self.time.value()))
        self.remove_button.clicked.connect(self.remove_selected)
        self.clear_button.clicked.connect(self.clear)
        self.build_button.clicked.connect(self.buildRequested.emit)
        self.list.currentRowChanged.connect(self._on_row)
        self.fps.valueChanged.connect(lambda v: self.edited.emit(f"Keyframe rate {v:g} fps"))
        self.interp.currentTextChanged.connect(
            lambda t: self.edited.emit(f"Keyframe interpolation {t}"))
        self._refresh()

    def show_animation(self, anim: Animation) -> None:
        """Show the document's keys, fps and interpolation (no ``edited``)."""
        self.keys = [(t, np.asarray(v, np.float64)) for t, v in anim.keys]
        with _blocked(self.fps, self.interp):
            self.fps.setValue(anim.fps)
            self.interp.setCurrentText(anim.interpolation)
        self._refresh()

    def animation(self, base: Animation) -> Animation:
        """``base`` with the keys, fps and interpolation shown here."""
        return base.replace(keys=tuple(self.keys), fps=self.fps.value(),
                            interpolation=self.interp.currentText())

    # ------------------------------------------------------------------ keys
    def add_key(self, t: float, vector: np.ndarray) -> None:
        """Add (or replace, at the same time) a key."""
        t = round(float(t), 4)
        self.keys = [k for k in self.keys if abs(k[0] - t) > 1e-6]
        self.keys.append((t, low_level(vector)))
        self.keys.sort(key=lambda k: k[0])
        self._refresh()
        self.edited.emit(f"Add key at {t:g} s")

    def remove_selected(self) -> None:
        row = self.list.currentRow()
        if 0 <= row < len(self.keys):
            t = self.keys.pop(row)[0]
            self._refresh()
            self.edited.emit(f"Remove key at {t:g} s")

    def clear(self) -> None:
        self.keys = []
        self._refresh()
        self.edited.emit("Clear keys")

    def set_keys(self, keys: list[tuple[float, np.ndarray]]) -> None:
        with _blocked(self):
            self.keys = []
            for t, v in keys:
                self.add_key(t, v)
        self._refresh()
        self.edited.emit("Set keys")

    def build(self) -> FapSequence:
        """The interpolated sequence; :class:`FapStudioError` with a one-line reason."""
        if not self.keys:
            raise FapStudioError("add at least one keyframe first")
        from editor.formats.keyframes import sequence_from_keyframes  # with the .fap module

        try:
            return sequence_from_keyframes(self.keys, self.fps.value(),
                                           self.interp.currentText(), name="keyframes")
        except ValueError as e:
            raise FapStudioError(f"cannot build the sequence: {e}") from None

    def _refresh(self) -> None:
        self.list.clear()
        for t, v in self.keys:
            used = int(np.count_nonzero(v))
            self.list.addItem(f"{t:6.2f} s   {used} FAPs set" if used else f"{t:6.2f} s   neutral")
        self.remove_button.setEnabled(bool(self.keys))
        self.clear_button.setEnabled(bool(self.keys))
        self.build_button.setEnabled(bool(self.keys))

    def _on_row(self, row: int) -> None:
        if 0 <= row < len(self.keys):
            self.time.setValue(self.keys[row][0])


def _blocked(*objects: QWidget):  # noqa: ANN202 -- a context manager
    from .qt_utils import signals_blocked

    return signals_blocked(*objects)
