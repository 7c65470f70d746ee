"""A large, soft face (the bench's 4K face: the sample upscaled to 1000 px wide, 470 px between
the eyes, edges ramping over 15 px) draws its folds, eyeballs and wide blurs on blocks of 2-3 px
and upsamples them (:func:`~editor.engine.creases._frame_blocks`,
:data:`~editor.engine.layers.EYE_BLOCK_SOFT`, :data:`~editor.engine.layers.WIDE_SIGMA`): the
frame stays within a few grey levels of the per-pixel drawing, and faces up to 1080p are drawn
per pixel (their renders do not change: the bit-identity sets of the speed work)."""

from __future__ import annotations

import numpy as np
import pytest

import editor.engine.creases as creases
import editor.engine.layers as layers
from editor.bench import EXPRESSION, _face_at, _time_pair
from editor.bench_render import Helpers, _face_wide
from editor.core import FAPS, apply_preset


@pytest.fixture(scope="module")
def face_4k():
    hp = Helpers(lambda d: None, _face_at, _time_pair, EXPRESSION)
    return _face_wide(hp, (3840, 2160), 1000.0)


def test_block_factors_by_face(face_4k, sample_face):
    assert creases._frame_blocks(face_4k) > 1
    assert int(layers.layer_plan(face_4k).soft // layers.EYE_BLOCK_SOFT) > 1
    assert creases._frame_blocks(sample_face) == 1
    assert layers.layer_plan(sample_face).soft < layers.EYE_BLOCK_SOFT


@pytest.mark.parametrize("vec", [FAPS.clamp(FAPS.vector(EXPRESSION)), apply_preset("fear", 1.2)],
                         ids=["bench", "fear"])
def test_blocks_close_to_per_pixel(face_4k, vec, monkeypatch):
    got = face_4k.render(vec)
    monkeypatch.setattr(creases, "_frame_blocks", lambda face: 1)
    monkeypatch.setattr(layers, "EYE_BLOCK_SOFT", float("inf"))
    monkeypatch.setattr(layers, "WIDE_SIGMA", float("inf"))
    ref = face_4k.render(vec)
    d = np.abs(got.astype(np.int16) - ref).max(2)
    assert d.max() <= 12
    assert d.mean() <= 0.01  # over the frame (~0.005 measured)
    assert (d > 2).mean() <= 1e-3
