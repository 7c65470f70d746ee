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

import numpy as np

#: longest chord of the sampled curve, pixels: a circular arc of radius R sampled with chords
#: of length c departs from them by c^2 / (8 R): a quarter of a pixel for the lips' arcs
#: (R of ~20 px and more wherever sides are longer than this); loops with shorter sides (the
#: paper's 431 x 591 face, IOD 37 px: sides of 2-5 px) stay polygons, as before
CHORD_PX = 6.0

#: most samples per side (a 4K face's widest mouth: sides of ~60 px)
MAX_SPLIT = 24


def smooth_loop(poly: np.ndarray, corners: tuple[int, int], chord_px: float = CHORD_PX
                ) -> np.ndarray:
    """The closed loop ``poly`` (n, 2) with each of its two arcs (``corners[0]`` ..
    ``corners[1]`` and back) replaced by a centripetal Catmull-Rom curve through the same
    vertices, in the same order and dtype, sampled at most ``chord_px`` apart; the corners
    stay sharp (two arcs meet there). ``poly`` itself when every side is shorter than that."""
    p = np.asarray(poly)
    n = len(p)
    d = np.diff(p, axis=0, append=p[:1]).astype(np.float64)
    longest = math.sqrt(float((d * d).sum(1).max()))
    split = min(MAX_SPLIT, math.ceil(longest / chord_px))
    if split <= 1:
        return poly
    a, b = corners
    arcs = [np.arange(a, b + 1), np.r_[np.arange(b, n), np.arange(0, a + 1)]]
    pieces = [_catmull_rom(p[idx].astype(np.float64), split)[:-1] for idx in arcs]
    return np.concatenate(pieces).astype(p.dtype)


def _catmull_rom(pts: np.ndarray, split: int) -> np.ndarray:
    """Centripetal Catmull-Rom through ``pts`` (m, 2), ``split`` samples per side, both ends
    included ((m - 1) * split + 1, 2); at each end a phantom point continues the parabola
    through the last three points (the arc leaves the corner bent as it is next to it, not
    along its first chord)."""
    if len(pts) < 3:
        ext = np.concatenate([2.0 * pts[:1] - pts[1:2], pts, 2.0 * pts[-1:] - pts[-2:-1]])
    else:
        ext = np.concatenate([3.0 * (pts[:1] - pts[1:2]) + pts[2:3], pts,
                              3.0 * (pts[-1:] - pts[-2:-1]) + pts[-3:-2]])
    p0, p1, p2, p3 = ext[:-3], ext[1:-2], ext[2:-1], ext[3:]
    # knot spacing sqrt(chord), never zero (coincident points: closed lips' twin vertices)
    def gap(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.maximum(np.sqrt(np.hypot(*(v - u).T)), 1e-6)[:, None, None]

    t1 = gap(p0, p1)
    t2 = t1 + gap(p1, p2)
    t3 = t2 + gap(p2, p3)
    s = np.linspace(0.0, 1.0, split, endpoint=False)[None, :, None]
    t = t1 + s * (t2 - t1)  # (sides, split, 1)
    P0, P1, P2, P3 = (q[:, None, :] for q in (p0, p1, p2, p3))
    a1 = ((t1 - t) * P0 + t * P1) / t1
    a2 = ((t2 - t) * P1 + (t - t1) * P2) / (t2 - t1)
    a3 = ((t3 - t) * P2 + (t - t2) * P3) / (t3 - t2)
    b1 = ((t2 - t) * a1 + t * a2) / t2
    b2 = ((t3 - t) * a2 + (t - t1) * a3) / (t3 - t1)
    c = ((t2 - t) * b1 + (t - t1) * b2) / (t2 - t1)
    return np.concatenate([c.reshape(-1, 2), pts[-1:]])
