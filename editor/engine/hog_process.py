"""dlib's HOG face scan in a helper process, for programs with an event loop (the editor).

dlib holds Python's GIL while it scans an image (about 0.3 s for the 800-pixel copy the
detector works on): run on a worker thread, that still freezes every other Python thread, the
GUI's included. :func:`enable` makes :class:`~editor.engine.landmarks.DlibDetector` send the
scan (a small greyscale array) to one long-lived helper process instead; the calling thread
then waits without the GIL. The result is the same call on the same pixels, so the same face.
The command line never enables it (nothing to keep responsive there).
"""

from __future__ import annotations

import multiprocessing
from concurrent.futures import BrokenExecutor, ProcessPoolExecutor
from functools import lru_cache
from typing import Any

import numpy as np

Scan = tuple[list[tuple[int, int, int, int]], list[float]]

_POOL: ProcessPoolExecutor | None = None


def enable() -> None:
    """Start the helper process now (in the background) and use it for every scan."""
    global _POOL
    if _POOL is None:
        _POOL = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"))
        _POOL.submit(_warm)


def disable() -> None:
    """Scan in process again and stop the helper (program exit, tests)."""
    global _POOL
    pool, _POOL = _POOL, None
    if pool is not None:
        pool.shutdown(wait=True, cancel_futures=True)


def enabled() -> bool:
    return _POOL is not None


def scan(grey: np.ndarray, upsample: int) -> Scan | None:
    """Boxes (left, top, right, bottom) and scores of the faces in ``grey`` from the helper
    process, or None when it is not enabled or has died (the caller scans in process)."""
    pool = _POOL
    if pool is None:
        return None
    try:
        return pool.submit(_scan, np.ascontiguousarray(grey), int(upsample)).result()
    except (BrokenExecutor, OSError, RuntimeError):
        disable()
        return None


@lru_cache(maxsize=1)
def _detector() -> Any:
    import dlib

    return dlib.get_frontal_face_detector()


def _warm() -> None:
    _detector()


def _scan(grey: np.ndarray, upsample: int) -> Scan:
    rects, scores, _ = _detector().run(grey, upsample, 0.0)
    return ([(r.left(), r.top(), r.right(), r.bottom()) for r in rects],
            [float(s) for s in scores])
