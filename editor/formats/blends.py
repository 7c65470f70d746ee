"""MPEG-4 high-level FAPs: FAP 2 (expression) and FAP 1 (viseme) blends of presets.

Numbering (MPEG4_FAP.md §4): :data:`EXPRESSIONS` 0-6, :data:`VISEMES` 0-14, each naming a
shipped preset. FAP 2 blend: p1·i1/63 + p2·i2/63; FAP 1 blend: v1·blend/63 + v2·(1 - blend/63);
results clamped to the FAP ranges. A per-face ``table`` may replace the shipped presets.
:func:`editor.formats.fapfile.expand_high_level` applies these blends to a sequence.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from editor.engine.faps import FAPS
from editor.errors import PresetError

from .presets import Preset, number_in, shipped_presets

#: MPEG-4 expression_select -> shipped preset name (0 = neutral: all zero).
EXPRESSIONS = {0: "neutral", 1: "joy", 2: "sadness", 3: "anger", 4: "fear", 5: "disgust",
               6: "surprise"}
#: MPEG-4 viseme_select -> shipped preset name (phonemes: the preset's ``phonemes``).
VISEMES = {i: "viseme_" + n for i, n in enumerate(
    ("neutral", "pbm", "fv", "th", "td", "kg", "ch", "sz", "nl", "r", "aa", "e", "i", "q", "u"))}



def _vector(sel: int | Preset | np.ndarray, table: Mapping[int, object] | None,
            names: Mapping[int, str], what: str) -> np.ndarray:
    if isinstance(sel, Preset):
        return sel.vector
    if isinstance(sel, np.ndarray):
        return np.asarray(sel, np.float32).reshape(68)
    if isinstance(sel, bool) or not isinstance(sel, (int, np.integer)) or sel not in names:
        raise PresetError(f"{what} must be 0-{max(names)}, got {sel!r}")
    if table is not None and int(sel) in table:
        return _vector(table[int(sel)], None, names, what)  # type: ignore[arg-type]
    if int(sel) == 0 and what == "expression_select":
        return np.zeros(68, np.float32)
    return shipped_presets()[names[int(sel)]].vector


def _weight(x: float, what: str) -> float:
    if not number_in(x, 0, 63):
        raise PresetError(f"{what} must be 0-63, got {x!r}")
    return float(x) / 63.0


def blend_expressions(sel1: int | Preset, int1: float, sel2: int | Preset = 0, int2: float = 0,
                      *, table: Mapping[int, Preset | np.ndarray] | None = None) -> np.ndarray:
    """FAP 2: p1·int1/63 + p2·int2/63 (intensities 0-63), clamped. ``sel``: 0-6 or a Preset;
    ``table`` overrides the shipped presets per index (a per-face table)."""
    v = (_vector(sel1, table, EXPRESSIONS, "expression_select") * _weight(int1, "intensity1")
         + _vector(sel2, table, EXPRESSIONS, "expression_select") * _weight(int2, "intensity2"))
    return FAPS.clamp(v)


def blend_visemes(sel1: int | Preset, sel2: int | Preset, blend: float,
                  *, table: Mapping[int, Preset | np.ndarray] | None = None) -> np.ndarray:
    """FAP 1: v1·blend/63 + v2·(1 - blend/63) (blend 0-63), clamped. ``sel``: 0-14 or a Preset."""
    w = _weight(blend, "viseme_blend")
    v = (_vector(sel1, table, VISEMES, "viseme_select") * w
         + _vector(sel2, table, VISEMES, "viseme_select") * (1 - w))
    return FAPS.clamp(v)
