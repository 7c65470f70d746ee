"""Long work off the GUI thread: :func:`run_task` runs a function on Qt's thread pool while the
event loop keeps running, with a progress dialog (and Cancel) when it takes a while.

The caller reads like a plain call -- ``face = run_task(win, "Opening…", load)`` -- and applies
the result on the GUI thread itself (through the document model). Meanwhile the window repaints
and timers run; user input is held back until the progress dialog appears (after
``show_after_ms``), and that dialog is window-modal, so nothing else can start a second document
change half-way. The function gets a :class:`Progress` to report ``(done, total)`` and to see a
cancellation: ``progress(done, total)`` raises :class:`~editor.errors.Cancelled` once the user
pressed Cancel. Work that cannot look (a face fit) is abandoned on Cancel: its result is dropped
when it arrives. Errors raised by the function are raised again on the GUI thread.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any, TypeVar

from PySide6.QtCore import QEventLoop, QObject, QRunnable, Qt, QThreadPool, QTimer, Signal
from PySide6.QtWidgets import QProgressDialog, QWidget

from editor.errors import Cancelled

T = TypeVar("T")

#: The progress dialog appears when the work takes longer than this.
SHOW_AFTER_MS = 400


class Progress:
    """Given to the work function: report progress, and learn that the user cancelled."""

    def __init__(self, signals: _Signals, cancel: threading.Event) -> None:
        self._signals = signals
        self._cancel = cancel

    @property
    def cancelled(self) -> bool:
        return self._cancel.is_set()

    def __call__(self, done: int, total: int, text: str = "") -> None:
        """Report ``done`` of ``total`` steps (and a new label); raise Cancelled if cancelled."""
        if self._cancel.is_set():
            raise Cancelled("cancelled")
        self._signals.progress.emit(int(done), int(total), text)

    def check(self) -> None:
        if self._cancel.is_set():
            raise Cancelled("cancelled")


class _Signals(QObject):
    progress = Signal(int, int, str)
    done = Signal(bool, object)  # ok, result or exception


class _Job(QRunnable):
    def __init__(self, fn: Callable[[Progress], Any], signals: _Signals,
                 cancel: threading.Event) -> None:
        super().__init__()
        self.setAutoDelete(True)
        self.fn, self.signals, self.progress = fn, signals, Progress(signals, cancel)

    def run(self) -> None:
        try:
            result = self.fn(self.progress)
        except BaseException as e:  # noqa: BLE001 -- raised again on the GUI thread
            self.signals.done.emit(False, e)
        else:
            self.signals.done.emit(True, result)


#: The user's own tasks run on a pool of their own: an Open never waits behind background work
#: (preset thumbnails) that fills Qt's global pool. Created on first use.
_POOL: list[QThreadPool] = []


def task_pool() -> QThreadPool:
    """The thread pool of :func:`run_task` (tests and the Quit path wait on it)."""
    if not _POOL:
        pool = QThreadPool()
        pool.setMaxThreadCount(4)  # nested tasks (a task that starts a task) never deadlock
        _POOL.append(pool)
    return _POOL[0]


#: Signal objects of jobs still running (a cancelled job finishes later and emits into it).
_ALIVE: set[_Signals] = set()

#: The tasks running now (nested event loops), innermost last: tests and the Quit action look.
RUNNING: list[threading.Event] = []


def run_task(parent: QWidget | None, label: str, fn: Callable[[Progress], T], *,
             title: str = "FAP Studio", cancellable: bool = True,
             show_after_ms: int = SHOW_AFTER_MS) -> T:
    """Run ``fn(progress)`` on the thread pool; return its result or raise its exception (or
    :class:`Cancelled` when the user cancelled), while the event loop keeps running."""
    signals = _Signals()
    cancel = threading.Event()
    loop = QEventLoop()
    outcome: list[tuple[bool, Any]] = []

    def finished(ok: bool, value: object) -> None:
        _ALIVE.discard(signals)
        outcome.append((ok, value))
        loop.quit()

    signals.done.connect(finished, Qt.ConnectionType.QueuedConnection)
    dialog = QProgressDialog(label, "Cancel" if cancellable else "", 0, 0, parent)
    dialog.setWindowTitle(title)
    dialog.setWindowModality(Qt.WindowModality.WindowModal)
    dialog.setMinimumDuration(0)
    dialog.setAutoClose(False)
    dialog.setAutoReset(False)
    if not cancellable:
        dialog.setCancelButton(None)
    dialog.hide()

    def on_progress(done: int, total: int, text: str) -> None:
        if text:
            dialog.setLabelText(text)
        if total > 0:
            dialog.setMaximum(total)
            dialog.setValue(min(done, total))

    def on_cancel() -> None:
        cancel.set()
        outcome.append((False, Cancelled("cancelled")))
        loop.quit()

    signals.progress.connect(on_progress, Qt.ConnectionType.QueuedConnection)
    dialog.canceled.connect(on_cancel)
    RUNNING.append(cancel)
    _ALIVE.add(signals)
    try:
        task_pool().start(_Job(fn, signals, cancel))
        # first: no user input (it waits in the queue), so nothing starts a second change
        show = QTimer()
        show.setSingleShot(True)
        show.timeout.connect(loop.quit)
        show.start(max(0, show_after_ms))
        loop.exec(QEventLoop.ProcessEventsFlag.ExcludeUserInputEvents)
        show.stop()
        if not outcome:  # it takes a while: the modal dialog, with Cancel
            dialog.show()
            loop.exec()
    finally:
        RUNNING.remove(cancel)
        dialog.canceled.disconnect(on_cancel)
        dialog.close()
        dialog.deleteLater()
    ok, value = outcome[0]
    if not ok:
        raise value
    return value  # type: ignore[no-any-return]


def cancel_all() -> None:
    """Ask every running task to stop (the application is quitting)."""
    for event in RUNNING:
        event.set()
