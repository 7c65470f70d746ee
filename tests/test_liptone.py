"""A stretched upper lip pales (editor/engine/liptone.py); the drawn mouth interior carries
the photo's grain (grain.grain_over in mouth.MouthPlan.render)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from conftest import jaffe_images

from editor.core import Face
from editor.engine import face as face_module
from editor.engine import layers as layers_module
from editor.engine.grain import grain_plan
from editor.engine.liptone import SKIN_BAND, _loop, tone_plan
from editor.formats.presets import apply_preset

WOMEN = ("KA", "KL", "KM", "KR", "MK", "NA", "NM", "TM", "UY", "YM")


def _neutral(who: str) -> Face:
    paths = jaffe_images(f"{who}.NE*")
    if not paths:
        pytest.skip("JAFFE not available")
    return Face.from_image(paths[0], own_expression=False)


def _lip_over_skin(f: Face, img: np.ndarray, V: np.ndarray) -> float:
    """Median luminance of the upper lip (the mesh's loop, eroded a pixel) over that of the
    skin band above it, ``V`` the mesh where ``img`` has it."""
    loop, (c0, c1) = _loop(f)
    Y = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY).astype(np.float32)
    m = np.zeros(Y.shape, np.uint8)
    cv2.fillPoly(m, [np.round(V[loop]).astype(np.int32)], 1)
    core = cv2.erode(m, np.ones((3, 3), np.uint8)) > 0
    d = cv2.distanceTransform((1 - m).astype(np.uint8), cv2.DIST_L2, 3)
    yy, xx = np.mgrid[0:Y.shape[0], 0:Y.shape[1]]
    t = np.clip((xx - V[c0, 0]) / (V[c1, 0] - V[c0, 0]), 0, 1)
    above = yy < V[c0, 1] + t * (V[c1, 1] - V[c0, 1])
    iod = f.interocular
    band = ((d > SKIN_BAND[0] * iod) & (d <= SKIN_BAND[1] * iod) & above
            & (xx > V[c0, 0]) & (xx < V[c1, 0]))
    return float(np.median(Y[core]) / np.median(Y[band]))


@pytest.fixture
def no_tone(monkeypatch):
    monkeypatch.setattr(face_module, "apply_lip_tone", lambda face, res, v: res)


def _paling(emotion: str) -> list[float]:
    out = []
    for who in WOMEN:
        f = _neutral(who)
        v = apply_preset(emotion, 1.0)
        out.append(_lip_over_skin(f, f.render(v), f.deform(v))
                   / _lip_over_skin(f, f.image, f.vertices))
    return out


def test_a_smile_pales_the_upper_lip_as_real_smiles_do():
    """JAFFE's real smile photos: the upper lip over the skin above it 1.27 of the woman's
    neutral photo (median of ten; 1.06-2.01). The renders of joy: 1.27 (1.09-1.57)."""
    r = _paling("joy")
    assert 1.15 <= float(np.median(r)) <= 1.4, np.round(r, 2)
    assert min(r) >= 1.02, np.round(r, 2)


def test_without_the_layer_the_smile_keeps_the_dark_lip(no_tone):
    """The warp alone keeps the neutral lip's tone (median 1.0-1.04): what the layer adds."""
    r = _paling("joy")
    assert float(np.median(r)) < 1.08, np.round(r, 2)


@pytest.mark.parametrize("emotion", ["sadness", "disgust", "anger", "surprise"])
def test_mouths_that_widen_little_keep_their_lip_tone(emotion, monkeypatch):
    """Real disgust and sadness photos leave the upper lip's tone as it is (and so do the
    narrower mouths of anger and surprise), and their lower lips are not pulled down towards
    the chin (surprise's drops with its wide jaw): up to 150 % the renders with the layer are
    the renders without it. (Fear pulls its lower lip down: see below.)"""
    from editor.engine.liptone import tone_share

    f = _neutral("KA")
    v = apply_preset(emotion, 1.5)
    plan = tone_plan(f)
    assert plan is not None
    assert tone_share(plan, f.deform(v)) == 0.0
    assert tone_share(plan, f.deform(apply_preset("joy", 1.0))) > 0.05
    with_layer = f.render(v)
    monkeypatch.setattr(face_module, "apply_lip_tone", lambda face, res, verts: res)
    assert np.array_equal(with_layer, f.render(v))


def test_the_lip_never_turns_lighter_than_the_skin(monkeypatch):
    """Each pixel moves towards the skin's colour by its own distance to it: none is pushed
    past it (no light halo along the lip's edge), and pixels away from the lip are untouched."""
    f = _neutral("TM")
    v = apply_preset("joy", 1.5)
    import editor.engine.liptone as lt

    plan = tone_plan(f)
    assert plan is not None
    captured = {}
    orig = lt.apply_lip_tone

    def spy(face, res, verts):
        captured["before"] = res.image.copy()
        out = orig(face, res, verts)
        captured["after"] = out.image.copy()
        return out

    monkeypatch.setattr(face_module, "apply_lip_tone", spy)
    f.render(v)
    b = captured["before"].astype(np.int16)
    a = captured["after"].astype(np.int16)
    changed = np.any(a != b, axis=2)
    assert changed.sum() > 50  # (the layer did something)
    skin = np.array(plan.skin[:3])
    # a pixel only ever gets lighter (the lip towards the skin, the lower lip's shadow
    # lifted), and on the upper lip never beyond the skin (rounding: 1 level)
    assert ((a - b) >= 0).all()
    V = f.deform(v)
    poly = V[_loop(f)[0]]
    top = poly[:, 1].max() + 3
    lip = changed.copy()
    lip[int(top):] = False
    assert (a[lip] <= np.maximum(b[lip], skin[None, :]) + 1).all()
    # only on the upper lip and the band below the lower lip, within the mouth's width
    ys, xs = np.nonzero(changed)
    assert xs.min() >= poly[:, 0].min() - 3 and xs.max() <= poly[:, 0].max() + 3
    low = V[f.mesh.index("lipo_d4"), 1] + 0.14 * f.interocular
    assert ys.min() >= poly[:, 1].min() - 3 and ys.max() <= low


def test_the_untouched_photo_and_a_neutral_render_stay_exact():
    f = _neutral("NA")
    assert np.array_equal(f.render(None), f.image)


@pytest.mark.parametrize("who", ["KA", "TM"])
def test_the_drawn_mouth_interior_has_the_photos_grain(who, monkeypatch):
    """A wide-open mouth's drawn teeth, tongue and cavity: the robust level of their
    high-pass (1.48 MAD, edges do not count) is the photo's grain (1.1-1.2 of its level on
    JAFFE); drawn without it 0.3-0.4, a smooth inlay in a grainy photo."""
    f = _neutral(who)
    g = grain_plan(f)
    assert g is not None
    v = apply_preset("surprise", 1.5)
    V = f.deform(v)
    m = np.zeros(f.image.shape[:2], np.uint8)
    cv2.fillPoly(m, [np.round(V[f.mesh.holes["mouth"]]).astype(np.int32)], 1)
    m = cv2.erode(m, np.ones((5, 5), np.uint8)) > 0

    def level(img: np.ndarray) -> float:
        Y = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY).astype(np.float32)
        h = (Y - cv2.GaussianBlur(Y, (0, 0), 1.0))[m]
        return 1.4826 * float(np.median(np.abs(h - np.median(h)))) / g.level

    assert 0.85 <= level(f.render(v)) <= 1.4
    monkeypatch.setattr(layers_module, "grain_over", lambda face, box: None)
    assert level(f.render(v)) < 0.55


