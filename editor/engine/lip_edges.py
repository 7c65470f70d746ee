"""The face mesh's inner-lip contour moved onto the photo's own inner lip edges (open mouths).

On an open mouth MediaPipe's inner-lip contour is too large: its lower curve lies on the lower
lip's body below the lip's inner edge (under the teeth's edge, or under the dark cavity's), and
its upper curve sometimes inside the upper lip. :func:`refine_inner_lips` searches, for each of
the 9 inner points of both curves (the two inner mouth corners stay), along the contour's
normal for the strongest luminance step (lip to dark cavity or to bright teeth) on a lightly
smoothed luminance (Gaussian, sigma 1.2 % of the inter-ocular distance, at least 0.8 px), with
a parabolic sub-sample peak. The search is one-sided on purpose: inwards (into the opening) it
reaches :data:`SEARCH_IOD` inter-ocular distances but never past :data:`GAP_FRACTION` of the
mesh's opening (the curves cannot cross), outwards only :data:`OUT_IOD` and at most
:data:`LIP_FRACTION` of the lip's thickness (a wider outward range picks up the lip's
highlights and outer edge). The found offsets, weighted by their step's strength, become one
smooth correction per curve, ``s (1 - s) (a + b (s - 1/2))`` along the contour (zero at the
corners: a bulge and a tilt), fitted by Huber-reweighted least squares, so the contour never
turns jagged and a stray edge does not bend it. A closed mouth (the mesh's own opening under
:data:`CLOSED_PX` pixels) or a curve with fewer than :data:`MIN_POINTS` steps of at least
:data:`MIN_STEP` grey levels per pixel (fewer on a large face, see there) is left alone.

Measured on JAFFE against its Stasm points (``scripts/landmark_accuracy.py``, % IOD): inner
lips 2.03 -> 1.70, closed mouths 1.48 -> 1.29, open mouths 3.31 -> 2.64 (dlib 2.01 / 1.76 /
2.58). Known misses: a dark upper lip over a dark cavity (a weak true edge) can be pulled
towards an edge inside the opening (JAFFE KA.SU3: the upper middle moves 3.9 px down,
about 5 px below the lip's edge).

Pure numpy/OpenCV, vectorised over points and samples (no per-point loop); about 0.3 ms a face.
"""

from __future__ import annotations

import numpy as np

# OpenCV is imported by the function that uses it (see editor.engine.landmarks)

#: Mesh indices of the inner and outer lip curves, mouth corner to mouth corner (image left to
#: right), point k of an inner curve facing point k of the outer one.
INNER_UPPER = np.array([78, 191, 80, 81, 82, 13, 312, 311, 310, 415, 308])
INNER_LOWER = np.array([78, 95, 88, 178, 87, 14, 317, 402, 318, 324, 308])
OUTER_UPPER = np.array([61, 185, 40, 39, 37, 0, 267, 269, 270, 409, 291])
OUTER_LOWER = np.array([61, 146, 91, 181, 84, 17, 314, 405, 321, 375, 291])

#: Mouths whose mesh opening (median over the middle points) is below this many pixels are
#: closed: nothing to search.
CLOSED_PX = 1.5
#: Search range either side of the mesh's point, in inter-ocular distances (inwards; never past
#: the opening's middle).
SEARCH_IOD = 0.08
#: Outwards the search reaches at most this many inter-ocular distances (the mesh's error is an
#: opening too large: its curves lie on the lips' bodies, rarely inside the opening)...
OUT_IOD = 0.015
#: ...and at most this fraction of the lip's thickness (inner to outer contour).
LIP_FRACTION = 0.4
#: Inwards the search reaches at most this fraction of the mesh's opening (the middle: the
#: curves never cross).
GAP_FRACTION = 0.5
#: A curve moves when at least this many of its 9 points find an edge of at least this many
#: grey levels per pixel (after the light smoothing) at the smoothing's floor of SIGMA_MIN px;
#: where the smoothing is wider (a large face: 1.2 % of its inter-ocular distance) the step
#: asked for is as much lower, as the same edge spreads over as many more pixels (the search
#: is laid out in inter-ocular distances; its threshold was per pixel: the 4K bench face, IOD
#: 468 px, sigma 5.6 px, found no step of 4 grey levels per pixel, kept MediaPipe's contour and
#: its opening 0.17 IOD tall against 0.11 at 512 and 1080 px, its upper lip 0.064 IOD thick
#: against 0.10; faces up to 67 px between the eyes, JAFFE's, unchanged)
MIN_POINTS = 4
MIN_STEP = 4.0
SIGMA_MIN = 0.8


def _eye_distance(mesh: np.ndarray) -> float:
    return float(np.linalg.norm((mesh[263] + mesh[362]) / 2 - (mesh[33] + mesh[133]) / 2))


