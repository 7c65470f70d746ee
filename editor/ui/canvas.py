"""The canvas: the photo with its editable mesh (left) and the live preview (right).

Both views show image pixels (x right, y down; ``ViewBox(lockAspect=True, invertY=True)``)
and are linked, so zoom (wheel) and pan (drag) move both. The preview shows the newest frame of
the :class:`~editor.ui.render_scheduler.RenderScheduler`; when eyeball FAPs are set it rings
the deformed irises.
"""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtGui import QPainter
from PySide6.QtWidgets import QHBoxLayout, QSplitter, QWidget

from .document_model import Document, DocumentModel
from .mesh_item import MeshItem
from .render_scheduler import RenderResult

#: FAPs whose effect is drawn as iris rings over the photo, with the mesh (gaze, eyeball thrust,
#: pupils); never over the preview, which shows the result as it is.
EYEBALL_FAPS = slice(22, 30)


def _pane(title: str) -> tuple[pg.GraphicsLayoutWidget, pg.ViewBox]:
    """A titled view of image pixels: ``ViewBox(lockAspect=True, invertY=True)``."""
    w = pg.GraphicsLayoutWidget()
    w.setAcceptDrops(False)  # drops go to the main window
    w.viewport().setAcceptDrops(False)
    # zoomed photos are drawn with bilinear filtering, not nearest-neighbour blocks
    w.setRenderHint(QPainter.RenderHint.SmoothPixmapTransform, True)
    w.ci.setContentsMargins(2, 2, 2, 2)
    w.ci.setSpacing(2)
    w.addLabel(title, row=0, col=0, size="9pt")
    vb = w.addViewBox(row=1, col=0, lockAspect=True, invertY=True, enableMenu=False)
    vb.setBackgroundColor((30, 30, 30))
    return w, vb


def _face_box(vertices: np.ndarray, regions: np.ndarray,
              size: tuple[int, int]) -> tuple[float, float, float, float]:
    """(x0, y0, x1, y1) around the face mesh (no margin/border ring), padded, in the photo."""
    inner = vertices[~np.isin(regions, ("margin", "border"))]
    lo, hi = inner.min(0), inner.max(0)
    pad = 0.12 * (hi - lo)
    lo, hi = np.maximum(lo - pad, 0), np.minimum(hi + pad, size)
    return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])


class Canvas(QWidget):
    """Photo + mesh and preview side by side (linked zoom/pan, resizable split)."""

    def __init__(self, model: DocumentModel, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.model = model
        self.photo_widget, self.photo_view = _pane("Photo and mesh (drag a vertex to correct "
                                                   "the fit)")
        self.preview_widget, self.preview_view = _pane("Preview")
        self.preview_view.setXLink(self.photo_view)
        self.preview_view.setYLink(self.photo_view)
        self.splitter = QSplitter(Qt.Orientation.Horizontal)
        self.splitter.addWidget(self.photo_widget)
        self.splitter.addWidget(self.preview_widget)
        self.splitter.setChildrenCollapsible(False)
        self.splitter.setSizes([1000, 1000])
        lay = QHBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.addWidget(self.splitter)
        self.photo = pg.ImageItem(axisOrder="row-major")
        self.preview = pg.ImageItem(axisOrder="row-major")
        self.photo_view.addItem(self.photo)
        self.preview_view.addItem(self.preview)
        self.mesh = MeshItem(model)
        self.photo_view.addItem(self.mesh)
        self.irises = pg.ScatterPlotItem(pxMode=False, pen=pg.mkPen((255, 60, 60), width=1.5),
                                         brush=None, symbol="o")
        self.photo_view.addItem(self.irises)
        self._overlay = True
        self._eyes_moved = False
        self._last: RenderResult | None = None
        self._face_box: tuple[float, float, float, float] | None = None
        self._autofit: str | None = None  # "face" or "photo" until the user zooms or pans
        for vb in (self.photo_view, self.preview_view):
            vb.sigRangeChangedManually.connect(self._on_manual_range)
        self.photo_view.sigResized.connect(self._refit)
        model.loaded.connect(self._on_loaded)
        model.changed.connect(self._on_changed)

    # ------------------------------------------------------------------ model -> view
    def _on_loaded(self) -> None:
        face = self.model.fitted
        if face is None:
            return
        h, w = face.image.shape[:2]
        self.photo.setImage(face.image, autoLevels=False)
        self.preview.setImage(face.image, autoLevels=False)
        self.mesh.set_mesh(face.mesh, (w, h))
        self.irises.setData(pos=np.zeros((0, 2)))
        self._last = None
        self._face_box = _face_box(face.vertices, face.mesh.regions, (w, h))
        self.fit_face()

    def _on_changed(self, old: Document | None, new: Document) -> None:
        if old is None or old.vertices is not new.vertices:
            self.mesh.set_vertices(new.vertices)
        self._eyes_moved = bool(np.any(new.faps[EYEBALL_FAPS]))
        self._update_irises()

    def set_result(self, result: RenderResult) -> None:
        """Show a rendered frame in the preview."""
        self._last = result
        self.preview.setImage(result.image, autoLevels=False)
        self._update_irises()

    def _update_irises(self) -> None:
        r = self._last
        if r is None or not (self._overlay and self._eyes_moved):
            self.irises.setData(pos=np.zeros((0, 2)))
            return
        self.irises.setData(pos=r.irises[:, :2], size=2.0 * r.irises[:, 2])

    # ------------------------------------------------------------------ commands
    def set_overlay_visible(self, on: bool) -> None:
        """Show or hide the mesh (and the iris rings); hidden vertices cannot be dragged."""
        self._overlay = bool(on)
        self.mesh.setVisible(self._overlay)
        self._update_irises()

    @property
    def overlay_visible(self) -> bool:
        return self._overlay

    def fit(self) -> None:
        """Fit the whole photo into the views (kept fitted on resize until the user zooms)."""
        face = self.model.fitted
        if face is None:
            return
        self._autofit = "photo"
        h, w = face.image.shape[:2]
        self.photo_view.setRange(xRange=(0, w), yRange=(0, h), padding=0.02)

    def fit_face(self) -> None:
        """Zoom onto the face (the mesh without its margin ring)."""
        if self._face_box is None:
            return
        self._autofit = "face"
        x0, y0, x1, y1 = self._face_box
        self.photo_view.setRange(xRange=(x0, x1), yRange=(y0, y1), padding=0.0)

    def _on_manual_range(self, *_args: object) -> None:
        self._autofit = None

    def _refit(self, *_args: object) -> None:
        if self._autofit == "face":
            self.fit_face()
        elif self._autofit == "photo":
            self.fit()

    def preview_image(self) -> np.ndarray | None:
        """The image currently shown in the preview (H, W, 3) uint8, or None."""
        return None if self._last is None else self._last.image
