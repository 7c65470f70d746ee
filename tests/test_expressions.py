"""Emotion/viseme presets: shipped data, intensity, FAP 1/2 blending, user presets, bad files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from editor.engine.faps import FAPS
from editor.errors import PresetError
from editor.formats.blends import EXPRESSIONS, VISEMES, blend_expressions, blend_visemes
from editor.formats.presets import (
    Preset,
    all_presets,
    apply_preset,
    get_preset,
    load_preset,
    preset_from_dict,
    save_user_preset,
    shipped_preset_dir,
    shipped_presets,
    user_preset_dir,
    user_presets,
)

MOUTH = {3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 16, 17, 43, 44, 45, 46, *range(51, 61)}
INNER_OUTER = {4: 51, 5: 52, 6: 53, 7: 54, 8: 55, 9: 56, 10: 57, 11: 58, 12: 59, 13: 60}


@pytest.fixture(autouse=True)
def data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("FAP_STUDIO_DATA_DIR", str(tmp_path / "data"))
    return tmp_path / "data"


def v(preset: str, fap: int | str) -> float:
    return float(shipped_presets()[preset].vector[FAPS.number(fap) - 1])


# ---------------------------------------------------------------------------- shipped data


def test_all_shipped_presets_load_and_are_in_range():
    presets = shipped_presets()
    files = sorted(shipped_preset_dir().glob("*.json"))
    assert len(presets) == len(files) == 6 + 15
    for path in files:
        p = load_preset(path)
        assert p.name == path.stem and p.source and p.kind in ("emotion", "viseme")
        assert (FAPS.lo <= p.vector).all() and (p.vector <= FAPS.hi).all()
        assert np.array_equal(FAPS.clamp(p.vector), p.vector)
        json.loads(path.read_text())  # plain JSON, human-readable
    assert [p.name for p in presets.values() if p.kind == "emotion"] == \
        [EXPRESSIONS[i] for i in range(1, 7)]
    assert [p.mpeg4_index for p in presets.values() if p.kind == "viseme"] == list(range(15))
    assert all(presets[VISEMES[i]].mpeg4_index == i for i in range(15))
    assert not presets["viseme_neutral"].vector.any()


def test_visemes_are_mouth_only_and_lip_pairs_match():
    for p in shipped_presets().values():
        used = {FAPS.number(k) for k in p.faps}
        if p.kind == "viseme":
            assert used <= MOUTH, (p.name, used - MOUTH)
            assert p.phonemes or p.mpeg4_index == 0
        for inner, outer in INNER_OUTER.items():  # set together (Xface adjustFAPs) ...
            # ... unless the preset's source gives the outer contour's FAP its own reason
            # (disgust curls the outer upper lip's sides, its inner lip stays)
            assert (p.vector[inner - 1] == p.vector[outer - 1]
                    or f"; {outer} = " in p.source), (p.name, inner)


def test_emotions_follow_the_expression_table():
    # FAP signs of the JAFFE-derived presets (scripts/derive_presets.py; lower-lip FAPs are
    # relative to the jaw, so the lower lip's net motion is checked in test_preset_motion.py)
    assert v("joy", "raise_l_cornerlip") > 0 and v("joy", "raise_r_cornerlip_o") > 0
    assert v("joy", "open_jaw") > 0 and v("joy", "lower_t_midlip") < 0
    assert v("joy", "stretch_l_cornerlip") > 0 and v("joy", "lift_l_cheek") > 0
    assert v("sadness", "raise_l_cornerlip") < 0 and v("sadness", "raise_l_i_eyebrow") > 0
    assert v("sadness", "raise_l_o_eyebrow") < 0 and v("sadness", "raise_r_o_eyebrow") < 0
    assert v("surprise", "raise_b_midlip") < 0 and v("surprise", "open_jaw") > 0
    assert all(v("surprise", n) > 0 for n in range(31, 37))
    assert v("anger", "lower_t_midlip") + v("anger", "raise_b_midlip") == 0  # lips stay shut
    assert v("anger", "push_b_lip") < 0 and v("anger", "push_t_lip") < 0
    assert v("anger", "raise_l_o_eyebrow") < 0 and v("anger", "squeeze_l_eyebrow") > 0
    assert v("fear", "raise_b_midlip") < 0 and v("fear", "raise_l_i_eyebrow") > 0
    # fear's brows are drawn together with the inner ends bent upward (the standard's look;
    # FACS AU1+4 as in JAFFE's fear photos): the inner ends rise well above the outer ones, the
    # brow as a whole rises a little. A flat, high brow (AU2 at +20, before) read as surprise
    # to a blind rater; the wide eyes and the open mouth tell this brow from sadness's
    i, m, o = (v("fear", f"raise_l_{k}_eyebrow") for k in "imo")
    assert i > 0 and i - o >= 50 and i + m + o > 0
    assert v("fear", "squeeze_l_eyebrow") > 0
    assert v("fear", "close_t_l_eyelid") < 0
    assert v("disgust", "lower_t_lip_lm_o") < 0 and v("disgust", "raise_l_m_eyebrow") < 0


# ---------------------------------------------------------------------------- intensity / blend


def test_apply_preset_scales_and_clamps():
    joy = shipped_presets()["joy"]
    assert not apply_preset(joy, 0).any()
    assert np.array_equal(apply_preset("joy"), joy.vector)
    assert np.allclose(apply_preset(joy, 0.5), joy.vector * 0.5)
    big = Preset("big", "custom", {"open_jaw": 1000.0, "squeeze_l_eyebrow": -250.0})
    out = apply_preset(big, 1.5)
    assert out[2] == FAPS["open_jaw"].range[1] and out[36] == FAPS["squeeze_l_eyebrow"].range[0]
    for bad in (-0.1, 1.51, float("nan"), True, "1"):
        with pytest.raises(PresetError, match="intensity"):
            apply_preset(joy, bad)


def test_blend_expressions_fap2_semantics():
    p = shipped_presets()
    joy, sad = p["joy"].vector, p["sadness"].vector
    assert np.allclose(blend_expressions(1, 63), joy)
    assert not blend_expressions(0, 63, 0, 63).any()
    assert np.allclose(blend_expressions(1, 21, 2, 42), FAPS.clamp(joy / 3 + sad * 2 / 3))
    assert np.allclose(blend_expressions(1, 63, 2, 63), FAPS.clamp(joy + sad))
    assert np.allclose(blend_expressions(p["fear"], 63), p["fear"].vector)
    assert EXPRESSIONS[6] == "surprise" and np.allclose(blend_expressions(6, 63),
                                                        p["surprise"].vector)
    with pytest.raises(PresetError, match="expression_select"):
        blend_expressions(7, 63)
    with pytest.raises(PresetError, match="intensity1"):
        blend_expressions(1, 64)


def test_blend_visemes_fap1_semantics():
    p = shipped_presets()
    pbm, aa = p["viseme_pbm"].vector, p["viseme_aa"].vector
    assert np.allclose(blend_visemes(1, 10, 63), pbm)
    assert np.allclose(blend_visemes(1, 10, 0), aa)
    assert np.allclose(blend_visemes(1, 10, 40), pbm * 40 / 63 + aa * 23 / 63, atol=1e-3)
    table = {1: np.full(68, 5.0, np.float32) * (np.arange(68) > 1)}
    assert blend_visemes(1, 0, 63, table=table)[2] == 5.0  # per-face table
    with pytest.raises(PresetError, match="viseme_select"):
        blend_visemes(15, 0, 10)
    with pytest.raises(PresetError, match="viseme_blend"):
        blend_visemes(1, 2, -1)


# ---------------------------------------------------------------------------- user presets


def test_user_preset_dir_honours_env_and_xdg(monkeypatch, tmp_path, data_dir):
    assert user_preset_dir() == data_dir / "presets"
    monkeypatch.delenv("FAP_STUDIO_DATA_DIR")
    monkeypatch.setattr("sys.platform", "linux")
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    assert user_preset_dir() == tmp_path / "xdg" / "fap-studio" / "presets"
    monkeypatch.delenv("XDG_DATA_HOME")
    assert user_preset_dir() == Path.home() / ".local" / "share" / "fap-studio" / "presets"


def test_save_and_load_user_preset_round_trip(data_dir):
    vec = apply_preset("joy", 0.8)
    vec[2] += 0.4  # rounded on save
    p = save_user_preset("my_smile", vec, description="a test")
    assert p.path == data_dir / "presets" / "my_smile.json" and not p.shipped
    assert np.array_equal(p.vector, np.sign(vec) * np.floor(np.abs(vec) + 0.5))
    assert user_presets()["my_smile"].description == "a test"
    assert get_preset("MY_SMILE").name == "my_smile"
    assert list(all_presets())[:6] == [EXPRESSIONS[i] for i in range(1, 7)]
    assert "my_smile" in all_presets()
    with pytest.raises(PresetError, match="already exists"):
        save_user_preset("my_smile", vec)
    q = save_user_preset("my_smile", np.zeros(68), overwrite=True)
    assert not q.vector.any() and q.faps == {}


def test_user_preset_never_shadows_a_shipped_one(data_dir):
    for name in ("joy", "JOY", "viseme_aa"):
        with pytest.raises(PresetError, match="shipped"):
            save_user_preset(name, np.zeros(68))
    assert not (data_dir / "presets").exists()
    # a hand-made file with a shipped name is refused when listing
    (data_dir / "presets").mkdir(parents=True)
    doc = {"format": "fap-studio-preset", "version": 1, "kind": "emotion", "name": "joy",
           "faps": {"open_jaw": 5}}
    (data_dir / "presets" / "joy.json").write_text(json.dumps(doc))
    with pytest.raises(PresetError, match="shipped name"):
        user_presets()
    problems: list[str] = []
    assert user_presets(problems) == {} and len(problems) == 1
    assert np.array_equal(get_preset("joy").vector, shipped_presets()["joy"].vector)


@pytest.mark.parametrize("name, vec, match", [
    ("has space", np.zeros(68), "preset name"),
    ("", np.zeros(68), "preset name"),
    ("ok", np.zeros(67), "68 finite"),
    ("ok", np.r_[1.0, np.zeros(67)], "FAP 1/2"),
    ("ok", FAPS.vector({"open_jaw": 5000}), "outside its range"),
])
def test_save_user_preset_rejects(name, vec, match, data_dir):
    with pytest.raises(PresetError, match=match):
        save_user_preset(name, vec)
    assert not (data_dir / "presets").exists() or not any((data_dir / "presets").iterdir())


# ---------------------------------------------------------------------------- malformed files


GOOD = {"format": "fap-studio-preset", "version": 1, "kind": "emotion", "name": "x",
        "mpeg4_index": None, "source": "test", "faps": {"open_jaw": 100}}


@pytest.mark.parametrize("change, match", [
    ({"format": "other"}, "format"),
    ({"version": 2}, "newer"),
    ({"version": "1"}, "version"),
    ({"kind": "mood"}, "kind"),
    ({"name": "a b"}, "preset name"),
    ({"mpeg4_index": 7}, "mpeg4_index"),
    ({"faps": {"open_jaww": 1}}, "unknown FAP name 'open_jaww' \\(did you mean 'open_jaw'"),
    ({"faps": {"viseme": 1}}, "unknown FAP name"),
    ({"faps": {"3": 1}}, "unknown FAP name"),
    ({"faps": {"open_jaw": "big"}}, "not a finite number"),
    ({"faps": {"open_jaw": True}}, "not a finite number"),
    ({"faps": {"open_jaw": float("nan")}}, "not a finite number"),
    ({"faps": {"open_jaw": 2000}}, "outside its range 0 .. 1080"),
    ({"faps": [1, 2]}, "faps"),
    ({"source": 5}, "strings"),
    ({"phonemes": "p"}, "phonemes"),
])
def test_malformed_presets(change, match, tmp_path):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps({**GOOD, **change}))
    with pytest.raises(PresetError, match=match):
        load_preset(path)


def test_malformed_json_and_structure(tmp_path):
    path = tmp_path / "broken.json"
    path.write_text('{\n  "format": "fap-studio-preset",\n  "faps": {,}\n}')
    with pytest.raises(PresetError, match="broken.json line 3: not valid JSON"):
        load_preset(path)
    path.write_text('{"format": "fap-studio-preset", "format": "x"}')
    with pytest.raises(PresetError, match="duplicate"):
        load_preset(path)
    path.write_text("[1, 2]")
    with pytest.raises(PresetError, match="JSON object"):
        load_preset(path)
    path.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(PresetError, match="cannot read"):
        load_preset(path)
    with pytest.raises(PresetError, match="cannot read"):
        load_preset(tmp_path / "missing.json")
    assert preset_from_dict(GOOD).vector[2] == 100
    with pytest.raises(PresetError, match="unknown preset"):
        get_preset("no_such_preset")


def test_broken_user_preset_is_named_not_unknown(tmp_path, monkeypatch):
    from editor.errors import PresetError
    from editor.formats.presets import get_preset

    monkeypatch.setenv("FAP_STUDIO_DATA_DIR", str(tmp_path))
    (tmp_path / "presets").mkdir()
    (tmp_path / "presets" / "grin.json").write_text(
        '{"format": "fap-studio-preset", "version": 1, "kind": "emotion", "name": "grin", '
        '"faps": {"open_jaw": "lots"}}')
    with pytest.raises(PresetError, match=r"grin\.json: open_jaw"):
        get_preset("grin")
    assert get_preset("joy").name == "joy"  # shipped presets still load beside it
