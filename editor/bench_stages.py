"""The ``render_stages`` row of ``python -m editor.bench``: what each step of a render costs.

Issue 21 asks for the per-frame cost of what it added to the engine (the photo's own
expression, a mouth made from the photo, the eyes, creases). ``render_vs_engine`` gives the
total; this row splits the render of the bench's expression into its steps, in this thread's
CPU time (median ms over ``n`` renders), each named with the item it serves:

* ``warp``: the engine's warp (with the jaw's hook, :mod:`~editor.engine.jawband`);
* ``grain`` (the photo's grain the resampling loses), ``lid_skin`` (eyes: the lid skin a
  raised or lowered lid uncovers), ``lip_seal``/``contact_line`` (own expression: the lips a
  neutralised open mouth closes), ``lip_tone``/``lip_rims`` (mouth: the lips' shade and rims),
  ``layers`` (mouth interior and eyeballs), ``creases``, ``chin_boss``, ``own_cheeks`` (own
  expression: a smile's lit cheek undone), ``cheeks`` (creases: a smile's cheek shade);
* ``rest``: each render less its steps (deformation, the openings' transforms, glue).

The steps are timed by wrapping the functions :meth:`Face.render_mesh
<editor.engine.face.Face.render_mesh>` calls, for the time of the row only (the wrapping's own
cost, about a microsecond a step, lands in the steps). The render's total is timed without the
wrappers.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

#: the functions of :mod:`editor.engine.face` that ``render_mesh`` calls, by step name
STAGES = {"warp": "warp", "grain": "apply_grain", "lid_skin": "apply_lid_skin",
          "lip_seal": "apply_lip_seal", "lip_tone": "apply_lip_tone",
          "lip_rims": "apply_lip_rims", "layers": "render_layers",
          "contact_line": "apply_contact_line", "creases": "apply_creases",
          "chin_boss": "apply_chin_boss", "own_cheeks": "apply_own_cheeks",
          "cheeks": "apply_cheeks"}


@contextmanager
def _timed_steps(acc: dict[str, float]) -> Iterator[None]:
    """Within the block, each step of :data:`STAGES` adds its thread CPU seconds to
    ``acc[step]`` (the module's functions restored on the way out, whatever happens)."""
    from editor.engine import face as face_module

    saved = {name: getattr(face_module, name) for name in STAGES.values()}

    def wrap(step: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        def timed(*args: Any, **kwargs: Any) -> Any:
            t0 = time.thread_time()
            try:
                return fn(*args, **kwargs)
            finally:
                acc[step] = acc.get(step, 0.0) + time.thread_time() - t0
        return timed

    try:
        for step, name in STAGES.items():
            setattr(face_module, name, wrap(step, saved[name]))
        yield
    finally:
        for name, fn in saved.items():
            setattr(face_module, name, fn)


def stage_costs(face: Any, vec: np.ndarray, n: int = 40, warm: int = 3) -> dict[str, Any]:
    """Median thread CPU ms of ``face.render(vec)`` (``render_ms``, unwrapped) and of each of
    its steps (``steps``: name -> ms; ``rest``: each wrapped render less its steps, median)."""
    for _ in range(warm):
        face.render(vec)
    total = []
    for _ in range(n):
        t0 = time.thread_time()
        face.render(vec)
        total.append(time.thread_time() - t0)
    per: dict[str, list[float]] = {step: [] for step in (*STAGES, "rest")}
    acc: dict[str, float] = {}
    with _timed_steps(acc):
        for _ in range(n):
            acc.clear()
            t0 = time.thread_time()
            face.render(vec)
            t = time.thread_time() - t0
            for step in STAGES:
                per[step].append(acc.get(step, 0.0))
            per["rest"].append(t - sum(acc.values()))
    steps = {step: round(float(np.median(v)) * 1000.0, 3) for step, v in per.items()}
    return {"render_ms": round(float(np.median(total)) * 1000.0, 3), "steps": steps}
