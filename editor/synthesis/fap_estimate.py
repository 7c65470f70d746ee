"""FAPs measured from a performer's video (issue 10; SPEC §6, source side).

The model (the performer's neutral face, landmark motion linear in the FAPs, the bounded
least-squares solve) is :mod:`editor.engine.fap_model`; its names are re-exported here.

Video (:func:`track_video`): every frame against the first frame with a face (the neutral);
frames without a face are filled by linear interpolation (held at the ends) and reported; then
:func:`smooth`; a :class:`FapSequence` at the video's frame rate.
"""
from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy.signal import savgol_filter

from editor.engine.face import Face
from editor.engine.fap_model import (
    ESTIMATE_STABLE,
    ESTIMATE_STABLE_WEIGHTS,
    LANDMARK_WEIGHTS,
    OBSERVABLE,
    STABLE_POINTS,
    STABLE_WEIGHTS,
    Estimate,
    FapEstimator,
    estimate_faps,
    remove_head_motion,
)
from editor.engine.faps import FAPS
from editor.engine.landmarks import LandmarkTracker
from editor.errors import FapStudioError, NoFaceError
from editor.formats.fapfile import FapSequence

__all__ = [
    "OBSERVABLE", "STABLE_POINTS", "STABLE_WEIGHTS", "ESTIMATE_STABLE", "ESTIMATE_STABLE_WEIGHTS",
    "LANDMARK_WEIGHTS", "remove_head_motion", "Estimate",
    "FapEstimator", "estimate_faps", "smooth", "fill_missing", "TrackReport", "track_video",
]


# ---------------------------------------------------------------------------- video
def smooth(frames: np.ndarray, spec: str | None = "savgol:5") -> np.ndarray:
    """Temporal smoothing of (N, 68) FAP tracks; ``spec`` is one of

    * ``none`` - raw per-frame estimates;
    * ``savgol:W[:P]`` - Savitzky-Golay, odd window W frames, polynomial order P (default 2):
      zero lag, keeps peaks (a smile's maximum) better than a moving average;
    * ``ema:A`` - exponential smoothing with factor A in (0, 1] run forwards then backwards
      (zero lag; smaller A = smoother).
    """
    x = np.asarray(frames, np.float64)
    s = (spec or "none").strip().lower()
    kind, _, rest = s.partition(":")
    args = [a for a in rest.split(":") if a] if rest else []
    try:
        if kind == "none":
            return x.copy()
        if kind == "savgol":
            w = int(args[0]) if args else 5
            p = int(args[1]) if len(args) > 1 else 2
            if w < 3 or w % 2 == 0 or not 0 <= p < w:
                raise ValueError
            if len(x) < w:
                w = len(x) if len(x) % 2 else len(x) - 1
                if w <= p:
                    return x.copy()
            return savgol_filter(x, w, p, axis=0, mode="interp")
        if kind == "ema":
            a = float(args[0]) if args else 0.5
            if not 0.0 < a <= 1.0:
                raise ValueError
            y = x.copy()
            for i in range(1, len(y)):
                y[i] = a * y[i] + (1 - a) * y[i - 1]
            for i in range(len(y) - 2, -1, -1):
                y[i] = a * y[i] + (1 - a) * y[i + 1]
            return y
    except (ValueError, IndexError):
        pass
    raise FapStudioError(f"smoothing {spec!r}: expected none, savgol:W[:P] (odd W >= 3, P < W) "
                         f"or ema:A (0 < A <= 1)")


