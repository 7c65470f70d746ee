"""The paper's study design (SPEC §4) as plain constants (no numpy, no SQLite).

Here, not in :mod:`.mos` or :mod:`.stimuli`, so that ``fap-studio --help`` (the default of
``study create --presets``) imports neither the study store nor the renderer (issue 15).
"""

#: The paper's design (SPEC §4): these five expressions on every face, full intensity.
PAPER_EXPRESSIONS = ("joy", "sadness", "anger", "fear", "surprise")
