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
exception in a worker is raised in the parent when its item's turn comes. A caller that knows
its process runs no Qt and no other thread (the CLI; :func:`fork_is_safe` checks) may ask for
``fork`` instead: no server to start, and the workers inherit what this process built.

The per-process :data:`FACE` is what :func:`render_face_into` renders on. :func:`rendered_frames`
hands the frames back through shared memory (a ring of frame buffers: a 1080p frame pickled
through the pool's pipe cost about as much as rendering it), so that on two cores one worker
renders while this process encodes; for a video already in the encoder's yuv420p layout (the
conversion done in the worker: :mod:`editor.engine.yuv`). Forked workers inherit the parent's
face with its plans built by the first frame, rendered in the parent (OpenCV's thread pool is
stopped while forking: a child inherits its state but not its threads).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import sys
from collections import deque
from collections.abc import Callable, Generator, Iterable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager, nullcontext
from multiprocessing import shared_memory
from typing import Any, TypeVar

import numpy as np

from editor.engine.yuv import I420Canvas, even_box, i420_box, i420_shape
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
    """Worker processes for rendering a video or a folder of frames: one per core, beside the
    writer (the H.264 encoder, PNG encoding) in the parent. Measured on 2 cores (1080p joy
    ramp to H.264, frames back through shared memory, pool warm): 2 workers 77-78 frames/s,
    1 worker 73-75, all in one process 64 (callers render in this process on one core: see
    :func:`render_workers`)."""
    return default_jobs()


def render_workers(jobs: int | None) -> int:
    """How many worker processes render the frames for a ``jobs`` setting: None (auto) is
    :func:`default_render_jobs` when there are two cores or more, else 0 (this process); 1 is
    0; N > 1 is N."""
    if jobs is None:
        return default_render_jobs() if default_jobs() >= 2 else 0
    return jobs if jobs > 1 else 0


def fork_is_safe() -> bool:
    """Whether worker processes may be started by ``fork`` here: the platform has it, no
    other Python thread runs and Qt is not loaded (the GUI runs Qt threads: a forked child
    could inherit a lock one of them held; the CLI never imports Qt)."""
    import threading

    return ("fork" in mp.get_all_start_methods() and threading.active_count() == 1
            and not any(m in sys.modules for m in ("PySide6", "PyQt6", "PyQt5")))


