"""Landmark accuracy on JAFFE against the Stasm points shipped with it (issue 14).

``python scripts/landmark_accuracy.py [JAFFE_DIR] [--detector mediapipe dlib] [--json]``

For every JAFFE photo (213, 256x256 grey) each detector's landmarks are compared with the
independent Stasm-77 points of ``landmarks_stasm77/`` (see editor/synthesis/bilinear_data.py for
that layout). Errors are in % of the inter-ocular distance (Stasm's two pupils, 38 and 39):

* eye corners, mouth corners, pupils: point to point. Stasm's pupil is the centre of the iris's
  visible part (below the circle's centre when the upper lid covers the iris's top: the model
  circle's centre minus Stasm's pupil follows the lids' cover with a slope near 1), so a pupil
  is :meth:`Landmarks.pupils` (MediaPipe: the iris model's circle clipped by the mesh's lids;
  dlib: the centre of :func:`editor.engine.landmarks.locate_iris`'s circle, found on visible
  pixels). ``pupils (circle centre)`` measures the full circles' centres instead;
* chin: point to point (iBUG 8 against Stasm 6), on all photos and on open mouths only (inner
  lips more than 0.1 IOD apart in Stasm's points: 64 of the 213);
* lids and inner lips: each Stasm contour point's distance to the detector's contour, a polyline
  through its points (MediaPipe: the mesh's dense lid and inner-lip contours, 9 and 11 points a
  side; dlib: its 4 points per lid and 5 per inner lip, corners included); inner lips also on
  closed and open mouths apart. On open mouths Stasm's lower inner-lip middle lies 5.5 % IOD
  above dlib's (on wide-open mouths inside the cavity), and dlib's 5-point polylines cut
  across towards it. The mesh's inner-lip points are refined on the image
  (:mod:`editor.engine.lip_edges`): the model's own contour measures 2.03 (closed 1.48, open
  3.31), the refined one 1.70 (1.29, 2.64).

Prints one row per measure (mean over images and points) with both detectors side by side;
``--json`` prints ``{detector: {measure: mean %}}`` instead. Detectors that are not installed
(dlib without the extra) are skipped with a note on stderr.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from editor.engine.facemesh import CONTOURS  # noqa: E402
from editor.engine.imageio import load_image  # noqa: E402
from editor.engine.landmarks import Landmarks, detect_landmarks, get_detector  # noqa: E402
from editor.errors import FapStudioError  # noqa: E402
from editor.resources import checkout_jaffe_dir  # noqa: E402

MEASURES = ("eye corners", "mouth corners", "pupils", "pupils (circle centre)", "upper lids",
            "lower lids", "inner lips", "inner lips (closed mouths)", "inner lips (open mouths)",
            "chin", "chin (open mouths)")

# Stasm-77 indices (image-left = the subject's right eye)
_S_EYE_CORNERS = [34, 30, 40, 44]  # image-left outer, inner; image-right inner, outer
_S_MOUTH = [59, 65]
_S_PUPILS = [38, 39]  # image-left, image-right
_S_UPPER_LIDS = [31, 32, 33, 41, 42, 43]
_S_LOWER_LIDS = [35, 36, 37, 45, 46, 47]
_S_INNER_LIPS = [66, 67, 68, 69, 70, 71]


def _seg_dist(p: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance of each point p (n, 2) to the polyline ``poly`` (m, 2)."""
    a, b = poly[:-1][None], poly[1:][None]
    ab = b - a
    t = np.clip(((p[:, None] - a) * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-12), 0, 1)
    q = a + t[..., None] * ab
    return np.linalg.norm(p[:, None] - q, axis=-1).min(1)


def _contours(lm: Landmarks) -> dict[str, list[np.ndarray]]:
    """Upper lids, lower lids and inner lips of a detection, as polylines."""
    if lm.mesh is not None:
        m = lm.mesh.astype(np.float64)
        c = {k: m[list(v)] for k, v in CONTOURS.items()}
        return {"upper lids": [c["eye_r_upper"], c["eye_l_upper"]],
                "lower lids": [c["eye_r_lower"], c["eye_l_lower"]],
                "inner lips": [c["lips_inner_upper"], c["lips_inner_lower"]]}
    p = lm.points.astype(np.float64)
    return {"upper lids": [p[[36, 37, 38, 39]], p[[42, 43, 44, 45]]],
            "lower lids": [p[[39, 40, 41, 36]], p[[45, 46, 47, 42]]],
            "inner lips": [p[[60, 61, 62, 63, 64]], p[[64, 65, 66, 67, 60]]]}


