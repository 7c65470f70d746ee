"""Expression presets: named sets of low-level FAP values, shipped and user-made.

A preset is a JSON file (shipped in ``editor/data/presets/``, user ones in :func:`user_preset_dir`):
``{"format": "fap-studio-preset", "version": 1, "kind": "emotion"|"viseme"|"custom",
"name": "joy", "mpeg4_index": 1, "source": "...", "faps": {"open_jaw": 100, ...}}`` with values
in FAPU keyed by low-level FAP name (3-68), finite and inside ``FAPS[n].range``; optional
``description``, ``phonemes``, ``examples``; other keys are ignored. :class:`PresetError` else.

The MPEG-4 FAP 1/2 blends of presets live in :mod:`.blends`.
"""

from __future__ import annotations

import difflib
import json
import math
import os
import re
from dataclasses import dataclass, field
from datetime import date
from functools import lru_cache
from pathlib import Path

import numpy as np

from editor.engine.faps import FAPS, check_vector, round_half_away
from editor.errors import PresetError
from editor.resources import PRESETS_DIR, user_data_dir
from editor.safeio import atomic_write_text, read_bounded

PRESET_FORMAT = "fap-studio-preset"
PRESET_VERSION = 1
KINDS = ("emotion", "viseme", "custom")
MAX_INTENSITY = 1.5
MAX_PRESET_BYTES = 1 << 20
_LOW_LEVEL = {FAPS[n].name: FAPS[n] for n in range(3, 69)}
_NAME_CHARS = set("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-")


@dataclass(frozen=True, eq=False)
class Preset:
    """A named set of low-level FAP values (FAPU), keyed by FAP name.

    Loaded by :func:`get_preset` / :func:`all_presets` (or :func:`load_preset`), validated on
    creation from a file; :func:`apply_preset` scales one to an intensity.

    Parameters
    ----------
    name : str
        1-64 letters, digits, ``_`` or ``-``.
    kind : str
        ``"emotion"``, ``"viseme"`` or ``"custom"``.
    faps : dict
        Low-level FAP name (3-68) -> value in FAPU.
    mpeg4_index : int, optional
        The MPEG-4 expression (1-6) or viseme (0-14) number, for FAP 2 / FAP 1 blends.
    source, description : str
        Where the values come from; what the preset shows.
    phonemes : tuple of str
        A viseme's phonemes.
    path : pathlib.Path, optional
        The file it was loaded from.
    shipped : bool
        Shipped with FAP Studio (not a user preset).

    Attributes
    ----------
    vector : (68,) float32
        The values as a read-only FAP vector.

    Examples
    --------
    >>> from editor.core import FAPS, get_preset
    >>> joy = get_preset("joy")
    >>> joy.kind, joy.mpeg4_index, joy.shipped
    ('emotion', 1, True)
    >>> i = FAPS.number("raise_l_cornerlip_o") - 1  # FAP 59 is column 58 of a FAP vector
    >>> joy.faps["raise_l_cornerlip_o"] == float(joy.vector[i])
    True
    """

    name: str
    kind: str
    faps: dict[str, float]
    mpeg4_index: int | None = None
    source: str = ""
    description: str = ""
    phonemes: tuple[str, ...] = ()
    path: Path | None = None
    shipped: bool = False
    vector: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "vector", FAPS.vector(self.faps))
        self.vector.flags.writeable = False


def shipped_preset_dir() -> Path:
    """The shipped presets' folder (package data ``editor/data/presets``)."""
    return PRESETS_DIR


def user_preset_dir() -> Path:
    """``presets`` in :func:`editor.resources.user_data_dir` (``$FAP_STUDIO_DATA_DIR``, else the
    per-OS user data folder, e.g. ``~/.local/share/fap-studio``). Not created here."""
    return user_data_dir() / "presets"


def _check_name(name: object, label: str) -> str:
    if not isinstance(name, str) or not 1 <= len(name) <= 64 or not set(name) <= _NAME_CHARS:
        raise PresetError(f"{label}: preset name must be 1-64 letters, digits, '_' or '-', "
                          f"got {name!r}")
    return name


