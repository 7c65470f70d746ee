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

:class:`MotionSummary` is the summary of a measurement the preset tests use (per emotion and FAP:
median, p10, p90, min, max, count, median in pupil distances; the neutral noise; the joy lip
opening). ``scripts/freeze_jaffe_motion.py`` freezes dlib's into ``tests/data`` (summary numbers
only) so that the tests keep their real-motion bands where dlib is not installed.
:func:`neutral_faces` fits the women's meshes with any detector (the meshes presets are applied
to only need a mesh and FAPU, not dlib's motion reading).
"""

from __future__ import annotations

import hashlib
import json
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
    default_detector,
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


def neutral_faces(root: str | Path | None = None, detector: str | None = None) -> dict[str, Face]:
    """person -> :class:`Face` of her first neutral JAFFE photo in which ``detector`` (default:
    the session's default detector) finds the face; not cached (ten detections)."""
    images = Path(root or default_root()) / "images"
    det = get_detector(detector) if detector else default_detector()
    out: dict[str, Face] = {}
    for p in sorted(images.glob("*.NE*.tiff")):
        who = p.name.split(".")[0]
        if who in out:
            continue
        rgb = load_image(p)
        try:
            lm = detect_landmarks(rgb, det)
        except FapStudioError:  # a missed face: try her next neutral photo
            continue
        out[who] = Face.from_landmarks(rgb, lm, source=str(p))
    if not out:
        raise FileNotFoundError(f"{images}: no JAFFE neutral images with a detectable face")
    return out


def pupil_distance(face: Face) -> float:
    """Distance between the iris centres (pixels)."""
    il, ir = face.landmarks.iris_left, face.landmarks.iris_right
    return float(np.hypot(il.cx - ir.cx, il.cy - ir.cy))


def to_pupil_distances(face: Face, n: int, value: float | np.ndarray) -> float | np.ndarray:
    """FAP-equivalent value(s) of FAP ``n`` on ``face`` -> pupil distances."""
    return value * face.fapu[fap_axis(n)[3]] / pupil_distance(face)


#: Statistic names of :meth:`MotionSummary.stats` (arrays over the FAPs).
STAT_KEYS = ("median", "p10", "p90", "min", "max", "n", "median_pd")
#: JAFFE smiles are closed or open: inner-lip opening changes (MNS) below this are "closed".
LIP_OPEN_SPLIT = 250.0


def lip_opening(values: np.ndarray, faps: tuple[int, ...] = MEASURED) -> np.ndarray:
    """Inner lips' opening change (2.3 - 2.2, MNS) of FAP-equivalent rows (..., len(faps))."""
    i = {n: k for k, n in enumerate(faps)}
    return np.asarray(-values[..., i[5]] - values[..., i[4]])


@dataclass
class MotionSummary:
    """The summary numbers of a :class:`JaffeMotion` the preset tests use (no per-photo data)."""

    detector: str
    faps: tuple[int, ...]
    emotions: dict[str, dict[str, np.ndarray]]  # emotion -> STAT_KEYS -> (len(faps),)
    noise_p90: np.ndarray  # (len(faps),) p90 of |neutral vs her other neutrals|
    n_neutral: int
    joy_lips: dict[str, float]  # joy lip opening: n_closed, n_open, closed_max, open_min, median

    @classmethod
    def of(cls, m: JaffeMotion, detector: str = DETECTOR) -> MotionSummary:
        emotions = {}
        for e in sorted({s.emotion for s in m.samples} - {"neutral"}):
            st = m.stats(e)
            pd = np.array([[to_pupil_distances(m.faces[s.person], n, s.values[k])
                            for k, n in enumerate(m.faps)]
                           for s in m.samples if s.emotion == e])
            emotions[e] = {**st, "median_pd": np.median(pd, 0)}
        gaps = lip_opening(m.values("joy"), m.faps)
        closed, opened = gaps[gaps < LIP_OPEN_SPLIT], gaps[gaps >= LIP_OPEN_SPLIT]
        lips = {"n_closed": float(len(closed)), "n_open": float(len(opened)),
                "closed_max": float(closed.max()) if len(closed) else float("nan"),
                "open_min": float(opened.min()) if len(opened) else float("nan"),
                "median": float(np.median(gaps))}
        neutral = m.values("neutral")
        return cls(detector, tuple(m.faps), emotions,
                   np.percentile(np.abs(neutral), 90, 0), len(neutral), lips)

    def stats(self, emotion: str) -> dict[str, np.ndarray]:
        return self.emotions[emotion]

    def to_json(self) -> dict:
        def r(a: np.ndarray) -> list[float]:
            return [round(float(x), 5) for x in a]

        return {"detector": self.detector, "faps": list(self.faps),
                "noise_p90": r(self.noise_p90), "n_neutral": self.n_neutral,
                "joy_lips": {k: round(v, 5) for k, v in self.joy_lips.items()},
                "emotions": {e: {k: r(st[k]) for k in STAT_KEYS}
                             for e, st in self.emotions.items()}}

    @classmethod
    def from_json(cls, d: dict) -> MotionSummary:
        return cls(str(d["detector"]), tuple(int(n) for n in d["faps"]),
                   {e: {k: np.array(st[k], np.float64) for k in STAT_KEYS}
                    for e, st in d["emotions"].items()},
                   np.array(d["noise_p90"], np.float64), int(d["n_neutral"]),
                   {k: float(v) for k, v in d["joy_lips"].items()})

    @classmethod
    def load(cls, path: str | Path) -> MotionSummary:
        return cls.from_json(json.loads(Path(path).read_text(encoding="utf-8")))

    def differences(self, other: MotionSummary, rtol: float = 1e-3,
                    atol: float = 1e-3) -> list[str]:
        """Where ``other`` differs from this summary beyond the tolerance (empty: it matches)."""
        if (self.detector, self.faps, self.n_neutral) != (other.detector, other.faps,
                                                           other.n_neutral):
            return [f"detector/faps/n_neutral: {(self.detector, self.faps, self.n_neutral)} "
                    f"!= {(other.detector, other.faps, other.n_neutral)}"]
        if set(self.emotions) != set(other.emotions):
            return [f"emotions {sorted(self.emotions)} != {sorted(other.emotions)}"]
        bad = []
        pairs = [("noise_p90", self.noise_p90, other.noise_p90),
                 ("joy_lips", np.array(list(self.joy_lips.values())),
                  np.array([other.joy_lips.get(k, np.nan) for k in self.joy_lips]))]
        pairs += [(f"{e} {k}", st[k], other.emotions[e][k])
                  for e, st in self.emotions.items() for k in STAT_KEYS]
        for name, a, b in pairs:
            if not np.allclose(a, b, rtol=rtol, atol=atol, equal_nan=True):
                k = int(np.nanargmax(np.abs(a - b)))
                bad.append(f"{name}: {a[k]:.4f} != {b[k]:.4f} (item {k})")
        return bad
