"""2-D similarity fits: the one least-squares similarity (rotation, uniform scale, translation)
used wherever points are aligned (head motion, the neutral prior, the layers behind openings).
"""

from __future__ import annotations

import numpy as np


def similarity(src: np.ndarray, dst: np.ndarray, w: np.ndarray | None = None) -> np.ndarray:
    """Weighted least-squares similarity with ``dst ~ M[:, :2] @ src + M[:, 2]``.

    Parameters
    ----------
    src, dst : array_like
        (N, 2) corresponding points, N >= 2.
    w : array_like, optional
        (N,) non-negative weights (uniform when None).

    Returns
    -------
    numpy.ndarray
        (2, 3) float64 matrix ``[[s cos a, -s sin a, tx], [s sin a, s cos a, ty]]``; the
        identity rotation and scale when ``src`` is a single point repeated.

    Examples
    --------
    >>> src = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    >>> M = similarity(src, 2 * src + [3, 4])
    >>> np.round(M, 12).tolist()
    [[2.0, -0.0, 3.0], [0.0, 2.0, 4.0]]
    """
    s, d = np.asarray(src, np.float64), np.asarray(dst, np.float64)
    w = np.ones(len(s)) if w is None else np.asarray(w, np.float64)
    w = w / w.sum()
    ms, md = w @ s, w @ d
    a, b = s - ms, d - md
    den = float(w @ (a * a).sum(1)) or 1.0
    c = float(w @ (a * b).sum(1)) / den
    sn = float(w @ (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])) / den
    R = np.array([[c, -sn], [sn, c]])
    return np.hstack([R, (md - R @ ms)[:, None]])


def apply_affine(M: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """The (N, 2) points ``pts`` mapped by the 2x3 matrix ``M`` (float64).

    Examples
    --------
    >>> apply_affine(np.array([[2.0, 0, 3], [0, 2, 4]]), [[1.0, 1.0]]).tolist()
    [[5.0, 6.0]]
    """
    return np.asarray(pts, np.float64) @ M[:, :2].T + M[:, 2]
