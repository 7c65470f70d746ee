"""Influence rectangles of the feature points (SPEC §2.1, eq. 2) and the weights they give.

Each FAP moves its feature point p0 by ``s = value x FAPU``; a point (x, y) inside the point's
rectangle moves by ``w·s`` with ``w = wx(x)·wy(y)``. Eq. 2 of the paper is the tent
``wx = (x - xe)/(x0 - xe)`` (xe the rectangle side on the point's side), likewise wy. Only the
rectangle of FAP 52 is given in the paper; all others are ours, written below per feature point
with corners taken from named mesh vertices (face frame, offsets in inter-ocular distances).

Two documented extensions of eq. 2 (both reduce to it when unused):

* a *plateau* ``[c1, c2]`` around x0 (or y0) where the weight is 1, ramping linearly to 0 at the
  rectangle's sides: the jaw moves the whole lower lip and chin rigidly, an ear moves whole;
* a *parabolic* profile across an eye (``w = 1 - ((x - x0)/(xe - x0))^2``): the lids are parabolas
  through the eye corners, so a closing lid keeps its shape and meets the other lid all along.

A *side* filter keeps a FAP from dragging the opposite lip or lid: on a closed mouth the inner
upper and lower lip vertices coincide, and only their tags tell them apart.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Rect:
    """An influence rectangle in face-frame pixels."""

    x1: float
    y1: float
    x2: float
    y2: float
    px: tuple[float, float] | None = None
    py: tuple[float, float] | None = None
    parabolic_x: bool = False
    side: str | None = None  # "mouth_up", "mouth_low", "eye_l_up", "eye_l_low", ...


def weights(rect: Rect, p0: np.ndarray, pts: np.ndarray, sides: dict[str, np.ndarray],
            movable: np.ndarray) -> np.ndarray:
    """Eq. 2 weights (N,) of the points ``pts`` (N, 2, face frame) for a rectangle around p0."""
    return weights_many([rect], np.asarray(p0, np.float64)[None], pts, sides, movable)[0]


def weights_many(rects: Sequence[Rect], p0: np.ndarray, pts: np.ndarray,
                 sides: dict[str, np.ndarray], movable: np.ndarray) -> np.ndarray:
    """:func:`weights` of several rectangles (R,) around their points ``p0`` (R, 2) at once:
    (R, N), each row the values :func:`weights` gives (the same float64 operations)."""
    c = np.array([(r.x1, r.x2, r.y1, r.y2) for r in rects], np.float64).reshape(-1, 4)
    p0 = np.asarray(p0, np.float64).reshape(-1, 2)
    # p0 must lie strictly inside (SPEC: x1 < x0 < x2, y1 < y0 < y2)
    eps = 1e-3
    x1 = np.minimum(np.minimum(c[:, 0], c[:, 1]), p0[:, 0] - eps)
    x2 = np.maximum(np.maximum(c[:, 0], c[:, 1]), p0[:, 0] + eps)
    y1 = np.minimum(np.minimum(c[:, 2], c[:, 3]), p0[:, 1] - eps)
    y2 = np.maximum(np.maximum(c[:, 2], c[:, 3]), p0[:, 1] + eps)
    wx = _axis_weights(pts[:, 0], x1, x2, p0[:, 0], [r.px for r in rects],
                       np.array([r.parabolic_x for r in rects], bool))
    wy = _axis_weights(pts[:, 1], y1, y2, p0[:, 1], [r.py for r in rects],
                       np.zeros(len(rects), bool))
    w = wx * wy * movable
    for i, r in enumerate(rects):
        if r.side is not None:
            w[i] = w[i] * ~sides[_opposite(r.side)]
    return w


def _axis_weights(v: np.ndarray, lo: np.ndarray, hi: np.ndarray, c0: np.ndarray,
                  plateaus: Sequence[tuple[float, float] | None], parabolic: np.ndarray
                  ) -> np.ndarray:
    """The tents (or plateaus, parabolas) of several rectangles along one axis, (R, N): ramps
    from ``lo`` and ``hi`` (R,) to 1 on ``[a, b]`` (``c0`` without a plateau), at the points'
    coordinates ``v`` (N,)."""
    a, b = c0.astype(np.float64), c0.astype(np.float64)
    for i, p in enumerate(plateaus):
        if p is not None:
            a[i], b[i] = min(p), max(p)
    a, b = np.maximum(a, lo + 1e-6)[:, None], np.minimum(b, hi - 1e-6)[:, None]
    lo, hi, x = lo[:, None], hi[:, None], v[None, :]
    left = (x > lo) & (x < a)
    right = (x > b) & (x < hi)
    mid = (x >= a) & (x <= b)
    with np.errstate(divide="ignore", invalid="ignore"):  # (only the masked values count)
        wl = (x - lo) / (a - lo)
        wr = (hi - x) / (hi - b)
        if parabolic.any():
            k = np.flatnonzero(parabolic)
            wl[k] = 1.0 - ((x - a[k]) / (lo[k] - a[k])) ** 2
            wr[k] = 1.0 - ((x - b[k]) / (hi[k] - b[k])) ** 2
    # left, then right, then the plateau: the later wins where they overlap
    return np.where(mid, 1.0, np.where(right, wr, np.where(left, wl, 0.0)))


def _opposite(side: str) -> str:
    return side.replace("_up", "_LOW").replace("_low", "_up").replace("_LOW", "_low")


def side_tags(names: list[str]) -> dict[str, np.ndarray]:
    """Boolean masks of the points tagged upper/lower lip and upper/lower lid of each eye."""
    n = np.array(names)

    def starts(*prefixes: str) -> np.ndarray:
        return np.array([any(x.startswith(p) for p in prefixes) for x in n])

    return {
        # (nlab_*_1: the nasolabial fold's lowest point, above the upper lip beside the
        # philtrum, rides with the maxilla as the philtrum does; pulled down by the jaw it
        # squeezed the skin above the upper lip into a seam on an open mouth)
        "mouth_up": starts("lipi_u", "lipo_u", "lipb_u", "phil_", "nose", "nlab_l_1",
                           "nlab_r_1"),
        "mouth_low": starts("lipi_d", "lipo_d", "lipb_d", "tongue"),
        "eye_l_up": starts("eye_l_u", "eyering_l_u"),
        "eye_l_low": starts("eye_l_d", "eyering_l_d"),
        "eye_r_up": starts("eye_r_u", "eyering_r_u"),
        "eye_r_low": starts("eye_r_d", "eyering_r_d"),
    }


#: share of an upper lid's motion the eye ring above it (the crease line) takes when the lid
#: closes (:func:`closing_lid_share`)
RING_CLOSING_SHARE = 0.15


def closing_lid_share(names: Sequence[str]) -> dict[str, np.ndarray]:
    """Per upper-lid feature point (3.1, 3.2): the factor (N,) on its weights when the lid
    *closes* (positive FAPs 19/20): 1 on the lid's margin, :data:`RING_CLOSING_SHARE` on the
    eye ring, 0 elsewhere.

    An opening lid takes the skin up to the brow with it (the ramp of :func:`rectangles` runs
    from the brow's lower edge to the margin). A closing lid does not: in a blink the skin
    above the lid crease stays where it is and the lid's own skin unfolds from the crease. With
    the brow ramp the ring came down half-way with the lid (its sides, low on the curve, as far
    as the margin): the triangles from the brow's lower edge to the ring stretched, and the
    brow hair that lies in them (most photos' brows reach below the mesh's brow line) was
    pulled down into a wave.
    """
    n = np.array(names)
    out = {}
    for s, fdp in (("l", "3.1"), ("r", "3.2")):
        margin = np.char.startswith(n, f"eye_{s}_u")
        ring = np.char.startswith(n, f"eyering_{s}_u")
        out[fdp] = np.where(margin, 1.0, np.where(ring, RING_CLOSING_SHARE, 0.0))
    return out


#: How much less than its middle the lower lip's corners drop with the jaw: the jaw's weight
#: on the lower lip is multiplied by ``1 - JAW_LIP_TAPER t^4`` (t: 0 in the middle, 1 at the
#: corners). The jaw rectangle alone dropped the inner corners 0.62 and their neighbours 0.75
#: of the middle; the 33 open mouths of JAFFE surprise and fear drop them 0.40 and 0.66, their
#: openings 0.44 of the middle's height beside the corners (the rectangle: 0.72, a blunt end)
JAW_LIP_TAPER = 0.35


def jaw_lip_taper(P: dict[str, np.ndarray], names: Sequence[str]) -> np.ndarray:
    """(N,) factor on the jaw's weights (feature point 2.1): 1 but on the lower lip, where it
    falls towards the corners (:data:`JAW_LIP_TAPER`); ``P`` frame positions by name."""
    n = np.array(names)
    lip = np.zeros(len(n), bool)
    for prefix in ("lipi_d", "lipo_d", "lipb_d", "lipi_c", "lipo_c"):
        lip |= np.char.startswith(n, prefix)
    c0, c1 = P["lipi_c0"][0], P["lipi_c1"][0]
    half = max(abs(c1 - c0) / 2.0, 1e-6)
    x = np.array([P[k][0] for k in n[lip]])
    t = np.clip(np.abs(x - (c0 + c1) / 2.0) / half, 0.0, 1.0)
    out = np.ones(len(n))
    out[lip] = 1.0 - JAW_LIP_TAPER * t ** 4
    return out


def rectangles(P: dict[str, np.ndarray], iod: float) -> dict[str, Rect]:
    """The influence rectangle of every FAP-driven feature point, from frame positions ``P``."""

    def X(n: str, off: float = 0.0) -> float:
        return float(P[n][0] + off * iod)

    def Y(n: str, off: float = 0.0) -> float:
        return float(P[n][1] + off * iod)

    slit = 0.5 * (Y("lipi_c0") + Y("lipi_c1"))
    # the lip rectangles end 0.1 IOD past the lip line on the far side; the line is the corners'
    # (slit) or the middle's, whichever is further: with the corners well above the middle (an
    # upturned mouth) a rectangle ending at slit + 0.1 IOD would end at the upper lip's own
    # middle and cut its neighbours out of the lip FAPs (the lip would open at one vertex)
    mid = 0.5 * (Y("lipi_u4") + Y("lipi_d4"))
    below, above = max(slit, mid) + 0.1 * iod, min(slit, mid) - 0.1 * iod
    chin = Y("contour_16")
    nose_base = Y("nose_33")
    labiomental = Y("jaw_1_4")
    R: dict[str, Rect] = {}
    # jaw: the lower lip and chin move rigidly in the middle, less towards the jaw angles
    R["2.1"] = Rect(X("contour_4"), nose_base, X("contour_28"), chin + 0.6 * (chin - slit),
                    px=(X("lipi_u3"), X("lipi_u5")), py=(slit - 0.03 * iod, chin),
                    side="mouth_low")
    # Along a contour the tents of neighbouring feature points form a partition of unity (each
    # reaches 0 at the next point), so driving all of them by one value moves the contour
    # uniformly instead of overshooting where tents overlap.
    R["2.2"] = Rect(X("lipi_u2"), nose_base, X("lipi_u6"), below, side="mouth_up")
    R["2.3"] = Rect(X("lipi_d2"), above, X("lipi_d6"), labiomental, side="mouth_low")
    R["2.10"] = Rect(X("lipo_d2"), Y("lipo_d4"), X("lipo_d6"), chin, side="mouth_low")
    # paper's FAP 52 rectangle: outer corners to the chin, upper lip unaffected
    R["8.2"] = Rect(X("lipo_c0"), Y("lipo_c0"), X("lipo_c1"), chin, side="mouth_low")
    R["8.1"] = Rect(X("lipo_u2"), nose_base, X("lipo_u6"), below, side="mouth_up")
    eyes = {"l": ("eye_l_c0", "eye_l_c1"), "r": ("eye_r_c0", "eye_r_c1")}
    for s, sign in (("l", 1.0), ("r", -1.0)):
        c_out = "c1" if s == "l" else "c0"
        lo_mid, lo_c = ("lipi_u4", f"lipi_{c_out}")
        # inner lip: corners, mid-points
        corner_x = X(f"lipi_{c_out}")
        far = corner_x + sign * 0.45 * iod
        lip_low = Y("lipo_d4") + 0.5 * (chin - Y("lipo_d4"))
        fdp_c = "2.4" if s == "l" else "2.5"
        # the corner region (upper to lower lip at the corner) moves together
        k_near = 7 if s == "l" else 1
        corner_py = (Y(f"lipo_u{k_near}"), Y(f"lipo_d{k_near}"))
        R[fdp_c] = Rect(X(lo_mid), nose_base, far, lip_low, py=corner_py)
        fdp_c_o = "8.3" if s == "l" else "8.4"
        R[fdp_c_o] = Rect(X("lipo_u4"), nose_base, X(f"lipo_{c_out}") + sign * 0.45 * iod, lip_low,
                          py=corner_py)
        fdp_um = "2.6" if s == "l" else "2.7"
        R[fdp_um] = Rect(X(lo_mid), nose_base, X(lo_c), below, side="mouth_up")
        fdp_lm = "2.8" if s == "l" else "2.9"
        R[fdp_lm] = Rect(X("lipi_d4"), above, X(lo_c), labiomental, side="mouth_low")
        fdp_uo = "8.5" if s == "l" else "8.6"
        R[fdp_uo] = Rect(X("lipo_u4"), nose_base, X(f"lipo_{c_out}"), below,
                         side="mouth_up")
        fdp_lo = "8.7" if s == "l" else "8.8"
        R[fdp_lo] = Rect(X("lipo_d4"), slit, X(f"lipo_{c_out}"), labiomental, side="mouth_low")
        # eyelids: parabolic across the eye, corners fixed
        c0, c1 = eyes[s]
        up, low = ("3.1", "3.3") if s == "l" else ("3.2", "3.4")
        # each lid's own margin moves by the parabola alone: flat in y (a plateau) from its
        # feature point to the lower of its corners. A tent in y took the margin's sides,
        # which lie below the upper lid's top (above the lower lid's bottom), down to ~0.7 of
        # the parabola: a closed upper lid met the lower lid in the middle only, its sides
        # stayed up (the lash line a wavy W) and moved less than the skin above them
        corner_lo = max(Y(c0), Y(c1))
        corner_hi = min(Y(c0), Y(c1))
        R[up] = Rect(X(c0), Y(f"brow_{s}_d2"), X(c1), Y(f"eye_{s}_d3") + 0.02 * iod,
                     py=(Y(f"eye_{s}_u3"), corner_lo), parabolic_x=True,
                     side=f"eye_{s}_up")
        ring_lo = Y(f"eyering_{s}_d3")
        R[low] = Rect(X(c0), Y(f"eye_{s}_u3") - 0.02 * iod, X(c1),
                      ring_lo + 0.8 * (ring_lo - Y(f"eye_{s}_d3")),
                      py=(corner_hi, Y(f"eye_{s}_d3")), parabolic_x=True,
                      side=f"eye_{s}_low")
        # brows
        inner_e, outer_e = (f"brow_{s}_e0", f"brow_{s}_e1") if s == "l" else (
            f"brow_{s}_e1", f"brow_{s}_e0")
        fh_top = Y("hair_6")  # the forehead up to the hairline absorbs a brow raise
        eye_top = Y(f"eye_{s}_u3")
        b_in, b_mid, b_out = (("4.1", "4.3", "4.5") if s == "l" else ("4.2", "4.4", "4.6"))
        # the brow body (upper to lower edge) moves as a whole: a plateau across its thickness
        body = (Y(f"brow_{s}_u3"), Y(f"brow_{s}_d2"))
        R[b_in] = Rect(X("glabella", -sign * 0.08), fh_top, X(f"brow_{s}_u3"), eye_top,
                       py=(Y(inner_e) - 0.5 * (body[1] - body[0]), Y(inner_e) + 0.5 * (
                           body[1] - body[0])))
        R[b_mid] = Rect(X(inner_e), fh_top, X(outer_e), eye_top,
                        py=body)
        R[b_out] = Rect(X(f"brow_{s}_u3"), fh_top, X(outer_e, sign * 0.4),
                        Y(f"eye_{s}_{c_out if s == 'l' else 'c0'}"),
                        py=(Y(outer_e) - 0.5 * (body[1] - body[0]), Y(outer_e) + 0.5 * (
                            body[1] - body[0])))
        # cheeks
        cheek_c, cheek_b = (("5.1", "5.3") if s == "l" else ("5.2", "5.4"))
        ci = 27 if s == "l" else 5
        R[cheek_c] = Rect(X(f"lipo_{c_out}"), Y(f"eyering_{s}_d3"), X(f"contour_{ci}", sign * 0.15),
                          chin)
        cb = 30 if s == "l" else 2
        R[cheek_b] = Rect(X("nose_35" if s == "l" else "nose_31"), Y(f"eye_{s}_u3"),
                          X(f"contour_{cb}", sign * 0.1), Y(f"lipo_{c_out}"))
        # nose wings
        wing = "9.1" if s == "l" else "9.2"
        wn = "nose_35" if s == "l" else "nose_31"
        R[wing] = Rect(X("nose_33"), Y("nose_29"), X(wn, sign * 0.3), Y("lipo_u4"))
        # ears: the ear moves whole
        top, back = ("10.1", "10.3") if s == "l" else ("10.2", "10.4")
        ct = "contour_32" if s == "l" else "contour_0"
        xm, xb = sorted((X(f"ear_{s}_mid"), X(f"ear_{s}_back")))
        ear = Rect(X(ct, -sign * 0.02), Y(f"ear_{s}_top", -0.4), X(f"ear_{s}_back", sign * 0.3),
                   Y(f"ear_{s}_lobe", 0.15),
                   px=(xm, xb),
                   py=(Y(f"ear_{s}_top"), Y(f"ear_{s}_lobe")))
        R[top] = ear
        R[back] = ear
    R["9.3"] = Rect(X("nose_31", -0.1), Y("nose_28"), X("nose_35", 0.1), Y("lipo_u4"))
    return R


# ---------------------------------------------------------------------------------------------
# Brows: a band that follows the brow curve, with a partition of unity along it (SPEC §7)
# ---------------------------------------------------------------------------------------------

#: Brow feature points of each side, inner -> middle -> outer.
BROW_FDPS = {"l": ("4.1", "4.3", "4.5"), "r": ("4.2", "4.4", "4.6")}


#: Fraction of the brow-to-lid gap below the brow's fitted lower edge that moves with the brow.
BROW_SKIRT = 0.35


def _ramp(u: np.ndarray, a: float | np.ndarray, b: float | np.ndarray) -> np.ndarray:
    """0 at ``a``, 1 at ``b``, linear between (clamped); ``a < b``."""
    return np.clip((u - a) / np.maximum(b - a, 1e-6), 0.0, 1.0)


def _curve(P: dict[str, np.ndarray], names: list[str], x: np.ndarray) -> np.ndarray:
    """y of the polyline through the named points at abscissae ``x`` (clamped at its ends)."""
    q = np.array([P[n] for n in names])
    order = np.argsort(q[:, 0], kind="stable")
    return np.interp(x, q[order, 0], q[order, 1])


def brow_weights(P: dict[str, np.ndarray], pts: np.ndarray, iod: float) -> dict[str, np.ndarray]:
    """Weights (N,) of the six brow feature points 4.1-4.6 for the points ``pts`` (face frame).

    Replaces the three separate tents per brow (which peaked the arch into a tent when the brow
    was raised, and left a V-shaped seam between the brows when both were lowered):

    * *along* the brow (frame x) the inner, middle and outer weights are the linear hat
      functions on the knots (other brow's inner end, 4.1, 4.3, 4.5, 4.5 + 0.35 IOD): they sum
      to 1 from the inner to the outer end, so equal values move the brow as a rigid curve and
      unequal ones bend it along a smooth polyline through the three points. Across the gap
      between the brows the two inner hats meet: equal values move the glabella with the brows
      (no seam), a squeeze compresses the gap evenly instead of in one triangle;
    * *across* it (frame y) one profile shared by the six: 1 on the brow body (between its upper
      and lower edge, which follow the brow's own curve), falling linearly to 0 at the hairline
      above and at the upper lid below; between the brows it reaches down the nose bridge to
      9.12 (nose_29), so lowering the inner brows takes the glabella skin down with them instead
      of folding it against the nose.
    """
    x, y = pts[:, 0], pts[:, 1]
    tops = [f"brow_{s}_{k}" for s in "rl" for k in ("e0", "u1", "u2", "u3", "u4", "u5", "e1")]
    bots = [f"brow_{s}_{k}" for s in "rl" for k in ("e0", "d1", "d2", "d3", "e1")]
    hair = ["contour_0"] + [f"hair_{k}" for k in range(1, 12)] + ["contour_32"]
    lids = ([f"eye_r_{k}" for k in ("c0", "u1", "u2", "u3", "u4", "u5", "c1")] + ["nose_29"]
            + [f"eye_l_{k}" for k in ("c0", "u1", "u2", "u3", "u4", "u5", "c1")])
    top, bot = _curve(P, tops, x), _curve(P, bots, x)
    up = np.minimum(_curve(P, hair, x), top - 0.3 * iod)
    low = np.maximum(_curve(P, lids, x), bot + 0.1 * iod)
    # the fitted lower edge often sits inside the brow hair: the body stays rigid a little below
    # it (BROW_SKIRT of the gap to the lid) so that the hair is not stretched into spikes
    rigid = bot + BROW_SKIRT * (low - bot)
    top = top - 0.1 * BROW_SKIRT * (top - up)  # likewise a little above the fitted upper edge
    across = np.where(y < top, _ramp(y, up, top),
                      np.where(y > rigid, 1.0 - _ramp(y, rigid, low), 1.0))
    out: dict[str, np.ndarray] = {}
    for s, sign in (("l", 1.0), ("r", -1.0)):
        other = P["brow_r_e1" if s == "l" else "brow_l_e0"][0]
        b_in, b_mid, b_out = BROW_FDPS[s]
        ends = (f"brow_{s}_e0", f"brow_{s}_u3", f"brow_{s}_e1") if s == "l" else (
            f"brow_{s}_e1", f"brow_{s}_u3", f"brow_{s}_e0")
        # u grows from the middle of the face outwards on both sides
        u = sign * x
        k = [sign * other] + [sign * float(P[n][0]) for n in ends]
        k.append(k[-1] + 0.35 * iod)
        for j, fdp in enumerate((b_in, b_mid, b_out)):
            a, c, b = k[j], k[j + 1], k[j + 2]
            hat = np.where(u <= c, _ramp(u, a, c), 1.0 - _ramp(u, c, b))
            hat = hat * (u > a) * (u < b)
            out[fdp] = hat * across
    return out


# ---------------------------------------------------------------------------------------------
# The face region: motion stays inside the contour and the hairline
# ---------------------------------------------------------------------------------------------

#: Feature points whose FAPs may move the face outline itself: the jaw (2.1: open, thrust,
#: shift), the puffed cheeks (5.1/5.2) and the ears (10.x). Every other FAP leaves the contour
#: and the hairline where they are, so hair, ears and background never move with it.
OUTLINE_FDPS = frozenset({"2.1", "5.1", "5.2", "10.1", "10.2", "10.3", "10.4"})

#: Width of the band inside the contour/hairline over which the other FAPs fade out, in IOD.
FACE_BAND = 0.08


def face_polygon(P: dict[str, np.ndarray]) -> np.ndarray:
    """The face outline (frame): the contour from ear to ear over the chin, then the hairline."""
    names = [f"contour_{i}" for i in range(33)] + [f"hair_{k}" for k in range(11, 0, -1)]
    return np.array([P[n] for n in names], np.float64)


def inside_distance(poly: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Signed distance (N,) of the points to the closed polygon: > 0 inside, < 0 outside."""
    # per coordinate ((N, S) arrays, not (N, S, 2)): the same float64 operations as the
    # vector form (a dot product or squared norm of two components is their sum)
    a = poly
    b = np.roll(poly, -1, axis=0)
    ax, ay = a[:, 0], a[:, 1]
    abx, aby = b[:, 0] - ax, b[:, 1] - ay  # (S,)
    px, py = pts[:, 0:1], pts[:, 1:2]
    apx, apy = px - ax[None], py - ay[None]  # (N, S)
    den = np.maximum(abx * abx + aby * aby, 1e-12)[None]
    t = np.clip((apx * abx[None] + apy * aby[None]) / den, 0.0, 1.0)
    ex, ey = apx - t * abx[None], apy - t * aby[None]
    d = np.sqrt(ex * ex + ey * ey).min(1)
    # even-odd rule: a ray towards +x crosses the edges whose y-span holds the point
    ay, by, ax, bx = a[None, :, 1], b[None, :, 1], a[None, :, 0], b[None, :, 0]
    spans = (ay > py) != (by > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = ax + (py - ay) * (bx - ax) / (by - ay)
    inside = (spans & (px < xc)).sum(1) % 2 == 1
    return np.where(inside, d, -d)


def face_mask(P: dict[str, np.ndarray], pts: np.ndarray, iod: float) -> np.ndarray:
    """(N,) 1 inside the face, falling linearly to 0 at the contour/hairline (FACE_BAND)."""
    dist = inside_distance(face_polygon(P), pts)
    return np.clip(dist / (FACE_BAND * iod), 0.0, 1.0)
