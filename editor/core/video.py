"""Rendering a FAP sequence to a video file or a folder of PNG frames (no Qt).

``export_sequence(face, seq, out, progress=cb)`` renders every frame of a
:class:`~editor.core.fapfile.FapSequence` (FAP 1/2 fields expanded into low-level FAPs, values
clamped to the FAP table's ranges) and writes a video through PyAV (FFmpeg's libraries in
process) when ``out`` ends in ``.mp4``/``.mov`` (H.264, yuv420p, ``+faststart`` so that the index
comes first and browsers and players start at once) or ``.avi`` (Motion JPEG), otherwise PNG
files ``frame_00000.png`` ... into the folder ``out``. yuv420p needs even sizes: an odd width or
height is padded by one replicated pixel column/row. ``progress(done, total)`` is called after
each frame; returning ``False`` cancels (a video file is then removed, PNG frames already written
are kept and counted in the result).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import cv2
import numpy as np

from .errors import FapStudioError
from .faps import FAPS
from .imageio import save_image

#: suffix -> (FFmpeg encoder, pixel format, container options)
VIDEO_SUFFIXES: dict[str, tuple[str, str, dict[str, str]]] = {
    ".mp4": ("libx264", "yuv420p", {"movflags": "+faststart"}),
    ".mov": ("libx264", "yuv420p", {"movflags": "+faststart"}),
    ".avi": ("mjpeg", "yuvj420p", {}),
}
#: x264 settings: constant quality (CRF 18, visually lossless), the usual speed/size trade-off
X264_OPTIONS = {"crf": "18", "preset": "medium"}


class VideoWriter:
    """Frames (RGB uint8, all of one size) into a video file through PyAV; a context manager.

    Odd sizes are padded to even ones (yuv420p halves the chroma resolution)."""

    def __init__(self, path: Path, size: tuple[int, int], fps: float) -> None:
        try:
            import av
        except ImportError as e:  # pragma: no cover - a dependency of the package
            raise FapStudioError(f"video export needs PyAV (pip install av): {e}") from e
        encoder, self.pix_fmt, options = VIDEO_SUFFIXES[path.suffix.lower()]
        w, h = size
        self.pad = (w % 2, h % 2)
        self.path = path
        try:
            self.container = av.open(str(path), "w", options=options)
        except (OSError, av.FFmpegError) as e:
            raise FapStudioError(f"{path}: cannot write the video ({e})") from e
        rate = Fraction(fps).limit_denominator(1001)
        self.stream = self.container.add_stream(
            encoder, rate=rate, options=X264_OPTIONS if encoder == "libx264" else {})
        self.stream.width, self.stream.height = w + self.pad[0], h + self.pad[1]
        self.stream.pix_fmt = self.pix_fmt
        self._av = av

    def write(self, rgb: np.ndarray) -> None:
        if any(self.pad):
            rgb = cv2.copyMakeBorder(rgb, 0, self.pad[1], 0, self.pad[0], cv2.BORDER_REPLICATE)
        frame = self._av.VideoFrame.from_ndarray(np.ascontiguousarray(rgb), format="rgb24")
        for packet in self.stream.encode(frame):
            self.container.mux(packet)

    def close(self) -> None:
        try:
            for packet in self.stream.encode():  # flush the encoder's delayed frames
                self.container.mux(packet)
        finally:
            self.container.close()

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


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
    h, w = face.image.shape[:2]
    writer = None
    if p.suffix.lower() in VIDEO_SUFFIXES:
        try:
            p.parent.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise FapStudioError(f"{p.parent}: cannot create the folder ({e.strerror or e})"
                                 ) from e
        fps = float(seq.fps) if seq.fps and seq.fps > 0 else 25.0
        writer = VideoWriter(p, (w, h), fps)
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
                writer.write(img)
            else:
                save_image(p / f"frame_{i:05d}.png", img)
            done += 1
            if progress is not None and progress(done, n) is False:
                cancelled = done < n
                break
    finally:
        if writer is not None:
            writer.close()
    if cancelled and writer is not None:
        p.unlink(missing_ok=True)
    return ExportResult(p, done, cancelled)
