"""The photo's open mouth sealed when the lips close (issue 21). No Qt.

A photo whose lips are apart (a smile showing teeth: most portraits) has pixels of its
opening just outside the mesh's inner-lip polygon: the dark corners of the cavity and the
shadow under the upper lip, which the polygon's straight edges between its inner-lip points
leave on the lips' triangles. When a target closes the lips (the neutralised face, anger,
sadness, the p/b/m visemes), the warp carries them onto the closed lips: dark wedges at the
mouth corners and a dark band along the lip line, which read as the photo's smile (a smirk
under every preset). A closed mouth, in turn, shows a dark contact line where its lips meet,
which no pixel of an open photo provides.

* **Once per face** (:func:`seal_plan`): the opening's pixels on the lips are found on the
  photo (darker than :data:`DARK` of the lips' median luminance, or teeth: brighter than
  :data:`BRIGHT` of it and paler; within :data:`REACH` of the inner-lip polygon, outside it,
  and joined to those within the lips up to twice as far) and filled: the colour from the
  lips around them (``cv2.inpaint``), the grain from the photo's own high-pass mirrored
  across the nearest lip pixel (a flat fill reads as paint on a grainy photo). Kept: the
  difference fill - photo over the mouth's box.
* **Per frame** (:func:`apply_lip_seal`): the share ``s`` by which the target closes the photo's
  opening (1 - area of the deformed inner polygon / the photo's, clipped to [0, 1]): 0 at the
  photo's own expression (the photo exactly) and wherever the lips open as far or further,
  1 on a closed mouth. The difference is carried to the frame by the warp's own backward map
  and added times ``s``; along the lips where they meet (their gap under :data:`SHUT` of the
  inter-ocular distance) a soft contact line darkens the lips by up to :data:`LINE_DEPTH`
  (on a colour photo deeper, towards :data:`LINE_FLOOR` of the lips' light;
  :func:`apply_contact_line`, after the mouth layer).
* **The corners.** A smile also leaves a dark notch beside each mouth corner (the commissure
  fold; a grin's cavity corner beyond the lips' corner point), which stays where the photo
  has it when the corner goes back (a detached dark tick beside a neutral mouth). Where the
  photo's corner lies more than :data:`CORNER_MOVE` from its neutral place, the pixels within
  :data:`CORNER_R` of it, lateral to it and outside the lips, darker than :data:`NOTCH_DARK` of
  the skin around, are filled the same way (on the photo with its opening already filled, so
  that no pixel takes two differences); per frame each corner's fill comes with that corner's
  share of the way from the photo's place to the neutral one.

On a soft photo (a large face from an upscaled or defocused picture: its edge ramp
``layers.LayerPlan.soft`` above a pixel) the masks are grown by half the ramp (the blurred rims
of teeth and cavity pass neither threshold) and the fills' differences feathered over it.

A photo with closed lips and its corners at their neutral places (a neutral photo) has no
plan: nothing changes. Runs after the lid skin, before the mouth and eye layers.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field
from functools import cached_property, lru_cache
from typing import TYPE_CHECKING

import cv2
import numpy as np

from .fitting import channel_median, clamp, clip, is_grey, luminance, median, median_binned
from .gaze import spread3, zero_alpha
from .layers import _blur_wide, _rebox, _union, layer_plan
from .warp import WarpResult, box_maps

if TYPE_CHECKING:
    from .face import Face
    from .mesh import StandardMesh

#: an opening's pixel on the lips is darker than this share of the lips' median luminance
DARK = 0.8
#: ... or brighter than this share and paler than 0.6 of the lips' saturation (teeth)
BRIGHT = 1.2
#: how far outside the inner-lip polygon such pixels are looked for (inter-ocular distances)
REACH = 0.08
#: the inner lips count as shut where their gap is under this share of the IOD (fading in from
#: twice it)
SHUT = 0.012
#: darkening of the contact line at its middle, relative to the lips, and its half-width
#: (Gaussian sigma, IOD). Ten JAFFE neutral photos: the lip line 0.53-0.77 darker than the
#: lips 0.08 IOD either side (median 0.71), its dip 7-10 % IOD wide at half depth (the lips'
#: own shading towards the line included); the fill keeps part of the photo's darker lip edge.
#: The depth measured as the line's darkest row over the lips 0.08 IOD above and below it
#: (columns within 0.1 IOD of the middle): the neutral photos 0.27 (0.21-0.47); eleven JAFFE
#: smiles neutralised 0.45 at a depth of 0.35 (a soft grey seam: blind raters called the
#: sample's closed mouth "smeared"), 0.27 at 0.5 (0.17-0.52)
LINE_DEPTH, LINE_SIGMA = 0.5, 0.018
#: on a colour photo the line darkens the lips by LINE_DEPTH x the tint (0.48 of their
#: luminance) or, where that leaves a pixel lighter than LINE_FLOOR of the lips' median
#: luminance on the photo, towards that floor (the line's middle: JAFFE's neutral photos'
#: median), by at most LINE_MAX of the pixel. By the measure above (the darkest row over the
#: lips 0.08 IOD above and below, columns within 0.1 IOD of the middle) the sample's
#: neutralised pale lips kept their line at 0.62 (sadness 0.60, anger 0.55), lighter than
#: any of JAFFE's ten neutral photos (0.21-0.47): a soft seam, "smeared"; now 0.43 (0.42,
#: 0.37). The line is under 2 px wide there: its darkest row stays lighter than the floor.
#: A grey photo's line (the tint's 1.5: 0.75) keeps its fixed depth
LINE_FLOOR, LINE_MAX = 0.27, 0.75
#: the floor's deepening fades in from this far from each inner-lip corner (IOD) over half as much
FLOOR_CORNER = 0.15
#: a mouth corner the photo's expression moved by more than this (IOD) from its neutral place
#: has its notch looked for: within CORNER_R of it, on its lateral side, outside the lips,
#: darker than NOTCH_DARK of the skin around it
CORNER_MOVE, CORNER_R, NOTCH_DARK = 0.03, 0.12, 0.85
#: the lower lip's light where the opening's fill covers it. A closed lower lip faces up
#: into the light and shows a bright band over its upper middle; the fill (the colour of the
#: lips around, inpainted) left it one flat dark tone. Down the lower lip's middle, contact
#: line -> outer edge (0.05 ... 0.95 of its height), over the cheek's luminance: JAFFE's neutral
#: photos 0.13 0.27 0.41 0.49 0.46 0.42 0.33 0.29 0.26 0.28; their 21 open smiles neutralised
#: 0.13 0.24 0.31 0.32 0.31 0.32 0.33 0.34 0.31 0.35. The band is added to the fill: its peak
#: (HIGHLIGHT_AT of the lip's height down from the inner lip) lifts the fill towards the skin
#: around the mouth by HIGHLIGHT of their difference, a Gaussian HIGHLIGHT_W tall (in the
#: lip's height), fading in over HIGHLIGHT_FADE of the width from each corner
HIGHLIGHT, HIGHLIGHT_AT, HIGHLIGHT_W, HIGHLIGHT_FADE = 0.5, 0.38, 0.13, 0.3
#: cv2.inpaint's neighbourhood, px (its cost grows with its square; the grain comes from the
#: mirrored high-pass, not from a wider inpainting)
INPAINT_R = 3
#: below this share (of the photo's opening closed, of a corner's way back) nothing is drawn
#: (at most 2 % of a fill's difference: a few grey levels)
_MIN_SHARE = 0.02
#: a contact line that can darken no pixel by this many grey levels (on white: its bound,
#: :func:`_contact_line`) is not drawn: it changes a pixel by at most 2 levels
_LINE_SKIP = 2.5


@dataclass(eq=False)
class _Patch:
    """A fill of the photo: ``diff`` (h, w, 4) float32 fill - photo (4th channel 0) over the
    box at ``org`` (its top-left corner on the photo)."""

    diff: np.ndarray
    org: tuple[int, int]
    #: the lips' median luminance around the opening on the photo (0: not measured)
    light: float = 0.0

    @cached_property
    def support(self) -> tuple[int, int, int, int] | None:
        """The box ``(x0, y0, x1, y1)`` of ``diff``'s nonzero pixels (its own coordinates;
        None: none), for :func:`add_carried`."""
        return _support(self.diff)


@dataclass(eq=False)
class _Corner:
    """A mouth corner the photo's expression moved: the dark notch beside it, filled."""

    vertex: int  # the outer lip corner's vertex
    p0: np.ndarray  # (2,) its place on the photo
    disp: np.ndarray  # (2,) from there to the neutral mesh's corner
    patch: _Patch

    @cached_property
    def p0_disp(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """:attr:`p0` and :attr:`disp` as Python floats (read every frame)."""
        (px, py), (wx, wy) = (np.asarray(a, np.float64).tolist() for a in (self.p0, self.disp))
        return (px, py), (wx, wy)


@dataclass(eq=False)
class SealPlan:
    """What :func:`apply_lip_seal` needs of one face (see the module docstring)."""

    opening: _Patch | None  # the opening's pixels on the lips (None: the lips are closed)
    corners: list[_Corner]  # the corners' notches (none on a neutral photo)
    area0: float  # the photo's inner-lip polygon area, px^2 (0 without ``opening``)
    upper: np.ndarray  # (n,) vertex indices of the upper inner lip, corner to corner
    lower: np.ndarray  # (n,) the lower inner lip, the same corners
    outer: np.ndarray  # vertex indices of the outer lip contour
    iod: float
    tint: np.ndarray  # (3,) float32 per-channel weights of the contact line's darkening
    hole: np.ndarray  # (n,) the mouth opening's vertex indices, in order
    corner_idx: np.ndarray  # (2,) the outer lip corners' vertex indices
    corner_p0: np.ndarray  # (2, 2) where the photo has them
    #: per corner, (x, y) from there to the neutral mesh's (0, 0: closer than CORNER_MOVE,
    #: nothing to go back); Python floats (:func:`back_share` reads two of them a frame)
    corner_way: list[list[float]]
    #: the grey level the contact line darkens the lips towards (0: the line's fixed depth
    #: alone; see :data:`LINE_FLOOR`)
    line_floor: float = 0.0
    #: the most the floor multiplies the line's darkening by: up to a luminance depth of
    #: :data:`LINE_MAX`; 1 without a floor (a grey photo)
    floor_gain: float = 1.0
    #: the sealed photo over the box of every fill, ``(box, pixels)`` (:func:`sealed_box`;
    #: made on its first call)
    region: tuple[tuple[int, int, int, int], np.ndarray] | None = field(
        default=None, init=False, repr=False)

    @property
    def patches(self) -> list[_Patch]:
        """Every fill: the opening's, then the corners'."""
        return ([self.opening] if self.opening is not None else []) + [c.patch
                                                                       for c in self.corners]


_PLANS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


_MISSING = object()  # (a face whose plan is None is cached too)


def seal_plan(face: Face) -> SealPlan | None:
    """The face's :class:`SealPlan` (cached for its lifetime; None: its lips are closed)."""
    p = _PLANS.get(face, _MISSING)
    if p is not _MISSING:
        return p
    p = _build(face)
    _PLANS[face] = p
    return p


def sealed_photo(face: Face) -> np.ndarray:
    """The photo with every fill of its plan added at full share (the photo itself when it
    has no plan). Read-only."""
    if seal_plan(face) is None:
        return face.image
    H, W = face.image.shape[:2]
    out = sealed_box(face, (0, 0, W, H))
    out.setflags(write=False)
    return out


def sealed_box(face: Face, box: tuple[int, int, int, int]) -> np.ndarray:
    """``sealed_photo(face)[y0:y1, x0:x1]`` for ``box`` ``(x0, y0, x1, y1)`` inside the
    photo, without copying the whole photo: what the photo's own folds are measured on
    (:mod:`creases`: the cavity's dark corners are no skin fold to lift). A view of the
    photo where no fill meets the box. Read only."""
    x0, y0, x1, y1 = box
    p = seal_plan(face)
    out = face.image[y0:y1, x0:x1]
    if p is None:
        return out
    if not any(_meets(q, box) for q in p.patches):
        return out
    # the fills are added once, over their own boxes (the plans measure several overlapping
    # boxes around the mouth): the box is the photo with that region's pixels where they
    # meet, the same values (each pixel's sum depends on that pixel alone)
    if p.region is None:
        H, W = face.image.shape[:2]
        u = (max(min(q.org[0] for q in p.patches), 0), max(min(q.org[1] for q in p.patches), 0),
             min(max(q.org[0] + q.diff.shape[1] for q in p.patches), W),
             min(max(q.org[1] + q.diff.shape[0] for q in p.patches), H))
        p.region = (u, _overlaid(face.image[u[1]:u[3], u[0]:u[2]], u, p.patches))
    (u0, v0, u1, v1), reg = p.region
    a0, b0, a1, b1 = max(x0, u0), max(y0, v0), min(x1, u1), min(y1, v1)
    out = out.copy()
    out[b0 - y0:b1 - y0, a0 - x0:a1 - x0] = reg[b0 - v0:b1 - v0, a0 - u0:a1 - u0]
    return out


def _meets(q: _Patch, box: tuple[int, int, int, int]) -> bool:
    """Whether the fill ``q`` overlaps ``box`` (x0, y0, x1, y1)."""
    ox, oy = q.org
    h, w = q.diff.shape[:2]
    return max(box[0], ox) < min(box[2], ox + w) and max(box[1], oy) < min(box[3], oy + h)


def _overlaid(img: np.ndarray, box: tuple[int, int, int, int], patches: list[_Patch]
              ) -> np.ndarray:
    """``img`` (the photo's ``box``) with the parts of ``patches`` that meet the box added,
    in order (a copy; ``img`` itself when none meets it)."""
    x0, y0, x1, y1 = box
    out = img
    for q in patches:
        ox, oy = q.org
        h, w = q.diff.shape[:2]
        a0, b0, a1, b1 = max(x0, ox), max(y0, oy), min(x1, ox + w), min(y1, oy + h)
        if a1 <= a0 or b1 <= b0:
            continue
        if out is img:
            out = img.copy()
        _add(out, _Patch(q.diff[b0 - oy:b1 - oy, a0 - ox:a1 - ox], (a0 - x0, b0 - y0)))
    return out


def _add(img: np.ndarray, q: _Patch) -> None:
    """``img`` (uint8, in place) plus a patch's difference, rounded."""
    x0, y0 = q.org
    h, w = q.diff.shape[:2]
    box = img[y0:y0 + h, x0:x0 + w]
    # (the difference's colour as a contiguous copy: numpy's arithmetic on the strided
    # channel view costs several times more)
    v: np.ndarray = box + np.asarray(cv2.cvtColor(q.diff, cv2.COLOR_RGBA2RGB), np.float32)
    v += np.float32(0.5)
    box[:] = np.clip(v, 0, 255, out=v).astype(np.uint8)


def _area(poly: np.ndarray) -> float:
    """Area of a closed polygon (n, 2), shoelace (a few us: this runs every frame)."""
    x, y = poly[:, 0], poly[:, 1]
    a = float(x[:-1] @ y[1:]) - float(x[1:] @ y[:-1]) + float(x[-1] * y[0] - x[0] * y[-1])
    return 0.5 * abs(a)


def _fill(img: np.ndarray, mask: np.ndarray, radius: int,
          src: np.ndarray | None = None) -> np.ndarray:
    """``img`` with ``mask`` filled: inpainted colour plus the photo's high-pass (sigma 1 px)
    mirrored across the nearest unmasked pixel (float32); ``src`` (nonzero: the pixels the
    grain may come from; default, or when none of them is unmasked: every unmasked one): the
    grain mirrored across the nearest of them and bounded by their own grain level."""
    filled = cv2.inpaint(img, mask, radius, cv2.INPAINT_TELEA).astype(np.float32)
    f = img.astype(np.float32)
    hp = f - cv2.GaussianBlur(f, (0, 0), 1.0)
    free = mask == 0
    if src is not None and ((src > 0) & free).any():
        free &= src > 0
    _, lab = cv2.distanceTransformWithLabels((~free).view(np.uint8), cv2.DIST_L2, 5,
                                             labelType=cv2.DIST_LABEL_PIXEL)
    zy, zx = np.nonzero(free)  # the labels number the source pixels in scan order
    ny = np.zeros(len(zy) + 1, np.float32)
    nx = np.zeros(len(zx) + 1, np.float32)
    ny[1:], nx[1:] = zy, zx
    # the grain only over the mask's bounding box (each pixel's sample is its own: the same
    # values there; elsewhere the photo is kept)
    x0, y0, bw, bh = cv2.boundingRect(mask)
    if bw == 0:
        return f
    x1, y1 = x0 + bw, y0 + bh
    # (np.mgrid's values, broadcast)
    yy = np.arange(y0, y1, dtype=np.float32)[:, None]
    xx = np.arange(x0, x1, dtype=np.float32)[None, :]
    lb = lab[y0:y1, x0:x1]
    grain: np.ndarray = np.asarray(cv2.remap(hp, 2 * nx[lb] - xx, 2 * ny[lb] - yy,
                                             cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT),
                                   np.float32)
    # within the sources' grain (a mirror landing on an edge would print it as a speckle)
    lim = 2.0 * _unmasked_median_abs(hp, (~free).view(np.uint8)) / 0.6745 + 1.0
    np.clip(grain, -lim, lim, out=grain)
    grain += filled[y0:y1, x0:x1]
    np.copyto(f[y0:y1, x0:x1], grain, where=spread3(mask[y0:y1, x0:x1]) > 0)
    return f


def _unmasked_median_abs(hp: np.ndarray, mask: np.ndarray) -> float:
    """``median(np.abs(hp[mask == 0]))`` of a finite float32 (h, w, 3) ``hp``, the same value:
    the masked pixels set to +inf in a copy, which sorts them after every value the median
    reads (a whole-array selection costs less than gathering the unmasked pixels first): the
    middle order statistic from one single-kth ``np.partition`` (a third of a full sort's time
    on a mouth's box), the lower one of an even count the largest value partitioned below it.
    From :data:`_BINNED_MIN` values on, the unmasked pixels gathered and their median taken
    by :func:`median_binned` (the same order statistics: ~0.11 instead of 0.17 ms on a 1080p
    face's mouth box)."""
    free = int(np.count_nonzero(mask == 0))
    if free == 0:
        return float(median(np.abs(hp[mask == 0])))
    if hp.shape[2] * free >= _BINNED_MIN:
        h, w = mask.shape
        px = hp.reshape(h * w, -1).take(np.flatnonzero(mask.reshape(-1) == 0), 0)
        return median_binned(np.abs(px).reshape(-1))
    a = np.abs(hp)
    np.copyto(a, np.float32(np.inf), where=spread3((mask > 0).view(np.uint8)) > 0)
    n = hp.shape[2] * free
    h = n // 2
    s = np.partition(a.reshape(-1), h)
    if n % 2:
        return float(s[h])
    return float((s[:h].max() + s[h]) / np.float32(2))


#: From this many values :func:`_unmasked_median_abs` takes :func:`median_binned` (below,
#: on a mouth corner's ~2800 values, one partition costs less than its dozen passes)
_BINNED_MIN = 8192


@lru_cache(maxsize=4)
def lip_curves(m: StandardMesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertex indices of the upper and the lower inner lip (inner corner to inner corner,
    facing point by point) and of the outer lip contour (a closed loop, upper lip first).
    Per mesh, read-only."""
    upper = np.array([m.index("lipi_c0")] + [m.index(f"lipi_u{k}") for k in range(1, 8)]
                     + [m.index("lipi_c1")])
    lower = np.array([m.index("lipi_c0")] + [m.index(f"lipi_d{k}") for k in range(1, 8)]
                     + [m.index("lipi_c1")])
    outer = np.array([m.index("lipo_c0")] + [m.index(f"lipo_u{k}") for k in range(1, 8)]
                     + [m.index("lipo_c1")] + [m.index(f"lipo_d{k}") for k in range(7, 0, -1)])
    for a in (upper, lower, outer):
        a.setflags(write=False)
    return upper, lower, outer


@lru_cache(maxsize=4)
def lower_outer_curve(m: StandardMesh) -> np.ndarray:
    """Vertex indices of the lower outer lip, outer corner to outer corner (facing
    :func:`lip_curves`' lower inner lip point by point). Per mesh, read-only."""
    out = np.array([m.index("lipo_c0")] + [m.index(f"lipo_d{k}") for k in range(1, 8)]
                   + [m.index("lipo_c1")])
    out.setflags(write=False)
    return out


def _build(face: Face) -> SealPlan | None:
    m = face.mesh
    iod = float(face.interocular)
    V = face.vertices.astype(np.float64)
    hole = np.asarray(m.holes["mouth"])
    upper, lower, outer = lip_curves(m)
    img = face.image
    area0 = _area(face.vertices.take(hole, 0))  # as closing_share measures it
    opening = None
    # the photo's edge ramp (1 px on a sharp photo: the fills as before)
    soft = layer_plan(face).soft
    if area0 >= 0.005 * iod * iod:
        opening = _opening_patch(img, V[hole], V[outer], iod, soft,
                                 (V[lower], V[lower_outer_curve(m)]))
    if opening is None:
        area0 = 0.0
    # the corners' notches are looked for on the photo with its opening filled (a pixel of
    # both fills would take both differences: photo + 2 x (fill - photo), white on a dark one)
    corners = [c for c in (_corner(face, opening, m.index(n), V[outer], iod, soft)
                           for n in ("lipo_c0", "lipo_c1")) if c is not None]
    if opening is None and not corners:
        return None
    # on a colour photo the line darkens towards the lips' deep red (blue and green more)
    grey = is_grey(img)
    tint = np.full(3, 1.5, np.float32) if grey else np.array([0.8, 1.0, 1.12], np.float32)
    corner_idx = np.array([m.index("lipo_c0"), m.index("lipo_c1")])
    p0 = V[corner_idx]
    way = face.neutral_vertices[corner_idx].astype(np.float64) - p0
    way[np.hypot(way[:, 0], way[:, 1]) < CORNER_MOVE * iod] = 0.0
    floor = 0.0 if opening is None or grey else LINE_FLOOR * opening.light
    gain = 1.0 if floor <= 0.0 else max(LINE_MAX / (LINE_DEPTH * _tint_luma(tint)), 1.0)
    return SealPlan(opening, corners, area0, upper, lower, outer, iod, tint, hole, corner_idx,
                    p0, way.tolist(), floor, gain)


def _box(img: np.ndarray, lo: np.ndarray, hi: np.ndarray
         ) -> tuple[int, int, int, int] | None:
    H, W = img.shape[:2]
    x0, y0 = max(int(math.floor(lo[0])), 0), max(int(math.floor(lo[1])), 0)
    x1, y1 = min(int(math.ceil(hi[0])) + 1, W), min(int(math.ceil(hi[1])) + 1, H)
    return None if x1 - x0 < 4 or y1 - y0 < 4 else (x0, y0, x1, y1)


def _raster(shape: tuple[int, int], org: tuple[int, int], pts: np.ndarray) -> np.ndarray:
    a = np.zeros(shape, np.uint8)
    q = np.round((pts - org) * 16).astype(np.int32)
    cv2.fillPoly(a, [q], 1, cv2.LINE_8, 4)
    return a


def _opening_patch(img: np.ndarray, poly: np.ndarray, outer: np.ndarray, iod: float,
                   soft: float = 1.0,
                   lower_lip: tuple[np.ndarray, np.ndarray] | None = None) -> _Patch | None:
    """The opening's pixels on the lips (dark or teeth, within :data:`REACH` outside the
    inner-lip polygon ``poly``), filled (None: there are none); ``soft``: the photo's edge
    ramp (:func:`_soften`); ``lower_lip``: the lower lip's inner and outer curves (corner to
    corner, photo pixels), where the fill gets the lower lip's light (:func:`_highlight`)."""
    reach = max(REACH * iod, 1.5)
    pad = int(math.ceil(reach)) + 4
    box = _box(img, outer.min(0) - pad, outer.max(0) + pad)
    if box is None:
        return None
    x0, y0, x1, y1 = box
    patch = np.ascontiguousarray(img[y0:y1, x0:x1])
    shape = (y1 - y0, x1 - x0)
    inside = _raster(shape, (x0, y0), poly)
    lips = _raster(shape, (x0, y0), outer)
    r = max(int(round(reach)), 1)
    near = cv2.dilate(inside, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,
                                                                            2 * r + 1)))
    L = luminance(patch)
    ring = (lips > 0) & (inside == 0)
    if not ring.any():
        return None
    ref = float(median(L[ring]))
    hsv = cv2.cvtColor(patch, cv2.COLOR_RGB2HSV)
    sat = hsv[..., 1].astype(np.float32)
    lip_sat = float(median(sat[ring]))
    # dark (the cavity, the shadow under the upper lip) or teeth (bright and paler than the
    # lips; on a grey photo bright alone; only within the lips: beyond them, skin is as
    # bright on a grey photo)
    teeth = (L > BRIGHT * ref) & (sat <= 0.6 * lip_sat) & (lips > 0)
    cand = (inside == 0) & ((L < DARK * ref) | teeth)
    opening = (near > 0) & cand
    if not opening.any():
        return None
    # and what joins them within the lips up to twice as far (a toothy smile's lower teeth
    # and the dark gap above them, below a lower inner lip the detector put on the upper
    # teeth's edge: JAFFE KA, KM, NA); a lip's own gloss, apart from the opening, stays
    # (a distance transform: its cost does not grow with the reach as a dilation's does)
    far = cv2.distanceTransform(1 - inside, cv2.DIST_L2, cv2.DIST_MASK_PRECISE) <= 2 * r
    cand &= (lips > 0) & far
    cand |= opening
    n, lab = cv2.connectedComponents(cand.astype(np.uint8), connectivity=8)
    keep = np.zeros(n, bool)
    keep[lab[opening]] = True
    keep[0] = False
    opening = keep[lab]
    if soft > 1.0:
        opening = (_grow(opening, soft) > 0) & (near > 0) & (inside == 0)
    # inside the polygon: the lips' median colour (the warp's bilinear taps along a closed lip
    # line reach a pixel into the photo's opening; the mouth layer draws over what is inside a
    # deformed opening), so that only the ring is inpainted (its cost grows with the pixels
    # filled) and it is filled from the lips, not from the teeth
    base = patch.copy()
    # (channel_median: np.median's values from each channel's histogram, no gather)
    base[inside > 0] = channel_median(patch, ring).astype(np.uint8)
    # the grain mirrored from the lips the opening leaves, not from the flat tone set inside
    # the polygon (half of a toothy smile's fill lies nearer to it: a smooth band along the
    # closed lips) nor from the skin beyond them. The fill's high-pass (sigma 1 px, outside
    # the polygon) over the photo's lips left: the sample 0.70 -> 0.80, JAFFE KA.HA1, KM.HA1,
    # NA.HA1 0.78, 1.01, 1.03 -> 0.85, 1.20, 1.08 (tests/test_lipseal.py)
    src = ring.view(np.uint8)
    filled = _fill(base, opening.astype(np.uint8) * 255, INPAINT_R, src)
    if lower_lip is not None:
        skin = (cv2.dilate(lips, np.ones((3, 3), np.uint8)) == 0)
        if skin.any():
            _highlight(filled, opening, lower_lip, (x0, y0), float(median(L[skin])), iod)
    return _Patch(_difference(filled, patch, soft), (x0, y0), ref)


def _highlight(filled: np.ndarray, opening: np.ndarray, lower_lip: tuple[np.ndarray, np.ndarray],
               org: tuple[int, int], skin: float, iod: float) -> None:
    """The lower lip's light band (:data:`HIGHLIGHT`) added in place to ``filled`` (the
    patch at ``org``, float32) where the fill covers the lower lip (``opening``, feathered by
    0.02 IOD): each pixel's height between the lower lip's inner and outer curve places it in
    the band; grey (a sheen, the lips' colour kept under it)."""
    inner, outer = (np.asarray(c, np.float64) for c in lower_lip)
    h, w = opening.shape
    xs = np.arange(w, dtype=np.float64) + org[0]
    # (each curve's points in x order: the corners' order depends on the mesh's side)
    yi = np.interp(xs, *inner[np.argsort(inner[:, 0])].T)
    yo = np.interp(xs, *outer[np.argsort(outer[:, 0])].T)
    c0, c1 = float(min(inner[0, 0], inner[-1, 0])), float(max(inner[0, 0], inner[-1, 0]))
    if c1 - c0 < 2.0:
        return
    u = (xs - c0) / (c1 - c0)
    side = clamp(np.minimum(u, 1.0 - u) / HIGHLIGHT_FADE, 0.0, 1.0)
    side = side * side * (3.0 - 2.0 * side)
    ys = np.arange(h, dtype=np.float64)[:, None] + org[1]
    t = (ys - yi) / np.maximum(yo - yi, 1.0)
    band = np.exp(-0.5 * ((t - HIGHLIGHT_AT) / HIGHLIGHT_W) ** 2) * side
    cover = cv2.GaussianBlur(opening.astype(np.float32), (0, 0), max(0.02 * iod, 0.5))
    lift = np.maximum(skin - luminance(filled), 0.0) * np.float32(HIGHLIGHT)
    filled += spread3((band * cover * lift).astype(np.float32))


def _grow(mask: np.ndarray, soft: float) -> np.ndarray:
    """``mask`` (bool or 0/1) grown by half the edge ramp ``soft``: on a soft photo the
    blurred rim of teeth and cavity is neither dark nor bright enough for the thresholds,
    and stays on the closed lips as a pale ghost of the teeth."""
    r = int(math.ceil(0.5 * soft))
    return cv2.dilate(np.asarray(mask, np.uint8),
                      cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1)))


