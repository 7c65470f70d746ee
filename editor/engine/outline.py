"""Smooth outlines for the mesh's openings.

The mesh gives the mouth's opening as a loop of 16 vertices (the inner-lip contour: a corner,
seven points on the upper lip, the other corner, seven on the lower lip). Filled as a polygon,
its straight sides show once a face is large: a wide-open mouth on a 4K photo (a face 1000 px
wide) is a hexagon with chamfered corners, where real lips draw two smooth arcs that meet at
the corners of the mouth. :func:`smooth_loop` replaces each arc between two corners by a
centripetal Catmull-Rom curve through the same vertices (no overshoot or self-crossing between
unevenly spaced points; Yuksel, Schaefer and Keyser 2011), sampled so that no chord is longer
than :data:`CHORD_PX`. Loops whose sides are all shorter than that (small faces: the paper's
431 x 591 frame) come back unchanged, so the curve only appears where a
straight side could be seen.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

#: longest chord of the sampled curve, pixels: a circular arc of radius R sampled with chords
#: of length c departs from them by c^2 / (8 R): a quarter of a pixel for the lips' arcs
#: (R of ~20 px and more wherever sides are longer than this); loops with shorter sides (the
#: paper's 431 x 591 face, IOD 37 px: sides of 2-5 px) stay polygons, as before
CHORD_PX = 6.0

#: most samples per side (a 4K face's widest mouth: sides of ~60 px)
MAX_SPLIT = 24


def splits(loops: np.ndarray, nxt: np.ndarray, cuts: np.ndarray,
           chord_px: list[float]) -> list[int]:
    """Samples per side for each of several closed loops stored one after another in
    ``loops`` (N, 2), loop k starting at ``cuts[k]``, ``nxt`` each point's successor in its
    loop: the fewest that keep every chord under ``chord_px[k]`` (1: the loop's own sides
    already are), at most :data:`MAX_SPLIT`. One pass over all the loops (the layers ask it
    for the eyes and the mouth every frame)."""
    d = loops.take(nxt, 0) - loops
    longest = np.maximum.reduceat(np.einsum("ij,ij->i", d, d), cuts).tolist()
    return [min(MAX_SPLIT, max(1, math.ceil(math.sqrt(q) / c)))
            for q, c in zip(longest, chord_px, strict=True)]


def smooth_loop(poly: np.ndarray, corners: tuple[int, int], split: int) -> np.ndarray:
    """The closed loop ``poly`` (n, 2) with each of its two arcs (``corners[0]`` ..
    ``corners[1]`` and back, as many points each) replaced by a centripetal Catmull-Rom curve
    through the same vertices, ``split`` samples per side (see :func:`splits`), in the same
    order and dtype; the corners stay sharp (two arcs meet there). ``poly`` itself when
    ``split`` is 1.

    At each arc's ends a phantom point continues the parabola through its last three points,
    so the arc leaves a corner bent as it is next to it, not along its first chord. Each side
    is the curve's cubic in Hermite form: the centripetal tangents at its ends (Yuksel,
    Schaefer and Keyser's non-uniform Catmull-Rom, the same curve as the pyramid of
    interpolations) against a basis tabulated once per ``split``."""
    if split <= 1:
        return poly
    idx = _arcs(len(poly), corners)
    P = np.asarray(poly, np.float64).take(idx, 0)  # (2, m, 2)
    E = np.concatenate([3.0 * (P[:, :1] - P[:, 1:2]) + P[:, 2:3], P,
                        3.0 * (P[:, -1:] - P[:, -2:-1]) + P[:, -3:-2]], 1)
    step = np.diff(E, axis=1)
    # knot intervals sqrt(chord), never zero (closed lips' twin vertices)
    dt = np.maximum(np.sqrt(np.sqrt(np.einsum("abi,abi->ab", step, step))), 1e-6)[..., None]
    # the tangent at each vertex (per unit of knot), then at each side's two ends per unit of
    # the side's own parameter
    q = step / dt
    tan = q[:, :-1] - (step[:, :-1] + step[:, 1:]) / (dt[:, :-1] + dt[:, 1:]) + q[:, 1:]
    d1 = dt[:, 1:-1]
    G = np.stack([E[:, 1:-2], tan[:, :-1] * d1, E[:, 2:-1], tan[:, 1:] * d1], 2)
    out = np.matmul(_hermite(split), G)  # (2, sides, split, 2)
    return out.reshape(-1, 2).astype(poly.dtype)


@lru_cache(maxsize=64)
def _arcs(n: int, corners: tuple[int, int]) -> np.ndarray:
    """(2, m) indices of a loop of ``n`` points: corner a .. corner b, then b .. back to a."""
    a, b = corners
    up = np.arange(a, b + 1)
    low = np.r_[np.arange(b, n), np.arange(0, a + 1)]
    if len(up) != len(low) or len(up) < 3:
        raise ValueError(f"a loop of {n} points with corners {corners}: arcs of unequal length")
    out = np.stack([up, low])
    out.flags.writeable = False
    return out


@lru_cache(maxsize=MAX_SPLIT + 1)
def _hermite(split: int) -> np.ndarray:
    """(split, 4) the cubic Hermite basis (h00, h10, h01, h11) at s = k / split, k < split."""
    s = np.arange(split, dtype=np.float64) / split
    s2, s3 = s * s, s * s * s
    h = np.stack([2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, 3 * s2 - 2 * s3, s3 - s2], 1)
    h.flags.writeable = False
    return h
