"""Rendering in worker processes, results in order, a bounded number in flight (issue 15).

:func:`ordered_map` runs ``fn(item)`` for each item in a pool of ``jobs`` worker processes and
yields the results in the items' order, with at most ``window`` items submitted and not yet
consumed (memory stays bounded however long the input). The workers are started by
``forkserver`` where the platform has it (a fresh single-threaded server process: forking a
process that runs Qt, MediaPipe or OpenCV threads is not safe), else ``spawn``; each runs
``initializer(*initargs)`` once (e.g. :func:`init_face`, which builds the Face from the photo
and its fitted mesh: the per-item messages carry only a FAP vector). Workers ignore SIGINT:
Ctrl-C reaches the parent, which cancels what is queued, waits for the few running items and
lets the exception through (the callers' staging then removes everything partial). An
exception in a worker is raised in the parent when its item's turn comes.

The per-process :data:`FACE` is what :func:`render_face` renders on.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, TypeVar

import numpy as np

from editor.errors import FapStudioError

T = TypeVar("T")
R = TypeVar("R")

#: imported once in the forkserver (no threads started), inherited by every worker
PRELOAD = ["editor.engine.pool", "editor.engine.face", "editor.engine.own_expression",
           "editor.engine.fap_model", "editor.engine.laplacian", "editor.formats.presets"]

#: the Face of this worker process (set by :func:`init_face`)
FACE: Any = None


def default_jobs() -> int:
    """The CPU cores this process may use (at least 1)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def default_render_jobs() -> int:
    """Worker processes for rendering a video or a folder of frames: the cores but one, which
    the writer (the H.264 encoder, PNG encoding) keeps busy in the parent. On 2 cores that is
    1, in-process: measured, two render workers beside x264's threads were slower (34-37
    against 40-42 frames/s at 1080p on an idle 2-core machine)."""
    return max(1, default_jobs() - 1)


def _context() -> Any:
    methods = mp.get_all_start_methods()
    if "forkserver" in methods:
        ctx = mp.get_context("forkserver")
        ctx.set_forkserver_preload(PRELOAD)
        return ctx
    return mp.get_context("spawn")  # pragma: no cover - Windows


def _worker_init(threads: int, initializer: Callable[..., None] | None,
                 initargs: tuple[Any, ...]) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    import cv2

    cv2.setNumThreads(threads)
    if initializer is not None:
        initializer(*initargs)


def ordered_map(fn: Callable[[T], R], items: Iterable[T], jobs: int, *,
                window: int | None = None,
                initializer: Callable[..., None] | None = None,
                initargs: tuple[Any, ...] = (), threads: int = 1) -> Iterator[R]:
    """``fn(item)`` for every item in ``jobs`` worker processes, yielded in order.

    ``fn`` and ``initializer`` must be module-level functions (they are pickled by name).
    ``window`` (default ``2 * jobs + 1``) bounds the items submitted but not yet yielded.
    Closing the generator early (``break``, an exception) cancels what is queued.
    """
    window = max(1, window or 2 * jobs + 1)
    ex = ProcessPoolExecutor(max_workers=jobs, mp_context=_context(),
                             initializer=_worker_init, initargs=(threads, initializer, initargs))
    pending: deque[Future[R]] = deque()
    it = iter(items)
    try:
        while True:
            for item in it:
                pending.append(ex.submit(fn, item))
                if len(pending) >= window:
                    break
            if not pending:
                return
            try:
                result = pending.popleft().result()
            except BrokenProcessPool as e:
                raise FapStudioError(f"a render worker process stopped unexpectedly ({e})"
                                     ) from None
            yield result
    finally:
        for f in pending:
            f.cancel()
        ex.shutdown(wait=True, cancel_futures=True)


# --------------------------------------------------------------------- a Face per worker
def face_args(face: Any) -> tuple[tuple[Any, ...], np.ndarray]:
    """What a worker needs to build ``face`` again: the photo, landmarks, fitted mesh and own
    expression (a few MB, sent once per worker; not the plans and caches)."""
    return (np.asarray(face.image), face.landmarks, np.asarray(face.vertices), face.mesh,
            face.source, np.asarray(face.expression), face.expression_words,
            face.neutral_landmarks), np.asarray(face.neutral_vertices)


def init_face(args: tuple[Any, ...], neutral: np.ndarray) -> None:
    """Worker initializer: build this process's :data:`FACE` from :func:`face_args` (checked:
    the same neutralised mesh as the parent's face, so the same frames)."""
    from editor.engine.face import Face

    global FACE
    FACE = Face(*args)
    if not np.array_equal(FACE.neutral_vertices, neutral):  # pragma: no cover - a bug
        raise FapStudioError("a render worker rebuilt the face differently")


def render_face(task: tuple[np.ndarray, bool]) -> np.ndarray:
    """``(vector, creases)`` -> this worker's ``FACE.render(vector, creases=creases)``."""
    vec, creases = task
    return FACE.render(vec, creases=creases)
