"""Throughput rows of ``python -m editor.bench`` (issue 15), called from :func:`editor.bench.main`.

* ``animate_fps``: a 250-frame ``.fap`` (a joy ramp) rendered on the 1920 x 1080 sample
  canvas to H.264 MP4 with ``export_sequence`` as ``fap-studio animate`` runs it: the
  default ``jobs`` (a worker process per core while this process encodes; frames back
  through shared memory already yuv420p; pool start-up included), workers forked from this
  process (``start``) when :func:`~editor.engine.pool.fork_is_safe`; against rendering in
  this process (``jobs`` = 1, ``fps_serial``), N workers (``fps_jobsN``, N = the cores) and
  the editor's way (``fps_forkserver``: workers from a forkserver, each building the face)
  in the same run; ``cpu_ms_per_frame``: CPU time (this process, its threads and the
  workers) per frame, steadier than wall time on a shared machine; ``encode_only_fps``: the
  H.264 encoder alone (x264 preset veryfast, subme 1, CRF 16, as shipped) on 50 pre-rendered yuv420p
  frames, the ceiling whatever renders the frames; target >= 80 frames/s;
* ``fap_info``: ``fap-studio fap info`` on a 1 000 000-frame file, as a process (wall time and
  that child's own peak RSS (VmHWM); ``peak_rss_mb_tenth``: the same on a
  100 000-frame file, so flatness shows in one run); target <= 10 s;
* ``study_create``: the stimuli of 4 faces x 6 presets (``render_stimuli``: fit + render +
  crop; 1024-1536 px photos of the sample), in worker processes (a new pool each time, as
  each ``study create`` makes) against one after another, alternately, after a warm-up
  round, median of 3; target: faster than serial.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np


def _emit(d: dict) -> None:
    print(json.dumps(d), flush=True)


def main(want: Callable[..., bool], face_at: Callable[[tuple[int, int]], Any]) -> None:
    """The rows of this module that ``want`` asks for; ``face_at(size)`` makes the face."""
    if want("fap_info"):
        fap_info_bench()
    if want("animate_fps"):
        animate_fps_bench(face_at((1920, 1080)))
    if want("study_create"):
        study_create_bench()


def animate_fps_bench(face: Any, frames: int = 250, goal_fps: float = 80.0) -> None:
    from editor.engine.pool import default_jobs, default_render_jobs, fork_is_safe
    from editor.formats.fapfile import FapSequence
    from editor.formats.presets import apply_preset
    from editor.formats.video import export_sequence

    vec = apply_preset("joy", 1.0)
    seq = FapSequence(np.outer(np.sin(np.linspace(0, np.pi, frames)) ** 2, vec), fps=25)
    jobs, cores = default_render_jobs(), default_jobs()
    fork = fork_is_safe()  # as `fap-studio animate` (no Qt, no threads here)
    runs = {"fps": (None, fork), "fps_serial": (1, False), f"fps_jobs{cores}": (cores, fork),
            "fps_forkserver": (None, False)}  # the last: the editor's export (Qt: no fork)
    with tempfile.TemporaryDirectory() as d:
        t: dict[str, float] = {}
        cpu: dict[str, float] = {}
        for key, (j, f) in runs.items():
            if key != "fps" and (j, f) == runs["fps"]:
                continue
            c0, t0 = _cpu_seconds(), time.perf_counter()
            export_sequence(face, seq, Path(d) / f"{key}.mp4", jobs=j, fork=f)
            t[key], cpu[key] = time.perf_counter() - t0, _cpu_seconds() - c0
        enc = _encode_only_fps(face, seq.frames[:50], Path(d) / "e.mp4")
    t.setdefault(f"fps_jobs{cores}", t["fps"])
    fps = frames / t["fps"]
    h, w = face.image.shape[:2]
    _emit({"bench": "animate_fps", "size": f"{w}x{h}", "frames": frames, "jobs": jobs,
           "start": "fork" if fork else "forkserver", "fps": round(fps, 1),
           **{k: round(frames / v, 1) for k, v in t.items() if k != "fps"},
           "speedup": round(t["fps_serial"] / t["fps"], 2),
           "cpu_ms_per_frame": round(1000 * cpu["fps"] / frames, 1),
           "cpu_ms_per_frame_serial": round(1000 * cpu["fps_serial"] / frames, 1),
           "encode_only_fps": round(enc, 1),
           "goal": f">= {goal_fps:g} frames/s (H.264, {cores} cores)", "ok": fps >= goal_fps})


def _cpu_seconds() -> float:
    """CPU time of this process, its threads and its finished children (the render workers):
    the work an export costs, whatever else the machine runs."""
    import resource

    return sum(r.ru_utime + r.ru_stime for r in (resource.getrusage(resource.RUSAGE_SELF),
                                                  resource.getrusage(resource.RUSAGE_CHILDREN)))


def _encode_only_fps(face: Any, vecs: np.ndarray, out: Path) -> float:
    """Frames/s of the H.264 encoder alone (the shipped settings) on pre-rendered frames,
    already yuv420p (as the render workers hand them over): the ceiling of ``animate_fps``
    whatever renders them."""
    from editor.engine.yuv import rgb_to_i420
    from editor.formats.video import VideoWriter

    imgs = [rgb_to_i420(face.render(v)) for v in vecs]
    h, w = face.image.shape[:2]
    t0 = time.perf_counter()
    with VideoWriter(out, (w, h), 25.0) as wr:
        for im in imgs:
            wr.write(im)
    return len(imgs) / (time.perf_counter() - t0)


def _study_faces(folder: Path) -> list[Path]:
    """Four different photos of the sample, 1024-1536 px (camera photos are larger than the
    512-px sample): scaled x2, mirrored x2, x2.5, x3."""
    import cv2

    from .resources import SAMPLE_FACE

    img = cv2.imread(str(SAMPLE_FACE))
    if img is None:
        raise RuntimeError(f"cannot read {SAMPLE_FACE}")
    out = []
    for name, im, k in (("a", img, 2.0), ("b", img[:, ::-1], 2.0), ("c", img, 2.5),
                        ("d", img, 3.0)):
        p = folder / f"{name}.png"
        cv2.imwrite(str(p), cv2.resize(np.ascontiguousarray(im), None, fx=k, fy=k,
                                       interpolation=cv2.INTER_CUBIC))
        out.append(p)
    return out


def study_create_bench() -> None:
    from editor.engine.pool import default_jobs
    from editor.study.stimuli import render_stimuli

    presets = ["joy", "sadness", "anger", "fear", "surprise", "disgust"]
    jobs = default_jobs()
    with tempfile.TemporaryDirectory() as d:
        faces = _study_faces(Path(d))
        t: dict[int, list[float]] = {jobs: [], 1: []}
        for i in range(4):  # alternately: a warm-up round (imports, models), then 3 timed
            for j in (jobs, 1):
                t0 = time.perf_counter()
                render_stimuli(faces, presets, [1.0], jobs=j)
                if i:
                    t[j].append(time.perf_counter() - t0)
    par, ser = float(np.median(t[jobs])), float(np.median(t[1]))
    _emit({"bench": "study_create", "faces": 4, "presets": 6, "photo_px": "1024-1536",
           "jobs": jobs,
           "seconds": round(par, 3), "seconds_serial": round(ser, 3),
           "speedup": round(ser / par, 2), "goal": f"< serial ({jobs} cores)",
           "ok": par < ser})


def write_long_fap(path: Path, frames: int) -> None:
    """A ``.fap`` of ``frames`` frames (a few FAPs moving), written in blocks (no big string)."""
    mask = ["0"] * 68
    for i in (2, 3, 4, 11, 12, 18, 19, 30, 31, 47):
        mask[i] = "1"
    mask_line = " ".join(mask)
    block = 1000
    with open(path, "w", encoding="ascii") as fh:
        fh.write(f"2.1 long 25 {frames}\n")
        k = 0
        while k < frames:
            n = min(block, frames - k)
            lines = []
            for i in range(k, k + n):
                v = (i * 7) % 401 - 200
                lines.append(f"{mask_line}\n{i} {v} {-v} {v // 2} 10 -10 {v} {v} 30 40 {i % 100}")
            fh.write("\n".join(lines) + "\n")
            k += n


#: The child of ``fap_info``: the CLI in a fresh process, then its own peak RSS (VmHWM, KiB) as
#: the last line on stderr (``ru_maxrss`` of a child keeps the parent's peak across exec).
_FAP_INFO_CHILD = """
import sys
from editor.cli import main
code = main(["fap", "info", sys.argv[1]])
with open("/proc/self/status") as f:
    peak = next(int(x.split()[1]) for x in f if x.startswith("VmHWM:"))