def fill_missing(frames: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Linear interpolation of the rows where ``valid`` is False (held at the ends)."""
    x = np.asarray(frames, np.float64).copy()
    t = np.arange(len(x))
    ok = np.flatnonzero(valid)
    if len(ok) == 0:
        raise NoFaceError("no face found in any frame")
    for j in range(x.shape[1]):
        x[:, j] = np.interp(t, ok, x[ok, j])
    return x


@dataclass
class TrackReport:
    """What :func:`track_video` did."""

    frames: int
    fps: float
    neutral_frame: int
    missing: list[int] = field(default_factory=list)  # frames without a face (interpolated)
    residual_px: np.ndarray | None = None  # (N,) model fit RMS per frame, NaN where missing
    head_angle_deg: np.ndarray | None = None  # (N,) in-plane head roll removed
    smoothing: str = "savgol:5"
    seconds: float = 0.0
    cancelled: bool = False

    def summary(self) -> str:
        miss = (f"{len(self.missing)} without a face (interpolated: "
                f"{_ranges(self.missing)})" if self.missing else "a face in every frame")
        res = self.residual_px
        fit = (f"; fit residual median {np.nanmedian(res):.2f} px" if res is not None
               and np.isfinite(res).any() else "")
        return (f"{self.frames} frames at {self.fps:g} fps, neutral = frame {self.neutral_frame}, "
                f"{miss}{fit}; smoothing {self.smoothing}; {self.seconds:.1f} s")


def _ranges(idx: list[int]) -> str:
    out, start = [], None
    for k, i in enumerate(idx):
        if start is None:
            start = i
        if k + 1 == len(idx) or idx[k + 1] != i + 1:
            out.append(str(start) if start == i else f"{start}-{i}")
            start = None
    return ", ".join(out)


def track_video(path: str | os.PathLike[str], fps: float | None = None,
                smoothing: str | None = "savgol:5", *, faps=OBSERVABLE,
                progress: Callable[[int, int], bool | None] | None = None,
                detector=None, **estimator_kw) -> tuple[FapSequence, TrackReport]:
    """FAP sequence of a performer video, each frame against the first frame with a face.

    ``fps`` overrides the container's frame rate (used when it reports none: 25).
    ``progress(done, total)`` after each frame (total may be an estimate); ``False`` cancels
    (the frames read so far are returned, ``report.cancelled`` set).
    """
    t0 = time.perf_counter()
    tracker = LandmarkTracker(detector)
    cap = cv2.VideoCapture(str(path))
    if not os.path.exists(str(path)) or not cap.isOpened():
        raise FapStudioError(f"{path}: cannot open the video")
    rate = float(fps) if fps else float(cap.get(cv2.CAP_PROP_FPS) or 0.0)
    if not np.isfinite(rate) or rate <= 0:
        rate = 25.0
    total = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
    spec = smoothing or "none"
    smooth(np.zeros((1, 68)), spec)  # validate before the long part
    est: FapEstimator | None = None
    rows: list[np.ndarray | None] = []
    resid, angle = [], []
    neutral_idx = -1
    cancelled = False
    try:
        while True:
            ok, bgr = cap.read()
            if not ok:
                break
            rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
            i = len(rows)
            try:
                lm = tracker(rgb)
            except NoFaceError:
                lm = None
            if lm is not None and est is None:
                try:
                    est = FapEstimator(Face.from_landmarks(rgb, lm), faps, **estimator_kw)
                    neutral_idx = i
                except NoFaceError:
                    lm = None
            if lm is None or est is None:  # est is set once a face is found
                rows.append(None)
                resid.append(np.nan)
                angle.append(np.nan)
            else:
                e = est.estimate(lm.points)
                rows.append(e.faps)
                resid.append(e.residual_px)
                angle.append(-e.head_angle_deg)
            if progress is not None and progress(len(rows), max(total, len(rows))) is False:
                cancelled = True
                break
    finally:
        cap.release()
    if not rows:
        raise FapStudioError(f"{path}: no frames could be read")
    if est is None:
        raise NoFaceError(f"{path}: no face found in any of the {len(rows)} frames")
    valid = np.array([r is not None for r in rows])
    raw = np.array([r if r is not None else np.zeros(68, np.float32) for r in rows])
    filled = fill_missing(raw, valid)
    sm = smooth(filled, spec)
    sm = np.clip(sm, FAPS.lo, FAPS.hi)
    sm[:, :2] = 0.0
    mask = np.zeros((len(sm), 68), bool)
    mask[:, est.idx] = True
    seq = FapSequence(np.round(sm).astype(np.float32), mask, fps=rate,
                      name=os.path.splitext(os.path.basename(str(path)))[0].replace(" ", "_")
                      or "track")
    rep = TrackReport(len(rows), rate, neutral_idx, [int(i) for i in np.flatnonzero(~valid)],
                      np.array(resid), np.array(angle), spec, time.perf_counter() - t0, cancelled)
    return seq, rep

