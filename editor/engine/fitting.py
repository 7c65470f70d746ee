"""Placing every vertex of the standard mesh on a face (SPEC §1.3).

All rules work in the *face frame*: origin midway between the eye centres, x along the line
from the image-left eye to the image-right eye, y perpendicular to it and pointing down, pixel
units. A tilted photo is thus fitted as if upright, and the parabolas are fitted in that frame.

Rules, region by region (names are the vertex names of ``editor/data/mesh.json``):

* eyes: upper and lower lids are parabolas through both corners, least-squares through the two
  middle lid landmarks (SPEC parabolas 5-8); 5 points per lid at x = k/6 of the corner span, so
  that the middle one is the lid centre FDP (3.1-3.4) that FAPs 19-22 move (SPEC's reading had 4
  per lid at k/5, which leaves no vertex at the centre). A ring of 12 skin points surrounds each
  eye (the crease above, the lower orbit below; 3.9, 3.10, 3.13, 3.14);
* brows: the detector marks the upper edge; the upper contour is a parabola through the ends and
  the three middle points (5 samples), the lower contour is the same curve lowered by the brow
  thickness (3 samples);
* mouth: outer upper lip as two half parabolas meeting at 8.1 (Cupid's bow), outer lower lip,
  inner upper and inner lower lips as parabolas through the corners (7 samples each at k/8),
  6 points on the lip bodies between the two contours;
* face contour: 4 segments between the jaw landmarks 0, 4, 8, 12, 16; side segments as x = f(y),
  chin segments as y = f(x); 7 samples each, 33 points;
* forehead: the hairline midpoint by the 1 : 2 rule (glabella to hairline = half of glabella to
  chin), an elliptic hairline through it and the contour's ends, two rows in between;
* the rest (cheeks, jaw, philtrum, temples, ears) proportionally between fitted curves; a margin
  ring around the face and a ring on the image border close the mesh.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

try:  # numpy >= 2 (private modules: any other layout falls back to the public functions)
    from numpy._core.multiarray import interp as _compiled_interp
    from numpy._core.umath import clip as _clip_ufunc  # type: ignore[attr-defined]
except ImportError:
    try:  # numpy 1.x
        from numpy.core.multiarray import interp as _compiled_interp  # type: ignore[no-redef]
        from numpy.core.umath import clip as _clip_ufunc  # type: ignore[no-redef]
    except ImportError:
        _compiled_interp, _clip_ufunc = np.interp, np.clip

#: ``np.interp(x, xp, fp)`` for real ``fp`` (no ``left``, ``right``, ``period``): the compiled
#: function ``np.interp`` calls, the same values, without its Python wrapper (its complex-type
#: check costs ~2.5 us a call, as much as interpolating a layer's box; the per-frame code
#: calls it ~20 times a frame)
interp = _compiled_interp
#: ``np.clip(x, lo, hi, out=...)`` of a float array with both bounds: the ufunc ``np.clip``
#: calls (one pass, the same values) without its three Python layers
clip = _clip_ufunc


@dataclass(frozen=True)
class FaceFrame:
    """Similarity frame of a face: ``p_image = origin + R @ p_frame``."""

    origin: np.ndarray  # (2,)
    rot: np.ndarray  # (2, 2), columns = frame x and y axes in image coordinates

    @classmethod
    def from_points(cls, pts: np.ndarray) -> FaceFrame:
        el, er = pts[36:42].mean(0), pts[42:48].mean(0)
        u = (er - el) / max(float(np.linalg.norm(er - el)), 1e-6)
        rot = np.array([[u[0], -u[1]], [u[1], u[0]]], np.float64)
        return cls((el + er) / 2.0, rot)

    def to_frame(self, p: np.ndarray) -> np.ndarray:
        return (np.asarray(p, np.float64) - self.origin) @ self.rot

    def to_image(self, q: np.ndarray) -> np.ndarray:
        return np.asarray(q, np.float64) @ self.rot.T + self.origin

    @property
    def angle(self) -> float:
        """Roll of the face in the image, radians (positive = clockwise on screen)."""
        return float(np.arctan2(self.rot[1, 0], self.rot[0, 0]))


def parabola(pa: np.ndarray, pb: np.ndarray, mids: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Sample the parabola y(x) through ``pa`` and ``pb`` fitted to ``mids`` (least squares).

    ``y = line(x) + a (x - xa)(x - xb)``; samples at ``x = xa + t (xb - xa)``. Returns (n, 2).
    """
    xa, ya = pa
    xb, yb = pb
    dx = xb - xa if abs(xb - xa) > 1e-9 else 1e-9
    mids = np.atleast_2d(mids)
    g = (mids[:, 0] - xa) * (mids[:, 0] - xb)
    r = mids[:, 1] - (ya + (mids[:, 0] - xa) * (yb - ya) / dx)
    a = float((g * r).sum() / max(float((g * g).sum()), 1e-12))
    x = xa + np.asarray(t, np.float64) * dx
    y = ya + (x - xa) * (yb - ya) / dx + a * (x - xa) * (x - xb)
    return np.stack([x, y], 1)


def _vparabola(pa, pb, mids, t):
    """Like :func:`parabola` with the roles of x and y swapped (x = f(y))."""
    out = parabola(pa[::-1], pb[::-1], np.atleast_2d(mids)[:, ::-1], t)
    return out[:, ::-1]


def _interp_x(curve: np.ndarray, y: float) -> float:
    """x of a polyline (sorted by y) at height y, clamped at its ends."""
    order = np.argsort(curve[:, 1])
    return float(np.interp(y, curve[order, 1], curve[order, 0]))


def _interp_y(curve: np.ndarray, x: float) -> float:
    order = np.argsort(curve[:, 0])
    return float(np.interp(x, curve[order, 0], curve[order, 1]))


K6 = np.arange(1, 6) / 6.0
K8 = np.arange(1, 8) / 8.0
Vertices = dict[str, np.ndarray]


