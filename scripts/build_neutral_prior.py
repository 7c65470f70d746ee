"""Build the neutral-shape prior (``editor/data/neutral_prior.json``) from neutral photos.

``python scripts/build_neutral_prior.py IMAGES_DIR [-o editor/data/neutral_prior.json]``.
Every ``*.NE*.*`` image (JAFFE naming: ``PERSON.NEn.ID.ext``) is a neutral photo of the person
named before the first dot; any folder of neutral photos named that way works. Only summary
statistics are written (mean shape, identity-mode spreads, per-point noise), no image data.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from editor.core import detect_landmarks, load_image  # noqa: E402
from editor.engine.landmarks import default_detector  # noqa: E402
from editor.engine.own_expression import NeutralPrior, canonical  # noqa: E402
from editor.errors import NoFaceError  # noqa: E402
from editor.resources import NEUTRAL_PRIOR, source_path  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("images")
    ap.add_argument("-o", "--output", help="default: editor/data/neutral_prior.json")
    a = ap.parse_args()
    people: dict[str, list[np.ndarray]] = {}
    files = sorted(p for p in Path(a.images).iterdir() if ".NE" in p.name)
    for p in files:
        try:
            pts = detect_landmarks(load_image(p)).points
        except NoFaceError:
            print(f"{p.name}: no face, skipped", file=sys.stderr)
            continue
        people.setdefault(p.name.split(".")[0], []).append(canonical(pts))
    shapes = [np.array(v) for v in people.values()]
    n = sum(len(v) for v in shapes)
    prior = NeutralPrior.from_shapes(
        shapes, f"{default_detector().name} landmarks of {n} neutral photos of {len(shapes)} "
        "people "
        f"({Path(a.images).resolve().parent.name} '*.NE*' images; summary statistics only: "
        "mean shape made left/right symmetric, spread of each identity mode over the people "
        "x 1.5, at least 0.04 IOD, the mouth corners' height 0.015 IOD, per-point residual); "
        "built by scripts/build_neutral_prior.py")
    out = Path(a.output) if a.output else source_path(NEUTRAL_PRIOR)
    out.write_text(json.dumps(prior.to_json(), indent=1) + "\n", "utf-8")
    for name, s in zip(prior.names, prior.sigma, strict=True):
        print(f"{name:15s} sigma {s:.4f} IOD")
    print(f"noise per point: median {np.median(prior.noise):.4f}, max {prior.noise.max():.4f}")


if __name__ == "__main__":
    main()
