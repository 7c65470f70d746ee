"""Issue 15 (animate_fps): frames reach the H.264 encoder already yuv420p (converted where they
are rendered), and the CLI's render workers are forked from the exporting process: the same
frames as one process, buffers released, no hang on OpenCV's thread pool."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import av
import numpy as np
import pytest

from editor.engine import pool
from editor.engine.imageio import load_image
from editor.engine.yuv import i420_shape, rgb_to_i420
from editor.formats.fapfile import FapSequence
from editor.formats.presets import apply_preset, get_preset
from editor.formats.video import export_sequence
from editor.resources import SAMPLE_FACE

ROOT = Path(__file__).resolve().parents[1]


def _ramp(frames: int) -> FapSequence:
    vec = apply_preset(get_preset("joy"), 1.0)
    return FapSequence(np.linspace(0, 1, frames, dtype=np.float32)[:, None] * vec[None], fps=25)


def _swscale_i420(rgb: np.ndarray) -> np.ndarray:
    """What the encoder did before: FFmpeg's rgb24 -> yuv420p (swscale)."""
    return av.VideoFrame.from_ndarray(rgb, format="rgb24").reformat(format="yuv420p").to_ndarray()


@pytest.mark.parametrize("crop", [(512, 512), (509, 507), (510, 511)])
def test_rgb_to_i420_is_swscales_conversion(crop):
    """Luma within 1 of swscale, chroma the 2 x 2 block means (within a few levels); odd sizes
    padded by a replicated column/row, as the RGB path padded them."""
    rgb = np.ascontiguousarray(load_image(SAMPLE_FACE)[:crop[0], :crop[1]])
    h, w = rgb.shape[:2]
    got = rgb_to_i420(rgb)
    assert got.shape == i420_shape(h, w) == ((h + h % 2) * 3 // 2, w + w % 2)
    padded = np.pad(rgb, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")
    ref = _swscale_i420(padded).astype(int)
    eh = h + h % 2
    d = np.abs(got.astype(int) - ref)
    assert d[:eh].max() <= 1
    assert d[eh:].mean() < 0.5 and d[eh:].max() <= 8
    # the picture survives the round trip as well as swscale's own conversion does
    def psnr(yuv):
        back = av.VideoFrame.from_ndarray(yuv, format="yuv420p").to_ndarray(format="rgb24")
        return 10 * np.log10(255**2 / ((back.astype(float) - padded) ** 2).mean())
    assert psnr(got) >= psnr(ref.astype(np.uint8)) - 0.1
    # into a buffer: the same bytes; a wrong buffer is refused
    buf = np.zeros_like(got)
    assert rgb_to_i420(rgb, buf) is buf and np.array_equal(buf, got)
    with pytest.raises(ValueError):
        rgb_to_i420(rgb, np.zeros((eh, w + w % 2), np.uint8))


@pytest.mark.parametrize("layout,fork", [("i420", False), ("i420", True), ("rgb", True)])
def test_worker_frames_are_the_parents(sample_face, layout, fork):
    vecs = _ramp(7).frames
    got = [f.copy() for f in pool.rendered_frames(sample_face, vecs, True, 2, layout=layout,
                                                  fork=fork)]
    assert len(got) == 7
    for v, img in zip(vecs, got, strict=True):
        want = sample_face.render(v)
        assert np.array_equal(img, rgb_to_i420(want) if layout == "i420" else want)


@pytest.mark.parametrize("name", ["a.mp4", "odd.mp4", "frames"])
def test_forked_export_is_the_serial_export(sample_face, tmp_path, name):
    from editor.core import Face

    face = sample_face
    if name.startswith("odd"):
        face = Face.from_image(np.ascontiguousarray(load_image(SAMPLE_FACE)[:509, :507]))
    seq = _ramp(7)
    a = export_sequence(face, seq, tmp_path / "serial" / name, jobs=1)
    b = export_sequence(face, seq, tmp_path / "fork" / name, jobs=2, fork=True)
    assert a.frames == b.frames == 7 and not b.cancelled
    if name == "frames":
        files = sorted(p.name for p in a.path.iterdir())
        assert len(files) == 7
        assert all((a.path / f).read_bytes() == (b.path / f).read_bytes() for f in files)
        return

    def planes(p):  # what the encoder was given, as decoded (no conversion back to RGB)
        with av.open(str(p)) as c:
            return [f.to_ndarray() for f in c.decode(c.streams.video[0])]

    pa, pb = planes(a.path), planes(b.path)
    assert len(pa) == len(pb) == 7
    assert all(np.array_equal(x, y) for x, y in zip(pa, pb, strict=True))
    # and it is the frames: the last decoded frame is close to its render
    last = rgb_to_i420(face.render(seq.frames[-1])).astype(int)
    assert np.abs(pb[-1].astype(int) - last).mean() < 2.0


def test_forked_export_cancel_releases_everything(sample_face, tmp_path):
    shm = Path("/dev/shm")
    before = set(shm.iterdir()) if shm.is_dir() else set()
    res = export_sequence(sample_face, _ramp(12), tmp_path / "c.mp4", jobs=2, fork=True,
                          progress=lambda d, n: d < 4)
    assert res.cancelled and res.frames == 4
    assert list(tmp_path.iterdir()) == []
    assert (set(shm.iterdir()) if shm.is_dir() else set()) <= before


def test_fork_only_without_threads_or_qt(monkeypatch):
    """The editor (Qt's threads) keeps the forkserver: forking next to a running thread could
    copy a lock it holds."""
    monkeypatch.delitem(sys.modules, "PySide6", raising=False)
    stop = threading.Event()
    t = threading.Thread(target=stop.wait)
    t.start()
    try:
        assert not pool.fork_is_safe()
    finally:
        stop.set()
        t.join()
    if threading.active_count() == 1:  # pytest-qt or a plugin may run threads of its own
        assert pool.fork_is_safe()
        monkeypatch.setitem(sys.modules, "PySide6", sys)
        assert not pool.fork_is_safe()


#: a process whose OpenCV thread pool has run (as the CLI's detector and fitting do), then a
#: forked export: the children must not touch the pool's threads (they do not exist there)
_CHILD = """
import time
import cv2, numpy as np
from editor.core import Face
from editor.engine import pool
from editor.formats.presets import apply_preset
from editor.resources import SAMPLE_FACE
cv2.setNumThreads(2)
a = np.zeros((1500, 1500, 3), np.uint8)
for _ in range(5):
    cv2.GaussianBlur(cv2.resize(a, (2500, 2500)), (15, 15), 3)
face = Face.from_image(SAMPLE_FACE)
assert pool.fork_is_safe()
time.sleep(1)  # the pool's threads go from spinning to waiting on their condition variables
vecs = np.linspace(0, 1, 6)[:, None] * apply_preset("joy", 1.0)[None]
n = sum(1 for _ in pool.rendered_frames(face, vecs, True, 2, layout="i420", fork=True))
assert cv2.getNumThreads() == 2  # given back to this process
print(n)
"""


def test_fork_after_opencv_threads_ran_does_not_hang():
    p = subprocess.Popen([sys.executable, "-c", _CHILD], cwd=ROOT, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        out, err = p.communicate(timeout=120)
    except subprocess.TimeoutExpired:  # hung (forked workers too): end the whole group
        os.killpg(p.pid, signal.SIGKILL)
        p.communicate()
        pytest.fail("a forked export hung on OpenCV's thread pool")
    assert p.returncode == 0 and out.strip() == "6", err[-2000:]


def test_i420_box_is_the_frames_conversion_over_the_box():
    """Each luma value from its pixel, each chroma value from its 2 x 2 block: a box with even
    corners converts alone to the whole frame's values there (odd edges padded alike)."""
    from editor.engine.yuv import I420Canvas, even_box, i420_box, i420_planes

    rng = np.random.default_rng(3)
    for h, w in ((512, 512), (509, 507)):
        rgb = np.ascontiguousarray(load_image(SAMPLE_FACE)[:h, :w])
        full = i420_planes(rgb_to_i420(rgb), h + h % 2, w + w % 2)
        canvas = I420Canvas(rgb)
        for _ in range(20):
            x = np.sort(rng.integers(0, w + 1, 2))
            y = np.sort(rng.integers(0, h + 1, 2))
            box = even_box((int(x[0]), int(y[0]), int(x[1]) + 1, int(y[1]) + 1), h, w)
            assert box is not None and box[2] <= w + w % 2 and box[3] <= h + h % 2
            x0, y0, x1, y1 = box
            patch = i420_box(rgb, box)
            for p, f, s in zip(i420_planes(patch, y1 - y0, x1 - x0), full, (1, 2, 2),
                               strict=True):
                assert np.array_equal(p, f[y0 // s:y1 // s, x0 // s:x1 // s])
            # another picture's box pasted into the photo's: that frame (the previous box
            # restored)
            other = 255 - rgb
            want = rgb.copy()
            want[y0:y1, x0:x1] = other[y0:y1, x0:x1]
            got = canvas.show(box, i420_box(other, box).reshape(-1))
            assert np.array_equal(got, rgb_to_i420(want))
        assert np.array_equal(canvas.show(None, None), rgb_to_i420(rgb))


@pytest.mark.parametrize("jobs,fork,cache", [(0, False, None), (2, False, None),
                                             (2, True, None), (2, True, 0), (0, False, 1)])
def test_i420_frames_repeats_and_holds(sample_face, jobs, fork, cache):
    """Each frame is the I420 of its render: a vector that comes again (a hold, a return) is
    rendered once and its patch kept, or rendered again when there is no room to keep it."""
    ramp = _ramp(6).frames
    vecs = np.concatenate([ramp, ramp[3:4], ramp[3:4], np.zeros((2, 68), np.float32),
                           ramp[::-1]]).astype(np.float32)
    kw = {} if cache is None else {"cache_bytes": cache}
    got = [f.copy() for f in pool.i420_frames(sample_face, vecs, True, jobs, fork=fork, **kw)]
    assert len(got) == len(vecs)
    for v, img in zip(vecs, got, strict=True):
        assert np.array_equal(img, rgb_to_i420(sample_face.render(v)))