def _difference(filled: np.ndarray, patch: np.ndarray, soft: float) -> np.ndarray:
    """(h, w, 4) float32 fill minus photo (4th channel zero), feathered over the edge ramp
    ``soft`` on a soft photo (a patch cut at one pixel shows its outline there)."""
    diff = zero_alpha(filled - patch.astype(np.float32))
    if soft > 1.0:
        diff = cv2.GaussianBlur(diff, (0, 0), 0.31 * soft)  # (a 10-90 % width of 0.8 soft)
    return diff


def _corner(face: Face, opening: _Patch | None, vertex: int, outer: np.ndarray, iod: float,
            soft: float = 1.0) -> _Corner | None:
    """The dark notch the photo's expression made beside one mouth corner (a smile's
    commissure fold), filled with the skin around it; None when the photo's corner is where
    its neutral mesh puts it (within :data:`CORNER_MOVE`) or no notch is there."""
    p0 = face.vertices[vertex].astype(np.float64)
    disp = face.neutral_vertices[vertex].astype(np.float64) - p0
    if float(np.hypot(*disp)) < CORNER_MOVE * iod:
        return None
    img = face.image
    R = max(CORNER_R * iod, 2.0)
    box = _box(img, p0 - R - 4, p0 + R + 4)
    if box is None:
        return None
    x0, y0, x1, y1 = box
    # with the opening's fill where the boxes overlap
    patch = _overlaid(img[y0:y1, x0:x1], box, [opening] if opening is not None else [])
    shape = (y1 - y0, x1 - x0)
    lips = _raster(shape, (x0, y0), outer)
    # (np.mgrid's values, broadcast)
    yy = np.arange(y0, y1, dtype=np.float64)[:, None]
    xx = np.arange(x0, x1, dtype=np.float64)[None, :]
    out_dir = p0 - outer.mean(0)
    out_dir /= max(float(np.hypot(*out_dir)), 1e-9)
    # beside the corner, on its lateral side (not the lips' own shading above or below it)
    # (the distances and the projections are kept for the fade below)
    along = (xx - p0[0]) * out_dir[0] + (yy - p0[1]) * out_dir[1]
    lateral = along > -0.02 * iod
    d = np.hypot(xx - p0[0], yy - p0[1])
    disk = d < R
    L = luminance(patch)
    skin = (lips == 0) & ~disk
    if not skin.any():
        return None
    ref = float(median(L[skin]))
    notch = disk & lateral & (lips == 0) & (L < NOTCH_DARK * ref)
    if not notch.any():
        return None
    # the notch's soft edge too (one pixel around it)
    mask = cv2.dilate(notch.astype(np.uint8), np.ones((3, 3), np.uint8))
    if soft > 1.0:
        mask = _grow(mask, soft)
    mask[lips > 0] = 0
    filled = _fill(patch, mask * 255, INPAINT_R)
    if soft > 1.0:
        # the disc's and the lateral side's edges fade over a third of the radius: a fold
        # crossing them (the nasolabial fold, wide on a large face) is not cut off by a line
        side = (along + 0.02 * iod) / max(0.05 * iod, 1.0)
        wgt = clamp((R - d) / (R / 3.0), 0.0, 1.0) * clamp(side, 0.0, 1.0)
        filled = patch + spread3((wgt * wgt * (3.0 - 2.0 * wgt)).astype(np.float32)) \
            * (filled - patch.astype(np.float32))
    return _Corner(vertex, p0, disp, _Patch(_difference(filled, patch, soft), (x0, y0)))


