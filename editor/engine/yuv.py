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


def i420_planes(buf: np.ndarray, h: int, w: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Views of the Y ``(h, w)``, U and V ``(h / 2, w / 2)`` planes of an I420 buffer of an
    ``h x w`` picture (even sizes; ``buf`` contiguous, holding the planes one after another)."""
    flat = buf.reshape(-1)
    n, q = h * w, h * w // 4
    return (flat[:n].reshape(h, w), flat[n:n + q].reshape(h // 2, w // 2),
            flat[n + q:n + 2 * q].reshape(h // 2, w // 2))


def even_box(box: tuple[int, int, int, int] | None, h: int, w: int
             ) -> tuple[int, int, int, int] | None:
    """``(x0, y0, x1, y1)`` grown to even corners within the ``h x w`` frame's encoded picture
    (:func:`even_size`); None for None or an empty box."""
    if box is None:
        return None
    eh, ew = even_size(h, w)
    x0, y0 = max(box[0], 0) & ~1, max(box[1], 0) & ~1
    x1, y1 = min(box[2] + box[2] % 2, ew), min(box[3] + box[3] % 2, eh)
    return (x0, y0, x1, y1) if x1 > x0 and y1 > y0 else None


def i420_box(rgb: np.ndarray, box: tuple[int, int, int, int],
             out: np.ndarray | None = None) -> np.ndarray:
    """The I420 planes of ``rgb_to_i420(rgb)`` over ``box`` (even corners: :func:`even_box`),
    as a picture of the box's size (``i420_shape`` of it; into ``out`` if given): the same
    values, computed for the box alone."""
    x0, y0, x1, y1 = box
    return rgb_to_i420(rgb[y0:y1, x0:x1], out)


class I420Canvas:
    """The frames of a video that differ from one picture (the photo) inside a box each: a
    frame is the photo's I420 with a patch (:func:`i420_box` of the rendered frame) pasted in.

    :meth:`show` returns the same buffer every time (valid until the next call): the previous
    patch's box is restored from the photo, then the new patch pasted (the cost of the boxes,
    not of the frame)."""

    def __init__(self, rgb: np.ndarray) -> None:
        h, w = rgb.shape[:2]
        self.size = even_size(h, w)
        self.base = rgb_to_i420(rgb)
        self.frame = self.base.copy()
        self.box: tuple[int, int, int, int] | None = None

    def show(self, box: tuple[int, int, int, int] | None, patch: np.ndarray | None
             ) -> np.ndarray:
        """The frame with ``patch`` (the I420 planes of ``box``, one after another; None: the
        photo) in place of the photo."""
        eh, ew = self.size
        if self.box is not None:
            x0, y0, x1, y1 = self.box
            for d, b, s in zip(i420_planes(self.frame, eh, ew), i420_planes(self.base, eh, ew),
                               (1, 2, 2), strict=True):
                d[y0 // s:y1 // s, x0 // s:x1 // s] = b[y0 // s:y1 // s, x0 // s:x1 // s]
        if box is not None and patch is not None:
            x0, y0, x1, y1 = box
            for d, p, s in zip(i420_planes(self.frame, eh, ew),
                               i420_planes(patch, y1 - y0, x1 - x0), (1, 2, 2), strict=True):
                d[y0 // s:y1 // s, x0 // s:x1 // s] = p
        self.box = box if patch is not None else None
        return self.frame
