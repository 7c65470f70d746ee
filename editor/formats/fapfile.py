"""MPEG-4 ASCII FAP files (``.fap`` 2.1, MPEG4_FAP.md §5.1): reader and writer.

Reader, tolerant where producers differ: CRLF/CR, tabs, extra spaces, BOM, blank and ``#`` lines
anywhere; header version = first token, fps and count = the last two, name = the rest (Greta:
spaces); 2.0 read as 2.1; 69-flag masks (Greta, 69th ignored); decimal values rounded half away
from zero (Xface); frames numbered from 1 (VREng). Never clamps; unmasked FAPs are 0. One mask
line then one data line per frame. FAP 1/2: by token count per data line, the Xface form (FAP 1:
select1 select2 blend def; FAP 2: select1 intensity1 select2 intensity2 init_face def) goes to
``visemes``/``expressions``; the plain one-token form (Greta/VREng) stays in ``frames[:, 0/1]``
with no defined meaning. Tolerances used are listed in ``notes``. Bad counts, numbers or flags,
truncation, extra data, counts > :data:`MAX_FRAMES`, NUL bytes, non-UTF-8: :class:`FapFileError`
``"<file> line <k>: expected ..., got ..."``, never a partial load.

Writer: ``2.1 <name_without_spaces> <fps> <n>``, per frame a 68-flag mask line and a data line
numbered 0..n-1, integer values, single spaces, no comments. FAP 1/2 are expanded into low-level
FAPs by default (``high_level="xface"`` writes the 4/6-token fields); plain FAP 1/2 tokens are
dropped; :func:`expand_high_level` does the expansion (the blends of :mod:`.blends`).
:func:`fap_info` summarises a sequence (``fap-studio fap info``). Sequences are authored from
keyframes in :mod:`.keyframes`.
"""

from __future__ import annotations

import itertools
import os
import re
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from editor.engine.faps import FAPS, check_vector, partner_mask, round_half_away
from editor.errors import FapFileError
from editor.safeio import atomic_write_text, iter_bounded, read_bounded

from .blends import blend_expressions, blend_visemes
from .presets import Preset

__all__ = ["MAX_FRAMES", "ExpressionField", "FapSequence", "VisemeField", "check_vector",
           "expand_high_level", "fap_info", "fap_info_file", "format_fap", "fps_text",
           "partner_mask", "read_fap", "round_half_away", "write_fap"]

N_FAPS = 68
MAX_FRAMES = 1_000_000
MAX_FILE_BYTES = 256 * 1024 * 1024
MAX_FPS = 1000.0
MAX_ABS_VALUE = 2**24  # float32 holds every integer up to 2**24 exactly (exact round trip)

_INT = re.compile(r"[+-]?\d+\Z")
_NUM = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?\Z")
_HEADER = "'2.1 <name> <fps> <frame count>'"


def _filled_in() -> Any:
    """Default of a dataclass field that ``__post_init__`` computes when it is None."""
    return None


@dataclass(frozen=True)
class _Fields:
    """Integer fields, each in 0..``_limits[i]``; ValueError naming the field otherwise."""

    _limits: ClassVar[tuple[int, ...]] = ()

    def __post_init__(self) -> None:
        for f, hi in zip(fields(self), self._limits, strict=True):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 0 <= v <= hi:
                raise ValueError(f"{f.name} must be an integer 0-{hi}, got {v!r}")

    def tokens(self) -> list[str]:
        return [str(int(getattr(self, f.name))) for f in fields(self)]


@dataclass(frozen=True)
class VisemeField(_Fields):
    """FAP 1: mouth = viseme select1 · blend/63 + select2 · (1 - blend/63) (def: a flag)."""

    select1: int
    select2: int
    blend: int
    definition: int = 0
    _limits = (14, 14, 63, 1)


@dataclass(frozen=True)
class ExpressionField(_Fields):
    """FAP 2: face = expression select1 · intensity1/63 + select2 · intensity2/63."""

    select1: int
    intensity1: int
    select2: int
    intensity2: int
    init_face: int = 0
    definition: int = 0
    _limits = (6, 63, 6, 63, 1, 1)


