"""Contact sheet: every FAP group at -max and +max on one or more faces.

``python scripts/contact_sheet.py OUT.png PHOTO [PHOTO ...]`` (``sample``: the bundled face).
Rows are the MPEG-4 FAP groups (all FAPs of the group at the end of their range together),
columns -max / +max per face. Used to look for tears, seams and frozen patches. Do not write
sheets of JAFFE faces into the repository (research-only terms).
"""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from editor.cli.util import photo_arg  # noqa: E402
from editor.core import FAPS, Face, save_image  # noqa: E402

TILE = 170


def crop(face: Face, img: np.ndarray) -> np.ndarray:
    x0, y0, x1, y1 = face.crop_box(0.6, 1.0, 0.6, 0.6)
    c = img[y0:y1, x0:x1]
    s = TILE / max(c.shape[:2])
    c = cv2.resize(c, None, fx=s, fy=s, interpolation=cv2.INTER_AREA if s < 1 else
                   cv2.INTER_CUBIC)
    out = np.full((TILE, TILE, 3), 255, np.uint8)
    out[: c.shape[0], : c.shape[1]] = c
    return out


def main() -> None:
    out_path, photos = sys.argv[1], sys.argv[2:]
    faces = [Face.from_image(photo_arg(p)) for p in photos]
    rows = []
    for g, faps in FAPS.groups().items():
        tiles = []
        for face in faces:
            for end in (0, 1):
                vec = np.zeros(68, np.float32)
                for f in faps:
                    vec[f.number - 1] = f.range[end]
                t = crop(face, face.render(vec))
                label = f"G{g} {'-' if end == 0 else '+'}max"
                cv2.putText(t, label, (3, 12), cv2.FONT_HERSHEY_SIMPLEX, 0.38, (255, 255, 0), 1,
                            cv2.LINE_AA)
                tiles.append(t)
        rows.append(np.hstack(tiles))
    save_image(out_path, np.vstack(rows))


if __name__ == "__main__":
    main()
