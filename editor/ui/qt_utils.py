"""Small Qt helpers shared by the editor's widgets."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from PySide6.QtCore import QObject, QSettings

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
