"""The personalized mesh over the photo: edges as one path, vertices, FDP points, dragging.

Coordinates are image pixels (x, y), y down (the view is ``invertY``). Dragging a vertex is one
gesture on the :class:`DocumentModel`: press -> ``begin_gesture``, moves -> ``preview_vertex``,
release -> one "Move vertex" undo command. FAPU and the rendering follow the edited mesh.
"""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from pyqtgraph.GraphicsScene.mouseEvents import HoverEvent, MouseDragEvent
from PySide6.QtCore import QPointF, QRectF, Qt
from PySide6.QtGui import QPainter
from PySide6.QtWidgets import QStyleOptionGraphicsItem, QWidget

from editor.engine.mesh import StandardMesh

from .document_model import DocumentModel

EDGE_PEN = (255, 255, 255, 140)
VERTEX_BRUSH = (0, 220, 255, 200)
FDP_BRUSH = (255, 215, 0, 255)
HOVER_PEN = (255, 60, 60, 255)


def mesh_edges(triangles: np.ndarray) -> np.ndarray:
    """Unique undirected edges (E, 2) of a triangle list (T, 3)."""
    e = triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    return np.unique(np.sort(e, 1), axis=0)


def nearest_vertex(vertices: np.ndarray, p: np.ndarray, radius: float,
                   pickable: np.ndarray | None = None) -> int | None:
    """Index of the vertex nearest to ``p`` within ``radius`` (image pixels), or None."""
    if len(vertices) == 0:
        return None
    d2 = ((vertices - np.asarray(p, np.float32)) ** 2).sum(1)
    if pickable is not None:
        d2 = np.where(pickable, d2, np.inf)
    i = int(np.argmin(d2))
    return i if d2[i] <= radius * radius else None


