"""A frame-sized buffer whose pages are touched ahead of its use, on a thread. No Qt.

A new array's memory costs a page fault per page on its first write: a 24 MP RGB frame is
~17,600 pages, 40-250 ms of system time on this kind of (virtual) machine, more than the
copy itself. The first render of a large photo writes its whole frame into a new array (the
warp's copy of the photo); :func:`reserve`, called when the photo is loaded, has a thread
allocate that array and touch its pages while the caller detects the landmarks and fits the
mesh, and :func:`copy_of` then copies the photo into it instead of into new memory (the
same values: ``np.copyto`` of the whole array).

At most one buffer is held (a later :func:`reserve` replaces it); :func:`copy_of` hands it
out once, to the first copy of an image of its shape and type.
"""

from __future__ import annotations

import mmap
import threading

import numpy as np

from .threads import Pending

#: Smaller frames are not worth a thread (a 1080p frame faults in a few ms)
MIN_BYTES = 32 << 20

_LOCK = threading.Lock()
#: the pending buffer: (shape, dtype, the touching) or nothing
_SPARE: list[tuple[tuple[int, ...], np.dtype, Pending[np.ndarray]]] = []


def _touch(shape: tuple[int, ...], dtype: np.dtype) -> np.ndarray:
    a = np.empty(shape, dtype)
    a.reshape(-1).view(np.uint8)[::mmap.PAGESIZE] = 0  # one write a page
    return a


def reserve(shape: tuple[int, ...], dtype: np.dtype | type = np.uint8) -> None:
    """Start touching a buffer of ``shape`` and ``dtype`` on a thread (nothing for a frame
    below :data:`MIN_BYTES`); it replaces a buffer reserved before and not taken."""
    shape, dtype = tuple(int(n) for n in shape), np.dtype(dtype)
    if int(np.prod(shape)) * dtype.itemsize < MIN_BYTES:
        return
    with _LOCK:
        _SPARE[:] = [(shape, dtype, Pending(_touch, shape, dtype))]


def copy_of(img: np.ndarray) -> np.ndarray:
    """``img.copy()`` (C order), in the reserved buffer when one of its shape and type is
    pending (waiting for its thread if it is not done)."""
    out = _reserved(img)
    if out is None:
        return img.copy()
    np.copyto(out, img)
    return out


def empty_of(img: np.ndarray) -> np.ndarray:
    """An array of ``img``'s shape and type (C order), its values undefined: the reserved
    buffer as :func:`copy_of` takes it, else new memory (for a caller that writes every
    pixel itself)."""
    out = _reserved(img)
    return np.empty_like(img, order="C") if out is None else out


def _reserved(img: np.ndarray) -> np.ndarray | None:
    """The reserved buffer if it is of ``img``'s shape and type (taken: handed out once),
    else None."""
    if not _SPARE:  # (no lock: the common case, every frame)
        return None
    with _LOCK:
        got = _SPARE[0] if _SPARE and _SPARE[0][:2] == (img.shape, img.dtype) else None
        if got is not None:
            _SPARE.clear()
    if got is None:
        return None
    try:
        return got[2].result()
    except (MemoryError, RuntimeError):  # (no memory; a fork while it was touched)
        return None