def test_the_sample_declared_neutral_pales_its_lip_in_a_smile(sample_neutral, monkeypatch):
    """The same on the bundled sample (runs without JAFFE): its pink lip towards its skin."""
    f = sample_neutral
    v = apply_preset("joy", 1.0)
    V = f.deform(v)
    base = _lip_over_skin(f, f.image, f.vertices)
    with_layer = _lip_over_skin(f, f.render(v), V) / base
    monkeypatch.setattr(face_module, "apply_lip_tone", lambda face, res, verts: res)
    without = _lip_over_skin(f, f.render(v), V) / base
    assert with_layer > without + 0.02, (with_layer, without)



def test_a_neutralised_smile_keeps_its_lip_tone(sample_face):
    """The sample smiles (its mouth 1.1 x wider than neutral and more): its own expression
    and every narrower mouth (the neutralised face, sadness, anger) leave the lip alone."""
    from editor.engine.liptone import tone_share

    f = sample_face
    plan = tone_plan(f)
    assert plan is not None and plan.w_photo > 1.1 * plan.w_neutral
    for vec in (f.expression, None, apply_preset("sadness"), apply_preset("anger")):
        assert tone_share(plan, f.deform(vec)) == 0.0
    assert np.array_equal(f.render(f.expression), f.image)


