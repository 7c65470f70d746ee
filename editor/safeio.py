"""Safe file input and output at the boundary of FAP Studio (no Qt).

Reading: :func:`read_bounded` opens without blocking, accepts regular files only (no device
such as ``/dev/zero``, no FIFO, no folder) and refuses more than ``max_bytes`` *before* reading
them, so a bad path can neither hang the program nor exhaust its memory.

Writing: every output goes through :func:`atomic_file` (or :func:`atomic_write_bytes` /
:func:`atomic_write_text`) or :func:`atomic_dir`: the data are written to a temporary file
(folder) next to the target and renamed onto it only once complete, so an error, Ctrl-C or a
full disk leaves the target as it was and no temporary file behind.

:func:`quiet_stderr` silences what C libraries (libpng, libjpeg, FFmpeg, OpenCV) print on the
process's standard error, so that the command line prints one line per error.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import stat
import sys
from collections.abc import Iterator
from pathlib import Path

from .errors import FapStudioError

__all__ = ["atomic_dir", "atomic_file", "atomic_write_bytes", "atomic_write_text",
           "finite_in", "iter_bounded", "quiet_stderr", "read_bounded"]

_CHUNK = 1 << 20


def _why(e: OSError) -> str:
    return e.strerror or str(e)


def read_bounded(path: str | os.PathLike, max_bytes: int, *,
                 error: type[FapStudioError] = FapStudioError, label: str | None = None,
                 what: str = "a file") -> bytes:
    """The bytes of the regular file ``path`` (at most ``max_bytes``), else ``error``.

    Opened with ``O_NONBLOCK`` (a FIFO cannot hang the open), checked with ``fstat`` on the
    open descriptor (regular files only), refused if larger than ``max_bytes`` before and
    while reading (a file that grows is cut off, never read without bound).
    """
    return b"".join(iter_bounded(path, max_bytes, error=error, label=label, what=what))


def iter_bounded(path: str | os.PathLike, max_bytes: int, *,
                 error: type[FapStudioError] = FapStudioError, label: str | None = None,
                 what: str = "a file", chunk: int = _CHUNK) -> Iterator[bytes]:
    """:func:`read_bounded` in chunks of at most ``chunk`` bytes (a streaming reader's memory
    stays flat in the file length); the same checks and messages, raised when reached."""
    p = Path(path)
    label = label or str(p)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(p, flags)
    except OSError as e:
        raise error(f"{label}: cannot read ({_why(e)})") from None
    try:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            raise error(f"{label}: cannot read (is a folder, not {what})")
        if not stat.S_ISREG(st.st_mode):
            raise error(f"{label}: cannot read (not a regular file but a device, pipe or "
                        f"socket; expected {what})")
        if st.st_size > max_bytes:
            raise error(f"{label}: {st.st_size} bytes, expected at most {max_bytes} for {what}")
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
        total = 0
        while True:
            b = os.read(fd, min(chunk, max_bytes + 1 - total))
            if not b:
                break
            total += len(b)
            if total > max_bytes:
                raise error(f"{label}: more than {max_bytes} bytes, expected at most "
                            f"{max_bytes} for {what}")
            yield b
    except OSError as e:
        raise error(f"{label}: cannot read ({_why(e)})") from None
    finally:
        os.close(fd)


def _temp_name(p: Path, suffix: str) -> Path:
    import secrets  # here: with hashlib and OpenSSL, ~5 ms of every start otherwise

    return p.with_name(f".{p.name}.{os.getpid()}.{secrets.token_hex(4)}.part{suffix}")


def _write_all(fh, data: bytes) -> None:
    """Write ``data`` to the open file ``fh`` (the one place bytes hit the disk: tests replace
    it with a writer that fails half-way, as a full disk does)."""
    fh.write(data)


@contextlib.contextmanager
def atomic_file(path: str | os.PathLike, *, error: type[FapStudioError] = FapStudioError,
                label: str | None = None) -> Iterator[Path]:
    """Yield a temporary path in the target's folder (same extension, so a library that picks
    the format by extension still works); on a normal exit it is flushed to disk and renamed
    onto ``path``; on any exception (Ctrl-C included) it is removed and the target is left as
    it was. An OSError (full disk, read-only folder, ...) becomes ``error`` with one line.
    (No fsync: this is about never leaving a partial file, not about surviving power loss.)"""
    p = Path(path)
    label = label or str(p)
    if p.is_dir():
        raise error(f"{label}: is a folder, expected a file name")
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        tmp = _temp_name(p, p.suffix)
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    except OSError as e:
        raise error(f"{label}: cannot write ({_why(e)})") from None
    try:
        yield tmp
        os.replace(tmp, p)
    except OSError as e:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise error(f"{label}: cannot write ({_why(e)})") from None
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def atomic_write_bytes(path: str | os.PathLike, data: bytes, *,
                       error: type[FapStudioError] = FapStudioError,
                       label: str | None = None) -> Path:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_file`); returns the path."""
    with atomic_file(path, error=error, label=label) as tmp, open(tmp, "wb") as fh:
        _write_all(fh, data)
    return Path(path)


def atomic_write_text(path: str | os.PathLike, text: str, *,
                      error: type[FapStudioError] = FapStudioError,
                      label: str | None = None) -> Path:
    """Write UTF-8 ``text`` (``\\n`` line ends) to ``path`` atomically; returns the path."""
    return atomic_write_bytes(path, text.encode("utf-8"), error=error, label=label)


@contextlib.contextmanager
def atomic_dir(path: str | os.PathLike, *, error: type[FapStudioError] = FapStudioError,
               label: str | None = None) -> Iterator[Path]:
    """Yield a staging folder next to ``path``; on a normal exit its files are moved into
    ``path`` (the folder itself is renamed when ``path`` does not exist or is empty); on any
    exception the staging folder and everything in it are removed."""
    p = Path(path)
    label = label or str(p)
    if p.exists() and not p.is_dir():
        raise error(f"{label}: exists and is not a folder")
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        stage = _temp_name(p, "")
        stage.mkdir(0o777)
    except OSError as e:
        raise error(f"{label}: cannot create the folder ({_why(e)})") from None
    try:
        yield stage
        if p.is_dir() and not any(p.iterdir()):
            p.rmdir()
        if not p.exists():
            os.rename(stage, p)
        else:
            for f in sorted(stage.iterdir()):
                os.replace(f, p / f.name)
            stage.rmdir()
    except OSError as e:
        shutil.rmtree(stage, ignore_errors=True)
        raise error(f"{label}: cannot write ({_why(e)})") from None
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise


@contextlib.contextmanager
def quiet_stderr() -> Iterator[None]:
    """Send what C code writes on file descriptor 2 to /dev/null meanwhile (libpng, libjpeg,
    FFmpeg and OpenCV warnings); Python's own ``sys.stderr`` is flushed first."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):
        yield
        return
    try:
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, 2)
        finally:
            os.close(null)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def finite_in(value: object, lo: float, hi: float, what: str, *,
              error: type[FapStudioError] = FapStudioError, lo_open: bool = False) -> float:
    """``value`` as a float if it is a finite number in [lo, hi] (``(lo, hi]`` if
    ``lo_open``), else ``error`` naming ``what``."""
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError):
        raise error(f"{what}: expected a number, got {value!r}"[:200]) from None
    ok = x == x and abs(x) != float("inf") and (lo < x if lo_open else lo <= x) and x <= hi
    if not ok:
        br = "(" if lo_open else "["
        raise error(f"{what}: expected a finite number in {br}{lo:g}, {hi:g}], got {x:g}")
    return x