@dataclass(eq=False)
class FapSequence:
    """A FAP animation: N frames of 68 FAP values in FAPU, with per-frame masks.

    Attributes
    ----------
    frames : (N, 68) float32      value of FAP i+1 in column i; 0 where not masked
    masks : (N, 68) bool          FAP sent in that frame (default: the non-zero entries)
    fps : float                   frame k is shown at t = k / fps
    name, version : str           header fields (the writer always writes 2.1)
    frame_numbers : (N,) int64    as read (default 0..N-1); the writer renumbers from 0
    visemes, expressions : list   per frame a VisemeField / ExpressionField (Xface form) or None
    notes : list of str           what the reader tolerated (floats rounded, Greta masks, ...)

    Parameters
    ----------
    frames : array_like
        (N, 68) or (68,) values, finite; N >= 1.
    masks, fps, name, version, frame_numbers, visemes, expressions, notes
        As the attributes; left out, masks are the non-zero values (FAP 1/2 off).

    Raises
    ------
    ValueError
        Frames of the wrong shape or not finite, fps outside (0, 1000], per-frame lists of
        the wrong length.

    Examples
    --------
    >>> import numpy as np
    >>> from editor.core import FAPS, FapSequence, apply_preset
    >>> seq = FapSequence.single(apply_preset("joy"), fps=25, frames=50, name="joy")
    >>> seq.n_frames, seq.duration, seq.used_faps()[:3]
    (50, 2.0, [3, 4, 5])
    >>> ramp = np.outer(np.linspace(0, 1, 5), FAPS.vector({"open_jaw": 400}))
    >>> FapSequence(ramp, fps=10).frames[:, 2].tolist()
    [0.0, 100.0, 200.0, 300.0, 400.0]
    """

    # masks, frame_numbers, visemes, expressions: None (the default) is filled in by
    # __post_init__, so the attributes are never None
    frames: np.ndarray
    masks: np.ndarray = field(default_factory=_filled_in)
    fps: float = 25.0
    name: str = "fap-studio"
    version: str = "2.1"
    frame_numbers: np.ndarray = field(default_factory=_filled_in)
    visemes: list[VisemeField | None] = field(default_factory=_filled_in)
    expressions: list[ExpressionField | None] = field(default_factory=_filled_in)
    notes: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        f = np.array(self.frames, dtype=np.float32, ndmin=2)
        if f.ndim != 2 or f.shape[1] != N_FAPS or f.shape[0] < 1 or not np.isfinite(f).all():
            raise ValueError(f"frames must be finite with shape (N>=1, 68), got {f.shape}")
        n = f.shape[0]
        m = (f != 0) if self.masks is None else np.array(self.masks, bool).reshape(f.shape)
        if self.masks is None:
            m[:, :2] = False
        self.fps = float(self.fps)
        if not 0 < self.fps <= MAX_FPS:
            raise ValueError(f"fps must be in (0, {MAX_FPS:g}], got {self.fps!r}")
        for attr in ("visemes", "expressions"):
            lst = [None] * n if getattr(self, attr) is None else list(getattr(self, attr))
            if len(lst) != n:
                raise ValueError(f"{attr} must have one entry per frame ({n}), got {len(lst)}")
            setattr(self, attr, lst)
        m[:, 0] |= np.array([v is not None for v in self.visemes])
        m[:, 1] |= np.array([e is not None for e in self.expressions])
        f[~m] = 0.0
        self.frames, self.masks = f, m
        nums = np.arange(n) if self.frame_numbers is None else self.frame_numbers
        self.frame_numbers = np.asarray(nums, dtype=np.int64).reshape(n)
        self.name, self.notes = str(self.name), list(self.notes)

    @property
    def n_frames(self) -> int:
        """Number of frames N."""
        return int(self.frames.shape[0])

    @property
    def duration(self) -> float:
        """Playing time in seconds, N / fps (the last frame lasts 1/fps)."""
        return self.n_frames / self.fps

    @property
    def has_high_level(self) -> bool:
        """FAP 1 or FAP 2 masked in some frame (either form)."""
        return bool(self.masks[:, :2].any())

    def used_faps(self) -> list[int]:
        """FAP numbers masked in at least one frame."""
        return [int(i) + 1 for i in np.flatnonzero(self.masks.any(axis=0))]

    @classmethod
    def single(cls, vector: np.ndarray, fps: float = 25.0, frames: int = 1,
               name: str = "fap-studio", mask: np.ndarray | None = None) -> FapSequence:
        """``frames`` copies of one low-level (68,) vector, values rounded to integers.

        Default mask: every non-zero FAP plus its left/right partner, so that a decoder that
        fills in unsent partners (visage ``interpolateLR``) receives explicit zeros.
        """
        v = round_half_away(check_vector(vector)).astype(np.float32)
        if not 1 <= int(frames) <= MAX_FRAMES:
            raise ValueError(f"frames must be 1-{MAX_FRAMES}, got {frames}")
        m = partner_mask(v != 0) if mask is None else np.asarray(mask, bool).reshape(N_FAPS)
        return cls(np.repeat(v[None], int(frames), 0), np.repeat(m[None], int(frames), 0),
                   fps=fps, name=name)


