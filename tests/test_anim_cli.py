"""Presets on the command line, .fap export/info, and rendering sequences to video/PNG."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from conftest import SAMPLE

from editor.core import FapStudioError, load_image
from editor.formats.fapfile import FapSequence, read_fap
from editor.formats.presets import apply_preset, get_preset
from editor.formats.video import export_sequence


def test_render_preset_equals_api(cli, tmp_path, sample_face):
    r = cli("render", str(SAMPLE), "--preset", "joy:0.8", "-o", str(tmp_path / "j.png"))
    assert r.returncode == 0, r.stderr
    expected = sample_face.render(apply_preset(get_preset("joy"), 0.8), sharp=True)  # a still
    assert np.array_equal(load_image(tmp_path / "j.png"), expected)
    assert not np.array_equal(expected, sample_face.image)


def test_bad_preset_is_one_line_error(cli, tmp_path):
    for spec in ("nope", "joy:2", "joy:x"):
        r = cli("render", str(SAMPLE), "--preset", spec, "-o", str(tmp_path / "x.png"))
        assert r.returncode == 2 and r.stderr.startswith("fap-studio: error:"), spec
        assert "Traceback" not in r.stderr and r.stderr.count("\n") == 1, r.stderr
    # NaN is named as what it is, not as out of the range (a new user's report)
    r = cli("render", str(SAMPLE), "--preset", "joy:nan", "-o", str(tmp_path / "x.png"))
    assert r.returncode == 2 and "'nan' is not a number" in r.stderr, r.stderr


def test_an_unwritable_image_output_is_refused_before_the_work(cli, tmp_path):
    """``-o out.txt`` is refused while the arguments are read: with a photo that does not
    exist, the output's error comes first (no detection, no render, no file written)."""
    for cmd in (("render", "--preset", "joy"), ("landmarks",), ("mesh",)):
        out = tmp_path / "out.txt"
        r = cli(cmd[0], str(tmp_path / "missing.png"), *cmd[1:], "-o", str(out))
        assert r.returncode == 2 and "cannot write an image as .txt" in r.stderr, (cmd, r.stderr)
        assert r.stderr.count("\n") == 1 and not out.exists(), r.stderr
    r = cli("render", str(SAMPLE), "--preset", "joy", "-o", str(tmp_path / "j.webp"))
    assert r.returncode == 0 and load_image(tmp_path / "j.webp").shape == (512, 512, 3), r.stderr


def test_fap_export_info_and_animate(cli, tmp_path):
    fap = tmp_path / "joy.fap"
    r = cli("fap", "export", "--preset", "joy", "--keyframes", "--duration", "0.4", "--fps",
             "25", "-o", str(fap))
    assert r.returncode == 0, r.stderr
    seq = read_fap(fap)
    assert seq.n_frames == 11 and seq.fps == 25
    peak = seq.frames[5]
    assert np.allclose(peak, np.round(apply_preset(get_preset("joy"), 1.0)), atol=1)
    assert not seq.frames[0].any() and not seq.frames[-1].any()
    r = cli("fap", "info", str(fap))
    assert r.returncode == 0 and "frames:   11" in r.stdout and "open_jaw" in r.stdout
    r = cli("animate", str(SAMPLE), str(fap), "-o", str(tmp_path / "a.mp4"))
    assert r.returncode == 0, r.stderr
    cap = cv2.VideoCapture(str(tmp_path / "a.mp4"))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 11
    assert cap.get(cv2.CAP_PROP_FPS) == pytest.approx(25)
    ok, frame = cap.read()
    assert ok and frame.shape == (512, 512, 3)


def test_export_png_frames_and_cancel(tmp_path, sample_face):
    vec = apply_preset(get_preset("surprise"), 1.0)
    seq = FapSequence.single(vec, fps=10, frames=4)
    res = export_sequence(sample_face, seq, tmp_path / "frames")
    assert res.frames == 4 and not res.cancelled
    files = sorted((tmp_path / "frames").glob("frame_*.png"))
    assert len(files) == 4
    assert np.array_equal(load_image(files[0]), sample_face.render(seq.frames[0]))
    res = export_sequence(sample_face, seq, tmp_path / "c.mp4", progress=lambda d, n: d < 2)
    assert res.cancelled and res.frames == 2 and not (tmp_path / "c.mp4").exists()
    with pytest.raises(FapStudioError):
        export_sequence(sample_face, seq, "/proc/forbidden/out")


def test_entry_point_in_a_real_process(tmp_path, sample_face):
    """The other CLI tests call :func:`editor.cli.main` in process; this one runs the real
    entry points (``python -m editor`` and the installed ``fap-studio`` script) once."""
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    out = tmp_path / "j.png"
    r = subprocess.run([sys.executable, "-m", "editor", "render", str(SAMPLE), "--preset",
                        "joy:0.8", "-o", str(out)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert np.array_equal(load_image(out), sample_face.render(apply_preset(get_preset("joy"),
                                                                           0.8), sharp=True))
    r = subprocess.run([sys.executable, "-m", "editor", "render", str(SAMPLE), "--preset",
                        "nope", "-o", str(out)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and r.stderr.startswith("fap-studio: error:"), r.stderr
    assert r.stderr.count("\n") == 1, r.stderr
    script = Path(sys.executable).with_name("fap-studio")
    script = str(script) if script.exists() else shutil.which("fap-studio")
    if script is None:
        pytest.skip("the fap-studio script is not installed (pip install -e .)")
    r = subprocess.run([script, "--version"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stdout.startswith("fap-studio "), (r.stdout, r.stderr)


def test_animate_refuses_a_video_suffix_it_does_not_write(cli, tmp_path):
    """``-o a.mkv`` was written as a folder of PNG frames named a.mkv; now one line, exit 2."""
    from editor.formats.fapfile import FapSequence, write_fap
    from editor.formats.presets import apply_preset

    fap = write_fap(FapSequence.single(apply_preset("joy"), frames=2), tmp_path / "a.fap")
    for name in ("a.mkv", "a.gif"):
        r = cli("animate", "sample", fap, "-o", tmp_path / name)
        assert r.returncode == 2 and "is not written here" in r.stderr, r.stderr
        assert len(r.stderr.strip().splitlines()) == 1 and not (tmp_path / name).exists()
    r = cli("animate", "sample", fap, "-o", tmp_path / "frames.v2")  # a dotted folder name
    assert r.returncode == 0 and len(list((tmp_path / "frames.v2").glob("*.png"))) == 2


def test_animate_with_a_photo_as_its_animation_says_what_an_animation_is(cli, tmp_path):
    """A PNG given where the animation goes: one line that names the three kinds animate reads
    (it said only "expected a text .fap file", though CSVs are read too); nothing written."""
    out = tmp_path / "z.mp4"
    r = cli("animate", str(SAMPLE), str(SAMPLE), "-o", str(out))
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "Live Link Face CSV" in r.stderr and "AU CSV" in r.stderr
    assert not out.exists()
