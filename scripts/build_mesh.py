"""Build the standard mesh (editor/data/mesh.json) and draw it (docs/mesh.png).

The topology is designed once on a template face: the landmarks of the bundled sample photo,
made left/right symmetric and scaled to an inter-ocular distance of 100. Every vertex is placed
by the rules of ``editor.engine.fitting`` (the same code that fits the mesh on any photo); the
triangles are a constrained Delaunay triangulation (Shewchuk's Triangle, ``pip install triangle``,
needed only here) with the eye and mouth openings as holes and the feature curves as
constrained edges. Run from the repository root: ``python scripts/build_mesh.py``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from editor.engine import meshdef  # noqa: E402
from editor.engine.fitting import MARGIN_COUNT, FaceFrame, fit_vertices  # noqa: E402
from editor.engine.imageio import load_image, save_image  # noqa: E402
from editor.engine.landmarks import MIRROR_68, detect_landmarks  # noqa: E402
from editor.resources import MESH, SAMPLE_FACE, source_path  # noqa: E402


def template_landmarks() -> tuple[np.ndarray, tuple[int, int]]:
    img = load_image(SAMPLE_FACE)
    lm = detect_landmarks(img)
    fr = FaceFrame.from_points(lm.points)
    q = fr.to_frame(lm.points)
    m = q[MIRROR_68].copy()
    m[:, 0] *= -1
    sym = 0.5 * (q + m)
    iod = np.linalg.norm(sym[42:48].mean(0) - sym[36:42].mean(0))
    sym *= 100.0 / iod
    size = (420, 520)
    return sym + np.array([210.0, 200.0]), size


def chain(names: list[str], closed: bool) -> list[tuple[str, str]]:
    pairs = list(zip(names[:-1], names[1:], strict=True))
    if closed:
        pairs.append((names[-1], names[0]))
    return pairs


def main() -> None:
    import triangle

    pts, size = template_landmarks()
    verts, _ = fit_vertices(pts, size)
    names = list(verts)
    xy = np.array([verts[n] for n in names])
    idx = {n: i for i, n in enumerate(names)}

    segs: list[tuple[str, str]] = []
    holes = {"eye_r": meshdef.eye_hole("r"), "eye_l": meshdef.eye_hole("l"),
             "mouth": meshdef.mouth_hole()}
    for h in holes.values():
        segs += chain(h, True)
    segs += chain([f"contour_{i}" for i in range(33)], False)
    segs += chain(["contour_0"] + [f"hair_{k}" for k in range(1, 12)] + ["contour_32"], False)
    outer = (["lipo_c0"] + [f"lipo_u{k}" for k in range(1, 8)] + ["lipo_c1"]
             + [f"lipo_d{k}" for k in range(7, 0, -1)])
    segs += chain(outer, True)
    for s in "rl":
        segs += chain([f"brow_{s}_e0"] + [f"brow_{s}_u{k}" for k in range(1, 6)]
                      + [f"brow_{s}_e1"], False)
    segs += chain([f"margin_{k}" for k in range(MARGIN_COUNT)], True)
    segs += chain([f"border_{k}" for k in range(MARGIN_COUNT)], True)
    hole_pts = [xy[[idx[n] for n in h]].mean(0) for h in holes.values()]
    tri = triangle.triangulate(
        {"vertices": xy, "segments": np.array([[idx[a], idx[b]] for a, b in segs]),
         "holes": np.array(hole_pts)}, "p")
    if len(tri["vertices"]) != len(xy):
        raise SystemExit("triangulation added Steiner points: fix the vertex rules")
    t = np.asarray(tri["triangles"], np.int64)
    # Orient every triangle counter-clockwise on screen (positive signed area in y-down coords
    # means clockwise visually; we store positive sigma as in SPEC eq. 3).
    a, b, c = xy[t[:, 0]], xy[t[:, 1]], xy[t[:, 2]]
    sigma = (c[:, 0] - a[:, 0]) * (c[:, 1] - b[:, 1]) - (c[:, 1] - a[:, 1]) * (c[:, 0] - b[:, 0])
    t[sigma < 0] = t[sigma < 0][:, [0, 2, 1]]

    vertices = [{"name": n, "region": meshdef.region_of(n),
                 **({"fdp": meshdef.FDP_OF_VERTEX[n]} if n in meshdef.FDP_OF_VERTEX else {}),
                 "template": [round(float(x), 3) for x in xy[i]]} for i, n in enumerate(names)]
    out = {
        "format": "fap-studio-mesh", "version": 1,
        "note": "Standard face mesh of FAP Studio; built by scripts/build_mesh.py.",
        "template_size": list(size),
        "vertices": vertices,
        "triangles": t.tolist(),
        "holes": holes,
    }
    source_path(MESH).write_text(json.dumps(out, separators=(",", ":")))
    regions = {}
    for v in vertices:
        regions[v["region"]] = regions.get(v["region"], 0) + 1
    face_v = sum(n for r, n in regions.items() if r not in ("margin", "border"))
    print(f"{len(xy)} vertices ({face_v} face), {len(t)} triangles; regions {regions}")
    draw(xy, t, names, holes, ROOT / "docs" / "mesh.png")


COLOURS = {"eye_contour": (40, 120, 255), "eyebrow": (150, 80, 20), "nose": (0, 160, 0),
           "mouth": (220, 0, 0), "contour": (0, 0, 0), "forehead": (150, 0, 150),
           "cheek": (230, 140, 0), "jaw": (0, 150, 150), "ear": (120, 120, 0),
           "margin": (120, 120, 120), "border": (180, 180, 180)}


def draw(xy: np.ndarray, t: np.ndarray, names: list[str], holes: dict, path: Path) -> None:
    s = 2.0
    w, h = int((xy[:, 0].max() + 20) * s), int((xy[:, 1].max() + 20) * s)
    img = np.full((h, w, 3), 255, np.uint8)
    for name in holes:
        poly = np.round(xy[[names.index(n) for n in holes[name]]] * s).astype(np.int32)
        cv2.fillPoly(img, [poly], (255, 235, 235))
    for tri in t:
        p = np.round(xy[tri] * s).astype(np.int32)
        cv2.polylines(img, [p], True, (170, 170, 170), 1, cv2.LINE_AA)
    for i, n in enumerate(names):
        col = COLOURS[meshdef.region_of(n)]
        p = tuple(int(v) for v in np.round(xy[i] * s))
        cv2.circle(img, p, 3, col, -1, cv2.LINE_AA)
        if n in meshdef.FDP_OF_VERTEX:
            cv2.putText(img, meshdef.FDP_OF_VERTEX[n], (p[0] + 3, p[1] - 3),
                        cv2.FONT_HERSHEY_SIMPLEX, 0.3, (0, 0, 0), 1, cv2.LINE_AA)
    y = 16
    for region, col in COLOURS.items():
        cv2.circle(img, (12, y - 4), 4, col, -1)
        cv2.putText(img, region, (22, y), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1,
                    cv2.LINE_AA)
        y += 16
    save_image(path, img)


if __name__ == "__main__":
    main()
