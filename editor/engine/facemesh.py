"""MediaPipe's face detector, 468-point face mesh and iris model, run with OpenCV's DNN module.

The three Apache-2.0 TFLite models (``editor/data/models``, taken from the ``mediapipe`` 0.10.18
wheel; see the NOTICE there) run through ``cv2.dnn`` on the CPU; the ``mediapipe`` package is not
used. The pipeline follows MediaPipe's own graphs:

1. **Detection** (BlazeFace short range, 128x128 letterboxed input scaled to [-1, 1]): 896 fixed
   anchors (strides 8, 16, 16, 16; 2 + 6 anchors per cell) decode into boxes and six keypoints
   (the eyes, nose tip, mouth centre, ear tragions); logits above 0 (probability 0.5) count, the
   largest face wins (overlapping detections of it are averaged, weighted by score).
2. **Mesh** (192x192 input in [0, 1]): a square crop 1.5 times the detection box, rotated so the
   eye keypoints are level, gives 468 points (x, y in crop pixels) and a face-presence logit.
3. **Iris** (64x64 input in [0, 1]): per eye, a square 2.3 times the eye-corner distance, rotated
   along the corners; the model was trained on the image-left eye, so the other eye is mirrored.
   It gives 71 eye-region points (the first 16 are the lid contour; its two eye corners replace
   the mesh's, which are measurably less accurate, while the mesh keeps its own lids, which are
   more accurate than the iris model's on JAFFE) and 5 iris points (centre, then 4 on the rim:
   the radius is their mean distance to the centre).
4. **Inner lips** (not MediaPipe's): on an open mouth the model's inner-lip contour lies on the
   lips' bodies (the opening too large); its 18 inner points move onto the photo's inner lip
   edges (:func:`~editor.engine.lip_edges.refine_inner_lips`; JAFFE against Stasm, % IOD:
   2.03 -> 1.70, open mouths 3.31 -> 2.64). ``MediaPipeDetector(refine_lips=False)`` skips it.

Limitation: the mesh model's prior damps motion it sees on a warped face. On the sample
rendered 3x with the jaw open 400 and the brows raised 250 FAPU (131 px between the eyes) the
chin follows 53 % of its 15.2 px (41 % with the tracking crop; 29-33 % at any crop size with the
same crop on both images), the brows 36-48 % of 23.6 px and a 3 px mouth-corner lift not at
all; every chin and brow vertex alike, so no choice in :data:`MESH_TO_68` recovers it. FAPs
measured from detected landmarks (video tracking, cloning) are smaller than the motion shown.

:class:`MediaPipeDetector` returns a :class:`MeshDetection`; ``track`` takes the previous frame's
mesh to crop the next frame without running the detector (video). Everything is vectorised
numpy; one face costs about 12 ms on one core (the sample, 512 x 512).

Mesh index conventions are MediaPipe's canonical face model: 33/133 the image-left eye's outer
and inner corners (the subject's right eye), 263/362 the image-right eye's, 61/291 the mouth
corners, 78/308 the inner mouth corners, 13/14 the inner lip middles, 1 the nose tip, 152 the chin.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from editor.errors import FapStudioError, NoFaceError
from editor.resources import MODELS_DIR

from .lip_edges import refine_inner_lips
from .threads import Pending

# OpenCV is imported by the functions that use it (see editor.engine.landmarks)

#: Faces whose eye centres (midpoints of the eye corners) are closer than this many pixels are
#: refused: an eye is then under 8 px wide and the iris model's crop under 20 px. Chosen by
#: measurement, not the issue's suggested 60 px: the bundled sample face has 43 px, JAFFE's
#: 256 px photos 55-64 px, and the half-size sample (22 px) must still work (robustness case 13).
MIN_INTEROCULAR_PX = 16.0
#: A face is refused as a profile when the nose tip lies outside this fraction band of the line
#: between the outer eye corners (0.5 = frontal; a quarter turn puts it near 0 or 1).
PROFILE_NOSE_BAND = (0.22, 0.78)
#: Minimum face-presence probability of the mesh model.
MIN_PRESENCE = 0.5

#: Mesh indices of each eye's lid contour, in the order of the iris model's first 16 points
#: (lower lid from the outer to the inner corner, then the upper lid back from inner to outer).
EYE_CONTOUR_IMAGE_LEFT = np.array(
    [33, 7, 163, 144, 145, 153, 154, 155, 133, 246, 161, 160, 159, 158, 157, 173])
EYE_CONTOUR_IMAGE_RIGHT = np.array(
    [263, 249, 390, 373, 374, 380, 381, 382, 362, 466, 388, 387, 386, 385, 384, 398])

#: Dense contours of the mesh (MediaPipe's canonical topology), each as an ordered index list.
CONTOURS: dict[str, tuple[int, ...]] = {
    "oval": (10, 338, 297, 332, 284, 251, 389, 356, 454, 323, 361, 288, 397, 365, 379, 378, 400,
             377, 152, 148, 176, 149, 150, 136, 172, 58, 132, 93, 234, 127, 162, 21, 54, 103, 67,
             109),
    "lips_outer_upper": (61, 185, 40, 39, 37, 0, 267, 269, 270, 409, 291),
    "lips_outer_lower": (61, 146, 91, 181, 84, 17, 314, 405, 321, 375, 291),
    "lips_inner_upper": (78, 191, 80, 81, 82, 13, 312, 311, 310, 415, 308),
    "lips_inner_lower": (78, 95, 88, 178, 87, 14, 317, 402, 318, 324, 308),
    # image-left eye = subject's right eye
    "eye_r_upper": (33, 246, 161, 160, 159, 158, 157, 173, 133),
    "eye_r_lower": (33, 7, 163, 144, 145, 153, 154, 155, 133),
    "eye_l_upper": (362, 398, 384, 385, 386, 387, 388, 466, 263),
    "eye_l_lower": (362, 382, 381, 380, 374, 373, 390, 249, 263),
    "brow_r_upper": (70, 63, 105, 66, 107),
    "brow_r_lower": (46, 53, 52, 65, 55),
    "brow_l_upper": (336, 296, 334, 293, 300),
    "brow_l_lower": (285, 295, 282, 283, 276),
}

#: The iBUG-68 points as weighted means of mesh vertices: row k lists (mesh index, weight) pairs
#: whose weighted sum is iBUG point k (weights sum to 1). Fitted on JAFFE's 213 photos and the
#: sample face against dlib's 68 points (each point a blend of two neighbours along the mesh's own
#: contour: the oval for the jaw 0-16, the upper brow edges 17-26, the lid contours 36-47, the
#: outer lip contour 48-59 and the inner lip contour 60-67; nose points from the nose's midline
#: and flank vertices), then made mirror-symmetric (row k and row MIRROR_68[k] are mirror images).
#: Mean distance to dlib's points on those photos: 1.3-2.5 % of the inter-ocular distance at the
#: eyes and nose, 2.4-3.4 % on the upper lips and mouth corners, about 5 % on the lower lips and
#: brows' inner ends, 5-6.6 % along the jaw (dlib places the contour loosely).
MESH_TO_68: tuple[tuple[tuple[int, float], ...], ...] = (
    ((127, 1.0),),  # 0
    ((93, 0.25), (234, 0.75),),  # 1
    ((93, 0.5), (132, 0.5),),  # 2
    ((58, 0.625), (132, 0.375),),  # 3
    ((58, 0.25), (172, 0.75),),  # 4
    ((136, 0.875), (150, 0.125),),  # 5
    ((149, 0.75), (150, 0.25),),  # 6
    ((148, 0.5), (176, 0.5),),  # 7
    ((152, 1.0),),  # 8
    ((377, 0.5), (400, 0.5),),  # 9
    ((378, 0.75), (379, 0.25),),  # 10
    ((365, 0.875), (379, 0.125),),  # 11
    ((288, 0.25), (397, 0.75),),  # 12
    ((288, 0.625), (361, 0.375),),  # 13
    ((323, 0.5), (361, 0.5),),  # 14
    ((323, 0.25), (454, 0.75),),  # 15
    ((356, 1.0),),  # 16
    ((70, 0.625), (156, 0.375),),  # 17
    ((63, 0.875), (105, 0.125),),  # 18
    ((66, 0.375), (105, 0.625),),  # 19
    ((66, 0.625), (107, 0.375),),  # 20
    ((55, 0.375), (107, 0.625),),  # 21
    ((285, 0.375), (336, 0.625),),  # 22
    ((296, 0.625), (336, 0.375),),  # 23
    ((296, 0.375), (334, 0.625),),  # 24
    ((293, 0.875), (334, 0.125),),  # 25
    ((300, 0.625), (383, 0.375),),  # 26
    ((6, 0.25), (168, 0.75),),  # 27
    ((6, 0.875), (164, 0.125),),  # 28
    ((1, 0.5), (6, 0.5),),  # 29
    ((1, 0.875), (168, 0.125),),  # 30
    ((19, 0.125), (98, 0.875),),  # 31
    ((102, 0.375), (164, 0.625),),  # 32
    ((2, 0.75), (164, 0.25),),  # 33
    ((164, 0.625), (331, 0.375),),  # 34
    ((19, 0.125), (327, 0.875),),  # 35
    ((33, 1.0),),  # 36
    ((159, 0.375), (160, 0.625),),  # 37
    ((157, 0.25), (158, 0.75),),  # 38
    ((133, 0.25), (155, 0.75),),  # 39
    ((145, 0.25), (153, 0.75),),  # 40
    ((144, 0.625), (163, 0.375),),  # 41
    ((362, 0.25), (382, 0.75),),  # 42
    ((384, 0.25), (385, 0.75),),  # 43
    ((386, 0.375), (387, 0.625),),  # 44
    ((263, 1.0),),  # 45
    ((373, 0.625), (390, 0.375),),  # 46
    ((374, 0.25), (380, 0.75),),  # 47
    ((61, 1.0),),  # 48
    ((39, 0.625), (40, 0.375),),  # 49
    ((37, 1.0),),  # 50
    ((0, 1.0),),  # 51
    ((267, 1.0),),  # 52
    ((269, 0.625), (270, 0.375),),  # 53
    ((291, 1.0),),  # 54
    ((321, 0.5), (405, 0.5),),  # 55
    ((314, 1.0),),  # 56
    ((17, 1.0),),  # 57
    ((84, 1.0),),  # 58
    ((91, 0.5), (181, 0.5),),  # 59
    ((78, 1.0),),  # 60
    ((81, 0.375), (82, 0.625),),  # 61
    ((13, 1.0),),  # 62
    ((311, 0.375), (312, 0.625),),  # 63
    ((308, 1.0),),  # 64
    ((317, 0.75), (402, 0.25),),  # 65
    ((14, 1.0),),  # 66
    ((87, 0.75), (178, 0.25),),  # 67
)


#: MPEG-4 feature points taken straight from mesh vertices (mean of the listed indices), where
#: the mesh has the point itself rather than a blend of neighbours. Conventions as
#: :data:`editor.engine.landmarks.FDP_FROM_68` (face's own left = image right; 3.7/3.8/3.11/3.12
#: the left/right corners of the left/right eye). The iris centres 3.5/3.6 come from the iris
#: model; every other feature point of FDP_FROM_68 (jaw 2.11-2.14, nostrils 9.1/9.2/9.4/9.5,
#: bridge 9.12) comes from the 68 points. 2.6-2.9 (inner-lip mid-points) are new with the mesh.
FDP_FROM_MESH: dict[str, tuple[int, ...]] = {
    "2.1": (152,), "2.10": (17, 152, 152),  # chin bottom; chin boss a third of the way up
    "2.2": (13,), "2.3": (14,), "2.4": (308,), "2.5": (78,),  # inner lip middles and corners
    "2.6": (311,), "2.7": (81,), "2.8": (402,), "2.9": (178,),  # inner lip mid-points
    "3.1": (386,), "3.2": (159,), "3.3": (374,), "3.4": (145,),  # lid middles (top, bottom)
    "3.7": (263,), "3.8": (133,), "3.11": (362,), "3.12": (33,),  # eye corners
    "4.1": (336,), "4.2": (107,), "4.3": (334,), "4.4": (105,), "4.5": (300,), "4.6": (70,),
    "8.1": (0,), "8.2": (17,), "8.3": (291,), "8.4": (61,), "8.9": (37,), "8.10": (267,),
    "9.3": (1,), "9.15": (2,),  # nose tip, nose base middle
}


def _weights_68() -> np.ndarray:
    w = np.zeros((68, 468), np.float32)
    for k, row in enumerate(MESH_TO_68):
        for v, wt in row:
            w[k, v] = wt
    return w


_W68 = _weights_68()


def points68_from_mesh(mesh: np.ndarray) -> np.ndarray:
    """The 68 iBUG-equivalent points (68, 2) float32 of a (468, 2) mesh (:data:`MESH_TO_68`)."""
    return (_W68 @ np.asarray(mesh, np.float32).reshape(468, 2)).astype(np.float32)


_DET_SIZE = 128
_MESH_SIZE = 192
_IRIS_SIZE = 64


@dataclass(frozen=True)
class MeshDetection:
    """One face found by :class:`MediaPipeDetector` (image pixels, x right, y down).

    ``mesh`` (468, 2) float32; ``mesh_z`` (468,) relative depth in the same pixel scale (smaller
    is nearer the camera); ``box`` x0, y0, x1, y1 (the detection box, or the mesh's bounds when
    tracking); ``iris_image_left`` / ``iris_image_right`` (cx, cy, r) of the eye on the image's
    left (subject's right) and right; ``confidence`` the mesh model's face-presence probability.
    """

    mesh: np.ndarray
    mesh_z: np.ndarray
    box: np.ndarray
    iris_image_left: tuple[float, float, float]
    iris_image_right: tuple[float, float, float]
    confidence: float


def _anchors() -> np.ndarray:
    """BlazeFace short-range anchor centres (896, 2) in [0, 1] (fixed size 1: no w/h)."""
    out = []
    for stride, per_cell in ((8, 2), (16, 6)):
        n = _DET_SIZE // stride
        yy, xx = np.mgrid[0:n, 0:n].astype(np.float32)
        c = np.stack([(xx + 0.5) / n, (yy + 0.5) / n], -1).reshape(-1, 1, 2)
        out.append(np.repeat(c, per_cell, axis=1).reshape(-1, 2))
    return np.concatenate(out)


_ANCHORS = _anchors()


def _read_net(name: str) -> Any:
    import cv2

    path = MODELS_DIR / name
    if not path.is_file():
        raise FapStudioError(f"face model missing: {path} (reinstall FAP Studio)")
    # OpenCV 5's new DNN engine reports only one of a TFLite model's outputs: use the classic one.
    if hasattr(cv2.dnn, "ENGINE_CLASSIC"):
        net = cv2.dnn.readNetFromTFLite(str(path), engine=cv2.dnn.ENGINE_CLASSIC)
    else:  # pragma: no cover - OpenCV 4.x
        net = cv2.dnn.readNetFromTFLite(str(path))
    net.setPreferableBackend(cv2.dnn.DNN_BACKEND_OPENCV)
    net.setPreferableTarget(cv2.dnn.DNN_TARGET_CPU)
    return net


@lru_cache(maxsize=1)
def _nets() -> tuple[Any, Any, Any]:
    return (_read_net("face_detection_short_range.tflite"), _read_net("face_landmark.tflite"),
            _read_net("iris_landmark.tflite"))


def _run(net: Any, blob: np.ndarray, outputs: list[str]) -> list[np.ndarray]:
    net.setInput(blob)
    return [np.asarray(o) for o in net.forward(outputs)]


def _crop_matrix(centre: np.ndarray, size: float, angle: float, out: int) -> np.ndarray:
    """Affine 2x3 matrix mapping image pixels to an ``out`` x ``out`` crop of the square of side
    ``size`` centred at ``centre`` whose x axis runs along ``angle`` (radians, image coords).

    Pixel centres are at integer coordinates (OpenCV's convention): the square's corners map to
    the crop's outer pixel edges (-0.5), as MediaPipe's image-to-tensor step does; the models'
    outputs are in edge coordinates (0 = the crop's left edge), see :func:`_invert`."""
    import cv2

    ex = np.array([np.cos(angle), np.sin(angle)]) * size / 2
    ey = np.array([-np.sin(angle), np.cos(angle)]) * size / 2
    src = np.array([centre - ex - ey, centre + ex - ey, centre - ex + ey], np.float32)
    dst = np.array([[-0.5, -0.5], [out - 0.5, -0.5], [-0.5, out - 0.5]], np.float32)
    return np.asarray(cv2.getAffineTransform(src, dst), np.float64)


def _invert(m: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Model outputs (crop pixels, edge coordinates) -> image pixels (centre coordinates)."""
    import cv2

    inv = cv2.invertAffineTransform(m)
    return (pts - 0.5) @ inv[:, :2].T + inv[:, 2]


def nose_position(mesh: np.ndarray) -> float:
    """Where the nose tip (1) projects on the line from the image-left outer eye corner (33,
    0) to the other (263, 1): about 0.5 for a frontal face, towards 0 or 1 as it turns."""
    m = np.asarray(mesh, np.float64)
    u = m[263] - m[33]
    return float((m[1] - m[33]) @ u / (u @ u))


def _sigmoid(x: float) -> float:
    return float(1.0 / (1.0 + np.exp(-np.clip(x, -80.0, 80.0))))


def _area_down(img: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """``img`` resized down to ``size`` (w, h) by pixel-area averaging. More than 16 x down (a
    24 MP photo to the detector's 128 px), it first averages ``k x k`` blocks, ``k`` dividing
    both sides (OpenCV's integer-factor path, ~3 x faster than its general one on the whole
    photo), then resizes that; otherwise one resize, as before."""
    import cv2

    h, w = img.shape[:2]
    most = min(w // size[0], h // size[1]) // 8
    k = next((k for k in range(most, 1, -1) if w % k == 0 and h % k == 0), 1)
    if k >= 2:
        img = _block_means(img, k)
    return cv2.resize(img, size, interpolation=cv2.INTER_AREA)


def _block_means(img: np.ndarray, k: int) -> np.ndarray:
    """``cv2.resize(img, (w // k, h // k), interpolation=cv2.INTER_AREA)`` for ``k`` dividing
    both sides, its two halves of rows on two threads (OpenCV releases the GIL; with an
    integer factor each output row is the means of its own ``k`` input rows: the same values;
    ~50 ms on a 24 MP photo, the largest step of the detection after the decode)."""
    import cv2

    h, w = img.shape[:2]
    out = np.empty((h // k, w // k) + img.shape[2:], img.dtype)
    mid = (h // k) // 2

    def rows(r0: int, r1: int) -> None:
        cv2.resize(img[r0 * k:r1 * k], (w // k, r1 - r0), out[r0:r1],
                   interpolation=cv2.INTER_AREA)

    other = Pending(rows, mid, h // k)
    rows(0, mid)
    other.result()
    return out


class MediaPipeDetector:
    """The default landmark detector: BlazeFace, the 468-point face mesh and the iris model.

    ``detect`` satisfies :class:`editor.engine.landmarks.LandmarkDetector` (68 iBUG-equivalent
    points and the box); ``run`` returns the whole :class:`MeshDetection`; ``track`` crops from a
    previous mesh instead of detecting. Thread-safe (one lock around the shared networks).

    ``refine_lips`` (default True): on an open mouth the mesh's inner-lip points are moved onto
    the photo's inner lip edges (:func:`~editor.engine.lip_edges.refine_inner_lips`; the
    model's own contour lies on the lips' bodies, the opening too large). False keeps the
    model's points as they are.
    """

    name = "mediapipe-468"

    def __init__(self, refine_lips: bool = True) -> None:
        self._lock = threading.Lock()
        self.refine_lips = refine_lips

    # ------------------------------------------------------------------ stages
    def _candidates(self, rgb: np.ndarray, x0: int, y0: int,
                    side: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Detections in the square window (x0, y0, side) of the image (zero-padded where it
        leaves the image): boxes (n, 4), keypoints (n, 6, 2) in image pixels, scores (n,)."""
        h, w = rgb.shape[:2]
        win = rgb[max(0, y0):min(h, y0 + side), max(0, x0):min(w, x0 + side)]
        scale = _DET_SIZE / side
        nw, nh = max(1, round(win.shape[1] * scale)), max(1, round(win.shape[0] * scale))
        small = _area_down(win, (nw, nh))
        canvas = np.zeros((_DET_SIZE, _DET_SIZE, 3), np.float32)
        ox = round((max(0, x0) - x0) * scale)
        oy = round((max(0, y0) - y0) * scale)
        canvas[oy:oy + nh, ox:ox + nw] = small.astype(np.float32) / 127.5 - 1.0
        reg, cls = _run(_nets()[0], canvas.transpose(2, 0, 1)[None].copy(),
                        ["regressors", "classificators"])
        reg, logit = reg.reshape(-1, 16), cls.reshape(-1)
        keep = np.flatnonzero(logit > 0.0)
        raw = reg[keep] / _DET_SIZE
        anc = _ANCHORS[keep]
        cx, cy = raw[:, 0] + anc[:, 0], raw[:, 1] + anc[:, 1]
        bw, bh = raw[:, 2], raw[:, 3]
        boxes = np.stack([cx - bw / 2, cy - bh / 2, cx + bw / 2, cy + bh / 2], 1)
        kps = raw[:, 4:16].reshape(-1, 6, 2) + anc[:, None, :]
        # normalised window coordinates -> image pixels (edge coordinates -> pixel centres)
        origin = np.array([x0, y0], np.float64) - 0.5
        boxes = boxes * side + np.tile(origin, 2)
        kps = kps * side + origin
        score = 1.0 / (1.0 + np.exp(-np.clip(logit[keep], -80, 80)))
        return boxes.astype(np.float64), kps.astype(np.float64), score.astype(np.float64)

    def _detect_face(self, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Box (x0, y0, x1, y1) and keypoints (6, 2) of the largest face, image pixels.

        The short-range model wants faces of at least ~1/8 of its input: the whole image
        (letterboxed) comes first; when it finds nothing, overlapping square windows of half and
        then a quarter of the image's longer side (half a window apart) are searched."""
        h, w = rgb.shape[:2]
        side = max(h, w)
        found = [self._candidates(rgb, (w - side) // 2, (h - side) // 2, side)]
        for frac in (2, 4):
            if found[-1][2].size or min(h, w) < 2 * _DET_SIZE // frac:
                break
            win = max(h, w) // frac
            step = max(1, win // 2)
            xs = list(range(0, max(1, w - win + 1), step)) or [0]
            ys = list(range(0, max(1, h - win + 1), step)) or [0]
            if xs[-1] + win < w:
                xs.append(w - win)
            if ys[-1] + win < h:
                ys.append(h - win)
            parts = [self._candidates(rgb, x, y, win) for y in ys for x in xs]
            found.append((np.concatenate([p[0] for p in parts]),
                          np.concatenate([p[1] for p in parts]),
                          np.concatenate([p[2] for p in parts])))
        boxes, kps, score = found[-1]
        if score.size == 0:
            raise NoFaceError("no face found in the image")
        bw, bh = boxes[:, 2] - boxes[:, 0], boxes[:, 3] - boxes[:, 1]
        # the largest face (within 25 % of the largest area: the surest), its overlapping
        # detections averaged by score (MediaPipe's blending)
        area = bw * bh * (score > 0.5 * score.max())
        best = int(np.argmax(np.where(area >= 0.75 * area.max(), score, -1.0)))
        ix0 = np.maximum(boxes[:, 0], boxes[best, 0])
        iy0 = np.maximum(boxes[:, 1], boxes[best, 1])
        ix1 = np.minimum(boxes[:, 2], boxes[best, 2])
        iy1 = np.minimum(boxes[:, 3], boxes[best, 3])
        inter = np.clip(ix1 - ix0, 0, None) * np.clip(iy1 - iy0, 0, None)
        iou = inter / (bw * bh + bw[best] * bh[best] - inter)
        wgt = score * (iou > 0.3)
        box = (boxes * wgt[:, None]).sum(0) / wgt.sum()
        kp = (kps * wgt[:, None, None]).sum(0) / wgt.sum()
        return box, kp

    def _mesh(self, rgb: np.ndarray, centre: np.ndarray, size: float,
              angle: float) -> tuple[np.ndarray, np.ndarray, float]:
        import cv2

        m = _crop_matrix(centre, size, angle, _MESH_SIZE)
        crop = cv2.warpAffine(rgb, m, (_MESH_SIZE, _MESH_SIZE), flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_REPLICATE)
        blob = (crop.astype(np.float32) / 255.0).transpose(2, 0, 1)[None].copy()
        pts, flag = _run(_nets()[1], blob, ["conv2d_21", "conv2d_31"])
        p = pts.reshape(468, 3).astype(np.float64)
        xy = _invert(m, p[:, :2])
        z = p[:, 2] * size / _MESH_SIZE
        return xy, z, _sigmoid(float(flag.reshape(-1)[0]))

    def _iris(self, rgb: np.ndarray, outer: np.ndarray, inner: np.ndarray,
              mirror: bool) -> tuple[np.ndarray, tuple[float, float, float]]:
        """Refined lid contour (16, 2) and iris (cx, cy, r) of one eye from its two corners."""
        import cv2

        # the model's eye runs outer -> inner corner left to right when not mirrored
        a, b = (inner, outer) if mirror else (outer, inner)
        centre = (a + b) / 2
        d = b - a
        size = float(np.hypot(*d)) * 2.3
        m = _crop_matrix(centre, size, float(np.arctan2(d[1], d[0])), _IRIS_SIZE)
        crop = cv2.warpAffine(rgb, m, (_IRIS_SIZE, _IRIS_SIZE), flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_REPLICATE)
        if mirror:
            crop = crop[:, ::-1]
        blob = (crop.astype(np.float32) / 255.0).transpose(2, 0, 1)[None].copy()
        contour, iris = _run(_nets()[2], blob,
                             ["output_eyes_contours_and_brows", "output_iris"])
        c = contour.reshape(71, 3)[:16, :2].astype(np.float64)
        ir = iris.reshape(5, 3)[:, :2].astype(np.float64)
        if mirror:
            c[:, 0] = _IRIS_SIZE - c[:, 0]
            ir[:, 0] = _IRIS_SIZE - ir[:, 0]
        c, ir = _invert(m, c), _invert(m, ir)
        r = float(np.linalg.norm(ir[1:] - ir[0], axis=1).mean())
        return c, (float(ir[0, 0]), float(ir[0, 1]), r)

    # ------------------------------------------------------------------ public
    def detect(self, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The 68 iBUG-equivalent points and the face box (the LandmarkDetector interface)."""
        det = self.run(rgb)
        return points68_from_mesh(det.mesh), det.box

    def run(self, rgb: np.ndarray) -> MeshDetection:
        """Detect the largest face and return its mesh, irises and confidence."""
        rgb = np.ascontiguousarray(rgb[..., :3])
        with self._lock:
            box, kp = self._detect_face(rgb)
            # keypoint 0 is the image-left eye, 1 the image-right eye
            d = kp[1] - kp[0]
            angle = float(np.arctan2(d[1], d[0]))
            centre = np.array([(box[0] + box[2]) / 2, (box[1] + box[3]) / 2])
            size = 1.5 * float(max(box[2] - box[0], box[3] - box[1]))
            return self._finish(rgb, centre, size, angle, box)

    def track(self, rgb: np.ndarray, previous: np.ndarray | None) -> MeshDetection:
        """Like :meth:`run`, but the crop comes from ``previous`` (the last frame's 468 points)
        when given; a lost face (low presence) falls back to detection."""
        if previous is None:
            return self.run(rgb)
        rgb = np.ascontiguousarray(rgb[..., :3])
        prev = np.asarray(previous, np.float64).reshape(468, 2)
        d = prev[263] - prev[33]
        angle = float(np.arctan2(d[1], d[0]))
        # the bounds of the previous mesh in its own rotated frame
        rot = np.array([[np.cos(angle), np.sin(angle)], [-np.sin(angle), np.cos(angle)]])
        q = prev @ rot.T
        lo, hi = q.min(0), q.max(0)
        centre = ((lo + hi) / 2) @ rot
        size = 1.5 * float((hi - lo).max())
        box = np.concatenate([prev.min(0), prev.max(0)])
        try:
            with self._lock:
                return self._finish(rgb, centre, size, angle, box, tracking=True)
        except NoFaceError:
            return self.run(rgb)

    def _finish(self, rgb: np.ndarray, centre: np.ndarray, size: float, angle: float,
                box: np.ndarray, tracking: bool = False) -> MeshDetection:
        mesh, z, presence = self._mesh(rgb, centre, size, angle)
        if presence < MIN_PRESENCE:
            raise NoFaceError(f"no face found in the image (face-mesh confidence {presence:.2f})")
        if not tracking:
            # a second pass on the crop the mesh itself implies: the detector's box is coarse
            d = mesh[263] - mesh[33]
            angle = float(np.arctan2(d[1], d[0]))
            rot = np.array([[np.cos(angle), np.sin(angle)], [-np.sin(angle), np.cos(angle)]])
            q = mesh @ rot.T
            lo, hi = q.min(0), q.max(0)
            mesh2, z2, p2 = self._mesh(rgb, ((lo + hi) / 2) @ rot, 1.5 * float((hi - lo).max()),
                                       angle)
            if p2 >= MIN_PRESENCE:
                mesh, z, presence = mesh2, z2, p2
        eye_r = mesh[EYE_CONTOUR_IMAGE_LEFT[[0, 8]]]
        eye_l = mesh[EYE_CONTOUR_IMAGE_RIGHT[[0, 8]]]
        iod = float(np.linalg.norm(eye_l.mean(0) - eye_r.mean(0)))
        if iod < MIN_INTEROCULAR_PX:
            raise NoFaceError(
                f"the face is too small for landmarks ({iod:.0f} px between the eyes, at least "
                f"{MIN_INTEROCULAR_PX:.0f} needed): use a larger photo of the face")
        if not PROFILE_NOSE_BAND[0] <= nose_position(mesh) <= PROFILE_NOSE_BAND[1]:
            raise NoFaceError("the face is turned too far to the side (a profile): FAP Studio "
                              "needs a frontal face")
        mesh = mesh.copy()
        lid_r, iris_r = self._iris(rgb, eye_r[0], eye_r[1], mirror=False)
        lid_l, iris_l = self._iris(rgb, eye_l[0], eye_l[1], mirror=True)
        # the iris model's eye corners replace the mesh's; its lids do not (JAFFE against Stasm,
        # % IOD: its corners 2.4 against the mesh's 3.3, its lids 1.4 / 2.0 against 1.3 / 1.3)
        mesh[EYE_CONTOUR_IMAGE_LEFT[[0, 8]]] = lid_r[[0, 8]]
        mesh[EYE_CONTOUR_IMAGE_RIGHT[[0, 8]]] = lid_l[[0, 8]]
        if self.refine_lips:
            mesh = refine_inner_lips(rgb, mesh)
        return MeshDetection(mesh.astype(np.float32), z.astype(np.float32),
                             np.asarray(box, np.float32), iris_r, iris_l, presence)