def read_fap(source: str | os.PathLike | bytes, *, label: str | None = None) -> FapSequence:
    """Read an MPEG-4 ``.fap`` file (2.1; 2.0 and common producers' variants tolerated).

    Parameters
    ----------
    source : str, os.PathLike or bytes
        A path, the file's bytes, or its text (a ``str`` with a line break or NUL, or empty).
    label : str, optional
        Names the source in messages (default the file name, ``<bytes>`` or ``<text>``).

    Returns
    -------
    FapSequence
        What the file holds (never clamped); ``notes`` lists what was tolerated.

    Raises
    ------
    FapFileError
        ``"<file> line <k>: expected ..., got ..."``: a bad header, count, number or flag,
        a truncated file or extra data (see the module docstring); never a partial load.

    Examples
    --------
    >>> from editor.core import read_fap
    >>> text = "2.1 jaw 25 1\\n" + "0 0 1" + " 0" * 65 + "\\n0 300\\n"
    >>> seq = read_fap(text)
    >>> seq.name, seq.fps, seq.n_frames, float(seq.frames[0, 2])
    ('jaw', 25.0, 1, 300.0)
    """
    if isinstance(source, (bytes, bytearray)):
        data, label = bytes(source), label or "<bytes>"
    elif isinstance(source, str) and (not source or any(c in source for c in "\n\r\0")):
        data, label = source.encode("utf-8", "surrogatepass"), label or "<text>"
    else:
        path = Path(source)
        label = label or path.name
        data = read_bounded(path, MAX_FILE_BYTES, error=FapFileError, label=label,
                            what="a .fap file")
    return _Parser(_decode(data, label), label).parse()


def _decode(data: bytes, label: str) -> str:
    nul, nl = data.find(b"\x00"), b"\n"
    if nul >= 0:
        raise FapFileError(f"{label} line {data.count(nl, 0, nul) + 1}: binary data "
                           "(NUL byte), expected a text .fap file")
    data = data.removeprefix(b"\xef\xbb\xbf")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise FapFileError(f"{label} line {data.count(nl, 0, e.start) + 1}: byte "
                           f"0x{data[e.start]:02x} is not UTF-8, expected a text .fap file"
                           ) from None


def _short(tok: str) -> str:
    """repr of a token, cut to 24 characters (a 5000-digit token is not echoed whole)."""
    return repr(tok) if len(tok) <= 24 else repr(tok[:20]) + f"... ({len(tok)} characters)"


def _number(tok: str) -> tuple[float, bool] | None:
    """(value, was_decimal) of a plain decimal number token, else None (no nan/inf/1_0)."""
    if len(tok) > 40:  # never convert a huge token (int limit, OverflowError): out of range
        return (float("inf"), False) if tok.lstrip("+-")[:1].isdigit() else None
    if _INT.match(tok):
        return float(int(tok)), False
    return (float(tok), True) if _NUM.match(tok) else None