def _below_lip(f: Face, img: np.ndarray, V: np.ndarray) -> np.ndarray:
    """The skin below the lower lip's middle (half the mouth's width) at 0.04-0.06,
    0.06-0.08 and 0.08-0.10 IOD below the mesh's outer lower lip, over the forehead."""
    ix = f.mesh.index
    outer = [ix("lipo_c0"), *(ix(f"lipo_u{k}") for k in range(1, 8)), ix("lipo_c1"),
             *(ix(f"lipo_d{k}") for k in range(7, 0, -1))]
    Y = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY).astype(np.float32)
    m = np.zeros(Y.shape, np.uint8)
    o = V[outer]
    cv2.fillPoly(m, [np.round(o).astype(np.int32)], 1)
    d = cv2.distanceTransform((1 - m).astype(np.uint8), cv2.DIST_L2, 3) / f.interocular
    yy, xx = np.mgrid[0:Y.shape[0], 0:Y.shape[1]]
    xl, xr = o[:, 0].min(), o[:, 0].max()
    mid = (xx > xl + 0.25 * (xr - xl)) & (xx < xr - 0.25 * (xr - xl)) & (yy > o[:, 1].mean())
    br = V[[f.mesh.fdp[k] for k in ("4.1", "4.2")]].mean(0)
    iod = f.interocular
    fore = np.median(Y[int(br[1] - 0.35 * iod):int(br[1] - 0.1 * iod),
                       int(br[0] - 0.2 * iod):int(br[0] + 0.2 * iod)])
    return np.array([np.median(Y[mid & (d > lo) & (d <= lo + 0.02)]) / fore
                     for lo in (0.04, 0.06, 0.08)])


def test_a_smiles_lower_lip_casts_less_shadow_as_real_ones_do(monkeypatch):
    """JAFFE's ten women, the skin below the lower lip's middle (over the forehead) at
    0.04-0.10 IOD: real smiles 0.72 0.77 0.84, their neutral photos 0.63 0.73 0.76; the
    renders of joy 0.70 0.78 0.79, the warp alone 0.63 0.71 0.77 (the neutral lip's shadow
    carried along)."""
    on_m, off_m = _below_lip_medians("joy", monkeypatch)
    assert np.abs(on_m - [0.723, 0.770, 0.842]).max() < 0.06, np.round(on_m, 3)
    assert on_m[0] - off_m[0] > 0.03, (np.round(on_m, 3), np.round(off_m, 3))


