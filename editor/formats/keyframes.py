"""Authoring FAP sequences: keyframes sampled into a :class:`FapSequence`."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from editor.engine.faps import check_vector, partner_mask, round_half_away

from .fapfile import MAX_FPS, MAX_FRAMES, FapSequence


def sequence_from_keyframes(keys: Sequence[tuple[float, np.ndarray]], fps: float = 25.0,
                            interpolation: str = "linear", name: str = "keyframes"
                            ) -> FapSequence:
    """A sequence from ``(time_s, (68,) vector)`` keys (e.g. neutral -> joy -> neutral), sampled
    at t = k/fps up to the last key, ``"linear"`` or ``"smoothstep"`` (u²(3 - 2u)) in between,
    first key held before it; integer values; mask = FAPs non-zero in any key + L/R partners."""
    if interpolation not in ("linear", "smoothstep"):
        raise ValueError(f"interpolation must be 'linear' or 'smoothstep', got {interpolation!r}")
    if not keys or not 0 < float(fps) <= MAX_FPS:
        raise ValueError(f"need at least one keyframe and 0 < fps <= {MAX_FPS:g}")
    pairs = sorted(((float(t), check_vector(v)) for t, v in keys), key=lambda p: p[0])
    times, vals = np.array([t for t, _ in pairs]), np.stack([v for _, v in pairs])
    if not np.isfinite(times).all() or times[0] < 0 or np.any(np.diff(times) <= 0):
        raise ValueError("keyframe times must be finite, >= 0 and distinct")
    n = int(round(times[-1] * fps)) + 1
    if n > MAX_FRAMES:
        raise ValueError(f"{n} frames is more than {MAX_FRAMES}")
    t = np.minimum(np.arange(n) / fps, times[-1])
    j = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 1)
    j1 = np.minimum(j + 1, len(times) - 1)
    u = np.clip((t - times[j]) / np.where(j1 > j, times[j1] - times[j], 1.0), 0.0, 1.0)
    if interpolation == "smoothstep":
        u = u * u * (3 - 2 * u)
    out = round_half_away(vals[j] + (vals[j1] - vals[j]) * u[:, None])
    m = partner_mask((vals != 0).any(axis=0))
    return FapSequence(out, np.repeat(m[None], n, 0), fps=fps, name=name)
