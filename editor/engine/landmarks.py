"""Offline facial landmarks: the detector interface, the detectors, and the irises.

Two detectors: the default :class:`~editor.engine.facemesh.MediaPipeDetector` (MediaPipe's
Apache-2.0 face detector, 468-point mesh and iris models, shipped in the package) and the
optional :class:`DlibDetector` (dlib's 68-point model, non-commercial terms; ``pip install
fap-studio[dlib]``). :func:`set_default_detector` picks the process-wide default by name
(``mediapipe`` or ``dlib``; the CLI's ``--detector`` and the GUI's setting call it); the
``FAP_STUDIO_DETECTOR`` environment variable sets the initial choice.

Coordinates are image pixels, ``(x, y)`` with x to the right and y down, float32.

The 68-point layout is iBUG 300-W's (the order dlib's ``shape_predictor_68_face_landmarks``
uses): 0-16 jaw line from the image's left to its right, 17-21 and 22-26 the brows (image
left, image right), 27-30 nose bridge down to the tip, 31-35 nose base, 36-41 and 42-47 the eyes,
48-59 the outer lip contour, 60-67 the inner lip contour. The image's left is the subject's
right: point 36 is the subject's right eye's outer corner (MPEG-4 FDP 3.12).

Every detector gives these 68 points (the mesh through the documented table
:data:`editor.engine.facemesh.MESH_TO_68`, its inner-lip middles then moved onto the visible
opening: :func:`inner_lips_on_opening_68`). The MediaPipe detector adds the dense 468-point mesh
(``Landmarks.mesh``; its inner-lip contour on the photo's inner lip edges,
:mod:`editor.engine.lip_edges`), the iris model's circles and where each pupil shows (the
centre of the circle's part inside the lids, :func:`visible_iris_centre`). dlib gives no iris
(FDP 3.5 / 3.6): :func:`locate_iris` finds the dark disc inside each eye opening (a vectorised
circular template search, in the spirit of the paper's Canny-edge approach).
"""

from __future__ import annotations

import importlib.util
import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from editor.errors import FapStudioError, NoFaceError

from .facemesh import CONTOURS, FDP_FROM_MESH, MediaPipeDetector, points68_from_mesh
from .threads import Pending

# OpenCV is imported by the functions that use it (here, in .facemesh and .lip_edges): the
# editor's Settings menu reads the detector choice below while the window is built, before any
# photo is opened (issue 15, gui_ready_s).

#: Detection runs on a copy whose longer side is at most this many pixels.
DETECT_MAX_SIDE = 800

#: The subject's left/right mirror partner of every iBUG-68 index.
MIRROR_68 = np.array(
    list(range(16, -1, -1))
    + list(range(26, 21, -1)) + list(range(21, 16, -1))
    + [27, 28, 29, 30, 35, 34, 33, 32, 31]
    + [45, 44, 43, 42, 47, 46, 39, 38, 37, 36, 41, 40]
    + [54, 53, 52, 51, 50, 49, 48, 59, 58, 57, 56, 55]
    + [64, 63, 62, 61, 60, 67, 66, 65]
)

#: MPEG-4 feature points that coincide with (or are the mean of) iBUG-68 points.
#: Face's own left = image right.
FDP_FROM_68: dict[str, tuple[int, ...]] = {
    "2.1": (8,), "2.2": (62,), "2.3": (66,), "2.4": (64,), "2.5": (60,),
    "2.10": (57, 8, 8), "2.11": (10,), "2.12": (6,), "2.13": (12,), "2.14": (4,),
    "3.1": (43, 44), "3.2": (37, 38), "3.3": (46, 47), "3.4": (40, 41),
    "3.7": (45,), "3.8": (39,), "3.11": (42,), "3.12": (36,),
    "4.1": (22,), "4.2": (21,), "4.3": (24,), "4.4": (19,), "4.5": (26,), "4.6": (17,),
    "8.1": (51,), "8.2": (57,), "8.3": (54,), "8.4": (48,),
    "8.9": (50,), "8.10": (52,),
    "9.1": (35,), "9.2": (31,), "9.3": (30,), "9.15": (33,), "9.12": (29,),
    "9.4": (32,), "9.5": (34,),
}


