"""Face-tracking CSV files (no Qt): Live Link Face (ARKit blendshapes) and OpenFace-style AUs.

**Live Link Face** (Epic's iPhone app): a header ``Timecode,BlendShapeCount,EyeBlinkLeft,...,
TongueOut`` (the 52 ARKit blendshapes, any order, names matched without regard to case, so
MediaPipe's ``eyeBlinkLeft`` reads too) optionally followed by the 9 rotation columns
``HeadYaw,HeadPitch,HeadRoll,LeftEyeYaw,...,RightEyeRoll`` (radians); one row per captured
frame. ``Timecode`` is SMPTE ``HH:MM:SS:FF.sss`` (``FF`` the frame within the second, ``.sss``
the fraction of a frame; ``;`` for drop-frame is read the same); time = seconds + (FF +
.sss) / fps. The file does not store its frame rate: ``fps`` is given, else it is inferred
from the largest ``FF`` (the smallest usual rate above it: 24, 25, 30, 50, 60, 120) and said
in ``notes``. ``BlendShapeCount`` must be a whole number; exporters disagree on it (61, 51),
so a count other than the number of columns is only noted. Rotations are radians; a file with
an angle above pi is read as degrees (noted). The writer uses Live Link Face's own column
order (``JawRight,JawLeft`` and ``MouthRight,MouthLeft`` as the app writes them).

**OpenFace-style AU CSV** (OpenFace 2 ``FeatureExtraction``, py-feat/FACSvatar exports):
``frame,timestamp`` and ``AUxx_r`` intensity columns (0..5, FACS A..E = 1..5); spaces after
the commas (OpenFace writes them) are ignored; other columns (``face_id``, ``confidence``,
``AUxx_c``, gaze, pose, landmarks) are ignored and AUs without a 2-D mapping are skipped, both
said in ``notes``. ``AU45_r`` (blink) drives AU43.

Readers are strict: a wrong or duplicate header name, a row with the wrong number of values,
a non-number, a value out of range, a time that does not increase give one
:class:`CsvFormatError` line ``"<file> line <k>, column <name>: expected ..., got ..."``; nothing
is returned half read. Writers go through :mod:`editor.safeio` (nothing partial on failure).
Both kinds convert to a :class:`FapSequence` resampled at a uniform ``fps`` (linear
interpolation between rows) through :mod:`.arkit` / :mod:`.facs`.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from editor.errors import CsvFormatError, FapFileError
from editor.safeio import atomic_write_text, read_bounded

from .arkit import arkit_table, arkit_to_faps, faps_to_arkit
from .facs import au_table, aus_to_faps, faps_to_aus
from .fapfile import (
    MAX_FPS,
    MAX_FRAMES,
    FapSequence,
    expand_high_level,
    fps_text,
    read_fap,
    write_fap,
)

__all__ = ["AuCapture", "LiveLinkCapture", "detect_kind", "read_animation", "read_au_csv",
           "read_live_link", "write_animation", "write_au_csv", "write_live_link"]

MAX_FILE_BYTES = 256 * 1024 * 1024
AU_CSV_MAX = 5.0  # OpenFace intensity scale 0..5
STANDARD_RATES = (24.0, 25.0, 30.0, 50.0, 60.0, 120.0)
_TIMECODE = re.compile(r"(\d{1,3}):(\d{2}):(\d{2})[:;](\d{1,3})(?:\.(\d+))?\Z")
_AU_COL = re.compile(r"(?i)AU0*(\d{1,3})_r\Z")
_NUM = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?\Z")
KINDS = ("fap", "arkit", "au")


def _short(tok: str) -> str:
    return repr(tok) if len(tok) <= 24 else repr(tok[:20]) + f"... ({len(tok)} characters)"


@dataclass
class LiveLinkCapture:
    """A Live Link Face recording: times (N,) s from the first row, weights (N, 52) in ARKit
    order, rotations (N, 9) radians (zeros when the file has none), the frame rate used for
    the timecodes, and what the reader inferred or tolerated."""

    times: np.ndarray
    weights: np.ndarray
    rotations: np.ndarray
    fps: float
    has_rotations: bool = True
    notes: list[str] = field(default_factory=list)

    def faps(self) -> np.ndarray:
        """(N, 68) FAPs of the rows (not resampled)."""
        return arkit_to_faps(self.weights, self.rotations if self.has_rotations else None)


@dataclass
class AuCapture:
    """An AU recording: times (N,) s from the first row, values (N, len(AUs)) in 0..1 in
    :func:`au_table` order (bilateral), fps, notes."""

    times: np.ndarray
    values: np.ndarray
    fps: float
    notes: list[str] = field(default_factory=list)

    def faps(self) -> np.ndarray:
        return aus_to_faps(au_table().from_bilateral(self.values))


# ------------------------------------------------------------------ shared reading
def _text(path: str | os.PathLike, label: str) -> list[str]:
    data = read_bounded(path, MAX_FILE_BYTES, error=CsvFormatError, label=label,
                        what="a CSV file")
    nl = b"\n"
    nul = data.find(b"\x00")
    if nul >= 0:
        raise CsvFormatError(f"{label} line {data.count(nl, 0, nul) + 1}: binary data (NUL "
                             "byte), expected a text CSV file")
    try:
        text = data.removeprefix(b"\xef\xbb\xbf").decode("utf-8")
    except UnicodeDecodeError as e:
        raise CsvFormatError(f"{label} line {data.count(nl, 0, e.start) + 1}: byte "
                             f"0x{data[e.start]:02x} is not UTF-8, expected a text CSV file"
                             ) from None
    return text.replace("\r\n", "\n").replace("\r", "\n").split("\n")


def _rows(lines: list[str]) -> list[tuple[int, list[str]]]:
    """(1-based line number, stripped fields) of the non-blank lines."""
    return [(i + 1, [f.strip() for f in s.split(",")]) for i, s in enumerate(lines) if s.strip()]


def _float(tok: str, label: str, line: int, col: str, lo: float, hi: float,
           what: str, shown: str | None = None) -> float:
    """``tok`` as a number in [lo, hi] (``shown``: the range as the message says it)."""
    if len(tok) > 40 or not _NUM.match(tok):
        raise CsvFormatError(f"{label} line {line}, column {col}: expected {what}, "
                             f"got {_short(tok)}")
    v = float(tok)
    if not lo <= v <= hi:
        raise CsvFormatError(f"{label} line {line}, column {col}: expected {what} "
                             f"({shown or f'{lo:g} to {hi:g}'}), got {_short(tok)}")
    return v


def _check_width(label: str, line: int, fields: list[str], n: int) -> None:
    if len(fields) != n:
        raise CsvFormatError(f"{label} line {line}: expected {n} comma-separated values (one "
                             f"per header column), got {len(fields)}")


def _check_fps(fps: float | None) -> float | None:
    if fps is not None and not (math.isfinite(fps) and 0 < fps <= MAX_FPS):
        raise CsvFormatError(f"--fps: expected a frame rate in (0, {MAX_FPS:g}], got {fps!r}")
    return fps


def _header_and_rows(path: str | os.PathLike, fps: float | None, label: str | None,
                     header: str) -> tuple[str, list[tuple[int, list[str]]]]:
    """The label for messages and the file's rows (line number, cells), at least the header
    (``header``: what the message says is expected in an empty file); ``fps`` checked."""
    label = label or Path(path).name
    _check_fps(fps)
    rows = _rows(_text(path, label))
    if not rows:
        raise CsvFormatError(f"{label} line 1: empty file, expected the header '{header}'")
    return label, rows


# ------------------------------------------------------------------ Live Link Face
def read_live_link(path: str | os.PathLike, fps: float | None = None, *,
                   label: str | None = None) -> LiveLinkCapture:
    """Read a Live Link Face CSV (see the module doc); :class:`CsvFormatError` else."""
    label, rows = _header_and_rows(path, fps, label,
                                   "Timecode,BlendShapeCount,EyeBlinkLeft,...")
    t = arkit_table()
    hline, header = rows[0]
    if header[:2] != ["Timecode", "BlendShapeCount"]:
        raise CsvFormatError(f"{label} line {hline}: expected a Live Link Face header starting "
                             f"'Timecode,BlendShapeCount', got {_short(','.join(header[:2]))}")
    known = {n.lower(): ("shape", i) for i, n in enumerate(t.names)}
    known.update({n.lower(): ("rot", i) for i, n in enumerate(t.rotations)})
    where: dict[tuple[str, int], int] = {}
    for j, name in enumerate(header[2:], 2):
        key = known.get(name.lower())
        if key is None:
            raise CsvFormatError(f"{label} line {hline}, column {j + 1}: unknown column "
                                 f"{_short(name)}, expected an ARKit blendshape or a Live "
                                 "Link rotation (HeadYaw, LeftEyePitch, ...)")
        if key in where:
            raise CsvFormatError(f"{label} line {hline}, column {j + 1}: {name} appears twice")
        where[key] = j
    missing = [n for i, n in enumerate(t.csv_names) if ("shape", i) not in where]
    if missing:
        raise CsvFormatError(f"{label} line {hline}: missing blendshape column(s) "
                             f"{', '.join(missing[:4])}{' ...' if len(missing) > 4 else ''}; "
                             "expected all 52 ARKit blendshapes")
    rot_cols = [where.get(("rot", i)) for i in range(len(t.rotations))]
    has_rot = any(c is not None for c in rot_cols)
    if has_rot and None in rot_cols:
        gone = [t.rotations[i] for i, c in enumerate(rot_cols) if c is None]
        raise CsvFormatError(f"{label} line {hline}: rotation column(s) {', '.join(gone)} "
                             "missing, expected all 9 (HeadYaw ... RightEyeRoll) or none")
    data = rows[1:]
    if not data:
        raise CsvFormatError(f"{label} line {hline + 1}: no data rows after the header")
    if len(data) > MAX_FRAMES:
        raise CsvFormatError(f"{label}: {len(data)} rows, expected at most {MAX_FRAMES}")
    width = len(header)
    n = len(data)
    stamps = np.zeros((n, 3))  # seconds, frame, fraction
    weights = np.zeros((n, len(t.names)))
    rotations = np.zeros((n, len(t.rotations)))
    shape_cols = [where[("shape", i)] for i in range(len(t.names))]
    other_count: str | None = None
    for k, (line, fields) in enumerate(data):
        _check_width(label, line, fields, width)
        m = _TIMECODE.match(fields[0])
        if not m:
            raise CsvFormatError(f"{label} line {line}, column Timecode: expected "
                                 f"HH:MM:SS:FF.sss, got {_short(fields[0])}")
        h, mi, s, ff, sub = m.groups()
        if int(mi) > 59 or int(s) > 59:
            raise CsvFormatError(f"{label} line {line}, column Timecode: minutes and seconds "
                                 f"must be 00-59, got {fields[0]!r}")
        stamps[k] = (int(h) * 3600 + int(mi) * 60 + int(s), int(ff),
                     float("0." + sub) if sub else 0.0)
        count = fields[1]
        if not count.isdigit() or len(count) > 4:
            raise CsvFormatError(f"{label} line {line}, column BlendShapeCount: expected a "
                                 f"whole number, got {_short(count)}")
        other_count = other_count or (count if count != str(width - 2) else None)
        for i, j in enumerate(shape_cols):
            weights[k, i] = _float(fields[j], label, line, header[j], -1e-3, 1 + 1e-3,
                                   "a blendshape weight", "0 to 1")
        for i, c in enumerate(rot_cols if has_rot else []):
            assert c is not None
            rotations[k, i] = _float(fields[c], label, line, header[c], -360.0, 360.0,
                                     "an angle (radians, or degrees)")
    notes: list[str] = []
    if other_count:
        notes.append(f"BlendShapeCount {other_count} differs from the {width - 2} columns "
                     "after it (ignored: the header names the columns)")
    if has_rot and np.abs(rotations).max() > math.pi:
        rotations = np.radians(rotations)
        notes.append("rotations above pi: read as degrees")
    if fps is None:
        top = stamps[:, 1].max()
        fps = next((r for r in STANDARD_RATES if r > top), float(top + 1))
        notes.append(f"frame rate not stored in the file: {fps_text(fps)} fps inferred from "
                     f"the largest timecode frame ({int(top)}); give --fps to override")
    elif stamps[:, 1].max() >= fps:
        k = int(np.argmax(stamps[:, 1] >= fps))
        raise CsvFormatError(f"{label} line {data[k][0]}, column Timecode: frame "
                             f"{int(stamps[k, 1])} does not exist at {fps_text(fps)} fps")
    times = stamps[:, 0] + (stamps[:, 1] + stamps[:, 2]) / fps
    back = np.flatnonzero(np.diff(times) <= 0)
    if back.size:
        k = int(back[0]) + 1
        raise CsvFormatError(f"{label} line {data[k][0]}, column Timecode: {data[k][1][0]} is "
                             f"not after the previous row's {data[k - 1][1][0]}; expected "
                             "increasing timecodes")
    return LiveLinkCapture(times - times[0], np.clip(weights, 0.0, 1.0), rotations, fps,
                           has_rot, notes)


def live_link_order() -> list[int]:
    """ARKit indices in Live Link Face's CSV column order: ARKit's, except that the app writes
    JawRight before JawLeft and MouthRight before MouthLeft."""
    names = list(arkit_table().names)
    for a, b in (("jawLeft", "jawRight"), ("mouthLeft", "mouthRight")):
        i, j = names.index(a), names.index(b)
        names[i], names[j] = names[j], names[i]
    return [arkit_table().names.index(n) for n in names]


def _timecode(frame: int, fps: int) -> str:
    """SMPTE ``HH:MM:SS:FF.000`` of frame number ``frame`` at a whole ``fps``."""
    secs, ff = divmod(frame, fps)
    h, rest = divmod(secs, 3600)
    m, s = divmod(rest, 60)
    return f"{h:02d}:{m:02d}:{s:02d}:{ff:02d}.000"


def _low_level(seq: FapSequence) -> FapSequence:
    """``seq`` with FAP 1/2 (visemes, expressions) expanded into low-level FAPs."""
    return expand_high_level(seq) if seq.has_high_level else seq


def _num(v: float) -> str:
    s = f"{v:.6f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def format_live_link(seq: FapSequence) -> str:
    """The Live Link Face CSV text of ``seq`` (blendshapes fitted, rotations read off)."""
    t = arkit_table()
    weights, rot = faps_to_arkit(_low_level(seq).frames)
    order = live_link_order()
    weights = weights[:, order]
    header = ["Timecode", "BlendShapeCount", *(t.csv_names[i] for i in order), *t.rotations]
    out = [",".join(header)]
    count = str(len(header) - 2)
    if not float(seq.fps).is_integer():
        raise CsvFormatError(f"Live Link Face timecodes need a whole frame rate, got "
                             f"{fps_text(seq.fps)} fps (resample with --fps)")
    for k in range(seq.n_frames):
        vals = [_num(x) for x in weights[k]] + [_num(x) for x in rot[k]]
        out.append(",".join([_timecode(k, int(seq.fps)), count, *vals]))
    return "\n".join(out) + "\n"


def write_live_link(seq: FapSequence, path: str | os.PathLike) -> Path:
    path = Path(path)
    return atomic_write_text(path, format_live_link(seq), error=CsvFormatError,
                             label=path.name)


# ------------------------------------------------------------------ OpenFace-style AU CSV
def read_au_csv(path: str | os.PathLike, fps: float | None = None, *,
                label: str | None = None) -> AuCapture:
    """Read an OpenFace-style AU CSV (see the module doc); :class:`CsvFormatError` else."""
    label, rows = _header_and_rows(path, fps, label, "frame,timestamp,AU01_r,...")
    table = au_table()
    hline, header = rows[0]
    lower = [h.lower() for h in header]
    for need in ("frame", "timestamp"):
        if lower.count(need) != 1:
            raise CsvFormatError(f"{label} line {hline}: expected one column {need!r} in an AU "
                                 f"CSV header (frame,timestamp,AU01_r,...), got "
                                 f"{lower.count(need)}")
    au_cols: dict[int, list[int]] = {}
    skipped, ignored = [], 0
    for j, name in enumerate(header):
        m = _AU_COL.match(name)
        if not m:
            ignored += lower[j] not in ("frame", "timestamp", "face_id", "confidence", "success")
            continue
        number = table.aliases.get(int(m.group(1)), int(m.group(1)))
        if number not in table.numbers:
            skipped.append(name)
            continue
        if any(header[c].lower() == name.lower() for c in au_cols.get(number, [])):
            raise CsvFormatError(f"{label} line {hline}, column {j + 1}: {name} appears twice")
        au_cols.setdefault(number, []).append(j)
    if not au_cols:
        raise CsvFormatError(f"{label} line {hline}: no AUxx_r intensity column with a 2-D "
                             f"mapping (AU01_r, AU12_r, ...), got {_short(','.join(header))}")
    data = rows[1:]
    if not data:
        raise CsvFormatError(f"{label} line {hline + 1}: no data rows after the header")
    if len(data) > MAX_FRAMES:
        raise CsvFormatError(f"{label}: {len(data)} rows, expected at most {MAX_FRAMES}")
    fcol, tcol = lower.index("frame"), lower.index("timestamp")
    n, width = len(data), len(header)
    times = np.zeros(n)
    values = np.zeros((n, len(table.aus)))
    index = {a.number: i for i, a in enumerate(table.aus)}
    prev_frame = None
    for k, (line, fields) in enumerate(data):
        _check_width(label, line, fields, width)
        fr = fields[fcol]
        if not fr.isdigit() or len(fr) > 9:
            raise CsvFormatError(f"{label} line {line}, column frame: expected a frame number, "
                                 f"got {_short(fr)}")
        if prev_frame is not None and int(fr) <= prev_frame:
            raise CsvFormatError(f"{label} line {line}, column frame: {fr} is not after the "
                                 f"previous row's {prev_frame}; expected increasing frames")
        prev_frame = int(fr)
        times[k] = _float(fields[tcol], label, line, "timestamp", 0.0, 1e7,
                          "a time in seconds")
        if k and times[k] <= times[k - 1]:
            raise CsvFormatError(f"{label} line {line}, column timestamp: {fields[tcol]} is not "
                                 f"after the previous row's {data[k - 1][1][tcol]}; expected "
                                 "increasing times")
        for number, cols in au_cols.items():
            v = max(_float(fields[c], label, line, header[c], 0.0, AU_CSV_MAX,
                           "an AU intensity") for c in cols)
            values[k, index[number]] = v / AU_CSV_MAX
    notes = []
    if skipped:
        notes.append(f"AU column(s) without a 2-D mapping skipped: {', '.join(skipped)}")
    if ignored:
        notes.append(f"{ignored} other column(s) ignored (AUxx_c, gaze, pose, landmarks, ...)")
    if fps is None:
        if n > 1:
            raw = 1.0 / float(np.median(np.diff(times)))
            near = min(STANDARD_RATES, key=lambda r: abs(r - raw))
            # timestamps are rounded to milliseconds: snap to a usual rate within 2 %
            fps = near if abs(near - raw) <= 0.02 * near else min(max(round(raw, 3), 1e-3),
                                                                   MAX_FPS)
        else:
            fps = 30.0
        notes.append(f"frame rate {fps_text(fps)} fps from the timestamps; give --fps to "
                     "override")
    return AuCapture(times - times[0], values, float(fps), notes)


def format_au_csv(seq: FapSequence) -> str:
    """OpenFace-style CSV text of ``seq``: AU intensities 0..5 fitted to its FAPs (one per
    AU: the mean of a sided AU's left and right; AU43 written as OpenFace's AU45 blink)."""
    table = au_table()
    vals = table.to_bilateral(faps_to_aus(_low_level(seq).frames)) * AU_CSV_MAX
    names = [f"AU{45 if a.number == 43 else a.number:02d}_r" for a in table.aus]
    out = [", ".join(["frame", "face_id", "timestamp", "confidence", "success", *names])]
    for k in range(seq.n_frames):
        cells = [str(k + 1), "0", f"{k / seq.fps:.3f}", "1", "1"]
        out.append(", ".join(cells + [f"{v:.2f}" for v in vals[k]]))
    return "\n".join(out) + "\n"


def write_au_csv(seq: FapSequence, path: str | os.PathLike) -> Path:
    path = Path(path)
    return atomic_write_text(path, format_au_csv(seq), error=CsvFormatError, label=path.name)


# ------------------------------------------------------------------ any animation file
def resample(times: np.ndarray, faps: np.ndarray, fps: float, name: str) -> FapSequence:
    """Rows at ``times`` (s, from 0) -> a FapSequence of uniform frames at ``fps`` (linear)."""
    # + 0.05 frame: timestamps rounded to milliseconds (OpenFace) must not lose the last frame
    n = int(math.floor(times[-1] * fps + 0.05)) + 1
    if n > MAX_FRAMES:
        raise CsvFormatError(f"{name}: {n} frames at {fps_text(fps)} fps, expected at most "
                             f"{MAX_FRAMES}")
    t = np.arange(n) / fps
    idx = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 1)
    nxt = np.minimum(idx + 1, len(times) - 1)
    span = times[nxt] - times[idx]
    a = np.where(span > 0, (t - times[idx]) / np.where(span > 0, span, 1.0), 0.0)[:, None]
    frames = (1 - a) * faps[idx] + a * faps[nxt]
    frames[:, :2] = 0.0
    return FapSequence(frames.astype(np.float32), fps=fps, name=name)


def detect_kind(path: str | os.PathLike) -> str:
    """``"arkit"`` or ``"au"`` for a ``.csv`` (from its header), else ``"fap"`` (the .fap
    reader then judges the file)."""
    p = Path(path)
    if p.suffix.lower() != ".csv":
        return "fap"
    lines = _text(p, p.name)
    first = next((s for s in lines if s.strip()), "")
    cols = [c.strip() for c in first.split(",")]
    if cols[:2] == ["Timecode", "BlendShapeCount"]:
        return "arkit"
    if any(_AU_COL.match(c) for c in cols):
        return "au"
    raise CsvFormatError(f"{p.name} line 1: neither a Live Link Face CSV "
                         "('Timecode,BlendShapeCount,...') nor an AU CSV "
                         f"('frame,timestamp,AU01_r,...'), got {_short(first)}")


def read_animation(path: str | os.PathLike, fps: float | None = None
                   ) -> tuple[FapSequence, str, list[str]]:
    """(sequence, kind, notes) of a ``.fap``, Live Link Face or AU CSV file. CSV rows are
    resampled at ``fps`` (default: the file's). A ``.fap`` keeps its own frames."""
    kind = detect_kind(path)
    name = Path(path).stem
    if kind == "fap":
        try:
            seq = read_fap(path)
        except FapFileError as e:
            if Path(path).suffix.lower() == ".fap":
                raise
            # neither .fap nor .csv by its name: say what an animation may be
            raise FapFileError(f"{e} (an animation is a .fap file, a Live Link Face CSV or an "
                               "AU CSV)") from None
        return seq, kind, list(seq.notes)
    cap: LiveLinkCapture | AuCapture
    cap = read_live_link(path, fps) if kind == "arkit" else read_au_csv(path, fps)
    return resample(cap.times, cap.faps(), fps or cap.fps, name), kind, cap.notes


def write_animation(seq: FapSequence, path: str | os.PathLike, kind: str) -> Path:
    """Write ``seq`` as ``kind`` (``fap``, ``arkit``, ``au``) to ``path`` atomically."""
    if kind == "fap":
        return write_fap(seq, path)
    if kind == "arkit":
        return write_live_link(seq, path)
    if kind == "au":
        return write_au_csv(seq, path)
    raise FapFileError(f"unknown output kind {kind!r}, expected one of {', '.join(KINDS)}")