def _smooth_offsets(s: np.ndarray, d: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Smooth offset curves through the offsets ``d`` (c, n) with weights ``w`` (c, n) at
    contour positions ``s`` (c, n) in (0, 1), one per row: ``s (1 - s) (a + b (s - 1/2))``
    (zero at both corners: a bulge and a tilt), fitted by weighted least squares with three
    Huber re-weightings at 1.5 times the mean residual, at least a pixel (a stray edge does
    not bend the curve). Rows with fewer than :data:`MIN_POINTS` weighted points get zeros."""
    basis = (s * (1 - s))[..., None] * np.stack([np.ones_like(s), s - 0.5], -1)  # (c, n, 2)
    wt = w.copy()
    coef = np.zeros(s.shape[:1] + (2,))
    for _ in range(4):
        a = basis * wt[..., None]
        lhs = np.einsum("cnk,cnl->ckl", a, basis) + 1e-9 * np.eye(2)
        coef = np.linalg.solve(lhs, np.einsum("cnk,cn->ck", a, d)[..., None])[..., 0]
        r = np.abs(np.einsum("cnk,ck->cn", basis, coef) - d)
        used = w > 0
        mean_r = (r * used).sum(1, keepdims=True) / np.maximum(used.sum(1, keepdims=True), 1)
        scale = np.maximum(1.0, 1.5 * mean_r)
        wt = w * np.minimum(1.0, scale / np.maximum(r, 1e-9))
    fit = np.einsum("cnk,ck->cn", basis, coef)
    return np.where(((w > 0).sum(1) >= MIN_POINTS)[:, None], fit, 0.0)


def refine_inner_lips(rgb: np.ndarray, mesh: np.ndarray) -> np.ndarray:
    """``mesh`` (468, 2) with its inner-lip points on the photo's inner lip edges (a copy of the
    same dtype; unchanged when the mouth is closed or shows no clear edge). See the module
    docstring."""
    import cv2

    m = np.asarray(mesh, np.float64).reshape(468, 2)
    out = np.array(mesh, copy=True)
    iod = _eye_distance(m)
    ex = m[263] - m[33]
    ex /= np.linalg.norm(ex)
    ey = np.array([-ex[1], ex[0]])  # the face's "down" in the image
    inner = np.stack([m[INNER_UPPER], m[INNER_LOWER]])  # (2, 11, 2)
    outer = np.stack([m[OUTER_UPPER], m[OUTER_LOWER]])
    gap = (inner[1, 1:-1] - inner[0, 1:-1]) @ ey
    if not np.isfinite(iod) or float(np.median(gap[2:7])) < CLOSED_PX:
        return out
    r = SEARCH_IOD * iod
    step = max(0.25, r / 48)
    ts = np.arange(-r, r + step / 2, step)  # negative: outwards into the lip
    # the luminance of the lips' box only, lightly smoothed
    h, w = rgb.shape[:2]
    lips = outer.reshape(-1, 2)
    x0, y0 = np.clip(np.floor(lips.min(0) - r - 4).astype(int), 0, (w - 1, h - 1))
    x1, y1 = np.clip(np.ceil(lips.max(0) + r + 4).astype(int) + 1, 1, (w, h))
    box = np.ascontiguousarray(rgb[y0:y1, x0:x1, :3])
    sigma = max(SIGMA_MIN, 0.012 * iod)
    lum = cv2.GaussianBlur(cv2.cvtColor(box, cv2.COLOR_RGB2GRAY).astype(np.float32), (0, 0),
                           sigma)
    # normals of points 1..9 of both curves, pointing into the opening
    tang = inner[:, 2:] - inner[:, :-2]
    nrm = np.stack([-tang[..., 1], tang[..., 0]], -1)
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    nrm *= (np.sign(nrm @ ey) * np.array([[1.0], [-1.0]]))[..., None]
    p = inner[:, 1:-1]  # (2, 9, 2)
    q = (p[..., None, :] + ts[:, None] * nrm[..., None, :]).reshape(18, len(ts), 2)
    prof = cv2.remap(lum, (q[..., 0] - x0).astype(np.float32), (q[..., 1] - y0).astype(np.float32),
                     cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    grad = np.abs(np.gradient(prof, step, axis=1))
    # outwards a short way into the lip, inwards at most to the opening's middle
    thick = np.abs(((outer - inner)[:, 1:-1] * nrm).sum(-1)).reshape(18)
    lo_lim = -np.minimum(OUT_IOD * iod, LIP_FRACTION * thick)
    hi_lim = np.minimum(r, np.maximum(np.tile(gap, 2) * GAP_FRACTION - 0.5, 0.0))
    inside = (ts >= lo_lim[:, None]) & (ts <= hi_lim[:, None])
    g = np.where(inside, grad, 0.0)
    k = np.clip(g.argmax(1), 1, len(ts) - 2)  # the strongest step
    rows = np.arange(18)
    a, b, c = g[rows, k - 1], g[rows, k], g[rows, k + 1]
    den = a - 2 * b + c
    sub = np.where(den < 0, 0.5 * (a - c) / np.where(den < 0, den, -1.0), 0.0)
    d = (ts[k] + np.clip(sub, -0.5, 0.5) * step).reshape(2, 9)
    weight = np.where(b >= MIN_STEP * (SIGMA_MIN / sigma), b, 0.0).reshape(2, 9)
    seg = np.linalg.norm(np.diff(inner, axis=1), axis=-1)  # (2, 10)
    s = np.cumsum(seg, 1)[:, :-1] / seg.sum(1, keepdims=True)
    off = np.clip(_smooth_offsets(s, d, weight), -r, r)
    new = p + off[..., None] * nrm
    # the curves never cross: where they would, both go to their middle
    cross = (new[1] - new[0]) @ ey < 0
    mid = new.mean(0)
    new[:, cross] = mid[cross]
    out[INNER_UPPER[1:-1]] = new[0].astype(out.dtype)
    out[INNER_LOWER[1:-1]] = new[1].astype(out.dtype)
    return out