def closing_share(plan: SealPlan, vertices: np.ndarray) -> float:
    """Share of the photo's opening that ``vertices`` close (0: as open or more, 1: shut)."""
    if plan.opening is None:
        return 0.0
    poly = np.asarray(vertices).take(plan.hole, 0)
    return min(max(1.0 - _area(poly) / plan.area0, 0.0), 1.0)


def back_share(plan: SealPlan, vertices: np.ndarray) -> float:
    """How far the mouth corners of ``vertices`` went back from the photo's place towards the
    neutral mesh's, on average (each as :func:`corner_share`; 0 for a corner the photo has
    where the neutral mesh puts it)."""
    # (two corners: Python floats, the same float64 arithmetic as on arrays without their
    # per-call cost)
    d = (np.asarray(vertices).take(plan.corner_idx, 0).astype(np.float64)
         - plan.corner_p0).tolist()
    t = [min(max((dx * wx + dy * wy) / max(wx * wx + wy * wy, 1e-12), 0.0), 1.0)
         for (dx, dy), (wx, wy) in zip(d, plan.corner_way, strict=True)]
    return sum(t) / len(t)


def corner_share(corner: _Corner, vertices: np.ndarray) -> float:
    """How far a mouth corner of ``vertices`` went from the photo's place towards the
    neutral mesh's (its projection on that way, clipped to [0, 1])."""
    # (two coordinates: Python floats, the arithmetic of the 2-vectors' dot products written
    # out, without numpy's per-call cost)
    (px, py), (wx, wy) = corner.p0_disp
    vx, vy = np.asarray(vertices[corner.vertex], np.float64).tolist()
    t = ((vx - px) * wx + (vy - py) * wy) / (wx * wx + wy * wy)
    return min(max(t, 0.0), 1.0)


