"""Emotion and viseme presets (FAP 2 / FAP 1), user presets, sequence authoring, ``fap info``.

A preset is a JSON file (shipped in ``editor/data/presets/``, user ones in :func:`user_preset_dir`):
``{"format": "fap-studio-preset", "version": 1, "kind": "emotion"|"viseme"|"custom",
"name": "joy", "mpeg4_index": 1, "source": "...", "faps": {"open_jaw": 100, ...}}`` with values
in FAPU keyed by low-level FAP name (3-68), finite and inside ``FAPS[n].range``; optional
``description``, ``phonemes``, ``examples``; other keys are ignored. :class:`PresetError` else.

MPEG-4 numbering (MPEG4_FAP.md §4): :data:`EXPRESSIONS` 0-6, :data:`VISEMES` 0-14. FAP 2 blend:
p1·i1/63 + p2·i2/63; FAP 1 blend: v1·blend/63 + v2·(1 - blend/63); results clamped to the FAP
ranges. :func:`expand_high_level` *adds* the blend to the frame's low-level FAPs (the standard's
init_face reading). :func:`sequence_from_keyframes` and :func:`fap_info` are re-exported by
:mod:`.fapfile` (kept here for its size limit).
"""

from __future__ import annotations

import difflib
import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import date
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from editor.engine.faps import FAPS
from editor.errors import PresetError
from editor.resources import PRESETS_DIR, user_data_dir
from editor.safeio import read_bounded

if TYPE_CHECKING:
    from .fapfile import FapSequence

PRESET_FORMAT = "fap-studio-preset"
PRESET_VERSION = 1
KINDS = ("emotion", "viseme", "custom")
MAX_INTENSITY = 1.5
MAX_PRESET_BYTES = 1 << 20
_LOW_LEVEL = {FAPS[n].name: FAPS[n] for n in range(3, 69)}
_NAME_CHARS = set("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-")

#: MPEG-4 expression_select -> shipped preset name (0 = neutral: all zero).
EXPRESSIONS = {0: "neutral", 1: "joy", 2: "sadness", 3: "anger", 4: "fear", 5: "disgust",
               6: "surprise"}
#: MPEG-4 viseme_select -> shipped preset name (phonemes: the preset's ``phonemes``).
VISEMES = {i: "viseme_" + n for i, n in enumerate(
    ("neutral", "pbm", "fv", "th", "td", "kg", "ch", "sz", "nl", "r", "aa", "e", "i", "q", "u"))}


@dataclass(frozen=True, eq=False)
class Preset:
    """A named set of low-level FAP values (FAPU), keyed by FAP name."""

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
    """Shipped presets followed by user presets (see :func:`user_presets`)."""
    return {**shipped_presets(), **user_presets(problems)}


