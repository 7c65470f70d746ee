"""pyqtgraph plots of a MOS study: confusion heatmap and per-group bar charts with CI whiskers."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pyqtgraph as pg
from PySide6.QtWidgets import QWidget

from editor.study.mos_stats import Confusion


def _ticks(names: Sequence[str]) -> list[list[tuple[float, str]]]:
    return [[(i + 0.5, name) for i, name in enumerate(names)]]


class ConfusionPlot(pg.PlotWidget):
    """Row-normalised confusion matrix as a heatmap; each cell shows its count and row %.

    Rows (y, top to bottom) are the intended expressions, columns (x) the chosen labels.
    """

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent, background="w")
        self.setMenuEnabled(False)
        self.setMouseEnabled(False, False)
        self.hideButtons()
        self.image = pg.ImageItem(axisOrder="row-major")
        self.image.setColorMap(pg.colormap.get("CET-L18"))
        self.addItem(self.image)
        self.getPlotItem().invertY(True)
        self.texts: list[pg.TextItem] = []
        self.setTitle("Confusion matrix (rows: intended, columns: chosen; row %)")
        self.setLabel("left", "intended")
        self.setLabel("bottom", "chosen")
        self.getAxis("left").setWidth(90)  # room for the longest label before layout settles

    def set_confusion(self, cm: Confusion) -> None:
        for t in self.texts:
            self.removeItem(t)
        self.texts = []
        norm = np.nan_to_num(np.asarray(cm.normalised, dtype=float), nan=0.0)
        self.image.setImage(norm, levels=(0.0, 1.0))
        self.image.setRect(0, 0, norm.shape[1], norm.shape[0])
        for i in range(norm.shape[0]):
            for j in range(norm.shape[1]):
                pct = cm.normalised[i, j]
                share = "-" if math.isnan(pct) else f"{100 * pct:.0f} %"
                color = "white" if norm[i, j] > 0.55 else "black"
                item = pg.TextItem(anchor=(0.5, 0.5), html=(
                    f'<div style="text-align:center; color:{color}">'
                    f"{cm.counts[i, j]}<br>{share}</div>"))
                item.setTextWidth(70)  # fixed width, so that the lines are centred
                item.setPos(j + 0.5, i + 0.5)
                self.addItem(item)
                self.texts.append(item)
        self.getAxis("bottom").setTicks(_ticks(cm.columns))
        self.getAxis("left").setTicks(_ticks(cm.rows))
        self.setXRange(0, norm.shape[1], padding=0)
        self.setYRange(0, norm.shape[0], padding=0)


class BarPlot(pg.PlotWidget):
    """Bars of group means with confidence-interval whiskers (``ErrorBarItem``)."""

    def __init__(self, title: str, y_label: str, y_range: tuple[float, float],
                 parent: QWidget | None = None) -> None:
        super().__init__(parent, background="w")
        self.setMenuEnabled(False)
        self.setMouseEnabled(False, False)
        self.hideButtons()
        self.setTitle(title)
        self.setLabel("left", y_label)
        self.y_range = y_range
        self.bars: pg.BarGraphItem | None = None
        self.whiskers: pg.ErrorBarItem | None = None
        self.values: np.ndarray = np.zeros(0)

    def set_data(self, names: Sequence[str], means: Sequence[float],
                 cis: Sequence[tuple[float, float]]) -> None:
        """``means[i]`` with interval ``cis[i]`` (nan: no bar / no whisker)."""
        for item in (self.bars, self.whiskers):
            if item is not None:
                self.removeItem(item)
        x = np.arange(len(names), dtype=float) + 0.5
        y = np.nan_to_num(np.asarray(means, dtype=float), nan=0.0)
        lo = np.array([c[0] for c in cis], dtype=float)
        hi = np.array([c[1] for c in cis], dtype=float)
        self.values = y
        self.bars = pg.BarGraphItem(x=x, height=y, width=0.6, brush=pg.mkBrush(70, 120, 200))
        top = np.nan_to_num(hi - y, nan=0.0).clip(min=0)
        bottom = np.nan_to_num(y - lo, nan=0.0).clip(min=0)
        self.whiskers = pg.ErrorBarItem(x=x, y=y, top=top, bottom=bottom, beam=0.2,
                                        pen=pg.mkPen("k", width=2))
        self.addItem(self.bars)
        self.addItem(self.whiskers)
        self.getAxis("bottom").setTicks([[(xi, n) for xi, n in zip(x, names, strict=True)]])
        self.setXRange(0, max(len(names), 1), padding=0.02)
        self.setYRange(*self.y_range, padding=0.02)