def apply_lip_seal(face: Face, res: WarpResult, vertices: np.ndarray,
                   share: float | None = None) -> WarpResult:
    """Seal the photo's opening on the lips of ``res.image`` (in place), by the share the
    deformed mesh ``vertices`` closes it, and fill the corners' notches by their shares; the
    result's ``bbox`` grown to what was written. ``share``: :func:`closing_share` of
    ``vertices`` when the caller has it (the render computes it once for this stage and
    :func:`apply_contact_line`)."""
    plan = seal_plan(face)
    if plan is None:
        return res
    # the shares ramp in from _MIN_SHARE (continuous in the FAPs; nothing to do below it)
    s = _ramp(closing_share(plan, vertices) if share is None else share)
    # share, fill, its offset on the frame
    jobs: list[tuple[float, _Patch, tuple[float, float]]] = []
    if plan.opening is not None:
        # the photo's dark or bright rim of its opening also goes where its mouth corners go
        # back towards the neutral face (a smile's dark commissures and the teeth beside
        # them, outside the inner-lip polygon, dragged onto the lips of an opening that is
        # narrower at the corners: surprise or fear on a smiling photo)
        so = max(s, _ramp(back_share(plan, vertices)))
        if so > 0.0:
            jobs.append((so, plan.opening, (0.0, 0.0)))
    for c in plan.corners:
        cs = _ramp(corner_share(c, vertices))
        if cs > 0.0:
            (px, py), _ = c.p0_disp
            vx, vy = np.asarray(vertices[c.vertex], np.float64).tolist()
            jobs.append((cs, c.patch, (vx - px, vy - py)))
    if not jobs:
        return res
    out = res.image
    H, W = out.shape[:2]
    bbox = res.bbox
    m = 2
    step = reach_step(face)
    for share, patch, shift in jobs:
        # the frame's pixels whose photo position may fall in the fill's box: the box where
        # the photo has it and where its lip vertex took it, with a margin
        h, w = patch.diff.shape[:2]
        ox, oy = patch.org
        # (Python floats: the same values as numpy's element-wise min / max of two pairs)
        sx, sy = shift
        x0, y0 = max(int(min(ox, ox + sx) - m), 0), max(int(min(oy, oy + sy) - m), 0)
        x1 = min(int(max(ox + w, ox + w + sx) + m) + 1, W)
        y1 = min(int(max(oy + h, oy + h + sy) + m) + 1, H)
        if res.maps is None or x1 - x0 < 2 or y1 - y0 < 2:
            continue
        add_carried(out, res.maps, (x0, y0, x1, y1), patch.diff, (ox, oy), share,
                    patch.support, step)
        bbox = _union(bbox, (x0, y0, x1, y1))
    return res if bbox == res.bbox or bbox is None else _rebox(res, bbox, {})


