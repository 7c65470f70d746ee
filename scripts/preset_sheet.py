"""Preset contact sheet: neutral + each emotion preset at 100 % and 150 %, one row per face.

``python scripts/preset_sheet.py OUT.png [--jaffe DIR] [--people KA,KL,...] [--photo P ...]
[--tile 220]``. With ``--jaffe`` each JAFFE woman's row starts with her neutral photo and
ends with her real expression photos (first image of each), for side-by-side comparison.
Do not write sheets of JAFFE faces into the repository (research-only terms).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from editor.core import Face, save_image  # noqa: E402
from editor.engine.imageio import load_image  # noqa: E402
from editor.formats.presets import apply_preset  # noqa: E402
from editor.resources import SAMPLE_FACE  # noqa: E402
from editor.synthesis.jaffe import JAFFE_EMOTIONS  # noqa: E402

EMOTIONS = ("joy", "sadness", "surprise", "anger", "fear", "disgust")
JAFFE_CODE = {emotion: code for code, emotion in JAFFE_EMOTIONS.items()}


def tile(face: Face, img: np.ndarray, size: int, label: str) -> np.ndarray:
    x0, y0, x1, y1 = face.crop_box(0.35, 0.55, 0.35, 0.25)
    c = img[y0:y1, x0:x1]
    s = size / max(c.shape[:2])
    c = cv2.resize(c, None, fx=s, fy=s, interpolation=cv2.INTER_AREA if s < 1 else
                   cv2.INTER_CUBIC)
    out = np.full((size, size, 3), 255, np.uint8)
    out[: c.shape[0], : c.shape[1]] = c
    cv2.putText(out, label, (3, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 0), 1,
                cv2.LINE_AA)
    return out


#: with --extras: visemes, then gaze and lids (FAP values in their units)
EXTRAS: tuple[tuple[str, dict[str, float] | str], ...] = (
    ("viseme u", "viseme_u"), ("viseme aa", "viseme_aa"), ("viseme pbm", "viseme_pbm"),
    ("gaze left", {"yaw_l_eyeball": 30000, "yaw_r_eyeball": 30000}),
    ("gaze right", {"yaw_l_eyeball": -30000, "yaw_r_eyeball": -30000}),
    ("gaze up", {"pitch_l_eyeball": -25000, "pitch_r_eyeball": -25000}),
    ("gaze down", {"pitch_l_eyeball": 25000, "pitch_r_eyeball": 25000}),
    ("eyes closed", {"close_t_l_eyelid": 1080, "close_t_r_eyelid": 1080}),
)


def row(face: Face, size: int, reals: dict[str, Path] | None, render_kw: dict,
        extras: bool = False) -> np.ndarray:
    tiles = [tile(face, face.image, size, "photo"), tile(face, face.render(None), size,
                                                          "neutralised")]
    for e in EMOTIONS:
        for k in (1.0, 1.5):
            img = face.render(apply_preset(e, k), **render_kw)
            tiles.append(tile(face, img, size, f"{e} {int(k * 100)}"))
        if reals and e in reals:
            real = load_image(reals[e])
            try:
                rf = Face.from_image(reals[e])
                tiles.append(tile(rf, real, size, f"REAL {e}"))
            except Exception:  # noqa: BLE001
                tiles.append(tile(face, real, size, f"REAL {e}"))
    for label, what in EXTRAS if extras else ():
        vec = apply_preset(what, 1.0) if isinstance(what, str) else what
        tiles.append(tile(face, face.render(vec, **render_kw), size, label))
    return np.hstack(tiles)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--jaffe", default=None)
    ap.add_argument("--people", default="KA,KL,KM,KR,MK,NA,NM,TM,UY,YM")
    ap.add_argument("--photo", nargs="*", default=[])
    ap.add_argument("--tile", type=int, default=220)
    ap.add_argument("--no-sample", action="store_true")
    ap.add_argument("--extras", action="store_true",
                    help="add visemes u/aa/pbm, gaze left/right/up/down and closed eyes")
    args = ap.parse_args()
    photos = [] if args.no_sample else [SAMPLE_FACE]
    photos += [Path(p) for p in args.photo]
    rows = [row(Face.from_image(p), args.tile, None, {}, args.extras) for p in photos]
    if args.jaffe:
        d = Path(args.jaffe) / "images"
        for who in args.people.split(","):
            ne = sorted(d.glob(f"{who}.NE*.tiff"))
            if not ne:
                continue
            reals = {}
            for e, code in JAFFE_CODE.items():
                hits = sorted(d.glob(f"{who}.{code}*.tiff"))
                if hits:
                    reals[e] = hits[0]
            rows.append(row(Face.from_image(ne[0]), args.tile, reals, {}, args.extras))
    width = max(r.shape[1] for r in rows)
    rows = [np.pad(r, ((0, 0), (0, width - r.shape[1]), (0, 0)), constant_values=255)
            for r in rows]
    save_image(args.out, np.vstack(rows))


if __name__ == "__main__":
    main()
