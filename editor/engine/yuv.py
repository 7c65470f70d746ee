"""RGB frames to the H.264 encoder's picture layout: planar yuv420p (I420), even sizes.

:func:`rgb_to_i420` is what a render worker (or the exporting process, with one job) does to a
frame before it reaches the encoder, so that the encoding process only encodes: converting
there through FFmpeg's swscale cost about as much CPU as x264's own work (1080p on this
machine: ~9 ms a frame, against ~3 ms here).

The colours are swscale's default for ``rgb24 -> yuv420p`` (ITU-R BT.601, limited range): luma
through OpenCV's ``COLOR_RGB2YUV_I420`` (within 1 of swscale), chroma as the BT.601 matrix on
the mean of each 2 x 2 block (``INTER_AREA`` at half size; within 4 of swscale, mean 0.2;
OpenCV's own I420 chroma takes one pixel of each block and loses about 2 dB). Odd sizes are
padded by one replicated column/row (yuv420p halves the chroma resolution).
"""

from __future__ import annotations

import cv2
import numpy as np

#: full-range chroma (JPEG's YCrCb, as cv2.COLOR_RGB2YCrCb gives it) -> limited range (16..240)
_LIMITED = np.round((np.arange(256) - 128.0) * 224.0 / 255.0 + 128.0).astype(np.uint8)


def even_size(h: int, w: int) -> tuple[int, int]:
    """``(h, w)`` rounded up to even numbers (the encoded picture's size)."""
    return h + h % 2, w + w % 2


def i420_shape(h: int, w: int) -> tuple[int, int]:
    """The shape of the I420 buffer of an ``h x w`` RGB frame: Y rows, then U and V."""
    eh, ew = even_size(h, w)
    return eh * 3 // 2, ew


def rgb_to_i420(rgb: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """``(H, W, 3)`` uint8 RGB -> ``i420_shape(H, W)`` uint8 (written into ``out`` if given)."""
    h, w = rgb.shape[:2]
    if h % 2 or w % 2:
        rgb = cv2.copyMakeBorder(rgb, 0, h % 2, 0, w % 2, cv2.BORDER_REPLICATE)
        h, w = rgb.shape[:2]
    if out is None:
        out = np.empty((h * 3 // 2, w), np.uint8)
    elif (out.shape != (h * 3 // 2, w) or out.dtype != np.uint8
          or not out.flags.c_contiguous):
        raise ValueError(f"I420 buffer of shape {out.shape}, expected {(h * 3 // 2, w)}")
    cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2YUV_I420, dst=out)  # Y (and chroma)
    half = cv2.resize(rgb, (w // 2, h // 2), interpolation=cv2.INTER_AREA)  # 2 x 2 means
    ycc = cv2.cvtColor(half, cv2.COLOR_RGB2YCrCb)  # BT.601, full range: Y, Cr, Cb
    flat = out.reshape(-1)  # the planes follow each other: Y (h x w), U, V (h/2 x w/2 each)
    n, q = h * w, h * w // 4
    u = flat[n:n + q].reshape(h // 2, w // 2)
    v = flat[n + q:].reshape(h // 2, w // 2)
    cv2.mixChannels([ycc], [u, v], [2, 0, 1, 1])
    cv2.LUT(u, _LIMITED, dst=u)
    cv2.LUT(v, _LIMITED, dst=v)
    return out