class _Parser:
    def __init__(self, text: str, label: str) -> None:
        self.label = label
        self.lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
        stripped = [s.strip() for s in self.lines]
        self.content = [i for i, s in enumerate(stripped) if s and not s.startswith("#")]
        comments = sum(s.startswith("#") for s in stripped)
        self.notes = [f"{comments} '#' comment line(s) skipped"] if comments else []
        self.decimals = 0

    def fail(self, idx: int, msg: str) -> FapFileError:  # idx: 0-based line index
        return FapFileError(f"{self.label} line {idx + 1}: {msg}")

    def header(self) -> tuple[str, str, float, int]:
        if not self.content:
            raise self.fail(0, f"empty file, expected the header {_HEADER}")
        h = self.content[0]
        toks = self.lines[h].split()
        if len(toks) < 3 or toks[0] not in ("2.1", "2.0"):
            got = " ".join(toks[:5]) + (" ..." if len(toks) > 5 else "")
            raise self.fail(h, f"expected the header {_HEADER} (2.1 or 2.0), got {got!r}")
        fps = _number(toks[-2])
        if fps is None or not 0 < fps[0] <= MAX_FPS:
            raise self.fail(h, f"expected a frame rate in (0, {MAX_FPS:g}] as the "
                               f"second-to-last header token, got {_short(toks[-2])}")
        if (len(toks[-1]) > 12 or not _INT.match(toks[-1])
                or not 1 <= int(toks[-1]) <= MAX_FRAMES):
            raise self.fail(h, f"expected a frame count 1-{MAX_FRAMES} as the last header "
                               f"token, got {_short(toks[-1])}")
        self.notes += [t for c, t in ((toks[0] == "2.0", "version 2.0 read as 2.1 (no rescaling)"),
                                      (len(toks) > 4, "header name with spaces (Greta style)"))
                       if c]
        return toks[0], " ".join(toks[1:-2]), fps[0], int(toks[-1])

    def mask(self, idx: int) -> tuple[np.ndarray, bool]:
        toks = self.lines[idx].split()
        if len(toks) not in (68, 69):
            hint = " (a data line? every frame needs its own mask line)" if len(toks) < 68 else ""
            raise self.fail(idx, f"expected a mask line of 68 flags (0 or 1), "
                                 f"got {len(toks)} tokens{hint}")
        for j, t in enumerate(toks):
            if t != "0" and t != "1":
                raise self.fail(idx, f"mask flag {j + 1} is {_short(t)}, expected 0 or 1")
        return np.array([t == "1" for t in toks[:68]]), len(toks) == 69

    def data(self, idx: int, mask: np.ndarray, expected_frame: int | None, row: np.ndarray
             ) -> tuple[int, VisemeField | None, ExpressionField | None, bool]:
        toks = self.lines[idx].split()
        low = [int(i) + 3 for i in np.flatnonzero(mask[2:])]
        m1, m2 = int(mask[0]), int(mask[1])
        plain, xface, got = len(low) + m1 + m2, len(low) + 4 * m1 + 6 * m2, len(toks) - 1
        if got not in (plain, xface):
            want = f"{plain} value" + ("" if plain == 1 else "s")
            if xface != plain:
                want += f" (one per masked FAP) or {xface} (Xface 4/6-token FAP 1/2 fields)"
            masked = f"{plain} masked FAP" + ("" if plain == 1 else "s")
            raise self.fail(idx, f"expected {want} for {masked}, got {got}")
        num = _number(toks[0])
        if num is None or abs(num[0]) > 2**53 or num[0] != int(num[0]):
            raise self.fail(idx, f"expected a frame number, got {_short(toks[0])}")
        frame = int(num[0])
        if frame != expected_frame and (expected_frame is not None or frame not in (0, 1)):
            raise self.fail(idx, f"frame number {frame} out of order, expected "
                                 f"{0 if expected_frame is None else expected_frame}")
        is_x = got == xface != plain
        n1, n2 = (4 * m1, 6 * m2) if is_x else (m1, m2)
        values = []
        for k, (tok, fap) in enumerate(zip(toks[1:], [1] * n1 + [2] * n2 + low, strict=True), 1):
            num = _number(tok)
            if num is None or abs(num[0]) > MAX_ABS_VALUE:
                what = "a number" if num is None else f"a number with |value| <= {MAX_ABS_VALUE}"
                raise self.fail(idx, f"value {k} (FAP {fap} {FAPS[fap].name}) is {_short(tok)}, "
                                     f"expected {what}")
            self.decimals += num[1]
            values.append(num[0])
        vis: VisemeField | None = None
        expr: ExpressionField | None = None
        if is_x:
            # a non-integer value is passed on: the field's own check names it (ValueError)
            ints: list[Any] = [int(v) if v == int(v) else v for v in values[:n1 + n2]]
            try:
                vis = VisemeField(*ints[:4]) if m1 else None
                expr = ExpressionField(*ints[n1:]) if m2 else None
            except (ValueError, TypeError) as e:
                raise self.fail(idx, f"FAP 1/2 fields: {e}") from None
        else:
            row[:2][mask[:2]] = round_half_away(values[:n1 + n2])
        row[np.array(low, dtype=np.int64) - 1] = round_half_away(values[n1 + n2:])
        return frame, vis, expr, is_x

    def parse(self) -> FapSequence:
        version, name, fps, count = self.header()
        h = self.content[0]
        available = (len(self.content) - 1) // 2
        n = min(count, available)  # never allocate from the header's count alone
        frames, masks = np.zeros((n, N_FAPS), np.float32), np.zeros((n, N_FAPS), bool)
        numbers = np.zeros(n, np.int64)
        visemes: list[VisemeField | None] = [None] * n
        exprs: list[ExpressionField | None] = [None] * n
        greta = xface = plain = 0
        for k in range(n):
            masks[k], extra = self.mask(self.content[1 + 2 * k])
            expect = None if k == 0 else int(numbers[k - 1]) + 1
            numbers[k], visemes[k], exprs[k], is_x = self.data(
                self.content[2 + 2 * k], masks[k], expect, frames[k])
            greta, xface = greta + extra, xface + is_x
            plain += (not is_x) and bool(masks[k, :2].any())
        if count > available:
            raise self.fail(self.content[-1] + 1,
                            f"unexpected end of file: the header (line {h + 1}) declares "
                            f"{count} frames, expected a mask line and a data line per frame, "
                            f"got {available} complete frame(s)")
        if len(self.content) > 1 + 2 * count:
            raise self.fail(self.content[1 + 2 * count],
                            f"expected the end of the file after the {count} frame(s) the "
                            f"header (line {h + 1}) declares, got more data")
        notes = self.notes + [text for cond, text in (
            (numbers[0] == 1, "frame numbers start at 1 (VREng style); written from 0"),
            (greta, f"{greta} mask line(s) with 69 flags (Greta style); 69th ignored"),
            (self.decimals, f"values were floats and were rounded ({self.decimals} token(s))"),
            (xface, f"Xface 4/6-token FAP 1/2 fields in {xface} frame(s)"),
            (plain, f"FAP 1/2 masked with one plain token in {plain} frame(s): no defined "
                    "meaning, kept in frames[:, 0/1], not expanded")) if cond]
        return FapSequence(frames, masks, fps=fps, name=name, version=version,
                           frame_numbers=numbers, visemes=visemes, expressions=exprs,
                           notes=notes)


