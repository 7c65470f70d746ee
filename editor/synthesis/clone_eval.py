"""Evaluation of FAP recovery and expression cloning (issue 10): what ``fap-studio clone-eval``
prints.

* FAP recovery round trip: known FAP vectors rendered on a face, estimated back
  (:func:`roundtrip_vectors`, :func:`roundtrip_table`).
* JAFFE cloning (:func:`jaffe_evaluation`): every person's expressions (instances >= 2; instance 1
  of each emotion are the key models) cloned onto the sample face and onto the next person's
  neutral by each route; the closed-loop landmark error (inner 17-67, % of the target's
  inter-ocular distance) per route, as Markdown tables. JAFFE is research-only and read from
  disk at run time.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from editor.engine.face import Face
from editor.engine.faps import FAPS
from editor.engine.imageio import load_image, save_image
from editor.engine.landmarks import detect_landmarks
from editor.engine.mesh import signed_areas
from editor.errors import FapStudioError, NoFaceError
from editor.formats.presets import apply_preset
from editor.resources import SAMPLE_FACE

from .cloning import (
    KeyModels,
    clone,
    closed_loop_error,
    face_deformer,
    key_models,
    round_trip,
    transfer_motion,
)
from .fap_estimate import OBSERVABLE, FapEstimator, remove_head_motion
from .jaffe import JAFFE_EMOTIONS, jaffe_files

#: Routes compared; "nothing" = the target's own neutral landmarks (the do-nothing baseline).
ROUTES = ("nothing", "fap", "laplacian", "keys")
#: Table columns: (error key, heading); "_mesh" = landmarks carried by the deformed mesh.
COLUMNS = (("nothing", "do nothing"), ("fap_mesh", "FAP, mesh"), ("fap", "FAP, detected"),
           ("laplacian_mesh", "Laplacian, mesh"), ("laplacian", "Laplacian, detected"),
           ("keys", "Laplacian + NNLS keys, detected"))
Progress = Callable[[int, int], object]


def upscaled_face(rgb: np.ndarray, points: np.ndarray, scale: float = 3.0) -> np.ndarray:
    """The face region of a photo (landmark box + margins), enlarged ``scale`` times (cubic).

    dlib returns integer landmarks: on a small face one pixel is a large part of a FAPU, so the
    recovery round trip runs on an enlarged copy.
    """
    p = np.asarray(points, np.float64)
    (x0, y0), (x1, y1) = p.min(0), p.max(0)
    w = x1 - x0
    h, wd = rgb.shape[:2]
    box = np.round([max(0, x0 - 0.6 * w), max(0, y0 - 0.9 * w), min(wd, x1 + 0.6 * w),
                    min(h, y1 + 0.4 * w)]).astype(int)
    crop = np.ascontiguousarray(rgb[box[1]:box[3], box[0]:box[2]])
    return cv2.resize(crop, None, fx=scale, fy=scale, interpolation=cv2.INTER_CUBIC)


def roundtrip_vectors(n_random: int = 4, seed: int = 0) -> tuple[list[str], np.ndarray]:
    """The six emotion presets restricted to the observable FAPs, plus random vectors
    (each observable FAP uniform in +-25 % of its larger range end, left/right independent)."""
    obs = np.array(OBSERVABLE) - 1
    names, out = [], []
    for e in ("joy", "sadness", "surprise", "anger", "fear", "disgust"):
        v = np.zeros(68, np.float32)
        v[obs] = apply_preset(e)[obs]
        names.append(e)
        out.append(v)
    rng = np.random.default_rng(seed)
    amp = np.maximum(np.abs(FAPS.lo), FAPS.hi)[obs]
    for k in range(n_random):
        v = np.zeros(68, np.float32)
        v[obs] = rng.uniform(-0.25, 0.25, len(obs)) * amp
        names.append(f"random{k + 1}")
        out.append(FAPS.clamp(v))
    return names, np.array(out)


def roundtrip_table(face: Face, vectors: np.ndarray) -> tuple[str, np.ndarray]:
    """Markdown table of the per-FAP recovery error; also the (n, 68) errors."""
    err = round_trip(face, vectors) - vectors
    lines = ["| FAP | name | RMS error (FAPU) | max abs (FAPU) | RMS, % of range |",
             "|---|---|---|---|---|"]
    pct = []
    for n in OBSERVABLE:
        e = err[:, n - 1]
        rms = float(np.sqrt(np.nanmean(e ** 2)))
        pct.append(100 * rms / (FAPS.hi[n - 1] - FAPS.lo[n - 1]))
        lines.append(f"| {n} | {FAPS[n].name} | {rms:.0f} | {np.nanmax(np.abs(e)):.0f} | "
                     f"{pct[-1]:.1f} |")
    lines.append(f"| | **mean** | | | **{np.mean(pct):.1f}** |")
    return "\n".join(lines), err


@dataclass
class CloneEvaluation:
    """Errors (% IOD) keyed by (target kind, JAFFE code, column) and the counts of the run."""

    people: list[str]
    errors: dict[tuple[str, str, str], list[float]] = field(default_factory=dict)
    folds: int = 0
    skipped: int = 0

    def add(self, target: str, code: str, column: str, value: float) -> None:
        self.errors.setdefault((target, code, column), []).append(float(value))

    def table(self) -> str:
        """Markdown: one table per target kind, one row per expression, one column per route."""
        out = []
        for tname, title in (("sample", "onto the sample face"),
                             ("jaffe", "onto the next JAFFE person's neutral photo")):
            out += [f"\nCloned {title}: landmark error against the transferred motion, mean "
                    "over landmarks 17-67, % of the target's inter-ocular distance (lower is "
                    "better; 'detected' = closed loop, dlib on the result; 'mesh' = where the "
                    "deformed mesh puts the landmarks):\n",
                    "| expression | n | " + " | ".join(t for _, t in COLUMNS) + " |",
                    "|---|---|" + "---|" * len(COLUMNS)]
            allv: dict[str, list[float]] = {r: [] for r, _ in COLUMNS}
            for c, emotion in JAFFE_EMOTIONS.items():
                cells = []
                for r, _ in COLUMNS:
                    v = np.array(self.errors.get((tname, c, r), []), float)
                    allv[r] += list(v)
                    cells.append(f"{np.nanmean(v):.2f}" if v.size else "-")
                n = len(self.errors.get((tname, c, "nothing"), []))
                out.append(f"| {c} ({emotion}) | {n} | " + " | ".join(cells) + " |")
            tot = [f"**{np.nanmean(allv[r]):.2f}**" if allv[r] else "-" for r, _ in COLUMNS]
            out.append(f"| all | {len(allv['nothing'])} | " + " | ".join(tot) + " |")
        out.append(f"\nInverted triangles in any result: {self.folds}. Test images without a "
                   f"face: {self.skipped}. Persons: {', '.join(self.people)}.")
        return "\n".join(out)


def _detect_each(paths: list[Path]) -> list[np.ndarray | None]:
    """68 landmarks (float64) of each image, None where no face is found."""
    out: list[np.ndarray | None] = []
    for f in paths:
        try:
            out.append(detect_landmarks(load_image(f)).points.astype(np.float64))
        except NoFaceError:
            out.append(None)
    return out


def _clone_routes(ev: CloneEvaluation, tname: str, code: str, src: Face, q: np.ndarray,
                  tgt: Face, keys: KeyModels | None, est: FapEstimator) -> list[np.ndarray]:
    """Clone the expression landmarks ``q`` of ``src`` onto ``tgt`` by every route, recording
    the errors in ``ev``; the result images in route order."""
    al, _ = remove_head_motion(src.landmarks.points, q)
    exp = tgt.landmarks.points + transfer_motion(src, al - src.landmarks.points, tgt)
    e0 = np.linalg.norm(exp - tgt.landmarks.points, axis=1)[17:]
    ev.add(tname, code, "nothing", e0.mean() * 100 / tgt.interocular)
    images = []
    for r in ROUTES[1:]:
        if r == "keys" and keys is None:
            continue
        res = clone(src, q, tgt, "fap" if r == "fap" else "laplacian",
                    keys=keys if r == "keys" else None, estimator=est)
        ev.folds += bool((signed_areas(res.vertices.astype(np.float64), tgt.triangles)
                          <= 0).any())
        ev.add(tname, code, r, closed_loop_error(res.image, res.expected, tgt)["inner"])
        if r != "keys":  # landmarks carried by the mesh, no detector
            lm = tgt.landmarks.points + face_deformer(tgt).S @ (res.vertices - tgt.vertices)
            em = np.linalg.norm(lm - res.expected, axis=1)[17:].mean()
            ev.add(tname, code, r + "_mesh", em * 100 / tgt.interocular)
        images.append(res.image)
    return images


def jaffe_evaluation(images: Path, persons: list[str] | None = None,
                     renders: Path | None = None, progress: Progress | None = None) -> str:
    """The JAFFE cloning comparison as Markdown tables (see the module docstring).

    ``persons`` restricts the JAFFE person codes; ``renders`` is a folder for contact sheets
    (source neutral | source expression | each route's result); ``progress(done, total)`` is
    called per cloned pair. :class:`FapStudioError` if ``images`` holds no neutral image.
    """
    files = jaffe_files(images)
    people = [p for p in (persons or sorted(files)) if "NE" in files.get(p, {})]
    if not people:
        raise FapStudioError(f"{images}: no JAFFE neutral images found")
    sample = Face.from_image(SAMPLE_FACE)
    neutral = {p: Face.from_image(files[p]["NE"][0], own_expression=False)
               for p in sorted(files) if "NE" in files[p]}
    order = sorted(neutral)
    ev = CloneEvaluation(people)
    jobs = sum(max(len(files[p].get(c, [])) - 1, 0) for p in people for c in JAFFE_EMOTIONS)
    done = 0
    for p in people:
        src = neutral[p]
        est = FapEstimator(src)
        pts = {c: _detect_each(files[p].get(c, [])) for c in JAFFE_EMOTIONS}
        key_pts = {JAFFE_EMOTIONS[c]: v[0] for c, v in pts.items() if v and v[0] is not None}
        other = order[(order.index(p) + 1) % len(order)]
        for tname, tgt in (("sample", sample), ("jaffe", neutral[other])):
            keys = key_models(src, key_pts, tgt) if len(key_pts) >= 2 else None
            sheet = []
            for c in JAFFE_EMOTIONS:
                for k, q in enumerate(pts[c][1:]):
                    if q is None:
                        ev.skipped += 1
                        continue
                    row = _clone_routes(ev, tname, c, src, q, tgt, keys, est)
                    if renders is not None and k == 0:
                        sheet.append(_sheet_row(src.image, load_image(files[p][c][k + 1]),
                                                row, tgt))
                    if tname == "sample":
                        done += 1
                        if progress:
                            progress(done, jobs)
            if renders is not None and sheet:
                renders.mkdir(parents=True, exist_ok=True)
                save_image(renders / f"{p}_on_{tname if tname == 'sample' else other}.png",
                           np.vstack(sheet))
    return ev.table()


def _sheet_row(src_neutral: np.ndarray, src_expr: np.ndarray, results: list[np.ndarray],
               target: Face) -> np.ndarray:
    """One row of a contact sheet: source neutral | source expression | each result (face crop),
    all scaled to 240 px high."""
    p = target.landmarks.points
    (x0, y0), (x1, y1) = p.min(0), p.max(0)
    w = x1 - x0
    h, wd = target.image.shape[:2]
    b = np.round([max(0, x0 - 0.25 * w), max(0, y0 - 0.5 * w), min(wd, x1 + 0.25 * w),
                  min(h, y1 + 0.15 * w)]).astype(int)

    def fit(img: np.ndarray) -> np.ndarray:
        s = 240 / img.shape[0]
        return cv2.resize(img, (round(img.shape[1] * s), 240), interpolation=cv2.INTER_AREA
                          if s < 1 else cv2.INTER_CUBIC)

    tiles = [fit(src_neutral), fit(src_expr)] + [fit(r[b[1]:b[3], b[0]:b[2]]) for r in results]
    return np.hstack(tiles)
