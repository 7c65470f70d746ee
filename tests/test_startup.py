"""Quick start (issue 15), as behaviour: what ``fap-studio --help`` and the editor window import,
the blockwise luminance, ``python -m editor.bench --check``. (The timings live in editor.bench.)"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from editor.engine.fitting import luminance
from editor.engine.imageio import load_image
from editor.resources import SAMPLE_FACE

ROOT = Path(__file__).resolve().parent.parent


def _modules_after(code: str) -> set[str]:
    """The modules imported by ``code`` in a fresh interpreter (offscreen Qt)."""
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen",
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    out = subprocess.run([sys.executable, "-c", code + "\nimport sys\nprint(*sys.modules)"],
                         capture_output=True, text=True, env=env, check=True, timeout=120)
    return set(out.stdout.split())


def test_cli_help_imports_neither_numpy_nor_opencv_nor_scipy_nor_the_renderer():
    mods = _modules_after("import contextlib\nfrom editor.cli import main\n"
                          "with contextlib.suppress(SystemExit):\n    main(['--help'])")
    assert "editor.cli.study" in mods  # the parser was built
    assert not {"numpy", "cv2", "scipy", "editor.engine.face", "editor.study.stimuli",
                "editor.study.mos"} & mods


def test_the_editor_window_is_built_without_scipy_or_the_renderer():
    """The window comes first; OpenCV, the renderer (editor.engine.face), the video export,
    the study statistics and stimuli are imported when a photo is opened or their action is
    used."""
    mods = _modules_after("from editor.ui.app import application\n"
                          "from editor.ui.main_window import MainWindow\n"
                          "app = application()\nw = MainWindow()")
    assert "editor.ui.mos_panel" in mods and "editor.ui.au_panel" in mods
    assert not {m for m in mods if m == "scipy" or m.startswith("scipy.")}
    assert not {"cv2", "editor.engine.face", "editor.formats.video", "editor.study.mos_stats",
                "editor.study.stimuli", "editor.ui.mos_results"} & mods


@pytest.mark.parametrize("rows", [1, 5, 256, 10_000])
def test_luminance_in_blocks_is_the_whole_image_product_bit_for_bit(rows):
    rgb = load_image(SAMPLE_FACE)
    rgb = np.ascontiguousarray(np.concatenate([rgb, rgb[::-1, ::-1]], axis=0)[:, :333])
    want = np.asarray(rgb, np.float32) @ np.array([0.299, 0.587, 0.114], np.float32)
    got = luminance(rgb, rows)
    assert got.dtype == np.float32 and got.shape == rgb.shape[:2]
    assert np.array_equal(got, want)


def test_bench_check_exits_1_naming_a_missed_goal(monkeypatch, capsys):
    from editor import bench

    def fake_run(args) -> None:  # the benchmarks replaced by two rows, one missing its goal
        bench._emit({"bench": "cli_help_s", "seconds": 9.9, "goal": "<= 0.3 s", "ok": False})
        bench._emit({"bench": "gui_ready_s", "seconds": 1.0, "goal": "<= 1.5 s", "ok": True})

    monkeypatch.setattr(bench, "_run", fake_run)
    monkeypatch.setattr(bench, "_MISSED", [])
    bench.main([])  # without --check: rows printed, no exit
    with pytest.raises(SystemExit) as e:
        bench.main(["--check"])
    assert e.value.code == 1
    err = capsys.readouterr().err
    assert "cli_help_s missed its goal (<= 0.3 s)" in err and "gui_ready_s" not in err