def _no_duplicates(pairs: list[tuple[str, object]]) -> dict:
    if len(d := dict(pairs)) != len(pairs):
        raise ValueError(f"duplicate key in a JSON object ({', '.join(k for k, _ in pairs)})")
    return d


def preset_from_dict(data: object, label: str = "<preset>", *, path: Path | None = None,
                     shipped: bool = False) -> Preset:
    """Validate a decoded preset document; :class:`PresetError` naming the problem."""
    if not isinstance(data, dict):
        raise PresetError(f"{label}: expected a JSON object, got {type(data).__name__}")
    if data.get("format") != PRESET_FORMAT:
        raise PresetError(f"{label}: expected \"format\": \"{PRESET_FORMAT}\", "
                          f"got {data.get('format')!r}")
    ver = data.get("version")
    if isinstance(ver, bool) or not isinstance(ver, int) or ver != PRESET_VERSION:
        newer = " (written by a newer FAP Studio?)" if isinstance(ver, int) and ver > 1 else ""
        raise PresetError(f"{label}: expected \"version\": {PRESET_VERSION}, got {ver!r}{newer}")
    kind = data.get("kind")
    if kind not in KINDS:
        raise PresetError(f"{label}: expected \"kind\" one of {', '.join(KINDS)}, got {kind!r}")
    name = _check_name(data.get("name"), label)
    idx = data.get("mpeg4_index")
    top = {"emotion": 6, "viseme": 14}.get(kind, -1)
    if idx is not None and (isinstance(idx, bool) or not isinstance(idx, int)
                            or not 0 <= idx <= top):
        raise PresetError(f"{label}: mpeg4_index of a {kind} preset must be "
                          f"{'null' if top < 0 else f'0-{top} or null'}, got {idx!r}")
    texts = {k: data.get(k, "") for k in ("source", "description", "examples")}
    phon = data.get("phonemes", [])
    if type(phon) is not list or not all(isinstance(v, str) for v in [*texts.values(), *phon]):
        raise PresetError(f"{label}: expected strings for source, description, examples and "
                          "a list of strings for phonemes")
    faps = data.get("faps")
    if not isinstance(faps, dict):
        raise PresetError(f"{label}: expected \"faps\": an object of FAP name -> value")
    out: dict[str, float] = {}
    for key, val in faps.items():
        fap = _LOW_LEVEL.get(key) if isinstance(key, str) else None
        if fap is None:
            close = difflib.get_close_matches(str(key), list(_LOW_LEVEL), 1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise PresetError(f"{label}: unknown FAP name {key!r}{hint}; expected an MPEG-4 "
                              "low-level FAP name (3-68)")
        if isinstance(val, int) and not isinstance(val, bool):
            val = float(val) if abs(val) < 2**63 else math.inf  # no OverflowError on 10**400
        if isinstance(val, bool) or not isinstance(val, float) or not math.isfinite(val):
            raise PresetError(f"{label}: {key} = {str(val)[:24]} is not a finite number in "
                              "its range")
        lo, hi = fap.range
        if not lo <= val <= hi:
            raise PresetError(f"{label}: {key} = {val:g} is outside its range {lo:g} .. {hi:g}")
        out[key] = float(val)
    return Preset(name, kind, out, idx, texts["source"], texts["description"], tuple(phon),
                  path, shipped)


def load_preset(path: str | os.PathLike, *, shipped: bool = False) -> Preset:
    """Load and validate one preset file; :class:`PresetError` if it is malformed."""
    path = Path(path)
    data = read_bounded(path, MAX_PRESET_BYTES, error=PresetError, label=path.name,
                        what="a preset file")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise PresetError(f"{path.name}: cannot read the preset (not UTF-8 text)") from e
    try:
        data = json.loads(text, object_pairs_hook=_no_duplicates)
    except json.JSONDecodeError as e:
        raise PresetError(f"{path.name} line {e.lineno}: not valid JSON ({e.msg})") from e
    except (ValueError, RecursionError) as e:  # int digit limit, duplicate key, deep nesting
        why = "nested too deeply" if isinstance(e, RecursionError) else str(e)[:120]
        raise PresetError(f"{path.name}: not a valid preset ({why})") from None
    return preset_from_dict(data, path.name, path=path, shipped=shipped)


@lru_cache(maxsize=4)
def _load_shipped(directory: Path) -> tuple[Preset, ...]:
    presets = [load_preset(p, shipped=True) for p in sorted(directory.glob("*.json"))]
    names = [p.name.lower() for p in presets]
    if len(set(names)) != len(names):
        raise PresetError(f"{directory}: two shipped presets share a name")
    order = {"emotion": 0, "viseme": 1, "custom": 2}
    return tuple(sorted(presets, key=lambda p: (order[p.kind], p.mpeg4_index or 0, p.name)))


def shipped_presets() -> dict[str, Preset]:
    """The shipped presets by name: emotions, then visemes, in MPEG-4 index order."""
    return {p.name: p for p in _load_shipped(shipped_preset_dir())}


def user_presets(problems: list[str] | None = None) -> dict[str, Preset]:
    """User presets by name. Malformed files (or ones shadowing a shipped name) raise
    :class:`PresetError`, or are skipped with their message appended to ``problems``."""
    shipped = {n.lower() for n in shipped_presets()}
    out: dict[str, Preset] = {}
    d = user_preset_dir()
    for path in sorted(d.glob("*.json")) if d.is_dir() else []:
        try:
            p = load_preset(path)
            if p.name.lower() in shipped:
                raise PresetError(f"{path.name}: user preset {p.name!r} has a shipped name")
        except PresetError as e:
            if problems is None:
                raise
            problems.append(str(e))
            continue
        out[p.name] = p
    return out


def all_presets(problems: list[str] | None = None) -> dict[str, Preset]:
    """Shipped presets followed by user presets, by name.

    Parameters
    ----------
    problems : list of str, optional
        If given, a malformed user preset file is skipped and its one-line message appended
        here; otherwise it raises.

    Returns
    -------
    dict
        name -> :class:`Preset`: the emotions and visemes in MPEG-4 order, then the user's.

    Raises
    ------
    PresetError
        A malformed user preset file (or one shadowing a shipped name), unless ``problems``
        collects it.

    Examples
    --------
    >>> from editor.core import all_presets
    >>> presets = all_presets(problems=[])
    >>> list(presets)[:6]
    ['joy', 'sadness', 'anger', 'fear', 'disgust', 'surprise']
    >>> presets["viseme_aa"].kind, presets["viseme_aa"].mpeg4_index
    ('viseme', 10)
    """
    return {**shipped_presets(), **user_presets(problems)}


def get_preset(name: str) -> Preset:
    """A shipped or user preset by name (case-insensitive).

    Parameters
    ----------
    name : str
        e.g. ``"joy"``, ``"Viseme_AA"``.

    Returns
    -------
    Preset

    Raises
    ------
    PresetError
        No preset has that name (the message lists them), or the user preset file of that
        name is malformed (the message says why).

    Examples
    --------
    >>> from editor.core import get_preset
    >>> get_preset("SURPRISE").name
    'surprise'
    >>> get_preset("grin")
    Traceback (most recent call last):
    ...
    editor.errors.PresetError: unknown preset 'grin'; expected one of joy, sadness, ...
    """
    problems: list[str] = []
    found = {k.lower(): p for k, p in all_presets(problems).items()}
    if name.lower() not in found:
        # a user preset file of that name that failed to load: say why, not just "unknown"
        broken = [m for m in problems if m.lower().startswith(f"{name.lower()}.json")]
        if broken:
            raise PresetError(broken[0])
        raise PresetError(f"unknown preset {name!r}; expected one of {', '.join(found)}")
    return found[name.lower()]


def save_user_preset(name: str, vector: np.ndarray, *, kind: str = "custom",
                     source: str | None = None, description: str = "",
                     overwrite: bool = False) -> Preset:
    """Save a (68,) low-level vector (rounded; in range; FAP 1/2 zero) as ``<name>.json`` in
    :func:`user_preset_dir`, atomically. Never shadows a shipped name (case-insensitive); replaces
    a user preset only with ``overwrite=True``."""
    _check_name(name, "save")
    if kind not in KINDS:
        raise PresetError(f"save: kind must be one of {', '.join(KINDS)}, got {kind!r}")
    if name.lower() in {n.lower() for n in shipped_presets()}:
        raise PresetError(f"{name!r} is a shipped preset; choose another name")
    try:
        v = check_vector(vector)
    except ValueError as e:
        raise PresetError(f"save: {e}") from None
    d = user_preset_dir()
    path = d / f"{name}.json"
    existing = [p for p in d.glob("*.json") if p.stem.lower() == name.lower()] if d.is_dir() else []
    if existing and not overwrite:
        raise PresetError(f"a user preset {existing[0].stem!r} already exists")
    doc = preset_document(v, name, source or f"saved by the user on {date.today().isoformat()}",
                          kind=kind, extra={"description": description})
    atomic_write_text(path, json.dumps(doc, indent=2, ensure_ascii=False) + "\n",
                      error=PresetError, label=f"user preset {name!r}")
    try:
        for old in existing:  # the same name in other letter case: replaced
            if old != path and old.exists() and not old.samefile(path):  # case-insensitive FS
                old.unlink()
    except OSError as e:
        raise PresetError(f"user preset {name!r}: cannot remove {old.name} ({e})") from e
    return load_preset(path)


def preset_name(text: str, default: str = "preset") -> str:
    """``text`` made a valid preset name: other characters become ``_``, at most 64.

    Examples
    --------
    >>> preset_name("joy (take 2)")
    'joy__take_2_'
    """
    return re.sub(r"[^A-Za-z0-9_-]", "_", text)[:64] or default


def preset_document(vector: np.ndarray, name: str, source: str, *, kind: str = "custom",
                    extra: dict | None = None) -> dict:
    """The preset document of a (68,) low-level vector, values rounded half away from zero.

    FAP 1/2 and zero values are left out; ``extra`` keys are added (e.g. ``description``).
    :class:`PresetError` if the result is not a valid preset (a name, kind or value out of
    range: clamp first with ``FAPS.clamp`` where that is wanted).

    Examples
    --------
    >>> preset_document(FAPS.vector({"open_jaw": 99.5}), "mine", "a doctest")["faps"]
    {'open_jaw': 100}
    """
    v = round_half_away(np.asarray(vector, np.float64).reshape(68))
    doc = {"format": PRESET_FORMAT, "version": PRESET_VERSION, "kind": kind, "name": name,
           "mpeg4_index": None, "source": source,
           "faps": {FAPS[i + 1].name: int(x) for i, x in enumerate(v) if i >= 2 and x != 0}}
    doc.update(extra or {})
    preset_from_dict(doc, name)  # validate (names, ranges) before anything is written
    return doc


def apply_preset(preset: Preset | str, intensity: float = 1.0) -> np.ndarray:
    """The preset's values × ``intensity``, clamped to the FAP ranges: a FAP vector.

    Parameters
    ----------
    preset : Preset or str
        A preset or its name (see :func:`get_preset`).
    intensity : float, default 1.0
        0-1.5 (0-150 %).

    Returns
    -------
    numpy.ndarray
        (68,) float32 FAP vector, FAPU.

    Raises
    ------
    PresetError
        An unknown preset name, or an intensity outside 0-1.5.

    Examples
    --------
    >>> from editor.core import FAPS, apply_preset, get_preset
    >>> full = get_preset("joy").faps["raise_l_cornerlip_o"]
    >>> half = apply_preset("joy", 0.5)[FAPS.number("raise_l_cornerlip_o") - 1]
    >>> bool(half == full / 2)
    True
    >>> apply_preset("joy").shape
    (68,)
    """
    p = get_preset(preset) if isinstance(preset, str) else preset
    if not number_in(intensity, 0, MAX_INTENSITY):
        raise PresetError(f"intensity must be 0-{MAX_INTENSITY:g} (0-150 %), got {intensity!r}")
    return FAPS.clamp(p.vector * np.float32(intensity))


def number_in(x: object, lo: float, hi: float) -> bool:
    """``x`` is a real number (not a bool, not a string) in [lo, hi]."""
    return (isinstance(x, (int, float, np.number)) and not isinstance(x, bool)
            and bool(lo <= x <= hi))
