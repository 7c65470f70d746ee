"""Preset gallery: thumbnails of the current face rendered with every preset; click to apply.

The thumbnails are rendered with the core (``face.render``) at full intensity and cut to the
face; they are rebuilt when another face is loaded (or the mesh is edited). A click applies the
preset through the preset panel, with its intensity slider and replace/add mode (one undo entry).
"""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QSize, Qt, QTimer
from PySide6.QtGui import QIcon, QImage, QPixmap
from PySide6.QtWidgets import QListView, QListWidget, QListWidgetItem, QVBoxLayout, QWidget

from editor.formats.expressions import apply_preset

THUMB = 96


def thumbnail(face, vector: np.ndarray, size: int = THUMB) -> QPixmap:
    import cv2

    x0, y0, x1, y1 = face.crop_box(0.15, 0.25, 0.15, 0.15)  # brows to chin
    img = face.render(vector)[y0:y1, x0:x1]
    s = size / max(img.shape[:2])
    img = np.ascontiguousarray(cv2.resize(img, None, fx=s, fy=s, interpolation=cv2.INTER_AREA))
    q = QImage(img.data, img.shape[1], img.shape[0], img.strides[0], QImage.Format.Format_RGB888)
    return QPixmap.fromImage(q.copy())


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
        self._timer.timeout.connect(self.rebuild)
        self.view.itemClicked.connect(self._clicked)
        model.loaded.connect(self._timer.start)
        model.changed.connect(self._maybe_rebuild)
        self.rebuild()

    def _maybe_rebuild(self, _old: object, _new: object) -> None:
        face = self.model.face
        if face is not None and id(face) != self._face_id:
            self._timer.start()

    def rebuild(self) -> None:
        """Render one thumbnail per preset on the current face (about 3 ms each)."""
        face = self.model.face
        self.view.clear()
        self._face_id = None if face is None else id(face)
        if face is None:
            return
        for name, preset in self.panel.presets.items():
            item = QListWidgetItem(QIcon(thumbnail(face, apply_preset(preset, 1.0))), name)
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
