"""Reading and writing photos: RGB uint8 in memory, EXIF orientation applied, size limited.

Images live in memory as ``H x W x 3`` RGB ``uint8`` arrays (x to the right, y down). Files are
decoded once with OpenCV from bytes (so any path, including non-ASCII ones, works); grey, 16-bit
and alpha images are converted; an alpha channel (PNG, WebP) is composited over white.
"""

from __future__ import annotations

import os
import struct
from pathlib import Path

import numpy as np

from editor.errors import ImageError
from editor.safeio import atomic_write_bytes, quiet_stderr, read_bounded

#: Largest image accepted, in pixels (about 8000 x 8000). Larger images are refused before
#: they are decoded so that a decompression bomb cannot exhaust memory.
MAX_PIXELS = 64_000_000
#: Largest image file read (bytes), checked before reading: no device, FIFO or huge file.
MAX_FILE_BYTES = 512 * 1024 * 1024

# OpenCV reads its own decoder limit once, at the first decode: keep it in step with ours.
os.environ.setdefault("OPENCV_IO_MAX_IMAGE_PIXELS", str(MAX_PIXELS))

import cv2  # noqa: E402  (after the environment variable above)


def _header_size(data: bytes) -> tuple[int, int] | None:
    """Width and height from a PNG or JPEG header without decoding; None if unknown."""
    if data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) >= 24:
        if data[12:16] != b"IHDR":  # not a PNG's first chunk: the decoder will refuse it
            return None
        w, h = struct.unpack(">II", data[16:24])
        return int(w), int(h)
    if data[:2] == b"\xff\xd8":
        i, n = 2, len(data)
        while i + 9 < n:
            if data[i] != 0xFF:
                i += 1
                continue
            marker = data[i + 1]
            if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:
                i += 2
                continue
            seg = struct.unpack(">H", data[i + 2 : i + 4])[0]
            if marker in (0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE,
                          0xCF):
                h, w = struct.unpack(">HH", data[i + 5 : i + 9])
                return int(w), int(h)
            i += 2 + seg
    return None


def _declares_alpha(data: bytes) -> bool:
    """Whether a PNG (colour type 4/6 or a tRNS chunk) or WebP header declares transparency."""
    if data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) >= 26:
        if data[25] in (4, 6):
            return True
        i = 8
        while i + 8 <= len(data):
            n, kind = struct.unpack(">I", data[i : i + 4])[0], data[i + 4 : i + 8]
            if kind == b"tRNS":
                return True
            if kind in (b"IDAT", b"IEND"):
                return False
            i += 12 + n
        return False
    if data[:4] == b"RIFF" and data[8:12] == b"WEBP" and len(data) >= 21:
        return data[12:16] == b"VP8L" or (data[12:16] == b"VP8X" and bool(data[20] & 0x10))
    return False


def check_size(width: int, height: int, what: str = "image") -> None:
    """Raise ImageError if ``width x height`` exceeds :data:`MAX_PIXELS`."""
    if width * height > MAX_PIXELS:
        raise ImageError(
            f"{what} is {width}x{height} = {width * height / 1e6:.0f} megapixels; the limit is "
            f"{MAX_PIXELS / 1e6:.0f} megapixels (downscale it first)"
        )


def to_rgb8(img: np.ndarray) -> np.ndarray:
    """Convert a decoded OpenCV image (grey, BGR or BGRA; 8 or 16 bit) to RGB uint8."""
    img = _depth8(img)
    if img.ndim == 2:
        return cv2.cvtColor(img, cv2.COLOR_GRAY2RGB)
    if img.shape[2] == 4:
        bgr = img[..., :3].astype(np.float32)
        a = img[..., 3:4].astype(np.float32) / 255.0
        img = (bgr * a + 255.0 * (1.0 - a) + 0.5).astype(np.uint8)
    elif img.shape[2] == 1:
        return cv2.cvtColor(img[..., 0], cv2.COLOR_GRAY2RGB)
    return cv2.cvtColor(np.ascontiguousarray(img[..., :3]), cv2.COLOR_BGR2RGB)