def add_carried(out: np.ndarray, maps: tuple[np.ndarray, np.ndarray, tuple[int, int, int, int]],
                box: tuple[int, int, int, int], diff: np.ndarray, org: tuple[int, int],
                share: float, support: tuple[int, int, int, int] | None = None,
                step: int = 1) -> None:
    """Add ``share`` times a photo difference ``diff`` ((h, w, 4) float32 whose top-left
    corner is ``org`` on the photo) to ``out``'s ``box`` (in place, rounded and saturated),
    carried to the frame by the warp's backward ``maps`` (zeros where they leave it).
    ``support``: :func:`_support` of ``diff`` when known; then only the part of ``box``
    whose map reaches it is resampled (elsewhere the carried difference is zero and adds
    nothing: the same frame), on a box of more than :data:`REACH_MIN_PX` pixels; ``step``:
    :func:`_reached`'s."""
    if support is not None and (box[2] - box[0]) * (box[3] - box[1]) > REACH_MIN_PX:
        sub = _reached(maps, box, org, support, step)
        if sub is None:
            return
        box = sub
    x0, y0, x1, y1 = box
    mx, my = box_maps(maps, box, org)
    d = cv2.remap(diff, mx, my, cv2.INTER_LINEAR)  # (zeros outside: the default)
    d3 = np.asarray(cv2.cvtColor(d, cv2.COLOR_RGBA2RGB), np.float32)
    d3 *= np.float32(share)
    view = out[y0:y1, x0:x1]
    cv2.add(view, d3, view, None, cv2.CV_8U)  # rounded, saturated