def fps_text(fps: float) -> str:
    """``25`` for 25.0, ``12.5`` for 12.5 (shortest exact form)."""
    return str(int(fps)) if float(fps).is_integer() else repr(float(fps))


def _text_bytes(values: np.ndarray, masks: np.ndarray) -> int:
    """Bytes of the mask and data lines of integer ``values`` (F, 68) under ``masks`` (without
    FAP 1/2 tokens, a few bytes a frame): the size :func:`format_fap` writes, from counts."""
    v = np.abs(values[:, 2:])
    digits = np.where(v > 0, np.floor(np.log10(np.maximum(v, 1))) + 1, 1) + (values[:, 2:] < 0)
    m = np.asarray(masks)[:, 2:]
    frame_no = np.floor(np.log10(np.maximum(np.arange(len(values)), 1))) + 1
    per_frame = 2 * masks.shape[1] + frame_no + (digits * m).sum(1) + m.sum(1) + 1
    return int(per_frame.sum())


def format_fap(seq: FapSequence, *, high_level: str = "expand") -> str:
    """The file text of ``seq``. ``high_level="expand"``: FAP 1/2 fields become low-level FAPs
    (shipped presets); ``"xface"``: written as Xface 4/6-token fields (Greta/VREng can't read).
    """
    if high_level not in ("expand", "xface"):
        raise ValueError(f"high_level must be 'expand' or 'xface', got {high_level!r}")
    if high_level == "expand" and seq.has_high_level:
        seq = expand_high_level(seq)
    name = "_".join(seq.name.split()) or "fap-studio"
    out = [f"2.1 {name} {fps_text(seq.fps)} {seq.n_frames}"]
    values = round_half_away(seq.frames).astype(np.int64)
    size = _text_bytes(values, seq.masks) + len(out[0].encode()) + 1  # + the header line's newline
    if size > MAX_FILE_BYTES:  # a file no reader (ours included) would open
        raise FapFileError(f"{seq.n_frames} frames would make a {size / 2**20:.0f} MiB .fap "
                           f"file; readers accept at most {MAX_FILE_BYTES // 2**20} MiB: "
                           "write fewer frames or FAPs")
    for k in range(seq.n_frames):
        m = seq.masks[k].copy()
        vis, expr = seq.visemes[k], seq.expressions[k]
        m[0], m[1] = vis is not None, expr is not None
        out.append(" ".join("1" if f else "0" for f in m))
        toks = [str(k)] + (vis.tokens() if vis else []) + (expr.tokens() if expr else [])
        out.append(" ".join(toks + [str(v) for v in values[k, 2:][m[2:]]]))
    return "\n".join(out) + "\n"


def write_fap(seq: FapSequence, path: str | os.PathLike, *, high_level: str = "expand") -> Path:
    """Write ``seq`` as a ``.fap`` 2.1 file, atomically (nothing partial on an error).

    Parameters
    ----------
    seq : FapSequence
        The animation; values are written rounded to integers.
    path : str or os.PathLike
        The output file.
    high_level : {"expand", "xface"}, default "expand"
        FAP 1/2 fields expanded into low-level FAPs (readable by every player), or written
        as Xface 4/6-token fields (see :func:`format_fap`).

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    FapFileError
        The file cannot be written (the message says why).
    ValueError
        An unknown ``high_level``.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from editor.core import FapSequence, apply_preset, read_fap, write_fap
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "joy.fap"
    >>> _ = write_fap(FapSequence.single(apply_preset("joy"), frames=3, name="joy"), out)
    >>> out.read_text().splitlines()[0]
    '2.1 joy 25 3'
    >>> read_fap(out).n_frames
    3
    """
    path, text = Path(path), format_fap(seq, high_level=high_level)
    return atomic_write_text(path, text, error=FapFileError, label=path.name)


def expand_high_level(seq: FapSequence, *,
                      expression_table: Mapping[int, Preset | np.ndarray] | None = None,
                      viseme_table: Mapping[int, Preset | np.ndarray] | None = None
                      ) -> FapSequence:
    """A copy of ``seq`` with FAP 1/2 expanded into low-level FAPs and unmasked.

    Xface-form fields: the blends (shipped presets unless a per-face table is given) are added
    to the frame's low-level values, rounded, and their FAPs (plus L/R partners) masked. Plain
    one-token FAP 1/2 values have no meaning and are dropped. Noted in ``notes``.
    """
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


