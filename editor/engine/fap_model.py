"""The FAP estimation model: FAPs from landmark motion on one face (issue 10; SPEC §6).

Model: the performer's neutral :class:`~editor.engine.face.Face` (mesh, FAPU, ``plan.basis`` =
pixels per unit of every linear FAP). Each iBUG-68 landmark is tied to the neutral mesh by the
barycentric coordinates of its closest point (``laplacian.landmark_map``; inner-lip and eyelid
landmarks only to triangles of their own lip/lid, since a closed mouth's lips coincide). The warp
is piecewise affine, so a landmark moves with its triangle and the predicted motion is linear in
the FAPs, ``d = A (f @ basis)``, in the performer's own FAPU. The renderer's inner/outer lip pair
correction (``deform.LIP_PAIRS``) is piecewise linear and modelled exactly (re-solve with the
Jacobian of the current sign/min pattern); the crossing rule and fold guard are not modelled,
but open_jaw is bounded by what the face's mesh renders without folding.

Head motion: a weighted similarity maps the expression's stable points onto the neutral's: eye
corners 36, 39, 42, 45 and nose bridge 28-29 (weight 1), nose tip 30 (0.5); never mouth, brows,
jaw, nor the top of the bridge 27 (the brows' band moves it in the model, dlib does not).
Out-of-plane turns are not removed (they read as small brow/jaw FAPs).

Solve: bounded least squares (``scipy.optimize.lsq_linear``, the FAP table's ranges) on pixel
residuals (jaw contour weighted 1/2 at the chin, 1/4 on the sides: dlib places it loosely) plus
priors in pixels of each FAP's own motion ``u_k f_k`` (u_k = its FAPU in px): Tikhonov ``reg``,
left/right symmetry ``symmetry`` (f_l - f_r) and inner = outer lip ``pair`` (on landmarks the two
FAPs of a lip pair correlate 0.8-0.99; the presets keep them equal).

Signs (issue 21): where a FAP's own feature point (:data:`OWN_LANDMARKS`) clearly moves one way
(beyond :data:`SIGN_FLOOR_PX`, head motion removed), the FAP is bounded to that side of 0. The lip
FAPs of the jaw (:data:`JAW_CARRIED`: corners, lower lip) are displacements on top of open_jaw's,
which carries the lower lip 1:1 with the chin and the corners ~0.68:1, while real JAFFE corners
follow the chin by 0.2-0.9 (median 0.55 over the open-mouthed surprises): their point's motion is
taken relative to where the estimated jaw carries it (an open smile's corners may end up below
the neutral's, yet rise against the jaw: raise_cornerlip > 0). Judged on the absolute motion, 69
of 1031 JAFFE sign checks looked wrong, every one with open_jaw > 100 (corners of surprise, fear,
open smiles; lower lips of mouths that moved down as a whole); bounding those on the absolute
motion made the surprise preset's own motion (open_jaw 520, corners +85) come back with corners
0, and a real open smile (KA.HA1) lose its corner lift (+111 -> 0). Relative to the jaw, one of
1303 was wrong (TM.HA1's inner lower lip, pushed up by the lip-pair prior); the bounds fix it.

Observable FAPs (:data:`OBSERVABLE`): 3 open_jaw, 15 shift_jaw, 4-13 inner lips, 19-22 eyelids,
31-38 brows, 41-42 lift cheeks, 51-60 outer lips, 61-62 nose wings. Not estimated: 14/16/17
(their 2-D approximations are collinear with 3/52/51), 18 (no landmark in its region), 23-30
(gaze, pupils), 39-40 (puff is depth; only the loose jaw line would see it), 43-47 tongue, 48-50
head (removed by the alignment), 63-64 (the nose tip is an alignment reference), 65-68 ears.


It lives in the engine because a photo's own expression is estimated with it when the photo
opens (:mod:`editor.engine.own_expression`); video tracking builds on it in
:mod:`editor.synthesis.fap_estimate`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .deform import LIP_PAIRS, deform_points, linear_positions
from .faps import FAPS
from .laplacian import landmark_map
from .transform import apply_affine, similarity

OBSERVABLE: tuple[int, ...] = (3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 15, 19, 20, 21, 22,
                               31, 32, 33, 34, 35, 36, 37, 38, 41, 42,
                               51, 52, 53, 54, 55, 56, 57, 58, 59, 60, 61, 62)
STABLE_POINTS = np.array([36, 39, 42, 45, 27, 28, 29, 30])
STABLE_WEIGHTS = np.array([1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.5])
#: Alignment points of the estimator: :data:`STABLE_POINTS` without the top of the nose bridge
#: (27). The brows move as a band that reaches the glabella, so the model moves 27 almost 1:1
#: with the inner brows (4.8 px for fear's raised inner brows on the upscaled sample), while
#: dlib places 27 from the eyes and the nose, on real faces and on renders alike (1.6 px there).
ESTIMATE_STABLE = np.array([36, 39, 42, 45, 28, 29, 30])
ESTIMATE_STABLE_WEIGHTS = np.array([1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.5])
#: Residual weight per landmark: dlib places the jaw contour loosely (chin half, sides quarter);
#: 27 not at all (see :data:`ESTIMATE_STABLE`).
LANDMARK_WEIGHTS = np.select([np.arange(68) < 4, np.arange(68) < 13, np.arange(68) < 17,
                              np.arange(68) == 27], [0.25, 0.5, 0.25, 0.0], 1.0)
#: Each sign-bounded FAP's own feature point(s) among the iBUG-68 landmarks (the point whose
#: displacement the FAP names; its direction is taken from the model's own basis).
OWN_LANDMARKS: dict[int, tuple[int, ...]] = {
    3: (8,), 5: (66,), 52: (57,), 12: (64,), 13: (60,), 59: (54,), 60: (48,),
    19: (43, 44), 20: (37, 38), 31: (22,), 32: (21,), 35: (26,), 36: (17,),
}
#: Lip FAPs whose own point open_jaw carries: their sign follows the point's motion relative to
#: the estimated jaw's carriage.
JAW_CARRIED: frozenset[int] = frozenset({5, 52, 12, 13, 59, 60})
#: Head-free motion of a FAP's own feature point (pixels) beyond which the FAP may not go the
#: other way: 5x the detector's re-detection noise (MediaPipe, the same JAFFE neutral shifted
#: by sub-pixel amounts and rescaled by 0.96-1.08: RMS 0.20 px, largest 0.89 px).
SIGN_FLOOR_PX = 1.0
#: How far (px) a FAP may move its own point against a motion that is still at rest; the room
#: shrinks linearly to 0 as the motion reaches :data:`SIGN_FLOOR_PX`.
SIGN_RAMP_PX = 4.0


def remove_head_motion(neutral68: np.ndarray, expr68: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Expression points mapped into the neutral's pose; returns (aligned (68, 2), M 2x3)."""
    M = similarity(expr68[STABLE_POINTS], neutral68[STABLE_POINTS], STABLE_WEIGHTS)
    return apply_affine(M, expr68), M


