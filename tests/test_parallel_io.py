"""Issue 15 (throughput): parallel animate and study stimuli give the serial path's output;
``fap info`` streams and says what it said before (good and malformed files)."""

from __future__ import annotations

import numpy as np
import pytest

from editor.engine import pool
from editor.formats.fapfile import FapSequence
from editor.formats.presets import apply_preset, get_preset
from editor.formats.video import export_sequence
from editor.resources import SAMPLE_FACE


def _ramp(frames: int) -> FapSequence:
    vec = apply_preset(get_preset("joy"), 1.0)
    return FapSequence(np.linspace(0, 1, frames, dtype=np.float32)[:, None] * vec[None], fps=25)


@pytest.mark.parametrize("jobs", [1, 2])
def test_worker_face_renders_like_the_parent(sample_face, jobs):
    """Frames handed back through shared memory: each is the parent's render while it is
    current (a ring of buffers, reused only after the caller came back)."""
    vecs = _ramp(6).frames
    got = [f.copy() for f in pool.rendered_frames(sample_face, vecs, True, jobs)]
    assert len(got) == 6
    for v, img in zip(vecs, got, strict=True):
        assert np.array_equal(img, sample_face.render(v))


@pytest.fixture(scope="module")
def odd_face():
    """The sample cut to an odd width and height (the video pads one column and row)."""
    from editor.core import Face, load_image

    return Face.from_image(np.ascontiguousarray(load_image(SAMPLE_FACE)[:509, :507]))


@pytest.mark.parametrize("name", ["frames", "a.mp4", "a.avi", "odd.mp4"])
def test_parallel_export_is_the_serial_export(sample_face, odd_face, tmp_path, name):
    seq = _ramp(7)
    face = odd_face if name.startswith("odd") else sample_face
    a = export_sequence(face, seq, tmp_path / "serial" / name, jobs=1)
    b = export_sequence(face, seq, tmp_path / "pool" / name, jobs=2)
    assert a.frames == b.frames == 7 and not b.cancelled
    if name == "frames":
        files = sorted(p.name for p in a.path.iterdir())
        assert files == sorted(p.name for p in b.path.iterdir()) and len(files) == 7
        for f in files:
            assert (a.path / f).read_bytes() == (b.path / f).read_bytes(), f
    else:
        import av

        def frames(p):
            with av.open(str(p)) as c:
                return [f.to_ndarray(format="rgb24") for f in c.decode(c.streams.video[0])]

        fa, fb = frames(a.path), frames(b.path)
        assert len(fa) == len(fb) == 7
        assert fa[0].shape[:2] == (face.image.shape[0] + face.image.shape[0] % 2,
                                   face.image.shape[1] + face.image.shape[1] % 2)
        assert all(np.array_equal(x, y) for x, y in zip(fa, fb, strict=True))


def test_parallel_export_cancel_and_errors_leave_nothing(sample_face, tmp_path):
    from pathlib import Path

    shm = Path("/dev/shm")
    before = set(shm.iterdir()) if shm.is_dir() else set()
    res = export_sequence(sample_face, _ramp(9), tmp_path / "c.mp4", jobs=2,
                          progress=lambda d, n: d < 3)
    assert res.cancelled and res.frames == 3
    assert list(tmp_path.iterdir()) == []
    # the shared frame buffers are released, also on a cancel
    assert (set(shm.iterdir()) if shm.is_dir() else set()) <= before


def test_ordered_map_order_and_worker_error():
    assert list(pool.ordered_map(abs, [-3, 1, -2, 5, -4], 2, window=2)) == [3, 1, 2, 5, 4]
    with pytest.raises(TypeError):
        list(pool.ordered_map(abs, [1, "x", 2], 2))


def test_animate_jobs_option(cli, tmp_path):
    from editor.formats.fapfile import write_fap

    fap = tmp_path / "r.fap"
    write_fap(_ramp(4), fap)
    r = cli("animate", SAMPLE_FACE, fap, "-q", "--jobs", "0", "-o", tmp_path / "x")
    code, err = r.returncode, r.stderr
    assert code == 2 and "--jobs" in err
    r = cli("animate", SAMPLE_FACE, fap, "-q", "-j", "2", "-o", tmp_path / "y")
    code, err = r.returncode, r.stderr
    assert code == 0 and len(list((tmp_path / "y").iterdir())) == 4, err


