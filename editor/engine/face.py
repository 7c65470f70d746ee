"""The ``Face``: a photo, its landmarks, the personalized mesh, FAPU, and rendering.

Data flow: photo -> :func:`detect_landmarks` -> :func:`fit_vertices` (personalized mesh) ->
:func:`measure_fapu` -> FAP vector -> :func:`deform_points` -> :func:`warp` -> image.

The photo's own expression (issue 21): a photo that smiles is the neutral face plus a FAP vector
f0 (:attr:`Face.expression`, estimated by :func:`~editor.engine.own_expression.estimate_own`).
The mesh fitted to the photo (:attr:`Face.vertices`) is where the texture comes from; the
neutral mesh N (:attr:`Face.neutral_vertices`) is that mesh with its landmarks moved to the
neutral the estimate implies (Laplacian editing, see ``Face._neutralise``), and every FAP vector
f is applied to it: ``deform(f) = N + D_N(f) + s(f) r`` where ``r = P - N - D_N(f0)`` is the part
of the photo's expression the FAP motion does not render and ``s(f)`` in [0, 1] the share of f0
that f holds (:meth:`Face.own_share`): f0 renders the photo unchanged, f = 0 the neutral face,
and a preset that does not go the photo's way (sadness on a smile) gets none of the photo's
smile back. FAPU are measured on the neutral mesh.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import InitVar, dataclass, field
from functools import cached_property, lru_cache
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from editor.errors import NoFaceError

from . import prefault
from .cheeks import apply_cheeks
from .chinboss import apply_chin_boss
from .creases import apply_creases
from .deform import (
    EXTRA_POINTS,
    LIP_PAIRS,
    DeformPlan,
    build_plan,
    deform_points,
    eye_state,
    guard,
    linear_positions,
)
from .faps import FAPS
from .fapu import measure_fapu
from .fitting import CLOSED_LIPS_MW, TEETH_RATIO, FaceFrame, fit_vertices, snap_inner_lips
from .grain import apply_grain
from .imageio import as_rgb8, load_image
from .jawband import jaw_map
from .landmarks import LandmarkDetector, Landmarks, detect_landmarks
from .layers import render_layers
from .lidskin import apply_lid_skin
from .liprims import apply_lip_rims
from .lipseal import apply_contact_line, apply_lip_seal, closing_share, seal_plan
from .liptone import apply_lip_tone
from .mesh import StandardMesh, signed_areas, standard_mesh
from .ownshade import apply_own_cheeks
from .transform import similarity_pairs, similarity_to, source_fit
from .warp import WarpPlan, WarpResult, map_step, warp

#: estimate_own rounds, each against the FAPU of the neutral the previous one implies
OWN_ROUNDS = 3

#: The last neutralisation's landmark map and Laplacian deformer, with what they were built
#: from (photo mesh, landmarks, the photo mesh's plan, the mesh): estimating a photo's own
#: expression neutralises the same photo mesh four times (~10 ms each to rebuild them)
_LAPLACIAN: list[tuple[tuple[np.ndarray, np.ndarray, Any, Any], tuple[Any, Any]]] = []

FapInput = Mapping[Any, float] | np.ndarray | None  # keys: FAP names or numbers


def _extra_points(mesh: StandardMesh, verts: np.ndarray, lm: Landmarks,
                  fapu: dict[str, float]) -> dict[str, np.ndarray]:
    """Positions of the non-mesh feature points: irises and tongue (behind the lips)."""
    f = {k: verts[i] for k, i in mesh.fdp.items()}
    frame = FaceFrame.from_points(lm.points)
    ex, ey = frame.rot[:, 0], frame.rot[:, 1]
    mw = fapu["MW"] * 1024
    tip = 0.5 * (f["2.2"] + f["2.3"])
    body = tip + 0.12 * mw * ey
    return {
        "3.5": np.array([lm.iris_left.cx, lm.iris_left.cy]),
        "3.6": np.array([lm.iris_right.cx, lm.iris_right.cy]),
        "6.1": tip, "6.2": body, "6.3": body + 0.3 * mw * ex, "6.4": body - 0.3 * mw * ex,
    }


@dataclass(eq=False)
class Face:
    """A photo with its personalized MPEG-4 mesh: FAP values in, deformed mesh or image out.

    Made by :meth:`from_image` (detect, fit, estimate the photo's own expression) or
    :meth:`from_landmarks`; immutable in use (``with_*`` methods return copies). FAP values
    are in FAPU and relative to the neutral face: a photo that shows an expression is
    neutralised first (:attr:`expression`), so ``render(None)`` is its neutral face.

    Parameters
    ----------
    image : numpy.ndarray
        (H, W, 3) uint8 RGB photo.
    landmarks : Landmarks
        The detected landmarks of its face.
    vertices : numpy.ndarray
        (V, 2) personalized mesh fitted to them.
    mesh : StandardMesh, optional
        The topology (default :func:`standard_mesh`).
    source : str, optional
        Where the photo came from (used in messages).
    expression : numpy.ndarray, optional
        (68,) FAP vector of the photo's own expression (default zeros: a neutral photo).

    Attributes
    ----------
    image : (H, W, 3) uint8 RGB photo (read-only)
    landmarks : Landmarks
    vertices : (V, 2) float32 personalized mesh of the photo, image pixels (x, y), y down
    neutral_vertices : (V, 2) float32 the neutralised mesh (``vertices`` for a neutral photo)
    fapu : dict name -> pixels per unit (MNS, MW, ENS, ES, IRISD; AU = 1e-5 rad)
    fdp : dict feature point -> vertex index
    expression : (68,) float32 the photo's own expression f0; ``expression_words`` says it

    Examples
    --------
    >>> from editor.core import Face
    >>> from editor.resources import SAMPLE_FACE
    >>> face = Face.from_image(SAMPLE_FACE)
    >>> face.expression_words  # the sample smiles
    'smile, lips apart, lips stretched'
    >>> sorted(face.fapu)
    ['AU', 'ENS', 'ES', 'IRISD', 'MNS', 'MW']
    >>> v = face.deform({"open_jaw": 400, 53: 120})  # names or numbers, FAPU
    >>> v.shape, v.dtype
    ((285, 2), dtype('float32'))
    >>> chin = face.fdp["2.1"]
    >>> bool(v[chin, 1] > face.deform(None)[chin, 1])  # the chin goes down (y grows)
    True
    >>> face.render({"open_jaw": 400}).shape  # the photo's size
    (512, 512, 3)
    """

    image: np.ndarray
    landmarks: Landmarks
    vertices: np.ndarray
    mesh: StandardMesh = field(default_factory=standard_mesh)
    source: str | None = None
    #: (68,) float32 FAP vector of the photo's own expression f0 (zeros: the photo is neutral)
    expression: np.ndarray = field(default_factory=lambda: np.zeros(68, np.float32))
    expression_words: str = "neutral"
    #: (68, 2) landmarks of the neutral face the own-expression estimate implies (prior mean
    #: shape + identity modes, :attr:`OwnExpression.neutral68`); None: the photo's landmarks
    #: moved back by f0's motion
    neutral_landmarks: np.ndarray | None = field(default=None, repr=False)
    #: (FAPU, plan) of ``vertices`` if the caller has them (a copy of a face declared neutral):
    #: the neutralisation starts from them instead of building them again
    photo_plan: InitVar[tuple[dict[str, float], DeformPlan] | None] = None

    def __post_init__(self, photo_plan: tuple[dict[str, float], DeformPlan] | None = None
                      ) -> None:
        self.image = np.ascontiguousarray(self.image)
        self.image.setflags(write=False)
        self.vertices = np.asarray(self.vertices, np.float32)
        self.frame = FaceFrame.from_points(self.landmarks.points)
        f0 = FAPS.clamp(FAPS.vector(self.expression))
        self.expression = f0
        self.expression.setflags(write=False)
        self.neutral_vertices, self.fapu, self.plan, self._offset = self._neutralise(
            f0, photo_plan=photo_plan)

    def _measure_fapu(self, vertices: np.ndarray) -> dict[str, float]:
        lm = self.landmarks
        irises = np.array([[lm.iris_right.cx, lm.iris_right.cy, lm.iris_right.r],
                           [lm.iris_left.cx, lm.iris_left.cy, lm.iris_left.r]])
        return measure_fapu(vertices.astype(np.float64), self.mesh, self.frame, irises)

    def _build(self, vertices: np.ndarray) -> tuple[dict[str, float], DeformPlan]:
        fapu = self._measure_fapu(vertices)
        plan = build_plan(self.mesh, vertices, self.frame, fapu,
                          _extra_points(self.mesh, vertices, self.landmarks, fapu))
        return fapu, plan

    def _neutralise(self, f0: np.ndarray, rounds: int = 3,
                    photo_plan: tuple[dict[str, float], DeformPlan] | None = None
                    ) -> tuple[np.ndarray, dict[str, float], DeformPlan, np.ndarray | None]:
        """Neutral mesh N, its FAPU and plan, and the offset ``r = P - (N + D_N(f0))`` over all
        points (None when f0 = 0).

        N is the photo's mesh P with its landmarks moved back by the motion f0 gives them on N
        (a fixed point: FAPU and influence are the neutral's), keeping P's local shape
        (Laplacian editing, :class:`~editor.engine.laplacian.LaplacianDeformer`, what no FAP moves
        fixed); the
        inner lips of the neutral meet. Undoing f0 vertex by vertex (``N = P - D_N(f0)``)
        folds where the FAP influence does not match the photo's expression: on an open smile
        the upper lip next to the corners drops below them, and the fold guard then keeps the
        corners up (the neutral still smiled).
        """
        # imported on first use (not a cycle): scipy.sparse and scipy.stats add ~0.4 s to
        # `import editor.core`
        from .laplacian import CONSTRAINT_WEIGHTS, MU, LaplacianDeformer, landmark_map

        P = self.vertices
        fapu, plan = self._build(P) if photo_plan is None else photo_plan
        if not f0.any():
            return P, fapu, plan, None
        V = len(P)
        target = plan.neutral.astype(np.float64)  # photo mesh + extra points at rest
        plan_p = plan
        pts = self.landmarks.points
        got = _LAPLACIAN[0] if _LAPLACIAN else None
        if (got is not None and got[0][2] is plan and got[0][3] is self.mesh
                and np.array_equal(got[0][0], P) and np.array_equal(got[0][1], pts)):
            A, lap = got[1]  # the same photo's mesh and plan: estimating its own expression
        else:
            A = landmark_map(P, self.mesh.triangles, self.mesh.names, self.landmarks.points)
            # what no FAP moves stays where the photo has it (margin, border, hair, ears): the
            # neutral differs from the photo only where expressions act, so a frame warps only
            # that region (a free margin moved every vertex: each frame warped the whole image)
            still = (~np.abs(plan.basis[:, :V]).any(axis=(0, 2))
                     | (self.mesh.regions == "border"))
            lap = LaplacianDeformer(P, self.mesh.triangles, A, still, MU, CONSTRAINT_WEIGHTS)
            _LAPLACIAN[:] = [((P.copy(), np.array(pts, copy=True), plan, self.mesh), (A, lap))]
        x = A @ target[:V]
        ey = self.frame.rot[:, 1]
        up, low = np.array([61, 62, 63]), np.array([67, 66, 65])
        N = target.copy()
        mouth_moves = bool(f0[2:13].any() or f0[50:60].any())  # jaw, inner and outer lips
        pairs = self.mesh.pairs
        u, lo = pairs[:, 0], pairs[:, 1]
        mouth = _mouth_pairs(self.mesh)
        for k in range(rounds):
            U = x - A @ (linear_positions(plan, f0)[:V] - N[:V])
            if self.neutral_landmarks is not None and mouth_moves:  # the estimate's neutral
                U[48:] = np.asarray(self.neutral_landmarks, np.float64)[48:]
            # a neutral mouth is closed: the lower lip meets the upper one (the upper lip sits
            # on the skull; the jaw and the lower lip close onto it)
            U[low] -= ((U[low] - U[up]) @ ey)[:, None] * ey
            N[:V] = lap.solve(U)
            if k == rounds - 1 and mouth.any():
                break  # (the inner lips are closed below: the plan is built after that)
            fapu, plan = self._build(N[:V].astype(np.float32))
            N[V:] = plan.neutral[V:]  # extra points are re-derived from the neutral mesh
        # lips and lids of the neutral meet but never cross, and the inner lips are closed
        # (between the landmarks the Laplacian leaves them a little apart); the offset absorbs
        # the difference
        cross = ((N[lo] - N[u]) @ ey < 0) & ~mouth
        if cross.any():
            mean = 0.5 * (N[u[cross]] + N[lo[cross]])
            N[u[cross]] = N[lo[cross]] = mean
        N[lo[mouth]] = N[u[mouth]]
        cross |= mouth
        # no triangle of the neutral folds: the outer-lip vertices of folded triangles (never
        # the inner lips, which meet, nor the landmark-held corners) relax towards their
        # neighbours; what still folds goes through the fold guard (it scales an upper/lower
        # pair together: no crossing returns)
        N[:V] = _unfold_lips(self.mesh, N[:V], plan_p.neutral_sigma)
        D = N[None, :V] - target[None, :V]
        Dg = guard(plan_p, D)
        if Dg is not D or cross.any():
            N[:V] = target[:V] + Dg[0]
            fapu, plan = self._build(N[:V].astype(np.float32))
            N[V:] = plan.neutral[V:]
        offset = target - linear_positions(plan, f0)
        return plan.neutral[:V].copy(), fapu, plan, offset

    def own_share(self, vec: np.ndarray) -> float:
        """How much of the photo's own expression f0 a FAP vector holds, in [0, 1]: its
        projection on f0 (FAP motion in pixels, FAPU x value). 1 at f0, 0 at the neutral and
        for expressions that do not go the photo's way (a smiling photo's sadness)."""
        u, f0, den = self._own_projection
        if den <= 0:
            return 0.0
        return min(max(float((u * np.asarray(vec, np.float64)) @ f0) / den, 0.0), 1.0)

    @cached_property
    def _own_projection(self) -> tuple[np.ndarray, np.ndarray, float]:
        """:meth:`own_share`'s weights (FAPU ** 2 per FAP), f0 and f0's squared norm in them
        (once per face: f0 is read-only)."""
        f0 = self.expression.astype(np.float64)
        u = self._fap_px ** 2
        return u, f0, float((u * f0) @ f0)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_image(cls, image: str | os.PathLike[str] | np.ndarray,
                   detector: LandmarkDetector | None = None, *,
                   own_expression: bool = True) -> Face:
        """Detect the face in a photo (path or RGB array) and fit the personalized mesh.

        Parameters
        ----------
        image : str, os.PathLike or numpy.ndarray
            A photo file, or an (H, W), (H, W, 3) or (H, W, 4) uint8 array in RGB order.
        detector : LandmarkDetector, optional
            Default: the bundled offline detector.
        own_expression : bool, default True
            Estimate the expression the photo already shows (:attr:`expression`), so that
            FAPs apply to the neutralised face; ``False`` declares the photo neutral (a
            performer's neutral photo, a JAFFE neutral).

        Returns
        -------
        Face

        Raises
        ------
        ImageError
            An unreadable, corrupt or too large file, or an unusable array.
        NoFaceError
            No face is found.

        Examples
        --------
        >>> from editor.core import Face
        >>> from editor.resources import SAMPLE_FACE
        >>> neutral = Face.from_image(SAMPLE_FACE, own_expression=False)
        >>> neutral.has_expression, neutral.expression_words
        (False, 'neutral')
        """
        if isinstance(image, np.ndarray):
            rgb, source = as_rgb8(image), None
        else:
            rgb, source = load_image(image), str(Path(image))
        # the first render's frame, faulted in on a thread while the landmarks and the mesh
        # are fitted (a large photo: see :mod:`prefault`)
        prefault.reserve(rgb.shape, rgb.dtype)
        try:
            lm = detect_landmarks(rgb, detector)
        except NoFaceError as e:
            raise NoFaceError(f"{source}: {e}" if source else str(e)) from None
        face = cls.from_landmarks(rgb, lm, source=source)
        return face.with_own_expression() if own_expression else face

    def with_own_expression(self) -> Face:
        """A copy whose :attr:`expression` is the estimate of what the photo shows."""
        from .own_expression import estimate_own  # on first use, as above

        base = self if not self.expression.any() else self.with_expression(None)
        own = estimate_own(base)
        if not own.faps.any():
            return base
        face = base.with_expression(own.faps, own.words)
        # FAPU are the neutral's (a smile widens the mouth and changes the mouth-nose
        # distance): the estimate is redone with the motion per unit of the neutral it implies,
        # else f0 renders a fraction of the photo's expression and neutralising leaves the rest
        for k in range(OWN_ROUNDS - 1):
            own = estimate_own(face)
            if not own.faps.any():
                return base
            if k < OWN_ROUNDS - 2:
                face = base.with_expression(own.faps, own.words)
        # the last estimate's vector as with_expression's face would hold it (that face's
        # neutral is not built: the face returned neutralises with the estimate's neutral
        # landmarks instead)
        f0 = FAPS.clamp(FAPS.vector(base.fap_vector(own.faps)))
        return Face(self.image, self.landmarks, self.vertices, self.mesh, self.source,
                    f0, own.words, own.neutral68, photo_plan=base._photo_plan())

    def with_expression(self, expression: FapInput, words: str | None = None) -> Face:
        """A copy with another own expression f0 (None or zeros: the photo is neutral)."""
        vec = None if expression is None else self.fap_vector(expression)
        if words is None:
            words = "neutral" if vec is None or not vec.any() else "edited"
        f0 = np.zeros(68, np.float32) if vec is None else vec
        return Face(self.image, self.landmarks, self.vertices, self.mesh, self.source, f0,
                    words, photo_plan=self._photo_plan())

    def _photo_plan(self) -> tuple[dict[str, float], DeformPlan] | None:
        """FAPU and plan of the photo's mesh if this face has them (declared neutral)."""
        return None if self.expression.any() else (dict(self.fapu), self.plan)

    @classmethod
    def from_landmarks(cls, rgb: np.ndarray, lm: Landmarks, source: str | None = None) -> Face:
        mesh = standard_mesh()
        h, w = rgb.shape[:2]
        closed, teeth = CLOSED_LIPS_MW.get(lm.detector, 0.05), TEETH_RATIO.get(lm.detector, 1.25)
        named, _ = fit_vertices(lm.points, (w, h))
        snap_inner_lips(named, rgb, lm.points, closed, teeth)
        verts = np.array([named[n] for n in mesh.names], np.float32)
        sig = signed_areas(verts.astype(np.float64), mesh.triangles)
        if lm.interocular < 6:
            raise NoFaceError(f"the face is too small ({lm.interocular:.1f} px between the eyes)")
        if (sig <= 0).any():
            verts = _relax(mesh, verts)
        return cls(rgb, lm, verts, mesh, source)

    def with_vertices(self, vertices: np.ndarray) -> Face:
        """A copy with an edited photo mesh (FAPU and rendering follow; same own expression)."""
        return Face(self.image, self.landmarks, np.asarray(vertices, np.float32), self.mesh,
                    self.source, self.expression, self.expression_words,
                    self.neutral_landmarks)

    # ------------------------------------------------------------------ API
    @property
    def triangles(self) -> np.ndarray:
        return self.mesh.triangles

    @property
    def fdp(self) -> dict[str, int]:
        """Feature point id -> vertex index (mesh vertices only)."""
        return self.mesh.fdp

    @property
    def has_expression(self) -> bool:
        """True when the photo is not neutral (its own expression is non-zero)."""
        return bool(self.expression.any())

    def _deform(self, vec: np.ndarray) -> np.ndarray:
        # the offset enters before the crossing rule and the fold guard, so lips/lids never
        # cross and no triangle folds for any vector (at f0 both leave the photo's mesh as is)
        # the offset is the part of the photo's expression the FAP motion does not render: it
        # comes with the share of f0 the vector holds (all of it at f0: the photo exactly)
        # except the lips' opening: the photo's own gap between the inner lips comes with the
        # share of the photo's opening the vector's FAPs make (a slit of a smile on a photo
        # that opens wider is not closed by the photo's offset; f0 still gives the photo)
        if self._offset is None:
            return deform_points(self.plan, vec)
        f = np.asarray(vec, np.float64)
        own = self.own_share(f)
        off = own * self._offset
        lip = self._lip_gap
        if lip is not None:
            up, lo, G, Gc, g0, d = lip
            s = np.minimum(np.maximum(_fap_gap(G, Gc, f) / g0, 0.0), 1.0)
            corr = (own - s)[:, None] * d
            off[up] += corr
            off[lo] -= corr
        return deform_points(self.plan, vec, off)

    @cached_property
    def _lip_gap(self) -> tuple[np.ndarray, ...] | None:
        """Inner-lip pairs whose FAP model opens at the photo's own expression: upper and
        lower vertex, the gap's FAP basis (P, 68) and its inner/outer lip pairs' shared part
        (P, 10) (see :func:`_fap_gap`), the gap at f0 over the neutral's (pixels), and the
        offset's half difference (P, 2) across each pair (along the face's vertical)."""
        if self._offset is None:
            return None
        names = self.mesh.names
        pairs = np.array([(u, lo) for u, lo in self.mesh.pairs if names[u].startswith("lip")])
        up, lo = pairs[:, 0], pairs[:, 1]
        ey = self.frame.rot[:, 1].astype(np.float64)
        basis = self.plan.basis.astype(np.float64)
        G = (basis[:, lo] - basis[:, up]) @ ey  # (68, P): gap opened per FAP unit
        G = G.T
        pb = self.plan.pair_basis.astype(np.float64).reshape(len(LIP_PAIRS), -1, 2)
        Gc = ((pb[:, lo] - pb[:, up]) @ ey).T  # (P, 10)
        g0 = _fap_gap(G, Gc, self.expression)
        keep = g0 > 1e-3  # the model opens these pairs at f0
        if not keep.any():
            return None
        half = 0.5 * ((self._offset[lo] - self._offset[up]) @ ey)
        d = half[:, None] * ey[None, :]
        k = keep
        return up[k], lo[k], G[k], Gc[k], g0[k], d[k]

    @cached_property
    def _fap_px(self) -> np.ndarray:
        """(68,) pixels per unit of each FAP (its FAPU on the neutral; 0 for FAPs 1-2)."""
        fapu = self.fapu
        return np.array([fapu.get(u, 0.0) if u is not None else 0.0 for u in _fap_units()])

    @cached_property
    def warp_plan(self) -> WarpPlan:
        return WarpPlan(self.image, self.vertices, self.mesh.triangles, self.mesh.holes,
                        band=self.mesh.regions == "margin",
                        map_step=map_step(self.interocular, self.image.shape))

    def fap_vector(self, faps: FapInput) -> np.ndarray:
        """(68,) float32 FAP vector from a mapping (names or numbers) or array, clamped."""
        return FAPS.clamp(FAPS.vector(faps))

    def deform(self, faps: FapInput) -> np.ndarray:
        """Deformed mesh vertices for FAP values in FAPU.

        Parameters
        ----------
        faps : mapping, numpy.ndarray or None
            ``{name or number: value}``, a (68,) vector (index i = FAP i+1) or None (all 0,
            the neutral face). Values outside a FAP's range are clamped to it.

        Returns
        -------
        numpy.ndarray
            (V, 2) float32 vertices, image pixels (x, y), y down; fold-free.

        Raises
        ------
        ValueError
            An unknown FAP, or a value that is not a finite number within ±1e9
            (:data:`~editor.engine.faps.MAX_VALUE`).

        Examples
        --------
        >>> import numpy as np
        >>> from editor.core import Face
        >>> from editor.resources import SAMPLE_FACE
        >>> face = Face.from_image(SAMPLE_FACE, own_expression=False)
        >>> np.array_equal(face.deform(None), face.vertices)  # neutral photo: FAP 0 = photo
        True
        >>> face.deform({"open_jaw": 1e12})
        Traceback (most recent call last):
        ...
        ValueError: FAP 'open_jaw': value 1000000000000.0 is not a finite number within ±1e+09
        """
        pts = self._deform(self.fap_vector(faps))
        return pts[: self.plan.n_vertices]

    def deform_all(self, faps: FapInput) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Deformed vertices (V, 2) and the extra feature points (irises 3.5/3.6, tongue 6.x)."""
        pts = self._deform(self.fap_vector(faps))
        V = self.plan.n_vertices
        return pts[:V], {k: pts[V + i] for i, k in enumerate(EXTRA_POINTS)}

    def feature_points(self, faps: FapInput = None) -> dict[str, list[float]]:
        """Every feature point (mesh FDPs + irises + tongue) after deformation, id -> [x, y]."""
        v, extra = self.deform_all(faps)
        out = {k: [float(v[i, 0]), float(v[i, 1])] for k, i in self.fdp.items()}
        out.update({k: [float(p[0]), float(p[1])] for k, p in extra.items()})
        return out

    def eye_state(self, faps: FapInput = None) -> np.ndarray:
        """Iris and pupil radii ``[[r, pupil_r] for 3.5, 3.6]`` after FAPs 27-30."""
        r = np.array([self.landmarks.iris_left.r, self.landmarks.iris_right.r])
        return eye_state(self.plan, self.fap_vector(faps), r)

    def render_full(self, faps: FapInput, creases: bool = True, sharp: bool = False
                    ) -> WarpResult:
        """Warp result with the opening masks, mouth interior and eyeballs composited."""
        vec = self.fap_vector(faps)
        pts = self._deform(vec)
        V = self.plan.n_vertices
        return self.render_mesh(pts[:V], pts[V:], vec, creases=creases, sharp=sharp)

    def render_mesh(self, vertices: np.ndarray, extra: np.ndarray | None = None,
                    faps: np.ndarray | None = None, creases: bool = True,
                    sharp: bool = False) -> WarpResult:
        """Render the photo on any deformed mesh (e.g. from cloning), layers included.

        ``vertices`` (V, 2) deformed mesh; ``extra`` (6, 2) irises/tongue points (default: where
        ``faps`` puts them); ``faps`` the (68,) vector that drives the eyes and tongue (default:
        zeros, the eyes and tongue at rest); ``creases``: darken the skin folds the deformation
        compresses (:mod:`creases`); ``sharp``: resample the photo bicubically (see
        :meth:`render`).
        """
        v = np.asarray(vertices, np.float32)
        vec = np.zeros(68, np.float32) if faps is None else np.asarray(faps, np.float32)
        if extra is None:
            extra = self._deform(vec)[self.plan.n_vertices:]
        tf = self.layer_transforms(v)
        w = warp(self.warp_plan, v, tf, cavity=False, hook=jaw_map(self, v),
                 interpolation=cv2.INTER_CUBIC if sharp else cv2.INTER_LINEAR)
        w = apply_lid_skin(self, apply_grain(self, w), v)
        # (the share of the photo's opening the mesh closes: the lip seal's and the contact
        # line's, computed once)
        sp = seal_plan(self)
        shut = None if sp is None else closing_share(sp, v)
        w = apply_lip_rims(self, apply_lip_tone(self, apply_lip_seal(self, w, v, shut), v), v)
        res = apply_contact_line(self, render_layers(self, w, v, extra, vec, tf), v, shut)
        if not creases:
            return res
        # (a smiling photo's lit cheek top is taken back where the mouth corners come down
        # from the photo's, a smile's shade drawn where they rise beyond it: never both on
        # one side in one frame)
        res = apply_own_cheeks(self, apply_chin_boss(self, apply_creases(self, res, v), v), v)
        return apply_cheeks(self, res, v)

    def layer_transforms(self, v: np.ndarray) -> dict[str, np.ndarray]:
        """2x3 source->destination maps of what lies behind the openings (see ``warp``).

        Each eyeball follows its two eye corners (a similarity); the mouth interior (teeth)
        follows the skull: a least-squares similarity of the inner eye corners and the nose.
        """
        # (the two eyes' two-point fits at once, :func:`similarity_pairs`: their values)
        anchors = self._layer_anchors
        eyes = similarity_pairs(self._eye_anchor_src,
                                np.asarray(v).take(self._eye_anchor_idx, 0))
        return {"eye_l": eyes[0], "eye_r": eyes[1],
                "mouth": similarity_to(self._mouth_anchor_fit, v[anchors["mouth"]])}

    @cached_property
    def _mouth_anchor_fit(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """:func:`source_fit` of the mouth's anchors on the photo's mesh (once per face)."""
        return source_fit(self.vertices[self._layer_anchors["mouth"]])

    @cached_property
    def _eye_anchor_idx(self) -> np.ndarray:
        """(2, 2) the eyes' anchors (:attr:`_layer_anchors`), left eye first."""
        return np.stack([self._layer_anchors["eye_l"], self._layer_anchors["eye_r"]])

    @cached_property
    def _eye_anchor_src(self) -> np.ndarray:
        """(2, 2, 2) float64: where the photo's mesh has them (once per face)."""
        return self.vertices.take(self._eye_anchor_idx, 0).astype(np.float64)

    @cached_property
    def _layer_anchors(self) -> dict[str, np.ndarray]:
        """Vertex indices each opening's layer follows (computed once per face)."""
        m = self.mesh
        out = {f"eye_{s}": np.array([m.index(f"eye_{s}_c0"), m.index(f"eye_{s}_c1")])
               for s in "lr"}
        out["mouth"] = np.array([self.fdp[k] for k in ("3.8", "3.11", "9.3", "9.15", "9.1",
                                                       "9.2")])
        return out

    def render(self, faps: FapInput, creases: bool = True, sharp: bool = False) -> np.ndarray:
        """The photo with the expression.

        Parameters
        ----------
        faps : mapping, numpy.ndarray or None
            As for :meth:`deform`.
        creases : bool, default True
            Add and remove skin folds (nasolabial, crow's feet, forehead, ...).
        sharp : bool, default False
            Resample the photo bicubically instead of bilinearly: the skin that moves keeps
            the photo's sharpness (bilinear sampling at fractional offsets halves the fine
            detail of a neutralised smile's cheeks), at ~1.3 x the render's cost. For stills
            that are exported; the live preview and video frames use the default.

        Returns
        -------
        numpy.ndarray
            (H, W, 3) uint8 RGB, the photo's size.

        Raises
        ------
        ValueError
            As for :meth:`deform`.

        Examples
        --------
        >>> from editor.core import Face, apply_preset
        >>> from editor.resources import SAMPLE_FACE
        >>> face = Face.from_image(SAMPLE_FACE)
        >>> img = face.render(apply_preset("surprise"))
        >>> img.shape, img.dtype
        ((512, 512, 3), dtype('uint8'))
        """
        return self.render_full(faps, creases=creases, sharp=sharp).image

    def crop_box(self, left: float, top: float, right: float, bottom: float
                 ) -> tuple[int, int, int, int]:
        """``(x0, y0, x1, y1)``: the detected face box grown by the given fractions of its width
        (left, right) and height (top, bottom), clipped to the photo."""
        b = self.landmarks.box
        w, h = float(b[2] - b[0]), float(b[3] - b[1])
        H, W = self.image.shape[:2]
        return (int(max(0, b[0] - left * w)), int(max(0, b[1] - top * h)),
                int(min(W, b[2] + right * w)), int(min(H, b[3] + bottom * h)))

    @cached_property
    def interocular(self) -> float:
        # (once per face: each plan reads it; the landmarks' norm of means costs ~0.1 ms)
        return self.landmarks.interocular


def _fap_gap(G: np.ndarray, Gc: np.ndarray, vec: np.ndarray) -> np.ndarray:
    """Inner-lip gaps (P,) the FAP model opens for ``vec``, px: its linear basis ``G`` (P, 68)
    less the inner/outer lip pairs' shared part ``Gc`` (P, 10) moved once, not twice (as
    ``deform._linear`` renders it; without it a vector setting both, such as joy or a
    smiling photo's f0, was credited with up to a quarter more opening than it makes)."""
    f = np.asarray(vec, np.float64)
    # (the ten pairs' shared part on Python floats: numpy's values, sign(a) min(|a|, |b|)
    # where a b > 0, else 0, without eight array calls on ten values)
    v = f.tolist()
    common = [math.copysign(min(abs(v[i]), abs(v[j])), v[i]) if v[i] * v[j] > 0 else 0.0
              for i, j in _LIP_PAIR_LIST]
    return G @ f - Gc @ np.array(common)


#: :data:`~editor.engine.deform.LIP_PAIRS` as Python pairs of indices
_LIP_PAIR_LIST = [(int(a), int(b)) for a, b in LIP_PAIRS]


def _unfold_lips(mesh: StandardMesh, verts: np.ndarray, sigma0: np.ndarray,
                 iters: int = 100) -> np.ndarray:
    """Move the lip vertices of folded triangles (signed area below 10 % of ``sigma0``, the
    photo mesh's) towards the mean of their neighbours: outer lips, and the closed inner lips
    together (the lower one on the upper one); the corners stay."""
    movable, pairs, e, deg = _lip_topology(mesh)
    v = np.asarray(verts, np.float64).copy()
    tri = mesh.triangles
    for _ in range(iters):
        bad = signed_areas(v, tri) * np.sign(sigma0) < 0.1 * np.abs(sigma0)
        if not bad.any():
            break
        sel = np.zeros(len(v), bool)
        sel[tri[bad].ravel()] = True
        sel &= movable
        if not sel.any():
            break
        avg = _neighbour_mean(e, v, deg)
        v[sel] += 0.5 * (avg[sel] - v[sel])
        v[pairs[:, 1]] = v[pairs[:, 0]]  # the lower inner lip stays on the upper one
    return v


@lru_cache(maxsize=1)
def _fap_units() -> tuple[str | None, ...]:
    """The FAPU name of each FAP (index i = FAP i+1; None for FAPs 1-2) from the static
    table, looked up once (not through ``FAPS[...]``'s key checks for every face)."""
    return tuple(FAPS[i + 1].unit if i >= 2 else None for i in range(68))


@lru_cache(maxsize=4)
def _mouth_pairs(mesh: StandardMesh) -> np.ndarray:
    """(P,) bool: which of the mesh's upper/lower pairs are the mouth's inner lips."""
    m = np.isin(mesh.pairs[:, 0], mesh.holes["mouth"])
    m.setflags(write=False)
    return m


@lru_cache(maxsize=4)
def _lip_topology(mesh: StandardMesh) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """What :func:`_unfold_lips` needs of the mesh (once per mesh, not per neutralisation):
    the lip vertices it may move, the mouth's inner-lip pairs, the edges and the vertex
    degrees."""
    names = np.array(mesh.names)
    movable = (np.char.startswith(names, "lipo_") | np.char.startswith(names, "lipb_")
               | np.char.startswith(names, "lipi_u")) & \
        ~np.isin(np.arange(len(names)), [mesh.fdp[k] for k in ("8.3", "8.4", "2.4", "2.5")])
    pairs = mesh.pairs[_mouth_pairs(mesh)]
    e = mesh.edges()
    deg = np.bincount(e.ravel(), minlength=len(names)).astype(np.float64)
    for a in (movable, pairs, e, deg):
        a.setflags(write=False)
    return movable, pairs, e, deg


def _neighbour_mean(edges: np.ndarray, v: np.ndarray, deg: np.ndarray) -> np.ndarray:
    """(V, 2) mean position of each vertex's mesh neighbours (``deg``: neighbour counts)."""
    acc = np.zeros_like(v)
    np.add.at(acc, edges[:, 0], v[edges[:, 1]])
    np.add.at(acc, edges[:, 1], v[edges[:, 0]])
    return acc / np.maximum(deg, 1)[:, None]


def _relax(mesh: StandardMesh, verts: np.ndarray, iters: int = 200) -> np.ndarray:
    """Untangle inverted triangles of a fitted mesh by moving only the free vertices.

    Free vertices (cheeks, jaw, forehead interior, margin) move towards the mean of their
    neighbours until every triangle has a positive area. Feature curves stay where fitted.
    """
    free_regions = ("cheek", "jaw", "forehead", "margin", "ear")
    free = np.isin(mesh.regions, free_regions)
    for n in ("hair_",):
        free &= ~np.char.startswith(np.array(mesh.names), n)
    e = mesh.edges()
    v = verts.astype(np.float64).copy()
    deg = np.bincount(e.ravel(), minlength=len(v)).astype(np.float64)
    for _ in range(iters):
        sig = signed_areas(v, mesh.triangles)
        if (sig > 0).all():
            break
        avg = _neighbour_mean(e, v, deg)
        v[free] += 0.5 * (avg[free] - v[free])
    return v.astype(np.float32)
