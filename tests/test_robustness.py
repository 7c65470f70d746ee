"""Issue 16: every bad input and every fault gives one clear line, nothing partial, nothing lost.

One test per numbered case of the issue (``test_case01_...`` .. ``test_case13_...``), a fuzz
test per reader (.fap, preset, project, study, model, image header) with a fixed seed, a
full-disk test (a writer that fails half-way; a real 1 MiB tmpfs too when this machine lets us
mount one) and a Ctrl-C test for ``animate``.
"""

from __future__ import annotations

import errno
import io
import json
import math
import os
import signal
import sqlite3
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

from editor.cli import main
from editor.core import FAPS
from editor.errors import (
    FapFileError,
    FapStudioError,
    ImageError,
    ModelError,
    PresetError,
    ProjectError,
    StudyError,
)
from editor.formats.fapfile import FapSequence, read_fap, write_fap
from editor.resources import PRESETS_DIR, SAMPLE_FACE

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = SAMPLE_FACE
ENV = {**os.environ, "PYTHONPATH": str(ROOT), "QT_QPA_PLATFORM": "offscreen"}
_REAL_VIDEO_WRITER = __import__("editor.formats.video", fromlist=["VideoWriter"]).VideoWriter
MASK_JAW = " ".join(["0", "0", "1"] + ["0"] * 65)


def cli(capfd, *args: str) -> tuple[int, str, str]:
    """Run the CLI in this process; (exit code, stdout, stderr) with C-level output caught."""
    capfd.readouterr()
    try:
        code = main([str(a) for a in args])
    except SystemExit as e:  # argparse's usage errors
        code = e.code
    out, err = capfd.readouterr()
    return code, out, err


