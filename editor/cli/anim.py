"""CLI commands for presets, .fap files and animation: ``animate``, ``fap export``, ``fap info``.

``render --preset`` lives in :mod:`editor.cli`; this module registers the rest.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import TYPE_CHECKING

from editor.errors import FapStudioError

from .util import PHOTO_HELP, ProgressBar, detector_option, photo_arg

if TYPE_CHECKING:
    import numpy as np

# numpy and the engine are imported by the commands that use them, so that ``fap-studio --help``
# stays quick (issue 15, ``cli_help_s``).


def parse_preset(spec: str) -> tuple[str, float]:
    """``joy`` or ``joy:0.8`` -> (name, intensity)."""
    name, _, inten = spec.partition(":")
    if not name:
        raise FapStudioError(f"--preset {spec!r}: expected NAME or NAME:INTENSITY")
    try:
        value = float(inten) if inten else 1.0
    except ValueError as e:
        raise FapStudioError(f"--preset {spec!r}: {inten!r} is not a number") from e
    if math.isnan(value):
        raise FapStudioError(f"--preset {spec!r}: {inten!r} is not a number")
    if not 0.0 <= value <= 1.5:
        raise FapStudioError(f"--preset {spec!r}: intensity must be within 0 … 1.5")
    return name, value


def preset_vector(specs: list[str] | None) -> np.ndarray:
    """Sum of presets ``NAME[:INTENSITY]`` as a (68,) vector (clamped)."""
    import numpy as np

    from editor.engine.faps import FAPS
    from editor.formats.presets import apply_preset, get_preset

    total = np.zeros(68, np.float32)
    for spec in specs or []:
        name, value = parse_preset(spec)
        total += apply_preset(get_preset(name), value)
    return FAPS.clamp(total)


def cmd_animate(a: argparse.Namespace) -> int:
    from editor.engine.face import Face
    from editor.formats.facecsv import read_animation
    from editor.formats.video import export_sequence
    from editor.safeio import finite_in

    fps = None if a.fps is None else finite_in(a.fps, 0, 1000, "--fps", lo_open=True)
    if a.jobs is not None and not 1 <= a.jobs <= 256:
        raise FapStudioError(f"--jobs: expected 1-256, got {a.jobs}")
    jobs = a.jobs  # None: a worker per core (pool.render_workers)
    seq, kind, notes = read_animation(a.fap_file, fps)
    face = Face.from_image(a.photo)
    for n in notes if kind != "fap" else []:  # what a CSV reader inferred (fps, columns)
        print(f"fap-studio: note: {n}", file=sys.stderr)
    with ProgressBar("render", quiet=a.quiet) as bar:
        # fork: this process runs no Qt (nor other threads): the workers inherit the face
        res = export_sequence(face, seq, a.output, progress=bar, creases=not a.no_creases,
                              jobs=jobs, fork=True)
    print(f"{res.frames} frames -> {res.path}", file=sys.stderr)
    return 0


def cmd_fap_export(a: argparse.Namespace) -> int:
    import numpy as np

    from editor.formats.fapfile import MAX_FPS, MAX_FRAMES, FapSequence, write_fap
    from editor.formats.keyframes import sequence_from_keyframes
    from editor.safeio import finite_in

    fps = finite_in(a.fps, 0, MAX_FPS, "--fps", lo_open=True)
    if a.keyframes:
        finite_in(a.duration, 0, (MAX_FRAMES - 1) / fps, "--duration", lo_open=True)
    elif not 1 <= a.frames <= MAX_FRAMES:
        raise FapStudioError(f"--frames: expected 1-{MAX_FRAMES}, got {a.frames}")
    vec = preset_vector(a.preset)
    if a.keyframes:
        # neutral -> expression -> neutral over the given duration
        d = a.duration
        seq = sequence_from_keyframes([(0.0, np.zeros(68, np.float32)), (d / 2, vec),
                                       (d, np.zeros(68, np.float32))], fps=a.fps,
                                      interpolation="smoothstep", name=a.name)
    else:
        seq = FapSequence.single(vec, fps=a.fps, frames=a.frames, name=a.name)
    write_fap(seq, a.output)
    print(f"{seq.n_frames} frames at {a.fps:g} fps -> {a.output}", file=sys.stderr)
    return 0


def cmd_fap_info(a: argparse.Namespace) -> int:
    from editor.formats.fapfile import fap_info_file

    print(fap_info_file(a.fap_file))  # streamed: memory flat in the file's length
    return 0


def add_anim_parser(sub) -> None:
    s = sub.add_parser("animate", help="render a .fap sequence, Live Link Face CSV or AU CSV on "
                       "a photo to MP4 or PNG frames")
    s.add_argument("photo", type=photo_arg, help=PHOTO_HELP)
    s.add_argument("fap_file", metavar="animation",
                   help=".fap, Live Link Face .csv (ARKit blendshapes) or AU .csv (AUxx_r)")
    s.add_argument("--fps", type=float, help="CSV input: frame rate to render at (default: "
                   "the file's, inferred and said)")
    s.add_argument("-o", "--output", required=True, help="out.mp4 / out.avi, or a folder")
    s.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    s.add_argument("--no-creases", action="store_true", help="geometry only: no skin folds")
    s.add_argument("-j", "--jobs", type=int, metavar="N",
                   help="render in N worker processes (default: one per CPU core while this "
                   "process encodes; 1: all in this process); the frames are the same")
    detector_option(s)
    s.set_defaults(func=cmd_animate)

    f = sub.add_parser("fap", help=".fap files: export presets, show information")
    fs = f.add_subparsers(dest="fap_command", metavar="COMMAND")
    e = fs.add_parser("export", help="write a preset (or a mix) as a .fap file")
    e.add_argument("--preset", action="append", required=True, metavar="NAME[:INTENSITY]",
                   help="an emotion or viseme preset at an intensity 0-1.5 (default 1); "
                   "repeat to mix, the values add up")
    e.add_argument("--frames", type=int, default=1, help="frames holding the expression")
    e.add_argument("--fps", type=float, default=25.0, help="frame rate (default: 25)")
    e.add_argument("--keyframes", action="store_true",
                   help="neutral -> expression -> neutral over --duration seconds")
    e.add_argument("--duration", type=float, default=2.0,
                   help="seconds from neutral back to neutral with --keyframes (default: 2)")
    e.add_argument("--name", default="fap-studio",
                   help="the sequence's name in the file's header (default: fap-studio)")
    e.add_argument("-o", "--output", required=True, help="the .fap file to write")
    e.set_defaults(func=cmd_fap_export)
    i = fs.add_parser("info", help="version, name, fps, frames and the FAPs a file uses")
    i.add_argument("fap_file")
    i.set_defaults(func=cmd_fap_info)