def fit_vertices(points68: np.ndarray, image_size: tuple[int, int]
                 ) -> tuple[dict[str, np.ndarray], FaceFrame]:
    """Place every named vertex of the standard mesh on a face.

    The regions are fitted in turn (see the module docstring), each by its own function on the
    landmarks in the face frame; later regions lean on the curves of earlier ones.

    Parameters
    ----------
    points68 : (68, 2) array
        iBUG-68 landmarks, image pixels (x, y), y down.
    image_size : (width, height)

    Returns
    -------
    vertices : dict name -> (2,) image position (float64)
    frame : FaceFrame
    """
    fr = FaceFrame.from_points(np.asarray(points68, np.float64))
    P = fr.to_frame(points68)
    V: Vertices = {}
    iod = float(np.linalg.norm(P[42:48].mean(0) - P[36:42].mean(0)))
    brow_upper, thick = _fit_brows(V, P, iod)
    _fit_eyes(V, P, iod, brow_upper, thick)
    _fit_nose(V, P, iod)
    ou, od = _fit_mouth(V, P)
    contour = _fit_contour(V, P)
    hair, hair_mid = _fit_forehead(V, P, contour, brow_upper, thick)
    _fit_cheeks(V, P, iod, contour, ou, od, hair)
    _fit_philtrum(V, P, ou)
    _fit_jaw(V, P, contour, od)
    _fit_ears(V, iod, contour)
    _fit_rings(V, fr, image_size, iod, contour, P[8], hair_mid)
    return {k: fr.to_image(v) for k, v in V.items()}, fr


def _fit_brows(V: Vertices, P: np.ndarray, iod: float
               ) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """Brows: upper edge (the landmarks) and lower edge; returns each side's upper contour and
    thickness."""
    brow_upper = {}
    thick = {}
    for s, (a, b) in (("r", (17, 21)), ("l", (22, 26))):
        ends = (P[a], P[b])
        up = parabola(ends[0], ends[1], P[a + 1 : b], K6)
        lid_top = min(P[37 + (6 if s == "l" else 0)][1], P[38 + (6 if s == "l" else 0)][1])
        gap = lid_top - float(np.max(up[:, 1]))
        T = float(np.clip(0.42 * gap, 0.04 * iod, 0.11 * iod))
        thick[s] = T
        brow_upper[s] = np.vstack([ends[0], up, ends[1]])
        V[f"brow_{s}_e0"] = ends[0] + (0, 0.5 * T)
        V[f"brow_{s}_e1"] = ends[1] + (0, 0.5 * T)
        for k, q in enumerate(up, 1):
            V[f"brow_{s}_u{k}"] = q
        low = parabola(ends[0], ends[1], P[a + 1 : b], np.arange(1, 4) / 4.0)
        for k, q in enumerate(low, 1):
            taper = 0.75 + 0.25 * np.sin(np.pi * k / 4.0)
            V[f"brow_{s}_d{k}"] = q + (0, T * taper)
    return brow_upper, thick


def _fit_eyes(V: Vertices, P: np.ndarray, iod: float, brow_upper: dict[str, np.ndarray],
              thick: dict[str, float]) -> None:
    """Eyes: lid parabolas and the ring of skin points around each eye (below the brow)."""
    for s, base in (("r", 36), ("l", 42)):
        c0, c1 = P[base], P[base + 3]
        up = parabola(c0, c1, P[base + 1 : base + 3], K6)
        lo = parabola(c0, c1, P[[base + 5, base + 4]], K6)
        lo[:, 1] = np.maximum(lo[:, 1], up[:, 1] + 0.02 * iod)  # lids never cross
        W = float(np.linalg.norm(c1 - c0))
        V[f"eye_{s}_c0"], V[f"eye_{s}_c1"] = c0, c1
        for k in range(5):
            V[f"eye_{s}_u{k + 1}"] = up[k]
            V[f"eye_{s}_d{k + 1}"] = lo[k]
        bu = brow_upper[s]
        prof = 0.55 + 0.45 * np.sin(np.pi * K6)
        for k in range(5):
            x = up[k, 0]
            brow_low = _interp_y(bu, x) + thick[s]
            gap = max(up[k, 1] - brow_low, 0.05 * iod)
            V[f"eyering_{s}_u{k + 1}"] = up[k] - (0, min(0.5 * gap, 0.28 * W) * prof[k])
            V[f"eyering_{s}_d{k + 1}"] = lo[k] + (0, 0.26 * W * prof[k])
        out = 1.0 if s == "l" else -1.0  # outward along frame x for the outer corner
        outer, inner = (c1, c0) if s == "l" else (c0, c1)
        V[f"eyering_{s}_c{1 if s == 'l' else 0}"] = outer + (out * 0.22 * W, -0.02 * W)
        V[f"eyering_{s}_c{0 if s == 'l' else 1}"] = inner + (-out * 0.14 * W, -0.04 * W)


def _fit_nose(V: Vertices, P: np.ndarray, iod: float) -> None:
    """Nose: the nine nose landmarks, the sides of the bridge and the alae."""
    for i in range(27, 36):
        V[f"nose_{i}"] = P[i]
    wn = P[35, 0] - P[31, 0]
    V["nose_side_r"] = np.array([P[28, 0] - 0.17 * iod, P[28, 1] + 0.05 * iod])
    V["nose_side_l"] = np.array([P[28, 0] + 0.17 * iod, P[28, 1] + 0.05 * iod])
    V["ala_r"] = np.array([P[31, 0] - 0.12 * wn, 0.45 * P[29, 1] + 0.55 * P[31, 1]])
    V["ala_l"] = np.array([P[35, 0] + 0.12 * wn, 0.45 * P[29, 1] + 0.55 * P[35, 1]])


