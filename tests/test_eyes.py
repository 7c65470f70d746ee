"""Eyes in expressions: raised lids uncover the eyeball, lids follow vertical gaze, closed lids
show one clean lash line (issue "Expressions that read as what they name", item 3); on soft
photos (large faces) the eye and mouth layers ramp their edges as the photo does."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from editor.core import Face
from editor.engine.deform import deform_points

LUM = np.array([0.299, 0.587, 0.114], np.float32)
EYES = (("eye_l", "iris_left"), ("eye_r", "iris_right"))


def _lum(img: np.ndarray) -> np.ndarray:
    return img.astype(np.float32) @ LUM


def _mask(shape, poly: np.ndarray) -> np.ndarray:
    m = np.zeros(shape[:2], np.uint8)
    cv2.fillPoly(m, [np.round(poly * 16).astype(np.int32)], 1, cv2.LINE_8, 4)
    return m.astype(bool)


def _upper(poly: np.ndarray) -> np.ndarray:
    return poly[[0, 1, 2, 3, 4, 5, 6]]


def _lower(poly: np.ndarray) -> np.ndarray:
    return poly[[0, 11, 10, 9, 8, 7, 6]]


def _lid_y(lid: np.ndarray, x: np.ndarray | float) -> np.ndarray:
    o = np.argsort(lid[:, 0])
    return np.interp(x, lid[o, 0], lid[o, 1])


def _sclera_lum(face: Face, name: str) -> float:
    """Luminance of the photo's white of the eye: the bright end of the neutral opening."""
    op = _mask(face.image.shape, face.vertices[face.mesh.holes[name]])
    op = cv2.erode(op.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    return float(np.percentile(_lum(face.image)[op], 90))


def _eyeball(lum: np.ndarray, sclera: float, iris: float) -> np.ndarray:
    """White-like (at least 0.7 of the sclera) or iris-like pixels."""
    return (lum >= 0.7 * sclera) | (lum <= iris + (sclera - iris) / 3.0)


@pytest.fixture(scope="module")
def faces(sample_neutral, jaffe_faces):
    return [sample_neutral, *jaffe_faces[:3]]


@pytest.fixture(scope="module")
def big_faces(sample_neutral, jaffe_faces):
    """The sample face and three JAFFE faces enlarged to portrait size (eyes 50-75 px wide):
    at 256 px a raised lid uncovers one or two rows only."""
    out = [Face.from_image(cv2.resize(sample_neutral.image, None, fx=2, fy=2,
                                      interpolation=cv2.INTER_CUBIC), own_expression=False)]
    for f in jaffe_faces[:3]:
        out.append(Face.from_image(cv2.resize(f.image, None, fx=3, fy=3,
                                              interpolation=cv2.INTER_CUBIC),
                                   own_expression=False))
    return out


def test_raised_upper_lids_uncover_white_and_iris_not_lid_skin(big_faces):
    """What a raised upper lid uncovers is the eyeball (between the bands the lid carries with
    it, its lashes' lower half and their shadow half an iris radius deep, at the neutral and at
    the raised lid): beside the iris bright like the photo's sclera and without
    a second dark line, over the iris as dark as the iris; and the opening shows more white
    than the photo's."""
    faps = {19: -300, 20: -300}
    beside_n = over_n = 0
    for face in big_faces:
        img, v = face.render(faps), face.deform(faps)
        lum, photo_lum = _lum(img), _lum(face.image)
        yy, xx = np.mgrid[0:img.shape[0], 0:img.shape[1]]
        for name, iris_name in EYES:
            iris = getattr(face.landmarks, iris_name)
            hole_new, hole_old = v[face.mesh.holes[name]], face.vertices[face.mesh.holes[name]]
            new = _mask(img.shape, hole_new)
            old = _mask(img.shape, hole_old)
            # (the band each upper lid carries: half an iris radius under it)
            band = max(1.0, 0.5 * iris.r)
            uncovered = (new & (yy < _lid_y(_upper(hole_old), xx) + band - 0.5)
                         & (yy > _lid_y(_upper(hole_new), xx) + band))
            sclera = _sclera_lum(face, name)
            core = old & (np.hypot(xx - iris.cx, yy - iris.cy) <= 0.7 * iris.r)
            iris_l = float(np.median(photo_lum[core]))
            beside = uncovered & (np.abs(xx - iris.cx) > 1.1 * iris.r)
            over = uncovered & (np.hypot(xx - iris.cx, yy - iris.cy) < 0.9 * iris.r)
            if beside.sum() >= 3:
                got = lum[beside]
                assert got.mean() > 0.6 * sclera, (name, got, sclera)
                assert (got < 0.5 * sclera).mean() <= 0.2, (name, got, sclera)
                beside_n += 1
            if over.sum() >= 3:
                got = lum[over].mean()
                assert got < iris_l + 0.35 * (sclera - iris_l), (name, got, iris_l, sclera)
                over_n += 1
            # more eyeball shows: white- or iris-like pixels in the opening
            assert (_eyeball(lum, sclera, iris_l)[new].sum()
                    > _eyeball(photo_lum, sclera, iris_l)[old].sum()), name
    assert beside_n >= 4 and over_n >= 4, (beside_n, over_n)


def test_raised_lid_profile_beside_the_iris(big_faces):
    """Luminance down a column through the upper lid next to the iris (the lid vertex nearest
    the middle that is clear of the iris): in the photo, dark lid margin then the white;
    rendered with the lid raised, the dark run of the lid margin stays thin (the lashes are
    not stretched into a band over the uncovered eye)."""
    for face in big_faces[1:]:
        faps = {19: -300, 20: -300}
        img, v = face.render(faps), face.deform(faps)
        lum, plum = _lum(img), _lum(face.image)
        for name, iris_name in EYES:
            iris = getattr(face.landmarks, iris_name)
            hole = face.mesh.holes[name]
            # u2/u4 with its lower partner d2/d4 (loop order c0 u1..u5 c1 d5..d1)
            cand = [(i, j) for i, j in ((2, 10), (4, 8), (1, 11), (5, 7))
                    if abs(face.vertices[hole[i], 0] - iris.cx) > 1.2 * iris.r]
            assert cand, name
            i, j = cand[0]
            x = int(round(v[hole[i], 0]))
            y_new, y_old = v[hole[i], 1], face.vertices[hole[i], 1]
            y_low = v[hole[j], 1]
            assert y_old - y_new > 1.0
            col = lum[:, x - 1:x + 2].mean(1)
            pcol = plum[:, x - 1:x + 2].mean(1)
            thr = 0.5 * (pcol[int(y_old) - 8:int(y_old) - 3].mean() + pcol[int(y_old):int(
                y_low)].min())
            # dark pixels from just above the lid down to the lower lid: the lid margin's own
            # (moved up with it), not a second band of lashes pulled over the white
            dark = int((col[int(y_new) - 4:int(y_low)] < thr).sum())
            pdark = int((pcol[int(y_old) - 4:int(y_low)] < thr).sum())
            assert dark <= pdark + 1, (name, dark, pdark)


def test_pitch_moves_the_upper_lid_with_the_iris(sample_neutral, jaffe_faces):
    for face in (sample_neutral, jaffe_faces[0]):
        plan = face.plan
        V = plan.n_vertices
        ey = plan.frame_rot[:, 1]
        for val in (30000, -30000):
            p = deform_points(plan, face.fap_vector({25: val, 26: val})) - plan.neutral
            for k, name in enumerate(("eye_l", "eye_r")):
                iris = float(p[V + k] @ ey)
                lid = float(p[face.mesh.holes[name][3]] @ ey)
                low = float(p[face.mesh.holes[name][9]] @ ey)
                if val > 0:  # looking down: the lid comes down as far as the iris
                    assert iris > 1.0 and abs(lid - iris) < 0.15 * iris, (name, lid, iris)
                    assert 0.0 < low < 0.5 * iris
                else:  # looking up: the lid goes up by about half of it
                    assert iris < -1.0 and 0.3 * iris > lid > 0.8 * iris, (name, lid, iris)
        # a closed lid stays closed whatever the eyeball does
        shut = {19: 1080, 20: 1080, 21: 600, 22: 600}
        a = deform_points(plan, face.fap_vector(shut))
        b = deform_points(plan, face.fap_vector({**shut, 25: 30000, 26: -30000}))
        assert np.abs(a[:V] - b[:V]).max() < 1e-4


def test_looking_down_leaves_no_white_above_the_iris(jaffe_faces):
    for face in jaffe_faces[:3]:
        faps = {25: 30000, 26: 30000}
        img = face.render(faps)
        v, extra = face.deform_all(faps)
        lum = _lum(img)
        for k, (name, _iris_name) in enumerate(EYES):
            sclera = _sclera_lum(face, name)
            cx, cy = extra["3.5" if k == 0 else "3.6"]
            r = getattr(face.landmarks, _iris_name).r
            # the opening one pixel clear of the lids, as _sclera_lum reads it: the polygon's
            # edge row is the lid margin (skin blended with the eyeball; JAFFE KL and KM with
            # MediaPipe's lids: 1-2 such pixels of lum 113-142 under a lid of that brightness,
            # against a sclera of 142-177), not white showing above the iris
            op = _mask(img.shape, v[face.mesh.holes[name]])
            op = cv2.erode(op.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
            ys, xs = np.mgrid[0:img.shape[0], 0:img.shape[1]]
            above = op & (np.abs(xs - cx) <= 0.5 * r) & (ys < cy - 0.3 * r)
            assert above.sum() >= 5, (name, above.sum())  # there is something to look at
            assert not (above & (lum > 0.75 * sclera)).any(), name


def _closed(face: Face):
    faps = {19: 1080, 20: 1080, 21: 600, 22: 600}
    return face.render(faps), face.deform(faps)


def test_closed_lids_show_skin_and_one_dark_lash_line(faces):
    for face in faces:
        img, v = _closed(face)
        lum = _lum(img)
        for name, iris_name in EYES:
            iris = getattr(face.landmarks, iris_name)
            hole = v[face.mesh.holes[name]]
            up, lo = _upper(hole), _lower(hole)
            x0, x1 = up[0, 0], up[-1, 0]
            xs = np.arange(int(np.ceil(x0 + 0.2 * (x1 - x0))), int(x1 - 0.2 * (x1 - x0)) + 1)
            line = _lid_y(up, xs) + 0.25 * (_lid_y(lo, xs) - _lid_y(up, xs))
            # skin: the photo's lid a little above the neutral lid line
            n_up = _upper(face.vertices[face.mesh.holes[name]])
            ref = float(np.median(_lum(face.image)[
                np.rint(_lid_y(n_up, xs) - 1.5 * iris.r).astype(int), xs]))
            dark, skin_above, skin_below = [], [], []
            for x, y in zip(xs, line, strict=True):
                yi = int(round(y))
                dark.append(lum[yi - 2:yi + 3, x].min())
                skin_above.append(lum[int(round(y - 0.8 * iris.r - 2)), x])
                skin_below.append(lum[int(round(y + 0.8 * iris.r + 2)), x])
            dark = np.array(dark)
            # a continuous dark line along the lids' meeting line
            assert (dark < 0.6 * ref).mean() >= 0.9, (name, dark, ref)
            # thin: skin a little above and below it (not a smear of lashes or iris)
            assert np.median(skin_above) > 0.7 * ref, (name, skin_above, ref)
            assert np.median(skin_below) > 0.7 * ref, (name, skin_below, ref)


def test_a_closing_upper_lid_meets_the_lower_lid_all_along(faces):
    """Closed (FAP 19/20 at 1080 IRISD), every point of the upper lid's margin lies within
    0.024 IOD of its lower partner; at 500 its sides move at least 0.9 x as far as the skin
    just above them (now 1.05-1.37 x). The margin's sides once moved by ~0.7 of the lid's
    parabola (a tent in y took them down): closed, they stayed 0.030-0.038 IOD above the lower
    lid (the lash line a wavy W), and the ones beside the inner corner moved less than the skin
    above them (0.65-0.71 x)."""
    for face in faces:
        n = face.mesh.index
        frame = face.frame.to_frame
        V = frame(face.deform({19: 1080, 20: 1080}).astype(np.float64))
        half = frame(face.deform({19: 500, 20: 500}).astype(np.float64))
        V0 = frame(face.deform(None).astype(np.float64))
        for s in "lr":
            gaps = [V[n(f"eye_{s}_d{k}"), 1] - V[n(f"eye_{s}_u{k}"), 1] for k in range(1, 6)]
            assert max(gaps) <= 0.024 * face.interocular, (s, np.round(gaps, 2))
            for k in (1, 5):
                lid = half[n(f"eye_{s}_u{k}"), 1] - V0[n(f"eye_{s}_u{k}"), 1]
                ring = half[n(f"eyering_{s}_u{k}"), 1] - V0[n(f"eyering_{s}_u{k}"), 1]
                assert lid >= 0.9 * ring > 0, (s, k, lid, ring)


def test_zero_vector_is_the_photo(faces):
    for face in faces:
        assert np.array_equal(face.render({}), face.image)


def test_a_raised_lid_carries_its_lash_band(big_faces):
    """Down a column beside the iris, half an iris radius under the raised upper lid (FAPs 19/20
    at -300) shows what the photo shows under its own lid (the lashes' lower half, which the
    mesh's lid line leaves inside the opening, and their shadow), moved up with the lid: mean
    difference at most 0.13 of the photo's brightest there, 0.32 in any column (now 0.10 and
    0.25). Painting the band over with white, as before, left the lashes cut in half by a
    sticker-like white edge: 0.16 and 0.46."""
    errs = []
    for face in big_faces:
        faps = {19: -300, 20: -300}
        lum, plum = _lum(face.render(faps)), _lum(face.image)
        v = face.deform(faps)
        for name, iris_name in EYES:
            iris = getattr(face.landmarks, iris_name)
            hole = face.mesh.holes[name]
            for i in (1, 2, 4, 5):  # u1, u2, u4, u5
                if abs(face.vertices[hole[i], 0] - iris.cx) <= 1.2 * iris.r:
                    continue  # over the iris
                ks = np.arange(0.0, 0.5 * iris.r, 0.5)
                a = cv2.remap(lum.astype(np.float32), np.full((1, len(ks)), v[hole[i], 0],
                                                              np.float32),
                              (v[hole[i], 1] + ks)[None].astype(np.float32), cv2.INTER_LINEAR)[0]
                b = cv2.remap(plum.astype(np.float32),
                              np.full((1, len(ks)), face.vertices[hole[i], 0], np.float32),
                              (face.vertices[hole[i], 1] + ks)[None].astype(np.float32),
                              cv2.INTER_LINEAR)[0]
                errs.append(float(np.mean(np.abs(a - b)) / max(float(b.max()), 1.0)))
    assert len(errs) >= 8
    assert np.mean(errs) <= 0.13 and max(errs) <= 0.32, np.round(errs, 3)


def test_uncovered_white_is_as_bright_as_the_photos_sclera(big_faces):
    """Wide-open lids (surprise at 150 %) uncover the eyeball: the new white is the photo's
    brightest sclera, barely shaded (a lit ball), not a grey band (median over the new pixels
    outside the iris and outside the band each lid carries - half an iris radius under the
    upper lid, a quarter above the lower one -, mean over the eyes: 0.85 of the photo's bright
    sclera; 0.80 with a former reference and ball shade)."""
    from editor.formats.presets import apply_preset

    vec = apply_preset("surprise", 1.5)
    ratios = []
    for face in big_faces:
        v = face.deform(vec)
        lum = _lum(face.render(vec))
        for name in ("eye_l", "eye_r"):
            sc = _sclera_lum(face, name)
            hole = v[face.mesh.holes[name]]
            r = getattr(face.landmarks, "iris_left" if name == "eye_l" else "iris_right").r
            yy, xx = np.mgrid[0:lum.shape[0], 0:lum.shape[1]]
            old = face.vertices[face.mesh.holes[name]]

            def clear(poly, m=lum.shape, xx=xx, yy=yy, r=r):  # the opening minus its bands
                return (_mask(m, poly) & (yy > _lid_y(_upper(poly), xx) + 0.5 * r)
                        & (yy < _lid_y(_lower(poly), xx) - 0.25 * r))
            new = clear(hole) & ~clear(old)
            px = lum[new]
            px = px[px > 0.5 * sc]  # not the iris
            if len(px) > 20:
                ratios.append(float(np.median(px)) / sc)
    assert len(ratios) >= 6
    assert np.mean(ratios) >= 0.82, ratios


# --------------------------------------------------------------- soft photos (large faces)
@pytest.fixture(scope="module")
def soft_face(sample_face):
    """The sample upscaled 4x (cubic): a large face whose edges span several pixels, as on a
    defocused or upscaled portrait."""
    img = cv2.resize(sample_face.image, None, fx=4, fy=4, interpolation=cv2.INTER_CUBIC)
    return Face.from_image(img)


def _steps(img: np.ndarray, poly: np.ndarray) -> float:
    """99.5th percentile of the luminance step between neighbouring pixels in and around an
    eye opening (grown by 2 px): how hard its sharpest edges are."""
    g = _lum(img)
    m = cv2.dilate(_mask(img.shape, poly).astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    dx = np.abs(np.diff(g, axis=1))[m[:, 1:] & m[:, :-1]]
    dy = np.abs(np.diff(g, axis=0))[m[1:] & m[:-1]]
    return float(np.percentile(np.r_[dx, dy], 99.5))


def test_edge_ramp_follows_the_photos_softness(sample_face, soft_face):
    """The eye layers' edge ramp is measured from the irises' edges: one pixel (today's
    edges, renders unchanged) on the sharp sample, several on the same face upscaled 4x."""
    from editor.engine.layers import layer_plan

    assert layer_plan(sample_face).soft == 1.0
    assert 3.0 <= layer_plan(soft_face).soft <= 8.0


def test_eyeball_edges_are_as_soft_as_the_photos(soft_face):
    """On a soft photo the uncovered eyeball (surprise at 150 %: lids wide open) has no edge
    harder than the photo's own eye: the iris's limbus, the white's hand-over from the photo
    to the continued ball and the lids' edges ramp over the photo's edge width. With the
    one-pixel edges of a sharp photo the sharpest steps were twice the photo's."""
    from editor.formats.presets import apply_preset

    f = soft_face
    vec = apply_preset("surprise", 1.5)
    v, out = f.deform(vec), f.render(vec)
    for name, _ in EYES:
        hole = f.mesh.holes[name]
        assert _steps(out, v[hole]) <= 1.4 * _steps(f.image, f.vertices[hole]), name


@pytest.mark.parametrize("name", ["joy", "fear"])
def test_mouth_edges_are_as_soft_as_the_photos(soft_face, name):
    """On the same soft face the mouth's interior fades in inside the lips and the photo's own
    teeth ramp into the cavity: no edge in or around the opening is much harder than the
    photo's own open smile (99.5th percentile step: photo 23, joy 31, fear 57; with one-pixel
    edges joy 35, fear 124 along the upper teeth)."""
    from editor.formats.presets import apply_preset

    f = soft_face
    hole = f.mesh.holes["mouth"]
    photo = _steps(f.image, f.vertices[hole])
    vec = apply_preset(name, 1.0)
    limit = {"joy": 1.4, "fear": 3.0}[name]
    assert _steps(f.render(vec), f.deform(vec)[hole]) <= limit * photo


def test_edge_ramp_is_capped_by_the_iris(soft_face):
    """A badly defocused photo (the 4x face blurred further) measures very wide edges; the
    ramp stays at most half an iris radius, so no eye or mouth is faded away."""
    from editor.engine.gaze import edge_ramp
    from editor.engine.layers import layer_plan

    f = Face.from_image(cv2.GaussianBlur(soft_face.image, (0, 0), 10.0))
    lp = layer_plan(f)
    r = 0.5 * (lp.eyes["eye_l"].r0 + lp.eyes["eye_r"].r0)
    # the edges ask for a ramp wider than half an iris radius ...
    assert edge_ramp([*lp.eyes["eye_l"].widths, *lp.eyes["eye_r"].widths]) > 0.5 * r
    assert 1.0 < lp.soft <= 0.5 * r + 1e-9  # ... the ramp stops there


def _lid_edge_roughness(face: Face, faps) -> float:
    """Mean |second difference| (px) along x of the upper lid's edge height over the iris (the
    middle 1.6 radii), both eyes: per column, where the luminance crosses halfway from the skin
    3 px above the deformed lid line down to the darkest pixel within 3 px below it."""
    lum, v = _lum(face.render(faps)), face.deform(faps)
    out = []
    for name, iris_name in EYES:
        iris = getattr(face.landmarks, iris_name)
        up = _upper(v[face.mesh.holes[name]])
        xs = np.arange(int(np.ceil(iris.cx - 0.8 * iris.r)), int(iris.cx + 0.8 * iris.r) + 1)
        edges = []
        for x, y in zip(xs, _lid_y(up, xs), strict=True):
            y0 = int(np.floor(y)) - 3
            col = lum[y0:y0 + 7, x]
            mid = 0.5 * (col[0] + col.min())
            k = int(np.argmax(col < mid))
            edges.append(y0 + k - 1 + (col[k - 1] - mid) / max(col[k - 1] - col[k], 1e-6))
        out.append(float(np.abs(np.diff(edges, 2)).mean()))
    return float(np.mean(out))


def test_raised_and_lowered_lids_keep_one_clean_lash_line(jaffe_faces):
    """On sharp photos (JAFFE, eyes ~25 px wide) the upper lid's edge over the iris stays as
    smooth as the photo's under every emotion preset at 100 and 150 %: mean roughness (the
    edge height's second difference) at most 1.25 x the photos' (now 0.96 x). The lid's
    partly covered outline pixels continued with the light skin around the opening, against
    the dark lash band the eyeball layer carries, read as stitches along the lash line: 1.7 x
    (KL's anger 0.83 px against her photo's 0.19)."""
    from editor.formats.presets import apply_preset

    emotions = ("joy", "sadness", "surprise", "anger", "disgust", "fear")
    renders, photos = [], []
    for face in jaffe_faces:
        photos.append(_lid_edge_roughness(face, {}))
        renders += [_lid_edge_roughness(face, apply_preset(e, k)) for e in emotions
                    for k in (1.0, 1.5)]
    assert np.mean(renders) <= 1.25 * np.mean(photos), (np.mean(renders), np.mean(photos))


def test_raised_lids_keep_one_clean_lash_line_on_a_small_sharp_face(sample_neutral):
    """The same on the sample at 0.6 x (eyes ~15 px wide, a sharp photo): the renders' mean
    lid-edge roughness at most 1.5 x the photo's (now 1.2 x; the skin-continued outline 1.8 x)."""
    from editor.formats.presets import apply_preset

    img = cv2.resize(sample_neutral.image, None, fx=0.6, fy=0.6, interpolation=cv2.INTER_AREA)
    face = Face.from_image(img, own_expression=False)
    renders = [_lid_edge_roughness(face, apply_preset(e, k))
               for e in ("joy", "sadness", "surprise", "anger", "disgust", "fear")
               for k in (1.0, 1.5)]
    assert np.mean(renders) <= 1.5 * _lid_edge_roughness(face, {})


def _under_iris_darkening(face: Face, vec) -> float:
    """The most the render darkens (grey levels) a pixel just under an iris: |x - cx| within
    0.6 radii, from the iris's bottom edge 2 px down (the photo shows the lower lid there)."""
    lum, photo = _lum(face.render(vec)), _lum(face.image)
    out = []
    for _name, iris_name in EYES:
        it = getattr(face.landmarks, iris_name)
        x0, x1 = int(np.floor(it.cx - 0.6 * it.r)), int(np.ceil(it.cx + 0.6 * it.r))
        y0, y1 = int(np.floor(it.cy + it.r - 0.5)), int(np.ceil(it.cy + it.r + 2))
        out.append(float((photo[y0:y1, x0:x1] - lum[y0:y1, x0:x1]).max()))
    return max(out)


def test_a_lower_lid_barely_lowered_shows_no_speck_of_iris(sample_face):
    """Fear lowers the sample's lower lid by a fraction of a pixel in its middle: the iris its
    photo hides there fades in over the lid's first pixel of motion (as the white does), so no
    dark speck hangs under the iris: at most 30 grey levels darker than the photo there (a
    drawn speck: 61; now 14)."""
    from editor.formats.presets import apply_preset

    for k in (1.0, 1.5):
        assert _under_iris_darkening(sample_face, apply_preset("fear", k)) <= 30.0


def _lower_lid_edge(image: np.ndarray, lm=None) -> float:
    """The dark eye's lower edge below the corners' chord at 0.4, 0.5 and 0.6 of the eye's
    width (inter-ocular distances, mean of both eyes): per column, the first row under the
    chord (from 0.03 IOD above it) lighter than halfway from the eye's darkest 5 % to the skin
    0.2-0.28 IOD below. ``lm``: landmarks to measure in (default: detected on ``image``)."""
    from editor.engine.landmarks import detect_landmarks

    lm = lm or detect_landmarks(image)
    p, iod = lm.points.astype(np.float64), lm.interocular
    g = cv2.GaussianBlur(_lum(image), (0, 0), 0.7)
    edges = []
    for a, b in ((39, 36), (42, 45)):  # inner -> outer corner
        pa, pb = p[a], p[b]
        box = g[int(min(pa[1], pb[1]) - 0.08 * iod):int(max(pa[1], pb[1]) + 0.06 * iod),
                int(min(pa[0], pb[0])):int(max(pa[0], pb[0]))]
        dark = np.percentile(box, 5)
        for t in (0.4, 0.5, 0.6):
            q = pa + t * (pb - pa)
            x = int(round(q[0]))
            col = g[:, x - 1:x + 2].mean(1)
            skin = np.median(col[int(q[1] + 0.2 * iod):int(q[1] + 0.28 * iod)])
            below = col[int(round(q[1] - 0.03 * iod)):] >= dark + 0.5 * (skin - dark)
            edges.append((int(round(q[1] - 0.03 * iod)) + int(below.argmax()) - q[1]) / iod)
    return float(np.mean(edges))


def test_jaffe_smile_narrows_the_eyes_from_below_as_real_ones():
    # JAFFE's ten women: how far the dark eye's lower edge rises from each woman's neutral
    # photos to her real smiles (31 photos): median 0.015 IOD. Joy drawn on the neutral photos
    # rose 0.035 with the lower lids at 125 and the cheeks at 150 (the skin pushed up over the
    # eye, lighter than real: a squint, not a smile); 0.020 at 60 / 100
    from conftest import jaffe_images

    from editor.engine.imageio import load_image
    from editor.engine.landmarks import detect_landmarks
    from editor.formats.presets import apply_preset

    real, drawn = [], []
    for ne in jaffe_images("*.NE1.*.tiff"):
        smiles = jaffe_images(f"{ne.name[:2]}.HA*.tiff")
        if not smiles:
            continue
        n0 = float(np.mean([_lower_lid_edge(load_image(p))
                            for p in jaffe_images(f"{ne.name[:2]}.NE*.tiff")]))
        real += [n0 - _lower_lid_edge(load_image(p)) for p in smiles]
        f = Face.from_image(ne, own_expression=False)
        lm = detect_landmarks(f.image)
        joy = f.render(apply_preset("joy"))
        drawn.append(_lower_lid_edge(f.image, lm) - _lower_lid_edge(joy, lm))
    if len(drawn) < 8:
        pytest.skip("../shared/data/jaffe is not available")
    r, d = float(np.median(real)), float(np.median(drawn))
    assert 0.5 * r < d < 1.5 * r, (r, d)


#: stable points (inner eye corners, nose bridge and base) that align a photo to its neutral
_STABLE = [39, 42, 27, 28, 29, 30, 31, 35]


def _upper_lid_edges(image: np.ndarray, ref: np.ndarray) -> float:
    """The dark eye's upper edge at 0.4, 0.55, 0.7 and 0.85 of the eye's width (inner -> outer
    corner, mean of both eyes) in inter-ocular distances under the corners' chord of ``ref``
    (the neutral photo's landmarks), after aligning ``image`` to ``ref`` by a similarity on
    :data:`_STABLE`: per column, from the darkest row near the chord up to the first row lighter
    than halfway from the eye's darkest 5 % to the skin 0.14-0.2 IOD above the chord."""
    from editor.engine.landmarks import detect_landmarks

    p = detect_landmarks(image).points.astype(np.float32)
    m, _ = cv2.estimateAffinePartial2D(p[_STABLE], ref[_STABLE].astype(np.float32))
    g = cv2.warpAffine(_lum(image), m, (image.shape[1], image.shape[0]),
                       borderMode=cv2.BORDER_REPLICATE)
    g = cv2.GaussianBlur(g, (0, 0), 0.7)
    iod = float(np.linalg.norm(ref[36:42].mean(0) - ref[42:48].mean(0)))
    edges = []
    for a, b in ((39, 36), (42, 45)):
        pa, pb = ref[a].astype(np.float64), ref[b].astype(np.float64)
        box = g[int(min(pa[1], pb[1]) - 0.08 * iod):int(max(pa[1], pb[1]) + 0.06 * iod),
                int(min(pa[0], pb[0])):int(max(pa[0], pb[0]))]
        dark = np.percentile(box, 5)
        for t in (0.4, 0.55, 0.7, 0.85):
            q = pa + t * (pb - pa)
            x, yq = int(round(q[0])), int(round(q[1]))
            col = g[:, x - 1:x + 2].mean(1)
            skin = np.median(col[int(q[1] - 0.2 * iod):int(q[1] - 0.14 * iod)])
            lo = yq - int(0.06 * iod)
            start = lo + int(np.argmin(col[lo:yq + int(0.04 * iod) + 1]))
            above = col[start::-1] >= dark + 0.5 * (skin - dark)
            edges.append((start - int(above.argmax()) - q[1]) / iod)
    return float(np.mean(edges))


@pytest.mark.parametrize("emotion,code", [("joy", "HA"), ("disgust", "DI")])
def test_jaffe_expression_lowers_the_upper_lids_as_real_ones(emotion, code):
    # JAFFE's ten women, each photo aligned to her neutral on the inner eye corners and the
    # nose: the dark eye's upper edge over its middle and outer part drops a median 0.015 IOD
    # from the neutral photo to her real smiles (31). Joy drawn with the upper lids at 60
    # dropped it 0.005 (the eyes kept their neutral opening from above; the blind raters:
    # "the eyes are unchanged"); at 120, as far as real smiles (0.0137 against 0.0134).
    # Disgust (29 photos): 0.033; its fitted 125 dropped it 0.021 (0.63 x), the eyes open
    # from above beside the real squint; at 220 0.025 (0.76 x)
    from conftest import jaffe_images

    from editor.engine.imageio import load_image
    from editor.engine.landmarks import detect_landmarks
    from editor.formats.presets import apply_preset

    real, drawn = [], []
    for ne in jaffe_images("*.NE1.*.tiff"):
        smiles = jaffe_images(f"{ne.name[:2]}.{code}*.tiff")
        if not smiles:
            continue
        f = Face.from_image(ne, own_expression=False)
        ref = detect_landmarks(f.image).points
        n0 = _upper_lid_edges(f.image, ref)
        real.append(float(np.median([_upper_lid_edges(load_image(p), ref) for p in smiles]))
                    - n0)
        drawn.append(_upper_lid_edges(f.render(apply_preset(emotion)), ref) - n0)
    if len(drawn) < 8:
        pytest.skip("../shared/data/jaffe is not available")
    r, d = float(np.median(real)), float(np.median(drawn))
    assert r > 0.005, r  # (the measure sees the real lids come down)
    assert 0.7 * r < d < 1.5 * r, (emotion, r, d)



def test_soft_irises_are_refined_to_their_own_edges():
    """On a soft photo the iris circle is refined from edges ramping over ~10 px, where a bump
    of the white's texture steeper than the limbus won the edge search: on the 4K bench face
    (the sample upscaled, IOD 468 px) the right iris came out 52 px against the left's 44,
    its limbus read 4 and 20 px wide, and its outer band, the photo's white, was drawn as a
    light ring inside the iris. Both irises now agree in size, each side's limbus about as
    soft as the other's."""
    from editor import bench
    from editor.bench_render import Helpers, _face_wide
    from editor.engine.layers import layer_plan

    hp = Helpers(emit=print, face_at=bench._face_at, time_pair=None,
                 expression=bench.EXPRESSION)
    eyes = layer_plan(_face_wide(hp, (3840, 2160), 1000.0)).eyes
    rl, rr = eyes["eye_l"].r0, eyes["eye_r"].r0
    assert max(rl, rr) / min(rl, rr) <= 1.08, (rl, rr)
    for ep in eyes.values():
        w = ep.widths
        assert len(w) == 2 and max(w) / min(w) <= 2.0, (ep.name, w)
