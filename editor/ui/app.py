"""Starting the editor: ``run()`` opens the window (or saves a headless screenshot).

``fap-studio`` (no argument) and ``fap-studio gui [PHOTO] [--fap NAME=VALUE ...]
[--screenshot out.png]`` call :func:`run`.
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
import traceback
from pathlib import Path
from types import TracebackType

from PySide6.QtCore import (
    QEventLoop,
    QMessageLogContext,
    QTimer,
    QtMsgType,
    qInstallMessageHandler,
)
from PySide6.QtWidgets import QApplication, QMessageBox

from editor.engine.faps import FAPS
from editor.errors import FapStudioError
from editor.resources import SAMPLE_FACE
from editor.safeio import atomic_file

from .main_window import MainWindow
from .qt_utils import APPLICATION, ORGANIZATION, settings

SCREENSHOT_SIZE = (1400, 860)


def application() -> QApplication:
    """The QApplication (created on first use) with FAP Studio's names set."""
    app = QApplication.instance()
    if app is None:
        # Qt's platform plugins chat on stderr (xcb, offscreen); a user cannot act on it
        os.environ.setdefault("QT_LOGGING_RULES", "qt.qpa.*=false")
        qInstallMessageHandler(_qt_messages)
        app = QApplication(sys.argv[:1])
    assert isinstance(app, QApplication)
    app.setOrganizationName(ORGANIZATION)
    app.setApplicationName(APPLICATION)
    app.setApplicationDisplayName(APPLICATION)
    return app


#: Qt messages that say nothing to a user (the offscreen platform cannot resize a window to
#: its size hints; harmless) and would break the "one line on stderr" rule.
QUIET_QT_MESSAGES = ("propagateSizeHints",)


def _qt_messages(mode: QtMsgType, context: QMessageLogContext, message: str) -> None:
    """Qt's messages: the harmless ones above dropped, the others on stderr as Qt does."""
    if any(m in message for m in QUIET_QT_MESSAGES):
        return
    print(message, file=sys.stderr)


def _excepthook(kind: type[BaseException], value: BaseException,
                tb: TracebackType | None) -> None:
    """Unexpected errors in a slot: print them and tell the user; never abort."""
    traceback.print_exception(kind, value, tb)
    app = QApplication.instance()
    if isinstance(app, QApplication) and app.activeWindow() is not None:
        QMessageBox.critical(app.activeWindow(), "Unexpected error",
                             f"{kind.__name__}: {value}\n\nFAP Studio keeps running; saving "
                             "your work is recommended.")


def _pump(app: QApplication, seconds: float) -> None:
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        app.processEvents(QEventLoop.ProcessEventsFlag.AllEvents, 20)
        time.sleep(0.005)


def open_initial(window: MainWindow, photo: str | None = None,
                 project: str | None = None, photo_neutral: bool = False) -> bool:
    """Open what the editor starts with: ``project``, else ``photo``, else the last project
    (QSettings ``lastProject``), else the bundled sample face. False if the requested file
    could not be opened (the sample face is shown instead, after an error message)."""
    ok = True
    if project is not None:
        ok = window.docs.open_project(project, ask=False)
    elif photo is not None:
        ok = window.docs.open_photo(photo, ask=False, photo_neutral=photo_neutral)
    else:
        last = str(settings().value("lastProject", "") or "")
        if last and Path(last).is_file():
            window.docs.open_project(last, ask=False)
    if window.model.doc is None:
        ok = window.docs.open_photo(str(SAMPLE_FACE), ask=False, photo_neutral=photo_neutral,
                                    remember=False) and ok
    return ok


def run(photo: str | None = None, faps: dict[str, float] | None = None,
        screenshot: str | None = None, project: str | None = None,
        photo_neutral: bool = False, keep_expression: bool = False,
        preset: tuple[str, float] | None = None) -> int:
    """Open the editor window; returns the exit code.

    Parameters
    ----------
    photo : a neutral frontal photo to open; without ``photo`` and ``project``, the last
        project saved or opened (QSettings), else the bundled sample face
    faps : FAP name (or number) -> value in FAPU, applied after opening (one undo step)
    screenshot : if given, lay the window out (offscreen works), render, save a PNG of the
        whole window there and return 0 without entering the event loop
    project : a project file to open (takes precedence over ``photo``)
    photo_neutral : declare the photo neutral (FAPs apply to the photo itself)
    keep_expression : ``faps`` add to the photo's own expression instead of replacing it
    preset : (name, intensity) when ``faps`` are that one preset: the Presets panel shows it
        selected at that intensity

    A file that cannot be opened is reported (message box, or stderr and exit code 2 when
    headless); the interactive window then shows the sample face.
    """
    app = application()
    headless = screenshot is not None
    window = MainWindow()

    errors: list[str] = []

    def fail(message: str) -> int:  # one line: the first error said, else ``message``
        print(f"fap-studio: error: {' '.join((errors or [message])[0].split())}",
              file=sys.stderr)
        window.close_without_prompt()
        return 2

    def open_and_apply() -> int | None:  # the exit code when headless and failed
        ok = open_initial(window, photo, project, photo_neutral)
        if not ok and headless:
            return fail(f"cannot open {project or photo or SAMPLE_FACE}")
        if faps:
            try:
                # the requested FAPs replace the document's (the photo's own expression): they
                # apply to the neutralised face, as presets and .fap files do; with
                # keep_expression they add to what the photo shows
                doc = window.model.doc
                if doc is not None:
                    vec = FAPS.vector(faps) + (doc.faps if keep_expression else 0)
                    window.model.push(doc.with_fap_vector(vec), "Apply FAPs")
                    panel = window.extensions.get("presets_panel")
                    if preset is not None and panel is not None:
                        with contextlib.suppress(KeyError):  # (a name the list spells otherwise)
                            panel.select(preset[0])
                            panel.intensity.setValue(round(preset[1] * 100))
            except ValueError as e:
                if headless:
                    return fail(str(e))
                QMessageBox.warning(window, "Cannot apply the FAPs", str(e))
        return None

    if headless:  # no dialogs (errors go to stderr), no recent files
        window.docs.remember = False
        window.docs.interactive = False
        window.docs.error = lambda _title, msg: errors.append(str(msg))
        code = open_and_apply()
        return code if code is not None else _screenshot(app, window, str(screenshot))
    sys.excepthook = _excepthook
    window.restore_layout()
    # the window first, then the photo: opening it (detector and models loaded on first use,
    # landmarks, fitting) runs on the thread pool while the window is already up (issue 15)
    window.show()
    QTimer.singleShot(0, open_and_apply)
    return app.exec()


def _screenshot(app: QApplication, window: MainWindow, path: str) -> int:
    window.resize(*SCREENSHOT_SIZE)
    window.show()
    _pump(app, 0.15)
    window.canvas.fit_face()
    rendered = window.scheduler.wait(15000)
    _pump(app, 0.15)
    image = window.grab()
    window.close_without_prompt()
    if not rendered:
        print("fap-studio: error: the preview did not render in time", file=sys.stderr)
        return 2
    out = Path(path)
    try:
        with atomic_file(out) as tmp:
            if not image.save(str(tmp), "PNG"):
                raise FapStudioError(f"{out}: cannot write the screenshot")
    except FapStudioError as e:
        print(f"fap-studio: error: {e}", file=sys.stderr)
        return 2
    return 0
