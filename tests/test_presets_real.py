"""The emotion presets move the feature points as real people do (JAFFE, issue item 5).

The real motion is dlib's (the instrument the presets were derived with, issue 14): measured
live from ../shared/data/jaffe when the dlib extra is installed (landmark detections cached in
the system temp directory; first run ~10 s, then ~1 s), and then
:func:`test_frozen_summary_matches_dlib` fails when ``tests/data/jaffe_motion_dlib.json`` is
stale; without dlib (CI) that frozen summary (``scripts/freeze_jaffe_motion.py``: summary numbers
only, no JAFFE images or landmarks) stands in. The meshes the presets are applied to are the ten
women's first neutral photos fitted by the default detector (they only give mesh and FAPU), so
those tests are skipped only when JAFFE is absent.

Band rule: with 29-32 photos per emotion, a preset at 100 % must move every measured feature
point (FAP-equivalent motion, median over the ten women's meshes) inside the real p10..p90
band; a band the FAP cannot reach (open_jaw >= 0 where JAFFE's chin rises in anger) requires
no motion at all. Where the band excludes 0 this fixes the sign. At 150 % every point stays
inside the real min..max (strong, still human).
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from conftest import JAFFE, ROOT

from editor.engine.face import Face
from editor.engine.faps import FAPS
from editor.engine.landmarks import dlib_available
from editor.formats.presets import apply_preset, shipped_presets
from editor.synthesis import jaffe_stats as js

EMOTIONS = ("joy", "sadness", "surprise", "anger", "fear", "disgust")
#: dlib's JAFFE motion summary, frozen by scripts/freeze_jaffe_motion.py
FROZEN = ROOT / "tests" / "data" / "jaffe_motion_dlib.json"


def _have_jaffe() -> bool:
    return (JAFFE / "images").is_dir()


def _live_dlib() -> bool:
    return _have_jaffe() and dlib_available()


needs_live_dlib = pytest.mark.skipif(
    not _live_dlib(), reason="needs dlib (pip install '.[dlib]') and ../shared/data/jaffe")


@pytest.fixture(scope="module")
def live() -> js.MotionSummary:
    """dlib's summary measured now (only with dlib and JAFFE)."""
    if not _live_dlib():
        pytest.skip("needs dlib (pip install '.[dlib]') and ../shared/data/jaffe")
    return js.MotionSummary.of(js.measure(JAFFE))


@pytest.fixture(scope="module")
def real(request) -> js.MotionSummary:
    """dlib's JAFFE motion summary: live with dlib, else the frozen copy (CI)."""
    if _live_dlib():
        return request.getfixturevalue("live")
    return js.MotionSummary.load(FROZEN)


@pytest.fixture(scope="module")
def faces() -> dict[str, Face]:
    """The women's meshes (first neutral photo, default detector): mesh and FAPU only."""
    if not _have_jaffe():
        pytest.skip("../shared/data/jaffe is not available")
    return js.neutral_faces(JAFFE)


@pytest.fixture(scope="module")
def preset_motion(faces):
    """emotion, intensity -> (len(MEASURED),) motion, median over the women's meshes."""
    cache: dict = {}

    def run(emotion: str, k: float = 1.0) -> np.ndarray:
        if (emotion, k) not in cache:
            vec = apply_preset(emotion, k)
            cache[emotion, k] = np.median([js.preset_motion(f, vec) for f in faces.values()], 0)
        return cache[emotion, k]

    return run


def test_frozen_summary_matches_dlib(live):
    """The frozen copy CI uses is dlib's current measurement (else: re-run
    scripts/freeze_jaffe_motion.py)."""
    frozen = js.MotionSummary.load(FROZEN)
    assert frozen.detector == "dlib" and frozen.faps == js.MEASURED
    bad = frozen.differences(live)
    assert not bad, "\n".join(bad[:20])