@dataclass(frozen=True)
class Iris:
    """An iris circle in image pixels."""

    cx: float
    cy: float
    r: float

    def as_list(self) -> list[float]:
        return [round(self.cx, 2), round(self.cy, 2), round(self.r, 2)]


@dataclass(frozen=True)
class Landmarks:
    """Detected landmarks of one face.

    Attributes
    ----------
    points : (68, 2) float32
        iBUG-68 points, image pixels (x, y), y down.
    box : (4,) float32
        Face box ``x0, y0, x1, y1`` in image pixels.
    iris_left, iris_right : Iris
        The subject's left (image right, FDP 3.5) and right (FDP 3.6) iris.
    detector : str
        Name of the detector that produced them.
    mesh : (468, 2) float32 or None
        The MediaPipe face mesh (its canonical vertex order), None from dlib.
    confidence : float
        The detector's face-presence probability (1.0 when it gives none).
    pupil_left, pupil_right : tuple of float or None
        The centre of the visible part of each iris (image pixels), below the circle's centre
        when the upper lid covers the iris's top; None: the circle's centre
        (:meth:`pupils`).

    Examples
    --------
    >>> from editor.engine.imageio import load_image
    >>> from editor.resources import SAMPLE_FACE
    >>> lm = detect_landmarks(load_image(SAMPLE_FACE))
    >>> lm.points.shape, lm.mesh.shape, lm.detector
    ((68, 2), (468, 2), 'mediapipe-468')
    >>> 40 < lm.interocular < 48  # pixels between the eye centres of the sample face
    True
    >>> lm.iris_left.cx > lm.iris_right.cx  # the subject's left eye is on the image's right
    True
    """

    points: np.ndarray
    box: np.ndarray
    iris_left: Iris
    iris_right: Iris
    detector: str = "dlib-68"
    mesh: np.ndarray | None = None
    confidence: float = 1.0
    pupil_left: tuple[float, float] | None = None
    pupil_right: tuple[float, float] | None = None

    def pupils(self) -> dict[str, tuple[float, float]]:
        """Where the photo shows each pupil: the centre of the iris's visible part ("3.5" the
        subject's left, "3.6" the right). With the MediaPipe detector the iris circle clipped by
        the lid contours (:func:`visible_iris_centre`); without (dlib, whose circle search
        scores visible pixels only) the iris circles' centres. The circles themselves (the
        eyeball's iris, which gaze rendering moves) keep the full circle's centre."""
        return {"3.5": self.pupil_left or (self.iris_left.cx, self.iris_left.cy),
                "3.6": self.pupil_right or (self.iris_right.cx, self.iris_right.cy)}

    def fdp_points(self) -> dict[str, tuple[float, float]]:
        """MPEG-4 feature points derived directly from the detection (incl. 3.5, 3.6): from the
        68 points (:data:`FDP_FROM_68`), and with a mesh from its vertices
        (:data:`~editor.engine.facemesh.FDP_FROM_MESH`)."""
        out = {k: tuple(map(float, self.points[list(v)].mean(0))) for k, v in FDP_FROM_68.items()}
        if self.mesh is not None:  # the mesh's own vertices where it has the point
            out.update({k: tuple(map(float, self.mesh[list(v)].mean(0)))
                        for k, v in FDP_FROM_MESH.items()})
        out["3.5"] = (self.iris_left.cx, self.iris_left.cy)
        out["3.6"] = (self.iris_right.cx, self.iris_right.cy)
        return out  # type: ignore[return-value]

    @property
    def interocular(self) -> float:
        """Distance between the two eye centres (mean of each eye's six points), pixels."""
        return float(np.linalg.norm(self.points[42:48].mean(0) - self.points[36:42].mean(0)))


