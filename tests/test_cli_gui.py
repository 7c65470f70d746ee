"""`fap-studio gui` without a display: screenshots work, the window says what is missing."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest


def _env() -> dict[str, str]:
    return {k: v for k, v in os.environ.items()
            if k not in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM")}


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="display rules are Linux's")
def test_headless_screenshot_and_clear_error_without_display(tmp_path):
    env = _env()
    env["XDG_CONFIG_HOME"] = str(tmp_path / "config")  # never touch the user's settings
    shot = tmp_path / "s.png"
    r = subprocess.run([sys.executable, "-m", "editor", "gui", "--fap", "open_jaw=300",
                        "--screenshot", str(shot)], env=env, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    assert shot.stat().st_size > 50_000
    r = subprocess.run([sys.executable, "-m", "editor"], env=env, capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 2
    assert r.stderr.startswith("fap-studio: error: no display")


def test_a_missing_photo_or_project_is_named_before_the_window(cli, monkeypatch, tmp_path):
    """``fap-studio nothing.jpg`` says the file is missing (not "no display"), one line, exit 2."""
    monkeypatch.delenv("QT_QPA_PLATFORM", raising=False)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    for args in ([tmp_path / "nothing.jpg"], ["gui", "--project", tmp_path / "x.fapproj"]):
        r = cli(*args)
        assert r.returncode == 2
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and "no such file" in lines[0], r.stderr


def test_render_says_when_it_clamps_a_fap(cli, tmp_path):
    """A value outside the FAP's range is clamped (as the renderer does) and said so in one line;
    values inside say nothing of the kind."""
    out = tmp_path / "x.png"
    r = cli("render", "sample", "--fap", "open_jaw=999999", "--fap", "head_roll=-500", "-o", out)
    assert r.returncode == 0 and out.is_file()
    notes = [ln for ln in r.stderr.splitlines() if "clamped" in ln]
    assert notes == ["fap-studio: note: outside their range, clamped: open_jaw 999999 -> 1080 MNS"]
    r = cli("render", "sample", "--fap", "open_jaw=500", "-o", out)
    assert "clamped" not in r.stderr


@pytest.mark.gui
def test_gui_preset_option_shows_the_preset_in_its_panel(qapp, isolated_settings, monkeypatch,
                                                         tmp_path, cli):
    """``fap-studio gui --preset fear:1.5`` applies fear at 150 % and the Presets panel says so
    (fear selected, its intensity at 150 %): a new user saw the FAPs applied while the panel
    showed nothing selected at 100 %. Mixed with ``--fap`` the panel shows no single preset."""
    from editor.ui import app as ui_app

    seen: list[tuple[str | None, int, float]] = []

    def look(_app, window, _path) -> int:
        p = window.extensions["presets_panel"]
        seen.append((p.selected_name(), p.intensity.value(),
                     float(window.model.doc.faps[2])))  # open_jaw
        window.close_without_prompt()
        return 0

    monkeypatch.setattr(ui_app, "_screenshot", look)
    monkeypatch.setenv("QT_QPA_PLATFORM", "offscreen")
    shot = tmp_path / "s.png"
    assert cli("gui", "sample", "--preset", "fear:1.5", "--screenshot", shot).returncode == 0
    assert cli("gui", "sample", "--preset", "fear:1.5", "--fap", "open_jaw=10",
               "--screenshot", shot).returncode == 0
    (name, pct, jaw), (name2, pct2, jaw2) = seen
    from editor.formats.presets import apply_preset

    assert (name, pct) == ("fear", 150) and jaw == pytest.approx(apply_preset("fear", 1.5)[2])
    assert jaw > 0 and (name2, pct2) == (None, 100) and jaw2 == pytest.approx(jaw + 10)