def test_frozen_summary_holds_no_photo_data():
    """Only summary numbers: no image names, landmarks or per-photo arrays."""
    raw = json.loads(FROZEN.read_text(encoding="utf-8"))
    assert ".tiff" not in json.dumps(raw)
    assert set(raw) == {"about", "detector", "faps", "noise_p90", "n_neutral", "joy_lips",
                        "emotions"}
    assert set(raw["joy_lips"]) == {"n_closed", "n_open", "closed_max", "open_min", "median"}
    assert set(raw["emotions"]) == set(EMOTIONS)
    for st in raw["emotions"].values():
        assert set(st) == set(js.STAT_KEYS)
        assert all(len(v) == len(raw["faps"]) for v in st.values())


def test_measurement_is_above_its_noise_floor(real):
    """Neutral vs neutral is the noise; a smile's corner lift and an open surprise jaw are
    far above it (else the table would be measuring detector jitter)."""
    i = {n: k for k, n in enumerate(real.faps)}
    noise = real.noise_p90
    joy, sur = real.stats("joy"), real.stats("surprise")
    for n in (59, 60):
        assert joy["median"][i[n]] > 2.5 * noise[i[n]]
    assert sur["median"][i[3]] > 4 * noise[i[3]] and sur["median"][i[52]] < -4 * noise[i[52]]
    assert {int(real.stats(e)["n"][0]) for e in EMOTIONS} <= set(range(25, 40))
    assert real.n_neutral >= 20


@pytest.mark.parametrize("emotion", EMOTIONS)
def test_preset_inside_the_real_band(real, preset_motion, emotion):
    st = real.stats(emotion)
    m1, m15 = preset_motion(emotion, 1.0), preset_motion(emotion, 1.5)
    bad = []
    for i, n in enumerate(real.faps):
        lo, hi = st["p10"][i], st["p90"][i]
        if FAPS[n].range[0] >= 0 and hi < 0:  # unreachable (e.g. open_jaw in anger)
            lo, hi = -1.0, 1.0
        if not lo - 1 <= m1[i] <= hi + 1:
            bad.append(f"{n} {FAPS[n].name}: {m1[i]:.0f} not in p10..p90 {lo:.0f}..{hi:.0f}")
        lo15, hi15 = (st["min"][i], st["max"][i]) if hi > 1 or lo < -1 else (-1.0, 1.0)
        if not lo15 - 1 <= m15[i] <= hi15 + 1:
            bad.append(f"{n} {FAPS[n].name} at 150 %: {m15[i]:.0f} not in min..max "
                       f"{lo15:.0f}..{hi15:.0f}")
    assert not bad, "\n".join(bad)


def test_joy_lifts_the_corners_like_a_real_smile(real, faces, preset_motion):
    i = {n: k for k, n in enumerate(real.faps)}
    for n in (59, 60):  # outer corners, pupil distances
        real_pd = real.stats("joy")["median_pd"][i[n]]  # per photo in her own PD, median
        mine = preset_motion("joy")[i[n]]
        mine_pd = np.median([js.to_pupil_distances(f, n, mine) for f in faces.values()])
        assert 0.09 <= real_pd <= 0.13  # the measurement: smiles lift the corners ~0.11 PD
        assert 0.09 <= mine_pd <= 0.13 and abs(mine_pd - real_pd) < 0.02


def test_joy_parts_the_lips_like_a_real_open_smile(real, preset_motion):
    # JAFFE smiles are closed or open, nothing in between: the inner lips' opening change
    # (2.3 - 2.2, MNS) is at most 175 or at least 331, median 332; joy parts them by that
    # median (main before: 215, a slit between the two that rendered as a dark line)
    lips = real.joy_lips  # split at js.LIP_OPEN_SPLIT = 250
    assert lips["n_closed"] >= 10 and lips["n_open"] >= 10
    assert lips["closed_max"] < lips["open_min"] - 100
    mine = float(js.lip_opening(preset_motion("joy"), real.faps))
    assert abs(mine - lips["median"]) < 25 and mine > lips["open_min"] - 25, (mine, lips)