def test_parallel_stimuli_are_the_serial_stimuli(tmp_path):
    import cv2

    from editor.study.stimuli import encode_png, render_stimuli

    img = cv2.imread(str(SAMPLE_FACE))
    faces = [SAMPLE_FACE, tmp_path / "mirror.png", tmp_path / "small.png"]
    cv2.imwrite(str(faces[1]), img[:, ::-1])
    cv2.imwrite(str(faces[2]), cv2.resize(img, None, fx=0.8, fy=0.8))
    seen: list[tuple[int, int]] = []
    args = (faces, ["joy", "anger"], [0.5, 1.0])
    serial = render_stimuli(*args, jobs=1)
    par = render_stimuli(*args, jobs=2, progress=lambda d, t: seen.append((d, t)))
    assert len(serial) == len(par) == 12
    assert [r[:3] for r in serial] == [r[:3] for r in par]
    assert [encode_png(r[3]) for r in serial] == [encode_png(r[3]) for r in par]
    assert seen == [(5, 15), (10, 15), (15, 15)]


def test_parallel_stimuli_error_is_the_serial_error(tmp_path):
    from editor.errors import FapStudioError
    from editor.study.stimuli import render_stimuli

    bad = tmp_path / "blank.png"
    import cv2

    cv2.imwrite(str(bad), np.full((200, 200, 3), 128, np.uint8))
    errs = []
    for jobs in (1, 2):
        with pytest.raises(FapStudioError) as e:
            render_stimuli([SAMPLE_FACE, bad, SAMPLE_FACE], ["joy"], [1.0], jobs=jobs)
        errs.append(str(e.value))
    assert errs[0] == errs[1] and "blank.png" in errs[0]


# ---------------------------------------------------------------- fap info, streamed
def _old_info(data: bytes) -> str:
    from editor.errors import FapFileError
    from editor.formats.fapfile import fap_info, read_fap

    try:
        return fap_info(read_fap(data, label="t.fap"))
    except FapFileError as e:
        return f"error: {e}"


def _new_info(data: bytes, rng: np.random.Generator) -> str:
    from editor.errors import FapFileError
    from editor.formats.fapfile import _InfoStream, _stream_blocks

    cuts = np.sort(rng.integers(0, len(data) + 1, int(rng.integers(0, 12))))
    chunks = [data[a:b] for a, b in zip([0, *cuts], [*cuts, len(data)], strict=True)]
    try:
        return _InfoStream("t.fap").run(_stream_blocks(iter(chunks), "t.fap"))
    except FapFileError as e:
        return f"error: {e}"


def _fap_samples() -> list[bytes]:
    from editor.formats.fapfile import ExpressionField, VisemeField, format_fap

    vec = np.eye(68)[2] * 300 + np.eye(68)[40] * 200
    ramp = _ramp(5)
    xf = FapSequence(np.zeros((3, 68)), visemes=[VisemeField(1, 2, 30), None, None],
                     expressions=[None, ExpressionField(1, 40, 3, 20), None])
    mask = " ".join(["0", "0", "1"] + ["0"] * 65)
    return [format_fap(FapSequence.single(vec, frames=3)).encode(),
            format_fap(ramp).encode(), format_fap(xf, high_level="xface").encode(),
            b"\xef\xbb\xbf# greta\r\n2.0 a b c 12.5 2\r\n" + (" ".join(["0"] * 68 + ["1"])).encode()
            + b"\r\n0\r\n" + (" ".join(["1"] * 68)).encode() + b"\r\n1 "
            + b" ".join([b"1"] * 66) + b" 2 3\r\n",
            f"2.1 t 25 3\n# c\n{mask}\n1 10.6\n\n{mask}\n2\t-3\r{mask}\n3 +4\n".encode(),
            f"2.1 t 25 2\n{mask}\n0 5\n{mask}\n1 {2**24 + 1}\n".encode(),
            f"2.1 t 25 2\n{mask}\n0 5\n{mask}\n".encode(),
            f"2.1 t 25 1\n{mask}\n0 5\n{mask}\n0 5\n".encode(),
            f"2.1 t 25 2\n{mask}\n0 5\n{mask}\n7 5\n\x00".encode(),
            f"2.1 t 25 2\n{mask}\n0 5 6\n{mask}\n\xe9 5\n".encode("latin-1"),
            b"", b"\n# only\n", b"2.2 x 25 1\n"]


def test_fap_info_stream_is_fap_info_of_read_fap():
    samples = _fap_samples()
    rng = np.random.default_rng(15)
    for data in samples:
        old = _old_info(data)
        for _ in range(4):  # chunked at random places (CR LF, UTF-8, BOM across chunks)
            assert _new_info(data, rng) == old, data[:80]
    assert sum(_old_info(d).startswith("error:") for d in samples) >= 8  # malformed ones too


