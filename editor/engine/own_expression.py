"""The photo's own expression: the FAP vector a single photo already shows (issue 21 item 1).

MPEG-4 FAPs are displacements from the neutral face, but most portraits are not neutral (they
smile, often with teeth showing). Without a neutral photo of the same person we compare the
photo's 68 landmarks with a *neutral-shape prior* (SPEC §7.1):

    x = M(mu + B c) + J f + noise

* ``mu`` (68, 2): the mean neutral shape, in a canonical frame (eye centres at (-0.5, 0) and
  (0.5, 0), y down), aligned to the photo by the weighted similarity ``M`` on the stable points
  (eye corners, nose bridge, nose tip; :data:`~editor.engine.fap_model.STABLE_POINTS`);
* ``B`` (136, K): identity modes, rigid variations of face parts between people (mouth height,
  mouth width, lip thickness, brow height/arch/spacing, eye opening, nose and jaw length, face
  width, corner height), each with a prior standard deviation ``sigma`` measured on real neutral
  faces; no mode opens the lips, so lips apart always reads as expression;
* ``J f``: the FAP model of :class:`~editor.engine.fap_model.FapEstimator` on this
  photo's mesh.

Identity and expression are solved together (bounded least squares); the identity modes absorb
what people differ in, the FAPs what only an expression explains. FAPs whose motion stays below
the landmark noise are set to 0 (a neutral photo gives an exactly neutral vector).

The prior (``editor/data/neutral_prior.json``) is built by ``scripts/build_neutral_prior.py``
from neutral photos; the shipped one comes from the JAFFE neutral images (10 women; summary
statistics only, see the file's ``source``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.optimize import lsq_linear
from scipy.stats import chi2

from editor.resources import NEUTRAL_PRIOR

from .deform import LIP_PAIRS
from .fap_model import STABLE_POINTS, STABLE_WEIGHTS, FapEstimator
from .faps import FAPS
from .transform import apply_affine, similarity

PRIOR_PATH = NEUTRAL_PRIOR
CORNER_SIGMA = 0.015  # prior spread of the corners' height above the lip line (IOD)

#: iBUG-68 index of each point's mirror image (left/right swapped).
MIRROR_68 = np.array(
    list(range(16, -1, -1)) + list(range(26, 21, -1)) + list(range(21, 16, -1))
    + [27, 28, 29, 30] + [35, 34, 33, 32, 31]
    + [45, 44, 43, 42, 47, 46] + [39, 38, 37, 36, 41, 40]
    + [54, 53, 52, 51, 50, 49, 48, 59, 58, 57, 56, 55]
    + [64, 63, 62, 61, 60, 67, 66, 65])


def canonical(points68: np.ndarray) -> np.ndarray:
    """Points in the canonical frame: eye centres at (-0.5, 0), (0.5, 0); y down."""
    p = np.asarray(points68, np.float64)
    el, er = p[36:42].mean(0), p[42:48].mean(0)
    d = er - el
    s = float(np.hypot(*d)) or 1.0
    c, sn = d / s
    R = np.array([[c, sn], [-sn, c]])  # rotate the eye line onto +x
    return ((p - 0.5 * (el + er)) @ R.T) / s


def symmetrize(points68: np.ndarray) -> np.ndarray:
    """Mean of a canonical shape and its mirror image (x -> -x, left/right points swapped)."""
    p = np.asarray(points68, np.float64)
    m = p[MIRROR_68] * np.array([-1.0, 1.0])
    return 0.5 * (p + m)


def identity_modes(mu: np.ndarray) -> dict[str, np.ndarray]:
    """Unit identity modes (68, 2) on the canonical mean shape ``mu`` (see module docstring)."""
    z = np.zeros((68, 2))
    mouth = np.arange(48, 68)
    cx = mu[mouth, 0].mean()
    modes: dict[str, np.ndarray] = {}

    def mode(**cols: tuple[np.ndarray, np.ndarray | float]) -> np.ndarray:
        m = z.copy()
        for axis, (idx, val) in cols.items():
            m[idx, 0 if axis == "x" else 1] = val
        return m

    modes["mouth_height"] = mode(y=(mouth, 1.0))
    modes["mouth_width"] = mode(x=(mouth, mu[mouth, 0] - cx))
    modes["upper_lip"] = mode(y=(np.arange(49, 54), -1.0))
    modes["lower_lip"] = mode(y=(np.arange(55, 60), 1.0))
    modes["corner_height"] = mode(y=(np.array([48, 54, 60, 64]), 1.0))
    brows = np.arange(17, 27)
    modes["brow_height"] = mode(y=(brows, -1.0))
    bx = mu[brows, 0]
    half = np.where(bx < 0, bx - mu[17:22, 0].mean(), bx - mu[22:27, 0].mean())
    span = 0.5 * (mu[21, 0] - mu[17, 0])
    modes["brow_arch"] = mode(y=(brows, -(1.0 - np.clip((half / span) ** 2, 0, 1))))
    modes["brow_spacing"] = mode(x=(brows, np.sign(bx)))
    modes["brow_tilt"] = mode(y=(brows, -(np.abs(bx) - np.abs(bx).mean())))
    modes["eye_opening"] = mode(y=(np.array([37, 38, 43, 44, 40, 41, 46, 47]),
                                   np.array([-1, -1, -1, -1, 1, 1, 1, 1], float)))
    nose = np.arange(31, 36)
    modes["nose_length"] = mode(y=(nose, 1.0))
    modes["nose_width"] = mode(x=(nose, mu[nose, 0] - mu[33, 0]))
    jaw = np.arange(0, 17)
    modes["jaw_length"] = mode(y=(jaw, np.clip(mu[jaw, 1] - mu[30, 1], 0, None)))
    modes["face_width"] = mode(x=(jaw, mu[jaw, 0]))
    return modes


@dataclass(frozen=True)
class NeutralPrior:
    """Mean neutral shape, identity modes and their spreads (canonical units: IOD = 1)."""

    mean: np.ndarray  # (68, 2)
    names: tuple[str, ...]
    modes: np.ndarray  # (K, 68, 2)
    sigma: np.ndarray  # (K,) prior standard deviation of each mode's coefficient
    noise: np.ndarray  # (68,) residual spread per point after the modes
    source: str

    @classmethod
    def from_shapes(cls, shapes_by_person: list[np.ndarray], source: str,
                    noise_floor: float = 0.012, spread: float = 1.5,
                    min_sigma: float = 0.04) -> NeutralPrior:
        """Build from canonical neutral shapes, one (n_i, 68, 2) array per person.

        ``spread`` widens the measured identity spreads and ``min_sigma`` bounds them from
        below (canonical units): a small set of people under-represents how much faces differ.
        """
        per = np.array([np.mean(s, 0) for s in shapes_by_person])
        mu = symmetrize(per.mean(0))
        # a neutral mouth is closed: the inner lips meet (61-67, 62-66, 63-65)
        up, low = np.array([61, 62, 63]), np.array([67, 66, 65])
        mu[up] = mu[low] = 0.5 * (mu[up] + mu[low])
        table = identity_modes(mu)
        names = tuple(table)
        B = np.stack([table[n] for n in names])  # (K, 68, 2)
        Bf = B.reshape(len(B), -1).T
        coef, res = [], []
        for s in per:
            d = (s - mu).ravel()
            c, *_ = np.linalg.lstsq(Bf, d, rcond=None)
            coef.append(c)
            res.append((d - Bf @ c).reshape(68, 2))
        coef_a, res_a = np.array(coef), np.array(res)
        sigma = np.maximum(spread * np.sqrt(np.mean(coef_a ** 2, 0)), min_sigma)
        # mouth corners above the lip line are what a smile is: a neutral mouth is close to
        # flat, so that mode is kept tight (an upturned neutral mouth is flattened a little)
        sigma[names.index("corner_height")] = CORNER_SIGMA
        within = [np.asarray(s) - np.mean(s, 0) for s in shapes_by_person if len(s) > 1]
        jitter = (np.sqrt(np.mean(np.concatenate(within) ** 2, axis=(0, 2)))
                  if within else np.zeros(68))
        noise = np.sqrt(np.mean(res_a ** 2, axis=(0, 2)) + jitter ** 2)
        noise = np.maximum(noise, noise_floor)
        return cls(mu, names, B, sigma, noise, source)

    def to_json(self) -> dict:
        return {"format": "fap-studio-neutral-prior", "version": 1, "source": self.source,
                "units": "canonical frame: eye centres at (-0.5, 0) and (0.5, 0), y down",
                "mean": np.round(self.mean, 5).tolist(), "modes": list(self.names),
                "sigma": np.round(self.sigma, 5).tolist(),
                "noise": np.round(self.noise, 5).tolist()}

    @classmethod
    def from_json(cls, data: dict) -> NeutralPrior:
        mu = np.asarray(data["mean"], np.float64)
        table = identity_modes(mu)
        names = tuple(data["modes"])
        return cls(mu, names, np.stack([table[n] for n in names]),
                   np.asarray(data["sigma"], np.float64), np.asarray(data["noise"], np.float64),
                   str(data.get("source", "")))


@lru_cache(maxsize=1)
def default_prior() -> NeutralPrior:
    return NeutralPrior.from_json(json.loads(PRIOR_PATH.read_text("utf-8")))


@dataclass
class OwnExpression:
    """What a photo shows: its FAP vector and the identity that explains the rest."""

    faps: np.ndarray  # (68,) float32, the photo's FAPU
    identity: dict[str, float]  # mode -> coefficient in prior standard deviations
    residual: float  # RMS landmark residual, % of the inter-ocular distance
    neutral68: np.ndarray  # (68, 2) the neutral landmarks the fit implies, photo pixels
    words: str = "neutral"  # e.g. "smile, lips apart"


#: FAPs a photo's own expression is made of (the rest are identity, or not seen in one photo)
OWN_FAPS: tuple[int, ...] = (3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 19, 20, 21, 22,
                             31, 32, 33, 34, 35, 36, 37, 38,
                             51, 52, 53, 54, 55, 56, 57, 58, 59, 60)

#: Prior spread of each FAP group's motion of its feature point, fraction of the inter-ocular
#: distance: lids move little (and eye shape differs a lot between people), jaw and lips much.
FAP_SPREAD = {"jaw": 0.08, "inner_lip": 0.05, "outer_lip": 0.05, "corner": 0.08,
              "lid": 0.015, "brow": 0.035}

#: FAP groups judged together, with the landmarks they are seen on
GROUPS: tuple[tuple[tuple[int, ...], np.ndarray], ...] = (
    ((3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 51, 52, 53, 54, 55, 56, 57, 58, 59, 60),
     np.arange(48, 68)),
    ((19, 21), np.arange(42, 48)), ((20, 22), np.arange(36, 42)),
    ((31, 33, 35, 37), np.arange(22, 27)), ((32, 34, 36, 38), np.arange(17, 22)),
)


def _group(n: int) -> str:
    if n == 3:
        return "jaw"
    if n in (12, 13, 59, 60, 6, 7, 53, 54):
        return "corner"
    if 19 <= n <= 22:
        return "lid"
    if 31 <= n <= 38:
        return "brow"
    return "inner_lip" if n < 14 else "outer_lip"


def estimate_own(face, prior: NeutralPrior | None = None, *, min_move: float = 0.02,
                 spread: float = 1.0, significance: float = 0.999) -> OwnExpression:
    """Estimate the expression a photo shows against the neutral prior.

    ``min_move``: a FAP group (mouth, each lid pair, each brow) whose joint motion of its
    landmarks stays below this fraction of the inter-ocular distance is set to 0 (below the
    landmark noise), and so is one that does not lower the fit's cost significantly (chi-square
    test at ``significance`` with as many degrees of freedom as its FAPs). ``spread`` scales
    :data:`FAP_SPREAD`, the prior standard deviation of each FAP's motion of its feature point
    (expressions compete with the identity modes on the same footing).
    """
    pr = prior or default_prior()
    x = np.array(face.landmarks.points, np.float64)  # a copy: the inner lips are moved below
    M = similarity(pr.mean[STABLE_POINTS], x[STABLE_POINTS], STABLE_WEIGHTS)
    mu_x = apply_affine(M, pr.mean)
    scale = float(np.hypot(*M[:, 0]))  # canonical unit -> pixels (the photo's IOD)
    A = M[:, :2]
    Bx = np.stack([(m @ A.T).ravel() for m in pr.modes], 1)  # (136, K) pixels per unit coef
    est = FapEstimator(face, OWN_FAPS, reg=0.0, symmetry=0.3, pair=1.0)
    w = np.repeat(1.0 / (pr.noise * scale), 2)
    w[np.repeat(STABLE_POINTS, 2)] *= 0.25  # they fixed the alignment
    w[:34] *= 0.5  # the contour: dlib places it loosely, people differ most there
    K = Bx.shape[1]
    prior_c = np.diag(1.0 / pr.sigma)  # coefficients are in canonical units
    n_f = len(est.idx)
    u = np.array([face.fapu[FAPS[int(i) + 1].unit] for i in est.idx])  # px per unit
    sd = np.array([FAP_SPREAD[_group(int(i) + 1)] for i in est.idx]) * spread * scale
    # an inner/outer lip pair drives one part of the lips (the renderer moves their shared part
    # once; the pair prior keeps them equal): the spread is that motion's, not paid twice
    sd[np.isin(est.idx, LIP_PAIRS)] *= np.sqrt(2.0)
    fap_prior = np.vstack([np.diag(u / sd),  # ridge, in prior spreads
                           est._priors / (0.02 * scale)])  # symmetry / lip pairs (px rows)
    rows_prior = np.vstack([np.hstack([np.zeros((K, n_f)), prior_c]),
                            np.hstack([fap_prior, np.zeros((len(fap_prior), K))])])
    # lip contact: the gaps between the inner lips (along the face's vertical) are the surest
    # cue; no identity mode opens them, so they are fitted tightly. They are the mesh's inner
    # lips' gaps (snapped to the photo's lip/teeth edges, :func:`~editor.engine.fitting.
    # snap_inner_lips`), which the renderer opens, not dlib's inner-lip points' (on the sample's
    # open smile 6-7 px where the lips show 3.6-4.8: f0 opened the side pairs to 6.5-8.1 px)
    ey = face.frame.rot[:, 1]
    names = face.mesh.names
    lp = np.array([(u_, l_) for u_, l_ in face.mesh.pairs if names[u_].startswith("lipi")])
    basis = face.plan.basis.astype(np.float64)
    Gm = ((basis[:, lp[:, 1]] - basis[:, lp[:, 0]]) @ ey).T  # (P, 68) gap per FAP unit
    pb = face.plan.pair_basis.astype(np.float64).reshape(len(LIP_PAIRS), -1, 2)
    Gc = ((pb[:, lp[:, 1]] - pb[:, lp[:, 0]]) @ ey).T  # (P, 10) the lip pairs' shared part
    verts = np.asarray(face.vertices, np.float64)
    gap_p = np.maximum((verts[lp[:, 1]] - verts[lp[:, 0]]) @ ey, 0.0)
    # dlib's inner-lip points follow the mesh's snapped edge along the vertical (their own
    # residuals would otherwise pull the opening back to dlib's)
    for a_, ids in ((lp[:, 0], (61, 62, 63)), (lp[:, 1], (67, 66, 65))):
        ex = face.frame.rot[:, 0]
        t = verts[a_] @ ex
        o = np.argsort(t)
        for i_ in ids:
            on = np.interp(x[i_] @ ex, t[o], (verts[a_] @ ey)[o])
            x[i_] = x[i_] + (on - x[i_] @ ey) * ey
    d = (x - mu_x).ravel()

    def gap_rows(f_: np.ndarray) -> np.ndarray:
        Ge = Gm.copy()
        for k_, (a_, b_) in enumerate(LIP_PAIRS):
            if f_[a_] * f_[b_] > 0:
                Ge[:, a_ if abs(f_[a_]) <= abs(f_[b_]) else b_] -= Gc[:, k_]
        return Ge[:, est.idx]

    wg = 1.0 / (0.005 * scale)
    lo = np.concatenate([est.lo, np.full(K, -np.inf)])
    hi = np.concatenate([est.hi, np.full(K, np.inf)])
    f = np.zeros(68)
    best = None
    for _ in range(4):  # re-solve at the lip-pair pattern of the previous solution
        J = est._effective_jacobian(f)[:, est.idx]
        Ab = np.vstack([w[:, None] * np.hstack([J, Bx]), rows_prior,
                        np.hstack([gap_rows(f), np.zeros((len(lp), K))]) * wg])
        b = np.concatenate([w * d, np.zeros(len(rows_prior)), gap_p * wg])
        sol = lsq_linear(Ab, b, bounds=(lo, hi), method="bvls").x
        f = np.zeros(68)
        f[est.idx] = sol[:n_f]
        # the cost of a solution at its own lip-pair pattern (it was solved with the previous
        # pattern's Jacobian: at f = 0 an inner and an outer lip FAP of the same sign both move
        # their shared part, which the renderer moves once)
        J = est._effective_jacobian(f)[:, est.idx]
        As = np.vstack([w[:, None] * np.hstack([J, Bx]), rows_prior,
                        np.hstack([gap_rows(f), np.zeros((len(lp), K))]) * wg])
        cost = float(np.sum((As @ sol - b) ** 2))
        if best is None or cost < best[0]:
            best = (cost, f.copy(), sol[n_f:].copy())
    assert best is not None
    _, f, c = best
    iod = face.interocular
    # a group is dropped as a whole (single FAPs of a group compensate each other, e.g. jaw
    # down + lower lip up) when its joint motion of its landmarks stays below the noise, or
    # when it does not explain the landmarks significantly better than the identity modes
    # and the other groups do: the fit without it (re-solved) costs less than the chi-square
    # bound of its FAPs more (residual rows are in units of the prior's landmark noise)
    J = est._effective_jacobian(f)[:, est.idx]
    Ab = np.vstack([w[:, None] * np.hstack([J, Bx]), rows_prior,
                    np.hstack([gap_rows(f), np.zeros((len(lp), K))]) * wg])
    b = np.concatenate([w * d, np.zeros(len(rows_prior)), gap_p * wg])
    cost = float(np.sum((Ab @ np.concatenate([f[est.idx], c]) - b) ** 2))
    drop = []
    for fap_nums, lms in GROUPS:
        sel = np.zeros(68)
        idx = np.array(fap_nums) - 1
        if fap_nums[0] == 3:
            idx = np.array(OWN_FAPS[:11] + OWN_FAPS[23:]) - 1
        sel[idx] = f[idx]
        if np.abs(est.predict(sel)[lms]).max(initial=0.0) < min_move * iod:
            drop.append(idx)
            continue
        keep = np.concatenate([~np.isin(est.idx, idx), np.ones(K, bool)])
        sub = lsq_linear(Ab[:, keep], b, bounds=(lo[keep], hi[keep]), method="bvls").x
        gain = float(np.sum((Ab[:, keep] @ sub - b) ** 2)) - cost
        if gain < chi2.ppf(significance, len(idx)):
            drop.append(idx)
    for idx in drop:
        f[idx] = 0.0
    # a smile narrows the eyes (AU6: the cheeks push the lower lids up, the upper lids come
    # down a little), by an amount a photo's landmarks cannot tell from the shape of the
    # person's eyes (the identity modes explain it as well): where the lids' FAPs are not
    # estimated, they take what the smile implies, the joy preset's lids scaled by the smile
    k = _smile_share(f)
    if k > 0.0:
        for n, v in SMILE_LIDS.items():
            if f[n - 1] == 0.0:
                f[n - 1] = k * v
    f = FAPS.clamp(f).astype(np.float64)
    motion = est.predict(f)
    neutral68 = mu_x + (Bx @ c).reshape(68, 2)
    if k > 0.0:
        f, motion, neutral68 = _smile_corners(f, motion, neutral68, est, pr, face, k)
        f, motion, neutral68 = _smile_width(f, motion, neutral68, est, face, k)
    res = float(np.sqrt(np.mean(np.sum((neutral68 + motion - x) ** 2, 1)))) * 100.0 / iod
    words = _words(motion, face.frame.rot, iod, min_move)
    return OwnExpression(f.astype(np.float32),
                         {n: float(v / s) for n, v, s in zip(pr.names, c, pr.sigma, strict=True)},
                         res, neutral68, words)


#: the lids of a full smile (FAPs 19-22, FACS AU6; JAFFE's real smiles narrow the eyes by
#: 0.01-0.025 IOD from above and 0-0.025 from below) and its mouth corners' raise (FAPs
#: 12/13/59/60, MNS: the joy preset's). The upper lids are the joy preset's 19/20, the lower
#: ones half its 21/22. On JAFFE's 31 smiling photos neutralised, the lids' mean distance from
#: the same women's neutral photos falls from 0.0127 (upper) and 0.0115 (lower) IOD without
#: this to 0.0108 and 0.0092 (the photos' own: 0.0119, 0.0107). Joy's full 125 on the lower
#: lids measured 0.0088 but lowered the sample's neutral lower lids so far that closing its
#: eyes drew a thick, wavy lash line; twice joy's 60 on the upper lids (0.0098) made it stare
SMILE_LIDS = {19: 60.0, 20: 60.0, 21: 60.0, 22: 60.0}
#: how much further than the implied neutral's excess height the corners are brought down
#: (:func:`_smile_corners`): what the eye (and the landmark detector) takes for the mouth's
#: corner is the dark commissure, whose skin beside the lips follows the corner vertex about
#: a third to a half of the way (a corner FAP moving the mesh's corners 0.020 IOD on the
#: sample moves the detected ones 0.011). JAFFE's 21 open smiles neutralised, corners over
#: the lip line against the same women's neutral photos (re-detected, median of the
#: differences): +0.018 IOD without the correction, +0.012 at 1, +0.011 at 2, +0.005 at 2.5,
#: +0.002 at 3 (where the lifted folds of a smile left a thin dark line beside MK's corners
#: in sharp stills: 36 levels, test_creases' bar 28)
CORNER_LAG = 2.5
SMILE_CORNERS = 420.0


def _corner_height(points68: np.ndarray, ey: np.ndarray, iod: float) -> float:
    """How far the mouth corners (48, 54) lie above the inner lips' middle (62, 66), along
    the face's vertical ``ey`` (down), in inter-ocular distances."""
    y = points68 @ ey
    return float(0.5 * (y[62] + y[66]) - 0.5 * (y[48] + y[54])) / iod


