"""The mouth made from the photo: soft shaded opening, teeth that neither cut nor sliver."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from conftest import jaffe_images

from editor.core import Face
from editor.engine.imageio import load_image
from editor.formats.presets import apply_preset

LUM = np.float32([0.299, 0.587, 0.114])
#: FAPs that bring the sample's parted lips together (inner lips meet at the middle)
CLOSE = {n: 250 for n in ("lower_t_midlip", "raise_b_midlip", "lower_t_lip_lm",
                          "lower_t_lip_rm", "raise_b_lip_lm", "raise_b_lip_rm")}


def _lum(img: np.ndarray) -> np.ndarray:
    return img.astype(np.float32) @ LUM


def _skin(face: Face) -> float:
    v = face.vertices
    x0, y0 = v[face.fdp["8.4"]] - 0.3 * face.interocular
    x1, y1 = v[face.fdp["8.3"]] + 0.3 * face.interocular
    return float(np.median(_lum(face.image[int(y0):int(y1), int(x0):int(x1)])))


def _opening(face: Face, v: np.ndarray, shape) -> np.ndarray:
    m = np.zeros(shape[:2], np.uint8)
    cv2.fillPoly(m, [np.round(v[face.mesh.holes["mouth"]] * 16).astype(np.int32)], 1,
                 cv2.LINE_8, 4)
    return m.astype(bool)


def _hard_edge_fraction(face: Face, faps) -> float:
    """Fraction of the opening's border pixels darker than the lip next to them by more
    than 0.45 of the skin's luminance (a flat dark fill cut out with a hard edge)."""
    img, v = face.render(faps), face.deform(faps)
    L = _lum(img)
    h = _opening(face, v, img.shape)
    ring = h & ~cv2.erode(h.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    lip = cv2.dilate(np.where(h, 0.0, L).astype(np.float32), np.ones((3, 3), np.uint8))
    return float(((lip - L)[ring] > 0.45 * _skin(face)).mean())


@pytest.mark.parametrize("faps", [apply_preset("surprise", 1.0), apply_preset("fear", 1.5),
                                  {"open_jaw": 400}], ids=["surprise", "fear150", "jaw400"])
def test_open_mouth_has_soft_shaded_edges(sample_face, faps):
    # the cavity starts from the lips' darkened inner surface, not a flat dark polygon
    # (main before this change: 0.20, 0.13, 0.16)
    assert _hard_edge_fraction(sample_face, faps) < 0.11


def test_closed_lips_show_no_teeth(sample_face):
    f = sample_face
    img, v = f.render(CLOSE), f.deform(CLOSE)
    up, lo = (v[[f.mesh.index(f"lipi_{s}{k}") for k in range(1, 8)]] for s in "ud")
    assert float(np.abs(lo[:, 1] - up[:, 1]).max()) < 1.5  # really closed
    line = np.zeros(img.shape[:2], np.uint8)
    pts = np.vstack([v[f.mesh.index("lipi_c0")], 0.5 * (up + lo), v[f.mesh.index("lipi_c1")]])
    cv2.polylines(line, [np.round(pts * 16).astype(np.int32)], False, 1, 1, cv2.LINE_8, 4)
    L = _lum(img)[line.astype(bool)]
    # the lips (pale pink here, ~0.85 of the skin) meet without the photo's teeth between them
    # (main before this change: white specks up to 1.15 of the skin on the lip line)
    assert L.max() < 1.08 * _skin(f), L.max() / _skin(f)
    # and without a dark gap wider than a lip line: the contact line alone (lipseal's
    # LINE_DEPTH 0.5, calibrated on JAFFE's neutral photos) leaves 0.57 of the skin on it, the
    # opening's cavity would leave 0.2-0.3
    assert np.median(L) > 0.45 * _skin(f)

def test_own_expression_reproduces_the_photo(sample_face):
    # the photo's own expression f0 renders the photo exactly (zeros: the neutralised face)
    assert sample_face.has_expression
    assert np.array_equal(sample_face.render(sample_face.expression), sample_face.image)


# ---------------------------------------------------------------------------- second round
def _band_under_upper_lip(face: Face, faps: np.ndarray, rows=(1, 3)):
    """Luminance (relative to the skin) of the opening's rows 1-2 under the upper lip in the
    middle columns (+-0.1 MW around 2.2), and its change when the jaw opens by 200 more."""
    img = face.render(faps)
    img2 = face.render(np.asarray(faps) + face.fap_vector({"open_jaw": 200}))
    h = _opening(face, face.deform(faps), img.shape)
    s = _skin(face)
    xc, half = face.deform(faps)[face.fdp["2.2"], 0], 0.1 * face.fapu["MW"] * 1024
    vals, diffs = [], []
    for x in range(int(round(xc - half)), int(round(xc + half)) + 1):
        r = np.flatnonzero(h[:, x])[rows[0]:rows[1]]
        vals += list(_lum(img[r, x]) / s)
        diffs += list(np.abs(_lum(img[r, x]) - _lum(img2[r, x])) / s)
    return float(np.median(vals)), float(np.median(diffs))


def test_upper_lip_faps_move_an_upturned_mouths_whole_lip(sample_face):
    # the neutralised sample keeps its corners ~0.1 IOD above the lip middle; the upper lip's
    # rectangles must still reach past the lip (main before: lower_t_midlip moved lipi_u5 by
    # half of lipi_u4's motion and lipi_u3 not at all: the smile opened at one vertex)
    f = sample_face
    ey = f.frame.rot[:, 1]
    up = [f.mesh.index(f"lipi_u{k}") for k in range(1, 8)]
    d = (f.deform({"lower_t_midlip": -300}) - f.deform(None))[up] @ ey
    assert d[3] < -1.0
    assert 0.3 < d[2] / d[3] < 0.7 and 0.3 < d[4] / d[3] < 0.7, d
    assert abs(d[2] - d[4]) < 0.15 * abs(d[3]), d


def _jaffe_smilers(jaffe_faces):
    return [f for f in jaffe_faces if not f.has_expression][:3]


def test_upper_teeth_show_in_a_smile(sample_face, jaffe_faces):
    # closed-mouth faces: the drawn upper teeth fill the top of a smile's opening (main before:
    # 0.74-0.78 of the skin there, the lower teeth's shadowed middle, moving with the jaw)
    # (drawn at TEETH_L 0.95 of the skin, as lit as real smiles' teeth: 0.90-1.18 here)
    faces = _jaffe_smilers(jaffe_faces)
    assert len(faces) >= 2
    for f in faces + [sample_face]:
        lum, _ = _band_under_upper_lip(f, apply_preset("joy", 1.0))
        assert lum > 0.85, (f.source, lum)
        # and they are the upper teeth: fixed to the skull while the jaw opens further
        lum, moved = _band_under_upper_lip(f, apply_preset("joy", 1.5))
        assert lum > 0.85 and moved < 0.1, (f.source, lum, moved)


def _teeth_p90(image: np.ndarray) -> float | None:
    """The 90th percentile of the luminance inside the detected inner lips (eroded a pixel)
    over the skin's median in a ring 0.08-0.16 IOD outside the outer lips, the same measure on
    a real photo and on a render; None when the lips part by less than 0.05 IOD."""
    got = _open_mouth(image)
    if got is None:
        return None
    L, p, _, skin = got
    inner = np.zeros(L.shape, np.uint8)
    cv2.fillPoly(inner, [np.round(p[60:68]).astype(np.int32)], 1)
    inner = cv2.erode(inner, np.ones((3, 3), np.uint8)).astype(bool)
    return float(np.percentile(L[inner], 90)) / skin


def _open_mouth(image: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, float] | None:
    """Luminance, detected landmarks (68), inter-ocular distance and the skin's median
    luminance in a ring 0.08-0.16 IOD outside the outer lips; None when the inner lips part by
    less than 0.05 IOD."""
    from editor.engine.landmarks import detect_landmarks

    lm = detect_landmarks(image)
    p, iod = lm.points.astype(np.float32), float(lm.interocular)
    L = _lum(image)
    if p[66, 1] - p[62, 1] < 0.05 * iod:
        return None
    outer = np.zeros(L.shape, np.uint8)
    cv2.fillPoly(outer, [np.round(p[48:60]).astype(np.int32)], 1)
    d = cv2.distanceTransform(1 - outer, cv2.DIST_L2, 3)
    return L, p, iod, float(np.median(L[(d > 0.08 * iod) & (d < 0.16 * iod)]))


def test_drawn_teeth_are_as_bright_as_real_smiles_teeth():
    # JAFFE's ten women: their real smiles' teeth against joy drawn on their neutral photos.
    # Real: median p90 1.21 of the skin around the mouth (21 open smiles); drawn at TEETH_L
    # 1.1 they were 1.32 (1.58 at 150 %), white blocks the blind raters called pasted on;
    # at 0.95: 1.23. Neither brighter than real nor dimmed into grey
    real, drawn = [], []
    for ne in jaffe_images("*.NE1.*.tiff"):
        real += [_teeth_p90(load_image(p)) for p in jaffe_images(f"{ne.name[:2]}.HA*.tiff")]
        drawn.append(_teeth_p90(Face.from_image(ne, own_expression=False).render(
            apply_preset("joy", 1.0))))
    real = [r for r in real if r is not None]
    drawn = [d for d in drawn if d is not None]
    if len(real) < 10:
        pytest.skip("../shared/data/jaffe is not available")
    assert len(drawn) >= 8
    r, d = float(np.median(real)), float(np.median(drawn))
    assert r - 0.12 < d < r + 0.06, (r, d)


def test_drawn_teeth_take_the_photos_colour(sample_face, jaffe_faces):
    from editor.engine.layers import _photo_teeth, layer_plan

    def hsv(rgb):
        px = np.clip(np.asarray(rgb, np.float32).reshape(1, 1, 3), 0, 255).astype(np.uint8)
        h, s, v = cv2.cvtColor(px, cv2.COLOR_RGB2HSV_FULL)[0, 0].astype(float)
        return h * 360.0 / 256.0, s / 255.0, v

    def drawn(face):  # the crowns (the texture's pink gum band is not the teeth's colour)
        t = layer_plan(face).mouth.tex["upper_teeth"]
        a = t[..., 3] > 0.95
        c = t[..., :3][a] / t[..., 3:4][a]
        return c[c[:, 0] - c[:, 1] < 0.15 * 255].mean(0)

    f = sample_face
    own = _photo_teeth(f.image, f.vertices[f.mesh.holes["mouth"]], _skin(f))
    assert own is not None
    (h0, s0, _), (h1, s1, _) = hsv(own), hsv(drawn(f))
    assert min(abs(h0 - h1), 360 - abs(h0 - h1)) < 15.0 and abs(s0 - s1) < 0.08, (own, drawn(f))
    for face in jaffe_faces[:2]:  # grey photos, grey teeth
        assert hsv(drawn(face))[1] < 0.03


def _dark_run(face: Face, faps) -> float:
    """Median over the middle columns (+-0.15 MW) of the longest run of dark pixels
    (< 0.25 of the skin) as a fraction of the opening's height in that column."""
    img, v = face.render(faps), face.deform(faps)
    L, s = _lum(img), _skin(face)
    h = _opening(face, v, img.shape)
    xc, half = v[face.fdp["2.2"], 0], 0.15 * face.fapu["MW"] * 1024
    runs = []
    for x in range(int(xc - half), int(xc + half) + 1):
        rows = np.flatnonzero(h[:, x])
        if len(rows) < 3:
            continue
        d = np.concatenate([[0], (L[rows, x] < 0.25 * s).astype(np.int8), [0]])
        edges = np.flatnonzero(np.diff(d))
        runs.append(float((edges[1::2] - edges[::2]).max(initial=0)) / len(rows))
    return float(np.median(runs))


#: What real wide-open mouths look like with _dark_run: the JAFFE surprise photos whose inner lips
#: are more than 0.6 MNS apart (11 photos of KL, KM, MK, NM, YM, each on its own fitted mesh,
#: MediaPipe landmarks) have median 0.58 of the opening's height dark (quartiles 0.44-0.61,
#: lightest 0.11, darkest 0.75). (With the dlib-era meshes: 9 photos, median 0.42; the bound
#: 0.28 before that was lighter than every one of them.)
REAL_WIDE_OPEN_DARK = 0.58


def _wide_open_parts(face: Face, faps) -> tuple[float, float]:
    """Middle columns (+-0.15 MW) of the opening: median over columns of the brightest pixel
    in its top quarter (upper teeth under the lip) and of the median of its bottom 40 %
    (tongue, lower teeth), relative to the skin."""
    img, v = face.render(faps), face.deform(faps)
    L = _lum(img) / _skin(face)
    h = _opening(face, v, img.shape)
    xc, half = v[face.fdp["2.2"], 0], 0.15 * face.fapu["MW"] * 1024
    top, bottom = [], []
    for x in range(int(xc - half), int(xc + half) + 1):
        rows = np.flatnonzero(h[:, x])
        n = len(rows)
        if n < 6:
            continue
        top.append(L[rows[1:max(2, n // 4)], x].max())
        bottom.append(np.median(L[rows[n - max(2, int(0.4 * n)):n - 1], x]))
    return float(np.median(top)), float(np.median(bottom))


def test_wide_open_mouth_is_not_a_dark_hole(jaffe_faces):
    # surprise at 150 %: tongue over the lower teeth, the dark back of the mouth above them; no
    # darker than the median real wide-open JAFFE mouth (main before: 0.33-0.46 of the
    # opening's height dark)
    for f in jaffe_faces[:3]:
        faps = apply_preset("surprise", 1.5)
        r = _dark_run(f, faps)
        assert r < REAL_WIDE_OPEN_DARK, (f.source, r)
        _, bottom = _wide_open_parts(f, faps)
        assert bottom > 0.35, (f.source, bottom)


def test_upper_teeth_show_in_an_open_mouth(jaffe_faces):
    # surprise at 100 % opens the lips ~0.5 MNS: the real JAFFE surprise photos opened that far
    # (NM, TM, KR) show their upper incisors under the lip, 1.06-1.54 x skin in the top quarter
    # (main before: 0.12-0.15, the drawn teeth stayed behind the upper lip). Wider (> 0.6 MNS)
    # real mouths mostly hide them (0.05-0.39): no check there.
    for f in jaffe_faces[:3]:
        top, _ = _wide_open_parts(f, apply_preset("surprise", 1.0))
        assert top > 0.8, (f.source, top)


@pytest.mark.parametrize("jaw", [80, 130])
def test_thin_gap_shows_no_teeth(sample_face, jaw):
    # the neutralised sample's lips part by ~1 px: a dark line, not the photo's teeth through
    # it (main before: pixels up to 1.25-1.39 of the skin's luminance)
    f = sample_face
    img, v = f.render({"open_jaw": jaw}), f.deform({"open_jaw": jaw})
    up, lo = (v[[f.mesh.index(f"lipi_{s}{k}") for k in range(1, 8)]] for s in "ud")
    assert 0.3 < float((lo[:, 1] - up[:, 1]).max()) < 2.0  # really a thin gap
    near = cv2.dilate(_opening(f, v, img.shape).astype(np.uint8), np.ones((3, 3), np.uint8))
    assert _lum(img)[near.astype(bool)].max() < 1.15 * _skin(f)


def test_drawn_teeth_read_as_teeth_at_jaffe_size(jaffe_faces):
    # 256-px faces, viseme aa: the upper teeth row (rows 1-2 under the upper lip, +-0.1 MW
    # around the midline) shows the central incisors' contact as a dip as deep as real teeth
    # show it (JAFFE's 25 open mouths with upper teeth: 0.63 of the row's median, p10..p90
    # 0.35..0.83), neither a black notch (main before: the rounded incisal corners left a V
    # of cavity there, 0.18-0.34 x the row's median) nor a flat white bar
    for f in jaffe_faces[:3]:
        faps = apply_preset("viseme_aa", 1.0)
        img, v = f.render(faps), f.deform(faps)
        L = _lum(img) / _skin(f)
        h = _opening(f, v, img.shape)
        xc, half = v[f.fdp["2.2"], 0], 0.1 * f.fapu["MW"] * 1024
        row = []
        for x in range(int(round(xc - half)), int(round(xc + half)) + 1):
            r = np.flatnonzero(h[:, x])
            row.append(L[r[1:3], x].mean())
        rel = min(row) / float(np.median(row))
        assert float(np.median(row)) > 0.95 and 0.35 < rel < 0.9, (f.source, row)


def test_lips_pushed_forward_shade_the_teeth(sample_face):
    """A rounded u (lips pushed forward, FAPs 16/17) puts the opening in front of the teeth:
    they show dim and warm in a dark hole (the photo's bright incisors filled it before),
    while the same opening with the lips not pushed keeps them lit."""
    f = sample_face
    u = apply_preset("viseme_u", 1.0)
    flat = u.copy()
    flat[[15, 16]] = 0  # push_b_lip, push_t_lip
    lit = []
    for vec in (u, flat):
        img, m = f.render(vec), _opening(f, f.deform(vec), f.image.shape)
        m = cv2.erode(m.astype(np.uint8), np.ones((3, 1), np.uint8)).astype(bool)
        assert m.sum() > 10
        lit.append(np.percentile(_lum(img)[m], 90))
        if vec is u:
            rgb = img[m].astype(np.float32).mean(0)
            assert rgb[0] >= rgb[2], rgb  # warm, not blue-grey
    assert lit[0] < 0.8 * lit[1], lit


def _sides_over_centre(face: Face, faps) -> float:
    """Mean luminance of the opening's outer columns (beyond 0.3 of its width from the middle)
    over that of its middle columns (within 0.2)."""
    img, v = face.render(faps), face.deform(faps)
    L = _lum(img)
    ys, xs = np.nonzero(_opening(face, v, img.shape))
    u = np.abs((xs - xs.min()) / max(float(np.ptp(xs)), 1.0) - 0.5)
    val = L[ys, xs]
    return float(val[u > 0.3].mean() / val[u < 0.2].mean())


def test_the_corners_of_an_opening_are_in_shadow(jaffe_faces):
    # fear parts the lips into a wide, low opening: light reaches the teeth through the local
    # gap between the lips and the dental arch turns away from it, so the corners are dark
    # (real JAFFE fear photos: 0.37 of the middle's light, inner lips as detected; main before:
    # 0.46-0.57 here, evenly lit drawn teeth from corner to corner; now 0.35-0.47)
    for f in jaffe_faces[:3]:
        r = _sides_over_centre(f, apply_preset("fear", 1.0))
        assert r < 0.5, (f.source, r)


def test_lower_lip_edge_does_not_ride_down_with_the_jaw(sample_face):
    # the sample's opening ends in a one-to-three-pixel run of lower-lip edge under its upper
    # teeth (3x: 1536 px); carried down with the jaw it drew a bright line across the dark
    # opening (fear 150 %: 110 pixels of the opening's lower part above 0.85 of the skin; 6
    # after the fix, 17 with the drawn lower teeth's light since: their anti-aliased rim; 33
    # since the neutral's corners sit lower (own_expression.CORNER_LAG): the corners drawn down
    # from there open more of the drawn lower teeth, whose rim is the rest).
    # The mouth of fear at 150 % as it was then (the preset's upper lip now holds over the
    # upper teeth, whose tips reach into the opening's lower part)
    from editor.engine.faps import FAPS
    from editor.engine.imageio import load_image

    img0 = cv2.resize(load_image(sample_face.source), None, fx=3, fy=3,
                      interpolation=cv2.INTER_CUBIC)
    big = Face.from_image(img0)
    mouth = {"raise_b_midlip": -255, "raise_b_lip_lm": -150, "raise_b_lip_rm": -150,
             "lower_t_midlip": 90, "lower_t_lip_lm": 90, "lower_t_lip_rm": 90,
             "raise_l_cornerlip": -225, "raise_r_cornerlip": -225,
             "stretch_l_cornerlip": 37.5, "stretch_r_cornerlip": 37.5}
    faps = FAPS.vector({"open_jaw": 390, **mouth, **{f"{k}_o": x for k, x in mouth.items()}})
    img, v = big.render(faps), big.deform(faps)
    inside = cv2.erode(_opening(big, v, img.shape).astype(np.uint8), np.ones((5, 5), np.uint8))
    L = _lum(img) / _skin(big)
    bright = 0
    for x in np.flatnonzero(inside.any(0)):
        rows = np.flatnonzero(inside[:, x])
        low = rows[rows > rows.min() + 0.55 * np.ptp(rows)]
        bright += int((L[low, x] > 0.85).sum())
    assert bright < 40, bright


def test_a_soft_photos_mouth_edges_are_as_soft_as_its_own():
    """On a soft photo (the sample upscaled 4x: edges ramp over 5.3 px, a blur of sigma 2.07)
    the opening is composited through the same blur (counted from 0.2 up). (1) The thin
    wedge at each corner of disgust's raised upper lip reads as a soft shadow, not a black
    tick: its darkest pixel at least 0.38 of the lips and skin around it (an inside-only fade
    drew it at 0.29 / 0.33, this code 0.55 / 0.48). (2) The compositing itself: across a
    straight edge the coverage ramps on both sides of the outline over most of the photo's
    ramp (10-90 % width at least 0.7 x it; the inside-only fade rose from 0 to 0.25 in one
    pixel, 0.43 x), and a 2 px sliver stays below 0.45 (it reached 0.53)."""
    from editor.engine.imageio import load_image
    from editor.engine.layers import _soft_edge, layer_plan
    from editor.resources import SAMPLE_FACE

    img = cv2.resize(load_image(SAMPLE_FACE), None, fx=4, fy=4, interpolation=cv2.INTER_CUBIC)
    f = Face.from_image(img)
    soft = layer_plan(f).soft
    assert soft > 4.0  # a soft photo
    vec = apply_preset("disgust", 1.0)
    v = f.deform(vec)
    L = _lum(f.render(vec))
    r = int(0.06 * f.interocular)
    for a, b in (("2.4", "2.5"), ("2.5", "2.4")):
        c, o = v[f.fdp[a]], v[f.fdp[b]]
        worst = 1.0
        for t in np.linspace(0.02, 0.12, 12):  # the corner's first 12 % towards the other
            x, y = (int(round(q)) for q in c + t * (o - c))
            local = np.median(L[y - 3 * r:y + 3 * r, x - r:x + r])
            worst = min(worst, float(L[y - r:y + r + 1, x].min() / local))
        assert worst >= 0.38, (a, worst)
    # the compositing: a straight edge (rows 20+ open) and a 2 px sliver (rows 60-61)
    hole = np.zeros((90, 40), bool)
    hole[20:50] = True
    hole[60:62] = True
    alpha = hole.astype(np.float32)
    inside = hole.astype(np.uint8)
    depth = cv2.distanceTransform(inside, cv2.DIST_L2, 3)
    rim = np.zeros((90, 40, 3), np.float32)
    got, _ = _soft_edge(np.zeros((90, 40, 3), np.uint8), (0, 0, 40, 90), hole, alpha, soft, 1.0,
                        (depth, rim))
    col = got[:, 20]
    assert col[19] > 0.15  # the edge ramps outside the outline too
    rise = np.flatnonzero(col[:35] >= 0.9)[0] - np.flatnonzero(col[:35] >= 0.1)[0]
    assert rise >= 0.7 * soft, (rise, soft)
    assert col[55:67].max() < 0.45


def test_a_soft_photos_lips_lose_teeth_strips_as_wide_as_its_blur():
    """The photo's lip triangles end on its inner-lip contour; on a soft photo the strip of
    teeth they carry along it is several pixels wide, and rides on the lips as a row of bright
    dots when the lips move over the teeth (fear's lowered upper lip on the sample at 700 px).
    Along the outline the lips lose bright structures up to soft / 2 + 2 px wide (a 4 px
    strip at the 4x sample's 5.3 px ramp; the 3 px opening of sharp photos left it), and
    nothing outside that band changes."""
    from editor.engine.layers import _clean_lip_line

    out = np.full((60, 120, 3), 150, np.uint8)  # lips
    out[30:34, 10:110] = 235  # a 4 px strip of teeth along the outline (row 34)
    poly = np.array([[10.0, 34.0], [110.0, 34.0], [110.0, 50.0], [10.0, 50.0]])
    alpha = np.zeros((60, 120), np.float32)
    alpha[35:50, 10:110] = 1.0  # the opening below
    sharp = out.copy()
    _clean_lip_line(sharp, (0, 0, 120, 60), poly, alpha, 1.0, 1.0)
    assert sharp[31, 60].max() > 200  # a sharp photo's 3x3 opening keeps a 4 px strip
    _clean_lip_line(out, (0, 0, 120, 60), poly, alpha, 1.0, 5.3)
    assert out[30:34, 20:100].max() <= 160, out[30:34, 60]
    assert (out[:24] == 150).all()  # the lips away from the outline are untouched


@pytest.mark.parametrize(("width", "least"), [(40, 0.095), (60, 0.068)])
def test_drawn_teeth_keep_their_gaps_at_a_small_face(width, least):
    """The upper teeth texture (460 px wide) shrunk to a JAFFE face's 40-60 px: the gaps
    between the teeth survive as darker columns (the luminance's mean deviation along the rows
    from its 5 px running mean, over the crowns' middle: 0.116 / 0.080 of its mean; averaged
    away before: 0.071 / 0.054, one smooth slab with a seam), and the crowns' mean light is the
    texture's (the teeth's colour is matched to the photo's on it)."""
    from editor.engine import mouth

    h = max(2, round(width * 130 / 460))
    one = np.ones(3, np.float32)
    t = mouth._tinted_at("upper_teeth", 1.0, one, (width, h))
    a = t[..., 3]
    lum = (mouth._lum(t[..., :3]) / np.maximum(a, 1e-3)).astype(np.float32)
    band = lum[int(0.35 * h):int(0.75 * h), int(0.15 * width):int(0.85 * width)]
    assert float(np.abs(band - cv2.blur(band, (5, 1))).mean() / band.mean()) >= least
    plain = cv2.resize(mouth._texture_parts()["upper_teeth"][5], (width, h),
                       interpolation=cv2.INTER_AREA)
    crowns = a > 0.9
    assert abs(mouth._lum(t[..., :3])[crowns].mean() / mouth._lum(plain[..., :3])[crowns].mean()
               - 1.0) < 0.03


def test_a_smile_shows_its_upper_teeth_towards_the_corners(jaffe_faces):
    """Drawn upper teeth in a smile reach towards the mouth's corners as real ones do: the
    share of teeth-bright pixels (over 0.55 of the cheek's light) in the outer thirds of the
    opening (landmarks re-detected on the render) of joy on five JAFFE neutrals, median >= 0.1
    (0.14 here; the real smiles of the ten women 0.18). With the lower teeth's narrow, dark
    arch the upper teeth ended in dark wedges: 0.05."""
    from editor.engine.landmarks import detect_landmarks

    def lum(im):
        return im.astype(np.float32) @ np.array([0.299, 0.587, 0.114], np.float32)

    vals = []
    for face in jaffe_faces:
        c = face.vertices[face.mesh.fdp["5.3"]]
        skin = float(np.median(lum(face.image)[int(c[1]) - 5:int(c[1]) + 5,
                                               int(c[0]) - 5:int(c[0]) + 5]))
        img = face.render(apply_preset("joy", 1.0))
        L, lm = lum(img), detect_landmarks(img).points
        mask = np.zeros(L.shape, np.uint8)
        cv2.fillPoly(mask, [np.round(lm[60:68]).astype(np.int32)], 1)
        ys, xs = np.nonzero(mask)
        t = (xs - xs.min()) / max(np.ptp(xs), 1)
        outer = (t < 0.3) | (t > 0.7)
        vals.append(float((L[ys, xs] > 0.55 * skin)[outer].mean()))
    assert float(np.median(vals)) >= 0.1, np.round(vals, 2)


def test_a_wider_smile_continues_the_photos_teeth_as_crowns(sample_face):
    """Joy at 150 % on the smiling sample (3x, so that the teeth are several pixels tall)
    raises the upper lip above the photo's own teeth: what shows there is the crowns continued
    (tooth-coloured, the gaps between teeth as thin lines), not each column's pixel under the
    photo's lip (lip shadow, pink papillae, dark embrasures) drawn upwards as stripes. In the
    upper 30 % of the opening (its middle half): mean luminance >= 0.85 of the teeth's (p90; 0.86),
    column-to-column change <= 6 grey levels on average (stripes: 0.80 and 7.4)."""
    from editor.engine.fitting import luminance

    img = cv2.resize(sample_face.image, None, fx=3, fy=3, interpolation=cv2.INTER_CUBIC)
    f = Face.from_image(img)
    res = f.render_full(f.fap_vector(apply_preset("joy", 1.5)))
    mm, L = res.mouth_mask, luminance(res.image)
    xs = np.nonzero(mm)[1]
    cols = np.arange(int(np.percentile(xs, 25)), int(np.percentile(xs, 75)))
    top = np.argmax(mm[:, cols], 0)
    h = mm.shape[0] - np.argmax(mm[::-1, cols], 0) - top
    rows = [L[t:t + max(int(0.3 * hh), 1), c] for t, hh, c in zip(top, h, cols, strict=True)]
    assert np.concatenate(rows).mean() >= 0.85 * np.percentile(L[mm], 90)
    assert np.abs(np.diff([r.mean() for r in rows])).mean() <= 6.0


def test_drawn_teeth_on_a_soft_photo_are_no_sharper_than_the_photo(sample_face):
    """The smiling sample upscaled 6x (a soft photo: its edges ramp over ~8 px) under surprise
    at 150 %: the drawn lower teeth below its own show no edge steeper than the photo's
    steepest one (Sobel, grey levels a pixel: 40.6). Drawn crisp, their gaps were black slits
    between grey blocks: 50.7 (now 33.8)."""
    from editor.engine.fitting import luminance
    from editor.engine.layers import layer_plan

    f = Face.from_image(cv2.resize(sample_face.image, None, fx=6, fy=6,
                                   interpolation=cv2.INTER_CUBIC))

    def steepest(img: np.ndarray) -> np.ndarray:
        lum = luminance(img).astype(np.float32)
        return np.hypot(cv2.Sobel(lum, cv2.CV_32F, 1, 0), cv2.Sobel(lum, cv2.CV_32F, 0, 1)) / 8

    res = f.render_full(apply_preset("surprise", 1.5))
    k = int(layer_plan(f).soft) | 1  # inside the opening, past its softened outline
    inner = cv2.erode(res.mouth_mask.astype(np.uint8), np.ones((k, k), np.uint8)) > 0
    assert inner.sum() > 1000
    assert steepest(res.image)[inner].max() <= steepest(f.image).max()


def _teeth_row_contrast(face: Face, img: np.ndarray, v: np.ndarray) -> float | None:
    """How much a row of teeth varies along itself: on the row of the opening with the most
    tooth-bright pixels (over 0.75 of the skin), the middle 60 % of its bright span, mean
    |profile - its Gaussian blur (2 px)| over its mean (teeth and the gaps between them)."""
    L = _lum(img)
    hole = _opening(face, v, img.shape)
    bright = hole & (L > 0.75 * _skin(face))
    if bright.sum() < 40:
        return None
    row = int(np.argmax(bright.sum(1)))
    cols = np.flatnonzero(bright[row])
    a, b = int(cols.min()), int(cols.max())
    k = int(0.2 * (b - a))
    a, b = a + k, b - k
    if b - a < 8:
        return None
    prof = L[row - 1:row + 2, a:b + 1].mean(0)
    smooth = cv2.GaussianBlur(prof[None].astype(np.float32), (0, 0), 2.0)[0]
    return float(np.abs(prof - smooth).mean() / prof.mean())


def test_drawn_teeth_are_separate_teeth_not_a_slab(jaffe_faces):
    """Joy at 100 and 150 % on five JAFFE faces: the drawn upper teeth vary along their row
    as separate teeth do. JAFFE's own open smiles: 0.115 (median of 16, same measure); with
    0.6 px gaps (mouth.GAP_PX before) the drawn row gave 0.053 (a smooth slab, "pasted" to
    three blind raters), with 1.5 px 0.073."""
    vals = []
    for f in jaffe_faces:
        for k in (1.0, 1.5):
            faps = apply_preset("joy", k)
            c = _teeth_row_contrast(f, f.render(faps), f.deform(faps))
            if c is not None:
                vals.append(c)
    assert len(vals) >= 6
    assert 0.065 < float(np.median(vals)) < 0.2, vals


def _opening_top(image: np.ndarray) -> float | None:
    """The light under the upper lip: across the inner lips at their middle (detected
    landmarks 62 -> 66), the rows at 0.1, 0.2 and 0.3 of the way down, each row's 75th
    percentile over +-0.06 IOD about the middle over the skin's median in a ring 0.08-0.16 IOD
    outside the outer lips; their mean. None when the lips part by less than 0.05 IOD."""
    got = _open_mouth(image)
    if got is None:
        return None
    L, p, iod, skin = got
    x0, x1 = int(p[62, 0] - 0.06 * iod), int(p[62, 0] + 0.06 * iod) + 1
    rows = [int(round(p[62, 1] + t * (p[66, 1] - p[62, 1]))) for t in (0.1, 0.2, 0.3)]
    return float(np.mean([np.percentile(L[y, x0:x1], 75) for y in rows])) / skin


def test_fear_shows_the_upper_teeth_under_the_upper_lip_as_real_open_fear():
    # JAFFE's open fear photos (16 of 32) show the upper teeth right under the upper lip, which
    # stays where it is: the top of the opening 0.92-0.99 of the skin (median per row). Fear
    # drawn with the upper lip pulled down over the teeth (lower_t_midlip +60: +0.044 IOD by
    # the landmarks, real +0.007) was a dark lens there, 0.45-0.59; held (-10): 0.93-0.99
    from conftest import jaffe_real_and_drawn

    r, d = jaffe_real_and_drawn(_opening_top, "FE", "fear")
    assert r > 0.85, r
    assert d > r - 0.12, (r, d)


def test_a_soft_photos_open_mouth_has_no_step_sharper_than_the_photos(sample_face):
    """The smiling sample upscaled 6x (its edges ramp over ~8 px) under surprise, fear and
    viseme aa at 150 %: no step between two neighbouring pixels in or around the opening is
    steeper than the photo's steepest (42 grey levels). The photo's own upper teeth (moved with
    the skull) and the drawn lower teeth were blurred up to their images' edges and stopped
    there at half their coverage: a one-pixel cut across the opening, 51-57 grey levels (the
    4K bench face: 98 -> 35 in a pixel); padded before the blur, 31-35."""
    from editor.engine.fitting import luminance

    f = Face.from_image(cv2.resize(sample_face.image, None, fx=6, fy=6,
                                   interpolation=cv2.INTER_CUBIC))
    photo = luminance(f.image).astype(np.float32)
    steepest = max(np.abs(np.diff(photo, axis=0)).max(), np.abs(np.diff(photo, axis=1)).max())
    for name in ("surprise", "fear", "viseme_aa"):
        res = f.render_full(apply_preset(name, 1.5))
        L = luminance(res.image).astype(np.float32)
        near = cv2.dilate(res.mouth_mask.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
        dy = np.abs(np.diff(L, axis=0))[near[1:] & near[:-1]].max()
        dx = np.abs(np.diff(L, axis=1))[near[:, 1:] & near[:, :-1]].max()
        assert max(dy, dx) <= steepest, (name, dy, dx, steepest)


def _cavity_profile(image: np.ndarray) -> tuple[float, float, float, float] | None:
    """An open mouth's interior by its detected inner lips (68 landmarks), relative to the
    skin's median in a ring 0.08-0.16 IOD outside the outer lips: the median luminance of its
    first 0.02 IOD inside the lips and of its pixels 0.08-0.12 IOD deep, the spread (std over
    mean) of the pixels deeper than 0.02 IOD, and the light line under the upper lip (middle
    columns, +-0.08 IOD: the brightest of the first 0.03 IOD under the inner upper lip less the
    brightest of the lip 0.01-0.04 IOD above it, median). None when the lips part by less
    than 0.12 IOD."""
    got = _open_mouth(image)
    if got is None:
        return None
    L, p, iod, skin = got
    if p[66, 1] - p[62, 1] < 0.12 * iod:
        return None
    inner = np.zeros(L.shape, np.uint8)
    cv2.fillPoly(inner, [np.round(p[60:68]).astype(np.int32)], 1)
    d = cv2.distanceTransform(inner, cv2.DIST_L2, 3) / iod
    near = float(np.median(L[(inner > 0) & (d < 0.02)])) / skin
    deep = float(np.median(L[(d >= 0.08) & (d < 0.12)])) / skin
    core = L[d > 0.02]
    yu = p[62, 1]
    bumps = [(L[int(yu):int(yu + 0.03 * iod) + 1, x].max()
              - L[int(yu - 0.04 * iod):int(yu - 0.01 * iod), x].max()) / skin
             for x in range(int(p[62, 0] - 0.08 * iod), int(p[62, 0] + 0.08 * iod) + 1)]
    return near, deep, float(core.std() / core.mean()), float(np.median(bumps))


def test_a_large_faces_open_mouth_darkens_into_its_back_as_real_ones():
    """JAFFE women upscaled 4x (edges ramping over ~4 px), surprise at 150 %, measured as on
    their real wide-open surprise photos upscaled alike (median of 21: 0.16 of the skin in the
    first 0.02 IOD inside the lips, 0.04 at 0.08-0.12 IOD deep, spread 1.02, light line under
    the upper lip -0.12). On KA, KL, KM drawn as one flat dark fill (0.12-0.14 deep, spread
    0.77-0.87) with a sliver of lit upper teeth along the lip (0.40-0.74: a drawn outline);
    now the back darkens with depth, the tongue is lit at its front only, the sliver stays in
    the lip's shadow: 0.09-0.10 deep, spread 0.82-1.01, line 0.13-0.69. (The first 0.02 IOD
    stays at 0.24-0.29, 0.27-0.30 before: the tongue's lit front and the lower teeth.)"""
    got = []
    for ne in jaffe_images("*.NE1.*.tiff")[:3]:
        img = cv2.resize(load_image(ne), None, fx=4, fy=4, interpolation=cv2.INTER_CUBIC)
        m = _cavity_profile(Face.from_image(img, own_expression=False)
                            .render(apply_preset("surprise", 1.5), sharp=True))
        if m is not None:
            got.append(m)
    if len(got) < 3:
        pytest.skip("../shared/data/jaffe is not available")
    near, deep, spread, line = (float(np.median(c)) for c in zip(*got, strict=True))
    assert deep < 0.105, got
    assert spread > 0.86, got
    assert line < 0.35, got


def test_a_soft_photos_lips_lose_their_photos_lip_line_as_wide_as_its_ramp():
    """A JAFFE face upscaled 4x carries its photo's lip line (teeth between parted lips, 1-2
    px there) as a light band 5-8 px wide along the opened lips; left on them it drew a light
    outline around the opening. At the 4x sample's ramp (5.3 px) a 6 px strip goes (an
    opening of soft / 2 + 2 px kept it: LIP_LINE_SOFT 0.5 before)."""
    from editor.engine.layers import _clean_lip_line

    out = np.full((60, 120, 3), 150, np.uint8)  # lips
    out[28:34, 10:110] = 235  # a 6 px strip of teeth along the outline (row 34)
    poly = np.array([[10.0, 34.0], [110.0, 34.0], [110.0, 50.0], [10.0, 50.0]])
    alpha = np.zeros((60, 120), np.float32)
    alpha[35:50, 10:110] = 1.0  # the opening below
    _clean_lip_line(out, (0, 0, 120, 60), poly, alpha, 1.0, 5.3)
    assert out[28:34, 20:100].max() <= 160, out[26:36, 60]
    assert (out[:18] == 150).all()  # the lips away from the outline are untouched


def _darkest_hue(img: np.ndarray, m: np.ndarray, q: float = 0.05) -> np.ndarray:
    """Colour over luminance (3,) of the darkest ``q`` of the pixels under mask ``m``."""
    px = img[m].astype(np.float64)
    lum = px @ LUM.astype(np.float64)
    c = px[np.argsort(lum)[:max(3, int(q * len(px)))]].mean(0)
    return c / float(c @ LUM.astype(np.float64))


@pytest.mark.parametrize("preset", ["surprise", "viseme_aa"])
def test_an_open_mouths_dark_interior_takes_the_photos_own_hue(sample_face, preset):
    # light at the back of an open mouth has bounced off its reddish walls: the sample's own
    # dark interior (its smile's buccal corridor: the darkest 5 % of its opening) is a deep
    # red-brown, colour over luminance 1.83 0.72 0.29. The drawn cavity took CAVITY_RGB
    # desaturated by the skin's saturation and the lips' own pink darkened: a purple-black,
    # 1.44 0.82 0.79 (aa 1.45 0.81 0.79); with the skin's hue raised to the bounces (mouth.
    # CAVITY_BOUNCES, INNER_BOUNCES) 1.65 0.77 0.47 (aa 1.67 0.77 0.44)
    f = sample_face
    own = _darkest_hue(f.image, _opening(f, f.vertices, f.image.shape))
    faps = apply_preset(preset, 1.0)
    img = f.render(faps)
    drawn = _darkest_hue(img, _opening(f, f.deform(faps), img.shape))
    assert drawn[0] - own[0] > -0.3, (drawn, own)
    assert drawn[2] - own[2] < 0.3, (drawn, own)


def test_a_grey_photos_cavity_stays_grey():
    from editor.engine.mouth import _LUM, CAVITY_RGB, cavity_hue
    assert np.allclose(cavity_hue(np.array([120.0, 120.0, 120.0])), 1.0)
    warm = cavity_hue(np.array([213.0, 177.0, 152.0]))
    assert abs(float(warm @ _LUM) - 1.0) < 1e-6 and warm[0] > 1.8 and warm[2] < 0.3
    assert float(_LUM @ CAVITY_RGB) > 0
