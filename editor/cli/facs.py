"""CLI for FACS Action Units and ARKit blendshapes: ``convert`` between ``.fap``, Live Link
Face CSV and AU CSV, and the ``--au`` values of ``render`` (:func:`au_vector`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from editor.errors import FapStudioError

if TYPE_CHECKING:
    import numpy as np

# numpy and the tables are imported by the commands that use them (``cli_help_s``, issue 15)

KIND_NAMES = {"fap": ".fap", "arkit": "Live Link Face CSV", "au": "AU CSV"}


def au_vector(specs: list[str] | None) -> np.ndarray:
    """(68,) FAPs of ``--au AU=INTENSITY`` values (repeated AUs add up), clamped to the FAP
    ranges."""
    import numpy as np

    from editor.engine.faps import FAPS
    from editor.formats.facs import aus_to_faps, column_weights, parse_au_spec

    pairs: list[tuple[str | int, float]] = []
    for spec in specs or []:
        try:
            keys, value = parse_au_spec(spec)
        except ValueError as e:
            raise FapStudioError(f"--au {e}") from None
        pairs += [(k, value) for k in keys]
    return FAPS.clamp(aus_to_faps(column_weights(pairs)).astype(np.float32))


def _output_kind(path: str, to: str | None) -> str:
    ext = Path(path).suffix.lower()
    if to:
        want = ".fap" if to == "fap" else ".csv"
        if ext != want:
            raise FapStudioError(f"{Path(path).name}: --to {to} writes a {want} file")
        return to
    if ext == ".fap":
        return "fap"
    if ext == ".csv":
        raise FapStudioError(f"{Path(path).name}: a .csv output needs --to arkit (Live Link "
                             "Face) or --to au (OpenFace-style AU CSV)")
    raise FapStudioError(f"{Path(path).name}: expected a .fap or .csv output")


def cmd_convert(a: argparse.Namespace) -> int:
    import numpy as np

    from editor.formats.facecsv import read_animation, resample, write_animation
    from editor.safeio import finite_in

    fps = None if a.fps is None else finite_in(a.fps, 0, 1000, "--fps", lo_open=True)
    kind_out = _output_kind(a.output, a.to)
    seq, kind_in, notes = read_animation(a.input, fps)
    if kind_in == "fap" and fps is not None and fps != seq.fps:
        from editor.formats.fapfile import expand_high_level

        seq = expand_high_level(seq) if seq.has_high_level else seq
        times = np.arange(seq.n_frames) / seq.fps
        seq = resample(times, seq.frames.astype(np.float64), fps, seq.name)
    write_animation(seq, a.output, kind_out)
    for n in notes:
        print(f"fap-studio: note: {n}", file=sys.stderr)
    print(f"{KIND_NAMES[kind_in]} -> {KIND_NAMES[kind_out]}: {seq.n_frames} frames at "
          f"{seq.fps:g} fps -> {a.output}", file=sys.stderr)
    return 0


def add_facs_parser(sub) -> None:
    s = sub.add_parser("convert", help="convert between .fap, Live Link Face CSV (ARKit "
                       "blendshapes) and AU CSV (OpenFace-style)",
                       description="The input kind comes from its extension and header (.fap; "
                       ".csv starting Timecode,BlendShapeCount: Live Link Face; .csv with "
                       "AUxx_r columns: AU CSV). FAPs -> ARKit/AUs is a bounded least-squares "
                       "fit: what the target cannot express is lost (see README).")
    s.add_argument("input", help=".fap, Live Link Face .csv or AU .csv")
    s.add_argument("output", help=".fap or .csv (with --to)")
    s.add_argument("--to", choices=("arkit", "au", "fap"),
                   help="output kind (needed for .csv: arkit = Live Link Face, au = AU CSV)")
    s.add_argument("--fps", type=float, help="frame rate to resample to (CSV input: also the "
                   "rate of the Live Link timecodes; default: inferred and said)")
    s.set_defaults(func=cmd_convert)
