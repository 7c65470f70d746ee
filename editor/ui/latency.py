"""Slider-change -> preview-updated latency of the real editor window (for ``editor.bench``).

:func:`slider_latency` opens the window (offscreen works) on a photo, drags a FAP slider back
and forth at a fixed event rate and times each frame from the slider change that requested it
to the moment the preview's ImageItem holds it (GUI thread, before the lazy paint). Frames the
latest-only scheduler dropped are counted, not timed. Returns plain numbers (JSON-ready).
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path

from PySide6.QtCore import QEventLoop

from editor.engine.faps import FAPS

from .app import application
from .main_window import MainWindow
from .render_scheduler import RenderResult


def _pump(seconds: float) -> None:
    app = application()
    end = time.perf_counter() + seconds
    while True:
        app.processEvents(QEventLoop.ProcessEventsFlag.AllEvents, 5)
        if time.perf_counter() >= end:
            return
        time.sleep(0.0005)


def slider_latency(photo: str | Path, fap: str = "open_jaw", moves: int = 240,
                   interval_ms: float = 16.0) -> dict[str, float | int | str]:
    """Drag ``fap``'s slider ``moves`` times, one change every ``interval_ms``.

    Returns ``{"photo", "size", "moves", "frames", "median_ms", "p95_ms", "max_ms",
    "render_median_ms"}``; times in milliseconds.
    """
    application()
    window = MainWindow()
    try:
        if not window.docs.open_photo(str(photo), ask=False):
            raise RuntimeError(f"cannot open {photo}")
        window.resize(1400, 860)
        window.show()
        _pump(0.2)
        window.scheduler.wait()
        lat: list[float] = []
        ren: list[float] = []

        def shown(r: RenderResult) -> None:  # connected after the canvas: the preview is set
            lat.append((time.perf_counter() - r.request.submitted) * 1000.0)
            ren.append(r.ms)

        window.scheduler.resultReady.connect(shown)
        row = window.fap_panel.rows[FAPS.number(fap)]
        lo, hi = row.slider.minimum(), row.slider.maximum()
        row.slider.setSliderDown(True)
        for k in range(moves):
            phase = (k % 60) / 59.0
            tri = 2 * phase if phase <= 0.5 else 2 * (1 - phase)
            row.slider.setValue(int(lo + (hi - lo) * tri))
            _pump(interval_ms / 1000.0)
        row.slider.setSliderDown(False)
        window.scheduler.wait()
        lat.sort()
        face = window.model.fitted
        assert face is not None
        h, w = face.image.shape[:2]
        return {
            "photo": str(photo), "size": f"{w}x{h}", "moves": moves, "frames": len(lat),
            "median_ms": round(statistics.median(lat), 2),
            "p95_ms": round(lat[min(len(lat) - 1, int(0.95 * len(lat)))], 2),
            "max_ms": round(lat[-1], 2),
            "render_median_ms": round(statistics.median(ren), 2),
        }
    finally:
        window.close_without_prompt()