def test_fap_info_stream_fuzz():
    from tests.test_robustness import _mutate

    rng = np.random.default_rng(1515)
    base = _fap_samples()[:6]
    errors = 0
    for k in range(300):
        data = base[k % len(base)]
        for _ in range(int(rng.integers(1, 4))):
            data = _mutate(rng, data)
        old = _old_info(data)
        errors += old.startswith("error:")
        assert _new_info(data, rng) == old, (k, data[:200])
    assert 50 < errors < 300


def _long_fap(frames: int, data: dict[int, str] | None = None,
              between: dict[int, str] | None = None, masks: dict[int, str] | None = None,
              count: int | None = None, first: int = 0, eol: str = "\n") -> bytes:
    """A file of ``frames`` plain integer frames under one mask (the block path's case), with
    frame k's data line, the lines before it or its mask line replaced."""
    flags = ["0"] * 68
    for i in (2, 3, 10, 30, 47):
        flags[i] = "1"
    mask = " ".join(flags)
    out = [f"2.1 long 25 {frames if count is None else count}"]
    for k in range(frames):
        out += [(between or {}).get(k, "")] if k in (between or {}) else []
        out.append((masks or {}).get(k, mask))
        v = (k * 37) % 301 - 150
        out.append((data or {}).get(k, f"{k + first} {v} {-v} 7 {k % 50} -{k % 9}"))
    return (eol.join(out) + eol).encode()


