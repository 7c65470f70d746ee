"""Latest-only rendering on one worker thread.

The GUI thread never waits for a render: :meth:`RenderScheduler.submit` drops the request in a
one-slot mailbox (replacing any request still waiting there, which then never runs) and
returns. One worker thread takes the newest request, renders it (cv2 and numpy release the
GIL) and posts the result back to the GUI thread, where results older than the newest one
shown, or older than the last :meth:`cancel` (e.g. another photo was opened), are dropped.
"""

from __future__ import annotations

import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from PySide6.QtCore import QCoreApplication, QEventLoop, QObject, Qt, Signal

if TYPE_CHECKING:  # the renderer is imported where a photo is opened, after the window shows
    from editor.engine.face import Face


@dataclass(frozen=True, eq=False)
class RenderRequest:
    """What to render: a face (mesh) and a (68,) float32 FAP vector in FAPU."""

    face: Face
    faps: np.ndarray
    generation: int = 0
    creases: bool = True  # darken the skin folds (View > Skin Creases)
    submitted: float = field(default_factory=time.perf_counter)


@dataclass(eq=False)
class RenderResult:
    """A rendered frame.

    Attributes
    ----------
    image : (H, W, 3) uint8 RGB
    irises : (2, 3) float32 rows (x, y, r) of the deformed irises 3.5 and 3.6, image pixels
    ms : render time on the worker, milliseconds
    latency_ms : submit -> delivered on the GUI thread, milliseconds (set on delivery)
    """

    request: RenderRequest
    image: np.ndarray
    irises: np.ndarray
    ms: float = 0.0
    latency_ms: float = 0.0

    @property
    def generation(self) -> int:
        return self.request.generation


def render_request(req: RenderRequest) -> RenderResult:
    """Default renderer: the warped photo and the deformed irises (gaze, eyeball FAPs)."""
    img = req.face.render(req.faps, creases=req.creases)
    pts = req.face.feature_points(req.faps)
    radii = req.face.eye_state(req.faps)[:, 0]
    irises = np.array([[*pts["3.5"], radii[0]], [*pts["3.6"], radii[1]]], np.float32)
    return RenderResult(req, img, irises)


class RenderScheduler(QObject):
    """Renders only the latest submitted request on one worker thread.

    Signals
    -------
    rendered(image, ms)
        A new frame for the preview (GUI thread); ``ms`` is the render time.
    resultReady(RenderResult)
        The same frame with its request, irises and latency.
    failed(str)
        A render raised; the message is one line.
    """

    rendered = Signal(object, float)
    resultReady = Signal(object)
    failed = Signal(str)
    _done = Signal(object)
    _error = Signal(int, str)

    def __init__(self, render: Callable[[RenderRequest], RenderResult] = render_request,
                 parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._render = render
        self._cond = threading.Condition()
        self._slot: RenderRequest | None = None
        self._generation = 0
        self._delivered = 0
        self._min_generation = 0
        self._stopping = False
        self._done.connect(self._deliver, Qt.ConnectionType.QueuedConnection)
        self._error.connect(self._report, Qt.ConnectionType.QueuedConnection)
        self._thread = threading.Thread(target=self._run, name="fap-render", daemon=True)
        self._thread.start()

    # ------------------------------------------------------------------ GUI thread
    def submit(self, face: Face, faps: np.ndarray, creases: bool = True) -> int:
        """Queue a render of ``faps`` on ``face``; returns its generation. Never blocks."""
        with self._cond:
            self._generation += 1
            self._slot = RenderRequest(face, faps, self._generation, creases=creases)
            self._cond.notify()
            return self._generation

    def cancel(self) -> None:
        """Drop the waiting request and ignore every result of a request made so far."""
        with self._cond:
            self._slot = None
            self._min_generation = self._generation + 1

    @property
    def generation(self) -> int:
        """Generation of the newest submitted request."""
        return self._generation

    @property
    def delivered(self) -> int:
        """Generation of the newest result delivered to the GUI."""
        return self._delivered

    def is_idle(self) -> bool:
        """True when the newest request has been delivered (or cancelled)."""
        with self._cond:
            return self._slot is None and (self._delivered >= self._generation
                                           or self._min_generation > self._generation)

    def wait(self, timeout_ms: int = 5000) -> bool:
        """Process events until the newest request is shown (for screenshots and tests)."""
        end = time.perf_counter() + timeout_ms / 1000.0
        app = QCoreApplication.instance()
        while not self.is_idle():
            if time.perf_counter() > end:
                return False
            if app is not None:
                app.processEvents(QEventLoop.ProcessEventsFlag.AllEvents, 10)
            time.sleep(0.001)
        return True

    def shutdown(self, timeout: float = 2.0) -> None:
        """Stop the worker (after the render in progress, if any)."""
        with self._cond:
            self._stopping = True
            self._slot = None
            self._cond.notify()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout)

    def _deliver(self, result: RenderResult) -> None:
        gen = result.generation
        if gen < self._min_generation or gen <= self._delivered:
            return  # stale: another photo was opened, or a newer frame is already shown
        self._delivered = gen
        result.latency_ms = (time.perf_counter() - result.request.submitted) * 1000.0
        self.resultReady.emit(result)
        self.rendered.emit(result.image, result.ms)

    def _report(self, generation: int, message: str) -> None:
        if generation >= self._min_generation:
            self._delivered = max(self._delivered, generation)
            self.failed.emit(message)

    # ------------------------------------------------------------------ worker thread
    def _run(self) -> None:
        while True:
            with self._cond:
                while self._slot is None and not self._stopping:
                    self._cond.wait()
                if self._stopping:
                    return
                req, self._slot = self._slot, None
            t0 = time.perf_counter()
            try:
                result = self._render(req)
                result.ms = (time.perf_counter() - t0) * 1000.0
                self._done.emit(result)
            except RuntimeError:  # the scheduler was deleted while rendering
                if self._stopping:
                    return
                self._emit_error(req.generation)
            except Exception:  # a render bug must never kill the app
                self._emit_error(req.generation)

    def _emit_error(self, generation: int) -> None:
        line = traceback.format_exc().strip().splitlines()[-1]
        try:
            self._error.emit(generation, f"render failed: {line}")
        except RuntimeError:
            pass
