"""Piecewise-affine texture mapping (SPEC §2.4, eq. 5): backward, bilinear, vectorised.

Per frame: find the triangles with a moved vertex; rasterize their ids (destination mesh)
into the bounding box they cover; fit each one's inverse affine map (destination -> source) in
one batched solve; gather the coefficients per pixel; one ``cv2.remap`` of the box; every
other pixel is the photo's own. A zero FAP vector therefore reproduces the photo exactly.

Fill rule: triangles are drawn one after another with ``cv2.fillConvexPoly`` (sub-pixel
vertices); a pixel on a shared edge takes the id of the last triangle drawn there, and because
neighbouring affine maps agree on their shared edge the map is continuous: no holes, no seams.

Openings: pixels inside the deformed eye and mouth openings are not covered by any triangle.
The eyes show the photo's own pixels there; the mouth shows the photo's own pixels where the
photo's mouth was already open and a dark, softly shaded cavity elsewhere (the layered mouth
interior of SPEC §3.1 draws over it when available). The openings are returned as masks.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

_SHIFT = 4
_ONE = 1 << _SHIFT

#: Colour of the mouth cavity (RGB) before shading.
CAVITY_RGB = np.array([58, 22, 24], np.float32)


@dataclass(eq=False)
class WarpPlan:
    """Per-mesh precomputation for :func:`warp`.

    Attributes
    ----------
    image : (H, W, 3) uint8 RGB photo (read-only)
    src : (V, 2) float32 neutral vertices
    triangles : (T, 3) int32
    holes : dict name -> vertex loop (int32)
    """

    image: np.ndarray
    src: np.ndarray
    triangles: np.ndarray
    holes: dict[str, np.ndarray]
    tri_of_vertex: list[np.ndarray] = field(default_factory=list)
    neutral_mouth: np.ndarray | None = None  # (H, W) bool, photo's own mouth opening

    def __post_init__(self) -> None:
        self.image = np.ascontiguousarray(self.image)
        self.image.setflags(write=False)
        self.src = np.asarray(self.src, np.float32)
        self.triangles = np.asarray(self.triangles, np.int32)
        h, w = self.image.shape[:2]
        m = np.zeros((h, w), np.uint8)
        poly = np.round(self.src[self.holes["mouth"]] * _ONE).astype(np.int32)
        cv2.fillPoly(m, [poly], 1, cv2.LINE_8, _SHIFT)
        self.neutral_mouth = m.astype(bool)
        # source triangle vertices with a homogeneous row, for the batched affine fit
        s = self.src[self.triangles].astype(np.float64)  # (T, 3, 2)
        self._S = np.concatenate([s.transpose(0, 2, 1), np.ones((len(s), 1, 3))], 1)


@dataclass
class WarpResult:
    """Output of :func:`warp`.

    image : (H, W, 3) uint8 warped photo
    mouth_mask, eye_mask : (H, W) bool openings in the deformed face (None if unchanged)
    bbox : (x0, y0, x1, y1) region that was recomputed, or None
    """

    image: np.ndarray
    mouth_mask: np.ndarray | None
    eye_mask: np.ndarray | None
    bbox: tuple[int, int, int, int] | None


def _fill_ids(ids: np.ndarray, dst: np.ndarray, tris: np.ndarray, which: np.ndarray,
              ox: int, oy: int) -> None:
    pts = np.round((dst[tris[which]] - (ox, oy)) * _ONE).astype(np.int32)  # (n, 3, 2)
    for k, t in enumerate(which):
        cv2.fillConvexPoly(ids, pts[k], int(t), cv2.LINE_8, _SHIFT)


LAYERS = ("eye_l", "eye_r", "mouth")


def warp(plan: WarpPlan, dst: np.ndarray, layers: dict[str, np.ndarray] | None = None,
         tol: float = 1e-3) -> WarpResult:
    """Warp the photo so that the neutral mesh ``plan.src`` lands on ``dst`` (V, 2).

    Only triangles with a vertex that moved by more than ``tol`` pixels are re-filled.
    ``layers`` optionally gives, for each opening (``eye_l``, ``eye_r``, ``mouth``), the 2x3
    affine map (source -> destination) of what lies behind it: the eyeball follows its eye's
    corners, the mouth interior follows the skull. Without it the openings are static.
    """
    img = plan.image
    h, w = img.shape[:2]
    dst = np.asarray(dst, np.float32)
    V = len(plan.src)
    moved_v = np.abs(dst[:V] - plan.src).max(1) > tol
    if not moved_v.any():
        return WarpResult(img.copy(), None, None, None)
    tris = plan.triangles
    moved_t = np.flatnonzero(moved_v[tris].any(1))
    p = dst[tris[moved_t]].reshape(-1, 2)
    x0 = int(np.clip(np.floor(p[:, 0].min()) - 1, 0, w))
    y0 = int(np.clip(np.floor(p[:, 1].min()) - 1, 0, h))
    x1 = int(np.clip(np.ceil(p[:, 0].max()) + 2, 0, w))
    y1 = int(np.clip(np.ceil(p[:, 1].max()) + 2, 0, h))
    out = img.copy()
    if x1 <= x0 or y1 <= y0:
        return WarpResult(out, None, None, None)
    bw, bh = x1 - x0, y1 - y0
    ids = np.full((bh, bw), -1, np.int32)
    T = len(tris)
    layer_rows = {}
    for k, name in enumerate(LAYERS):
        if layers and name in layers:
            poly = np.round((dst[plan.holes[name]] - (x0, y0)) * _ONE).astype(np.int32)
            cv2.fillPoly(ids, [poly], T + 1 + k, cv2.LINE_8, _SHIFT)
            fwd = np.vstack([np.asarray(layers[name], np.float64), [0.0, 0.0, 1.0]])
            layer_rows[T + 1 + k] = np.linalg.inv(fwd)[:2]
    _fill_ids(ids, dst, tris, moved_t, x0, y0)

    # inverse affine per moved triangle: src = M @ [x, y, 1] (M is 2x3)
    d = dst[tris[moved_t]].astype(np.float64)
    Dm = np.concatenate([d.transpose(0, 2, 1), np.ones((len(d), 1, 3))], 1)
    det = np.linalg.det(Dm)
    ok = np.abs(det) > 1e-9
    Dinv = np.zeros_like(Dm)
    Dinv[ok] = np.linalg.inv(Dm[ok])
    M = plan._S[moved_t][:, :2, :] @ Dinv  # (n, 2, 3)
    # degenerate destination triangles (never produced by the guard): identity
    M[~ok] = np.array([[1, 0, 0], [0, 1, 0]], np.float64)
    table = np.zeros((T + 1 + len(LAYERS), 6), np.float32)
    table[:, 0] = 1.0
    table[:, 4] = 1.0  # identity for unmoved triangles and uncovered pixels (row T)
    table[moved_t] = M.reshape(-1, 6).astype(np.float32)
    for row, m in layer_rows.items():
        table[row] = m.reshape(-1)
    c = table[np.where(ids < 0, T, ids)]  # (bh, bw, 6)
    xs = np.arange(x0, x1, dtype=np.float32)[None, :]
    ys = np.arange(y0, y1, dtype=np.float32)[:, None]
    map_x = c[..., 0] * xs + c[..., 1] * ys + c[..., 2]
    map_y = c[..., 3] * xs + c[..., 4] * ys + c[..., 5]
    out[y0:y1, x0:x1] = cv2.remap(img, map_x, map_y, cv2.INTER_LINEAR,
                                  borderMode=cv2.BORDER_REPLICATE)

    # openings of the deformed face
    mouth = np.zeros((h, w), np.uint8)
    poly = np.round(dst[plan.holes["mouth"]] * _ONE).astype(np.int32)
    cv2.fillPoly(mouth, [poly], 1, cv2.LINE_8, _SHIFT)
    mouth_b = mouth.astype(bool)
    eyes = np.zeros((h, w), np.uint8)
    for k in ("eye_l", "eye_r"):
        poly = np.round(dst[plan.holes[k]] * _ONE).astype(np.int32)
        cv2.fillPoly(eyes, [poly], 1, cv2.LINE_8, _SHIFT)
    # mouth pixels whose source lies outside the photo's own opening: the cavity
    sub = (ids < 0) | (ids > T)
    sx = np.clip(np.round(map_x).astype(np.int32), 0, w - 1)
    sy = np.clip(np.round(map_y).astype(np.int32), 0, h - 1)
    cav = mouth_b[y0:y1, x0:x1] & sub & ~plan.neutral_mouth[sy, sx]
    if cav.any():
        region = out[y0:y1, x0:x1]
        region[cav] = _cavity(dst, plan.holes["mouth"], x0, y0, cav.shape)[cav]
    return WarpResult(out, mouth_b, eyes.astype(bool), (x0, y0, x1, y1))


def _cavity(dst: np.ndarray, loop: np.ndarray, x0: int, y0: int,
            shape: tuple[int, int]) -> np.ndarray:
    """A dark mouth cavity, lighter near the lips and darker towards the throat."""
    poly = dst[loop]
    cx, cy = poly.mean(0)
    half_w = max(float(np.ptp(poly[:, 0])) / 2.0, 1.0)
    half_h = max(float(np.ptp(poly[:, 1])) / 2.0, 1.0)
    ys, xs = np.mgrid[y0:y0 + shape[0], x0:x0 + shape[1]].astype(np.float32)
    r = np.sqrt(((xs - cx) / half_w) ** 2 + ((ys - cy) / half_h) ** 2)
    shade = np.clip(0.35 + 0.65 * r, 0.35, 1.0)[..., None]
    return (CAVITY_RGB * shade).astype(np.uint8)
