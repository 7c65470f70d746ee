"""Start-up benchmark rows of ``python -m editor.bench`` (issue 15), each in its own process:

* ``cli_help_s``: ``fap-studio --help`` as a process (interpreter start included); target
  <= 0.3 s;
* ``gui_ready_s``: process start to a usable editor window (offscreen, isolated settings): the
  window visible and its event loop running (a timer fired), while the sample face opens on
  the thread pool; target <= 1.5 s. ``document_ready_s``: until the face's document is loaded
  (sliders act on it);
* ``gui_open_gap_ms``: the longest the editor's event loop stalls (a 10 ms timer's longest gap)
  while it opens a 12 MP photo (decode, fit, first render on workers, the result shown), in a
  window that has opened the sample face before; target <= 100 ms (nothing a user notices);
* ``imread`` and ``open_fit_render``: ``cv2.imread`` of a 24 MP JPEG, and opening it as the
  editor does (load, landmarks, mesh fit, own-expression estimate, first render of an
  expression), in a process that has opened the sample face before (imports done, models
  loaded: the editor opening a second photo); target: open_fit_render <= 4 x imread of the
  same file, and its peak memory (``peak_rss_mb``, the whole process, measured in a fresh one)
  <= 6 x the decoded image size + 300 MB. The JPEG is made at run time from the sample face
  (upscaled, with noise); never shipped.

Each row carries ``"goal"`` and ``"ok"`` (``--check`` exits 1 when a row is not ok).
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

#: The directory holding the ``editor`` package (children import the same code).
_ROOT = str(Path(__file__).resolve().parent.parent)

CLI_HELP_GOAL_S = 0.3
GUI_READY_GOAL_S = 1.5
OPEN_FIT_RENDER_GOAL_RATIO = 4.0
BIG_SIZE = (6000, 4000)  # 24 MP


def _env(**extra: str) -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([_ROOT, *filter(None, [env.get("PYTHONPATH")])])
    env.update(extra)
    return env


def _run(args: list[str], env: dict[str, str] | None = None, timeout: float = 120
         ) -> subprocess.CompletedProcess[str]:
    # cwd: ``-c``/``-m`` put the working folder first on sys.path, before PYTHONPATH
    return subprocess.run([sys.executable, *args], capture_output=True, text=True,
                          env=env or _env(), timeout=timeout, check=True, cwd=_ROOT)


def cli_help_bench(emit: Callable[[dict], None], n: int = 7) -> None:
    """``fap-studio --help`` (``python -m editor.cli --help``, the console script's code)."""
    times = []
    for _ in range(n + 1):  # the first run warms the file cache
        t0 = time.perf_counter()
        out = _run(["-m", "editor.cli", "--help"])
        times.append(time.perf_counter() - t0)
        if "usage: fap-studio" not in out.stdout:
            raise RuntimeError(f"fap-studio --help printed {out.stdout[:200]!r}")
    s = statistics.median(times[1:])
    emit({"bench": "cli_help_s", "seconds": round(s, 3), "n": n,
          "goal": f"<= {CLI_HELP_GOAL_S} s", "ok": s <= CLI_HELP_GOAL_S})


#: The child of ``gui_ready_s``: the editor as ``fap-studio`` starts it (``run()``), with a
#: timer polling for the first moment the window is visible with its document loaded.
_GUI_CHILD = r"""
import sys, time
from PySide6.QtCore import QTimer
from editor.ui.app import application, run
from editor.ui.main_window import MainWindow

app = application()
shown = []

def poll():
    wins = [w for w in app.topLevelWidgets() if isinstance(w, MainWindow) and w.isVisible()]
    if wins and not shown:
        shown.append(time.time())
    if wins and wins[0].model.doc is not None:
        print(f"READY {shown[0]!r} {time.time()!r}", flush=True)
        wins[0].close_without_prompt()
        app.quit()
        return
    QTimer.singleShot(5, poll)

QTimer.singleShot(0, poll)
sys.exit(run())
"""


def gui_ready_bench(emit: Callable[[dict], None], n: int = 5) -> None:
    """Process start -> usable window, offscreen, with settings in a fresh folder."""
    ready, shown = [], []
    with tempfile.TemporaryDirectory(prefix="fap-bench-gui-") as home:
        env = _env(QT_QPA_PLATFORM="offscreen", HOME=home, XDG_CONFIG_HOME=home,
                   XDG_CACHE_HOME=home)
        for i in range(n + 1):
            t0 = time.time()
            out = _run(["-c", _GUI_CHILD], env=env)
            line = next((x for x in out.stdout.splitlines() if x.startswith("READY")), None)
            if line is None:
                raise RuntimeError(f"the editor did not become ready: {out.stderr[-500:]}")
            if i:  # the first run warms the file cache
                _, a, b = line.split()
                shown.append(float(a) - t0)
                ready.append(float(b) - t0)
    s = statistics.median(shown)
    emit({"bench": "gui_ready_s", "seconds": round(s, 3),
          "document_ready_s": round(statistics.median(ready), 3), "n": n,
          "goal": f"<= {GUI_READY_GOAL_S} s (window visible, event loop running)",
          "ok": s <= GUI_READY_GOAL_S})


#: The child of ``gui_open_gap_ms``: the editor opens a 12 MP photo while a 10 ms timer on the
#: GUI thread records its longest gap.
_GAP_CHILD = r"""
import sys, time
import cv2
from PySide6.QtCore import QEventLoop, QTimer
from editor.resources import SAMPLE_FACE
from editor.ui.app import application
from editor.ui.main_window import MainWindow

big = sys.argv[1]
cv2.imwrite(big, cv2.resize(cv2.imread(str(SAMPLE_FACE)), (3000, 4000),
                            interpolation=cv2.INTER_CUBIC))
app = application()
win = MainWindow()
win.show()

def run_until(ready):
    loop = QEventLoop()
    def poll():
        if ready():
            loop.quit()
        else:
            QTimer.singleShot(5, poll)
    poll()
    loop.exec()

win.docs.open_photo(str(SAMPLE_FACE), ask=False, remember=False)
run_until(lambda: win.last_result is not None)
settle = time.time() + 0.5  # the sample's preset thumbnails start; let the window settle
run_until(lambda: time.time() > settle)
worst, last = [0.0], [time.perf_counter()]

def tick():
    now = time.perf_counter()
    worst[0] = max(worst[0], now - last[0])
    last[0] = now

timer = QTimer()
timer.timeout.connect(tick)
timer.start(10)
last[0] = time.perf_counter()
win.docs.open_photo(big, ask=False, remember=False)
run_until(lambda: win.last_result is not None and win.last_result.image.shape[:2] == (4000, 3000))
tick()
print(f"GAP {worst[0] * 1000:.1f}", flush=True)
win.close_without_prompt()
"""

GUI_OPEN_GAP_GOAL_MS = 100.0


def gui_open_gap_bench(emit: Callable[[dict], None], n: int = 3) -> None:
    """The editor's longest event-loop stall while it opens a 12 MP photo (fresh processes)."""
    gaps = []
    with tempfile.TemporaryDirectory(prefix="fap-bench-gap-") as home:
        env = _env(QT_QPA_PLATFORM="offscreen", HOME=home, XDG_CONFIG_HOME=home,
                   XDG_CACHE_HOME=home)
        for _ in range(n):
            out = _run(["-c", _GAP_CHILD, str(Path(home) / "big.png")], env=env, timeout=300)
            line = next((x for x in out.stdout.splitlines() if x.startswith("GAP")), None)
            if line is None:
                raise RuntimeError(f"the editor did not open the photo: {out.stderr[-500:]}")
            gaps.append(float(line.split()[1]))
    ms = statistics.median(gaps)
    emit({"bench": "gui_open_gap_ms", "size": "3000x4000", "median_ms": round(ms, 1),
          "max_ms": round(max(gaps), 1), "n": n, "goal": f"<= {GUI_OPEN_GAP_GOAL_MS:g} ms",
          "ok": ms <= GUI_OPEN_GAP_GOAL_MS})


def make_big_jpeg(path: Path, size: tuple[int, int] = BIG_SIZE) -> None:
    """The sample face upscaled to ``size`` (aspect kept, padded by reflection) with sensor-like
    noise, as a quality-92 JPEG."""
    import cv2
    import numpy as np

    from .resources import SAMPLE_FACE

    img = cv2.imread(str(SAMPLE_FACE), cv2.IMREAD_COLOR)
    w, h = size
    s = min(w / img.shape[1], h / img.shape[0])
    fit = cv2.resize(img, None, fx=s, fy=s, interpolation=cv2.INTER_CUBIC)
    top, left = (h - fit.shape[0]) // 2, (w - fit.shape[1]) // 2
    big = cv2.copyMakeBorder(fit, top, h - fit.shape[0] - top, left, w - fit.shape[1] - left,
                             cv2.BORDER_REFLECT_101)
    noise = np.random.default_rng(15).normal(0, 4, big.shape).astype(np.float32)
    big = np.clip(big.astype(np.float32) + noise, 0, 255).astype(np.uint8)
    if not cv2.imwrite(str(path), big, [cv2.IMWRITE_JPEG_QUALITY, 92]):
        raise RuntimeError(f"cannot write {path}")


#: The child of ``open_fit_render``: ``mode`` imread or open; prints per-run ms and peak RSS.
_OPEN_CHILD = r"""
import json, resource, sys, time
import cv2
cv2.setNumThreads(1)
mode, path, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
if mode == "open":
    from editor.bench import EXPRESSION
    from editor.engine.face import Face
    from editor.engine.faps import FAPS
    from editor.resources import SAMPLE_FACE
    vec = FAPS.clamp(FAPS.vector(EXPRESSION))
    Face.from_image(SAMPLE_FACE).render(vec)  # imports and models loaded, as in the editor
ms = []
for _ in range(n):
    t0 = time.perf_counter()
    if mode == "imread":
        img = cv2.imread(path, cv2.IMREAD_COLOR)
        shape = img.shape
    else:
        face = Face.from_image(path)
        out = face.render(vec)
        shape = out.shape
    ms.append((time.perf_counter() - t0) * 1000)
try:  # this process's own peak (ru_maxrss may keep the parent's across fork + exec)
    with open("/proc/self/status") as f:
        peak = next(int(x.split()[1]) for x in f if x.startswith("VmHWM:")) / 1024
except (OSError, StopIteration):
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps({"ms": ms, "peak_rss_mb": peak, "shape": list(shape)}))
"""


def open_fit_render_bench(emit: Callable[[dict], None], n: int = 3) -> None:
    """24 MP JPEG: ``imread`` vs open (load, landmarks, mesh, own expression, first render)."""
    with tempfile.TemporaryDirectory(prefix="fap-bench-24mp-") as tmp:
        path = Path(tmp) / "face_24mp.jpg"
        make_big_jpeg(path)
        size = f"{BIG_SIZE[0]}x{BIG_SIZE[1]}"

        def child(mode: str, runs: int) -> dict:
            out = _run(["-c", _OPEN_CHILD, mode, str(path), str(runs)], timeout=600)
            return json.loads(out.stdout.strip().splitlines()[-1])

        child("imread", 1)  # warms the file cache
        imread = child("imread", n * 3)
        ofr = [child("open", 1) for _ in range(n)]  # a fresh process each: first render
        imread_ms = statistics.median(imread["ms"])
        ofr_ms = statistics.median(r["ms"][0] for r in ofr)
        peak = max(r["peak_rss_mb"] for r in ofr)
        decoded_mb = BIG_SIZE[0] * BIG_SIZE[1] * 3 / 2**20
        mem_goal = 6 * decoded_mb + 300
        ratio = ofr_ms / imread_ms
        emit({"bench": "imread", "size": size, "median_ms": round(imread_ms, 1),
              "n": len(imread["ms"]), "file_mb": round(path.stat().st_size / 2**20, 1)})
        emit({"bench": "open_fit_render", "size": size, "median_ms": round(ofr_ms, 1),
              "n": n, "ratio_vs_imread": round(ratio, 2), "peak_rss_mb": round(peak, 1),
              "decoded_mb": round(decoded_mb, 1),
              "goal": f"<= {OPEN_FIT_RENDER_GOAL_RATIO:g} x imread; peak_rss_mb <= "
                      f"6 x decoded_mb + 300 = {mem_goal:.0f}",
              "ok": ratio <= OPEN_FIT_RENDER_GOAL_RATIO and peak <= mem_goal})


def start_benches(emit: Callable[[dict], None], want: Callable[..., bool]) -> None:
    """The rows of this module that ``want`` selects."""
    if want("cli_help_s"):
        cli_help_bench(emit)
    if want("gui_ready_s"):
        gui_ready_bench(emit)
    if want("gui_open_gap_ms"):
        gui_open_gap_bench(emit)
    if want("open_fit_render", "imread"):
        open_fit_render_bench(emit)