def _below_lip_medians(emotion: str, monkeypatch) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_below_lip` of ``emotion`` at 100 % on the ten women, median, with the layer and
    without it (the second leaves it patched out)."""
    out = []
    for on in (True, False):
        if not on:
            monkeypatch.setattr(face_module, "apply_lip_tone", lambda face, res, verts: res)
        rows = []
        for who in WOMEN:
            f = _neutral(who)
            v = apply_preset(emotion, 1.0)
            rows.append(_below_lip(f, f.render(v), f.deform(v)))
        out.append(np.median(rows, 0))
    return out[0], out[1]


def test_a_neutralised_smiles_lower_lip_casts_its_shadow_again(sample_face, monkeypatch):
    """The sample's stretched smiling lower lip casts no shadow; neutralised (its mouth 0.38
    of the neutral width narrower than the photo's) the lip protrudes again and the skin under
    its middle darkens, as JAFFE's neutral photos are darker there than their smiles (0.82-0.91
    of the smile's light at 0.01-0.05 IOD); nothing above the lip or beside the mouth changes,
    and no pixel gets lighter. The photo's own expression keeps the photo."""
    from editor.engine.liptone import narrowing_share

    f = sample_face
    plan = tone_plan(f)
    assert plan is not None
    assert narrowing_share(plan, f.deform(f.expression)) == 0.0
    N = f.deform(None)
    assert narrowing_share(plan, N) == 1.0
    with_layer = f.render(None).astype(np.int16)
    monkeypatch.setattr(face_module, "apply_lip_tone", lambda face, res, verts: res)
    without = f.render(None).astype(np.int16)
    diff = with_layer - without
    assert (diff <= 0).all()
    ys, xs = np.nonzero(np.any(diff != 0, axis=2))
    lower = N[[f.mesh.index(n) for n in ("lipo_c0", "lipo_d4", "lipo_c1")]]
    assert xs.min() >= lower[:, 0].min() - 1 and xs.max() <= lower[:, 0].max() + 1
    assert ys.min() >= lower[:, 1].min() - 1
    # the skin just under the lower lip's middle: 5-12 % darker
    iod = f.interocular
    x, y = N[f.mesh.index("lipo_d4")]
    box = (slice(int(y + 0.02 * iod), int(y + 0.05 * iod) + 1),
           slice(int(x - 0.1 * iod), int(x + 0.1 * iod) + 1))
    ratio = with_layer[box].mean() / without[box].mean()
    assert 0.88 <= ratio <= 0.95, ratio


def test_fears_lower_lip_pulled_down_casts_less_shadow_as_real_ones_do(monkeypatch):
    """JAFFE's fear pulls the lower lip down towards the chin (AU16/20 beyond the jaw) and flat:
    the skin below its middle at 0.04-0.10 IOD over the forehead is 0.83 0.85 0.87 in the real
    photos (neutral 0.63 0.73 0.76); the renders of fear 0.78 0.80 0.83, the warp alone
    0.69 0.77 0.83. Surprise, whose jaw drops wide, keeps its shadow (no lift on 9 of 10)."""
    from editor.engine.liptone import pull_share

    surprise = []
    for who in WOMEN:
        f = _neutral(who)
        plan = tone_plan(f)
        assert plan is not None
        assert pull_share(plan, f.deform(apply_preset("fear", 1.0))) > 0.15, who
        surprise.append(pull_share(plan, f.deform(apply_preset("surprise", 1.0))))
    assert sum(x == 0.0 for x in surprise) >= 9, surprise
    on_m, off_m = _below_lip_medians("fear", monkeypatch)
    assert np.abs(on_m - [0.827, 0.848, 0.865]).max() < 0.06, np.round(on_m, 3)
    assert on_m[0] - off_m[0] > 0.05, (np.round(on_m, 3), np.round(off_m, 3))


def test_a_lower_lip_pulled_down_lifts_its_shadow_a_wide_jaw_does_not(sample_neutral):
    """The sample declared neutral (runs without JAFFE): fear's lower lip pulled down lifts
    its shadow, surprise's wide jaw and a closed neutral mouth do not."""
    from editor.engine.liptone import pull_share

    f = sample_neutral
    plan = tone_plan(f)
    assert plan is not None
    assert pull_share(plan, f.deform(apply_preset("fear", 1.0))) > 0.1  # (0.14)
    assert pull_share(plan, f.deform(apply_preset("surprise", 1.0))) == 0.0
    assert pull_share(plan, f.deform(None)) == 0.0
