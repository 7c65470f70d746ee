"""Draw the default detector's dense contours on a photo's face, enlarged (issue 14's check).

``python scripts/landmark_overlay.py PHOTO -o out.png [--zoom 4] [--compare-dlib]``

Lid contours green, inner lips yellow, outer lips, brows and face oval blue, iris circles
magenta with their visible parts' centres (:meth:`Landmarks.pupils`) as magenta dots, the 68
iBUG-equivalent points as white crosses; ``--compare-dlib`` adds dlib's 68 points as red dots
(when its extra is installed). The face region is cut out and enlarged with
bicubic interpolation so that sub-pixel placement can be judged by eye.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from editor.engine.facemesh import CONTOURS  # noqa: E402
from editor.engine.imageio import load_image, save_image  # noqa: E402
from editor.engine.landmarks import detect_landmarks, get_detector  # noqa: E402
from editor.resources import SAMPLE_FACE  # noqa: E402

COLOURS = {"eye": (0, 255, 0), "lips_inner": (255, 255, 0), "other": (0, 200, 255)}  # RGB


def overlay(rgb: np.ndarray, zoom: int = 4, compare_dlib: bool = False) -> np.ndarray:
    lm = detect_landmarks(rgb, get_detector("mediapipe"))
    assert lm.mesh is not None
    x0, y0, x1, y1 = lm.box
    cx, cy, s = (x0 + x1) / 2, (y0 + y1) / 2, 0.75 * max(x1 - x0, y1 - y0)
    bx0, by0 = int(max(0, cx - s)), int(max(0, cy - 0.8 * s))
    bx1, by1 = int(min(rgb.shape[1], cx + s)), int(min(rgb.shape[0], cy + 1.1 * s))
    out = cv2.resize(rgb[by0:by1, bx0:bx1], None, fx=zoom, fy=zoom,
                     interpolation=cv2.INTER_CUBIC).copy()
    sh = 4  # fixed-point bits for sub-pixel drawing

    def px(p: np.ndarray) -> np.ndarray:  # image pixel centres -> enlarged pixel centres
        return ((np.asarray(p, np.float64) - (bx0, by0)) * zoom + (zoom - 1) / 2) * (1 << sh)

    for name, idx in CONTOURS.items():
        col = COLOURS["eye" if name.startswith("eye") else
                      "lips_inner" if name.startswith("lips_inner") else "other"]
        pts = np.round(px(lm.mesh[list(idx)])).astype(np.int32)
        cv2.polylines(out, [pts], False, col, 1, cv2.LINE_AA, sh)
    for iris in (lm.iris_left, lm.iris_right):
        c = np.round(px([iris.cx, iris.cy])).astype(int)
        cv2.circle(out, (int(c[0]), int(c[1])), int(round(iris.r * zoom * (1 << sh))),
                   (255, 0, 255), 1, cv2.LINE_AA, sh)
    for x, y in lm.pupils().values():  # the visible irises' centres: magenta dots
        c = np.round(px([x, y])).astype(int)
        cv2.circle(out, (int(c[0]), int(c[1])), 2 * (1 << sh), (255, 0, 255), -1, cv2.LINE_AA, sh)
    if compare_dlib:
        for p in px(detect_landmarks(rgb, get_detector("dlib")).points) / (1 << sh):
            cv2.circle(out, (int(p[0]), int(p[1])), 3, (255, 0, 0), -1)
    for p in px(lm.points) / (1 << sh):
        cv2.drawMarker(out, (int(p[0]), int(p[1])), (255, 255, 255), cv2.MARKER_CROSS, 7, 1)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("photo", nargs="?", default=str(SAMPLE_FACE))
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--zoom", type=int, default=4)
    ap.add_argument("--compare-dlib", action="store_true")
    a = ap.parse_args()
    save_image(a.output, overlay(load_image(a.photo), a.zoom, a.compare_dlib))


if __name__ == "__main__":
    main()
