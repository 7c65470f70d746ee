"""The emotion presets move the feature points as real people do (JAFFE, issue item 5).

JAFFE is read at test time from ../shared/data/jaffe (skipped when absent); the landmark
detections are cached in the system temp directory (first run ~10 s, then ~1 s).

Band rule: with 29-32 photos per emotion, a preset at 100 % must move every measured feature
point (FAP-equivalent motion, median over the ten women's meshes) inside the real p10..p90
band; a band the FAP cannot reach (open_jaw >= 0 where JAFFE's chin rises in anger) requires
no motion at all. Where the band excludes 0 this fixes the sign. At 150 % every point stays
inside the real min..max (strong, still human).
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from conftest import JAFFE, ROOT

from editor.engine.faps import FAPS
from editor.engine.landmarks import dlib_available
from editor.formats.presets import apply_preset, shipped_presets
from editor.synthesis import jaffe_stats as js

EMOTIONS = ("joy", "sadness", "surprise", "anger", "fear", "disgust")


@pytest.fixture(scope="module")
def real() -> js.JaffeMotion:
    if not (JAFFE / "images").is_dir():
        pytest.skip("../shared/data/jaffe is not available")
    if not dlib_available():  # the presets were derived from dlib's JAFFE landmarks (issue 14)
        pytest.skip("the real-motion bands are dlib's (pip install '.[dlib]')")
    return js.measure(JAFFE)


@pytest.fixture(scope="module")
def preset_motion(real):
    """emotion, intensity -> (len(MEASURED),) motion, median over the women's meshes."""
    cache: dict = {}

    def run(emotion: str, k: float = 1.0) -> np.ndarray:
        if (emotion, k) not in cache:
            vec = apply_preset(emotion, k)
            cache[emotion, k] = np.median([js.preset_motion(f, vec)
                                           for f in real.faces.values()], 0)
        return cache[emotion, k]

    return run


def pd_motion(real: js.JaffeMotion, n: int, values: np.ndarray, people: list[str]) -> np.ndarray:
    """FAP-equivalent values of FAP ``n`` -> pupil distances, per person."""
    unit = js.fap_axis(n)[3]
    out = []
    for v, who in zip(values, people, strict=True):
        f = real.faces[who]
        il, ir = f.landmarks.iris_left, f.landmarks.iris_right
        out.append(v * f.fapu[unit] / np.hypot(il.cx - ir.cx, il.cy - ir.cy))
    return np.array(out)


def test_measurement_is_above_its_noise_floor(real):
    """Neutral vs neutral is the noise; a smile's corner lift and an open surprise jaw are
    far above it (else the table would be measuring detector jitter)."""
    i = {n: k for k, n in enumerate(real.faps)}
    noise = np.percentile(np.abs(real.values("neutral")), 90, 0)
    joy, sur = real.stats("joy"), real.stats("surprise")
    for n in (59, 60):
        assert joy["median"][i[n]] > 2.5 * noise[i[n]]
    assert sur["median"][i[3]] > 4 * noise[i[3]] and sur["median"][i[52]] < -4 * noise[i[52]]
    assert {len(real.values(e)) for e in EMOTIONS} <= set(range(25, 40))


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


def test_joy_lifts_the_corners_like_a_real_smile(real, preset_motion):
    people = list(real.faces)
    i = {n: k for k, n in enumerate(real.faps)}
    for n in (59, 60):  # outer corners, pupil distances
        vals = [s.values[i[n]] for s in real.samples if s.emotion == "joy"]
        who = [s.person for s in real.samples if s.emotion == "joy"]
        real_pd = np.median(pd_motion(real, n, np.array(vals), who))
        mine = np.median([js.preset_motion(real.faces[p], apply_preset("joy"))[i[n]]
                          for p in people])
        mine_pd = np.median(pd_motion(real, n, np.full(len(people), mine), people))
        assert 0.09 <= real_pd <= 0.13  # the measurement: smiles lift the corners ~0.11 PD
        assert 0.09 <= mine_pd <= 0.13 and abs(mine_pd - real_pd) < 0.02


def test_joy_parts_the_lips_like_a_real_open_smile(real, preset_motion):
    # JAFFE smiles are closed or open, nothing in between: the inner lips' opening change
    # (2.3 - 2.2, MNS) is at most 175 or at least 331, median 332; joy parts them by that
    # median (main before: 215, a slit between the two that rendered as a dark line)
    i = {n: k for k, n in enumerate(real.faps)}
    gaps = np.array([-s.values[i[5]] - s.values[i[4]] for s in real.samples
                     if s.emotion == "joy"])
    closed, opened = gaps[gaps < 250], gaps[gaps >= 250]
    assert len(closed) >= 10 and len(opened) >= 10 and closed.max() < opened.min() - 100
    m = preset_motion("joy")
    mine = -m[i[5]] - m[i[4]]
    assert abs(mine - np.median(gaps)) < 25 and mine > opened.min() - 25, (mine, gaps)


def test_anger_brows_down_and_barely_together(real, preset_motion):
    people = list(real.faces)
    i = {n: k for k, n in enumerate(real.faps)}
    m = preset_motion("anger")
    squeeze_pd = pd_motion(real, 37, np.full(len(people), m[i[37]]), people)
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
    assert m("fear", 53) > 30
    # disgust: upper lip raised, lids narrowed, brows lowered and together
    assert m("disgust", 51) < -50 and m("disgust", 19) > 50 and m("disgust", 21) > 50
    assert m("disgust", 33) < -50 and m("disgust", 37) > 20
    # joy: lower lids pushed up by the cheeks, brows still
    assert m("joy", 21) > 50 and abs(m("joy", 35)) < 30


def test_every_preset_value_has_a_source():
    for e in EMOTIONS:
        p = shipped_presets()[e]
        assert "derive_presets.py" in p.source and "JAFFE" in p.source
        for name in p.faps:
            assert f"{FAPS.number(name)}" in p.source, (e, name)


def test_preset_files_match_the_derivation(real):
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


def test_viseme_pbm_closes_the_lips_over_the_whole_width(real, sample_neutral, sample_face):
    closed = 0
    for face in real.faces.values():
        g0 = _inner_gaps(face, None)
        if g0.max() / face.fapu["MNS"] > 80:  # parted lips in the photo: needs neutralisation
            continue
        closed += 1
        assert _inner_gaps(face, apply_preset("viseme_pbm")).max() < 0.05, face.source
    assert closed >= 8
    # the sample declared neutral smiles with teeth (~540 MNS): pbm narrows the gap but cannot
    # close it alone; opened as the product does (its smile neutralised) pbm keeps it closed
    g0 = _inner_gaps(sample_neutral, None)
    g1 = _inner_gaps(sample_neutral, apply_preset("viseme_pbm"))
    assert g1.max() < g0.max() - 1.0
    # closed to a quarter pixel: the neutralisation offset is re-guarded after the pair rule
    assert _inner_gaps(sample_face, apply_preset("viseme_pbm")).max() < 0.3


def test_viseme_u_rounds_the_lips(real):
    for face in list(real.faces.values())[:4]:
        n = face.mesh.names
        v0, v1 = face.deform(None), face.deform(apply_preset("viseme_u"))
        w0, w1 = (np.linalg.norm(v[n.index("lipo_c0")] - v[n.index("lipo_c1")]) for v in (v0, v1))
        assert w1 < 0.85 * w0  # corners pulled in
        g = _inner_gaps(face, apply_preset("viseme_u"))
        assert g.min() > 0.5 and g[3] > 1.4 * g[[1, 5]].mean()  # small, round opening
