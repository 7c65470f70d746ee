"""Video export through PyAV: H.264 / yuv420p / faststart MP4, even sizes, frames that match."""

from __future__ import annotations

import av
import numpy as np
import pytest

from editor.core import Face, load_image
from editor.formats.fapfile import FapSequence
from editor.formats.presets import apply_preset, get_preset
from editor.formats.video import export_sequence
from editor.resources import SAMPLE_FACE


def _seq(frames: int = 6, fps: float = 25) -> FapSequence:
    vec = apply_preset(get_preset("joy"), 1.0)
    ramp = np.linspace(0, 1, frames, dtype=np.float32)[:, None] * vec[None]
    seq = FapSequence.single(vec, fps=fps, frames=frames)
    seq.frames[:] = ramp
    return seq


def _decode(path) -> tuple[av.video.stream.VideoStream, list[np.ndarray]]:
    with av.open(str(path)) as c:
        s = c.streams.video[0]
        frames = [f.to_ndarray(format="rgb24") for f in c.decode(s)]
        return s, frames


def _atoms(path) -> list[bytes]:
    """Top-level MP4 box types in file order."""
    data, i, out = path.read_bytes(), 0, []
    while i + 8 <= len(data):
        size = int.from_bytes(data[i:i + 4], "big")
        out.append(data[i + 4:i + 8])
        if size < 8:
            break
        i += size
    return out


def test_mp4_is_h264_yuv420p_faststart_and_shows_the_frames(tmp_path, sample_face):
    seq = _seq()
    out = tmp_path / "joy.mp4"
    res = export_sequence(sample_face, seq, out)
    assert res.frames == 6 and not res.cancelled
    stream, frames = _decode(out)
    ctx = stream.codec_context
    assert ctx.name == "h264" and ctx.pix_fmt == "yuv420p"
    assert (ctx.width, ctx.height) == (512, 512)
    assert len(frames) == 6 and float(stream.average_rate) == pytest.approx(25)
    atoms = _atoms(out)
    assert atoms.index(b"moov") < atoms.index(b"mdat")  # the index first: +faststart
    first, last = (sample_face.render(seq.frames[i]).astype(int) for i in (0, 5))
    for got, want in ((frames[0], first), (frames[5], last)):  # lossy, but close
        assert np.abs(got.astype(int) - want).mean() < 3.0
    moved = np.abs(last - first).max(axis=2) > 30  # where the smile changed the picture
    assert moved.sum() > 200
    err = np.abs(frames[5].astype(int) - last)[moved].mean()
    assert err < 0.3 * np.abs(frames[5].astype(int) - first)[moved].mean()  # frame order kept


def test_odd_sizes_are_padded_to_even(tmp_path):
    rgb = load_image(SAMPLE_FACE)[:509, :511]
    face = Face.from_image(rgb, own_expression=False)
    out = tmp_path / "odd.mp4"
    export_sequence(face, _seq(frames=2, fps=12.5), out)
    stream, frames = _decode(out)
    assert (stream.codec_context.width, stream.codec_context.height) == (512, 510)
    assert stream.codec_context.name == "h264" and len(frames) == 2
    assert float(stream.average_rate) == pytest.approx(12.5)
    # the padding repeats the last column/row, the picture itself is not shifted
    assert np.abs(frames[0][:509, :511].astype(int) - face.image).mean() < 3.0
    assert np.abs(frames[0][:, 511].astype(int) - frames[0][:, 510]).mean() < 3.0


def test_avi_is_motion_jpeg(tmp_path, sample_face):
    out = tmp_path / "joy.avi"
    export_sequence(sample_face, _seq(frames=3), out)
    stream, frames = _decode(out)
    assert stream.codec_context.name == "mjpeg" and len(frames) == 3
