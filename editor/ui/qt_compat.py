"""Workaround for a reference-count bug of the PySide6 6.12.0 wheels on Python < 3.12.

The bindings return ``None`` (every void method: ``setValue``, ``processEvents``, ...) and
``True`` (``SignalInstance.emit``) without taking a reference, as if these objects were
immortal, which they are only from Python 3.12 on. On Python 3.11 each such call drops one
reference; after a few thousand calls (a minute of dragging sliders, or pyqtgraph emitting on
every pan and hover) the count reaches zero and the interpreter aborts with "Fatal Python
error: none_dealloc" / "bool_dealloc". :func:`guard_singleton_refcounts` detects the bug with a
probe and, only then, gives the singletons a huge extra reference count (what 3.12 does for
immortal objects). Nothing happens on Python 3.12+ or with fixed bindings.
"""

from __future__ import annotations

import ctypes
import sys

_APPLIED = False


def bindings_drop_singletons() -> bool:
    """True if PySide6 calls drop references to ``None`` or ``True`` (the bug above)."""
    from PySide6.QtCore import QObject, Signal

    class _Probe(QObject):
        ping = Signal()

    probe = _Probe()

    def drops() -> bool:
        none0, true0 = sys.getrefcount(None), sys.getrefcount(True)
        for _ in range(16):
            probe.ping.emit()
            probe.setObjectName("probe")
        return sys.getrefcount(None) < none0 - 8 or sys.getrefcount(True) < true0 - 8

    # the bug drops a reference on every call, every time; other threads releasing None or
    # True during one probe (a render worker finishing) do not, three times in a row
    return all(drops() for _ in range(3))


def guard_singleton_refcounts() -> bool:
    """Apply the workaround if needed (CPython < 3.12 only); True if it was applied."""
    global _APPLIED
    if _APPLIED:
        return True
    if sys.implementation.name != "cpython" or sys.version_info >= (3, 12):
        return False
    if not bindings_drop_singletons():
        return False
    for obj in (None, True, False, NotImplemented, Ellipsis):  # ob_refcnt: first field
        ctypes.c_ssize_t.from_address(id(obj)).value += 1 << 40
    _APPLIED = True
    return True
