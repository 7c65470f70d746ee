"""Small Qt helpers shared by the editor's widgets."""

from __future__ import annotations

import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from PySide6.QtCore import QObject, QSettings, Qt
from PySide6.QtWidgets import QApplication, QMessageBox, QWidget

from editor.errors import Cancelled, FapStudioError

ORGANIZATION = "FAP Studio"
APPLICATION = "FAP Studio"


@contextmanager
def signals_blocked(*objects: QObject) -> Iterator[None]:
    """Block the signals of ``objects`` inside the block (restoring the previous state)."""
    previous = [o.blockSignals(True) for o in objects]
    try:
        yield
    finally:
        for o, p in zip(objects, previous, strict=True):
            o.blockSignals(p)


def settings() -> QSettings:
    """The application's user settings.

    The format is ``QSettings.defaultFormat()`` (native unless changed), so tests can redirect
    everything with ``setDefaultFormat(IniFormat)`` + ``setPath(IniFormat, UserScope, tmp)``.
    """
    return QSettings(QSettings.defaultFormat(), QSettings.Scope.UserScope, ORGANIZATION,
                     APPLICATION)


def error_text(exc: BaseException) -> str:
    """One line for the user: a FapStudioError's own message, else the exception's type."""
    if isinstance(exc, FapStudioError):
        text = str(exc)
    else:
        text = f"unexpected error: {type(exc).__name__}: {exc}"
    return text.strip().splitlines()[0] if text.strip() else type(exc).__name__


def run_guarded(parent: QWidget | None, title: str, action: Callable[[], Any], *,
                busy: bool = False,
                report: Callable[[str, str], None] | None = None) -> tuple[bool, Any]:
    """Run ``action``; any error becomes a one-line message and the GUI carries on.

    Returns ``(True, result)`` or ``(False, None)`` (also, silently, when the user cancelled:
    :class:`Cancelled`). ``busy`` shows the wait cursor meanwhile;
    ``report(title, message)`` replaces the warning box (the headless CLI prints instead).
    Unexpected exceptions (bugs) also print their traceback on stderr.
    """
    if busy:
        QApplication.setOverrideCursor(Qt.CursorShape.WaitCursor)
    try:
        return True, action()
    except Cancelled:
        return False, None
    except Exception as e:  # a bug must not take the user's work down
        if not isinstance(e, FapStudioError):
            traceback.print_exc()
        message = error_text(e)
    finally:
        if busy:
            QApplication.restoreOverrideCursor()
    if report is not None:
        report(title, message)
    else:
        QMessageBox.warning(parent, title, message)
    return False, None