def fap_info(seq: FapSequence) -> str:
    """Summary for ``fap info``: version, name, fps, frames, duration, FAPs used, notes."""
    nv = sum(v is not None for v in seq.visemes)
    ne = sum(e is not None for e in seq.expressions)
    used = [n for n in seq.used_faps() if n > 2]
    stats = []
    for n in used:
        col = seq.frames[seq.masks[:, n - 1], n - 1]
        stats.append((n, col.size, col.min(), col.max()))
    return _info_text(seq.version, seq.name, seq.fps, seq.n_frames,
                      (int(seq.frame_numbers[0]), int(seq.frame_numbers[-1])), nv, ne,
                      seq.has_high_level, stats, seq.notes)


def _info_text(version: str, name: str, fps: float, n: int, numbers: tuple[int, int], nv: int,
               ne: int, high_level: bool, stats: list[tuple[int, int, Any, Any]],
               notes: list[str]) -> str:
    plain = ", plain one-token form (no meaning)" if high_level and not nv + ne else ""
    lines = [f"version:  {version}", f"name:     {name}",
             f"fps:      {fps_text(fps)}",
             f"frames:   {n} (numbered {numbers[0]}-{numbers[1]})",
             f"duration: {n / fps:.3f} s",
             f"FAP 1/2:  viseme fields in {nv} frame(s), expression fields in {ne} frame(s)"
             + plain]
    lines.append(f"FAPs used ({len(stats)}):")
    for k, size, lo, hi in stats:
        lines.append(f"  {k:2d} {FAPS[k].name:<22} in {size} frame(s), "
                     f"values {lo:g} .. {hi:g}")
    return "\n".join(lines + (["notes:"] + [f"  - {t}" for t in notes] if notes else []))


def fap_info_file(path: str | os.PathLike, *, label: str | None = None) -> str:
    """:func:`fap_info` of the ``.fap`` file ``path``, read as a stream: memory stays flat in
    the file's length (a 1 M-frame file is never held whole). The same text as
    ``fap_info(read_fap(path))``, and the same :class:`FapFileError` for a malformed file."""
    p = Path(path)
    label = label or p.name
    chunks = iter_bounded(p, MAX_FILE_BYTES, error=FapFileError, label=label,
                          what="a .fap file")
    return _InfoStream(label).run(_stream_blocks(chunks, label))


def _stream_blocks(chunks: Iterator[bytes], label: str) -> Iterator[list[str]]:
    """The lines of :meth:`_Parser`'s split (CRLF, CR, LF) of the decoded chunks, a list per
    chunk (the complete lines it ends); at the end (only when run to the end)
    :func:`_decode`'s errors: the first NUL byte, else the first non-UTF-8 byte, anywhere in
    the file."""
    buf, first, nl_before = b"", True, 0
    bad_utf8: FapFileError | None = None
    nl = b"\n"
    for chunk in itertools.chain(chunks, [None]):
        if chunk is not None:
            buf += chunk
            cut = max(buf.rfind(nl), buf.rfind(b"\r", 0, len(buf) - 1))  # keep a last CR
            if cut < 0:
                continue
            part, buf = buf[:cut + 1], buf[cut + 1:]
        else:
            part, buf = buf, b""
        nul = part.find(b"\x00")
        if nul >= 0:
            raise FapFileError(f"{label} line {nl_before + part.count(nl, 0, nul) + 1}: binary "
                               "data (NUL byte), expected a text .fap file")
        if first:
            part, first = part.removeprefix(b"\xef\xbb\xbf"), False
        if bad_utf8 is None:
            try:
                text = part.decode("utf-8")
            except UnicodeDecodeError as e:
                bad_utf8 = FapFileError(
                    f"{label} line {nl_before + part.count(nl, 0, e.start) + 1}: byte "
                    f"0x{part[e.start]:02x} is not UTF-8, expected a text .fap file")
            else:
                if "\r" in text:
                    text = text.replace("\r\n", "\n").replace("\r", "\n")
                lines = text.split("\n")
                if chunk is not None:
                    lines.pop()  # "": the part ends with its last line's break
                if lines:
                    yield lines
        nl_before += part.count(nl)
    if bad_utf8 is not None:
        raise bad_utf8


#: a data line of plain integer tokens (ASCII digits, spaces/tabs): the line-by-line fast path
_PLAIN_INTS = re.compile(r"[ \t]*[+-]?[0-9]{1,15}(?:[ \t]+[+-]?[0-9]{1,15})*[ \t]*\Z")

#: byte classes of :func:`_plain_frames`: 1 digit, 2 sign, 4 space or tab, 8 line break,
#: 0 anything else (the line is left to the reader's own code)
_BYTE_CLASS = np.zeros(256, np.uint8)
_BYTE_CLASS[np.frombuffer(b"0123456789", np.uint8)] = 1
_BYTE_CLASS[np.frombuffer(b"+-", np.uint8)] = 2
_BYTE_CLASS[np.frombuffer(b" \t", np.uint8)] = 4
_BYTE_CLASS[ord("\n")] = 8
_MAX_DIGITS = 15  # a token of at most 15 digits is exact in int64 and float64

