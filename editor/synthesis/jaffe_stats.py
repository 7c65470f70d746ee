"""Real feature-point motion of JAFFE neutral -> expression pairs, in each woman's FAPU.

Used by ``scripts/derive_presets.py`` (the preset derivation table) and by the preset tests.
It reads JAFFE at run time (``$FAP_STUDIO_JAFFE``, else ``../shared/data/jaffe`` beside the
repository) and ships no JAFFE data; the landmark detections are cached outside the repository
(the system temporary directory) so that a second run takes seconds.

Per woman: her first neutral photo gives the :class:`Face` (mesh, FAPU, face frame); her
neutral shape is the mean of all her neutral photos after head-motion removal
(:func:`.fap_estimate.remove_head_motion`: similarity on eye corners and nose). Each expression
photo is aligned the same way; the motion of the feature point of FAP ``n`` along that FAP's
axis (face frame: up/down = y, left/right = x, the face's own left = +x) divided by her FAPU of
the FAP's unit is the FAP value a renderer would need to reproduce it ("FAP-equivalent motion").
The noise floor is each neutral photo against the mean of her other neutral photos.

The landmarks come from :data:`DETECTOR` (dlib's 68 points, the optional extra), the instrument
the shipped emotion presets were derived with (issue 14): MediaPipe's mesh, the default
detector, follows the brows' and lids' expression motion less (JAFFE squeeze_eyebrow p10..p90
-3..12 FAPU against dlib's -6..20 and more), so the bands are only comparable with dlib's.
"""

from __future__ import annotations

import hashlib
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from editor.engine.face import Face
from editor.engine.faps import FAPS
from editor.engine.imageio import load_image
from editor.engine.landmarks import (
    FDP_FROM_68,
    Iris,
    Landmarks,
    detect_landmarks,
    get_detector,
)
from editor.errors import FapStudioError
from editor.resources import checkout_jaffe_dir
from editor.safeio import atomic_file

from .fap_estimate import remove_head_motion
from .jaffe import JAFFE_EMOTIONS

#: The detector the statistics are measured with (see the module docstring).
DETECTOR = "dlib"
#: Feature point -> iBUG-68 indices: :data:`.landmarks.FDP_FROM_68` plus the lip mid-points
#: (the landmarks nearest to the mesh's FDP vertices; face's own left = image right).
FDP_68 = {**FDP_FROM_68, "2.6": (63,), "2.7": (61,), "2.8": (65,), "2.9": (67,),
          "8.5": (53,), "8.6": (49,), "8.7": (55,), "8.8": (59,)}
#: FAPs whose feature point a dlib landmark observes (eyelids: 3.1-3.4 are lid mid-points).
MEASURED = (3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 19, 20, 21, 22, 31, 32, 33, 34, 35, 36, 37, 38,
            51, 52, 53, 54, 55, 56, 57, 58, 59, 60, 61, 62)
_AXIS = {"up": (1, -1.0), "down": (1, 1.0), "left": (0, 1.0), "right": (0, -1.0)}


def default_root() -> Path:
    """``$FAP_STUDIO_JAFFE``, else ``../shared/data/jaffe`` beside the source checkout."""
    return checkout_jaffe_dir()


def fap_axis(n: int) -> tuple[str, int, float, str]:
    """(feature point, frame axis 0=x/1=y, sign, FAPU name) of FAP ``n``'s positive motion."""
    f = FAPS[n]
    return f.fdp or "", *_AXIS[f.direction], f.unit


def fap_motion(d_frame: dict[str, np.ndarray], fapu: dict[str, float],
               faps: tuple[int, ...] = MEASURED) -> np.ndarray:
    """FAP-equivalent values (len(faps),) of feature-point motions (face frame, pixels)."""
    out = []
    for n in faps:
        fdp, ax, sign, unit = fap_axis(n)
        out.append(sign * float(d_frame[fdp][ax]) / fapu[unit])
    return np.array(out)


def _detect_all(paths: list[Path], detector: str = DETECTOR) -> dict[str, np.ndarray]:
    """name -> (73,) float32: 68 points, box 4 (unused), irises (x, y, r) x 2; cached."""
    key = hashlib.sha1((detector + "".join(f"{p.name}{p.stat().st_size}{p.stat().st_mtime_ns}"
                                           for p in paths)).encode()).hexdigest()[:16]
    cache = Path(tempfile.gettempdir()) / f"fap-studio-jaffe-landmarks-{key}.npz"
    if cache.exists():
        with np.load(cache) as z:
            return {k: z[k] for k in z.files}

    det = get_detector(detector)
    out = {}
    for p in paths:
        try:
            lm = detect_landmarks(load_image(p), det)
        except Exception:  # noqa: BLE001 - a missed face is simply not measured
            continue
        out[p.name] = np.concatenate([lm.points.ravel(), lm.box,
                                      [lm.iris_left.cx, lm.iris_left.cy, lm.iris_left.r,
                                       lm.iris_right.cx, lm.iris_right.cy, lm.iris_right.r]]
                                     ).astype(np.float32)
    try:
        with atomic_file(cache) as tmp, open(tmp, "wb") as fh:
            np.savez_compressed(fh, allow_pickle=False, **out)
    except FapStudioError:  # a cache that cannot be written is only slower next time
        pass
    return out