def one_line_error(code: int, err: str, *, what: str = "") -> None:
    assert code == 2, (code, err)
    assert err.startswith("fap-studio: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err and what in err, err


def only(tmp: Path, *names: str) -> None:
    """The folder holds exactly ``names`` (nothing partial, no temporary file)."""
    assert sorted(p.name for p in tmp.iterdir()) == sorted(names)


def fap_text(value: str = "100", frame: str = "0", count: str = "1", fps: str = "25") -> str:
    return f"2.1 t {fps} {count}\n{MASK_JAW}\n{frame} {value}\n"


# ------------------------------------------------------------------------------ case 1
@pytest.mark.parametrize("text", [
    fap_text(value="9" * 400), fap_text(value="-" + "9" * 400), fap_text(frame="9" * 400),
    fap_text(count="9" * 400), fap_text(count="9" * 5000), fap_text(value="1" + "0" * 5000),
    fap_text(fps="9" * 400), fap_text(value="1e400"), fap_text(frame="1e400"),
])
def test_case01_huge_numbers_in_fap_files(text):
    with pytest.raises(FapFileError, match="line"):
        read_fap(text)


def test_case01_huge_numbers_in_cli_and_api(capfd, sample_neutral, tmp_path):
    for value in ("1e300", "3.5e38", "1e39", "1" + "0" * 400, "inf", "nan"):
        code, _, err = cli(capfd, "render", SAMPLE, "--fap", f"open_jaw={value}",
                           "-o", tmp_path / "x.png")
        one_line_error(code, err, what="open_jaw")
    only(tmp_path)
    for bad in (10**400, 1e300, float("nan")):
        with pytest.raises(ValueError):
            sample_neutral.deform({"open_jaw": bad})
    # the same value is rejected the same way as an array and as a dict
    for big in (1e30, 1e39, 1e300):
        arr = np.zeros(68)
        arr[2] = big
        with pytest.raises(ValueError, match="within"):
            FAPS.vector(arr)
        with pytest.raises(ValueError, match="within"):
            FAPS.vector({"open_jaw": big})
    assert FAPS.vector({"open_jaw": 1e6})[2] == FAPS.vector(np.eye(68)[2] * 1e6)[2] == 1e6


# ------------------------------------------------------------------------------ case 2
@pytest.mark.parametrize("opts", [
    ["--fps", "0"], ["--fps", "nan"], ["--fps", "inf"], ["--fps", "-5"], ["--fps", "1e300"],
    ["--frames", "0"], ["--frames", "-1"], ["--frames", "2000000"],
    ["--keyframes", "--duration", "0"], ["--keyframes", "--duration", "-1"],
    ["--keyframes", "--duration", "nan"], ["--keyframes", "--duration", "1e300"],
    ["--keyframes", "--duration", "inf"], ["--fps", "x"], ["--frames", "1.5"],
])
def test_case02_fap_export_numbers(capfd, tmp_path, opts):
    code, _, err = cli(capfd, "fap", "export", "--preset", "joy", *opts,
                       "-o", tmp_path / "x.fap")
    one_line_error(code, err)
    only(tmp_path)


# ------------------------------------------------------------------------------ case 3
BAD_PRESETS = {
    "huge": '{"format": "fap-studio-preset", "version": 1, "kind": "custom", "name": "huge",'
            ' "faps": {"open_jaw": 1' + "0" * 400 + "}}",
    "huger": '{"format": "fap-studio-preset", "version": 1, "kind": "custom", "name": "huger",'
             ' "faps": {"open_jaw": 1' + "0" * 5000 + "}}",
    "nested": "[" * 100_000 + "]" * 100_000,
    "nan": '{"format": "fap-studio-preset", "version": 1, "kind": "custom", "name": "nan",'
           ' "faps": {"open_jaw": NaN}}',
}


@pytest.fixture
def bad_user_presets(tmp_path, monkeypatch):
    monkeypatch.setenv("FAP_STUDIO_DATA_DIR", str(tmp_path / "data"))
    d = tmp_path / "data" / "presets"
    d.mkdir(parents=True)
    for name, text in BAD_PRESETS.items():
        (d / f"{name}.json").write_text(text)
    os.mkfifo(d / "fifo.json")
    return d


def test_case03_bad_user_presets_are_skipped(capfd, tmp_path, bad_user_presets):
    from editor.formats.presets import all_presets, get_preset

    problems: list[str] = []
    presets = all_presets(problems)
    assert "joy" in presets and len(problems) == len(BAD_PRESETS) + 1, problems
    for name in (*BAD_PRESETS, "fifo"):
        with pytest.raises(PresetError, match=name):
            get_preset(name)
    out = tmp_path / "out"
    out.mkdir()
    code, _, err = cli(capfd, "fap", "export", "--preset", "joy", "-o", out / "j.fap")
    assert code == 0, err
    code, _, err = cli(capfd, "render", SAMPLE, "--preset", "joy", "-o", out / "j.png")
    assert code == 0, err
    code, _, err = cli(capfd, "render", SAMPLE, "--preset", "huge", "-o", out / "h.png")
    one_line_error(code, err, what="huge.json")
    only(out, "j.fap", "j.png")


def test_case03_editor_starts_with_bad_user_presets(qtbot, bad_user_presets, isolated_settings,
                                                      warnings):
    from editor.ui.main_window import MainWindow

    w = MainWindow()
    qtbot.addWidget(w)
    panel = w.presets_panel
    assert "joy" in panel.presets and len(panel.problems) == len(BAD_PRESETS) + 1
    assert all(name not in panel.presets for name in BAD_PRESETS)
    w.close_without_prompt()


# ------------------------------------------------------------------------------ case 4
def test_case04_unwritable_targets_are_one_line(capfd, tmp_path):
    (tmp_path / "file").write_text("not a folder")
    target = tmp_path / "file"
    code, _, err = cli(capfd, "fap", "export", "--preset", "joy", "-o", target / "x.fap")
    one_line_error(code, err, what="cannot write")
    code, _, err = cli(capfd, "study", "create", target / "s.db", "--faces", SAMPLE,
                       "--presets", "joy")
    one_line_error(code, err, what="cannot create study")
    code, _, err = cli(capfd, "render", SAMPLE, "-o", target / "x.png")
    one_line_error(code, err, what="cannot write")
    only(tmp_path, "file")


def test_case04_read_only_folder(capfd, tmp_path, ro_dir):
    code, _, err = cli(capfd, "fap", "export", "--preset", "joy", "-o", ro_dir / "x.fap")
    one_line_error(code, err, what="Read-only")
    code, _, err = cli(capfd, "study", "create", ro_dir / "s.db", "--faces", SAMPLE,
                       "--presets", "joy")
    one_line_error(code, err, what="cannot create study")
    assert list(ro_dir.iterdir()) == []


def _mount(tmp_path: Path, opts: str) -> Path:
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    if sys.platform != "linux" or os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root on Linux")
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", opts, "tmpfs", str(mnt)],
                       capture_output=True)
    if r.returncode:
        pytest.skip(f"cannot mount a tmpfs here ({r.stderr.decode().strip()})")
    return mnt


@pytest.fixture
def ro_dir(tmp_path):
    mnt = _mount(tmp_path, "ro,size=64k")
    yield mnt
    subprocess.run(["umount", str(mnt)], check=False)


@pytest.fixture
def small_disk(tmp_path):
    mnt = _mount(tmp_path, "size=64k")
    yield mnt
    subprocess.run(["umount", str(mnt)], check=False)


