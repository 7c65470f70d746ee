"""Drawing landmarks and meshes over a photo (for the CLI, docs and tests; no Qt)."""

from __future__ import annotations

import cv2
import numpy as np

from .landmarks import Landmarks

_SHIFT = 4


def _pt(p: np.ndarray | tuple[float, float], s: float = 1.0) -> tuple[int, int]:
    return int(round(p[0] * s * 16)), int(round(p[1] * s * 16))


def draw_landmarks(rgb: np.ndarray, lm: Landmarks, scale: float = 1.0) -> np.ndarray:
    """The photo with the 68 points (green), MPEG-4 ids of the mapped points and iris circles."""
    img = cv2.resize(rgb, None, fx=scale, fy=scale, interpolation=cv2.INTER_CUBIC) \
        if scale != 1.0 else rgb.copy()
    r = max(1, int(round(1.5 * scale)))
    for p in lm.points:
        cv2.circle(img, _pt(p, scale), r * 16, (0, 255, 0), -1, cv2.LINE_AA, _SHIFT)
    for ir in (lm.iris_left, lm.iris_right):
        cv2.circle(img, _pt((ir.cx, ir.cy), scale), int(ir.r * scale * 16), (255, 60, 60), 1,
                   cv2.LINE_AA, _SHIFT)
    if scale >= 2:
        for k, (x, y) in lm.fdp_points().items():
            cv2.putText(img, k, (int(x * scale) + 3, int(y * scale) - 3),
                        cv2.FONT_HERSHEY_SIMPLEX, 0.28 * scale / 2, (255, 255, 0), 1, cv2.LINE_AA)
    return img


def draw_mesh(rgb: np.ndarray, vertices: np.ndarray, triangles: np.ndarray,
              fdp: dict[str, int] | None = None, scale: float = 1.0,
              holes: dict[str, np.ndarray] | None = None) -> np.ndarray:
    """The photo with the mesh edges (white), vertices (cyan) and FDP vertices (yellow)."""
    img = cv2.resize(rgb, None, fx=scale, fy=scale, interpolation=cv2.INTER_CUBIC) \
        if scale != 1.0 else rgb.copy()
    e = triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    e = np.unique(np.sort(e, 1), axis=0)
    seg = np.round(vertices[e] * scale * 16).astype(np.int32)
    layer = img.copy()
    cv2.polylines(layer, list(seg), False, (255, 255, 255), 1, cv2.LINE_AA, _SHIFT)
    if holes:
        for loop in holes.values():
            poly = np.round(vertices[loop] * scale * 16).astype(np.int32)
            cv2.polylines(layer, [poly], True, (255, 80, 80), 1, cv2.LINE_AA, _SHIFT)
    img = cv2.addWeighted(layer, 0.7, img, 0.3, 0)
    r = max(1, int(round(scale)))
    fdp_idx = set(fdp.values()) if fdp else set()
    for i, p in enumerate(vertices):
        col = (255, 220, 0) if i in fdp_idx else (0, 220, 255)
        cv2.circle(img, _pt(p, scale), r * 16, col, -1, cv2.LINE_AA, _SHIFT)
    if fdp and scale >= 2:
        for k, i in fdp.items():
            x, y = vertices[i] * scale
            cv2.putText(img, k, (int(x) + 3, int(y) - 3), cv2.FONT_HERSHEY_SIMPLEX,
                        0.28 * scale / 2, (255, 255, 0), 1, cv2.LINE_AA)
    return img
