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
    return similarity_to(source_fit(src, w), dst)


def source_fit(src: np.ndarray, w: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """What :func:`similarity` computes of ``src`` and ``w`` alone: the normalised weights,
    the weighted mean, the points about it and their weighted spread (for points fitted
    again and again: :func:`similarity_to`)."""
    s = np.asarray(src, np.float64)
    w = np.ones(len(s)) if w is None else np.asarray(w, np.float64)
    w = w / w.sum()
    ms = w @ s
    a = s - ms
    return w, ms, a, float(w @ (a * a).sum(1)) or 1.0


def similarity_to(fit: tuple[np.ndarray, np.ndarray, np.ndarray, float], dst: np.ndarray
                  ) -> np.ndarray:
    """:func:`similarity` from :func:`source_fit` of its ``src`` (and weights) to ``dst``."""
    w, ms, a, den = fit
    d = np.asarray(dst, np.float64)
    md = w @ d
    b = d - md
    c = float(w @ (a * b).sum(1)) / den
    sn = float(w @ (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])) / den
    R = np.array([[c, -sn], [sn, c]])
    return np.hstack([R, (md - R @ ms)[:, None]])


def similarity_pairs(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """:func:`similarity` of several two-point correspondences at once, its values.

    Parameters
    ----------
    src, dst : array_like
        (K, 2, 2) float64: K pairs of points and where they go.

    Returns
    -------
    numpy.ndarray
        (K, 2, 3) float64, ``similarity(src[k], dst[k])`` for each k (the same values: the
        means, spreads and covariances of two points are halves of sums of two exact
        products, one rounding each, whichever way they are added, so they are worked out in
        Python floats; the rotation applied to the mean is the same matrix product, one
        batched call for the K matrices).

    Examples
    --------
    >>> src = np.array([[[0.0, 0.0], [1.0, 0.0]], [[1.0, 1.0], [1.0, 3.0]]])
    >>> M = similarity_pairs(src, 2 * src + [3, 4])
    >>> bool(np.array_equal(M[1], similarity(src[1], 2 * src[1] + [3, 4])))
    True
    """
    rot, mean, md = [], [], []
    for ((s0x, s0y), (s1x, s1y)), ((d0x, d0y), (d1x, d1y)) in zip(
            np.asarray(src, np.float64).tolist(), np.asarray(dst, np.float64).tolist(),
            strict=True):
        msx, msy = 0.5 * s0x + 0.5 * s1x, 0.5 * s0y + 0.5 * s1y
        mdx, mdy = 0.5 * d0x + 0.5 * d1x, 0.5 * d0y + 0.5 * d1y
        a0x, a0y, a1x, a1y = s0x - msx, s0y - msy, s1x - msx, s1y - msy
        b0x, b0y, b1x, b1y = d0x - mdx, d0y - mdy, d1x - mdx, d1y - mdy
        den = 0.5 * (a0x * a0x + a0y * a0y) + 0.5 * (a1x * a1x + a1y * a1y) or 1.0
        c = (0.5 * (a0x * b0x + a0y * b0y) + 0.5 * (a1x * b1x + a1y * b1y)) / den
        sn = (0.5 * (a0x * b0y - a0y * b0x) + 0.5 * (a1x * b1y - a1y * b1x)) / den
        rot.append([[c, -sn], [sn, c]])
        mean.append([[msx], [msy]])
        md.append([mdx, mdy])
    R = np.array(rot)
    out = np.empty((len(rot), 2, 3))
    out[:, :, :2] = R
    np.subtract(md, np.matmul(R, mean)[:, :, 0], out=out[:, :, 2])
    return out


def apply_affine(M: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """The (N, 2) points ``pts`` mapped by the 2x3 matrix ``M`` (float64).

    Examples
    --------
    >>> apply_affine(np.array([[2.0, 0, 3], [0, 2, 4]]), [[1.0, 1.0]]).tolist()
    [[5.0, 6.0]]
    """
    return np.asarray(pts, np.float64) @ M[:, :2].T + M[:, 2]