def get_preset(name: str) -> Preset:
    """A shipped or user preset by name (case-insensitive); :class:`PresetError` if unknown."""
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
    from .fapfile import check_vector, round_half_away

    try:
        v = check_vector(vector)
    except ValueError as e:
        raise PresetError(f"save: {e}") from None
    d = user_preset_dir()
    path = d / f"{name}.json"
    existing = [p for p in d.glob("*.json") if p.stem.lower() == name.lower()] if d.is_dir() else []
    if existing and not overwrite:
        raise PresetError(f"a user preset {existing[0].stem!r} already exists")
    faps = {FAPS[i + 1].name: int(x) for i, x in enumerate(round_half_away(v)) if x != 0}
    doc = {"format": PRESET_FORMAT, "version": PRESET_VERSION, "kind": kind, "name": name,
           "mpeg4_index": None, "description": description,
           "source": source or f"saved by the user on {date.today().isoformat()}", "faps": faps}
    preset_from_dict(doc, name)  # validate (ranges) before touching the disk
    tmp = d / f".{name}.json.{os.getpid()}.tmp"
    try:
        d.mkdir(parents=True, exist_ok=True)
        tmp.write_text(json.dumps(doc, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
        for old in existing:
            if old != path:
                old.unlink()
        os.replace(tmp, path)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        raise PresetError(f"cannot save user preset {name!r} ({e})") from e
    return load_preset(path)


def apply_preset(preset: Preset | str, intensity: float = 1.0) -> np.ndarray:
    """(68,) float32: the preset's values × ``intensity`` (0-1.5), clamped to the FAP ranges."""
    p = get_preset(preset) if isinstance(preset, str) else preset
    if not _number_in(intensity, 0, MAX_INTENSITY):
        raise PresetError(f"intensity must be 0-{MAX_INTENSITY:g} (0-150 %), got {intensity!r}")
    return FAPS.clamp(p.vector * np.float32(intensity))


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


def _number_in(x: object, lo: float, hi: float) -> bool:
    return (isinstance(x, (int, float, np.number)) and not isinstance(x, bool)
            and bool(lo <= x <= hi))


def _weight(x: float, what: str) -> float:
    if not _number_in(x, 0, 63):
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


def expand_high_level(seq: FapSequence, *,
                      expression_table: Mapping[int, Preset | np.ndarray] | None = None,
                      viseme_table: Mapping[int, Preset | np.ndarray] | None = None
                      ) -> FapSequence:
    """A copy of ``seq`` with FAP 1/2 expanded into low-level FAPs and unmasked.

    Xface-form fields: the blends (shipped presets unless a per-face table is given) are added
    to the frame's low-level values, rounded, and their FAPs (plus L/R partners) masked. Plain
    one-token FAP 1/2 values have no meaning and are dropped. Noted in ``notes``.
    """
    from .fapfile import FapSequence, partner_mask, round_half_away

    frames, masks = seq.frames.astype(np.float64), seq.masks.copy()
    done, plain = 0, int(seq.masks[:, :2].any(axis=1).sum())
    for k, (vis, expr) in enumerate(zip(seq.visemes, seq.expressions, strict=True)):
        add = np.zeros(68)
        if vis is not None:
            add += blend_visemes(vis.select1, vis.select2, vis.blend, table=viseme_table)
        if expr is not None:
            add += blend_expressions(expr.select1, expr.intensity1, expr.select2,
                                     expr.intensity2, table=expression_table)
        done += vis is not None or expr is not None
        frames[k] = round_half_away(frames[k] + add)
        masks[k] |= partner_mask(add != 0)
    frames[:, :2] = 0
    masks[:, :2] = False
    notes = seq.notes + [t for c, t in (
        (done, f"FAP 1/2 fields of {done} frame(s) expanded into low-level FAPs"),
        (plain - done, f"plain FAP 1/2 tokens of {plain - done} frame(s) dropped")) if c]
    return FapSequence(frames, masks, fps=seq.fps, name=seq.name, version=seq.version,
                       frame_numbers=seq.frame_numbers, notes=notes)


def sequence_from_keyframes(keys: Sequence[tuple[float, np.ndarray]], fps: float = 25.0,
                            interpolation: str = "linear", name: str = "keyframes"
                            ) -> FapSequence:
    """A sequence from ``(time_s, (68,) vector)`` keys (e.g. neutral -> joy -> neutral), sampled
    at t = k/fps up to the last key, ``"linear"`` or ``"smoothstep"`` (u²(3 - 2u)) in between,
    first key held before it; integer values; mask = FAPs non-zero in any key + L/R partners."""
    from .fapfile import MAX_FPS, MAX_FRAMES, FapSequence, check_vector, partner_mask
    from .fapfile import round_half_away as rnd

    if interpolation not in ("linear", "smoothstep"):
        raise ValueError(f"interpolation must be 'linear' or 'smoothstep', got {interpolation!r}")
    if not keys or not 0 < float(fps) <= MAX_FPS:
        raise ValueError(f"need at least one keyframe and 0 < fps <= {MAX_FPS:g}")
    pairs = sorted(((float(t), check_vector(v)) for t, v in keys), key=lambda p: p[0])
    times, vals = np.array([t for t, _ in pairs]), np.stack([v for _, v in pairs])
    if not np.isfinite(times).all() or times[0] < 0 or np.any(np.diff(times) <= 0):
        raise ValueError("keyframe times must be finite, >= 0 and distinct")
    n = int(round(times[-1] * fps)) + 1
    if n > MAX_FRAMES:
        raise ValueError(f"{n} frames is more than {MAX_FRAMES}")
    t = np.minimum(np.arange(n) / fps, times[-1])
    j = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 1)
    j1 = np.minimum(j + 1, len(times) - 1)
    u = np.clip((t - times[j]) / np.where(j1 > j, times[j1] - times[j], 1.0), 0.0, 1.0)
    if interpolation == "smoothstep":
        u = u * u * (3 - 2 * u)
    out = rnd(vals[j] + (vals[j1] - vals[j]) * u[:, None])
    m = partner_mask((vals != 0).any(axis=0))
    return FapSequence(out, np.repeat(m[None], n, 0), fps=fps, name=name)


def fap_info(seq: FapSequence) -> str:
    """Summary for ``fap info``: version, name, fps, frames, duration, FAPs used, notes."""
    from .fapfile import fps_text

    nv = sum(v is not None for v in seq.visemes)
    ne = sum(e is not None for e in seq.expressions)
    plain = ", plain one-token form (no meaning)" if seq.has_high_level and not nv + ne else ""
    lines = [f"version:  {seq.version}", f"name:     {seq.name}",
             f"fps:      {fps_text(seq.fps)}",
             f"frames:   {seq.n_frames} (numbered {seq.frame_numbers[0]}-"
             f"{seq.frame_numbers[-1]})", f"duration: {seq.duration:.3f} s",
             f"FAP 1/2:  viseme fields in {nv} frame(s), expression fields in {ne} frame(s)"
             + plain]
    used = [n for n in seq.used_faps() if n > 2]
    lines.append(f"FAPs used ({len(used)}):")
    for n in used:
        col = seq.frames[seq.masks[:, n - 1], n - 1]
        lines.append(f"  {n:2d} {FAPS[n].name:<22} in {col.size} frame(s), "
                     f"values {col.min():g} .. {col.max():g}")
    return "\n".join(lines + (["notes:"] + [f"  - {t}" for t in seq.notes] if seq.notes else []))