class LandmarkDetector(Protocol):
    """What FAP Studio needs from a landmark detector.

    ``detect`` takes an RGB uint8 image and returns the 68 points (iBUG order) and the face box
    of the largest face, or raises :class:`NoFaceError`.

    Attributes
    ----------
    name : str
        The detector's name as :class:`Landmarks` records it (``"mediapipe-468"``,
        ``"dlib-68"``).

    Examples
    --------
    >>> import numpy as np
    >>> det = default_detector()  # MediaPipe's models unless $FAP_STUDIO_DETECTOR says dlib
    >>> det.name
    'mediapipe-468'
    >>> det.detect(np.full((200, 200, 3), 128, np.uint8))
    Traceback (most recent call last):
    ...
    editor.errors.NoFaceError: no face found in the image
    """

    name: str

    def detect(self, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...


def _models_dir() -> Path:
    spec = importlib.util.find_spec("face_recognition_models")
    if spec is None or not spec.submodule_search_locations:
        raise FapStudioError(
            "the face-recognition-models package is not installed (pip install "
            "face-recognition-models); it holds the 68-point landmark model"
        )
    return Path(list(spec.submodule_search_locations)[0]) / "models"


@lru_cache(maxsize=1)
def _dlib_models() -> tuple[Any, Any]:  # dlib has no type information
    import dlib

    path = _models_dir() / "shape_predictor_68_face_landmarks.dat"
    if not path.exists():
        raise FapStudioError(f"landmark model missing: {path}")
    return dlib.get_frontal_face_detector(), dlib.shape_predictor(str(path))


class DlibDetector:
    """dlib HOG face detector + the 68-point shape predictor from ``face-recognition-models``.

    Detection runs on a copy downscaled to at most :data:`DETECT_MAX_SIDE` pixels (keeping the
    aspect ratio); the shape predictor then runs on the full-resolution image. When several faces
    are found, the largest is taken (ties within 25 % of area go to the higher detector score).
    """

    name = "dlib-68"

    def detect(self, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        import cv2
        import dlib

        detector, predictor = _dlib_models()
        h, w = rgb.shape[:2]
        grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
        scale = min(1.0, DETECT_MAX_SIDE / max(h, w))
        small = grey if scale == 1.0 else cv2.resize(
            grey, (max(1, round(w * scale)), max(1, round(h * scale))), interpolation=cv2.INTER_AREA
        )
        # Small images (e.g. 256 px JAFFE faces) need one upsampling step to find ~80 px faces.
        upsample = 1 if max(small.shape) < 640 else 0
        rects, scores, _ = detector.run(small, upsample, 0.0)
        if len(rects) == 0 and upsample == 0:
            rects, scores, _ = detector.run(small, 1, 0.0)
        if len(rects) == 0:
            raise NoFaceError("no face found in the image")
        boxes = np.array([[r.left(), r.top(), r.right(), r.bottom()] for r in rects], np.float64)
        areas = (boxes[:, 2] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 1])
        cand = np.flatnonzero(areas >= 0.75 * areas.max())
        best = cand[np.argmax(np.asarray(scores)[cand])]
        box = boxes[best] / scale
        rect = dlib.rectangle(*(int(round(v)) for v in box))
        shape = predictor(grey, rect)
        pts = np.array([(p.x, p.y) for p in shape.parts()], np.float32)
        return pts, box.astype(np.float32)


#: Detector names accepted by :func:`get_detector` (``--detector``, the GUI setting).
DETECTOR_NAMES = ("mediapipe", "dlib")
#: Environment variable naming the initial default detector.
DETECTOR_ENV = "FAP_STUDIO_DETECTOR"

_DETECTORS: dict[str, LandmarkDetector] = {}
_DEFAULT_NAME: str | None = None
_EXPLICIT = False


def dlib_available() -> bool:
    """True when the optional dlib extra (dlib and face-recognition-models) is installed."""
    return all(importlib.util.find_spec(m) is not None
               for m in ("dlib", "face_recognition_models"))


def get_detector(name: str) -> LandmarkDetector:
    """The (shared) detector called ``name`` (:data:`DETECTOR_NAMES`); FapStudioError for an
    unknown name or dlib when its extra is not installed."""
    key = name.strip().lower()
    if key not in DETECTOR_NAMES:
        raise FapStudioError(f"unknown landmark detector {name!r} (choose from "
                             f"{', '.join(DETECTOR_NAMES)})")
    if key == "dlib" and not dlib_available():
        raise FapStudioError("the dlib detector is not installed (pip install "
                             "'fap-studio[dlib]'); the default mediapipe detector needs nothing")
    if key not in _DETECTORS:
        _DETECTORS[key] = MediaPipeDetector() if key == "mediapipe" else DlibDetector()
    return _DETECTORS[key]


def set_default_detector(name: str, explicit: bool = True) -> None:
    """Make ``name`` the detector used when none is given (checked like :func:`get_detector`).
    ``explicit``: chosen for this session (the CLI's ``--detector``), which a stored GUI
    preference does not override."""
    global _DEFAULT_NAME, _EXPLICIT
    get_detector(name)
    _DEFAULT_NAME = name.strip().lower()
    _EXPLICIT = _EXPLICIT or explicit


def default_detector_is_explicit() -> bool:
    """True when the session's detector was chosen by ``--detector`` or the environment."""
    return _EXPLICIT or bool(os.environ.get(DETECTOR_ENV, "").strip())


def default_detector_name() -> str:
    """The name of the current default detector (``$FAP_STUDIO_DETECTOR`` or mediapipe)."""
    if _DEFAULT_NAME is not None:
        return _DEFAULT_NAME
    return os.environ.get(DETECTOR_ENV, "").strip().lower() or "mediapipe"


def default_detector() -> LandmarkDetector:
    """The detector used when none is given (MediaPipe's face mesh unless changed)."""
    return get_detector(default_detector_name())


def _eye_polygon(points: np.ndarray, eye: int) -> np.ndarray:
    return points[36 + 6 * eye : 42 + 6 * eye]


#: The largest eye width (px) :func:`locate_iris` searches at; wider eyes are downsampled to it
#: (the sample face at 3x: 53 px, unchanged; a 24 MP portrait: ~140 px).
IRIS_WORK_WIDTH = 64.0


def locate_iris(rgb: np.ndarray, points: np.ndarray, eye: int,
                near: Iris | None = None) -> Iris:
    """Find the iris circle of one eye (``eye`` 0 = image left = subject's right).

    The iris is the darkest disc in the eye opening whose rim is brighter outside than inside.
    Candidate radii span 0.17-0.30 of the eye width (an adult iris is ~0.4 of the palpebral
    fissure's width). Each candidate disc is scored on the pixels visible in the opening only, so
    lids covering part of the iris do not bias it. Falls back to the opening's centre with a
    radius of 0.21 eye widths when the eye is too small or closed.

    With ``near`` (the iris model's circle) only the radius is searched, at ``near``'s centre,
    over 0.9-1.25 times its radius: the model's centres are the better ones (the free search
    can slide into a lower lid's shadow), but its radii are 3-10 % short of the dark disc's
    edge on clearly visible irises (the sample face, JAFFE's neutral eyes, drawn at 8x). Falls
    back to ``near`` itself.
    """
    import cv2

    poly = _eye_polygon(points, eye).astype(np.float32)
    c0, c1 = poly[0], poly[3]
    width = float(np.linalg.norm(c1 - c0))
    centre = poly.mean(0)
    fallback = near or Iris(float(centre[0]), float(centre[1]), 0.21 * max(width, 1.0))
    if width < 8:
        return fallback
    # work at an eye width of >= 40 px (small eyes upsampled). The free search of a large eye
    # (a 24 MP portrait's are ~140 px wide) runs downsampled to IRIS_WORK_WIDTH, where the disc
    # filters over the whole opening cost ~ width^4 and the dark disc's edge is as well found
    # (the radii searched are the same fractions of the eye); the radius search at ``near``'s
    # centre stays at full size but sums each disc and ring at that one pixel only
    at_centre = near is not None and width > IRIS_WORK_WIDTH
    s = (max(1.0, 40.0 / width) if width <= IRIS_WORK_WIDTH or at_centre
         else IRIS_WORK_WIDTH / width)
    pad = int(0.5 * width) + 2
    x0, y0 = int(max(0, poly[:, 0].min() - pad)), int(max(0, poly[:, 1].min() - pad))
    x1 = int(min(rgb.shape[1], poly[:, 0].max() + pad))
    y1 = int(min(rgb.shape[0], poly[:, 1].max() + pad))
    roi: np.ndarray = cv2.cvtColor(rgb[y0:y1, x0:x1], cv2.COLOR_RGB2GRAY).astype(np.float32)
    if s > 1.0:
        roi = cv2.resize(roi, None, fx=s, fy=s, interpolation=cv2.INTER_CUBIC)
    elif s < 1.0:
        roi = cv2.resize(roi, None, fx=s, fy=s, interpolation=cv2.INTER_AREA)
    mask = np.zeros(roi.shape, np.uint8)
    cv2.fillPoly(mask, [np.round((poly - (x0, y0)) * s * 16).astype(np.int32)], 1, cv2.LINE_8, 4)
    if mask.sum() < 20:
        return fallback
    m = mask.astype(np.float32)
    dark = (255.0 - cv2.GaussianBlur(roi, (0, 0), 0.8)) * m
    w = width * s
    best: tuple[float, float, float, float] | None = None
    radii = (np.linspace(0.17, 0.30, 8) * w if near is None
             else np.linspace(0.9, 1.25, 15) * near.r * s)
    centre_px = None
    if at_centre and near is not None:
        centre_px = (int(round(near.cx - x0)), int(round(near.cy - y0)))
        if not (0 <= centre_px[1] < dark.shape[0] and 0 <= centre_px[0] < dark.shape[1]):
            return near
    for r in radii:
        k = int(np.ceil(1.45 * r))
        yy, xx = np.mgrid[-k : k + 1, -k : k + 1].astype(np.float32)
        d = np.hypot(xx, yy)
        disc = (d <= r).astype(np.float32)
        ring = ((d > r) & (d <= 1.4 * r)).astype(np.float32)
        if centre_px is not None:
            xc, yc = centre_px
            # the four filters' values at the centre (zeros outside the ROI, as their border)
            wd, wm = _window(dark, yc, xc, k), _window(m, yc, xc, k)
            c_sd, c_sm = float((wd * disc).sum()), float((wm * disc).sum())
            c_rd, c_rm = float((wd * ring).sum()), float((wm * ring).sum())
            c_vis = min(max(c_sm / float(disc.sum()), 0.0), 1.0)
            val = ((c_sd / max(c_sm, 1.0) - 0.6 * c_rd / max(c_rm, 1.0)) * np.sqrt(c_vis)
                   * (c_vis > 0.25) * float(mask[yc, xc] > 0))
            if best is None or val > best[0]:
                best = (val, float(xc), float(yc), float(r))
            continue
        sd = cv2.filter2D(dark, -1, disc, borderType=cv2.BORDER_CONSTANT)
        sm = cv2.filter2D(m, -1, disc, borderType=cv2.BORDER_CONSTANT)
        rd = cv2.filter2D(dark, -1, ring, borderType=cv2.BORDER_CONSTANT)
        rm = cv2.filter2D(m, -1, ring, borderType=cv2.BORDER_CONSTANT)
        inside = sd / np.maximum(sm, 1.0)
        outside = rd / np.maximum(rm, 1.0)
        # Contrast, weighted by how much of the disc is visible; centre must be in the opening.
        vis = np.clip(sm / disc.sum(), 0.0, 1.0)
        score = (inside - 0.6 * outside) * np.sqrt(vis) * (vis > 0.25) * (mask > 0)
        if near is None:
            i = int(np.argmax(score))
        else:
            xi_, yi_ = (int(round((near.cx - x0) * s)), int(round((near.cy - y0) * s)))
            if not (0 <= yi_ < score.shape[0] and 0 <= xi_ < score.shape[1]):
                return near
            i = yi_ * score.shape[1] + xi_
        val = float(score.flat[i])
        if best is None or val > best[0]:
            yi, xi = divmod(i, score.shape[1])
            best = (val, float(xi), float(yi), float(r))
    if best is None or best[0] <= 0:
        return fallback
    _, xi, yi, r = best
    if near is not None:
        return Iris(near.cx, near.cy, r / s)
    return Iris(x0 + xi / s, y0 + yi / s, r / s)


def _window(a: np.ndarray, y: int, x: int, k: int) -> np.ndarray:
    """``a[y - k : y + k + 1, x - k : x + k + 1]``, zeros where it leaves ``a``."""
    out = np.zeros((2 * k + 1, 2 * k + 1), a.dtype)
    ya, yb = max(y - k, 0), min(y + k + 1, a.shape[0])
    xa, xb = max(x - k, 0), min(x + k + 1, a.shape[1])
    out[ya - y + k:yb - y + k, xa - x + k:xb - x + k] = a[ya:yb, xa:xb]
    return out


def visible_iris_centre(iris: Iris, upper: np.ndarray, lower: np.ndarray,
                        samples: int = 48) -> tuple[float, float]:
    """The centroid of the part of the iris circle that lies inside the eye opening.

    ``upper`` and ``lower`` are the lid contours (n, 2) from one eye corner to the other (the
    same two corners, either order). The disc is cut into ``samples`` vertical strips in the
    frame of the eye-corner line; each strip's chord is clipped to the span between the lids
    there, and the strips' areas and centres give the centroid. A lid over the iris's top moves
    the point down, one over its bottom moves it up; a fully visible iris gives its own centre,
    and a closed eye (nothing visible) the circle's centre.
    """
    up = np.asarray(upper, np.float64).reshape(-1, 2)
    lo = np.asarray(lower, np.float64).reshape(-1, 2)
    d = up[-1] - up[0]
    n = float(np.hypot(*d))
    if n < 1e-9 or iris.r <= 0:
        return iris.cx, iris.cy
    ex = d / n
    ex = ex if ex[0] >= 0 else -ex  # the eye's x axis points to the image's right
    ey = np.array([-ex[1], ex[0]])  # and its y axis down
    rot = np.stack([ex, ey])
    o = np.array([iris.cx, iris.cy])
    u_up, u_lo = (up - o) @ rot.T, (lo - o) @ rot.T
    u_up, u_lo = u_up[np.argsort(u_up[:, 0])], u_lo[np.argsort(u_lo[:, 0])]
    r = float(iris.r)
    x = (np.arange(samples) + 0.5) / samples * 2 * r - r
    half = np.sqrt(np.maximum(r * r - x * x, 0.0))
    top = np.maximum(-half, np.interp(x, u_up[:, 0], u_up[:, 1], left=np.inf, right=np.inf))
    bottom = np.minimum(half, np.interp(x, u_lo[:, 0], u_lo[:, 1], left=-np.inf, right=-np.inf))
    w = np.clip(bottom - top, 0.0, None)
    area = float(w.sum())
    if area <= 1e-6 * r:
        return iris.cx, iris.cy
    c = np.array([(x * w).sum(), (0.5 * (top + bottom) * w).sum()]) / area
    p = o + c @ rot
    return float(p[0]), float(p[1])


def inner_lips_on_opening_68(rgb: np.ndarray, points: np.ndarray, detector: str) -> np.ndarray:
    """The 68 points with the inner-lip middles (61-63, 65-67) on the photo's visible mouth
    opening, as iBUG's annotation (and dlib) place them: on a mouth showing teeth the teeth's
    edges, on a closed one the lip line. The mesh's inner-lip contour is each lip's own edge
    instead (the upper one above the shadow over the teeth), so the points are moved along the
    face's vertical onto the inner lips of a mesh fitted and snapped to the image
    (:func:`~editor.engine.fitting.snap_inner_lips`)."""
    from .fitting import (
        CLOSED_LIPS_MW,
        TEETH_RATIO,
        fit_vertices,
        inner_lips_on_opening,
        snap_inner_lips,
    )

    h, w = rgb.shape[:2]
    named, _ = fit_vertices(points, (w, h))
    snap_inner_lips(named, rgb, points, CLOSED_LIPS_MW.get(detector, 0.05),
                    TEETH_RATIO.get(detector, 1.25))
    return inner_lips_on_opening(points, named)


def _from_mesh(det: MediaPipeDetector, found: Any, rgb: np.ndarray) -> Landmarks:
    pts68 = points68_from_mesh(found.mesh)
    # the model's centres, the radii at the dark disc's edge (see locate_iris)
    right, left = _irises(rgb, pts68, Iris(*found.iris_image_left),
                          Iris(*found.iris_image_right))
    pts = inner_lips_on_opening_68(rgb, pts68, det.name)
    # the pupils where the photo shows them: the model's circles clipped by the mesh's lids
    m = found.mesh
    pupil_r = visible_iris_centre(right, m[list(CONTOURS["eye_r_upper"])],
                                  m[list(CONTOURS["eye_r_lower"])])
    pupil_l = visible_iris_centre(left, m[list(CONTOURS["eye_l_upper"])],
                                  m[list(CONTOURS["eye_l_lower"])])
    return Landmarks(pts, found.box, left, right, det.name, found.mesh,
                     float(found.confidence), pupil_l, pupil_r)


def detect_landmarks(rgb: np.ndarray, detector: LandmarkDetector | None = None) -> Landmarks:
    """Detect the 68 landmarks and both irises of the largest face in an RGB uint8 image
    (and the 468-point mesh with the MediaPipe detector).

    Parameters
    ----------
    rgb : (H, W, 3) uint8
        The photo, RGB.
    detector : LandmarkDetector, optional
        Default: :func:`default_detector` (MediaPipe's face mesh; ``--detector`` /
        ``$FAP_STUDIO_DETECTOR`` choose dlib's 68 points when that extra is installed).

    Returns
    -------
    Landmarks
        The largest face's 68 iBUG points, box, irises (and mesh, confidence).

    Raises
    ------
    NoFaceError
        No face, a face too small for a useful mesh, or a profile face.

    Examples
    --------
    >>> from editor.engine.imageio import load_image
    >>> from editor.resources import SAMPLE_FACE
    >>> lm = detect_landmarks(load_image(SAMPLE_FACE))
    >>> round(lm.fdp_points()["3.5"][0]) > round(lm.fdp_points()["3.6"][0])  # FDP 3.5: left iris
    True
    """
    det = detector or default_detector()
    if isinstance(det, MediaPipeDetector):
        return _from_mesh(det, det.run(rgb), rgb)
    pts, box = det.detect(rgb)
    pts = np.asarray(pts, np.float32).reshape(68, 2)
    right, left = _irises(rgb, pts)
    return Landmarks(pts, np.asarray(box, np.float32), left, right, det.name)


def _irises(rgb: np.ndarray, points: np.ndarray, near_right: Iris | None = None,
            near_left: Iris | None = None) -> tuple[Iris, Iris]:
    """:func:`locate_iris` of the image-left eye (the subject's right, FDP 3.6, ``near_right``)
    and of the other, the second on a thread: their disc filters (OpenCV, ~80 % of the
    search) run without the GIL (1080p: ~10 ms an eye)."""
    left = Pending(locate_iris, rgb, points, 1, near_left)
    right = locate_iris(rgb, points, 0, near_right)
    return right, left.result()


class LandmarkTracker:
    """Landmarks frame after frame of a video: with the MediaPipe detector each frame is cropped
    from the previous frame's mesh (no detection while the face stays found); other detectors
    detect every frame. A frame without a face raises :class:`NoFaceError` and the next frame
    detects afresh."""

    def __init__(self, detector: LandmarkDetector | None = None) -> None:
        self.detector = detector or default_detector()
        self._previous: np.ndarray | None = None

    def __call__(self, rgb: np.ndarray) -> Landmarks:
        det = self.detector
        if not isinstance(det, MediaPipeDetector):
            return detect_landmarks(rgb, det)
        try:
            lm = _from_mesh(det, det.track(rgb, self._previous), rgb)
        except NoFaceError:
            self._previous = None
            raise
        self._previous = lm.mesh
        return lm