@pytest.mark.parametrize("emotion", EMOTIONS)
def test_the_mouth_widens_as_real_faces_do(real, preset_motion, emotion):
    """The mouth corners' sideways motion (FAPs 6 + 7, stretch, MW) of each preset is the real
    median's within a fifth of it or 50 MW. The corners' band alone allowed fear and disgust
    their FACS lip stretch at 55-60 (2.5-9 x the real 20 / 13: blind raters called their
    mouths swollen, oversized, pasted on) and joy 160 (320 against 248: the 150 % grin too
    wide)."""
    i = {n: k for k, n in enumerate(real.faps)}
    want = float(sum(real.stats(emotion)["median"][i[n]] for n in (6, 7)))
    got = float(sum(preset_motion(emotion)[i[n]] for n in (6, 7)))
    assert abs(got - want) <= max(0.2 * abs(want), 50.0), (got, want)


def test_anger_brows_down_and_barely_together(real, faces, preset_motion):
    i = {n: k for k, n in enumerate(real.faps)}
    m = preset_motion("anger")
    squeeze_pd = np.array([js.to_pupil_distances(f, 37, m[i[37]]) for f in faces.values()])
    assert (squeeze_pd > 0.005).all() and (squeeze_pd < 0.05).all()  # real: ~0.02, max ~0.09
    assert m[i[35]] < 0 and m[i[36]] < 0  # outer brows lowered, not raised
    assert m[i[31]] < -50 and m[i[33]] < -50  # inner/middle brows clearly down (AU4)
    assert m[i[21]] > 50  # lower lids tensed (AU7)
    gap = -m[i[5]] - m[i[4]]  # inner lips: opening change (MNS), pressed = not opening
    assert gap <= 5


def test_emotion_cues_relative_to_each_other(preset_motion, real):
    i = {n: k for k, n in enumerate(real.faps)}
    def m(e: str, n: int) -> float:
        return float(preset_motion(e)[i[n]])

    # sadness: the oblique brow (inner end above outer), upper lids lowered, corners down
    assert m("sadness", 31) - m("sadness", 35) > 50 and m("sadness", 19) > 50
    assert m("sadness", 59) < 0
    # surprise: brows up, lids wide, jaw open - the most of all emotions
    assert min(m("surprise", n) for n in (31, 33)) > 30 and m("surprise", 19) < -50
    assert m("surprise", 3) == max(m(e, 3) for e in EMOTIONS)
    # fear: inner brows up and together, lids wider, corners stretched
    assert m("fear", 31) > 30 and m("fear", 37) > 0 and m("fear", 19) < -30
    # (the corners' stretch at least as far as real fear's (median 14/23 MW outer); the
    # widening of re-detected landmarks is held near real fear's by
    # tests/test_presets_sad_fear.py)
    assert m("fear", 53) >= 20
    # disgust: upper lip curled up at its sides, lids narrowed, brows lowered and together
    assert m("disgust", 55) < -50 and m("disgust", 19) > 50 and m("disgust", 21) > 50
    assert m("disgust", 33) < -50 and m("disgust", 37) > 20
    # joy: lower lids pushed up by the cheeks, brows still
    assert m("joy", 21) > 50 and abs(m("joy", 35)) < 30


def test_every_preset_value_has_a_source():
    for e in EMOTIONS:
        p = shipped_presets()[e]
        assert "derive_presets.py" in p.source and "JAFFE" in p.source
        for name in p.faps:
            assert f"{FAPS.number(name)}" in p.source, (e, name)


@pytest.mark.skipif(not _live_dlib(), reason="derive_presets.py --check re-derives the presets "
                    "from dlib's per-photo JAFFE landmarks, which no summary can stand in for "
                    "(needs dlib and ../shared/data/jaffe)")
