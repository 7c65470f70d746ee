"""A call run on a thread of its own, its result (or its exception) collected later. No Qt.

For the one-time steps on large photos whose heavy parts run in OpenCV or numpy without the
GIL (the detector's downscale, the two irises, the eye plans beside the mouth's). A thread per
call, none kept: no pool survives into a fork (the video export forks its render workers).
Plain :mod:`threading`, not :mod:`concurrent.futures`, whose import pulls in :mod:`logging`
(~15 ms more to import the renderer).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any, Generic, TypeVar

T = TypeVar("T")


class Pending(Generic[T]):
    """``fn(*args)`` running on a thread; :meth:`result` waits for it."""

    def __init__(self, fn: Callable[..., T], *args: Any) -> None:
        self._out: list[T] = []
        self._err: BaseException | None = None
        self._thread = threading.Thread(target=self._run, args=(fn, args), daemon=True,
                                        name=f"fap-{getattr(fn, '__name__', 'call')}")
        self._thread.start()

    def _run(self, fn: Callable[..., T], args: tuple[Any, ...]) -> None:
        try:
            self._out.append(fn(*args))
        except BaseException as e:  # (handed to the caller of result)
            self._err = e

    def result(self) -> T:
        """The call's value, or its exception raised here (RuntimeError: the thread ended
        without either, as it seems to in a process forked while it ran)."""
        self._thread.join()
        if self._err is not None:
            raise self._err
        if not self._out:
            raise RuntimeError(f"{self._thread.name} did not finish (forked while it ran?)")
        return self._out[0]