#: the block path (:func:`_plain_frames`) is tried once _RUN frames in a row were plain under
#: one mask (a file of short runs pays nothing for it); it looks at _WINDOW_MIN frames, doubled
#: while it takes every frame it looks at (to _WINDOW_MAX: its temporaries stay small)
_RUN, _WINDOW_MIN, _WINDOW_MAX = 8, 16, 1 << 9


def _plain_frames(block: list[str], p: int, m: int, mask_text: str, width: int,
                  expect: int) -> np.ndarray:
    """The longest run of frames of ``block`` from line ``p`` on (at most ``m``) that
    :meth:`_Parser.data` reads as plain integers without a message: each a mask line that is
    ``mask_text`` (a mask without FAP 1/2) then a data line of ``width`` tokens
    ``[+-]?[0-9]{1,15}`` (ASCII, spaces and tabs between; longer tokens would saturate in
    int64), frame numbers ``expect``, ``expect + 1``, ..., values within
    :data:`MAX_ABS_VALUE` (the first frame, which sets the mask, is never read here). Returns
    their tokens, (r, width) int64, r in 0..m; whatever is left goes through the reader's own
    code line by line (its checks, its messages)."""
    none = np.zeros((0, width), np.int64)
    r = next(itertools.compress(itertools.count(), map(mask_text.__ne__, block[p:p + 2 * m:2])),
             m)
    if r == 0:
        return none
    data = "\n".join(block[p + 1:p + 2 * r:2]).encode()
    cls = _BYTE_CLASS[np.frombuffer(data, np.uint8)]
    line = np.cumsum(cls == 8, dtype=np.int32)  # each byte's line (a break: the next one's)
    digit, sign, tok = cls == 1, cls == 2, (cls & 3) != 0
    after_sep = np.ones(len(cls), bool)
    after_sep[1:] = (cls[:-1] & 12) != 0
    before_digit = np.zeros(len(cls), bool)
    before_digit[:-1] = digit[1:]
    bad = (cls == 0) | (sign & ~(after_sep & before_digit))  # a sign only starts a number
    edges = np.concatenate(([-1], np.flatnonzero(~digit), [len(cls)]))
    long_runs = edges[:-1][np.diff(edges) > _MAX_DIGITS + 1] + 1  # first digit of each
    counts = np.bincount(line[tok & after_sep], minlength=r)  # tokens per line
    for firsts in (np.flatnonzero(counts != width), line[bad], line[long_runs]):
        if len(firsts):
            r = min(r, int(firsts[0]))  # each sorted: its first is its least
    if r == 0:
        return none
    if r < len(counts):
        data = data[:np.flatnonzero(cls == 8)[r - 1]]
    vals = np.fromstring(data, np.int64, sep=" ").reshape(r, width)
    wrong = vals[:, 0] != expect + np.arange(r)
    if width > 1:
        wrong |= np.abs(vals[:, 1:]).max(axis=1) > MAX_ABS_VALUE
    stop = np.flatnonzero(wrong)
    return vals[:stop[0]] if len(stop) else vals


