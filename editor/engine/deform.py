"""FAP-driven mesh deformation (SPEC §2): eq. 2 weights, superposition, fold guard. Batched.

A :class:`DeformPlan` is built once per personalized mesh. All low-level FAPs except the
rotations act linearly (value x FAPU x weight x direction), so they are precomputed as one
basis matrix and a FAP vector (or a batch of them) becomes a single matrix product. Gaze,
tongue roll and head rotations are applied after it; then the lips/lids crossing rule and the
topology guard (SPEC §2.3, eqs. 3-4). Everything uses neutral positions, so FAP order does not
matter.

Points: the V mesh vertices followed by extra feature points that are not mesh vertices
(irises 3.5/3.6, tongue 6.1-6.4): they move with the FAPs but are not part of any triangle.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from .faps import FAPS
from .fitting import FaceFrame
from .influence import (
    BROW_FDPS,
    OUTLINE_FDPS,
    brow_weights,
    closing_lid_share,
    face_mask,
    jaw_lip_taper,
    rectangles,
    side_tags,
    weights_many,
)
from .mesh import StandardMesh, signed_areas

EXTRA_POINTS = ("3.5", "3.6", "6.1", "6.2", "6.3", "6.4")

#: Guard: a triangle may shrink to EPS_SOLVE of its neutral signed area, never invert.
EPS_SOLVE = 0.06
EPS_CHECK = 0.05

_DIRS = {"up": (0.0, -1.0), "down": (0.0, 1.0), "left": (1.0, 0.0), "right": (-1.0, 0.0)}

# 2-D approximations of depth FAPs: fap -> list of (fdp, dx, dy) per unit, frame axes
_DEPTH = {
    14: [("2.1", 0.0, 0.3)],
    16: [("8.2", 0.0, 0.5)],
    17: [("8.1", 0.0, -0.5)],
    45: [("6.1", 0.0, 0.5)],
}
_NONLINEAR = {23, 24, 25, 26, 27, 28, 29, 30, 47, 48, 49, 50}
_NONLINEAR_IDX = np.array(sorted(x - 1 for x in _NONLINEAR))
_BROW_FDPS = frozenset(k for v in BROW_FDPS.values() for k in v)
#: FAP rows (0-based) of close_t_l/r_eyelid (19, 20): their closing part (positive values) has
#: its own basis (:func:`~editor.engine.influence.closing_lid_share`); ``_CLOSING`` the same
#: rows as a slice (a view of a batch of FAP rows)
CLOSING_LIDS = (18, 19)
_CLOSING = slice(18, 20)

#: Inner/outer lip FAP pairs that drive (almost) the same part of the lips. Alone, each moves
#: its own point by value x FAPU; together, the part of the face both reach is moved by the
#: larger common value once, not twice: D = w_in v_in + w_out v_out - min(w_in, w_out) m, with
#: m the common same-sign part of the two values (0 when their signs differ).
LIP_PAIRS = np.array([(4, 51), (5, 52), (6, 53), (7, 54), (8, 55), (9, 56), (10, 57), (11, 58),
                      (12, 59), (13, 60)]) - 1


@dataclass(frozen=True, eq=False)
class DeformPlan:
    """Everything needed to deform one personalized mesh, precomputed.

    Attributes
    ----------
    neutral : (N, 2) float32
        Neutral positions, image pixels; N = V mesh vertices + extra feature points.
    basis : (68, N, 2) float32
        Displacement in pixels per unit of each linear FAP.
    """

    neutral: np.ndarray
    basis: np.ndarray
    pair_basis: np.ndarray  # (10, N*2) shared influence of the inner/outer lip FAP pairs
    close_basis: np.ndarray  # (2, N*2) upper lids closing (FAPs 19/20 > 0) minus the basis
    n_vertices: int
    triangles: np.ndarray
    incidence: np.ndarray  # (V, maxdeg) triangle ids, padded with T (a dummy)
    pairs: np.ndarray  # (P, 2) upper/lower
    frame_rot: np.ndarray  # (2, 2)
    fapu: dict[str, float]
    head_weight: np.ndarray  # (N,) rotation weight: 1 face, 0.4 margin, 0 border
    depth: np.ndarray  # (N,) dome depth for pitch/yaw, pixels
    pivot: np.ndarray  # (2,) 7.1, image pixels
    eye_radius: float  # R of SPEC §3.2 (IRISD0)
    tongue_roll_scale: float
    neutral_sigma: np.ndarray  # (T,)
    movable: np.ndarray  # (V,) bool: can move for some FAP vector (not border)
    brow_gap: float = np.inf  # frame distance between the inner brow ends 4.1 and 4.2, pixels
    # float64 copies set by __post_init__
    neutral64: np.ndarray = field(init=False, repr=False)  # (N, 2)
    basis_flat: np.ndarray = field(init=False, repr=False)  # (68, N*2)
    tri_neutral: np.ndarray = field(init=False, repr=False)  # (T, 3, 2)

    def __post_init__(self) -> None:
        # float64 copies used on every call (the hot path avoids per-call conversions)
        object.__setattr__(self, "neutral64", self.neutral.astype(np.float64))
        object.__setattr__(self, "basis_flat",
                           self.basis.astype(np.float64).reshape(68, -1))
        object.__setattr__(self, "tri_neutral", self.neutral64[self.triangles])


@dataclass(frozen=True, eq=False)
class _Topology:
    """What :func:`build_plan` needs of a mesh that does not depend on the face (built once per
    mesh: the neutralisation of a photo's own expression builds up to 7 plans per photo)."""

    names: list[str]  # mesh vertex names + the extra points'
    sides: dict[str, np.ndarray]  # influence.side_tags(names)
    regions: np.ndarray  # (N,) vertex regions, "extra" for the extra points
    movable: np.ndarray  # (N,) not margin/border
    movable_lin: np.ndarray  # (N,) movable and not an iris
    head_w: np.ndarray  # (N,) head-rotation weight
    triangles: np.ndarray  # (T, 3) int64
    incidence: np.ndarray  # (V, maxdeg) triangle ids per vertex, padded with T
    pairs: np.ndarray  # (P, 2) int64
    close_share: dict[str, np.ndarray]  # influence.closing_lid_share(names)


@lru_cache(maxsize=4)
def _topology(mesh: StandardMesh) -> _Topology:
    names = list(mesh.names) + [f"tongue_{k}" if k.startswith("6") else f"iris_{k}"
                                for k in EXTRA_POINTS]
    regions = np.concatenate([mesh.regions, np.array(["extra"] * len(EXTRA_POINTS))])
    movable = ~np.isin(regions, ("margin", "border"))
    iris_mask = np.array([n.startswith("iris_") for n in names])
    head_w = np.where(regions == "border", 0.0, np.where(regions == "margin", 0.4, 1.0))
    tri = mesh.triangles.astype(np.int64)
    V, T = mesh.n_vertices, len(tri)
    # incidence: the triangles of each vertex in triangle order (padded with the dummy T)
    corner_v = tri.ravel()
    order = np.argsort(corner_v, kind="stable")  # by vertex, then by triangle id
    deg = np.bincount(corner_v, minlength=V)
    first = np.concatenate([[0], np.cumsum(deg)[:-1]])
    slot = np.arange(len(order)) - np.repeat(first, deg)
    inc = np.full((V, int(deg.max())), T, np.int64)
    inc[corner_v[order], slot] = order // 3
    topo = _Topology(names, side_tags(names), regions, movable, movable & ~iris_mask, head_w,
                     tri, inc, mesh.pairs.astype(np.int64), closing_lid_share(names))
    for a in (regions, movable, topo.movable_lin, head_w, tri, inc, topo.pairs,
              *topo.sides.values(), *topo.close_share.values()):
        a.setflags(write=False)
    return topo


@dataclass(frozen=True)
class _LinearFaps:
    """The linear FAPs' static table: per FAP row of the basis (``rows``), its unit's name, its
    direction (frame) and the index (``fdp_of``) of its feature point in ``fdps``: first those
    with an eq. 2 rectangle (``rect_fdps``), then the brows' and the tongue's; ``outline``:
    the feature point may move the face outline (:data:`OUTLINE_FDPS`)."""

    rows: np.ndarray
    units: tuple[str, ...]
    dirs: np.ndarray
    fdp_of: np.ndarray
    fdps: tuple[str, ...]
    rect_fdps: tuple[str, ...]
    outline: np.ndarray


@lru_cache(maxsize=1)
def _linear_faps() -> _LinearFaps:
    rows, units, dirs, fdp_list = [], [], [], []
    for f in FAPS.values():
        if f.number < 3 or f.number in _NONLINEAR:
            continue
        comps = _DEPTH.get(f.number)
        if not comps:
            if f.fdp is None:  # only FAP 1/2 (skipped above) have no feature point
                raise ValueError(f"FAP {f.number} has no feature point")
            comps = [(f.fdp, *_DIRS[f.direction])]
        if len(comps) != 1:
            raise ValueError(f"FAP {f.number}: one feature point per FAP")
        fdp, dx, dy = comps[0]
        rows.append(f.number - 1)
        units.append(f.unit)
        dirs.append((dx, dy))
        fdp_list.append(fdp)
    special = [k for k in dict.fromkeys(fdp_list) if k.startswith("6.") or k in _BROW_FDPS]
    rect_fdps = tuple(k for k in dict.fromkeys(fdp_list) if k not in special)
    fdps = rect_fdps + tuple(special)
    return _LinearFaps(np.array(rows), tuple(units), np.array(dirs, np.float64),
                       np.array([fdps.index(k) for k in fdp_list]), fdps, rect_fdps,
                       np.array([k in OUTLINE_FDPS for k in fdps]))


def build_plan(mesh: StandardMesh, vertices: np.ndarray, frame: FaceFrame,
               fapu: dict[str, float], extras: dict[str, np.ndarray]) -> DeformPlan:
    """Precompute the deformation of a personalized mesh.

    Parameters
    ----------
    vertices : (V, 2) neutral mesh vertices, image pixels
    extras : feature point id -> (2,) image position, for :data:`EXTRA_POINTS`
    """
    V = len(vertices)
    topo = _topology(mesh)
    names = topo.names
    pts_img = np.vstack([vertices, np.array([extras[k] for k in EXTRA_POINTS])])
    P = frame.to_frame(pts_img)
    byname = {n: P[i] for i, n in enumerate(names)}
    iod = float(np.linalg.norm(P[mesh.index("eye_l_u3")] - P[mesh.index("eye_r_u3")]))
    rects = rectangles(byname, iod)
    brows = brow_weights(byname, P, iod)
    on_face = face_mask(byname, P, iod)
    sides, movable, movable_lin = topo.sides, topo.movable, topo.movable_lin
    fdp_pos = {k: P[i] for k, i in mesh.fdp.items()}
    for i, k in enumerate(EXTRA_POINTS):
        fdp_pos[k] = P[V + i]
    N = len(P)
    lin = _linear_faps()
    # eq. 2 weights of every feature point the FAPs drive, all rectangles in one pass
    rect_w = weights_many([rects[k] for k in lin.rect_fdps],
                          np.array([fdp_pos[k] for k in lin.rect_fdps]), P, sides, movable_lin)
    W = np.empty((len(lin.fdps), N))
    W[:len(lin.rect_fdps)] = rect_w
    W[list(lin.rect_fdps).index("2.1")] *= jaw_lip_taper(byname, names)
    for j, fdp in enumerate(lin.fdps[len(lin.rect_fdps):], len(lin.rect_fdps)):
        if fdp.startswith("6."):
            W[j] = 0.0
            W[j, V + EXTRA_POINTS.index(fdp)] = 1.0
        else:
            W[j] = brows[fdp] * movable_lin
    # the motion stays inside the contour and the hairline (but for OUTLINE_FDPS: x 1)
    W = W * np.where(lin.outline[:, None], 1.0, on_face[None, :])
    single_w = W[lin.fdp_of]  # (F, N) the weight of each linear FAP
    units = np.array([fapu[u] for u in lin.units])
    basis = np.zeros((68, N, 2), np.float64)
    basis[lin.rows] += units[:, None, None] * single_w[:, :, None] * lin.dirs[:, None, :]
    # tongue points follow the jaw (they sit behind the lower teeth)
    tongue = np.arange(V + 2, N)
    basis[2, tongue] = basis[2, mesh.fdp["2.1"]]
    basis[13, tongue] += basis[13, mesh.fdp["2.1"]]
    basis[14, tongue] = basis[14, mesh.fdp["2.1"]]
    row_of = {int(r): i for i, r in enumerate(lin.rows)}
    ia = np.array([row_of[int(a)] for a in LIP_PAIRS[:, 0]])
    shared = np.minimum(single_w[ia], single_w[[row_of[int(b)] for b in LIP_PAIRS[:, 1]]])
    pair_basis = units[ia, None, None] * shared[:, :, None] * lin.dirs[ia, None, :]
    # a closing upper lid leaves the skin above its crease (influence.closing_lid_share): for
    # positive values its basis row is the basis plus this difference
    share = topo.close_share
    close_basis = np.zeros((len(CLOSING_LIDS), N, 2))
    for j, fap in enumerate(CLOSING_LIDS):
        i = row_of[fap]
        w = single_w[i]
        close_basis[j] = units[i] * (w * share[lin.fdps[lin.fdp_of[i]]] - w)[:, None] \
            * lin.dirs[i][None, :]
    # frame -> image directions
    basis = basis @ frame.rot.T
    pair_basis = pair_basis @ frame.rot.T
    close_basis = close_basis @ frame.rot.T

    # head rotation: face 1, margin 0.4, border 0 (topo.head_w); dome depth for pitch/yaw
    chin = P[mesh.fdp["2.1"]]
    hair = P[mesh.fdp["11.1"]]
    cl, cr = P[mesh.index("contour_0")], P[mesh.index("contour_32")]
    centre = np.array([0.5 * (cl[0] + cr[0]), 0.5 * (hair[1] + chin[1])])
    a, b = 0.5 * (cr[0] - cl[0]) + 1e-6, 0.5 * (chin[1] - hair[1]) + 1e-6
    rho2 = ((P[:, 0] - centre[0]) / a) ** 2 + ((P[:, 1] - centre[1]) / b) ** 2
    depth = 0.6 * a * np.clip(1.0 - rho2, 0.0, None)
    depth[mesh.fdp["9.3"]] += 0.25 * a
    pivot_f = np.array([chin[0], chin[1] + 0.15 * (chin[1] - hair[1])])
    tri, inc = topo.triangles, topo.incidence
    return DeformPlan(
        neutral=pts_img.astype(np.float32),
        basis=basis.astype(np.float32),
        pair_basis=pair_basis.reshape(len(LIP_PAIRS), -1),
        close_basis=close_basis.reshape(len(CLOSING_LIDS), -1),
        n_vertices=V,
        triangles=tri,
        incidence=inc,
        pairs=topo.pairs,
        frame_rot=frame.rot.astype(np.float64),
        fapu=dict(fapu),
        head_weight=topo.head_w,
        depth=depth,
        pivot=frame.to_image(pivot_f),
        eye_radius=fapu["IRISD"] * 1024.0,
        tongue_roll_scale=0.3 * fapu["MW"] * 1024.0,
        neutral_sigma=signed_areas(pts_img[:V].astype(np.float64), tri),
        movable=movable[:V],
        brow_gap=float(abs(fdp_pos["4.1"][0] - fdp_pos["4.2"][0])),
    )


def _rotate(points: np.ndarray, pivot: np.ndarray, ang: np.ndarray) -> np.ndarray:
    """Rotate (B, N, 2) points about pivot by per-point angles (B, N) (screen clockwise +)."""
    c, s = np.cos(ang), np.sin(ang)
    d = points - pivot
    return pivot + np.stack([c * d[..., 0] - s * d[..., 1], s * d[..., 0] + c * d[..., 1]], -1)


def _nonlinear(plan: DeformPlan, faps: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """Gaze, tongue roll and head rotations on top of the linear part. (B, N, 2)."""
    V = plan.n_vertices
    R = plan.frame_rot
    ex, ey = R[:, 0], R[:, 1]  # frame axes in image coordinates
    au = 1e-5
    # gaze: iris centre moves by R sin(theta); yaw + = face's left = frame +x; pitch + = down
    for k, (iyaw, ipitch) in enumerate(((22, 24), (23, 25))):  # 3.5 uses 23/25, 3.6 uses 24/26
        i = V + k
        dx = plan.eye_radius * np.sin(faps[:, iyaw] * au)
        dy = plan.eye_radius * np.sin(faps[:, ipitch] * au)
        pos[:, i] += dx[:, None] * ex + dy[:, None] * ey
    # tongue roll raises the tongue borders 6.3 / 6.4
    lift = plan.tongue_roll_scale * np.sin(faps[:, 46] * au * 100.0)
    pos[:, V + 4:V + 6] -= lift[:, None, None] * ey
    # head pitch / yaw: dome rotation, orthographic projection (relative to neutral)
    yaw, pitch, roll = faps[:, 48] * au, faps[:, 47] * au, faps[:, 49] * au
    if np.any(yaw) or np.any(pitch):
        rel = (plan.neutral.astype(np.float64) - plan.pivot) @ R  # frame coords
        w = plan.head_weight
        z = plan.depth
        dxf = (rel[None, :, 0] * (np.cos(yaw)[:, None] - 1.0) + z[None] * np.sin(yaw)[:, None])
        dyf = (rel[None, :, 1] * (np.cos(pitch)[:, None] - 1.0)
               + z[None] * np.sin(pitch)[:, None])
        pos += w[None, :, None] * (dxf[..., None] * ex + dyf[..., None] * ey)
    if np.any(roll):
        # positive roll = towards the face's right; on screen a clockwise turn for an upright
        # face seen from the front is towards the image left at the top: angle -roll
        ang = -roll[:, None] * plan.head_weight[None, :]
        pos = _rotate(pos, plan.pivot, ang)
    return pos


#: Lids follow the eyeball's pitch (FAPs 25/26): per eye (pitch, upper lid, lower lid) FAP
#: indices, and how far each lid moves per pixel of iris motion, looking down / up.
_GAZE_LIDS = ((24, 18, 20), (25, 19, 21))
_LID_FOLLOW_UP = (1.0, 0.5)  # upper lid: down 1:1 with the iris, up by half of it
_LID_FOLLOW_LOW = (0.3, 0.2)  # lower lid: a little, both ways


def _gaze_lids(plan: DeformPlan, f: np.ndarray) -> np.ndarray:
    """FAP vectors (B, 68) with the lids' share of the eyeball pitch added to FAPs 19-22.

    The iris centre moves by ``R sin(pitch)`` px (R = :attr:`DeformPlan.eye_radius`); the upper
    lid's feature point moves down by the same amount when the eye looks down (no white band
    above the iris) and up by half of it when it looks up; the lower lid follows by 0.3 / 0.2.
    Expressed as eyelid FAP values, so the lids' own influence regions carry the skin around
    them, the pair rule keeps the lids from crossing and the fold guard applies as usual.
    A lid that is nearly closed by its own FAP follows less (nothing from 70 % of its range's
    maximum to the maximum): the eyeball turns behind closed lids without moving them.
    """
    pitch_idx = [p for p, _u, _l in _GAZE_LIDS]
    if not f[:, pitch_idx].any():
        return f
    f = f.copy()
    per = plan.__dict__.get("_lid_per_unit")
    if per is None:
        # px per FAP unit of each lid's feature point along the frame's down axis (the
        # feature point carries weight 1: the largest motion of the basis); once per plan
        ey = plan.frame_rot[:, 1]
        per = {lid: float(np.abs(plan.basis[lid] @ ey).max())
               for _p, up, low in _GAZE_LIDS for lid in (up, low)}
        object.__setattr__(plan, "_lid_per_unit", per)
    for p, up, low in _GAZE_LIDS:
        dy = plan.eye_radius * np.sin(f[:, p] * 1e-5)  # iris motion, px, + = down
        for lid, follow, sign in ((up, _LID_FOLLOW_UP, 1.0), (low, _LID_FOLLOW_LOW, -1.0)):
            per_unit = per[lid]
            if per_unit <= 1e-9:
                continue
            k = np.where(dy > 0, follow[0], follow[1])
            hi = float(FAPS.hi[lid])
            k = k * np.clip((hi - f[:, lid]) / (0.3 * hi), 0.0, 1.0)
            # close_t (upper) moves down for +, close_b (lower) moves up for +
            f[:, lid] += sign * k * dy / per_unit
    return f


def _pair_rule(plan: DeformPlan, pos: np.ndarray) -> None:
    """Upper/lower lips and lids meet but never cross (in the face frame's y), in place."""
    u, lo = plan.pairs[:, 0], plan.pairs[:, 1]
    ey = plan.frame_rot[:, 1]
    yu = pos[:, u] @ ey
    yl = pos[:, lo] @ ey
    cross = yl < yu
    if cross.any():
        mean = 0.5 * (pos[:, u] + pos[:, lo])
        pu, pl = pos[:, u], pos[:, lo]
        pu[cross] = mean[cross]
        pl[cross] = mean[cross]
        pos[:, u], pos[:, lo] = pu, pl


def _tri_columns(plan: DeformPlan) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The triangles' three corner indices as contiguous arrays (once per plan)."""
    cols = plan.__dict__.get("_tri_cols")
    if cols is None:
        cols = tuple(np.ascontiguousarray(plan.triangles[:, k]) for k in range(3))
        object.__setattr__(plan, "_tri_cols", cols)
    return cols


def _fold_limits(plan: DeformPlan) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(1, T) sign of each neutral triangle's area, its solve limit (EPS_SOLVE of its area) and
    the tolerance of :func:`_folds_none` (once per plan)."""
    got = plan.__dict__.get("_fold_limits")
    if got is None:
        c0 = plan.neutral_sigma[None, :]
        got = (np.sign(c0), EPS_SOLVE * np.abs(c0), 1e-7 * np.abs(c0) + 1e-9)
        object.__setattr__(plan, "_fold_limits", got)
    return got


def _tau(plan: DeformPlan, D: np.ndarray, base: np.ndarray | None = None) -> np.ndarray:
    """First t in (0, 1] where a triangle's area reaches EPS_SOLVE of its neutral area. (B, T).

    ``base`` (B, V, 2): the displacement ``D`` starts from these positions instead of the
    neutral; a triangle already at or below the limit there is not constrained (t = 1).
    """
    t = plan.triangles
    if base is None:
        tn = plan.tri_neutral  # (T, 3, 2) neutral corners, precomputed
        A0, B0, C0 = tn[:, 0], tn[:, 1], tn[:, 2]
        dA, dB, dC = D[:, t[:, 0]], D[:, t[:, 1]], D[:, t[:, 2]]
        u0, w0 = C0 - A0, C0 - B0
        du, dw = dC - dA, dC - dB
    else:
        # positions and displacements gathered together (3 gathers, not 6)
        t0, t1, t2 = _tri_columns(plan)
        X = np.concatenate([base, D], axis=2)  # (B, V, 4)
        XC = X.take(t2, 1)  # (take: fancy indexing along an axis costs several us more)
        u = XC - X.take(t0, 1)
        w = XC - X.take(t1, 1)
        u0, du, w0, dw = u[..., :2], u[..., 2:], w[..., :2], w[..., 2:]

    def cross(p: np.ndarray, q: np.ndarray) -> np.ndarray:
        return p[..., 0] * q[..., 1] - p[..., 1] * q[..., 0]

    c0 = plan.neutral_sigma[None, :]
    sg = np.sign(c0)
    a2 = sg * cross(du, dw)
    a1 = sg * (cross(u0, dw) + cross(du, w0))
    if base is None:
        a0 = (1.0 - EPS_SOLVE) * np.abs(c0) * np.ones_like(a1)
    else:
        a0 = sg * cross(u0, w0) - EPS_SOLVE * np.abs(c0)
        a1 = np.where(a0 > 0, a1, 0.0)  # already at the limit: left to the guard
        a2 = np.where(a0 > 0, a2, 0.0)
        a0 = np.maximum(a0, 1e-12)
    lin = np.abs(a2) < 1e-12
    with np.errstate(divide="ignore", invalid="ignore"):
        r_lin = np.where(lin & (a1 < 0), -a0 / a1, np.inf)
        disc = a1 * a1 - 4.0 * a2 * a0
        sq = np.sqrt(np.maximum(disc, 0.0))
        q1 = (-a1 - sq) / (2.0 * a2)
        q2 = (-a1 + sq) / (2.0 * a2)
    q1 = np.where(~lin & (disc >= 0) & (q1 > 0), q1, np.inf)
    q2 = np.where(~lin & (disc >= 0) & (q2 > 0), q2, np.inf)
    first = np.minimum(np.minimum(q1, q2), r_lin)
    return np.where(first <= 1.0, first * 0.999, 1.0)


def _folds_none(plan: DeformPlan, D: np.ndarray, base: np.ndarray) -> bool:
    """True when :func:`_tau` of ``D`` from ``base`` is 1 for every triangle, decided with a
    margin (False near the limit: then the caller solves for tau).

    A triangle's area along ``base + t D`` is ``a0 + a1 t + a2 t^2`` (above the limit at
    ``t = 0``); it stays above the limit on [0, 1] when it is above it at ``t = 1`` and, for a
    convex parabola whose vertex lies inside (0, 1), at the vertex. Triangles at or below the
    limit at ``t = 0`` are left to the guard, as in :func:`_tau`.
    """
    if base.shape[0] == 1:
        return _folds_none_1(plan, D[0], base[0])
    t0, t1, t2 = _tri_columns(plan)
    # (B, V, 4) viewed component first: the corners gathered with take (fancy indexing
    # costs several us more) into (4, B, T)
    X = np.concatenate([base, D], axis=2).transpose(2, 0, 1)
    XC = X.take(t2, 2)
    u = XC - X.take(t0, 2)
    w = XC - X.take(t1, 2)
    ux, uy, dux, duy = u
    wx, wy, dwx, dwy = w
    sg, lim, tol = _fold_limits(plan)
    a2 = sg * (dux * dwy - duy * dwx)
    a1 = sg * (ux * dwy - uy * dwx + dux * wy - duy * wx)
    a0 = sg * (ux * wy - uy * wx) - lim
    return _stays_above(a0, a1, a2, tol)


def _folds_none_1(plan: DeformPlan, D: np.ndarray, base: np.ndarray) -> bool:
    """:func:`_folds_none` of one vector (``D``, ``base`` (V, 2)): its (V, 4) positions and
    displacements, all corners gathered in one take (C, A, B of every triangle) and viewed
    component first, (4, T) each; the same element-wise arithmetic on (T,) rows and the
    decision of :func:`_stays_above` without its broadcasts and ``ndarray.all`` wrappers
    (each a few us: a neutralised face's every frame; the guard keeps its own)."""
    T = len(plan.triangles)
    G = np.concatenate([base, D], axis=1).take(_tri_gather(plan), 0).T
    XC = G[:, :T]
    ux, uy, dux, duy = XC - G[:, T:2 * T]
    wx, wy, dwx, dwy = XC - G[:, 2 * T:]
    sg, lim, tol = _fold_rows(plan)
    a2 = sg * (dux * dwy - duy * dwx)
    a1 = sg * (ux * dwy - uy * dwx + dux * wy - duy * wx)
    a0 = sg * (ux * wy - uy * wx) - lim
    p1 = a0 + a1 + a2
    if np.count_nonzero((a0 <= 0) | (p1 > tol)) < T:
        return False
    inner = np.flatnonzero((a2 > 0) & (a1 < 0) & (-a1 < 2.0 * a2) & (a0 > 0))
    if not len(inner):
        return True
    a1, a2 = a1.take(inner), a2.take(inner)
    return np.count_nonzero(a0.take(inner) - a1 * a1 / (4.0 * a2) > tol.take(inner)) == len(inner)


def _fold_rows(plan: DeformPlan) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_fold_limits` as (T,) rows (once per plan)."""
    got = plan.__dict__.get("_fold_rows")
    if got is None:
        got = tuple(np.ascontiguousarray(a[0]) for a in _fold_limits(plan))
        object.__setattr__(plan, "_fold_rows", got)
    return got


def _stays_above(a0: np.ndarray, a1: np.ndarray, a2: np.ndarray, tol: np.ndarray) -> bool:
    """True when every area polynomial ``a0 + a1 t + a2 t^2`` (over the limit) that starts above
    0 stays above ``tol`` on [0, 1]: at ``t = 1`` and, for a convex parabola whose vertex lies
    inside (0, 1), at the vertex (the decision of :func:`_folds_none`)."""
    p1 = a0 + a1 + a2
    if not ((a0 <= 0) | (p1 > tol)).all():
        return False
    # the parabola's minimum inside (0, 1) (convex, vertex -a1 / (2 a2) there): a0 - a1^2/(4 a2),
    # at those triangles only (a2 > 0 there: no division warning to silence)
    inner = np.flatnonzero((a2 > 0) & (a1 < 0) & (-a1 < 2.0 * a2) & (a0 > 0))
    if not len(inner):
        return True
    a0 = np.broadcast_to(a0, p1.shape).ravel().take(inner)
    a1, a2 = a1.ravel().take(inner), a2.ravel().take(inner)
    return bool((a0 - a1 * a1 / (4.0 * a2) > np.broadcast_to(tol, p1.shape).ravel().take(inner)
                 ).all())


def _tri_gather(plan: DeformPlan) -> np.ndarray:
    """The triangles' corners C, A, B (columns 2, 0, 1) concatenated: one gather of all of
    them (once per plan)."""
    got = plan.__dict__.get("_tri_gather")
    if got is None:
        t0, t1, t2 = _tri_columns(plan)
        got = np.concatenate([t2, t0, t1])
        object.__setattr__(plan, "_tri_gather", got)
    return got


def _fit_offset(plan: DeformPlan, base: np.ndarray, off: np.ndarray, rounds: int = 8
                ) -> np.ndarray:
    """The offset (B, N, 2) scaled per vertex so that it folds no triangle the FAP motion
    ``base`` (B, N, 2) leaves unfolded.

    A neutralised face's offset is the photo's shape the FAPs do not render, taken with the
    share of the photo's expression a vector holds; where the photo's own motion opens a
    triangle the offset then narrows (a smiling photo's mouth corner: the FAP model at f0 opens
    the sliver between the inner and the outer corner to 4.2 px², the photo has 2.4), a vector
    opening it less (joy: 1.0) is turned inside out, and the fold guard then took two thirds
    of that vector's own motion off the whole corner. Here only the offset gives way, in the
    triangles it folds (none at f0: the photo itself).
    """
    V = plan.n_vertices
    D = off[:, :V]
    base = base[:, :V]
    if _folds_none(plan, D, base):  # the common case, decided without solving for tau
        return off
    pairs = plan.pairs
    scaled = False
    for _ in range(rounds):
        tau = _tau(plan, D, base)
        if (tau >= 1.0).all():
            break
        tau_pad = np.concatenate([tau, np.ones((tau.shape[0], 1))], 1)
        f = tau_pad[:, plan.incidence].min(-1)
        fp = np.minimum(f[:, pairs[:, 0]], f[:, pairs[:, 1]])
        f[:, pairs[:, 0]] = fp
        f[:, pairs[:, 1]] = fp
        D = D * f[..., None]
        scaled = True
    if not scaled:  # (``off[:, :V]`` is a new view each time: test the flag, not identity)
        return off
    out = off.copy()
    out[:, :V] = D
    return out


def _neutral_folds_none(plan: DeformPlan, D: np.ndarray) -> bool:
    """True when :func:`_tau` of ``D`` (B, V, 2) from the neutral is 1 for every triangle,
    decided as :func:`_folds_none` decides it (with its margin; False near the limit, and
    where a nearly flat parabola's root is computed by cancellation in :func:`_tau`: then the
    caller solves for tau). The neutral's part of the area is the plan's own: only the
    displacements are gathered."""
    u0x, u0y, w0x, w0y, a0, tol = _neutral_terms(plan)
    T = len(plan.triangles)
    # (B, V, 2) viewed component first and gathered at C, A, B of every triangle in one take
    G = D.transpose(2, 0, 1).take(_tri_gather(plan), 2)  # (2, B, 3T)
    du = G[:, :, :T] - G[:, :, T:2 * T]
    dw = G[:, :, :T] - G[:, :, 2 * T:]
    dux, duy = du
    dwx, dwy = dw
    sg = _fold_limits(plan)[0]
    a2 = sg * (dux * dwy - duy * dwx)
    a1 = sg * ((u0x * dwy - u0y * dwx) + (dux * w0y - duy * w0x))
    # (a0 0: a degenerate neutral, tau 1 there.) A root of a nearly flat parabola comes out of
    # _tau's formula with an error of about 1e-16 a1^2 / |a2| (cancellation): it must lie far
    # enough beyond 1 for that
    big = np.abs(a2)
    if ((big >= 1e-12) & (a1 * a1 * 1e-14 >= (a0 + a1 + a2) * big)).any():
        return False
    return _stays_above(a0, a1, a2, tol)


def _neutral_terms(plan: DeformPlan) -> tuple[np.ndarray, ...]:
    """Per triangle (1, T) the neutral's edges C - A, C - B (x, y) and the constant term of
    :func:`_tau`'s area polynomial, with :func:`_folds_none`'s tolerance (once per plan)."""
    got = plan.__dict__.get("_neutral_terms")
    if got is None:
        tn = plan.tri_neutral
        u0, w0 = tn[:, 2] - tn[:, 0], tn[:, 2] - tn[:, 1]
        c0 = plan.neutral_sigma[None, :]
        got = (u0[None, :, 0], u0[None, :, 1], w0[None, :, 0], w0[None, :, 1],
               (1.0 - EPS_SOLVE) * np.abs(c0), _fold_limits(plan)[2])
        object.__setattr__(plan, "_neutral_terms", got)
    return got


def guard(plan: DeformPlan, D: np.ndarray, rounds: int = 8) -> np.ndarray:
    """Scale displacements (B, V, 2) so that no triangle inverts or degenerates (SPEC §2.3)."""
    if _neutral_folds_none(plan, D):  # the common case, decided without solving for tau
        return D
    B = D.shape[0]
    pairs = plan.pairs
    for _ in range(rounds):
        tau = _tau(plan, D)
        if (tau >= 1.0).all():
            return D
        tau_pad = np.concatenate([tau, np.ones((B, 1))], 1)
        f = tau_pad[:, plan.incidence].min(-1)  # (B, V)
        # lips and lids scale together so that the pair rule still holds
        fp = np.minimum(f[:, pairs[:, 0]], f[:, pairs[:, 1]])
        f[:, pairs[:, 0]] = fp
        f[:, pairs[:, 1]] = fp
        D = D * f[..., None]
    tau = _tau(plan, D)
    t_star = tau.min(1)
    return D * t_star[:, None, None]


#: The squeezed brows keep at least 1 - SQUEEZE_MAX of the gap between their inner ends: beyond
#: SQUEEZE_KNEE x SQUEEZE_MAX of it the squeeze saturates smoothly (the brow heads bunch the
#: glabella skin; they cannot meet or cross).
SQUEEZE_MAX = 0.55
SQUEEZE_KNEE = 0.6


def limit_squeeze(plan: DeformPlan, f: np.ndarray) -> np.ndarray:
    """FAP rows (B, 68) with squeeze_l/r_eyebrow (37/38) softly limited to the brow gap."""
    sq = f[:, 36:38]
    t = np.clip(sq, 0.0, None).sum(1) * plan.fapu["ES"]  # how far the brow heads approach, px
    lim = SQUEEZE_MAX * plan.brow_gap
    knee = SQUEEZE_KNEE * lim
    over = t > knee
    if not over.any():
        return f
    span = lim - knee
    t2 = np.where(over, knee + span * np.tanh((t - knee) / span), t)
    scale = np.where(over, t2 / np.maximum(t, 1e-12), 1.0)
    f = f.copy()
    f[:, 36:38] = np.where(sq > 0, sq * scale[:, None], sq)
    return f


def _linear(plan: DeformPlan, f: np.ndarray) -> np.ndarray:
    """(B, N, 2) positions of the linear FAPs (lip-pair corrected), before the crossing rule,
    the nonlinear FAPs and the guard; ``f`` (B, 68) after the gaze-lid and squeeze rules."""
    lin = f @ plan.basis_flat
    va, vb = f[:, LIP_PAIRS[:, 0]], f[:, LIP_PAIRS[:, 1]]
    common = np.where(va * vb > 0, np.sign(va) * np.minimum(np.abs(va), np.abs(vb)), 0.0)
    if common.any():
        lin -= common @ plan.pair_basis
    closing = np.maximum(f[:, _CLOSING], 0.0)
    if closing.any():
        lin += closing @ plan.close_basis
    return plan.neutral64[None] + lin.reshape(f.shape[0], -1, 2)


def linear_positions(plan: DeformPlan, faps: np.ndarray) -> np.ndarray:
    """(N, 2) positions of one FAP vector before the crossing rule and the guard."""
    f = np.atleast_2d(np.asarray(faps, np.float64))
    return _linear(plan, limit_squeeze(plan, _gaze_lids(plan, f)))[0]


def deform_points(plan: DeformPlan, faps: np.ndarray,
                  offset: np.ndarray | None = None) -> np.ndarray:
    """Deformed positions of all points (mesh vertices + extra feature points).

    Parameters
    ----------
    faps : (68,) or (B, 68) array
        FAP values in FAPU, already clamped to the table ranges.
    offset : (N, 2) array, optional
        A constant displacement added before the crossing rule and the guard (a neutralised
        face's offset, see :class:`~editor.engine.face.Face`).

    Returns
    -------
    (N, 2) or (B, N, 2) float32 image positions (x, y), y down.
    """
    f = np.asarray(faps, np.float64)
    single = f.ndim == 1
    f = np.atleast_2d(f)
    f = limit_squeeze(plan, _gaze_lids(plan, f))
    n0 = plan.neutral64
    pos = _linear(plan, f)
    if offset is not None:
        off = np.asarray(offset)
        # (one vector's (N, 2) offset as a view with a batch axis: np.broadcast_to costs ~3 us)
        off = off[None] if off.shape == pos.shape[1:] and pos.shape[0] == 1 else \
            np.broadcast_to(off, pos.shape)
        pos += _fit_offset(plan, pos, off)
    _pair_rule(plan, pos)
    if f[:, _NONLINEAR_IDX].any():
        pos = _nonlinear(plan, f, pos)
    V = plan.n_vertices
    D = pos[:, :V] - n0[None, :V]
    Dg = guard(plan, D)
    if Dg is not D:  # the guard scaled something: extra points follow the overall scale
        a = np.abs(D).sum((1, 2))
        ratio = np.abs(Dg).sum((1, 2)) / np.maximum(a, 1e-12)
        scale = np.where(a > 0, np.minimum(ratio, 1.0), 1.0)
        pos[:, :V] = n0[None, :V] + Dg
        pos[:, V:] = n0[None, V:] + (pos[:, V:] - n0[None, V:]) * scale[:, None, None]
    out = pos.astype(np.float32)
    return out[0] if single else out


def eye_state(plan: DeformPlan, faps: np.ndarray, iris_r: np.ndarray) -> np.ndarray:
    """Iris and pupil radii (2, 2) ``[[iris_r, pupil_r], ...]`` for eyes 3.5 (left), 3.6."""
    f = np.asarray(faps, np.float64)
    out = np.zeros((2, 2))
    for k, (thrust, dil) in enumerate(((26, 28), (27, 29))):
        r = iris_r[k] * (1.0 + f[thrust] * plan.fapu["ES"] / max(4.0 * iris_r[k], 1e-6))
        pupil = iris_r[k] / 3.0 + f[dil] * plan.fapu["IRISD"] / 2.0
        out[k] = (r, float(np.clip(pupil, 0.08 * r, 0.9 * r)))
    return out