#: :func:`add_carried` finds the part of a box its difference reaches (:func:`_reached`) from
#: this many pixels on; a smaller box is resampled whole (zeros add nothing: the same frame).
#: The search is five OpenCV calls on the warp's maps, which cost more than resampling a
#: small box's unreached pixels: the 431 x 591 bench face's corner boxes of ~770 px (110 px
#: reached), its opening's box of 2124 px (648), the 1080p face's corners of ~2200 px (in a
#: frame -6 us at 431, -10 us at 1080)
REACH_MIN_PX = 2500


def _support(diff: np.ndarray) -> tuple[int, int, int, int] | None:
    """The box ``(x0, y0, x1, y1)`` of the pixels of ``diff`` (h, w, c) that are not zero in
    every channel (None: none are)."""
    ne = diff != 0
    if ne.ndim == 3 and ne.shape[2] == 4 and ne.flags.c_contiguous:
        # (a pixel's four flags as one 32-bit word: nonzero where any is; numpy's any() over
        # the short last axis costs ~15 x more: 0.11 ms on a 1080p face's opening patch)
        nz = (ne.view(np.uint32)[..., 0] != 0).view(np.uint8)
    else:
        nz = np.ascontiguousarray(ne.any(axis=-1), np.uint8)
    x, y, w, h = cv2.boundingRect(nz)
    return (x, y, x + w, y + h) if w else None