class _InfoStream(_Parser):
    """:class:`_Parser` over a stream of blocks of lines, keeping per-FAP counts and ranges
    instead of the frames. Runs of plain integer frames under one mask are read a block at a
    time (:func:`_plain_frames`); every other line goes through :class:`_Parser`'s code (its
    checks, its messages). The first parse error is held until the stream has been read to the
    end (a NUL byte or a non-UTF-8 byte anywhere wins, as in :func:`read_fap`)."""

    def __init__(self, label: str) -> None:
        super().__init__("", label)
        self.lines: Any = {}
        self.content = []
        self.notes = []

    def run(self, blocks: Iterator[list[str]]) -> str:
        pending: FapFileError | None = None
        try:
            result = self._consume(blocks)
        except FapFileError as e:
            pending = e
        for _ in blocks:  # the rest of the file: NUL / UTF-8 errors come first
            pass
        if pending is not None:
            raise pending
        return result

    def _consume(self, blocks: Iterator[list[str]]) -> str:
        comments = 0
        idx = -1  # 0-based index of the last line read
        header: tuple[str, str, float, int] | None = None
        count = done = 0
        last_content = -1
        held: int | None = None  # the mask line of the frame being read
        frame_lines: dict[int, str] = {}
        self.lines = frame_lines
        # statistics
        n_used = np.zeros(N_FAPS, np.int64)
        lo = np.full(N_FAPS, np.inf, np.float32)
        hi = np.full(N_FAPS, -np.inf, np.float32)
        first_num = last_num = 0
        nv = ne = greta = xface = plain = 0
        high = False
        mask_text, mask_val = None, (np.zeros(N_FAPS, bool), False)
        low = np.zeros(0, np.int64)
        rows: list[list[int]] = []  # plain frames read line by line, under mask_text
        run = 0  # plain frames in a row under mask_text: from _RUN on, tried a block at a time
        window = _WINDOW_MIN

        def flush() -> None:
            if rows:
                a = np.array(rows, np.float32)[:, 1:]
                n_used[low - 1] += len(a)
                if a.shape[1]:
                    lo[low - 1] = np.minimum(lo[low - 1], a.min(axis=0))
                    hi[low - 1] = np.maximum(hi[low - 1], a.max(axis=0))
                rows.clear()

        for lines in blocks:
            p, n_lines = 0, len(lines)
            while p < n_lines:
                if (run >= _RUN and held is None and lines[p] == mask_text
                        and (m := min(window, (n_lines - p) // 2, count - done))):
                    taken = _plain_frames(lines, p, m, lines[p], len(low) + 1, last_num + 1)
                    r = len(taken)
                    run, window = ((run, min(2 * window, _WINDOW_MAX)) if r == m
                                   else (0, _WINDOW_MIN))
                    if r:
                        n_used[low - 1] += r
                        if len(low):
                            lo[low - 1] = np.minimum(lo[low - 1], taken[:, 1:].min(axis=0))
                            hi[low - 1] = np.maximum(hi[low - 1], taken[:, 1:].max(axis=0))
                        last_num = int(taken[-1, 0])
                        greta += r * mask_val[1]
                        done += r
                        p, idx = p + 2 * r, idx + 2 * r
                        last_content = idx
                        continue
                line = lines[p]
                p, idx = p + 1, idx + 1
                s = line.strip()
                if not s:
                    continue
                if s[0] == "#":
                    comments += 1
                    continue
                last_content = idx
                if header is None:
                    self.lines = {idx: line}
                    self.content = [idx]
                    header = self.header()
                    count = header[3]
                    self.lines = frame_lines
                    continue
                if done == count:
                    raise self.fail(idx, f"expected the end of the file after the {count} "
                                         f"frame(s) the header (line {self.content[0] + 1}) "
                                         "declares, got more data")
                if held is None:
                    held = idx
                    frame_lines.clear()
                    frame_lines[idx] = line
                    continue
                frame_lines[idx] = line
                mline = frame_lines[held]
                if mline != mask_text:
                    flush()
                    mask_val = self.mask(held)
                    mask_text = mline
                    low = np.flatnonzero(mask_val[0][2:]) + 3
                    run = 0
                mask, extra = mask_val
                expect = None if done == 0 else last_num + 1
                toks = line.split() if not (mask[0] or mask[1]) else None
                if (toks is not None and len(toks) == len(low) + 1 and _PLAIN_INTS.match(line)
                        and (ints := [int(t) for t in toks])
                        and (ints[0] == expect or (expect is None and ints[0] in (0, 1)))
                        and (len(ints) == 1 or max(map(abs, ints[1:])) <= MAX_ABS_VALUE)):
                    rows.append(ints)
                    num = ints[0]
                    run += 1
                    if len(rows) >= 4096:  # memory stays bounded
                        flush()
                else:  # anything else: the reader's own code (its checks, its messages)
                    flush()
                    run = 0
                    row = np.zeros(N_FAPS, np.float32)
                    num, vis, expr, is_x = self.data(idx, mask, expect, row)
                    nv, ne = nv + (vis is not None), ne + (expr is not None)
                    xface += is_x
                    plain += (not is_x) and bool(mask[:2].any())
                    sel = low - 1
                    n_used[sel] += 1
                    lo[sel] = np.minimum(lo[sel], row[sel])
                    hi[sel] = np.maximum(hi[sel], row[sel])
                high = high or bool(mask[0] or mask[1])
                greta += extra
                if done == 0:
                    first_num = num
                last_num = num
                done += 1
                held = None
        flush()
        if header is None:
            raise self.fail(0, f"empty file, expected the header {_HEADER}")
        if done < count:
            raise self.fail(last_content + 1,
                            f"unexpected end of file: the header (line {self.content[0] + 1}) "
                            f"declares {count} frames, expected a mask line and a data line "
                            f"per frame, got {done} complete frame(s)")
        version, name, fps, _ = header
        notes = ([f"{comments} '#' comment line(s) skipped"] if comments else []) + self.notes
        notes += [text for cond, text in (
            (first_num == 1, "frame numbers start at 1 (VREng style); written from 0"),
            (greta, f"{greta} mask line(s) with 69 flags (Greta style); 69th ignored"),
            (self.decimals, f"values were floats and were rounded ({self.decimals} token(s))"),
            (xface, f"Xface 4/6-token FAP 1/2 fields in {xface} frame(s)"),
            (plain, f"FAP 1/2 masked with one plain token in {plain} frame(s): no defined "
                    "meaning, kept in frames[:, 0/1], not expanded")) if cond]
        stats = [(k + 1, int(n_used[k]), lo[k], hi[k]) for k in range(2, N_FAPS) if n_used[k]]
        return _info_text(version, name, fps, count, (first_num, last_num), nv, ne, high,
                          stats, notes)
