"""Playhead timing, the editor's playback state (no Qt): which frame of a sequence to show for
the elapsed time of an injectable clock.

The playhead never counts ticks: the frame is ``floor((clock() - start) · fps)``, so when
rendering (or the timer) is late, frames are skipped and playback keeps the file's speed
instead of drifting. ``clock`` is any callable returning seconds (tests pass a fake one).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

Clock = Callable[[], float]


class Playhead:
    """Frame position of an ``n_frames`` sequence at ``fps``, playing or paused, looping or not."""

    def __init__(self, n_frames: int = 1, fps: float = 25.0,
                 clock: Clock = time.perf_counter) -> None:
        self.clock = clock
        self.loop = False
        self._n = 1
        self._fps = 25.0
        self._frame = 0
        self._start: float | None = None  # clock time of frame 0 while playing
        self.reset(n_frames, fps)

    def reset(self, n_frames: int, fps: float) -> None:
        """A new sequence: paused at frame 0."""
        if n_frames < 1 or not fps > 0:
            raise ValueError(f"need n_frames >= 1 and fps > 0, got {n_frames}, {fps}")
        self._n, self._fps, self._frame, self._start = int(n_frames), float(fps), 0, None

    @property
    def n_frames(self) -> int:
        return self._n

    @property
    def fps(self) -> float:
        return self._fps

    @property
    def playing(self) -> bool:
        return self._start is not None

    @property
    def time(self) -> float:
        """Time of the current frame, seconds."""
        return self._frame / self._fps

    def play(self) -> None:
        """Start (or resume) from the current frame; from 0 if at the end and not looping."""
        if self.playing:
            return
        if self._frame >= self._n - 1 and self._n > 1:
            self._frame = 0
        self._start = self.clock() - self._frame / self._fps

    def pause(self) -> None:
        if self.playing:
            self._frame = self.frame()
            self._start = None

    def seek(self, frame: int) -> int:
        """Go to ``frame`` (clamped); keeps playing from there if playing."""
        self._frame = max(0, min(self._n - 1, int(frame)))
        if self.playing:
            self._start = self.clock() - self._frame / self._fps
        return self._frame

    def frame(self) -> int:
        """The frame for now: elapsed time × fps, wrapped (loop) or stopped at the last frame."""
        if self._start is None:
            return self._frame
        k = math.floor((self.clock() - self._start) * self._fps + 1e-9)
        if k < 0:
            k = 0
        if k >= self._n:
            if self.loop:
                k %= self._n
                # re-base so the clock arithmetic stays small and seamless
                self._start += (self._n / self._fps) * ((self.clock() - self._start)
                                                        // (self._n / self._fps))
            else:
                k = self._n - 1
                self._start = None
        self._frame = k
        return k