class MeshItem(pg.GraphicsObject):
    """Mesh overlay: edges (one path), vertices (scatter), FDP vertices highlighted.

    Hovering a vertex shows its name (and MPEG-4 feature point id); dragging it with the left
    button edits the neutral mesh through ``model``. Border vertices cannot be dragged.
    """

    def __init__(self, model: DocumentModel, pick_px: float = 7.0) -> None:
        super().__init__()
        self.model = model
        self.pick_px = pick_px
        self._v = np.zeros((0, 2), np.float32)
        self._edges = np.zeros((0, 2), np.int32)
        self._names: tuple[str, ...] = ()
        self._fdp_of: dict[int, str] = {}
        self._fdp_idx = np.zeros(0, np.int64)
        self._pickable = np.zeros(0, bool)
        self._drag: int | None = None
        self._offset = np.zeros(2, np.float32)
        self._bounds = (0.0, 0.0)
        self._hover: int | None = None
        self.lines = pg.PlotCurveItem(pen=pg.mkPen(EDGE_PEN, width=1), antialias=True,
                                      skipFiniteCheck=True)
        self.dots = pg.ScatterPlotItem(size=4, pen=None, brush=pg.mkBrush(VERTEX_BRUSH))
        self.fdp_dots = pg.ScatterPlotItem(size=7, pen=pg.mkPen((60, 40, 0), width=1),
                                           brush=pg.mkBrush(FDP_BRUSH))
        self.hover_dot = pg.ScatterPlotItem(size=13, pen=pg.mkPen(HOVER_PEN, width=2),
                                            brush=None)
        self.label = pg.TextItem(anchor=(0, 1), color=(255, 255, 255),
                                 fill=pg.mkBrush(0, 0, 0, 170))
        for child in (self.lines, self.dots, self.fdp_dots, self.hover_dot, self.label):
            child.setParentItem(self)
        self.label.setZValue(10)
        self.label.hide()
        self.setAcceptHoverEvents(True)

    # ------------------------------------------------------------------ data
    def set_mesh(self, mesh: StandardMesh, image_size: tuple[int, int]) -> None:
        """Topology (fixed per mesh) and the photo size ``(width, height)`` for clamping."""
        self._edges = mesh_edges(mesh.triangles)
        self._names = mesh.names
        self._fdp_of = {i: k for k, i in mesh.fdp.items()}
        self._fdp_idx = np.array(sorted(self._fdp_of), np.int64)
        self._pickable = np.asarray(mesh.regions) != "border"
        self._bounds = (float(image_size[0]), float(image_size[1]))
        self._v = np.zeros((0, 2), np.float32)

    def set_vertices(self, vertices: np.ndarray) -> None:
        """Neutral mesh positions (V, 2) float32, image pixels."""
        self.prepareGeometryChange()
        self._v = np.asarray(vertices, np.float32)
        seg = self._v[self._edges].reshape(-1, 2)
        self.lines.setData(seg[:, 0], seg[:, 1], connect="pairs")
        self.dots.setData(pos=self._v)
        self.fdp_dots.setData(pos=self._v[self._fdp_idx])
        if self._hover is not None:
            self._show_hover(self._hover)

    @property
    def vertices(self) -> np.ndarray:
        return self._v

    def vertex_name(self, i: int) -> str:
        fdp = self._fdp_of.get(i)
        return f"FDP {fdp}  ({self._names[i]})" if fdp else self._names[i]

    # ------------------------------------------------------------------ QGraphicsItem
    def boundingRect(self) -> QRectF:
        if len(self._v) == 0:
            return QRectF()
        lo, hi = self._v.min(0), self._v.max(0)
        pad = 4.0
        return QRectF(float(lo[0]) - pad, float(lo[1]) - pad, float(hi[0] - lo[0]) + 2 * pad,
                      float(hi[1] - lo[1]) + 2 * pad)

    def paint(self, p: QPainter, opt: QStyleOptionGraphicsItem,
              widget: QWidget | None = None) -> None:
        pass  # the children draw

    # ------------------------------------------------------------------ picking
    def pick_radius(self) -> float:
        """The pick radius in image pixels (``pick_px`` screen pixels)."""
        px = self.pixelLength(pg.Point(1, 0))
        return self.pick_px * (float(px) if px else 1.0)

    def pick(self, pos: QPointF) -> int | None:
        """The draggable vertex under ``pos`` (item coordinates), or None."""
        p = np.array([pos.x(), pos.y()], np.float32)
        return nearest_vertex(self._v, p, self.pick_radius(), self._pickable)

    def hoverEvent(self, ev: HoverEvent) -> None:
        if ev.isExit():
            self._set_hover(None)
            return
        i = self.pick(ev.pos())
        if i is not None:
            ev.acceptDrags(Qt.MouseButton.LeftButton)
        self._set_hover(i)

    def _set_hover(self, i: int | None) -> None:
        if i == self._hover:
            return
        self._hover = i
        if i is None:
            self.hover_dot.setData(pos=np.zeros((0, 2)))
            self.label.hide()
            self.setCursor(Qt.CursorShape.ArrowCursor)
        else:
            self._show_hover(i)
            self.setCursor(Qt.CursorShape.PointingHandCursor)

    def _show_hover(self, i: int) -> None:
        x, y = (float(c) for c in self._v[i])
        self.hover_dot.setData(pos=[[x, y]])
        self.label.setText(self.vertex_name(i))
        self.label.setPos(x + 1.5, y - 1.5)
        self.label.show()

    def mouseDragEvent(self, ev: MouseDragEvent) -> None:
        if ev.button() != Qt.MouseButton.LeftButton:
            ev.ignore()
            return
        if ev.isStart():
            down = ev.buttonDownPos()
            i = self.pick(down)
            if i is None:
                ev.ignore()
                return
            self._drag = i
            self._offset = self._v[i] - np.array([down.x(), down.y()], np.float32)
            self.model.begin_gesture()
        if self._drag is None:
            ev.ignore()
            return
        ev.accept()
        pos = ev.pos()
        p = np.array([pos.x(), pos.y()], np.float32) + self._offset
        p = np.clip(p, 0.0, self._bounds)
        i = self._drag
        self.model.preview_vertex(i, p)
        if ev.isFinish():
            self._drag = None
            self.model.commit_gesture(f"Move vertex {self._names[i]}")
