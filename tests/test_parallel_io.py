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


def test_worker_face_renders_like_the_parent(sample_face):
    vecs = _ramp(5).frames
    got = list(pool.ordered_map(pool.render_face, ((v, True) for v in vecs), 2, window=2,
                                initializer=pool.init_face,
                                initargs=(pool.face_args(sample_face),)))
    assert len(got) == 5
    for v, img in zip(vecs, got, strict=True):
        assert np.array_equal(img, sample_face.render(v))


@pytest.mark.parametrize("name", ["frames", "a.mp4"])
def test_parallel_export_is_the_serial_export(sample_face, tmp_path, name):
    seq = _ramp(7)
    a = export_sequence(sample_face, seq, tmp_path / "serial" / name, jobs=1)
    b = export_sequence(sample_face, seq, tmp_path / "pool" / name, jobs=2)
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
        assert all(np.array_equal(x, y) for x, y in zip(fa, fb, strict=True))


def test_parallel_export_cancel_and_errors_leave_nothing(sample_face, tmp_path):
    res = export_sequence(sample_face, _ramp(9), tmp_path / "c.mp4", jobs=2,
                          progress=lambda d, n: d < 3)
    assert res.cancelled and res.frames == 3
    assert list(tmp_path.iterdir()) == []


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
