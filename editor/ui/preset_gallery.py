"""Preset gallery: thumbnails of the current face rendered with every preset; click to apply.

The thumbnails are rendered with the core (``face.render``) at full intensity and cut to the
face; they are rebuilt when another face is loaded (or the mesh is edited), on the thread pool
(a 12-megapixel photo takes seconds), and shown when all are ready if the face is still the
current one. A click applies the preset through the preset panel, with its intensity slider and
replace/add mode (one undo entry).
"""

from __future__ import annotations

import threading
import traceback

import numpy as np
from PySide6.QtCore import (
    QCoreApplication,
    QObject,
    QRunnable,
    QSize,
    Qt,
    QThreadPool,
    QTimer,
    Signal,
)
from PySide6.QtGui import QIcon, QImage, QPixmap
from PySide6.QtWidgets import QListView, QListWidget, QListWidgetItem, QVBoxLayout, QWidget

from editor.formats.presets import apply_preset

THUMB = 96


def thumbnail_rgb(face, vector: np.ndarray, size: int = THUMB) -> np.ndarray:
    """The face cut from brows to chin, rendered with ``vector``, ``size`` px on its long side
    (no Qt: runs on any thread)."""
    import cv2

    x0, y0, x1, y1 = face.crop_box(0.15, 0.25, 0.15, 0.15)  # brows to chin
    img = face.render(vector)[y0:y1, x0:x1]
    s = size / max(img.shape[:2])
    return np.ascontiguousarray(cv2.resize(img, None, fx=s, fy=s, interpolation=cv2.INTER_AREA))


def to_pixmap(img: np.ndarray) -> QPixmap:
    q = QImage(img.data, img.shape[1], img.shape[0], img.strides[0], QImage.Format.Format_RGB888)
    return QPixmap.fromImage(q.copy())


def thumbnail(face, vector: np.ndarray, size: int = THUMB) -> QPixmap:
    return to_pixmap(thumbnail_rgb(face, vector, size))


class _Thumbs(QObject):
    ready = Signal(object, object)  # id(face), [(name, rgb)]


class _ThumbJob(QRunnable):
    def __init__(self, face, presets: dict, signals: _Thumbs, stop: threading.Event) -> None:
        super().__init__()
        self.face, self.presets, self.signals, self.stop = face, presets, signals, stop

    def run(self) -> None:
        out = []
        try:
            for n, p in self.presets.items():
                if self.stop.is_set():  # another face, or the application quits
                    return
                out.append((n, thumbnail_rgb(self.face, apply_preset(p, 1.0))))
        except Exception:  # noqa: BLE001 -- a thumbnail is not worth a crash
            traceback.print_exc()
            out = []
        try:
            self.signals.ready.emit(id(self.face), out)
        except RuntimeError:  # the gallery was closed meanwhile
            pass


class PresetGallery(QWidget):
    """Icon grid of the presets on the current face; clicking one applies it via ``panel``."""

    def __init__(self, model, panel, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.model = model
        self.panel = panel
        self.view = QListWidget()
        self.view.setViewMode(QListView.ViewMode.IconMode)
        self.view.setIconSize(QSize(THUMB, THUMB))
        self.view.setResizeMode(QListView.ResizeMode.Adjust)
        self.view.setMovement(QListView.Movement.Static)
        self.view.setSpacing(4)
        self.view.setToolTip("Click to apply with the intensity and mode of the Presets tab")
        lay = QVBoxLayout(self)
        lay.setContentsMargins(2, 2, 2, 2)
        lay.addWidget(self.view)
        self._face_id: int | None = None
        self._timer = QTimer(self, singleShot=True, interval=50)
        self._timer.timeout.connect(lambda: self.rebuild(background=True))
        self._signals = _Thumbs(self)
        self._signals.ready.connect(self._show_thumbs, Qt.ConnectionType.QueuedConnection)
        self._pending: object = None  # the face whose thumbnails are being rendered
        self._stop = threading.Event()
        app = QCoreApplication.instance()
        if app is not None:
            app.aboutToQuit.connect(lambda: self._stop.set())
        self.destroyed.connect(lambda *_a, stop=self._stop: stop.set())
        self.view.itemClicked.connect(self._clicked)
        model.loaded.connect(self._timer.start)
        model.changed.connect(self._maybe_rebuild)
        self.rebuild()

    def _maybe_rebuild(self, _old: object, _new: object) -> None:
        face = self.model.face
        if face is not None and id(face) != self._face_id:
            self._timer.start()

    def rebuild(self, background: bool = False) -> None:
        """Render one thumbnail per preset on the current face (about 3 ms each on a small
        photo), here or (``background``) on the thread pool."""
        face = self.model.face
        self._face_id = None if face is None else id(face)
        if face is None:
            self.view.clear()
            return
        self._stop.set()  # the thumbnails of the previous face are not wanted any more
        self._stop = threading.Event()
        if background:
            self._pending = face
            QThreadPool.globalInstance().start(
                _ThumbJob(face, dict(self.panel.presets), self._signals, self._stop))
            return
        self._pending = None
        self._fill([(n, thumbnail_rgb(face, apply_preset(p, 1.0)))
                    for n, p in self.panel.presets.items()])

    def _show_thumbs(self, face_id: int, thumbs: list) -> None:
        if self._pending is not None and id(self._pending) == face_id == self._face_id:
            self._pending = None
            self._fill(thumbs)

    def _fill(self, thumbs: list) -> None:
        self.view.clear()
        for name, rgb in thumbs:
            preset = self.panel.presets.get(name)
            item = QListWidgetItem(QIcon(to_pixmap(rgb)), name)
            item.setData(Qt.ItemDataRole.UserRole, name)
            item.setToolTip(getattr(preset, "source", "") or name)
            self.view.addItem(item)

    def names(self) -> list[str]:
        return [self.view.item(i).data(Qt.ItemDataRole.UserRole)
                for i in range(self.view.count())]

    def _clicked(self, item: QListWidgetItem) -> None:
        self.panel.apply(item.data(Qt.ItemDataRole.UserRole))


def install(window, panel) -> PresetGallery:
    gallery = PresetGallery(window.model, panel)
    window.preset_gallery = gallery
    window.gallery_dock = window.add_panel_dock("Gallery", gallery, "galleryDock")
    return gallery
