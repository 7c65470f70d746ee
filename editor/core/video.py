"""Rendering a FAP sequence to a video file or a folder of PNG frames (no Qt).

``export_sequence(face, seq, out, progress=cb)`` renders every frame of a
:class:`~editor.core.fapfile.FapSequence` (FAP 1/2 fields expanded into low-level FAPs, values
clamped to the FAP table's ranges) and writes an MP4 (OpenCV ``VideoWriter``, codec mp4v) when
``out`` ends in ``.mp4``/``.avi``, otherwise PNG files ``frame_00000.png`` ... into the folder
``out``. ``progress(done, total)`` is called after each frame; returning ``False`` cancels.
Output is staged next to the target (a temporary file or folder) and moved there only when
complete and, for a video, read back with the right frame count: on cancel, error, Ctrl-C or
a full disk nothing partial is left (``frames`` counts those rendered).
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from .errors import FapStudioError
from .faps import FAPS
from .imageio import save_image
from .safeio import atomic_dir, atomic_file, quiet_stderr

VIDEO_SUFFIXES = {".mp4": "mp4v", ".avi": "MJPG", ".mov": "mp4v"}


@dataclass(frozen=True)
class ExportResult:
    path: Path
    frames: int
    cancelled: bool


def sequence_vectors(seq) -> np.ndarray:
    """(N, 68) low-level FAP vectors of a sequence (FAP 1/2 expanded), clamped."""
    from .expressions import expand_high_level

    s = expand_high_level(seq) if getattr(seq, "has_high_level", False) else seq
    v = np.asarray(s.frames, np.float32).copy()
    v[:, :2] = 0
    return FAPS.clamp(v)


def export_sequence(face, seq, out: str | os.PathLike[str],
                    progress: Callable[[int, int], bool | None] | None = None,
                    creases: bool = True) -> ExportResult:
    """Render ``seq`` on ``face`` into an MP4 file or a folder of PNG frames."""
    vecs = sequence_vectors(seq)
    n = len(vecs)
    if n == 0:
        raise FapStudioError("the sequence has no frames")
    p = Path(out)
    codec = VIDEO_SUFFIXES.get(p.suffix.lower())
    try:
        # staged next to the target, moved there only when complete (issue 16)
        with (atomic_file if codec else atomic_dir)(p) as tmp:
            done = _write_frames(face, vecs, tmp, codec, seq.fps, progress, creases)
            if done < n:
                raise _Cancelled(done)
            if codec:
                check_video(tmp, done, p)
    except _Cancelled as c:  # nothing partial is kept
        return ExportResult(p, c.args[0], True)
    except FapStudioError as e:  # name the target, not the staging folder
        msg = re.sub(r"\.[^/\\]*\.\d+\.[0-9a-f]{8}\.part[^/\\]*", p.name, str(e))
        raise type(e)(msg) from None
    return ExportResult(p, n, False)


def _write_frames(face, vecs: np.ndarray, out: Path, codec: str | None, fps: float,
                  progress: Callable[[int, int], bool | None] | None, creases: bool) -> int:
    """Render into the video file or folder ``out``; the number of frames written (fewer
    when ``progress`` cancelled). The video is finalised (released) before returning."""
    n = len(vecs)
    h, w = face.image.shape[:2]
    writer = None
    if codec:
        fps = float(fps) if fps and fps > 0 else 25.0
        with quiet_stderr():
            writer = cv2.VideoWriter(str(out), cv2.VideoWriter_fourcc(*codec), fps, (w, h))
        if not writer.isOpened():
            raise FapStudioError(f"{out}: cannot open a video writer ({codec})")
    done = 0
    try:
        for i, vec in enumerate(vecs):
            img = face.render(vec, creases=creases)
            if writer is not None:
                with quiet_stderr():  # "Failed to write frame" on a full disk: checked after
                    writer.write(cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
            else:
                save_image(out / f"frame_{i:05d}.png", img)
            done += 1
            if progress is not None and progress(done, n) is False:
                break
    finally:
        if writer is not None:
            with quiet_stderr():
                writer.release()
    return done


class _Cancelled(Exception):
    pass


def check_video(path: Path, frames: int, label: Path) -> None:
    """Raise FapStudioError unless ``path`` is a finished video of ``frames`` frames (a full
    disk leaves a truncated file the encoder does not report)."""
    try:
        size = path.stat().st_size
    except OSError as e:
        raise FapStudioError(f"{label}: cannot write the video ({e.strerror or e})") from None
    with quiet_stderr():
        cap = cv2.VideoCapture(str(path))
        try:
            got = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) if cap.isOpened() else -1
        finally:
            cap.release()
    if size == 0 or got != frames:
        raise FapStudioError(f"{label}: the video could not be written completely "
                             f"({got if got >= 0 else 0} of {frames} frames readable; "
                             "is the disk full?)")