# ------------------------------------------------------------------------------ case 5
@pytest.fixture
def full_disk(monkeypatch):
    """Every atomic write fails half-way with ENOSPC, as on a full disk."""
    from editor import safeio

    def write_half(fh, data):
        fh.write(data[: len(data) // 2])
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(safeio, "_write_all", write_half)


class _DroppingWriter:
    """The video writer on a full disk: opens, then silently writes nothing after 2 frames."""

    def __init__(self, path, size, fps):
        self._w = _REAL_VIDEO_WRITER(path, size, fps)
        self.layout = self._w.layout  # the frames it takes (yuv420p for H.264)
        self.n = 0

    def write(self, frame):
        self.n += 1
        if self.n <= 2:
            self._w.write(frame)

    def close(self):
        self._w.close()
        with open(self._path_hack, "r+b") as fh:  # the moov atom never reached the disk
            fh.truncate(os.path.getsize(self._path_hack) // 2)


def test_case05_full_disk_leaves_nothing(capfd, tmp_path, full_disk, monkeypatch):
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.fap").write_text(fap_text())
    code, _, err = cli(capfd, "render", SAMPLE, "-o", out / "r.png")
    one_line_error(code, err, what="No space left")
    code, _, err = cli(capfd, "mesh", SAMPLE, "--json", out / "m.json")
    one_line_error(code, err, what="No space left")
    code, _, err = cli(capfd, "fap", "export", "--preset", "joy", "-o", out / "keep.fap")
    one_line_error(code, err, what="No space left")
    assert (out / "keep.fap").read_text() == fap_text()  # the old file is intact
    code, _, err = cli(capfd, "animate", SAMPLE, out / "keep.fap", "-q", "-o", out / "frames")
    one_line_error(code, err, what="No space left")
    only(out, "keep.fap")


def test_case05_truncated_video_is_an_error(capfd, tmp_path, monkeypatch):
    from editor.formats import video

    made = []

    class Dropping(_DroppingWriter):
        def __init__(self, path, *a):
            super().__init__(path, *a)
            self._path_hack = path
            made.append(self)

    monkeypatch.setattr(video, "VideoWriter", Dropping)
    fap = tmp_path / "six.fap"
    write_fap(FapSequence.single(np.eye(68)[2] * 300, frames=6), fap)
    code, _, err = cli(capfd, "animate", SAMPLE, fap, "-q", "-o", tmp_path / "a.mp4")
    one_line_error(code, err, what="a.mp4")
    assert made and "could not be written completely" in err
    only(tmp_path, "six.fap")


def test_case05_real_full_disk(capfd, tmp_path, small_disk):
    fap = tmp_path / "long.fap"
    write_fap(FapSequence.single(np.eye(68)[2] * 300, frames=60), fap)
    for out in (small_disk / "a.mp4", small_disk / "frames", small_disk / "r.png"):
        args = ("render", SAMPLE, "-o", out) if out.suffix == ".png" else (
            "animate", SAMPLE, fap, "-q", "-o", out)
        code, _, err = cli(capfd, *args)
        assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
        assert list(small_disk.iterdir()) == [], err


# ------------------------------------------------------------------------------ case 6
def interrupt_animate(tmp_path: Path, out: Path, *extra: str) -> subprocess.CompletedProcess:
    """``fap-studio animate`` of a long .fap (options ``extra``), Ctrl-C after a few frames."""
    fap = tmp_path / "long.fap"
    if not fap.exists():
        write_fap(FapSequence.single(np.eye(68)[2] * 300, frames=3000), fap)
    p = subprocess.Popen([sys.executable, "-m", "editor", "animate", str(SAMPLE), str(fap),
                          *extra, "-o", str(out)], env=ENV, stderr=subprocess.PIPE, text=True,
                         bufsize=1)
    seen = ""
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:  # wait until a few frames were written
        ch = p.stderr.read(1)
        if not ch:
            break
        seen += ch
        if seen.endswith("/3000") and seen.count("/3000") >= 5:
            break
    p.send_signal(signal.SIGINT)
    rest = p.stderr.read()
    p.wait(60)
    return subprocess.CompletedProcess(p.args, p.returncode, "", seen + rest)


@pytest.mark.parametrize("name", ["a.mp4", "frames"])
def test_case06_ctrl_c_during_animate_leaves_nothing(tmp_path, name):
    out = tmp_path / "out"
    out.mkdir()
    r = interrupt_animate(tmp_path, out / name)
    assert r.returncode == 130, r.stderr
    assert r.stderr.rstrip().endswith("fap-studio: interrupted") and "Traceback" not in r.stderr
    only(out)


# ------------------------------------------------------------------------------ case 7
def test_case07_devices_and_fifos_are_refused(capfd, tmp_path):
    from editor.engine.imageio import load_image
    from editor.formats.project import load_project

    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    for path in ("/dev/zero", fifo, tmp_path):
        t0 = time.monotonic()
        with pytest.raises(ImageError, match="cannot read"):
            load_image(path)
        with pytest.raises(FapFileError, match="cannot read"):
            read_fap(path)
        with pytest.raises(ProjectError, match="cannot read"):
            load_project(path, [])
        assert time.monotonic() - t0 < 5
    code, _, err = cli(capfd, "fap", "info", "/dev/zero")
    one_line_error(code, err, what="regular file")


def test_case07_project_photo_is_dev_zero(qapp, isolated_settings, capfd, tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    proj = work / "z.fapproj"
    proj.write_text(json.dumps({"format": "fap-studio-project", "version": 1,
                                "photo": "/dev/zero"}))
    code, _, err = cli(capfd, "gui", "--project", proj, "--screenshot", work / "s.png")
    one_line_error(code, err, what="/dev/zero")
    only(work, "z.fapproj")


# ------------------------------------------------------------------------------ case 8
def _study(tmp_path: Path) -> Path:
    from editor.study.stimuli import create_from_renders

    rng = np.random.default_rng(0)
    renders = [(f, lab, 1.0, rng.integers(0, 256, (6, 5, 3), dtype=np.uint8))
               for f in ("Ann", "Bob") for lab in ("joy", "fear")]
    path = tmp_path / "s.db"
    with create_from_renders(path, "s", ["joy", "fear"], renders) as st:
        session = st.start_session("r1", seed=1)
        stim = session.next_stimulus()
        session.answer(stim, stim.label, 4, 900.0)
    return path


@pytest.mark.parametrize("sql", [
    "DROP TABLE answers", "DROP TABLE answer_history", "DROP TABLE stimuli",
    "UPDATE meta SET value = '[[\"joy\"], {\"a\": 1}]' WHERE key = 'labels'",
    "UPDATE meta SET value = '[' || replace(hex(zeroblob(5000)), '00', '[') WHERE key = 'labels'",
    "UPDATE meta SET value = '[\"joy\", \"joy\"]' WHERE key = 'labels'",
    "UPDATE meta SET value = '-3' WHERE key = 'break_every'",
    "ALTER TABLE answers RENAME COLUMN label TO x",
])
def test_case08_broken_study_files(capfd, tmp_path, sql):
    from editor.study.mos import Study

    path = _study(tmp_path)
    con = sqlite3.connect(path)
    con.execute(sql)
    con.commit()
    con.close()
    with pytest.raises(StudyError):
        Study.open(path)
    for cmd in (["report", path], ["export", path, "-o", tmp_path / "a.csv"]):
        code, _, err = cli(capfd, "study", *cmd)
        one_line_error(code, err, what=str(path))
    assert not (tmp_path / "a.csv").exists()


# ------------------------------------------------------------------------------ case 9
@pytest.fixture(scope="module")
def model_arrays(tmp_path_factory):
    from editor.synthesis.bilinear import save_model
    from editor.synthesis.bilinear_data import train_model

    sys.path.insert(0, str(ROOT / "tests"))
    try:
        from test_bilinear import synthetic_set
    finally:
        sys.path.pop(0)
    model, _ = train_model(synthetic_set(), I=3, J=3)
    path = tmp_path_factory.mktemp("model") / "good.npz"
    save_model(model, path)
    with np.load(path) as npz:
        return {k: npz[k] for k in npz.files}


def _npz(path: Path, arrays: dict, compress: bool = False) -> Path:
    with open(path, "wb") as fh:
        (np.savez_compressed if compress else np.savez)(fh, **arrays)
    return path


def _with_meta(arrays: dict, change) -> dict:
    meta = json.loads(str(arrays["metadata"]))
    text = change(meta)
    return arrays | {"metadata": np.array(text if isinstance(text, str) else json.dumps(meta))}


def _set(d: dict, key: str, value) -> None:
    d[key] = value


@pytest.mark.parametrize("label,change", [
    ("K infinity", lambda m: json.dumps(m).replace('"K": ', '"K": Infinity, "x": ', 1)),
    ("K huge", lambda m: json.dumps(m).replace('"K": ', '"K": 1' + "0" * 400 + ', "x": ', 1)),
    ("negative index", lambda m: _set(m["regions"][0], "indices",
                                      [-1, *m["regions"][0]["indices"][1:]])),
    ("index too big", lambda m: _set(m["regions"][0], "indices",
                                     [10**6, *m["regions"][0]["indices"][1:]])),
    ("float index", lambda m: _set(m["regions"][0], "indices",
                                   [0.5, *m["regions"][0]["indices"][1:]])),
    ("nested meta", lambda m: _set(m, "meta", {"lambda": {"ridge": {"deep": [1]}}})),
    ("meta list", lambda m: _set(m, "meta", [1, 2])),
    ("deep json", lambda m: "[" * 100_000 + "]" * 100_000),
    ("zero I", lambda m: _set(m["regions"][0], "I", 0)),
])
def test_case09_malformed_model_metadata(tmp_path, model_arrays, label, change):
    from editor.synthesis.bilinear import load_model

    path = _npz(tmp_path / "m.npz", _with_meta(model_arrays, change))
    with pytest.raises(ModelError, match="m.npz"):
        load_model(path)


def test_case09_zip_bomb_model_is_refused_before_inflating(tmp_path, model_arrays, monkeypatch):
    from editor.synthesis import bilinear

    monkeypatch.setattr(bilinear, "MAX_MODEL_BYTES", 1 << 20)  # as 256 MiB for a 2 GiB bomb
    path = _npz(tmp_path / "bomb.npz", model_arrays | {"pad": np.zeros(1 << 18)}, compress=True)
    assert path.stat().st_size < 100_000
    with pytest.raises(ModelError, match="unpack to more than"):
        bilinear.load_model(path)
    with pytest.raises(ModelError, match="regular file"):
        bilinear.load_model("/dev/zero")


# ------------------------------------------------------------------------------ case 10
@pytest.mark.parametrize("mu", ["nan", "-1", "0", "inf", "1e300"])
def test_case10_clone_mu(capfd, tmp_path, mu):
    code, _, err = cli(capfd, "clone", "--source-neutral", SAMPLE, "--source", SAMPLE,
                       "--target", SAMPLE, "--method", "laplacian", "--mu", mu,
                       "-o", tmp_path / "c.png")
    one_line_error(code, err, what="--mu")
    only(tmp_path)


def test_case10_deformer_rejects_bad_mu():
    import scipy.sparse as sp

    from editor.engine.laplacian import LaplacianDeformer

    v = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], float)
    tri = np.array([[0, 1, 2], [1, 3, 2]])
    for mu in (float("nan"), -1.0, 0.0):
        with pytest.raises(ValueError, match="mu"):
            LaplacianDeformer(v, tri, sp.identity(4), mu=mu)


# ------------------------------------------------------------------------------ case 11
def _corrupt_png(tmp_path: Path) -> Path:
    data = bytearray(SAMPLE.read_bytes())
    i = data.index(b"IDAT")
    data[i + 40: i + 60] = b"\x00" * 20  # a broken deflate stream: libpng complains
    p = tmp_path / "corrupt.png"
    p.write_bytes(bytes(data))
    return p


def test_case11_one_stderr_line(capfd, tmp_path):
    bad = _corrupt_png(tmp_path)
    code, _, err = cli(capfd, "render", bad, "-o", tmp_path / "x.png")
    one_line_error(code, err)
    jpg = tmp_path / "t.jpg"
    jpg.write_bytes(b"\xff\xd8\xff\xe0\x00\x10JFIF\x00" + b"\x01" * 300)
    code, _, err = cli(capfd, "render", jpg, "-o", tmp_path / "x.png")
    one_line_error(code, err)
    for args in (["fap", "export"], ["render"], ["nope"], ["fap", "export", "--preset", "joy",
                                                           "--fps", "x", "-o", "y.fap"]):
        with pytest.raises(SystemExit) as info:
            main(args)
        err = capfd.readouterr().err
        assert info.value.code == 2 and err.count("\n") == 1, err
        assert err.startswith("fap-studio: error: ") and "usage" not in err, err


def test_case11_gui_screenshot_and_rejected_project(qapp, isolated_settings, capfd, tmp_path):
    shot = tmp_path / "s.png"
    code, _, err = cli(capfd, "gui", "--screenshot", shot)
    assert code == 0 and err == "", err
    assert shot.stat().st_size > 1000
    (tmp_path / "bad.fapproj").write_text("{oops")
    code, _, err = cli(capfd, "gui", "--project", tmp_path / "bad.fapproj", "--screenshot",
                       tmp_path / "t.png")
    one_line_error(code, err, what="bad.fapproj")
    assert not (tmp_path / "t.png").exists()


def test_case11_broken_pipe(tmp_path):
    fap = tmp_path / "x.fap"
    write_fap(FapSequence.single(np.eye(68)[2] * 300, frames=3), fap)
    p = subprocess.Popen([sys.executable, "-c",
                          "import sys, time; from editor.cli import main; time.sleep(1.5); "
                          "sys.exit(main(['fap', 'info', sys.argv[1]]))", str(fap)],
                         env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    p.stdout.close()  # the reader (``| head``) is gone before anything is printed
    err = p.stderr.read().decode()
    p.wait(60)
    assert err == "" and p.returncode not in (0, 1), (p.returncode, err)


# ------------------------------------------------------------------------------ case 12
def test_case12_nan_never_reaches_a_project(model, tmp_path, sample_neutral):
    from editor.formats.project import load_project, save_project

    before = model.doc.faps.copy()
    for bad in (float("nan"), float("inf"), 10**400, "x"):
        with pytest.raises(ValueError):
            model.set_faps({"open_jaw": bad}, "bad")
    assert np.array_equal(model.doc.faps, before) and np.isfinite(model.doc.faps).all()
    with pytest.raises(ValueError):
        model.preview_vertex(0, (float("nan"), 1.0))
    faps = np.zeros(68, np.float32)
    faps[2] = np.nan
    path = tmp_path / "p.fapproj"
    names, verts = list(sample_neutral.mesh.names), model.doc.vertices
    with pytest.raises(ProjectError, match="NaN"):
        save_project(path, str(SAMPLE), verts, faps, names)
    assert not path.exists()
    faps[2] = 100
    save_project(path, str(SAMPLE), verts, faps, names)
    assert load_project(path, names).faps[2] == 100
    path.write_text(path.read_text().replace('"open_jaw": 100', '"open_jaw": NaN'))
    with pytest.raises(ProjectError):
        load_project(path, names)


# ----------------------------------------------------------------------------- fuzzing
def _mutate(rng: np.random.Generator, data: bytes) -> bytes:
    b = bytearray(data)
    op = int(rng.integers(0, 10))
    if op == 9:  # replace one whole token (whitespace-separated) by an odd one
        import re

        toks = [m.span() for m in re.finditer(rb"[^\s]+", bytes(b))]
        if toks:
            lo, hi = toks[int(rng.integers(0, len(toks)))]
            b[lo:hi] = rng.choice([b"9" * 400, b"-" + b"9" * 400, b"1" * 5000, b"1e400",
                                   b"1e39", b"nan", b"inf", b"-0", b"0x10", b"1_0", b"",
                                   b"2.5", b"-2147483649", b"9223372036854775808"])
        return bytes(b)
    i = int(rng.integers(0, max(len(b), 1)))
    if op == 0 and b:
        b[i] = int(rng.integers(0, 256))
    elif op == 1:
        b[i:i] = bytes(rng.integers(0, 256, int(rng.integers(1, 16)), dtype=np.uint8))
    elif op == 2:
        del b[i:i + int(rng.integers(1, 64))]
    elif op == 3:
        b = b[:i]
    elif op == 4:
        j = int(rng.integers(i, len(b) + 1))
        b[j:j] = b[i:j]
    elif op == 5:
        b[i:i] = rng.choice([b"9" * 400, b"-" + b"9" * 5000, b"1e400", b"NaN", b"-Infinity",
                             b"0.5", b"-1", b"\x00", b"\xff", b"[" * 5000, b"{", b'"', b"\n",
                             b" ", b"\r\n", b"#"])
    elif op == 6:  # replace a digit run by something huge or odd
        digits = [k for k, c in enumerate(b) if 48 <= c <= 57]
        if digits:
            k = digits[int(rng.integers(0, len(digits)))]
            b[k:k + 1] = rng.choice([b"9" * 400, b"1e39", b"nan", b"-0", b"99999999999"])
    elif op == 7 and b:
        b[i] ^= 1 << int(rng.integers(0, 8))
    else:
        b = b + b
    return bytes(b)


def _fuzz(seed: int, base: list[bytes], n: int, read, expected: type[Exception]) -> tuple:
    """Feed ``n`` mutations of ``base`` to ``read``; (tried, clean, failures)."""
    rng = np.random.default_rng(seed)
    failures = []
    for k in range(n):
        data = base[k % len(base)]
        for _ in range(int(rng.integers(1, 4))):
            data = _mutate(rng, data)
        try:
            read(data)
        except expected:
            pass
        except Exception as e:  # noqa: BLE001 - the point: nothing untyped
            failures.append((k, f"{type(e).__name__}: {str(e)[:120]}"))
    print(f"fuzz {read.__name__}: tried {n}, clean {n - len(failures)}")
    return n, n - len(failures), failures


def test_fuzz_fap_reader():
    from editor.formats.fapfile import format_fap

    vec = np.eye(68)[2] * 300 + np.eye(68)[40] * 200
    base = [fap_text().encode(), format_fap(FapSequence.single(vec, frames=3)).encode(),
            b"# greta\r\n2.0 a b c 12.5 2\r\n" + (" ".join(["0"] * 68 + ["1"])).encode()
            + b"\r\n0\r\n" + (" ".join(["1"] * 68)).encode() + b"\r\n1 " +
            b" ".join([b"1"] * 66) + b" 2 3\r\n"]

    def fap(data):
        read_fap(data)

    tried, clean, bad = _fuzz(1601, base, 400, fap, FapFileError)
    assert not bad, bad[:5]


def test_fuzz_preset_reader(tmp_path):
    from editor.formats.presets import load_preset

    base = [p.read_bytes() for p in sorted(PRESETS_DIR.glob("*.json"))[:6]]
    path = tmp_path / "p.json"

    def preset(data):
        path.write_bytes(data)
        load_preset(path)

    tried, clean, bad = _fuzz(1602, base, 300, preset, PresetError)
    assert not bad, bad[:5]


def test_fuzz_project_reader(tmp_path, sample_neutral):
    from editor.formats.project import load_project, project_text

    names = list(sample_neutral.mesh.names)
    text = project_text(str(SAMPLE), sample_neutral.vertices, np.eye(68)[2] * 300, names,
                        tmp_path)
    small = json.dumps({"format": "fap-studio-project", "version": 1, "photo": "x.png",
                        "faps": {"open_jaw": 100, "5": -20}})
    path = tmp_path / "p.fapproj"

    def project(data):
        path.write_bytes(data)
        load_project(path, names)

    tried, clean, bad = _fuzz(1603, [text.encode(), small.encode()], 300, project,
                              ProjectError)
    assert not bad, bad[:5]


def test_fuzz_study_reader(tmp_path):
    from editor.study.mos import Study

    good = _study(tmp_path).read_bytes()
    path = tmp_path / "f.db"

    def study(data):
        for suffix in ("-wal", "-shm"):
            Path(f"{path}{suffix}").unlink(missing_ok=True)
        path.write_bytes(data)
        with Study.open(path) as st:
            st.answers(), st.stimuli(), st.raters()

    # page-level mutations (headers, schema page, data pages) of a real study
    rng = np.random.default_rng(1604)
    tried = 0
    failures = []
    for k in range(150):
        b = bytearray(good)
        for _ in range(int(rng.integers(1, 4))):
            i = int(rng.integers(0, len(b)))
            if k % 3 == 0:
                i = int(rng.integers(0, min(len(b), 8192)))  # header and schema pages
            b[i] = int(rng.integers(0, 256))
        tried += 1
        try:
            study(bytes(b))
        except StudyError:
            pass
        except Exception as e:  # noqa: BLE001
            failures.append((k, f"{type(e).__name__}: {e}"))
    # meta-level mutations through SQL (right id and version, wrong content)
    values = ["", "[]", "[1]", "[[\"a\"]]", "{}", "null", "x", "1e999", "-1", "9" * 400,
              "[" * 3000, "[\"joy\", \"joy\"]"]
    for key in ("labels", "break_every", "name", "uid", "created", "magic"):
        for v in values:
            path.write_bytes(good)
            con = sqlite3.connect(path)
            con.execute("UPDATE meta SET value = ? WHERE key = ?", (v, key))
            con.commit()
            con.close()
            tried += 1
            try:
                with Study.open(path) as st:
                    st.answers(), st.stimuli()
            except StudyError:
                pass
            except Exception as e:  # noqa: BLE001
                failures.append((key, v[:20], f"{type(e).__name__}: {e}"))
    print(f"fuzz study: tried {tried}, clean {tried - len(failures)}")
    assert not failures, failures[:5]


def test_fuzz_model_reader(tmp_path, model_arrays):
    from editor.synthesis.bilinear import load_model

    buf = io.BytesIO()
    np.savez(buf, **model_arrays)
    base = [buf.getvalue()]
    meta = str(model_arrays["metadata"]).encode()
    path = tmp_path / "m.npz"

    def model_file(data):
        path.write_bytes(data)
        load_model(path)

    tried, clean, bad = _fuzz(1605, base, 150, model_file, ModelError)

    def model_meta(data):
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError:
            text = data.decode("latin-1")
        _npz(path, model_arrays | {"metadata": np.array(text)})
        load_model(path)

    tried2, clean2, bad2 = _fuzz(1606, [meta], 250, model_meta, ModelError)
    assert not bad and not bad2, (bad + bad2)[:5]


@pytest.mark.slow
def test_fuzz_image_header(tmp_path):
    import cv2

    from editor.engine.imageio import load_image

    rgb = np.random.default_rng(0).integers(0, 256, (24, 32, 3), dtype=np.uint8)
    base = [cv2.imencode(ext, rgb)[1].tobytes() for ext in (".png", ".jpg", ".bmp")]
    path = tmp_path / "i.img"
    rng = np.random.default_rng(1607)

    def image(data):
        # mutate within the header (first 64 bytes) most of the time, as the issue asks
        path.write_bytes(data)
        load_image(path)

    headers = []
    for k in range(300):
        b = bytearray(base[k % 3])
        for _ in range(int(rng.integers(1, 4))):
            i = int(rng.integers(0, 64))
            b[i] = int(rng.integers(0, 256)) if k % 2 else 0xFF
        headers.append(bytes(b))
    failures = []
    for data in headers:
        try:
            image(data)
        except ImageError:
            pass
        except Exception as e:  # noqa: BLE001
            failures.append(f"{type(e).__name__}: {e}")
    print(f"fuzz image header: tried {len(headers)}, clean {len(headers) - len(failures)}")
    tried, clean, bad = _fuzz(1608, base, 150, image, ImageError)
    assert not failures and not bad, (failures + bad)[:5]


def test_safeio_atomic_dir_and_file(tmp_path):
    from editor import safeio

    target = tmp_path / "frames"
    with pytest.raises(KeyboardInterrupt), safeio.atomic_dir(target) as stage:
        (stage / "a.png").write_bytes(b"x")
        raise KeyboardInterrupt
    only(tmp_path)
    with safeio.atomic_dir(target) as stage:
        (stage / "a.png").write_bytes(b"x")
    only(tmp_path, "frames")
    with pytest.raises(FapStudioError, match="is a folder"):
        safeio.atomic_write_bytes(target, b"x")
    with pytest.raises(FapStudioError, match="at most 3"):
        safeio.read_bounded(target / "a.png", 0, what="at most 3")
    assert safeio.finite_in("2", 0, 3, "x") == 2.0
    for bad in ("nan", "inf", "-1", "4", None, 10**400):
        with pytest.raises(FapStudioError):
            safeio.finite_in(bad, 0, 3, "x")
    assert math.isfinite(safeio.finite_in(3, 0, 3, "x"))
    assert zipfile  # (used by the model tests)


# ------------------------------------------------------------------------------ case 13
ISSUE_VECTOR = {"lower_t_lip_rm": 419.7, "raise_b_lip_rm": -418.9, "raise_r_cornerlip": 101.0,
                "yaw_l_eyeball": 39709, "raise_l_ear": 255.4, "raise_r_ear": -265.8,
                "pull_l_ear": -138.4}


def _portraits() -> list[tuple[str, np.ndarray]]:
    """The sample, rotated, scaled, mirrored and shifted copies of it (other face geometry in
    the image, other FAPU, other mesh), and two JAFFE faces when the data are there."""
    import cv2

    from editor.engine.imageio import load_image

    sys.path.insert(0, str(ROOT / "tests"))
    try:
        from conftest import jaffe_images
    finally:
        sys.path.pop(0)
    img = load_image(SAMPLE)
    h, w = img.shape[:2]
    out = [("sample", img)]
    for name, ang, sc in (("rot+20", 20, 1.0), ("rot-25 x0.6", -25, 0.6), ("x0.5", 0, 0.5)):
        m = cv2.getRotationMatrix2D((w / 2, h / 2), ang, sc)
        out.append((name, cv2.warpAffine(img, m, (w, h), borderMode=cv2.BORDER_REPLICATE)))
    out.append(("mirrored", np.ascontiguousarray(img[:, ::-1])))
    big = cv2.resize(img, (int(w * 1.6), int(h * 1.3)))  # anisotropic: a wider face
    out.append(("wide", big))
    for p in jaffe_images("*.SU1.*.tiff")[:1] + jaffe_images("*.HA2.*.tiff")[1:2]:
        out.append((p.name, load_image(p)))
    return out


@pytest.mark.slow
def test_case13_fold_guard_floor_on_many_faces():
    from editor.core import Face
    from editor.engine.deform import EPS_CHECK
    from editor.engine.mesh import signed_areas

    rng = np.random.default_rng(1613)
    vecs = rng.uniform(FAPS.lo, FAPS.hi, (160, 68))
    vecs[:80] *= rng.random((80, 68)) < 0.15  # sparse ones, as real expressions are
    alt = np.where(np.arange(68) % 2, FAPS.lo, FAPS.hi)
    vecs = np.vstack([FAPS.clamp(FAPS.vector(ISSUE_VECTOR))[None], FAPS.lo, FAPS.hi, alt, vecs])
    vecs[:, :2] = 0
    worst = {}
    for name, img in _portraits():
        for own in (False, True):
            face = Face.from_image(img, own_expression=own)
            pts = np.stack([face.deform(v) for v in vecs])  # the public path
            a = signed_areas(pts.astype(np.float64), face.triangles)
            a0 = signed_areas(face.neutral_vertices.astype(np.float64), face.triangles)
            ratio = a * np.sign(a0) / np.abs(a0)
            worst[name, own] = float(ratio.min())
            # lips and lids meet but never cross (without head rotation, which turns the frame)
            v2 = vecs.copy()
            v2[:, 47:50] = 0
            p2 = np.stack([face.deform(v) for v in v2])
            ey = face.frame.rot[:, 1]
            pairs = face.mesh.pairs
            assert (p2[:, pairs[:, 1]] @ ey >= p2[:, pairs[:, 0]] @ ey - 1e-3).all(), name
    assert min(worst.values()) >= EPS_CHECK * 0.999, worst
    assert len(worst) >= 12


def test_a_new_users_slips_get_plain_words(capfd, tmp_path):
    """From a new user's trial: an image name OpenCV cannot encode says which names work (it
    printed OpenCV's own source path); FAPs 1 and 2 on the command line point to --preset (they
    were silently ignored); a one-value frame says "1 value" (it said "1 values"); --mu with
    --method fap says it has no effect (it was silently accepted)."""
    code, _, err = cli(capfd, "render", SAMPLE, "-o", tmp_path / "x.txt")
    one_line_error(code, err, what=".png")
    assert "opencv" not in err.lower()
    for spec in ("1=3", "viseme=3", "expression=1"):
        code, _, err = cli(capfd, "render", SAMPLE, "--fap", spec, "-o", tmp_path / "v.png")
        one_line_error(code, err, what="--preset")
    only(tmp_path)
    bad = tmp_path / "one.fap"
    bad.write_text("2.1 one 25 1\n" + " ".join(["0", "0", "1"] + ["0"] * 65) + "\n0 5 6\n")
    code, _, err = cli(capfd, "fap", "info", bad)
    one_line_error(code, err, what="expected 1 value for 1 masked FAP, got 2")
    code, _, err = cli(capfd, "clone", "--source-neutral", SAMPLE, "--source", SAMPLE,
                       "--target", SAMPLE, "--mu", "5", "-o", tmp_path / "c.png")
    assert code == 0 and "--mu" in err and "does not use it" in err, err


def test_the_readmes_fap_example_is_a_fap_file(tmp_path):
    """The README's hand-written .fap example (a new user found no format description) reads as
    it says: two frames, FAPs 3, 12 and 13."""
    from conftest import ROOT

    from editor.formats.fapfile import read_fap

    text = (ROOT / "README.md").read_text(encoding="utf-8")
    start = text.index("```text\n2.1 smile") + len("```text\n")
    seq = read_fap(text[start:text.index("```", start)].encode())
    assert seq.frames.shape[0] == 2
    used = sorted(int(n) + 1 for n in np.flatnonzero(np.abs(seq.frames).max(0)))
    assert used == [3, 12, 13]
    assert seq.frames[1, 2] == 150 and seq.frames[1, 11] == 300


def test_clone_says_what_the_target_shows_and_what_each_route_did(capfd, tmp_path):
    """As ``render`` does, ``clone`` says the target's own expression is set aside (a new user
    saw a smiling target's smile vanish without a word), and the Laplacian route does not
    claim to have estimated FAPs (it transfers landmark motion; the estimate is for
    --faps-json)."""
    args = ["clone", "--source-neutral", SAMPLE, "--source", SAMPLE, "--target", SAMPLE]
    code, _, err = cli(capfd, *args, "-o", tmp_path / "f.png")
    assert code == 0 and "the target shows: smile" in err and "fap: 0 FAPs estimated" in err
    code, _, err = cli(capfd, *args, "--method", "laplacian", "-o", tmp_path / "l.png")
    assert code == 0 and "laplacian: landmark motion transferred" in err, err
