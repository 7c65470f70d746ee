"""Rendering a FAP sequence to a video file or a folder of PNG frames (no Qt).

``export_sequence(face, seq, out, progress=cb)`` renders every frame of a
:class:`~editor.core.fapfile.FapSequence` (FAP 1/2 fields expanded into low-level FAPs, values
clamped to the FAP table's ranges) and writes an MP4 (OpenCV ``VideoWriter``, codec mp4v) when
``out`` ends in ``.mp4``/``.avi``, otherwise PNG files ``frame_00000.png`` ... into the folder
``out``. ``progress(done, total)`` is called after each frame; returning ``False`` cancels
(an MP4 is then removed, PNG frames already written are kept and counted in the result).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from .errors import FapStudioError
from .faps import FAPS
from .imageio import save_image

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
    h, w = face.image.shape[:2]
    writer = None
    if codec:
        p.parent.mkdir(parents=True, exist_ok=True)
        fps = float(seq.fps) if seq.fps and seq.fps > 0 else 25.0
        writer = cv2.VideoWriter(str(p), cv2.VideoWriter_fourcc(*codec), fps, (w, h))
        if not writer.isOpened():
            raise FapStudioError(f"{p}: cannot open a video writer ({codec})")
    else:
        try:
            p.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise FapStudioError(f"{p}: cannot create the folder ({e.strerror or e})") from e
    done = 0
    cancelled = False
    try:
        for i, vec in enumerate(vecs):
            img = face.render(vec, creases=creases)
            if writer is not None:
                writer.write(cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
            else:
                save_image(p / f"frame_{i:05d}.png", img)
            done += 1
            if progress is not None and progress(done, n) is False:
                cancelled = done < n
                break
    finally:
        if writer is not None:
            writer.release()
    if cancelled and writer is not None:
        p.unlink(missing_ok=True)
    return ExportResult(p, done, cancelled)