def _smile_corners(f: np.ndarray, motion: np.ndarray, neutral68: np.ndarray,
                   est: FapEstimator, pr: NeutralPrior, face, k: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A smiling photo's neutral mouth corners brought down towards the prior's mean height
    above the lip line: by the smile's share ``k`` of their excess over it, :data:`CORNER_LAG`
    times on the mesh (as seen, the corners lag their vertices). The rest of the corners'
    rise is the smile's.

    A smile's corners rise far above the lip line, and from one photo their height splits
    between the expression (the corner FAPs) and the person's neutral mouth (the identity
    modes) as the fit's costs happen to weigh them. The neutralised smiles kept their corners
    up: JAFFE's 21 open smiles neutralised lie 0.018 IOD above the same women's own neutral
    photos (median of the differences, corners over the lip line, re-detected), the sample
    0.028 IOD above its lip line where JAFFE's neutral photos lie at 0.006; and a preset that
    turns the corners down started from a faint smile: on the sample, anger and fear were
    named joy by two blind raters out of two, sadness neutral (with the corners 0.02 IOD lower:
    neutral, surprise and sadness). The photo says nothing about its neutral corner height
    under a smile, so the prior's mean stands for it there. Returns ``f`` with the corner
    FAPs (12/13/59/60) raised by the difference, the motion it predicts, and the neutral
    landmarks (the photo's landmarks less the motion, as before).
    """
    ey = face.frame.rot[:, 1]
    iod = float(face.interocular)
    h = _corner_height(neutral68, ey, iod)
    h0 = _corner_height(pr.mean, np.array([0.0, 1.0]), 1.0)  # (canonical: y down, IOD 1)
    excess = k * (h - h0) * CORNER_LAG
    if excess <= 0.0:
        return f, motion, neutral68
    g = f.copy()
    g[[11, 12, 58, 59]] += excess * iod / float(face.fapu["MNS"])
    g = FAPS.clamp(g).astype(np.float64)
    motion_g = est.predict(g)
    # the landmarks stay what the photo shows: the neutral gives up what the motion takes
    return g, motion_g, neutral68 + motion - motion_g


#: how much a full smile widens the mouth (outer corners 48-54): JAFFE's 31 smiles against
#: the same women's neutral photos, median 1.29 (p90 1.43, max 1.61)
SMILE_WIDEN = 1.29


def _smile_width(f: np.ndarray, motion: np.ndarray, neutral68: np.ndarray,
                 est: FapEstimator, face, k: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A smiling photo's neutral mouth no narrower than real smiles imply: the corners'
    stretch (FAPs 6/7/53/54) scaled down so that the photo's mouth is at most
    ``1 + k (SMILE_WIDEN - 1)`` times as wide as the neutral one (``k`` the smile's share).

    How wide a smiling mouth is at rest, one photo does not say: the fit splits the width
    between the stretch and the prior's mouth-width mode as their costs happen to weigh, and
    the prior (ten JAFFE women) knows little of how mouths differ between people. The
    sample's broad smile came out 1.44 x its neutral mouth (the mesh's outer corners), past
    real smiles' p90, and blind raters called the neutralised lips pinched on every set: the
    real median stands for it there, as the prior's mean does for the corners' height
    (:func:`_smile_corners`). Returns ``f``, its motion and the neutral landmarks (the photo's
    landmarks less the motion, as before)."""
    ex = face.frame.rot[:, 0]
    cap = 1.0 + k * (SMILE_WIDEN - 1.0)
    g, motion_g = f, motion
    for _ in range(2):  # (the corners' lift moves them sideways a little too: once more)
        xs_photo = (neutral68 + motion) @ ex
        xs_rest = (neutral68 + motion - motion_g) @ ex
        w_photo = float(xs_photo[54] - xs_photo[48])
        w_rest = float(xs_rest[54] - xs_rest[48])
        if w_photo <= cap * w_rest * (1.0 + 1e-3) or w_photo <= w_rest:
            break
        s = (w_photo - w_photo / cap) / (w_photo - w_rest)
        g = g.copy()
        g[[5, 6, 52, 53]] *= s
        g = FAPS.clamp(g).astype(np.float64)
        motion_g = est.predict(g)
    if g is f:
        return f, motion, neutral68
    return g, motion_g, neutral68 + motion - motion_g


def _smile_share(f: np.ndarray) -> float:
    """How much of a full smile ``f`` shows: its mean mouth-corner raise over
    :data:`SMILE_CORNERS`, in [0, 1]."""
    raise_ = float(np.mean(f[[11, 12, 58, 59]]))
    return min(max(raise_ / SMILE_CORNERS, 0.0), 1.0)


def _words(motion: np.ndarray, rot: np.ndarray, iod: float, t: float) -> str:
    """Short words for what a landmark motion (68, 2) does, e.g. ``"smile, lips apart"``."""
    y = motion @ rot[:, 1] / iod  # along the face's vertical (down +), in IOD
    x = motion @ rot[:, 0] / iod
    words = []
    # a smile: the corners rise (against the head, whose motion the fit removed) and not below
    # the upper lip's middle. Against the lip line's middle alone (the mean of the inner lips)
    # a dropped jaw lifted the corners too: 16 of JAFFE's 30 surprise photos, 11 of 32 fear and
    # 10 of 29 disgust read "smile", 4 of 30 neutral ones; now 2, 0, 0 and 0 (smiles: 24 of 31
    # as before)
    rise = -0.5 * (y[48] + y[54])
    corners = rise + 0.5 * (y[62] + y[66])  # corners up against the lip line
    if rise > t and rise + y[62] > -t:
        words.append("smile")
    elif corners < -t:
        words.append("mouth corners down")
    gap = float(np.mean(y[[65, 66, 67]] - y[[63, 62, 61]]))
    if gap > 0.12:
        words.append("mouth open")
    elif gap > t:
        words.append("lips apart")
    if (x[54] - x[48]) > 2 * t:
        words.append("lips stretched")
    brows = -float(np.mean(y[17:27]))
    if brows > t:
        words.append("brows raised")
    elif brows < -t:
        words.append("brows lowered")
    if (x[22] - x[21]) < -t:
        words.append("brows drawn together")
    lids = float(np.mean(y[[43, 44, 37, 38]] - y[[47, 46, 41, 40]]))
    if lids > t:
        words.append("eyes narrowed")
    elif lids < -t:
        words.append("eyes wide")
    return ", ".join(words) if words else "neutral"
