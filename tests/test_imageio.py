"""Photo decoding: every file decoded once, alpha composited over white, EXIF still applied."""

from __future__ import annotations

import zlib

import cv2
import numpy as np
import pytest

from editor.engine import imageio
from editor.engine.imageio import load_image
from editor.resources import SAMPLE_FACE


@pytest.fixture
def decodes(monkeypatch) -> list[int]:
    """Flags of every cv2.imdecode call made by load_image."""
    calls: list[int] = []
    real = cv2.imdecode

    def counting(buf, flags):
        calls.append(flags)
        return real(buf, flags)

    monkeypatch.setattr(imageio.cv2, "imdecode", counting)
    return calls


def _ramp_alpha(rgb: np.ndarray) -> np.ndarray:
    h, w = rgb.shape[:2]
    a = np.tile(np.linspace(0, 255, w).astype(np.uint8), (h, 1))
    return np.dstack([rgb[..., ::-1], a])  # BGRA for OpenCV


@pytest.mark.parametrize("ext", [".png", ".jpg", ".webp", ".tiff"])
def test_each_file_is_decoded_once(tmp_path, decodes, ext):
    rgb = load_image(SAMPLE_FACE)
    decodes.clear()
    cv2.imwrite(str(tmp_path / f"x{ext}"), rgb[..., ::-1])
    assert load_image(tmp_path / f"x{ext}").shape == rgb.shape
    assert len(decodes) == 1


@pytest.mark.parametrize("ext", [".png", ".webp"])
def test_translucent_pixels_are_composited_over_white(tmp_path, decodes, ext):
    rgb = load_image(SAMPLE_FACE)
    decodes.clear()
    params = [cv2.IMWRITE_WEBP_QUALITY, 101] if ext == ".webp" else []  # 101 = lossless
    cv2.imwrite(str(tmp_path / f"a{ext}"), _ramp_alpha(rgb), params)
    out = load_image(tmp_path / f"a{ext}").astype(int)
    assert len(decodes) == 1
    assert np.abs(out[:, 0] - 255).max() <= 1  # alpha 0: white
    assert np.abs(out[:, -1] - rgb[:, -1]).max() <= 1  # alpha 255: the photo
    mid = rgb.shape[1] // 2  # alpha ~ 0.5: halfway between
    want = 0.5 * (rgb[:, mid].astype(int) + 255)
    assert np.abs(out[:, mid] - want).max() <= 3


def test_palette_png_with_transparency_keeps_its_alpha(tmp_path):
    """A tRNS chunk (palette transparency) declares alpha too."""
    png = bytearray(cv2.imencode(".png", np.zeros((20, 20), np.uint8))[1].tobytes())
    assert not imageio._declares_alpha(bytes(png))
    idat = png.index(b"IDAT") - 4

    trns = b"tRNS" + b"\x00\x00"
    chunk = (2).to_bytes(4, "big") + trns + zlib.crc32(trns).to_bytes(4, "big")
    assert imageio._declares_alpha(bytes(png[:idat]) + chunk + bytes(png[idat:]))


def test_study_png_encoder_round_trips_losslessly(tmp_path):
    from editor.errors import ImageError
    from editor.study.stimuli import encode_png

    rgb = np.random.default_rng(3).integers(0, 256, (37, 53, 3), dtype=np.uint8)
    png = encode_png(rgb)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    (tmp_path / "s.png").write_bytes(png)
    assert np.array_equal(load_image(tmp_path / "s.png"), rgb)  # RGB order kept, lossless
    for bad in (rgb[..., 0], rgb.astype(np.float32), np.zeros((0, 4, 3), np.uint8)):
        with pytest.raises(ImageError):
            encode_png(bad)
