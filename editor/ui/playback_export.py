"""Rendering a FAP sequence to MP4 or PNG frames on a worker thread, with a cancellable dialog.

:class:`ExportJob` runs :func:`editor.formats.video.export_sequence` in a ``QThread``; progress
comes back as a queued signal, so the GUI stays responsive. Cancelling (the dialog's button or
:meth:`ExportJob.cancel`) makes the progress callback return False: the core stops and removes
a partial MP4 (PNG frames already written are kept).
"""

from __future__ import annotations

import threading
import traceback
from typing import TYPE_CHECKING

from PySide6.QtCore import QObject, Qt, QThread, Signal
from PySide6.QtWidgets import QProgressDialog, QWidget

from editor.errors import FapStudioError

if TYPE_CHECKING:
    from editor.formats.video import ExportResult


class _Worker(QObject):
    progress = Signal(int, int)
    done = Signal(object, str)  # ExportResult | None, error message ('' if none)

    def __init__(self, face: object, seq: object, out: str, cancel: threading.Event) -> None:
        super().__init__()
        self.face, self.seq, self.out, self._cancel = face, seq, out, cancel

    def _progress(self, done: int, total: int) -> bool:
        self.progress.emit(done, total)
        return not self._cancel.is_set()

    def run(self) -> None:
        result, message = None, ""
        try:
            # imported here, not with the window (OpenCV, the render pool; issue 15)
            from editor.formats.video import export_sequence

            # frames rendered in worker processes (forkserver: safe beside Qt's threads)
            result = export_sequence(self.face, self.seq, self.out, progress=self._progress,
                                     jobs=None)  # a worker per core
        except FapStudioError as e:
            message = str(e)
        except Exception as e:  # reported, never raised into Qt's event loop
            traceback.print_exc()
            message = f"unexpected error: {type(e).__name__}: {e}"
        self.done.emit(result, message)


class ExportJob(QObject):
    """One export in the background.

    Signals
    -------
    progress(done, total)
        After each rendered frame (GUI thread).
    finished(result, message)
        ``ExportResult`` (``cancelled`` set when stopped early) and '' on success, or None and
        the one-line error message.
    """

    progress = Signal(int, int)
    finished = Signal(object, str)

    def __init__(self, face: object, seq: object, out: str, parent: QWidget | None = None,
                 dialog: bool = True) -> None:
        super().__init__(parent)
        self.out = out
        self.result: ExportResult | None = None
        self.message = ""
        self.running = False
        self._cancel = threading.Event()
        self._thread = QThread()
        self._worker = _Worker(face, seq, out, self._cancel)
        self._worker.moveToThread(self._thread)
        self._thread.started.connect(self._worker.run)
        self._worker.progress.connect(self._on_progress, Qt.ConnectionType.QueuedConnection)
        self._worker.done.connect(self._on_done, Qt.ConnectionType.QueuedConnection)
        self.dialog: QProgressDialog | None = None
        if dialog:
            n = int(getattr(seq, "n_frames", 0))
            d = QProgressDialog(f"Rendering {n} frames to {out}…", "Cancel", 0, max(n, 1),
                                parent)
            d.setWindowTitle("Export")
            d.setWindowModality(Qt.WindowModality.WindowModal)
            d.setMinimumDuration(300)
            d.setAutoClose(False)
            d.setAutoReset(False)
            d.canceled.connect(self.cancel)
            self.dialog = d

    def start(self) -> ExportJob:
        self.running = True
        self._thread.start()
        return self

    def cancel(self) -> None:
        self._cancel.set()

    @property
    def cancelled(self) -> bool:
        return self._cancel.is_set()

    def wait(self, ms: int = 30000) -> bool:
        """Block until the worker thread ends (shutdown, tests)."""
        return self._thread.wait(ms)

    def _on_progress(self, done: int, total: int) -> None:
        if self.dialog is not None and not self._cancel.is_set():
            self.dialog.setMaximum(total)
            self.dialog.setValue(done)
        self.progress.emit(done, total)

    def _on_done(self, result: ExportResult | None, message: str) -> None:
        self._thread.quit()
        self._thread.wait()
        self.running = False
        self.result, self.message = result, message
        if self.dialog is not None:
            self.dialog.canceled.disconnect(self.cancel)
            self.dialog.close()
            self.dialog.deleteLater()
            self.dialog = None
        self.finished.emit(result, message)