def _context(fork: bool = False) -> Any:
    methods = mp.get_all_start_methods()
    if fork and "fork" in methods:
        return mp.get_context("fork")
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
                initargs: tuple[Any, ...] = (), threads: int = 1, fork: bool = False
                ) -> Generator[R, None, None]:
    """``fn(item)`` for every item in ``jobs`` worker processes, yielded in order.

    ``fn`` and ``initializer`` must be module-level functions (they are pickled by name).
    ``window`` (default ``2 * jobs + 1``) bounds the items submitted but not yet yielded.
    Closing the generator early (``break``, an exception) cancels what is queued.
    ``fork``: start the workers by forking this process (only where :func:`fork_is_safe`
    says so: the caller's job to ask); they inherit its memory, and ``initargs`` are not
    pickled. Otherwise ``forkserver`` (``spawn`` where there is none).
    """
    window = max(1, window or 2 * jobs + 1)
    ex = ProcessPoolExecutor(max_workers=jobs, mp_context=_context(fork),
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


def _inherit_face(face: Any) -> None:
    """Worker initializer of a forked pool: this process's :data:`FACE` is the parent's
    (inherited with its plans and caches; nothing rebuilt or sent)."""
    global FACE
    FACE = face


#: the shared-memory frame buffers this worker has opened, by name
_SLOTS: dict[str, Any] = {}

#: frame layouts :func:`rendered_frames` hands back: RGB, or the encoder's I420 (yuv420p)
LAYOUTS = ("rgb", "i420")


def frame_shape(h: int, w: int, layout: str) -> tuple[int, ...]:
    """The shape of an ``h x w`` frame in ``layout`` (I420: even sizes, Y then U and V)."""
    if layout == "i420":
        return i420_shape(h, w)
    if layout == "rgb":
        return (h, w, 3)
    raise ValueError(f"unknown frame layout {layout!r}; expected one of {LAYOUTS}")


def render_face_into(task: tuple[np.ndarray, bool, str, tuple[int, ...]]) -> str:
    """``(vector, creases, buffer name, shape)``: render on this worker's :data:`FACE` into
    the shared RGB frame buffer; returns its name. (I420 frames go through
    :func:`render_patch_into`: only each render's box is converted.)"""
    vec, creases, name, shape = task
    shm = _SLOTS.get(name)
    if shm is None:
        shm = _SLOTS[name] = shared_memory.SharedMemory(name=name)
    out: np.ndarray = np.ndarray(shape, np.uint8, buffer=shm.buf)
    render_frame(FACE, vec, creases, out)
    return name


def render_frame(face: Any, vec: np.ndarray, creases: bool, out: np.ndarray) -> np.ndarray:
    """``face.render(vec)`` into ``out``, RGB ``(H, W, 3)``."""
    out[:] = face.render(vec, creases=creases)
    return out


def render_patch(face: Any, vec: np.ndarray, creases: bool, out: np.ndarray
                 ) -> tuple[int, int, int, int] | None:
    """``face.render(vec)`` as an I420 patch: the box (even corners) outside which the frame is
    the photo (the render's ``bbox``: every pixel it wrote lies inside), its I420 planes
    (:func:`~editor.engine.yuv.i420_box`) written at the start of ``out`` (1-D uint8, room for
    a whole frame); returns the box, None when the frame is the photo."""
    res = face.render_full(vec, creases=creases)
    h, w = res.image.shape[:2]
    box = even_box(res.bbox, h, w)
    if box is not None:
        bh, bw = box[3] - box[1], box[2] - box[0]
        i420_box(res.image, box, out[:bh * bw * 3 // 2].reshape(bh * 3 // 2, bw))
    return box


def render_patch_into(task: tuple[np.ndarray, bool, str, int]
                      ) -> tuple[str, tuple[int, int, int, int] | None]:
    """``(vector, creases, buffer name, buffer size)``: :func:`render_patch` on this worker's
    :data:`FACE` into the shared buffer; returns its name and the patch's box."""
    vec, creases, name, size = task
    shm = _SLOTS.get(name)
    if shm is None:
        shm = _SLOTS[name] = shared_memory.SharedMemory(name=name)
    return name, render_patch(FACE, vec, creases, np.ndarray((size,), np.uint8, buffer=shm.buf))


#: bytes of patches :func:`i420_frames` keeps for vectors that come again later
PATCH_CACHE_BYTES = 256 * 2**20


def _repeats(vecs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per frame an id of its vector (equal bytes, equal id) and how often each id occurs."""
    rows = np.ascontiguousarray(vecs).reshape(len(vecs), -1)
    keys = rows.view(np.dtype((np.void, rows.dtype.itemsize * rows.shape[1]))).ravel()
    _, ids, counts = np.unique(keys, return_inverse=True, return_counts=True)
    return ids.ravel(), counts


def i420_frames(face: Any, vecs: np.ndarray, creases: bool, jobs: int, *, fork: bool = False,
                cache_bytes: int = PATCH_CACHE_BYTES) -> Iterator[np.ndarray]:
    """``rgb_to_i420(face.render(v))`` for each vector, in order, rendered in ``jobs`` worker
    processes (0: in this process), as a video encoder takes them.

    A frame differs from the photo only inside its render's box: a worker converts that box
    alone (:func:`render_patch`) and hands back the patch through shared memory, this process
    pastes it into the photo's picture (:class:`~editor.engine.yuv.I420Canvas`). A vector that
    comes again (a hold, a return to an earlier expression) is rendered once: its patch is kept
    (up to ``cache_bytes`` in all) until its last frame; the frame of a hold is the previous one
    unchanged. Each frame is the same buffer, valid until the next one is asked for.

    ``fork`` (where :func:`fork_is_safe`): the first frame is rendered here, building the face's
    plans, then the workers are forked and inherit them. Otherwise each worker builds the face
    from :func:`face_args` (a ``forkserver`` child: safe beside Qt's threads)."""
    vecs = np.asarray(vecs)
    n = len(vecs)
    if n == 0:
        return
    ids, left = _repeats(vecs)
    canvas = I420Canvas(np.asarray(face.image))
    size = canvas.frame.size
    own = np.empty(size, np.uint8)  # this process's patch buffer
    cache: dict[int, tuple[tuple[int, int, int, int] | None, np.ndarray | None]] = {}
    held = [0]  # bytes in the cache
    shown = [-1]  # the id of the vector the canvas shows

    def show(i: int, box: tuple[int, int, int, int] | None, buf: np.ndarray | None
             ) -> np.ndarray:
        """Frame ``i``: the patch ``box`` (its planes at the start of ``buf``; None, None: the
        frame shown, the same vector); kept when the vector comes again and there is room."""
        k = int(ids[i])
        patch = None
        if box is not None and buf is not None:
            patch = buf[:(box[2] - box[0]) * (box[3] - box[1]) * 3 // 2]
        if buf is not None and k not in cache and left[k] > 1:  # comes again: a copy kept
            nbytes = 0 if patch is None else patch.size
            if held[0] + nbytes <= cache_bytes:
                cache[k] = (box, None if patch is None else patch.copy())
                held[0] += nbytes
        frame = canvas.show(box, patch) if k != shown[0] else canvas.frame
        shown[0] = k
        left[k] -= 1
        if not left[k] and k in cache:  # its last frame
            c = cache.pop(k)[1]
            held[0] -= 0 if c is None else c.size
        return frame

    def again(i: int) -> np.ndarray:
        """Frame ``i`` of a vector shown, kept or rendered before (here if it was not kept)."""
        k = int(ids[i])
        if k == shown[0]:
            return show(i, None, None)
        if k in cache:
            return show(i, *cache[k])
        return show(i, render_patch(face, vecs[i], creases, own), own)

    if jobs < 1:
        seen: set[int] = set()
        for i in range(n):
            k = int(ids[i])
            if k in seen:
                yield again(i)
            else:
                seen.add(k)
                yield show(i, render_patch(face, vecs[i], creases, own), own)
        return
    yield from _pooled_i420(face, vecs, creases, jobs, fork, ids, cache, show, again, own, size)


def _pooled_i420(face: Any, vecs: np.ndarray, creases: bool, jobs: int, fork: bool,
                 ids: np.ndarray, cache: dict[int, Any],
                 show: Callable[[int, Any, Any], np.ndarray],
                 again: Callable[[int], np.ndarray], own: np.ndarray, size: int
                 ) -> Generator[np.ndarray, None, None]:
    """:func:`i420_frames` in worker processes: at most ``2 jobs + 1`` renders in flight,
    each in its own shared buffer (free again once its patch is pasted or kept)."""
    n = len(vecs)
    window = 2 * jobs + 1
    slots = [shared_memory.SharedMemory(create=True, size=size) for _ in range(window)]
    bufs: dict[str, np.ndarray] | None = {
        s.name: np.ndarray((size,), np.uint8, buffer=s.buf) for s in slots}
    free = [s.name for s in slots]
    pending: dict[int, Future[tuple[str, Any]]] = {}  # frame -> its render
    flying: set[int] = set()  # the ids being rendered
    ex: ProcessPoolExecutor | None = None
    first: np.ndarray | None = None
    init: Callable[..., None]
    args: tuple[Any, ...]
    j = 0  # the next frame to schedule
    try:
        if fork:  # frame 0 here: the face's plans are built before the workers are forked
            first = show(0, render_patch(face, vecs[0], creases, own), own)
            j = 1
            ctx, init, args = _context(True), _inherit_face, (face,)
        else:
            ctx, init, args = _context(False), init_face, face_args(face)
        ex = ProcessPoolExecutor(max_workers=jobs, mp_context=ctx, initializer=_worker_init,
                                 initargs=(1, init, args))
        for i in range(n):
            # schedule: a frame whose vector is kept or in flight is not rendered again
            with _single_threaded_cv2() if fork and i == 0 else nullcontext():
                while j < n and len(pending) < window:
                    k = int(ids[j])
                    if k not in cache and k not in flying:
                        assert bufs is not None
                        pending[j] = ex.submit(render_patch_into,
                                               (vecs[j], creases, free.pop(), size))
                        flying.add(k)
                    j += 1
            if first is not None:
                frame, first = first, None
                yield frame
                continue
            f = pending.pop(i, None)
            if f is None:
                yield again(i)
                continue
            try:
                name, box = f.result()
            except BrokenProcessPool as e:
                raise FapStudioError(f"a render worker process stopped unexpectedly ({e})"
                                     ) from None
            flying.discard(int(ids[i]))
            assert bufs is not None
            frame = show(i, box, bufs[name])
            free.append(name)
            yield frame
    finally:
        for f in pending.values():
            f.cancel()
        if ex is not None:
            ex.shutdown(wait=True, cancel_futures=True)  # the workers let go of the buffers
        bufs = None
        for shm in slots:
            shm.close()
            shm.unlink()


def rendered_frames(face: Any, vecs: np.ndarray, creases: bool, jobs: int, *,
                    layout: str = "rgb", fork: bool = False) -> Iterator[np.ndarray]:
    """``face.render(v)`` for each vector, rendered in ``jobs`` worker processes, in order,
    in ``layout`` (``"rgb"``, or ``"i420"``: :func:`editor.engine.yuv.rgb_to_i420` of it).

    Each frame is a view of a shared buffer, valid until the next one is asked for (a ring of
    ``window + 1`` buffers: a buffer is handed to a new frame only after the frame it held was
    yielded and the caller came back). The buffers are released when the generator ends or is
    closed.

    ``fork`` (where :func:`fork_is_safe`): the first frame is rendered here, so that the
    face's plans are built once, then the workers are forked and inherit them (no face
    rebuilt per worker, no forkserver to start). Otherwise each worker builds the face from
    :func:`face_args` (a ``forkserver`` child: safe beside Qt's threads).
    """
    h, w = np.asarray(face.image).shape[:2]
    shape = frame_shape(h, w, layout)  # (an unknown layout refused here)
    if layout == "i420":  # the frames' boxes only: see i420_frames
        yield from i420_frames(face, vecs, creases, jobs, fork=fork)
        return
    size = int(np.prod(shape))
    window = 2 * jobs + 1
    slots = [shared_memory.SharedMemory(create=True, size=size) for _ in range(window + 1)]
    views: dict[str, np.ndarray] | None = {s.name: np.ndarray(shape, np.uint8, buffer=s.buf)
                                           for s in slots}
    names: Generator[str, None, None] | None = None
    try:
        if fork:
            assert views is not None
            yield from _forked_frames(face, vecs, creases, jobs, window, slots, views, shape)
            return
        tasks = ((v, creases, slots[i % len(slots)].name, shape) for i, v in enumerate(vecs))
        names = ordered_map(render_face_into, tasks, jobs, window=window,
                            initializer=init_face, initargs=face_args(face))
        for name in names:
            assert views is not None
            yield views[name]
    finally:
        if names is not None:
            names.close()  # the workers stop (and let go of the buffers) first
        views = None
        for shm in slots:
            try:
                shm.close()
            except BufferError:  # the caller still holds the last frame: freed with it
                pass
            shm.unlink()


@contextmanager
def _single_threaded_cv2() -> Iterator[None]:
    """OpenCV without its worker threads while this process forks (they are stopped and
    joined here, then started again as needed): a forked child inherits the thread pool's
    state but not its threads, and would hang in the first call that wakes or stops them
    (seen: ``cv2.setNumThreads`` waiting forever on a dead thread's condition variable)."""
    import cv2

    before = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        yield
    finally:
        cv2.setNumThreads(before)


def _forked_frames(face: Any, vecs: np.ndarray, creases: bool, jobs: int, window: int,
                   slots: list[Any], views: dict[str, np.ndarray], shape: tuple[int, ...]
                   ) -> Generator[np.ndarray, None, None]:
    """:func:`rendered_frames` with forked workers: frame 0 rendered here (building the plans
    they inherit), the workers forked before it is handed on (before the caller's encoder
    starts its threads), then the pool's frames."""
    if not len(vecs):
        return
    first = render_frame(face, vecs[0], creases, views[slots[0].name])
    tasks = ((v, creases, slots[i % len(slots)].name, shape)
             for i, v in enumerate(vecs) if i)
    names = ordered_map(render_face_into, tasks, jobs, window=window,
                        initializer=_inherit_face, initargs=(face,), fork=True)
    try:
        # the first result: the pool started (slots 1..window in use; slot 0 is reused
        # only once frame 1 has been handed on and the caller came back)
        with _single_threaded_cv2():
            name = next(names, None)
        yield first
        if name is None:
            return
        yield views[name]
        for name in names:
            yield views[name]
    finally:
        names.close()