def landmark_jacobian(face, A=None) -> np.ndarray:
    """(136, 68): the motion of the face's 68 landmarks (x, y interleaved) per unit of each FAP,
    pixels, in the linear model (each landmark moves with its triangle of the neutral mesh; the
    lip pair correction left out). ``A``: the landmark map, when already built."""
    if A is None:
        A = landmark_map(face.vertices, face.triangles, face.mesh.names,
                         np.asarray(face.landmarks.points, np.float64))
    return _map_columns(A, face.plan.basis[:, :face.plan.n_vertices])


def _map_columns(A, basis: np.ndarray) -> np.ndarray:
    """(136, K): ``(A @ basis[k]).ravel()`` for each of the K (V, 2) motions of ``basis``, as
    float64; one sparse product for all of them (each value is summed over the same terms in
    the same order as K products of one motion each)."""
    K, V = basis.shape[:2]
    m = np.ascontiguousarray(basis.astype(np.float64).transpose(1, 0, 2).reshape(V, 2 * K))
    out = A @ m  # (68, K * 2): landmark l, motion k, coordinate c at [l, 2 k + c]
    return np.ascontiguousarray(out.reshape(-1, K, 2).transpose(0, 2, 1).reshape(-1, K))


# ---------------------------------------------------------------------------- estimation
@dataclass
class Estimate:
    """One estimated FAP vector with diagnostics."""

    faps: np.ndarray  # (68,) float32, performer FAPU
    residual_px: float  # RMS landmark residual of the model fit, performer pixels
    head: np.ndarray  # 2x3 similarity expression -> neutral pose
    displacement: np.ndarray  # (68, 2) head-free landmark motion, performer pixels

    @property
    def head_scale(self) -> float:
        return float(np.hypot(*self.head[:, 0]))

    @property
    def head_angle_deg(self) -> float:
        return float(np.degrees(np.arctan2(self.head[1, 0], self.head[0, 0])))