print(f"VmHWM {peak}", file=sys.stderr)
sys.exit(code)
"""


def _fap_info_run(path: Path) -> tuple[subprocess.CompletedProcess, float, int]:
    """``fap-studio fap info path`` as a process: (result, seconds, its own peak RSS KiB)."""
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-c", _FAP_INFO_CHILD, str(path)],
                       capture_output=True, text=True, check=False)
    seconds = time.perf_counter() - t0
    lines = r.stderr.strip().splitlines()
    peak = int(lines[-1].split()[1]) if lines and lines[-1].startswith("VmHWM ") else -1
    r.stderr = "\n".join(lines[:-1]) if peak >= 0 else r.stderr
    return r, seconds, peak


def fap_info_bench(frames: int = 1_000_000, goal_s: float = 10.0) -> None:
    with tempfile.TemporaryDirectory() as d:
        small = Path(d) / "small.fap"  # a tenth: the peak must not grow with the length
        write_long_fap(small, frames // 10)
        _, _, peak_small = _fap_info_run(small)
        path = Path(d) / "long.fap"
        write_long_fap(path, frames)
        size_mb = path.stat().st_size / 2**20
        r, seconds, peak = _fap_info_run(path)
    row = {"bench": "fap_info", "frames": frames, "file_mb": round(size_mb, 1),
           "seconds": round(seconds, 2), "peak_rss_mb": round(peak / 1024, 1),
           "peak_rss_mb_tenth": round(peak_small / 1024, 1),
           "goal": f"<= {goal_s:g} s, peak memory flat in the file length",
           "ok": r.returncode == 0 and seconds <= goal_s}
    if r.returncode != 0:
        row["error"] = r.stderr.strip()[-300:]
    _emit(row)