def _reached(maps: tuple[np.ndarray, np.ndarray, tuple[int, int, int, int]],
             box: tuple[int, int, int, int], org: tuple[int, int],
             support: tuple[int, int, int, int], step: int = 1
             ) -> tuple[int, int, int, int] | None:
    """The part of the frame's ``box`` whose backward ``maps`` may sample a photo difference
    whose nonzero pixels lie in ``support`` (its coordinates, its top-left corner at ``org``
    on the photo): the bounding box of the pixels whose map lies within 2 px of it (None:
    none does). Elsewhere the bilinear sample reads only zeros (a map rounded to 1/32 px
    reads its floor and the next pixel: beyond 1.5 px of the support both are outside), so
    the carried difference is exactly zero there. ``box`` itself when the maps do not cover
    it (the identity beyond them: not worth a finer box). On the 4K bench face the lip
    seal's three boxes shrink to 61 % of their pixels (the opening's reaches 72 % of its
    box, the corners' ~40 %).

    ``step`` > 1 (a large face: :func:`reach_step`): the maps are read every ``step`` rows
    and columns, their range widened by ``step`` px and the box found grown by ``step // 2``
    px (every pixel lies within ``step // 2`` px of a sample along each axis, but for the
    box's last ``step - 1`` rows and columns, which go with their sample; a map that
    moves by less than ``step / (step // 2) / sqrt(2)`` px a pixel, 1.4 at ``step`` 4, reaches
    no further there): a box holding the exact one as long as the warp's map is that smooth
    where it leaves the support (the 4K bench face: the same frames; its boxes 4-16 % larger
    than the exact ones), at about a third of the cost (lip seal -0.2 ms a frame)."""
    x0, y0, x1, y1 = box
    map_x, map_y, (a0, b0, a1, b1) = maps
    if not (a0 <= x0 and b0 <= y0 and x1 <= a1 and y1 <= b1):
        return box
    sx0, sy0, sx1, sy1 = support
    ox, oy = org
    tol = 0.0 if step <= 1 else float(step)
    # (the maps' own memory; cv2.inRange: both bounds inclusive. The rows first: the x map
    # is then read only in the rows whose y map reaches the support, a third fewer of its
    # cold pixels on the bench face's corners and shadow)
    m = cv2.inRange(map_y[y0 - b0:y1 - b0:step, x0 - a0:x1 - a0:step],
                    float(oy + sy0 - 2 - tol), float(oy + sy1 + 1 + tol))
    _, r0, _, nr = cv2.boundingRect(m)
    if not nr:
        return None
    m = m[r0:r0 + nr]
    r0 = y0 + r0 * step
    cv2.bitwise_and(m, cv2.inRange(map_x[r0 - b0:r0 + (nr - 1) * step + 1 - b0:step,
                                         x0 - a0:x1 - a0:step],
                                   float(ox + sx0 - 2 - tol), float(ox + sx1 + 1 + tol)), m)
    x, y, w, h = cv2.boundingRect(m)
    if not w:
        return None
    if step <= 1:
        return (x0 + x, r0 + y, x0 + x + w, r0 + y + h)
    # (in samples from the box's corner: the first and last sample reached; the box's own
    # pixels beyond its last sample row or column, up to step - 1 of them, go with it)
    g = step // 2
    c0, c1 = x, x + w - 1
    s0, s1 = (r0 - y0) // step + y, (r0 - y0) // step + y + h - 1
    return (max(x0 + c0 * step - g, x0), max(y0 + s0 * step - g, y0),
            x1 if c1 == (x1 - 1 - x0) // step else min(x0 + c1 * step + g + 1, x1),
            y1 if s1 == (y1 - 1 - y0) // step else min(y0 + s1 * step + g + 1, y1))


def reach_step(face: Face) -> int:
    """:func:`_reached`'s sampling step for ``face``: 4 on a soft photo (edge ramp
    ``layers.LayerPlan.soft`` of at least 6 px: a large face, the bench's 4K one 15 px),
    where the carried differences span hundreds of pixels; else 1 (every pixel)."""
    return 4 if layer_plan(face).soft >= 6.0 else 1


def apply_contact_line(face: Face, res: WarpResult, vertices: np.ndarray,
                       share: float | None = None) -> WarpResult:
    """Darken the lips of ``res.image`` where they meet (in place), by the share the deformed
    mesh ``vertices`` closes the photo's opening; the result's ``bbox`` grown to what was
    written. Runs after the mouth layer (:func:`~editor.engine.layers.render_layers`): a
    mouth closed to a sliver still has an opening there, which the layer continues with the
    lips' colour beside it on a soft photo (``layers._soft_edge``): drawn before, the line
    was erased along the sliver and read as a light line between the lips. ``share``:
    :func:`closing_share` of ``vertices`` when the caller has it."""
    plan = seal_plan(face)
    if plan is None:
        return res
    s = _ramp(closing_share(plan, vertices) if share is None else share)
    if s <= 0.0:
        return res
    out = res.image
    H, W = out.shape[:2]
    # (the lips' rows gathered, then in float64: the values of all vertices converted; the
    # box's bounds on Python numbers)
    vv = np.asarray(vertices)
    up = vv.take(plan.upper, 0).astype(np.float64)
    lo = vv.take(plan.lower, 0).astype(np.float64)
    pad = max(int(math.ceil(3 * LINE_SIGMA * plan.iod)), 2) + 2
    qx, qy = up[:, 0].tolist(), up[:, 1].tolist()
    x0, y0 = max(int(min(qx)) - pad, 0), max(int(min(qy)) - pad, 0)
    x1, y1 = min(int(max(qx)) + pad + 1, W), min(int(max(qy)) + pad + 1, H)
    line = None if x1 - x0 < 2 or y1 - y0 < 2 else _contact_line(plan, up, lo,
                                                                  (x0, y0, x1, y1), s)
    if line is None:
        return res
    # only the pixels the line darkens by half a grey level or more: where line x tint stays
    # under 0.49 / 255, v (1 - line tint) + 0.5 rounds down to v itself for every v <= 255
    # (float32 rounding included), so the box is cut to those (on the 1080p bench face's
    # open mouth 23 pixels change, by 1: the box's 3-channel passes shrink to their box)
    gain = plan.floor_gain
    hot = line >= np.float32(0.49 / 255.0 / (float(plan.tint.max()) * gain))
    cj, ci, cw, ch = cv2.boundingRect(hot.view(np.uint8))
    if cw:
        view = out[y0 + ci:y0 + ci + ch, x0 + cj:x0 + cj + cw]
        cut = line[ci:ci + ch, cj:cj + cw]
        if gain > 1.0:
            # deeper where the pixel is lighter than the floor allows (LINE_FLOOR)
            tl = _tint_luma(plan.tint)
            k = 1.0 - np.float32(plan.line_floor) / np.maximum(luminance(view), 1.0)
            np.clip(k / np.float32(LINE_DEPTH * tl), 1.0, gain, out=k)
            # (not within FLOOR_CORNER of a corner: the line fades into the commissures at
            # its fixed depth, no dark tick there)
            xs = np.arange(x0 + cj, x0 + cj + cw, dtype=np.float32)[None, :]
            ys = np.arange(y0 + ci, y0 + ci + ch, dtype=np.float32)[:, None]
            d = np.minimum(np.hypot(xs - np.float32(up[0, 0]), ys - np.float32(up[0, 1])),
                           np.hypot(xs - np.float32(up[-1, 0]), ys - np.float32(up[-1, 1])))
            fade = np.clip((d - np.float32(FLOOR_CORNER * plan.iod))
                           / np.float32(0.5 * FLOOR_CORNER * plan.iod), 0.0, 1.0)
            cut = cut * (1.0 + (k - 1.0) * fade)
        # (line (h, w) spread over the channels first: numpy's broadcasting of (h, w, 1) over
        # 3 channels is several times slower; the same float32 products, in place; OpenCV's
        # product of the uint8 pixels and the float32 factors is numpy's on the pixels as
        # float32, and the sum cast into the pixels astype's truncation)
        f3 = spread3(cut)
        f3 *= plan.tint
        np.subtract(1.0, f3, out=f3)
        acc: np.ndarray = np.asarray(cv2.multiply(view, f3, dtype=cv2.CV_32F), np.float32)
        acc += np.float32(0.5)
        np.copyto(view, acc, casting="unsafe")
    bbox = _union(res.bbox, (x0, y0, x1, y1))
    return res if bbox == res.bbox else _rebox(res, bbox, {})


def _tint_luma(tint: np.ndarray) -> float:
    """The luminance of the contact line's per-channel weights ``tint`` (how deep it darkens
    a pixel's luminance, per unit of the line)."""
    return float(luminance(tint.reshape(1, 1, 3).astype(np.float32))[0, 0])


def _ramp(share: float) -> float:
    return max(share - _MIN_SHARE, 0.0) / (1.0 - _MIN_SHARE)


def _contact_line(plan: SealPlan, up: np.ndarray, lo: np.ndarray,
                  box: tuple[int, int, int, int], s: float) -> np.ndarray | None:
    """(h, w) float32 darkening along the lips where they meet (None: nowhere, or by less
    than :data:`_LINE_SKIP` grey levels anywhere); ``up``,
    ``lo`` the upper and lower inner lip (float64, :attr:`SealPlan.upper`, ``lower``)."""
    x0, y0, x1, y1 = box
    gap = np.hypot(*(lo - up).T)
    shut = SHUT * plan.iod
    c = clip((2.0 * shut - gap) / shut, 0.0, 1.0)  # 1 shut, 0 from twice SHUT apart
    c[0] *= 0.6  # the corners: the line fades into the commissure
    c[-1] *= 0.6
    w = s * c
    # (the line's darkest value is at most LINE_DEPTH times its largest weight: a straight
    # line's blurred peak is its weight per unit length, a curve as gentle as the lips' stays
    # under it, 0.57-0.99 of it over the six presets at 30-150 % on the 1080p bench face and
    # the sample. Below _LINE_SKIP grey levels on white it is not drawn: on the 1080p bench
    # face's expression the line changed 23 pixels by 1 level for ~0.15 ms a frame)
    wmax = float(w.max())
    if wmax * LINE_DEPTH * float(plan.tint.max()) * 255.0 < _LINE_SKIP:
        return None
    mid = 0.5 * (up + lo)
    mid[:, 0] -= x0
    mid[:, 1] -= y0
    # the line sampled every half pixel or finer, splatted bilinearly (one bincount)
    seg = mid[1:] - mid[:-1]
    seg_len = np.hypot(*seg.T)
    n = int(min(max(math.ceil(float(seg_len.max()) / 0.5), 1), 64))
    t = (np.arange(n) + 0.5) / n
    pts = (mid[:-1, None, :] + seg[:, None, :] * t[None, :, None]).reshape(-1, 2)
    wt = (w[:-1, None] + (w[1:] - w[:-1])[:, None] * t[None]).ravel()
    wt *= seg_len.repeat(n) / n  # a line's weight per unit length
    h, wd = y1 - y0, x1 - x0
    ix = np.floor(pts).astype(np.intp)
    fx, fy = pts[:, 0] - ix[:, 0], pts[:, 1] - ix[:, 1]
    # (the clip ufunc: np.clip's values on integers without its Python layers)
    cx, cy = clip(ix[:, 0], 0, wd - 2), clip(ix[:, 1], 0, h - 2)
    # the four pixels about each sample and their bilinear weights, corner by corner (top
    # left, top right, bottom left, bottom right: each product times wt, as one array)
    base = cy * wd + cx
    flat = (base[None, :] + np.array([0, 1, wd, wd + 1])[:, None]).ravel()
    gy, gx = 1 - fy, 1 - fx
    ws = np.concatenate([gy * gx, gy * fx, fy * gx, fy * fx])
    ws4 = ws.reshape(4, -1)  # (a view: the products times wt in place)
    ws4 *= wt
    canvas = np.bincount(flat, ws, h * wd).astype(np.float32).reshape(h, wd)
    sig = max(LINE_SIGMA * plan.iod, 0.6)
    line = _blur_wide(canvas, sig)
    # a 1-px line blurred by sig has its peak at 1 / (sqrt(2 pi) sig): scaled to LINE_DEPTH
    line *= np.float32(LINE_DEPTH * math.sqrt(2.0 * math.pi) * sig)
    np.minimum(line, LINE_DEPTH, out=line)
    return line
