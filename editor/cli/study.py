"""``fap-studio study ...``: create, report and export MOS rating studies (no Qt).

The builders and the CSV export live in :mod:`editor.study.stimuli` (the rating panel uses them
too); this module is the argparse sub-command (:func:`add_study_parser`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from editor.errors import StudyError
from editor.study.mos import Study
from editor.study.stimuli import (
    PAPER_EXPRESSIONS,
    create_from_renders,
    export_answers_csv,
    from_folder,
    render_stimuli,
)

from .util import detector_option, guarded, photo_arg


@guarded
def _cmd_create(args: argparse.Namespace) -> int:
    """``study create STUDY.db (--folder DIR --labels-csv CSV | --faces PHOTO ... [--presets])``."""
    labels = None if args.labels is None else [x.strip() for x in args.labels.split(",")]
    if (args.folder is None) == (not args.faces):
        raise StudyError("give either --folder with --labels-csv, or --faces (render route)")
    if args.faces:
        presets = [x.strip() for x in args.presets.split(",") if x.strip()]
        try:
            ks = [float(x) for x in args.intensities.split(",") if x.strip()]
        except ValueError as e:
            raise StudyError(f"--intensities {args.intensities!r}: not a list of numbers") from e
        if not ks or any(not 0 <= k <= 1.5 for k in ks):
            raise StudyError("--intensities must be numbers within 0 … 1.5")
        renders = render_stimuli(args.faces, presets, ks, crop=args.crop == "face")
        study = create_from_renders(args.study, args.name or Path(args.study).stem,
                                    labels or presets, renders, args.allow_revise,
                                    args.break_every)
    else:
        if args.labels_csv is None:
            raise StudyError("--folder needs --labels-csv")
        study = from_folder(args.study, args.folder, args.labels_csv, name=args.name,
                            labels=labels, allow_revise=args.allow_revise,
                            break_every=args.break_every)
    with study:
        print(f"created study {study.name!r} in {study.path}: {len(study.stimuli())} stimuli, "
              f"labels {', '.join(study.labels)} (+ cannot tell)")
    return 0


@guarded
def _cmd_report(args: argparse.Namespace) -> int:
    """``study report STUDY.db``: print Tables 4-6, confusion matrix, kappa and raters."""
    from editor.study.mos_stats import analyse, format_report  # scipy: import lazily

    with Study.open(args.study) as study:
        answers, stimuli = study.answers(), study.stimuli()
        report = analyse(answers, study.labels, stimuli, confidence=args.confidence)
        title = (f"Study {study.name!r}: {len(stimuli)} stimuli, {len(study.raters())} raters, "
                 f"{len(answers)} answers")
    print(format_report(report, title), end="")
    return 0


@guarded
def _cmd_export(args: argparse.Namespace) -> int:
    """``study export STUDY.db -o answers.csv``: one row per answer."""
    with Study.open(args.study) as study:
        n = export_answers_csv(study, args.output)
    print(f"wrote {n} answers to {args.output}")
    return 0


def _confidence(text: str) -> float:
    value = float(text)
    if not 0 < value < 1:
        raise argparse.ArgumentTypeError(f"confidence must be in (0, 1), got {text}")
    return value


def add_study_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``study {create,report,export}`` on a main parser's sub-parsers.

    Each leaf sets ``func``: the main CLI calls ``args.func(args)`` and exits with the returned
    code (0 ok, 2 on a :class:`FapStudioError`, already printed as one line on stderr).
    """
    study = subparsers.add_parser("study", help="MOS rating studies: create, report, export")
    sub = study.add_subparsers(dest="study_command", required=True, metavar="COMMAND")
    create = sub.add_parser(
        "create", help="create a study: render faces x presets x intensities (default: the "
        "paper's five expressions), or from a folder of images + labels CSV")
    create.add_argument("study", type=Path, help="new study database (must not exist)")
    create.add_argument("--faces", nargs="+", metavar="PHOTO", type=photo_arg,
                        help="neutral face photos to render the stimuli from")
    create.add_argument("--presets", default=",".join(PAPER_EXPRESSIONS),
                        help="comma-separated presets (default: %(default)s)")
    create.add_argument("--intensities", default="1.0",
                        help="comma-separated preset intensities 0-1.5 (default 1.0)")
    create.add_argument("--crop", choices=("face", "full"), default="face",
                        help="stimuli cut to the face region (default) or the full photo")
    create.add_argument("--folder", type=Path, help="folder of stimulus images")
    create.add_argument("--labels-csv", type=Path,
                        help="CSV with columns file,label[,face,intensity]")
    create.add_argument("--name", help="study name (default: the database file's stem)")
    create.add_argument("--labels", help="comma-separated labels in display order "
                                         "(default: the CSV's labels in order of appearance)")
    create.add_argument("--allow-revise", action="store_true",
                        help="let raters change a committed answer")
    create.add_argument("--break-every", type=int, default=0, metavar="N",
                        help="offer a break after every N answers (0: never)")
    detector_option(create)
    create.set_defaults(func=_cmd_create)
    report = sub.add_parser("report", help="print the result tables of a study")
    report.add_argument("study", type=Path)
    report.add_argument("--confidence", type=_confidence, default=0.95,
                        help="confidence level of the intervals (default 0.95)")
    report.set_defaults(func=_cmd_report)
    export = sub.add_parser("export", help="export all answers to CSV (one row per answer)")
    export.add_argument("study", type=Path)
    export.add_argument("-o", "--output", type=Path, required=True, help="CSV file to write")
    export.set_defaults(func=_cmd_export)
