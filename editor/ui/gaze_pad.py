"""Eye-gaze pad: drag a dot; x drives the eyeball yaw of both eyes, y their pitch.

The pad is drawn as seen on the photo: right = the image's right (the face's own left, positive
yaw FAPs 23/24), down = looking down (positive pitch FAPs 25/26). Press/drag/release is one
gesture (one undo entry), double-click centres the gaze, arrow keys nudge it.
"""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QPointF, QRectF, QSize, Qt
from PySide6.QtGui import QColor, QKeyEvent, QMouseEvent, QPainter, QPaintEvent, QPen
from PySide6.QtWidgets import QSizePolicy, QWidget

from editor.engine.faps import FAPS

from .document_model import Document, DocumentModel

#: MPEG-4 angular unit: 1e-5 rad.
AU_DEGREES = 1e-5 * 180.0 / np.pi
#: Height of the readout strip under the pad (the dot never covers it).
READOUT_H = 18
YAW = (23, 24)
PITCH = (25, 26)


class GazePad(QWidget):
    """A square pad with a dot; (x, y) in [-1, 1]^2 maps onto the FAP ranges of 23-26."""

    def __init__(self, model: DocumentModel, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.model = model
        self.yaw_max = min(FAPS[n].range[1] for n in YAW)
        self.pitch_max = min(FAPS[n].range[1] for n in PITCH)
        self._xy = np.zeros(2)
        self.setMinimumSize(120, 120 + READOUT_H)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Expanding)
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        self.setToolTip("Eye gaze: drag the dot (x = yaw FAPs 23/24, y = pitch FAPs 25/26, both "
                        "eyes); double-click to centre; arrow keys nudge")
        model.changed.connect(self._on_changed)
        if model.doc is not None:
            self._on_changed(None, model.doc)

    def sizeHint(self) -> QSize:
        return QSize(170, 170 + READOUT_H)

    # ------------------------------------------------------------------ geometry
    def pad_rect(self) -> QRectF:
        """The square the dot moves in; the gaze readout is written under it."""
        h = self.height() - READOUT_H
        s = min(self.width(), h) - 12
        return QRectF((self.width() - s) / 2, (h - s) / 2, s, s)

    def readout(self) -> str:
        """The gaze in degrees (right/left, up/down as seen on the photo)."""
        f = self.values(self._xy)
        yaw, pitch = f[YAW[0]] * AU_DEGREES, f[PITCH[0]] * AU_DEGREES
        return f"yaw {yaw:+.1f}°   pitch {pitch:+.1f}°"

    def to_pad(self, pos: QPointF) -> np.ndarray:
        """Widget position -> pad coordinates in [-1, 1]^2."""
        r = self.pad_rect()
        x = (pos.x() - r.center().x()) / (r.width() / 2)
        y = (pos.y() - r.center().y()) / (r.height() / 2)
        return np.clip([x, y], -1.0, 1.0)

    def to_widget(self, xy: np.ndarray) -> QPointF:
        r = self.pad_rect()
        return QPointF(r.center().x() + xy[0] * r.width() / 2,
                       r.center().y() + xy[1] * r.height() / 2)

    def values(self, xy: np.ndarray) -> dict[int, float]:
        """FAP values for pad coordinates ``xy`` (AU)."""
        yaw, pitch = round(float(xy[0]) * self.yaw_max), round(float(xy[1]) * self.pitch_max)
        return {YAW[0]: yaw, YAW[1]: yaw, PITCH[0]: pitch, PITCH[1]: pitch}

    @property
    def position(self) -> np.ndarray:
        """The dot in pad coordinates [-1, 1]^2."""
        return self._xy.copy()

    # ------------------------------------------------------------------ model -> view
    def _on_changed(self, old: Document | None, new: Document) -> None:
        f = new.faps
        xy = np.array([(f[YAW[0] - 1] + f[YAW[1] - 1]) / 2 / self.yaw_max,
                       (f[PITCH[0] - 1] + f[PITCH[1] - 1]) / 2 / self.pitch_max])
        if not np.array_equal(xy, self._xy):
            self._xy = xy
            self.update()

    # ------------------------------------------------------------------ input
    def mousePressEvent(self, e: QMouseEvent) -> None:
        if e.button() != Qt.MouseButton.LeftButton or self.model.doc is None:
            return super().mousePressEvent(e)
        self.model.begin_gesture()
        self.model.preview_faps(self.values(self.to_pad(e.position())))

    def mouseMoveEvent(self, e: QMouseEvent) -> None:
        if self.model.in_gesture and e.buttons() & Qt.MouseButton.LeftButton:
            self.model.preview_faps(self.values(self.to_pad(e.position())))

    def mouseReleaseEvent(self, e: QMouseEvent) -> None:
        if e.button() == Qt.MouseButton.LeftButton and self.model.in_gesture:
            self.model.commit_gesture("Move gaze")

    def mouseDoubleClickEvent(self, e: QMouseEvent) -> None:
        if e.button() == Qt.MouseButton.LeftButton:
            self.model.set_faps(self.values(np.zeros(2)), "Centre gaze")

    def keyPressEvent(self, e: QKeyEvent) -> None:
        step = {Qt.Key.Key_Left: (-1, 0), Qt.Key.Key_Right: (1, 0), Qt.Key.Key_Up: (0, -1),
                Qt.Key.Key_Down: (0, 1)}.get(Qt.Key(e.key()))
        if step is None or self.model.doc is None:
            return super().keyPressEvent(e)
        xy = np.clip(self._xy + 0.05 * np.array(step), -1.0, 1.0)
        self.model.set_faps(self.values(xy), "Move gaze", key="gaze")

    # ------------------------------------------------------------------ painting
    def paintEvent(self, e: QPaintEvent) -> None:
        p = QPainter(self)
        p.setRenderHint(QPainter.RenderHint.Antialiasing)
        r = self.pad_rect()
        pal = self.palette()
        p.setPen(QPen(pal.mid().color(), 1))
        p.setBrush(pal.base())
        p.drawRoundedRect(r, 8, 8)
        p.setPen(QPen(pal.mid().color(), 1, Qt.PenStyle.DashLine))
        c = r.center()
        p.drawLine(QPointF(r.left(), c.y()), QPointF(r.right(), c.y()))
        p.drawLine(QPointF(c.x(), r.top()), QPointF(c.x(), r.bottom()))
        p.drawEllipse(c, r.width() / 4, r.height() / 4)
        dot = self.to_widget(self._xy)
        p.setPen(QPen(pal.text().color(), 1))
        p.setBrush(QColor(70, 70, 70, 60))
        p.drawLine(c, dot)
        p.setPen(QPen(QColor(20, 20, 20), 1.5))
        p.setBrush(QColor(230, 70, 60) if self.hasFocus() else QColor(200, 90, 80))
        p.drawEllipse(dot, 8, 8)
        p.setBrush(QColor(20, 20, 20))
        p.drawEllipse(dot, 3, 3)
        p.setPen(pal.text().color())
        strip = QRectF(0, self.height() - READOUT_H, self.width(), READOUT_H)
        p.drawText(strip, Qt.AlignmentFlag.AlignCenter, self.readout())
        p.end()