def errors(lm: Landmarks, stasm: np.ndarray) -> dict[str, float]:
    """Mean error per measure (% IOD) of one detection against its Stasm points."""
    s = np.asarray(stasm, np.float64)
    iod = float(np.linalg.norm(s[38] - s[39]))
    p = lm.points.astype(np.float64)
    circles = np.array([[lm.iris_right.cx, lm.iris_right.cy],
                        [lm.iris_left.cx, lm.iris_left.cy]])
    pupils = np.array([lm.pupils()["3.6"], lm.pupils()["3.5"]])
    out = {
        "eye corners": np.linalg.norm(p[[36, 39, 42, 45]] - s[_S_EYE_CORNERS], axis=1),
        "mouth corners": np.linalg.norm(p[[48, 54]] - s[_S_MOUTH], axis=1),
        "pupils": np.linalg.norm(pupils - s[_S_PUPILS], axis=1),
        "pupils (circle centre)": np.linalg.norm(circles - s[_S_PUPILS], axis=1),
    }
    cont = _contours(lm)
    for name, idx in (("upper lids", _S_UPPER_LIDS), ("lower lids", _S_LOWER_LIDS)):
        out[name] = np.concatenate([_seg_dist(s[idx[:3]], cont[name][0]),
                                    _seg_dist(s[idx[3:]], cont[name][1])])
    lips = np.vstack(cont["inner lips"])  # one closed contour: the points fall on either lip
    out["inner lips"] = _seg_dist(s[_S_INNER_LIPS], lips)
    out["chin"] = np.linalg.norm(p[[8]] - s[[6]], axis=1)
    res = {k: 100.0 * float(v.mean()) / iod for k, v in out.items()}
    opened = float(np.linalg.norm(s[70] - s[67])) > 0.1 * iod  # inner lip middles apart
    res["chin (open mouths)"] = res["chin"] if opened else float("nan")
    res["inner lips (open mouths)"] = res["inner lips"] if opened else float("nan")
    res["inner lips (closed mouths)"] = float("nan") if opened else res["inner lips"]
    return res


def measure(jaffe: Path, detector: str) -> dict[str, float]:
    """Mean error per measure (% IOD) over every JAFFE photo with Stasm points."""
    feat_dir = jaffe / "landmarks_stasm77"
    names = (feat_dir / "all_names.txt").read_text().split()
    lines = (feat_dir / "all_features.txt").read_text().strip().splitlines()
    by_key = {(p.name.split(".")[0], p.name.split(".")[2]): p
              for p in (jaffe / "images").glob("*.tiff")}
    det = get_detector(detector)
    rows = []
    for name, line in zip(names, lines, strict=True):
        stasm = np.array(line.replace(",", " ").split(), float).reshape(77, 2)
        path = by_key[(name.split(".")[0], name.split(".")[2])]
        rows.append(errors(detect_landmarks(load_image(path), det), stasm))
    return {k: float(np.nanmean([r[k] for r in rows])) for k in MEASURES} | {"images": len(rows)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("jaffe", nargs="?", help="JAFFE folder (default ../shared/data/jaffe)")
    ap.add_argument("--detector", nargs="+", default=["mediapipe", "dlib"])
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    jaffe = Path(a.jaffe) if a.jaffe else checkout_jaffe_dir()
    if not (jaffe / "landmarks_stasm77" / "all_features.txt").is_file():
        sys.exit(f"landmark_accuracy: error: no JAFFE Stasm points under {jaffe}")
    res = {}
    for d in a.detector:
        try:
            res[d] = measure(jaffe, d)
        except FapStudioError as exc:
            print(f"{d}: skipped ({exc})", file=sys.stderr)
    if a.json:
        print(json.dumps(res))
        return
    dets = list(res)
    print(f"{'% of the inter-ocular distance':32s}" + "".join(f"{d:>12s}" for d in dets))
    for k in MEASURES:
        print(f"{k:32s}" + "".join(f"{res[d][k]:12.2f}" for d in dets))
    print(f"{'images':32s}" + "".join(f"{res[d]['images']:12d}" for d in dets))


if __name__ == "__main__":
    main()
