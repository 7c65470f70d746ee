"""Closed-loop check of FAP estimation on real expressions (JAFFE; issue 21 item 1).

For each woman, her first neutral photo is the model (:class:`Face`). For each of her real
expression photos: detect its landmarks, estimate the FAP vector that explains the motion from
her neutral, render that vector on the neutral photo, detect the landmarks again on the render
and compare them with the real photo's landmarks (moved into the neutral's head pose). The
error is in % of the inter-ocular distance, per region:

* ``brows`` 17-26, ``lids`` 36-47 (eye contours), ``lips`` 48-67, ``jaw`` 5-11 (chin part of
  the contour; detectors place the sides loosely), ``inner`` 17-67 (all but the contour).

"Do nothing" (the neutral's own landmarks) is the baseline every region must beat. Signs: for
each FAP, the sign of the estimate is compared with the sign of the real motion of the feature
point it drives (in the FAP's own axis), where that motion is above the noise floor (1.5 px:
MediaPipe re-detecting the same neutral photo shifted by sub-pixel amounts or rescaled by
0.96-1.08 moves these points by 0.20 px RMS, 0.89 px at most; two neutral photos of the same
woman differ by 0.53 px RMS). A FAP estimated as exactly 0 is not checked. The lip FAPs that
open_jaw carries (:data:`~editor.engine.fap_model.JAW_CARRIED`: corners, lower lip) are
displacements on top of the jaw's: their point's motion is taken relative to where the estimated
open_jaw carries it in the model (an open smile's corners may end up below the neutral's while
rising against the jaw).

JAFFE is research-only: it is read from disk at run time, nothing derived from it is stored.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from editor.engine.face import Face
from editor.engine.fap_model import JAW_CARRIED, landmark_jacobian
from editor.engine.imageio import load_image
from editor.engine.landmarks import detect_landmarks
from editor.errors import NoFaceError
from editor.resources import checkout_jaffe_dir

from .fap_estimate import FapEstimator, remove_head_motion
from .jaffe import JAFFE_EMOTIONS, jaffe_files

REGIONS = {"brows": np.arange(17, 27), "lids": np.arange(36, 48), "lips": np.arange(48, 68),
           "jaw": np.arange(5, 12), "inner": np.arange(17, 68)}


@dataclass
class ClosedLoop:
    """Per-image errors (% IOD) by route and region, and the sign checks."""

    rows: list[dict] = field(default_factory=list)  # person, code, route, region errors
    signs: list[tuple[str, str, int, float, float]] = field(default_factory=list)

    def mean(self, route: str, region: str, code: str | None = None) -> float:
        v = [r[region] for r in self.rows if r["route"] == route
             and (code is None or r["code"] == code) and np.isfinite(r[region])]
        return float(np.mean(v)) if v else float("nan")

    def wrong_signs(self) -> list[tuple[str, str, int, float, float]]:
        """(person, code, fap, estimate, real motion) where the estimate opposes the motion."""
        return [s for s in self.signs if s[3] * s[4] < 0]

    def table(self) -> str:
        """Markdown: estimated vs do-nothing error per expression and region."""
        regions = ("brows", "lids", "lips", "jaw", "inner")
        head = "| expression | n | " + " | ".join(f"{r} est / none" for r in regions) + " |"
        lines = [head, "|---|---|" + "---|" * len(regions)]
        for code in list(JAFFE_EMOTIONS) + [None]:
            n = sum(1 for r in self.rows if r["route"] == "estimate"
                    and (code is None or r["code"] == code))
            cells = [f"{self.mean('estimate', g, code):.2f} / {self.mean('nothing', g, code):.2f}"
                     for g in regions]
            name = "all" if code is None else f"{JAFFE_EMOTIONS[code]} ({code})"
            if code is None:
                cells = [f"**{c}**" for c in cells]
            lines.append(f"| {name} | {n} | " + " | ".join(cells) + " |")
        bad = self.wrong_signs()
        lines.append(f"\nSign checks: {len(self.signs)}, opposite to the real motion: {len(bad)}"
                     + (" (" + ", ".join(f"{p}.{c} FAP {k}: {e:+.0f} vs {m:+.2f} px"
                                         for p, c, k, e, m in bad[:12]) + ")" if bad else ""))
        return "\n".join(lines)


def _pose_free(neutral: np.ndarray, expr: np.ndarray) -> np.ndarray:
    return remove_head_motion(neutral, expr)[0]


def _errors(got: np.ndarray | None, want: np.ndarray, iod: float) -> dict[str, float]:
    if got is None:
        return {g: float("nan") for g in REGIONS}
    e = np.linalg.norm(np.asarray(got, np.float64) - want, axis=1) * 100.0 / iod
    return {g: float(e[idx].mean()) for g, idx in REGIONS.items()}


#: (FAP number, landmark index, axis sign): landmark motion along the FAP's axis in the
#: frame (x: +1 = image right, y: +1 = down) that the FAP's positive value produces.
SIGN_CHECKS: tuple[tuple[int, int, str, float], ...] = (
    (3, 8, "y", 1.0),       # open_jaw: chin down
    (19, 43, "y", 1.0), (19, 44, "y", 1.0),  # close_t_l_eyelid (face's left = image right)
    (20, 37, "y", 1.0), (20, 38, "y", 1.0),
    (31, 22, "y", -1.0), (32, 21, "y", -1.0),  # raise inner brows
    (35, 26, "y", -1.0), (36, 17, "y", -1.0),  # raise outer brows
    (59, 54, "y", -1.0), (60, 48, "y", -1.0),  # raise corner lips (outer)
    (52, 57, "y", -1.0),    # raise_b_midlip_o: lower lip up
    # their inner-lip partners
    (12, 64, "y", -1.0), (13, 60, "y", -1.0),  # raise corner lips (inner)
    (5, 66, "y", -1.0),     # raise_b_midlip: inner lower lip up
)


def closed_loop(images: Path, people: Sequence[str] | None = None, *,
                estimator_factory: Callable | None = None, noise_px: float = 1.5,
                progress: Callable[[int, int], None] | None = None) -> ClosedLoop:
    """Run the closed loop over JAFFE (see the module docstring). Detections are not cached.

    ``estimator_factory(face)`` returns an object with ``estimate(points68).faps`` (default
    :class:`~editor.synthesis.fap_estimate.FapEstimator`). ``noise_px``: real landmark motion below
    this is not sign-checked (see the module docstring for the detector's measured noise).
    """
    files = jaffe_files(images)
    who = [p for p in (people or sorted(files)) if "NE" in files.get(p, {})]
    make = estimator_factory or FapEstimator
    out = ClosedLoop()
    jobs = [(p, c, f) for p in who for c in JAFFE_EMOTIONS for f in files[p].get(c, [])]
    # Any: whatever estimator_factory makes; the landmarks' motion per unit of open_jaw
    faces: dict[str, tuple[Face, Any, np.ndarray]] = {}
    for k, (p, code, path) in enumerate(jobs):
        if p not in faces:
            face = Face.from_image(files[p]["NE"][0], own_expression=False)
            faces[p] = (face, make(face), landmark_jacobian(face)[:, 2].reshape(68, 2))
        face, est, jaw = faces[p]
        neutral = face.landmarks.points.astype(np.float64)
        iod = face.interocular
        try:
            q = detect_landmarks(load_image(path)).points.astype(np.float64)
        except NoFaceError:
            continue
        want = _pose_free(neutral, q)
        f = np.asarray(est.estimate(q).faps, np.float64)
        try:
            got = detect_landmarks(face.render(f)).points.astype(np.float64)
            got = _pose_free(neutral, got)
        except NoFaceError:
            got = None
        out.rows.append({"person": p, "code": code, "route": "estimate",
                         **_errors(got, want, iod)})
        out.rows.append({"person": p, "code": code, "route": "nothing",
                         **_errors(neutral, want, iod)})
        rot = face.frame.rot
        for fap, lm, axis, sgn in SIGN_CHECKS:
            move = want[lm] - neutral[lm]
            if fap in JAW_CARRIED:
                move = move - jaw[lm] * f[2]
            m = move @ rot[:, 0 if axis == "x" else 1] * sgn
            if abs(m) >= noise_px and abs(f[fap - 1]) > 1e-6:
                out.signs.append((p, code, fap, float(f[fap - 1]), float(m)))
        if progress:
            progress(k + 1, len(jobs))
    return out


if __name__ == "__main__":  # pragma: no cover - a development aid


    root = Path(sys.argv[1]) if len(sys.argv) > 1 else checkout_jaffe_dir()
    res = closed_loop(root / "images", sys.argv[2].split(",") if len(sys.argv) > 2 else None)
    print(res.table())