def load_image(path: str | os.PathLike[str]) -> np.ndarray:
    """Read a photo as an ``H x W x 3`` RGB uint8 array, EXIF orientation applied.

    The file is read once (regular files only, at most 512 MB) and decoded once; its size is
    checked against :data:`MAX_PIXELS` from the header, before decoding. Grey, 16-bit and
    RGBA images become RGB uint8 (alpha composited on white).

    Parameters
    ----------
    path : str or os.PathLike
        A PNG, JPEG, TIFF, BMP, WebP, ... file.

    Returns
    -------
    numpy.ndarray
        (H, W, 3) uint8, RGB.

    Raises
    ------
    ImageError
        If the file is missing, unreadable, empty, not an image, corrupt or too large.

    Examples
    --------
    >>> from editor.core import load_image
    >>> from editor.resources import SAMPLE_FACE
    >>> rgb = load_image(SAMPLE_FACE)
    >>> rgb.shape, rgb.dtype
    ((512, 512, 3), dtype('uint8'))
    """
    p = Path(path)
    if not p.exists():
        raise ImageError(f"{p}: no such file")
    data = read_bounded(p, MAX_FILE_BYTES, error=ImageError, what="an image file")
    if not data:
        raise ImageError(f"{p}: the file is empty (0 bytes)")
    size = _header_size(data)
    if size is not None:
        check_size(*size, what=str(p))
    buf = np.frombuffer(data, np.uint8)
    try:
        # One decode. IMREAD_COLOR applies the EXIF orientation but drops alpha; files whose
        # header declares alpha (PNG/WebP; no EXIF rotation in practice) keep it.
        # Without alpha the decoder writes RGB itself (no second full-size pass to swap the
        # channels: ~20-100 ms and one image-sized temporary on a 24 MP photo).
        alpha = _declares_alpha(data)
        flags = (cv2.IMREAD_UNCHANGED if alpha
                 else cv2.IMREAD_COLOR_RGB | cv2.IMREAD_ANYDEPTH)
        with quiet_stderr():  # libpng/libjpeg warnings: the one-line error says it
            img = cv2.imdecode(buf, flags)
    except cv2.error as e:
        raise ImageError(f"{p}: cannot decode the image ({str(e).strip().splitlines()[-1]})") from e
    if img is None or img.size == 0:
        raise ImageError(f"{p}: not an image, or a corrupt or truncated one")
    check_size(img.shape[1], img.shape[0], what=str(p))
    if alpha or img.ndim != 3 or img.shape[2] != 3:
        return to_rgb8(img)
    return _depth8(img)


def _depth8(img: np.ndarray) -> np.ndarray:
    """``img`` as uint8 (16-bit rounded, other types clipped), as :func:`to_rgb8` does."""
    if img.dtype == np.uint16:
        return (img / 257.0 + 0.5).astype(np.uint8)
    if img.dtype != np.uint8:
        return np.clip(img, 0, 255).astype(np.uint8)
    return img


def as_rgb8(image: np.ndarray) -> np.ndarray:
    """Validate an in-memory image and return it as a contiguous RGB uint8 array.

    Accepts ``H x W`` grey, ``H x W x 3`` RGB and ``H x W x 4`` RGBA arrays (RGB order).
    """
    a = np.asarray(image)
    if a.ndim not in (2, 3) or (a.ndim == 3 and a.shape[2] not in (1, 3, 4)):
        raise ImageError(f"expected an H x W, H x W x 3 or H x W x 4 image, got shape {a.shape}")
    if a.shape[0] < 16 or a.shape[1] < 16:
        raise ImageError(f"image of {a.shape[1]}x{a.shape[0]} pixels is too small for a face")
    check_size(a.shape[1], a.shape[0])
    if a.ndim == 3 and a.shape[2] in (3, 4):
        # Given as RGB(A): reuse the BGR(A) converter by swapping channels first.
        a = a[..., [2, 1, 0, 3][: a.shape[2]]]
    return np.ascontiguousarray(to_rgb8(a))


def check_image_path(path: str | Path) -> None:
    """Raise :class:`ImageError` (the message :func:`save_image` would give) when ``path``'s
    suffix is not an image format OpenCV writes: for commands that check their output before
    the work (an unwritable ``-o`` said at once, not after the detection and the render)."""
    p = Path(path)
    ext = p.suffix.lower() or ".png"
    if not cv2.haveImageWriter("x" + ext):
        raise ImageError(f"{p}: cannot write an image as {ext}: use .png, .jpg, .bmp, .tif or "
                         ".webp")


def save_image(path: str | os.PathLike[str], rgb: np.ndarray) -> None:
    """Write an RGB uint8 image; the format follows the file extension (PNG, JPEG, ...).

    The file is written beside its target and renamed into place when complete (nothing
    partial on an error); JPEG quality is 95; no extension means PNG.

    Parameters
    ----------
    path : str or os.PathLike
        The output file.
    rgb : numpy.ndarray
        (H, W, 3) uint8, RGB.

    Raises
    ------
    ImageError
        If the format is unknown to the encoder or the file cannot be written.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> from editor.core import load_image, save_image
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "grey.png"
    >>> save_image(out, np.full((32, 48, 3), 128, np.uint8))
    >>> load_image(out).shape
    (32, 48, 3)
    """
    p = Path(path)
    ext = p.suffix.lower() or ".png"
    bgr = cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2BGR)
    params = [cv2.IMWRITE_JPEG_QUALITY, 95] if ext in (".jpg", ".jpeg") else []
    try:
        ok, enc = cv2.imencode(ext, bgr, params)
    except cv2.error:
        ok = False  # (OpenCV's message names its source file, not the remedy)
    if not ok:
        raise ImageError(f"{p}: cannot write an image as {ext}: use .png, .jpg, .bmp, .tif or "
                         ".webp")
    atomic_write_bytes(p, enc.tobytes(), error=ImageError)