def _fit_mouth(V: Vertices, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mouth: outer and inner lip contours and the lip bodies; returns the outer upper and
    outer lower contours (7 points each)."""
    oc0, oc1 = P[48], P[54]
    mw = float(oc1[0] - oc0[0])
    left = parabola(oc0, P[51], P[49:51], np.array([0.25, 0.5, 0.75]))
    right = parabola(P[51], oc1, P[52:54], np.array([0.25, 0.5, 0.75]))
    ou = np.vstack([left, P[51], right])
    od = parabola(oc0, oc1, P[[59, 58, 57, 56, 55]], K8)
    ic0 = P[60].copy()
    ic1 = P[64].copy()
    ic0[0] = max(ic0[0], oc0[0] + 0.06 * mw)
    ic1[0] = min(ic1[0], oc1[0] - 0.06 * mw)
    ic0[1] = 0.5 * ic0[1] + 0.5 * oc0[1]
    ic1[1] = 0.5 * ic1[1] + 0.5 * oc1[1]
    iu = parabola(ic0, ic1, P[61:64], K8)
    idn = parabola(ic0, ic1, P[[67, 66, 65]], K8)
    # Inner lips meet but never cross; outer contour stays outside the inner one.
    cross = idn[:, 1] < iu[:, 1]
    mean = 0.5 * (idn[:, 1] + iu[:, 1])
    iu[cross, 1] = mean[cross]
    idn[cross, 1] = mean[cross]
    ou[:, 1] = np.minimum(ou[:, 1], iu[:, 1] - 0.015 * mw)
    od[:, 1] = np.maximum(od[:, 1], idn[:, 1] + 0.015 * mw)
    V["lipo_c0"], V["lipo_c1"], V["lipi_c0"], V["lipi_c1"] = oc0, oc1, ic0, ic1
    for k in range(7):
        V[f"lipo_u{k + 1}"], V[f"lipo_d{k + 1}"] = ou[k], od[k]
        V[f"lipi_u{k + 1}"], V[f"lipi_d{k + 1}"] = iu[k], idn[k]
    for k in (2, 4, 6):
        V[f"lipb_u{k}"] = 0.5 * (ou[k - 1] + iu[k - 1])
        V[f"lipb_d{k}"] = 0.5 * (od[k - 1] + idn[k - 1])
    return ou, od


def _fit_contour(V: Vertices, P: np.ndarray) -> np.ndarray:
    """Face contour: 33 points on four parabola segments between the jaw landmarks 0, 4, 8,
    12, 16; returns them (33, 2), image-left temple first."""
    J = P[0:17]
    segs = [_vparabola(J[0], J[4], J[1:4], K8), parabola(J[4], J[8], J[5:8], K8),
            parabola(J[8], J[12], J[9:12], K8), _vparabola(J[12], J[16], J[13:16], K8)]
    contour = [J[0]]
    for i, seg in enumerate(segs):
        contour.extend(seg)
        contour.append(J[4 * (i + 1)])
    contour_a = np.array(contour)
    for i, q in enumerate(contour_a):
        V[f"contour_{i}"] = q
    return contour_a


def _fit_forehead(V: Vertices, P: np.ndarray, contour: np.ndarray,
                  brow_upper: dict[str, np.ndarray], thick: dict[str, float]
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Forehead: the hairline (1 : 2 rule, elliptic), two rows of points between it and the
    brows, the glabella; returns the 11 hairline points and the hairline midpoint."""
    chin = P[8]
    g = 0.5 * (P[21] + P[22])
    hair_mid = g - 0.5 * (chin - g)
    cl, cr = contour[0], contour[-1]
    cx, cy = 0.5 * (cl[0] + cr[0]), 0.5 * (cl[1] + cr[1])
    a_ax = 0.5 * (cr[0] - cl[0])
    b_ax = cy - hair_mid[1]
    th = np.deg2rad(180.0 - 15.0 * np.arange(1, 12))
    hair = np.stack([cx + a_ax * np.cos(th) + (hair_mid[0] - cx) * np.sin(th),
                     cy - b_ax * np.sin(th)], 1)
    for k, q in enumerate(hair, 1):
        V[f"hair_{k}"] = q
    brow_top = np.vstack([brow_upper["r"], brow_upper["l"]])
    xs_f1 = np.linspace(0.1, 0.9, 9)
    xs_f2 = np.linspace(0.17, 0.83, 7)
    for row, (frac, xs) in enumerate(((0.36, xs_f1), (0.7, xs_f2)), 1):
        for k, fx in enumerate(xs, 1):
            x = cl[0] + fx * (cr[0] - cl[0])
            yb = _interp_y(brow_top, x)
            t = np.clip((x - cx) / max(a_ax, 1e-6), -0.999, 0.999)
            yh = cy - b_ax * np.sqrt(1 - t * t)
            V[f"forehead_{row}_{k}"] = np.array([x, yb + frac * (yh - yb)])
    V["glabella"] = np.array([g[0], g[1] + 0.35 * (thick["r"] + thick["l"]) / 2])
    return hair, hair_mid


def _fit_cheeks(V: Vertices, P: np.ndarray, iod: float, contour: np.ndarray, ou: np.ndarray,
                od: np.ndarray, hair: np.ndarray) -> None:
    """Cheeks: five rows between the nose/mouth and the contour, the nasolabial points, the
    mouth-corner skin and the temples."""
    oc0, oc1, chin = P[48], P[54], P[8]
    ring_lo = {s: V[f"eyering_{s}_d3"][1] for s in "rl"}
    nose_base = P[33, 1]
    mouth_y = 0.5 * (oc0[1] + oc1[1])
    lip_bottom = od[3, 1]
    for s, sign in (("r", -1.0), ("l", 1.0)):
        side = contour[:17] if s == "r" else contour[16:]
        eye_lo = ring_lo[s]
        corner = oc0 if s == "r" else oc1
        ala = V[f"ala_{s}"]
        rows = [
            (eye_lo + 0.3 * (nose_base - eye_lo), V[f"nose_side_{s}"][0] + sign * 0.06 * iod),
            (eye_lo + 0.68 * (nose_base - eye_lo), ala[0] + sign * 0.1 * iod),
            (nose_base + 0.1 * (mouth_y - nose_base), ala[0] + sign * 0.16 * iod),
            (mouth_y, corner[0] + sign * 0.14 * iod),
            (lip_bottom + 0.15 * (chin[1] - lip_bottom), corner[0] + sign * 0.1 * iod),
        ]
        for r, (y, x_in) in enumerate(rows, 1):
            x_out = _interp_x(side, y)
            for c, f in enumerate((0.28, 0.55, 0.8) if r < 5 else (0.3, 0.65), 1):
                V[f"cheek_{s}_{r}_{c}"] = np.array([x_in + f * (x_out - x_in), y])
        V[f"nlab_{s}_1"] = np.array([ala[0] + sign * 0.05 * iod, nose_base + 0.3 * (
            mouth_y - nose_base)])
        V[f"nlab_{s}_2"] = np.array([corner[0] + sign * 0.07 * iod, ou[0 if s == "r" else 6][1]])
        V[f"mcorner_{s}"] = corner + (sign * 0.07 * iod, 0.02 * iod)
        # temples: beside the eye ring and beside the brow's outer end
        oc = V[f"eyering_{s}_c{0 if s == 'r' else 1}"]
        be = V[f"brow_{s}_e{0 if s == 'r' else 1}"]
        xo = _interp_x(side, oc[1])
        # halfway from the eye ring's corner or the brow's outer end, whichever reaches further
        # out, to the contour: on a turned face the far brow's end can lie outside the point
        # halfway from the eye ring, and its triangle with the hairline then folds
        # (JAFFE NM.DI3.109 with MediaPipe's outline)
        inner = max(sign * oc[0], sign * be[0]) * sign
        V[f"temple_{s}_1"] = np.array([0.5 * (inner + xo), oc[1]])
        hx = hair[1] if s == "r" else hair[9]
        V[f"temple_{s}_2"] = np.array([0.5 * (be[0] + hx[0]) + sign * 0.03 * iod,
                                       0.5 * (be[1] + hx[1]) + 0.08 * iod])


def _fit_philtrum(V: Vertices, P: np.ndarray, ou: np.ndarray) -> None:
    """Philtrum: a row midway between the nose base and the upper lip."""
    for k, (ni, lip) in enumerate(zip((31, 32, 33, 34, 35), (0, 2, 3, 4, 6), strict=True), 1):
        top, bot = P[ni], ou[lip]
        x = 0.5 * (top[0] + bot[0])
        # the outer two never inward of their nostril's outer point: under a wide nose (or a
        # narrow, turned mouth) they would fold against the ala (JAFFE NM.DI3.109)
        if k == 1:
            x = min(x, top[0])
        elif k == 5:
            x = max(x, top[0])
        V[f"phil_{k}"] = np.array([x, top[1] + 0.5 * (bot[1] - top[1])])


def _fit_jaw(V: Vertices, P: np.ndarray, contour: np.ndarray, od: np.ndarray) -> None:
    """Jaw: two rows between the lower lip and the chin, across the contour."""
    chin, lip_bottom = P[8], od[3, 1]
    for row, frac in ((1, 0.38), (2, 0.7)):
        y = lip_bottom + frac * (chin[1] - lip_bottom)
        xl = _interp_x(contour[:17], y)
        xr = _interp_x(contour[16:], y)
        for k, f in enumerate(np.linspace(0.14, 0.86, 7), 1):
            x = xl + f * (xr - xl)
            if row == 2 and k == 4:
                x = chin[0]
            V[f"jaw_{row}_{k}"] = np.array([x, y])


def _fit_ears(V: Vertices, iod: float, contour: np.ndarray) -> None:
    """Ears: four points beside each upper contour."""
    for s, sign, idx in (("r", -1.0, (0, 2, 5)), ("l", 1.0, (32, 30, 27))):
        top, mid, low = (contour[i] for i in idx)
        be = V[f"brow_{s}_e{0 if s == 'r' else 1}"]
        V[f"ear_{s}_top"] = np.array([top[0] + sign * 0.13 * iod, be[1] + 0.05 * iod])
        V[f"ear_{s}_back"] = mid + (sign * 0.24 * iod, 0.0)
        V[f"ear_{s}_mid"] = 0.5 * (top + mid) + (sign * 0.1 * iod, 0.0)
        V[f"ear_{s}_lobe"] = low + (sign * 0.12 * iod, 0.0)


def _fit_rings(V: Vertices, fr: FaceFrame, image_size: tuple[int, int], iod: float,
               contour: np.ndarray, chin: np.ndarray, hair_mid: np.ndarray) -> None:
    """The margin ring around the face and the ring on the image border that close the mesh."""
    cl, cr = contour[0], contour[-1]
    centre = np.array([0.5 * (cl[0] + cr[0]), 0.5 * (hair_mid[1] + chin[1])])
    half_w = 0.5 * (cr[0] - cl[0]) + 0.35 * iod
    half_h = 0.5 * (chin[1] - hair_mid[1])
    corners_img = np.array([[0, 0], [image_size[0], 0], [image_size[0], image_size[1]],
                            [0, image_size[1]]], np.float64)
    corners_fr = fr.to_frame(corners_img)
    n = MARGIN_COUNT
    for k in range(n):
        phi = 2 * np.pi * k / n
        d = np.array([np.cos(phi), np.sin(phi)])
        r_face = 1.0 / np.sqrt((d[0] / half_w) ** 2 + (d[1] / half_h) ** 2)
        r_border = _ray_exit(centre, d, corners_fr)
        # below the chin the ring leaves room for the jaw to drop, also when the photo ends
        # close under the chin: the band would otherwise be squeezed against it, and the fold
        # guard, holding the vertices of its flattest triangles back, dented the chin into a W
        down = max(float(d[1]), 0.0)
        k_m = 1.3 + CHIN_ROOM * down ** 2
        r_m = max(min(k_m * r_face, (0.85 + 0.1 * down) * r_border), 1.08 * r_face)
        V[f"margin_{k}"] = centre + r_m * d
        phi_b = phi + np.pi / n
        db = np.array([np.cos(phi_b), np.sin(phi_b)])
        r_face_b = 1.0 / np.sqrt((db[0] / half_w) ** 2 + (db[1] / half_h) ** 2)
        # the outer ring: on the image border, or HEAD_BAND face radii beyond the margin when
        # the border lies further out (a small face in a large photo): a head rotation moves
        # the margin with the head and stretches only this band; the rest of the photo (body,
        # background) stays, and the warp does not cover the whole frame
        r_b = max(min(_ray_exit(centre, db, corners_fr), 1.3 * r_face_b + HEAD_BAND * r_face_b),
                  1.25 * r_m)
        V[f"border_{k}"] = centre + r_b * db


MARGIN_COUNT = 20
#: extra room of the margin ring straight below the chin (face radii; none sideways)
CHIN_ROOM = 0.3
#: width (in face radii, beyond the margin's 1.3) of the band between the margin ring and the
#: outer ring when the photo extends further
HEAD_BAND = 1.0


def _ray_exit(c: np.ndarray, d: np.ndarray, quad: np.ndarray) -> float:
    """Distance from ``c`` along ``d`` to the boundary of the convex quadrilateral ``quad``."""
    best = np.inf
    for i in range(4):
        a, b = quad[i], quad[(i + 1) % 4]
        e = b - a
        m = np.array([[d[0], -e[0]], [d[1], -e[1]]])
        det = np.linalg.det(m)
        if abs(det) < 1e-12:
            continue
        t, u = np.linalg.solve(m, a - c)
        if t > 0 and -1e-9 <= u <= 1 + 1e-9:
            best = min(best, t)
    return float(best if np.isfinite(best) else 0.0)



#: Inner lips at most this fraction of the mouth width apart count as closed (dlib's closed-lip
#: points coincide; MediaPipe's mesh keeps each lip's own inner edge, 0.03-0.08 MW apart on JAFFE's
#: closed neutral mouths, against 0.13 and more on its parted ones).
CLOSED_LIPS_MW = {"dlib-68": 0.05, "mediapipe-468": 0.09}
#: Teeth show when the opening's brightest pixels exceed the lips' luminance (``r`` beyond the
#: inner-lip points) by this factor. dlib puts the upper inner lip on the teeth's top edge, so
#: ``r`` above it is the lip's shadowed edge; MediaPipe puts it on the lip's own edge, so ``r``
#: above it is the lip's body, which on pale lips (the sample's) is within 1.25 of the teeth.
TEETH_RATIO = {"dlib-68": 1.25, "mediapipe-468": 1.1}


#: Rows per block of :func:`luminance` (a block's float32 copy is 12 x rows x width bytes).
LUMINANCE_ROWS = 256


def luminance(rgb: np.ndarray, rows: int = LUMINANCE_ROWS) -> np.ndarray:
    """``float32(rgb) @ (0.299, 0.587, 0.114)`` as one (H, W) float32 array, bit for bit, computed
    in blocks of ``rows`` rows: no (H, W, 3) float32 copy of the whole photo (288 MB at 24 MP;
    issue 15's peak memory)."""
    luma = np.array([0.299, 0.587, 0.114], np.float32)
    out = np.empty(rgb.shape[:2], np.float32)
    for i in range(0, rgb.shape[0], rows):
        out[i:i + rows] = np.asarray(rgb[i:i + rows], np.float32) @ luma
    return out


def median(a: np.ndarray, axis: int | None = None) -> np.ndarray:
    """``np.median(a)`` (``axis``: None or 0) bit for bit, without its Python-level overhead
    (~50 us a call, more than the partition itself on the plans' small arrays): the middle
    order statistic(s) from ``np.partition``, averaged in ``np.mean``'s precision (the array's
    float type, float64 for integers). Empty or NaN-holding input: ``np.median``."""
    a = np.asarray(a)
    if axis is None:
        a = a.reshape(-1)
    elif axis != 0:
        return np.median(a, axis=axis)
    n = a.shape[0]
    kind = a.dtype.kind
    if n == 0 or kind not in "fiub":
        return np.median(a, axis=axis)
    h = n // 2
    if n >= _ONE_KTH_MIN:
        # one kth per partition: np.partition given several (as np.median asks for its two
        # middle values and the NaN check) leaves numpy's vectorised selection for a scalar
        # one, ~8x slower on ~20k values. The lower middle value of an even count is the
        # largest of the h values partitioned below ``h``; NaNs (sorted last) lie at or after
        # ``h``
        part = np.partition(a, h, axis=0)
        mid = part[h]
        lo = mid if n % 2 == 1 else part[:h].max(axis=0)
        if kind != "f":
            return lo.astype(np.float64) if n % 2 == 1 else \
                (lo.astype(np.float64) + mid.astype(np.float64)) / 2.0
        # (a zero middle value may be +0 or -0, whichever the several-kth partition below
        # leaves there: that one then, as for NaNs)
        if not np.isnan(part[h:].max(axis=0)).any() and np.all(lo) and np.all(mid):
            return mid if n % 2 == 1 else (lo + mid) / a.dtype.type(2)
    kth = [h - 1, h] if n % 2 == 0 else [h]
    if kind == "f":
        kth.append(n - 1)  # NaNs sort last: np.median's check
    part = np.partition(a, kth, axis=0)
    if kind == "f" and np.isnan(part[n - 1]).any():
        return np.median(a, axis=axis)
    if kind == "f":
        lo = part[h - 1] if n % 2 == 0 else part[h]
        if n % 2 == 1:
            return lo
        return (lo + part[h]) / a.dtype.type(2)
    lo64 = part[h - 1 if n % 2 == 0 else h].astype(np.float64)
    if n % 2 == 1:
        return lo64
    return (lo64 + part[h].astype(np.float64)) / 2.0


def median_binned(a: np.ndarray, bins: int = 1024) -> float:
    """``float(np.median(a))`` of a 1-d float array whose values are finite, the same value
    (a zero's sign aside): each middle order statistic from a histogram of ``bins`` equal
    bins over the values' range (the bin index is monotonic in the value, so the k-th smallest
    lies in the bin where the counts reach k) and a partition of that bin's few values only;
    their mean as ``np.median`` takes it, in the array's precision. About a third of
    ``np.median``'s time on the ~40k values of a 1080p face's grain (two medians: 0.8 ->
    0.3 ms). Other input: ``np.median``."""
    a = np.asarray(a)
    n = a.size
    if a.ndim != 1 or a.dtype.kind != "f" or n < 2 * bins:
        return float(np.median(a))
    lo, hi = a.min(), a.max()
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return float(np.median(a))
    if lo == hi:
        return float(lo)
    at = ((a - lo) * a.dtype.type(bins / (float(hi) - float(lo)))).astype(np.intp)
    np.minimum(at, bins - 1, out=at)
    upto = np.cumsum(np.bincount(at, minlength=bins))
    h = n // 2

    def kth(k: int) -> np.floating:
        b = int(np.searchsorted(upto, k, side="right"))
        r = k - (int(upto[b - 1]) if b else 0)
        return np.partition(a[at == b], r)[r]

    if n % 2:
        return float(kth(h))
    return float((kth(h - 1) + kth(h)) / a.dtype.type(2))


#: From this many values :func:`median` partitions once per order statistic (below, numpy's
#: several-kth partition costs less than the extra checks)
_ONE_KTH_MIN = 6000


def catmull_rom(ctrl: np.ndarray, n: int) -> np.ndarray:
    """n points on a Catmull-Rom curve through the control points (uniform in parameter)."""
    c = np.vstack([2 * ctrl[0] - ctrl[1], ctrl, 2 * ctrl[-1] - ctrl[-2]])
    m = len(ctrl) - 1
    t = linspace(0.0, m, n)
    i = np.minimum(t.astype(int), m - 1)
    u = (t - i)[:, None]
    p0, p1, p2, p3 = c[i], c[i + 1], c[i + 2], c[i + 3]
    return 0.5 * (2 * p1 + (-p0 + p2) * u + (2 * p0 - 5 * p1 + 4 * p2 - p3) * u ** 2
                  + (-p0 + 3 * p1 - 3 * p2 + p3) * u ** 3)


def linspace(start: float, stop: float, num: int) -> np.ndarray:
    """``np.linspace(start, stop, num)`` of two float64 (or Python) numbers, ``num`` >= 2, bit
    for bit (numpy's arithmetic: ``arange * step + start``, the last value ``stop``) without
    its Python-level overhead (~10 us a call; the plans lay out dozens of lines)."""
    a, b = float(start), float(stop)
    delta = b - a
    step = delta / (num - 1)
    y = np.arange(num, dtype=np.float64)
    if step == 0:  # (numpy's order for a step that underflows)
        y /= num - 1
        y *= delta
    else:
        y *= step
    y += a
    y[-1] = b
    return y


def pad_edge(a: np.ndarray, k: int) -> np.ndarray:
    """``np.pad(a, k, mode="edge")`` of a 1-D array (its ends repeated ``k`` times), without
    np.pad's Python-level set-up (~20 us a call)."""
    return np.concatenate((np.repeat(a[:1], k), a, np.repeat(a[-1:], k)))


def percentile(a: np.ndarray, q: float) -> np.floating:
    """``np.percentile(a, q)`` (default linear method, a Python float ``q``) of a float array,
    bit for bit, without its Python-level overhead (~100 us a call): the two neighbouring
    order statistics from one ``np.partition`` and numpy's ``_lerp`` in the array's
    precision. Empty, non-float or NaN-holding input: ``np.percentile``."""
    a = np.asarray(a).reshape(-1)
    n = a.shape[0]
    if n == 0 or a.dtype.kind != "f":
        return np.percentile(a, q)
    vi = (n - 1) * float(np.true_divide(q, 100))
    if vi >= n - 1:
        prev = nxt = n - 1
        gamma = vi + 1.0  # (numpy's index -1; the two values are the same)
    elif vi < 0:
        prev = nxt = 0
        gamma = vi
    else:
        prev = int(np.floor(vi))
        nxt = prev + 1
        gamma = vi - prev
    part = np.partition(a, sorted({0, n - 1, prev, nxt}))
    if np.isnan(part[n - 1]):
        return np.percentile(a, q)
    lo, hi = part[prev], part[nxt]
    d = hi - lo
    if gamma >= 0.5:
        return hi - d * (1 - gamma)
    return lo + d * gamma


def clamp(x: ArrayLike, lo: ArrayLike, hi: ArrayLike) -> np.ndarray:
    """``np.clip(x, lo, hi)``'s values (NaN-free input) without its Python-level dispatch
    (several us a call, as much as the arithmetic on the plans' small arrays)."""
    return np.minimum(np.maximum(x, lo), hi)


def smooth01(t: ArrayLike) -> np.ndarray:
    """The smoothstep ``3 c^2 - 2 c^3`` of ``t`` clamped to [0, 1] (fades and weights)."""
    c = clamp(t, 0.0, 1.0)
    return c * c * (3.0 - 2.0 * c)


def smooth01_float(x: float) -> float:
    """:func:`smooth01` of a Python float (clamped to [0, 1] first): the same value without
    numpy's per-call cost on a scalar."""
    c = min(max(x, 0.0), 1.0)
    return c * c * (3.0 - 2.0 * c)


def gather_px(img: np.ndarray, rows: ArrayLike, cols: ArrayLike) -> np.ndarray:
    """``img[rows, cols]`` of an (h, w) or (h, w, c) array for in-range (non-negative)
    integer index arrays (broadcast): the same pixels by ``take`` on the flattened pixels,
    several times faster than numpy's two-array fancy indexing of a colour image."""
    h, w = img.shape[:2]
    flat = np.asarray(rows) * w + np.asarray(cols)
    return img.reshape((h * w,) + img.shape[2:]).take(flat, axis=0)


def masked_rows(img: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``img[mask]`` of an (h, w, c) array and an (h, w) bool mask: the same pixels in the
    same (row-major) order, gathered by ``take`` on their flat indices (numpy's boolean
    gather of (h, w, c) rows costs 2-3x more on the plans' boxes)."""
    h, w = mask.shape
    return np.ascontiguousarray(img).reshape(h * w, -1).take(np.flatnonzero(mask), 0)


def channel_median(img: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """``np.median(img[mask > 0], axis=0)`` (every pixel without ``mask``) of an (h, w, 3)
    uint8 image, float64 (3,), the same values from each channel's histogram: the middle rank's
    value, or the mean of the two middle ones. (``np.median`` partitions a copy of the pixels:
    several ms on a 24 MP photo's boxes.)"""
    import cv2  # local, as in snap_inner_lips

    m = None if mask is None else (mask > 0).astype(np.uint8)
    n = img.shape[0] * img.shape[1] if m is None else int(cv2.countNonZero(m))
    # (a partition is quicker below ~4000 pixels; the counts are float32: exact below 2^24)
    if img.dtype != np.uint8 or img.ndim != 3 or n < 4096 or n >= 1 << 24:
        return median(img.reshape(-1, img.shape[-1]) if m is None else masked_rows(img, m > 0),
                      axis=0)
    out = np.empty(img.shape[2])
    for c in range(img.shape[2]):
        cum = np.cumsum(cv2.calcHist([img], [c], m, [256], [0, 256]).ravel().astype(np.int64))
        lo, hi = np.searchsorted(cum, [(n - 1) // 2, n // 2], side="right")
        out[c] = (float(lo) + float(hi)) / 2.0
    return out


def box_medians(img: np.ndarray, boxes: list[tuple[int, int, int, int]]) -> np.ndarray:
    """``channel_median(img[y0:y1, x0:x1])`` of each box ``(x0, y0, x1, y1)`` (non-empty) of
    an (h, w, 3) uint8 image, (B, 3) float64, the same values: one histogram of every box's
    pixels per channel (each box's values offset by 256 x its index), whose cumulative counts
    give each box's middle rank(s) as :func:`channel_median`'s do (a fold layout's twenty
    small boxes: one call each cost ~15 us of overheads). Other input: one call a box."""
    parts = [img[y0:y1, x0:x1].reshape(-1, img.shape[-1]) for x0, y0, x1, y1 in boxes]
    n = np.array([len(p) for p in parts], np.int64)
    if img.dtype != np.uint8 or img.ndim != 3 or not len(parts) or not n.all():
        return np.array([channel_median(img[y0:y1, x0:x1]) for x0, y0, x1, y1 in boxes]
                        ).reshape(len(boxes), img.shape[-1])
    B = len(parts)
    px = np.concatenate(parts)
    at = np.repeat(np.arange(B, dtype=np.int64) * 256, n)
    lo_rank, hi_rank = ((n - 1) // 2)[:, None], (n // 2)[:, None]
    out = np.empty((B, img.shape[-1]))
    for c in range(img.shape[-1]):
        cum = np.cumsum(np.bincount(at + px[:, c], minlength=B * 256).reshape(B, 256), 1)
        # (the value of rank k: the first bin whose cumulative count exceeds k, i.e. the
        # number of bins whose count is at most k, as np.searchsorted(cum, k, "right"))
        lo = (cum <= lo_rank).sum(1)
        hi = (cum <= hi_rank).sum(1)
        out[:, c] = (lo.astype(np.float64) + hi.astype(np.float64)) / 2.0
    return out


def snap_inner_lips(V: dict[str, np.ndarray], rgb: np.ndarray, points68: np.ndarray,
                    closed_mw: float = 0.05, teeth_ratio: float = 1.25) -> None:
    """Move the inner-lip vertices (in place) onto the photo's own lip edges.

    dlib's eight inner-lip points are often a pixel or two off the real edge; the mesh's
    opening then cuts a strip of teeth into a lip triangle (it rides on the lip as a white
    sliver) or a strip of lip into the opening. Along each vertex's face-frame vertical,
    within ``r = 0.07 MW`` (at least 2 px), the photo's luminance profile is searched:

    * a mouth that shows teeth (pixels between the inner lips brighter than ``teeth_ratio``
      times the lips, see :data:`TEETH_RATIO`): the upper inner lip
      goes to the strongest dark-to-bright step (lip above teeth), the lower one to the
      strongest bright-to-dark step (teeth above lip), each on its own side of the opening;
    * a closed mouth (inner lips at most ``closed_mw`` mouth widths apart, see
      :data:`CLOSED_LIPS_MW`): both go to the darkest row, the lip line.

    The snapped points are refitted with the corner parabolas in the face frame (smooth); a
    weak edge keeps the dlib point; the lips never cross. Vectorised (``cv2.remap``).
    """
    import cv2  # local: the rest of fitting is numpy-only

    fr = FaceFrame.from_points(np.asarray(points68, np.float64))
    ey = fr.rot[:, 1]
    up = np.array([V[f"lipi_u{k}"] for k in range(1, 8)], np.float64)
    lo = np.array([V[f"lipi_d{k}"] for k in range(1, 8)], np.float64)
    mw = float(np.linalg.norm(V["lipo_c1"] - V["lipo_c0"]))
    r = max(0.07 * mw, 2.0)
    step = 0.25
    ts = np.arange(-r, r + step / 2, step)
    # every sample below lies within r of the inner lips' box: the luminance of that box only
    # (a 24 MP photo's would take 100 MB and 40 ms); the sample coordinates are shifted by the
    # box's integer corner after their float32 rounding, which is exact, and the box reaches
    # the image edge wherever a sample does, so BORDER_REPLICATE reads the same pixels
    h, w = rgb.shape[:2]
    ends = np.vstack([up, lo])
    x0, y0 = np.clip(np.floor(ends.min(0) - r - 3).astype(int), 0, (w - 1, h - 1))
    x1, y1 = np.clip(np.ceil(ends.max(0) + r + 3).astype(int) + 1, 1, (w, h))
    lum = luminance(rgb[y0:y1, x0:x1])
    ox, oy = np.float32(x0), np.float32(y0)

    def remap(xy: np.ndarray) -> np.ndarray:
        return cv2.remap(lum, xy[..., 0].astype(np.float32) - ox,
                         xy[..., 1].astype(np.float32) - oy, cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_REPLICATE)

    def profiles(centres: np.ndarray) -> np.ndarray:
        q = centres[:, None, :] + ts[None, :, None] * ey[None, None, :]
        return cv2.GaussianBlur(remap(q), (5, 1), 0)  # along each profile only

    gap = (lo - up) @ ey
    mid = 0.5 * (up + lo)
    seg = up[1:6, None, :] + np.linspace(0, 1, 9)[None, :, None] * (lo[1:6] - up[1:6])[:, None]
    between = remap(seg)
    ring = profiles(np.vstack([up, lo]))
    lip_l = float(np.median(np.concatenate([ring[:7, 0], ring[7:, -1]])))
    if gap[1:6].min() > 2.0 and np.median(between.max(1)) > teeth_ratio * lip_l:
        d = np.gradient(ring, step, axis=1)
        # the own side of the opening's middle: above it for the upper lip, below for the lower
        off = ts[None, :] + np.concatenate([-gap, gap])[:, None] * 0.5
        upper = np.arange(14)[:, None] < 7
        score = np.where(upper, d, -d)
        score = np.where(np.where(upper, off < 0, off > 0), score, -np.inf)
        best = score.argmax(1)
        ok = score[np.arange(14), best] > 0.08 * lip_l  # a real edge (luminance per px)
        cand = np.vstack([up, lo]) + ts[best][:, None] * ey
    elif float(np.median(gap)) <= closed_mw * mw:
        prof = profiles(mid)
        best = prof.argmin(1)
        ok = np.tile(lip_l - prof[np.arange(7), best] > 0.08 * lip_l, 2)
        cand = np.tile(mid + ts[best][:, None] * ey, (2, 1))
    else:
        return
    fit = []
    for half, orig in ((slice(0, 7), up), (slice(7, 14), lo)):
        if ok[half].sum() >= 3:
            f = fr.to_frame(cand[half][ok[half]])
            c0, c1 = fr.to_frame(V["lipi_c0"]), fr.to_frame(V["lipi_c1"])
            new = fr.to_image(parabola(c0, c1, f, K8))
            # at most r from the dlib curve
            new = orig + np.clip((new - orig) @ ey, -r, r)[:, None] * ey
        else:
            new = orig
        fit.append(new)
    new_up, new_lo = fit
    cross = (new_lo - new_up) @ ey < 0
    m = 0.5 * (new_up + new_lo)
    new_up[cross], new_lo[cross] = m[cross], m[cross]
    for k in range(7):
        V[f"lipi_u{k + 1}"], V[f"lipi_d{k + 1}"] = new_up[k], new_lo[k]
    for k in (2, 4, 6):
        V[f"lipb_u{k}"] = 0.5 * (V[f"lipo_u{k}"] + new_up[k - 1])
        V[f"lipb_d{k}"] = 0.5 * (V[f"lipo_d{k}"] + new_lo[k - 1])


def inner_lips_on_opening(points68: np.ndarray, V: dict[str, np.ndarray]) -> np.ndarray:
    """The 68 points with the inner-lip middles (61-63 upper, 65-67 lower) moved along the face
    frame's vertical onto the mesh's snapped inner-lip curves (:func:`snap_inner_lips`).

    With MediaPipe's mesh the upper inner lip is the lip's own edge; on a mouth showing teeth
    the snapped opening starts at the teeth's top edge instead (as dlib's points do). Fitting
    and the expression estimate then see one opening, the one the renderer opens and closes.
    """
    pts = np.asarray(points68, np.float64).copy()
    fr = FaceFrame.from_points(pts)
    ex, ey = fr.rot[:, 0], fr.rot[:, 1]
    for pre, ids in (("lipi_u", (61, 62, 63)), ("lipi_d", (67, 66, 65))):
        cur = np.array([V["lipi_c0"], *(V[f"{pre}{k}"] for k in range(1, 8)), V["lipi_c1"]],
                       np.float64)
        t = cur @ ex
        o = np.argsort(t)
        on = np.interp(pts[list(ids)] @ ex, t[o], (cur @ ey)[o])
        pts[list(ids)] += (on - pts[list(ids)] @ ey)[:, None] * ey
    return pts.astype(np.float32)


def is_grey(img: np.ndarray) -> bool:
    """Whether the three channels of ``img`` (h, w, 3) are equal everywhere. A colour photo
    is told by sparse samples of its pixels first (the whole image only when they agree)."""
    for a in (img[::61, ::61], img[::7, ::7], img):
        if not (np.array_equal(a[..., 0], a[..., 1]) and np.array_equal(a[..., 1], a[..., 2])):
            return False
    return True
