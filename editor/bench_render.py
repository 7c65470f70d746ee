"""The render rows of ``python -m editor.bench`` (issue 15), each timed against its floor in
the same loop (alternately, so that machine load affects both alike):

* ``fap_to_image`` and ``remap_full_frame`` at 3840 x 2160 (the sample upscaled, a face about
  1000 px wide); goal: the render at most 1.0 x the full-frame remap;
* ``fap_to_image_head_rotation`` at 1920 x 1080: FAPs 48-50 non-zero plus the bench's
  expression; goal: at most 1.5 x ``remap_full_frame`` at 1920 x 1080 (``floor_ms``);
* ``warp_plan_build`` at 1920 x 1080: what the first render of a face builds once (the warp
  plan, the eye/mouth layer plans, the crease plan, ...), i.e. the first render of a fresh face
  minus a steady render; goal: at most 2 x ``remap_full_frame`` at 1920 x 1080.

The helpers of :mod:`editor.bench` (the sample at a size, the alternating timer, the
expression) come in as arguments (``python -m editor.bench`` imports this module, not the
other way round).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np


@dataclass(frozen=True)
class Helpers:
    """What the rows need of :mod:`editor.bench`."""

    emit: Callable[[dict], None]
    face_at: Callable[[tuple[int, int]], Any]  # the sample fitted to a frame size
    time_pair: Callable[..., dict[str, float]]  # two callables timed alternately
    expression: dict

#: FAPs 48-50 (head pitch, yaw, roll; 1e-5 rad) of the head-rotation row: about 8, 11 and 9
#: degrees, as in Xface's .fap files
HEAD_ROTATION = {48: 14000, 49: -20000, 50: 16000}


def _remap_floor(image: np.ndarray) -> Callable[[], object]:
    h, w = image.shape[:2]
    mx, my = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    mx += 0.3
    return lambda: cv2.remap(image, mx, my, cv2.INTER_LINEAR)


def _row(name: str, size: str, ms: float, floor_ms: float, k: float, extra: dict | None = None
         ) -> dict:
    ratio = ms / floor_ms
    return {"bench": name, "size": size, "median_ms": round(ms, 3), **(extra or {}),
            "floor_ms": round(floor_ms, 3), "ratio": round(ratio, 2),
            "goal": f"<= {k} x remap_full_frame {size}", "ok": bool(ratio <= k)}


def _face_wide(hp: Helpers, size: tuple[int, int], width: float):
    """A fitted face whose jaw contour is ``width`` px wide: the sample upscaled (cubic, as
    the bench's ``_face_at``), cropped to ``size`` around the face, padded by reflection."""
    from .engine.face import Face
    from .engine.imageio import load_image
    from .resources import SAMPLE_FACE

    small = hp.face_at((512, 512))
    s = width / _face_width(small)
    big = cv2.resize(load_image(SAMPLE_FACE), None, fx=s, fy=s, interpolation=cv2.INTER_CUBIC)
    v, m = small.vertices, small.mesh
    cx = 0.5 * (v[m.index("contour_0"), 0] + v[m.index("contour_32"), 0]) * s
    cy = 0.5 * (v[m.fdp["11.1"], 1] + v[m.fdp["2.1"], 1]) * s
    w, h = size
    pad = max(w, h)
    big = cv2.copyMakeBorder(big, pad, pad, pad, pad, cv2.BORDER_REFLECT_101)
    x0, y0 = int(round(cx - w / 2)) + pad, int(round(cy - h / 2)) + pad
    face = Face.from_image(np.ascontiguousarray(big[y0:y0 + h, x0:x0 + w]))
    if abs(face.interocular - small.interocular * s) > 0.15 * small.interocular * s:
        raise RuntimeError(f"benchmark face at {size} is not the sample's face")
    return face


def render_4k_rows(hp: Helpers, n: int = 15) -> None:
    """``fap_to_image`` and ``remap_full_frame`` at 3840x2160, a face 1000 px wide."""
    from .engine.faps import FAPS

    emit = hp.emit
    face = _face_wide(hp, (3840, 2160), 1000.0)
    vec = FAPS.clamp(FAPS.vector(hp.expression))
    face.render(vec)
    p = hp.time_pair(lambda: face.render(vec), _remap_floor(face.image), n)
    res = {"interocular_px": round(face.interocular, 1),
           "face_width_px": round(_face_width(face), 1)}
    emit(_row("fap_to_image", "3840x2160", p["a_ms"], p["b_ms"], 1.0, res))
    emit({"bench": "remap_full_frame", "size": "3840x2160", "median_ms": round(p["b_ms"], 3)})


def _face_width(face) -> float:
    """Width of the face (the mesh's jaw contour), pixels."""
    m = face.mesh
    return float(face.vertices[m.index("contour_32"), 0] - face.vertices[m.index("contour_0"), 0])


def head_rotation_row(hp: Helpers, n: int = 20) -> None:
    """``fap_to_image_head_rotation`` at 1920x1080."""
    from .engine.faps import FAPS

    face = hp.face_at((1920, 1080))
    vec = FAPS.clamp(FAPS.vector({**hp.expression, **HEAD_ROTATION}))
    face.render(vec)
    p = hp.time_pair(lambda: face.render(vec), _remap_floor(face.image), n)
    hp.emit(_row("fap_to_image_head_rotation", "1920x1080", p["a_ms"], p["b_ms"], 1.5,
              {"faps_48_50": list(HEAD_ROTATION.values())}))


def warp_plan_row(hp: Helpers, n: int = 9) -> None:
    """``warp_plan_build`` at 1920x1080: first render of a fresh face minus a steady one."""
    from .engine.faps import FAPS

    face = hp.face_at((1920, 1080))
    vec = FAPS.clamp(FAPS.vector(hp.expression))
    face.render(vec)  # imports, module-level caches
    floor = _remap_floor(face.image)
    build, first, steady, fl = [], [], [], []
    for _ in range(n):
        fresh = face.with_vertices(face.vertices)  # same face, no per-face plans yet
        t0 = time.perf_counter()
        fresh.render(vec)
        t1 = time.perf_counter()
        fresh.render(vec)
        t2 = time.perf_counter()
        floor()
        t3 = time.perf_counter()
        first.append(t1 - t0)
        steady.append(t2 - t1)
        build.append((t1 - t0) - (t2 - t1))
        fl.append(t3 - t2)
    ms = 1000.0 * float(np.median(build))
    hp.emit(_row("warp_plan_build", "1920x1080", ms, 1000.0 * float(np.median(fl)), 2.0,
              {"first_render_ms": round(1000.0 * float(np.median(first)), 3),
               "steady_render_ms": round(1000.0 * float(np.median(steady)), 3)}))


def render_rows(hp: Helpers, want: Callable[..., bool]) -> None:
    """Every row of this module that ``want`` asks for."""
    if want("fap_to_image", "remap_full_frame"):
        render_4k_rows(hp)
    if want("fap_to_image_head_rotation"):
        head_rotation_row(hp)
    if want("warp_plan_build"):
        warp_plan_row(hp)