def test_fap_info_block_path_is_the_line_by_line_reader():
    """Runs of plain frames are read a block at a time: whatever a line holds, wherever a chunk
    ends (mid-frame, mid-line, between a mask and its data line), the text or the error is
    read_fap's."""
    n = 300
    samples = [_long_fap(n), _long_fap(n, first=1), _long_fap(n, eol="\r\n"),
               _long_fap(n, count=n + 1), _long_fap(n, count=n - 1), _long_fap(n)[:-200]]
    odd = ["+200 -0 007 1 2 3", " \t200 1\t+2  3 4 5\t ", "200 1 2 3 4 5.5", "200 1 2 3 4",
           f"200 1 2 3 4 {2**24}", f"200 1 2 3 4 -{2**24 + 1}", "200 1 2 3 4 1234567890123456",
           "200 1 2 3 4 5 6", "200 1 2 3 4 5-3", "200 1 2 3 4 --5", "200 1 2 3 4 +",
           "200 1 2 3 4 -99999999999999999999", "200 1 2 3 4 0000000000000000005",
           "200 1 2 3 4 \u0663", "200 1\x0b2 3 4 5", "200 1\xa02 3 4 5", "201 1 2 3 4 5",
           "199 1 2 3 4 5", "", "# a comment", "200 1 2 3 4 5 # note"]
    samples += [_long_fap(n, data={200: t}) for t in odd]
    samples += [_long_fap(n, data={0: "1 1 2 3 4 5"}), _long_fap(n, data={0: "2 1 2 3 4 5"}),
                _long_fap(n, data={k: f"{k} 1 2 3 4 5" for k in range(0, n, 3)})]
    samples += [_long_fap(n, between={k: t}) for k in (1, 200, n - 1) for t in ("", "# c")]
    alt = " ".join(["0", "0", "1", "1"] + ["0"] * 64)
    greta = " ".join(["0", "0", "1", "1", "0", "0", "0", "0", "0", "0", "1"] + ["0"] * 19
                     + ["1"] + ["0"] * 16 + ["1"] + ["0"] * 20 + ["1"])
    spaced = greta[:-2].replace(" ", "  ", 3)
    samples += [_long_fap(n, masks={200: alt}, data={200: "200 1 2"}),
                _long_fap(n, masks={k: greta for k in range(100, 250)}),
                _long_fap(n, masks={k: spaced for k in range(100, 250, 2)}),
                _long_fap(n, masks={200: "1 " + greta[2:-2]}, data={200: "200 3 1 2 3 4 5"}),
                _long_fap(n, masks={200: "1" + spaced[1:]}, data={200: "200 1 2 3 4 5"})]
    rng = np.random.default_rng(1515)
    olds = [_old_info(data) for data in samples]
    for data, old in zip(samples, olds, strict=True):
        for _ in range(2):
            assert _new_info(data, rng) == old, data[:80]
        mid = data.index(b"\n", data.index(b"\n", len(data) // 2) + 1) + 1  # a line's end
        for cuts in ([mid], [mid - 1], list(range(0, len(data), 1999))):
            chunks = [data[a:b] for a, b in zip([0, *cuts], [*cuts, len(data)], strict=True)]
            assert _stream_info(chunks) == old, (cuts[:2], data[:80])
    assert sum(old.startswith("error:") for old in olds) >= 15


def test_fap_info_reads_plain_runs_by_blocks(monkeypatch):
    """The block path is what reads a run of plain frames (the test above is not vacuous):
    all frames but the first few (line by line, until a run shows) and one per chunk."""
    from editor.formats import fapfile

    taken: list[np.ndarray] = []

    def spy(*args, **kwargs):
        taken.append(rows := plain_frames(*args, **kwargs))
        return rows

    plain_frames = fapfile._plain_frames
    monkeypatch.setattr(fapfile, "_plain_frames", spy)
    data = _long_fap(700)
    cuts = list(range(0, len(data), 20_000))
    chunks = [data[a:b] for a, b in zip([0, *cuts], [*cuts, len(data)], strict=True)]
    assert _stream_info(chunks) == _old_info(data)
    numbers = np.concatenate([r[:, 0] for r in taken])
    assert len(numbers) >= 700 - fapfile._RUN - len(chunks)
    assert (np.diff(numbers) > 0).all() and numbers[-1] == 699


def _stream_info(chunks: list[bytes]) -> str:
    from editor.errors import FapFileError
    from editor.formats.fapfile import _InfoStream, _stream_blocks

    try:
        return _InfoStream("t.fap").run(_stream_blocks(iter(chunks), "t.fap"))
    except FapFileError as e:
        return f"error: {e}"


def test_fap_info_long_fuzz():
    """Byte mutations anywhere in a long run of plain frames: the text or error of read_fap."""
    from tests.test_robustness import _mutate

    rng = np.random.default_rng(1516)
    base = [_long_fap(200), _long_fap(200, masks={100: " ".join(["0", "0", "1"] + ["0"] * 65)},
                                      data={100: "100 9"})]
    for k in range(80):
        data = base[k % 2]
        for _ in range(int(rng.integers(1, 4))):
            data = _mutate(rng, data)
        assert _new_info(data, rng) == _old_info(data), (k, data[:200])


def test_fap_info_cli_streams_a_file(cli, tmp_path):
    from editor.formats.fapfile import fap_info, read_fap, write_fap

    p = tmp_path / "r.fap"
    write_fap(_ramp(9), p)
    r = cli("fap", "info", p)
    assert r.returncode == 0 and r.stdout == fap_info(read_fap(p)) + "\n"
    p.write_bytes(p.read_bytes()[:-30])
    r = cli("fap", "info", p)
    with pytest.raises(Exception) as e:
        read_fap(p)
    assert r.returncode == 2 and r.stderr == f"fap-studio: error: {e.value}\n"


@pytest.mark.parametrize("name", ["a.mp4", "frames"])
def test_ctrl_c_during_parallel_animate_leaves_nothing(tmp_path, name):
    """tests/test_robustness.py case 6 with render workers (--jobs 2; the default is the
    cores but one, so 1 on a 2-core machine)."""
    from tests.test_robustness import interrupt_animate, only

    out = tmp_path / "out"
    out.mkdir()
    r = interrupt_animate(tmp_path, out / name, "--jobs", "2")
    assert r.returncode == 130, r.stderr
    assert r.stderr.rstrip().endswith("fap-studio: interrupted") and "Traceback" not in r.stderr
    only(out)


def test_worker_error_is_one_line_and_leaves_nothing(cli, tmp_path, monkeypatch):
    """An error in a render worker: one line, exit 2, nothing partial (case 5 with workers)."""
    from editor.formats.fapfile import write_fap

    fap = tmp_path / "r.fap"
    write_fap(_ramp(6), fap)
    out = tmp_path / "out"
    out.mkdir()
    from editor.engine import pool

    monkeypatch.setattr(pool, "render_face_into", _failing_render)  # runs in the workers
    monkeypatch.setattr(pool, "render_patch_into", _failing_render)  # (H.264: the boxes)
    r = cli("animate", SAMPLE_FACE, fap, "-q", "--jobs", "2", "-o", out / "a.mp4")
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "worker says no" in r.stderr and "Traceback" not in r.stderr
    assert list(out.iterdir()) == []


def _failing_render(task):
    from editor.errors import FapStudioError

    raise FapStudioError("worker says no")
