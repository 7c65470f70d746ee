"""Old import path of the presets, blends and sequence authoring (kept while parallel branches
move to the new modules; nothing below it imports it).

Use :mod:`.presets` (preset files), :mod:`.blends` (MPEG-4 FAP 1/2 blends),
:mod:`.keyframes` (:func:`sequence_from_keyframes`) and :mod:`.fapfile`
(:func:`expand_high_level`, :func:`fap_info`).
"""

from .blends import EXPRESSIONS, VISEMES, blend_expressions, blend_visemes
from .fapfile import expand_high_level, fap_info
from .keyframes import sequence_from_keyframes
from .presets import (
    KINDS,
    MAX_INTENSITY,
    MAX_PRESET_BYTES,
    PRESET_FORMAT,
    PRESET_VERSION,
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

__all__ = ["EXPRESSIONS", "KINDS", "MAX_INTENSITY", "MAX_PRESET_BYTES", "PRESET_FORMAT",
           "PRESET_VERSION", "VISEMES", "Preset", "all_presets", "apply_preset",
           "blend_expressions", "blend_visemes", "expand_high_level", "fap_info", "get_preset",
           "load_preset", "preset_from_dict", "save_user_preset", "sequence_from_keyframes",
           "shipped_preset_dir", "shipped_presets", "user_preset_dir", "user_presets"]