def test_preset_files_match_the_derivation():
    r = subprocess.run([sys.executable, str(ROOT / "scripts" / "derive_presets.py"), "--check",
                        "--jaffe", str(JAFFE), "--table", "/dev/null"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr


def _inner_gaps(face, vec) -> np.ndarray:
    """Inner lower minus inner upper lip (face frame y, px) at the 7 inner-lip columns."""
    q = (face.deform(vec).astype(np.float64) - face.frame.origin) @ face.frame.rot
    n = face.mesh.names
    return np.array([q[n.index(f"lipi_d{k}"), 1] - q[n.index(f"lipi_u{k}"), 1]
                     for k in range(1, 8)])


def test_viseme_pbm_closes_the_lips_over_the_whole_width(faces, sample_neutral, sample_face):
    closed = 0
    for face in faces.values():
        g0 = _inner_gaps(face, None)
        if g0.max() / face.fapu["MNS"] > 80:  # parted lips in the photo: needs neutralisation
            continue
        closed += 1
        assert _inner_gaps(face, apply_preset("viseme_pbm")).max() < 0.05, face.source
    # 8 of the 10 neutral photos have closed lips by dlib's reading, 7 by MediaPipe's (it reads
    # MK's neutral lips 270 MNS apart where dlib reads them closed)
    assert closed >= 7
    # the sample declared neutral smiles with teeth (~540 MNS): pbm narrows the gap but cannot
    # close it alone; opened as the product does (its smile neutralised) pbm keeps it closed
    g0 = _inner_gaps(sample_neutral, None)
    g1 = _inner_gaps(sample_neutral, apply_preset("viseme_pbm"))
    assert g1.max() < g0.max() - 1.0
    # closed to a quarter pixel: the neutralisation offset is re-guarded after the pair rule
    assert _inner_gaps(sample_face, apply_preset("viseme_pbm")).max() < 0.3


def test_viseme_u_rounds_the_lips(faces):
    for face in list(faces.values())[:4]:
        n = face.mesh.names
        v0, v1 = face.deform(None), face.deform(apply_preset("viseme_u"))
        w0, w1 = (np.linalg.norm(v[n.index("lipo_c0")] - v[n.index("lipo_c1")]) for v in (v0, v1))
        assert w1 < 0.85 * w0  # corners pulled in
        g = _inner_gaps(face, apply_preset("viseme_u"))
        assert g.min() > 0.5 and g[3] > 1.4 * g[[1, 5]].mean()  # small, round opening


def test_recogniser_learns_separable_emotions_and_needs_all_six():
    """The classifier of editor/synthesis/recognise.py on synthetic motion: six clusters in a
    102-dimensional feature space, 20 samples each, are labelled right when new samples of
    them come; a training set without one emotion is refused."""
    from editor.synthesis.recognise import CODES, Classifier

    rng = np.random.default_rng(4)
    centres = rng.normal(0, 1, (len(CODES), 102))
    X = np.concatenate([c + rng.normal(0, 0.3, (20, 102)) for c in centres])
    y = [c for c in CODES for _ in range(20)]
    clf = Classifier.fit(X, y)
    new = np.concatenate([c + rng.normal(0, 0.3, (5, 102)) for c in centres])
    assert clf.predict(new) == [c for c in CODES for _ in range(5)]
    with pytest.raises(ValueError, match="no training photo"):
        Classifier.fit(X[20:], y[20:])


def test_a_recogniser_of_real_faces_names_the_presets():
    """Would a recogniser name them? A classifier of the landmark motion of real JAFFE
    expressions (editor/synthesis/recognise.py), trained on nine women, labels the presets at
    100 % rendered on the tenth woman's neutral photo (and detected again), for each woman.
    On unseen women's real photos it is right 66 % of the time (chance: 17 %; disgust 45 %).
    Joy, sadness, surprise, anger and fear are named right on at least 8 of the 10 women
    (measured: 10, 9, 10, 10, 10), disgust on at least 5 (measured 6; 10 at 150 %). Disgust
    raising the whole upper lip (4/51 at -190) was named anger on 10 of 10: its inner-lip
    landmarks moved up as JAFFE's anger raises the whole mouth, where JAFFE's disgust keeps the
    inner lips at rest and raises only the outer contour."""
    if not _have_jaffe():
        pytest.skip("../shared/data/jaffe is not available")
    from editor.synthesis.recognise import recognise

    res = recognise(JAFFE / "images")
    assert res.women == 10
    assert res.accuracy(res.real) >= 0.55, res.table()
    for code in ("HA", "SA", "SU", "AN", "FE"):
        right, n = res.hits(code)
        assert n == 10 and right >= 8, (code, res.table())
    right, n = res.hits("DI")
    assert n == 10 and right >= 5, res.table()