class FapEstimator:
    """FAP estimation for one performer (precomputed model of the neutral Face).

    Parameters
    ----------
    face : Face of the performer's neutral photo
    faps : FAP numbers to estimate (default :data:`OBSERVABLE`); the others stay 0
    reg, symmetry, pair : prior weights (see the module docstring)
    bounds : (lo, hi) (68,) arrays, default the FAP table ranges
    renderable : bound open_jaw by what the face's mesh renders without folding
        (:meth:`_jaw_limit`)
    sign_floor : pixels of motion of a FAP's own feature point beyond which the FAP may not go
        the other way (:meth:`bounds_for`); ``None`` leaves only the FAP table's ranges
    """

    def __init__(self, face, faps=OBSERVABLE, *, reg: float = 0.1, symmetry: float = 0.3,
                 pair: float = 1.0, bounds: tuple[np.ndarray, np.ndarray] | None = None,
                 landmark_weights: np.ndarray | None = None, renderable: bool = True,
                 sign_floor: float | None = SIGN_FLOOR_PX) -> None:
        self.face = face
        self.neutral = np.asarray(face.landmarks.points, np.float64)
        self.idx = np.array(sorted({int(FAPS.number(k)) for k in faps}), np.int64) - 1
        if (self.idx < 2).any():
            raise ValueError("FAPs 1 and 2 (visemes, expressions) cannot be estimated")
        lo, hi = (FAPS.lo, FAPS.hi) if bounds is None else bounds
        self.lo = np.asarray(lo, np.float64)[self.idx]
        self.hi = np.asarray(hi, np.float64)[self.idx]
        V = face.plan.n_vertices
        A = landmark_map(face.vertices, face.triangles, face.mesh.names, self.neutral)
        self.J = landmark_jacobian(face, A)
        pb = face.plan.pair_basis.reshape(len(LIP_PAIRS), -1, 2)[:, :V]
        self.P = _map_columns(A, pb)  # (136, 10)
        lw = LANDMARK_WEIGHTS if landmark_weights is None else np.asarray(landmark_weights)
        self.w = np.repeat(np.asarray(lw, np.float64), 2)
        self._priors = self._prior_rows(reg, symmetry, pair)
        self.stable, self.stable_w = ESTIMATE_STABLE, ESTIMATE_STABLE_WEIGHTS
        self.renderable = renderable
        self.sign_floor = sign_floor
        self._sign_rows()
        # open_jaw no further than the mesh allows: the margin ring under a JAFFE chin is ~0.1
        # IOD away, and beyond that the fold guard scales the *whole* deformation down (brows
        # included: 0.46 on wide-open surprise, jaw at its 1080 bound)
        if renderable and 2 in self.idx:
            k = int(np.flatnonzero(self.idx == 2)[0])
            self.hi[k] = self._jaw_limit(self.lo[k], self.hi[k])

    def _sign_rows(self) -> None:
        """The sign-bounded FAPs: positions in ``idx``, the (n, 136) rows that project the
        landmark motion onto each one's own feature point(s) along its own direction in the
        model (mean over its points), and that motion per unit of the FAP (px)."""
        pos, rows, gain = [], [], []
        J = self.J.reshape(68, 2, 68)
        for k, i in enumerate(self.idx):
            pts = OWN_LANDMARKS.get(int(i) + 1)
            if not pts:
                continue
            r = np.zeros((68, 2))
            g = 0.0
            for lm in pts:
                v = J[lm, :, i]
                n = float(np.hypot(*v))
                if n > 0:
                    r[lm] = v / (n * len(pts))
                    g += n / len(pts)
            if g > 0:
                pos.append(k)
                rows.append(r.ravel())
                gain.append(g)
        self._sign_pos = np.array(pos, np.int64)
        self._sign_proj = np.array(rows).reshape(len(pos), 136)
        self._sign_gain = np.array(gain, np.float64)
        carried = np.array([int(self.idx[k]) + 1 in JAW_CARRIED for k in pos], bool)
        # the motion open_jaw gives each carried row's point, px per unit (0 for the others)
        self._sign_jaw = np.where(carried, self._sign_proj @ self.J[:, 2], 0.0)
        self._sign_carried = carried

    def bounds_for(self, d: np.ndarray, faps: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of the estimated FAPs (``idx`` order) for a head-free motion ``d`` (136,):
        the FAP table's, and where a FAP's own feature point moves beyond ``sign_floor`` pixels
        one way, the FAP may not go the other way. The :data:`JAW_CARRIED` FAPs are bounded on
        their point's motion relative to the carriage of the (68,) vector ``faps``'s open_jaw,
        and not at all without ``faps``."""
        lo, hi = self.lo.copy(), self.hi.copy()
        if self.sign_floor is None or not len(self._sign_pos):
            return lo, hi
        m = self._sign_proj @ d
        k = self._sign_pos
        if faps is None:
            keep = ~self._sign_carried
            m, k = m[keep], k[keep]
            gain = self._sign_gain[keep]
        else:
            m = m - self._sign_jaw * float(faps[2])
            gain = self._sign_gain
        # how far the FAP may move its point against the motion, px: SIGN_RAMP_PX at rest,
        # shrinking linearly to 0 at the floor (no jump when a tracked point crosses it)
        room = SIGN_RAMP_PX * np.clip(1.0 - np.abs(m) / self.sign_floor, 0.0, 1.0) / gain
        up = m > 0
        lo[k[up]] = np.maximum(lo[k[up]], -room[up])
        hi[k[~up]] = np.minimum(hi[k[~up]], room[~up])
        return lo, hi

    def _prior_rows(self, reg: float, symmetry: float, pair: float) -> np.ndarray:
        n = len(self.idx)
        pos = {int(i): k for k, i in enumerate(self.idx)}
        u = np.array([self.face.fapu[FAPS[int(i) + 1].unit] for i in self.idx])  # px/unit
        rows = [reg * np.diag(u)] if reg > 0 else []
        links = []
        if symmetry > 0:
            for i in self.idx:
                m = FAPS[int(i) + 1].mirror
                if m and m - 1 in pos and m - 1 > i:
                    links.append((symmetry, pos[int(i)], pos[m - 1]))
        if pair > 0:
            for a, b in LIP_PAIRS:
                if int(a) in pos and int(b) in pos:
                    links.append((pair, pos[int(a)], pos[int(b)]))
        for wt, a, b in links:
            r = np.zeros(n)
            r[a], r[b] = wt * u[a], -wt * u[b]
            rows.append(r[None])
        return np.vstack(rows) if rows else np.zeros((0, n))

    def _effective_jacobian(self, f: np.ndarray) -> np.ndarray:
        """Jacobian of the pair-corrected linear model at the pattern of ``f`` (68,)."""
        J = self.J.copy()
        for k, (a, b) in enumerate(LIP_PAIRS):
            va, vb = f[a], f[b]
            if va * vb > 0:  # common part = the smaller of the two, subtracted once
                J[:, a if abs(va) <= abs(vb) else b] -= self.P[:, k]
        return J

    def predict(self, faps: np.ndarray) -> np.ndarray:
        """Landmark motion (68, 2) the model predicts for a (68,) FAP vector, pixels."""
        f = np.asarray(faps, np.float64)
        return (self._effective_jacobian(f) @ f).reshape(68, 2)

    def estimate(self, expr68: np.ndarray, neutral68: np.ndarray | None = None,
                 rounds: int = 3) -> Estimate:
        """Estimate the FAPs of one expression (68 landmarks in the performer's photo).

        The head alignment's reference points are not perfectly still under every FAP (the
        brows' band reaches the nose bridge, lift_cheek the outer eye corners): after each solve
        the alignment is redone against the neutral plus the motion the model predicts at those
        points (``rounds`` alignments in all), so the estimate is exact on the model's own
        motion.
        """
        neutral = self.neutral if neutral68 is None else np.asarray(neutral68, np.float64)
        expr = np.asarray(expr68, np.float64)
        f = np.zeros(68)
        for _ in range(max(1, rounds)):
            ref = neutral + self.predict(f) if f.any() else neutral
            M = similarity(expr[self.stable], ref[self.stable], self.stable_w)
            d = (apply_affine(M, expr) - neutral).ravel()
            f = self._solve(d)
        res = self.predict(f).ravel() - d
        return Estimate(f.astype(np.float32), float(np.sqrt(np.mean(res ** 2))), M,
                        d.reshape(68, 2))

    def folds(self, f: np.ndarray) -> bool:
        """True when the renderer's fold guard scales this (68,) vector down on the face."""
        plan = self.face.plan
        V = plan.n_vertices
        lin = linear_positions(plan, f)[:V] - plan.neutral64[:V]
        got = deform_points(plan, f)[:V] - plan.neutral64[:V]
        return float(np.linalg.norm(got)) < 0.999 * float(np.linalg.norm(lin))

    def _jaw_limit(self, lo: float, hi: float, steps: int = 10) -> float:
        """The largest open_jaw in [lo, hi] that does not fold on its own (bisection)."""
        v = np.zeros(68)
        v[2] = hi
        if not self.folds(v):
            return hi
        a, b = lo, hi
        for _ in range(steps):
            v[2] = 0.5 * (a + b)
            a, b = (v[2], b) if not self.folds(v) else (a, v[2])
        return max(a, lo + 1.0)

    def _solve(self, d: np.ndarray) -> np.ndarray:
        """Bounded least squares for a head-free landmark motion ``d`` (136,), re-solved at the
        lip-pair pattern of the previous solution; the (68,) vector of least cost. Solved first
        with the sign bounds that do not depend on the jaw, then again while a jaw-carried lip
        FAP goes against its point's motion relative to the solution's jaw."""
        f = self._solve_bounded(d, *self.bounds_for(d))
        if self.sign_floor is None:
            return f
        for _ in range(3):
            lo, hi = self.bounds_for(d, f)
            sol = f[self.idx]
            if ((sol >= lo - 1e-6) & (sol <= hi + 1e-6)).all():
                break
            f = self._solve_bounded(d, lo, hi)
        return f

    def _solve_bounded(self, d: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """:meth:`_solve` within the bounds ``lo``, ``hi`` (``idx`` order)."""
        from scipy.optimize import lsq_linear  # scipy on first use: a quick start (issue 15)

        n_prior = len(self._priors)
        b = np.concatenate([self.w * d, np.zeros(n_prior)])
        free = lo < hi  # a FAP bounded to [0, 0] stays 0 (lsq_linear wants lo < hi)
        f = np.zeros(68)
        best: tuple[float, np.ndarray] | None = None
        pattern = None
        for _ in range(6):
            J = self._effective_jacobian(f)
            Ab = np.vstack([self.w[:, None] * J[:, self.idx], self._priors])
            sol = np.zeros(len(self.idx))
            sol[free] = lsq_linear(Ab[:, free], b, bounds=(lo[free], hi[free]),
                                   method="bvls").x
            f = np.zeros(68)
            f[self.idx] = sol
            r = self.w * (self._effective_jacobian(f) @ f - d)
            cost = float(r @ r + np.sum((self._priors @ sol) ** 2))
            if best is None or cost < best[0]:
                best = (cost, f.copy())
            new = tuple(np.sign(f[LIP_PAIRS[:, 0]] * f[LIP_PAIRS[:, 1]]).astype(int)) + tuple(
                np.abs(f[LIP_PAIRS[:, 0]]) <= np.abs(f[LIP_PAIRS[:, 1]]))
            if new == pattern:
                break
            pattern = new
        assert best is not None
        return best[1]


def estimate_faps(neutral_points68: np.ndarray, expr_points68: np.ndarray, face, *,
                  faps=OBSERVABLE, bounds=None, reg: float = 0.1, symmetry: float = 0.3,
                  pair: float = 1.0) -> np.ndarray:
    """(68,) FAP vector (performer FAPU) explaining the motion neutral -> expression.

    ``face`` is the performer's neutral :class:`Face` (its mesh, FAPU and basis are the model);
    ``neutral_points68`` are the landmarks the displacements are measured from (normally
    ``face.landmarks.points``). See :class:`FapEstimator` for the options.
    """
    est = FapEstimator(face, faps, reg=reg, symmetry=symmetry, pair=pair, bounds=bounds)
    return est.estimate(expr_points68, neutral_points68).faps