def _landmarks(row: np.ndarray) -> Landmarks:
    pts = row[:136].reshape(68, 2)
    il, ir = row[140:143], row[143:146]
    return Landmarks(pts.copy(), row[136:140].copy(), Iris(*map(float, il)),
                     Iris(*map(float, ir)), "dlib-68" if DETECTOR == "dlib" else "mediapipe-468")


@dataclass
class Sample:
    person: str
    emotion: str  # "neutral" for the noise samples
    image: str
    values: np.ndarray  # (len(MEASURED),) FAP-equivalent motion, FAPU


@dataclass
class JaffeMotion:
    samples: list[Sample]
    faces: dict  # person -> Face of her first neutral photo
    neutral: dict  # person -> (68, 2) mean neutral landmarks (aligned to that photo)
    faps: tuple[int, ...] = MEASURED

    def values(self, emotion: str) -> np.ndarray:
        return np.array([s.values for s in self.samples if s.emotion == emotion])

    def stats(self, emotion: str) -> dict[str, np.ndarray]:
        """median, p10, p90, min, max, n per FAP (arrays over :attr:`faps`)."""
        v = self.values(emotion)
        return {"median": np.median(v, 0), "p10": np.percentile(v, 10, 0),
                "p90": np.percentile(v, 90, 0), "min": v.min(0), "max": v.max(0),
                "n": np.full(v.shape[1], len(v))}


def measure(root: str | Path | None = None) -> JaffeMotion:
    """Measure every JAFFE expression photo against its woman's neutral (see the module)."""
    images = Path(root or default_root()) / "images"
    paths = sorted(images.glob("*.tiff"))
    if not paths:
        raise FileNotFoundError(f"{images}: no JAFFE images")
    det = _detect_all(paths)
    people = sorted({p.name.split(".")[0] for p in paths})
    samples: list[Sample] = []
    faces, neutrals = {}, {}
    for who in people:
        ne = [p for p in paths if p.name.startswith(f"{who}.NE") and p.name in det]
        if not ne:
            continue
        face = Face.from_landmarks(load_image(ne[0]), _landmarks(det[ne[0].name]),
                                   source=str(ne[0]))
        ref = face.landmarks.points.astype(np.float64)
        aligned = [remove_head_motion(ref, det[p.name][:136].reshape(68, 2).astype(np.float64))[0]
                   for p in ne]
        mean = np.mean(aligned, 0)
        faces[who], neutrals[who] = face, mean
        def motion(pts: np.ndarray, base: np.ndarray, face: Face = face) -> np.ndarray:
            d = (pts - base) @ face.frame.rot  # face frame, pixels
            return fap_motion({k: d[list(v)].mean(0) for k, v in FDP_68.items()}, face.fapu)

        for i, p in enumerate(ne):  # noise: each neutral against the mean of the others
            if len(ne) > 1:
                others = np.mean([a for j, a in enumerate(aligned) if j != i], 0)
                samples.append(Sample(who, "neutral", p.name, motion(aligned[i], others)))
        for p in paths:
            code = p.name.split(".")[1][:2]
            if not p.name.startswith(f"{who}.") or code not in JAFFE_EMOTIONS or p.name not in det:
                continue
            pts, _ = remove_head_motion(mean, det[p.name][:136].reshape(68, 2).astype(np.float64))
            samples.append(Sample(who, JAFFE_EMOTIONS[code], p.name, motion(pts, mean)))
    return JaffeMotion(samples, faces, neutrals)


def preset_motion(face, faps: np.ndarray, fap_list: tuple[int, ...] = MEASURED) -> np.ndarray:
    """FAP-equivalent motion of the mesh feature points of ``face`` under a FAP vector."""
    p0 = face.deform(None).astype(np.float64)
    p1 = face.deform(faps).astype(np.float64)
    d = (p1 - p0) @ face.frame.rot
    return fap_motion({k: d[i] for k, i in face.fdp.items()}, face.fapu, fap_list)
