"""``fap-studio study ...``: create, report, export, QC, invite, revoke and serve (no Qt).

The builders and the CSV export live in :mod:`editor.study.stimuli` (the rating panel uses them
too), quality control in :mod:`editor.study.qc`, remote raters in :mod:`editor.study.remote` and
:mod:`editor.study.web`; this module is the argparse sub-command (:func:`add_study_parser`).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from editor.errors import StudyError
from editor.study.design import PAPER_EXPRESSIONS

from .util import detector_option, guarded, photo_arg

if TYPE_CHECKING:
    from editor.study.mos import Study

# The study store (numpy, SQLite) and the QC, remote-rater and stimulus modules (the renderer,
# OpenCV) are imported by the commands that use them, so that ``fap-studio --help`` stays quick
# (issue 15, ``cli_help_s``).


def _open(path: str) -> Study:
    """``Study.open(path)``, the study store imported on first use."""
    from editor.study.mos import Study

    return Study.open(path)


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
        from editor.engine.pool import default_jobs
        from editor.study.stimuli import create_from_renders, render_stimuli

        renders = render_stimuli(args.faces, presets, ks, crop=args.crop == "face",
                                 jobs=default_jobs())
        study = create_from_renders(args.study, args.name or Path(args.study).stem,
                                    labels or presets, renders, args.allow_revise,
                                    args.break_every)
    else:
        if args.labels_csv is None:
            raise StudyError("--folder needs --labels-csv")
        from editor.study.stimuli import from_folder

        study = from_folder(args.study, args.folder, args.labels_csv, name=args.name,
                            labels=labels, allow_revise=args.allow_revise,
                            break_every=args.break_every)
    with study:
        print(f"created study {study.name!r} in {study.path}: {len(study.stimuli())} stimuli, "
              f"labels {', '.join(study.labels)} (+ cannot tell)")
        if args.qc:
            _add_qc(study, args.faces or [], args.crop == "face", 3, 2)
    return 0


def _add_qc(study: Study, faces: list, crop: bool, training: int, traps: int) -> None:
    from editor.study.qc import add_qc_items, qc_items, render_qc, trap_specs

    specs = render_qc(faces, study.labels, crop, training) if faces else []
    specs += trap_specs(study, traps, seed=len(qc_items(study)))
    add_qc_items(study, specs)
    n = {k: sum(s.kind == k for s in specs) for k in ("training", "gold", "trap")}
    print(f"added QC trials: {n['training']} training, {n['gold']} gold, {n['trap']} trapping"
          + ("" if faces else " (gold and training need --faces)"))


@guarded
def _cmd_qc(args: argparse.Namespace) -> int:
    """``study qc STUDY.db [--faces PHOTO ...] [--training N] [--traps N]``."""
    if args.training < 0 or args.traps < 0:
        raise StudyError("--training and --traps must be >= 0")
    with _open(args.study) as study:
        _add_qc(study, args.faces or [], args.crop == "face", args.training, args.traps)
    return 0


@guarded
def _cmd_invite(args: argparse.Namespace) -> int:
    """``study invite STUDY.db --raters N [--base-url URL]``: one URL per new web rater."""
    from editor.study.remote import invite

    base = args.base_url.rstrip("/")
    if not base.startswith(("http://", "https://")):
        raise StudyError(f"--base-url must start with http:// or https://, got {base!r}")
    with _open(args.study) as study:
        for inv in invite(study, args.raters):
            print(f"{inv.rater}\t{base}/r/{inv.token}/")
    return 0


@guarded
def _cmd_revoke(args: argparse.Namespace) -> int:
    """``study revoke STUDY.db RATER_OR_TOKEN ...``."""
    from editor.study.remote import revoke

    with _open(args.study) as study:
        for who in args.who:
            print(f"revoked {revoke(study, who)}")
    return 0


@guarded
def _cmd_serve(args: argparse.Namespace) -> int:
    """``study serve STUDY.db [--host H] [--port P]``: the rating page until Ctrl-C."""
    import sys

    from editor.study.remote import count_tokens
    from editor.study.web import serve

    if not 0 <= args.port <= 65535:
        raise StudyError(f"--port must be 0 … 65535, got {args.port}")

    with _open(args.study) as study:
        valid, revoked = count_tokens(study)

    def ready(url: str) -> None:
        print(f"serving study {args.study} at {url}/r/TOKEN/ to {valid} invited raters "
              f"({revoked} revoked; more: fap-studio study invite); Ctrl-C stops", flush=True)
        sys.stdout.flush()

    serve(args.study, args.host, args.port, args.rate_limit, ready)
    return 0


@guarded
def _cmd_report(args: argparse.Namespace) -> int:
    """``study report STUDY.db``: print Tables 4-6, confusion matrix, kappa and raters."""
    from editor.study.mos_stats import analyse, format_report  # scipy: import lazily
    from editor.study.qc import format_qc, mos_answers, qc_items, rater_qc

    with _open(args.study) as study:
        answers, stimuli = mos_answers(study), study.stimuli()
        report = analyse(answers, study.labels, stimuli, confidence=args.confidence)
        qc = rater_qc(study)
        n_out = sum(r.excluded for r in qc)
        title = (f"Study {study.name!r}: {len(stimuli)} stimuli, {len(study.raters())} raters, "
                 f"{len(answers)} answers"
                 + (f" (MOS without the {n_out} raters excluded by QC)" if n_out else ""))
        qc_text = format_qc(qc_items(study), qc)
    print(format_report(report, title), end="")
    print("\n" + qc_text, end="")
    return 0


@guarded
def _cmd_export(args: argparse.Namespace) -> int:
    """``study export STUDY.db -o answers.csv``: one row per answer."""
    from editor.study.stimuli import export_answers_csv

    with _open(args.study) as study:
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
    study = subparsers.add_parser("study", help="MOS rating studies: create, report, export, "
                                  "qc, invite, revoke, serve")
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
    create.add_argument("--qc", action="store_true",
                        help="add P.808-style QC trials: 2 trapping, and with --faces 3 "
                        "training and 2 gold per face (see 'study qc')")
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
    qc = sub.add_parser("qc", help="add P.808-style quality-control trials (training, gold, "
                        "trapping) for web raters")
    qc.add_argument("study", type=Path)
    qc.add_argument("--faces", nargs="+", metavar="PHOTO", type=photo_arg,
                    help="neutral photos for gold trials (the photo unchanged, a preset at "
                    "150 %%) and, with them, training trials on the sample face")
    qc.add_argument("--training", type=int, default=3, metavar="N",
                    help="training trials with feedback (needs --faces; default 3)")
    qc.add_argument("--traps", type=int, default=2, metavar="N",
                    help="trapping trials with a printed instruction (default 2)")
    qc.add_argument("--crop", choices=("face", "full"), default="face")
    qc.set_defaults(func=_cmd_qc)
    inv = sub.add_parser("invite", help="create web rater tokens; prints one URL per rater")
    inv.add_argument("study", type=Path)
    inv.add_argument("--raters", type=int, required=True, metavar="N")
    inv.add_argument("--base-url", default="http://127.0.0.1:8808",
                     help="public address of 'study serve' (default %(default)s)")
    inv.set_defaults(func=_cmd_invite)
    rev = sub.add_parser("revoke", help="revoke web raters' links (rater id or token)")
    rev.add_argument("study", type=Path)
    rev.add_argument("who", nargs="+", metavar="RATER_OR_TOKEN")
    rev.set_defaults(func=_cmd_revoke)
    serve = sub.add_parser("serve", help="serve the rating page to invited web raters")
    serve.add_argument("study", type=Path)
    serve.add_argument("--host", default="127.0.0.1", help="address to listen on "
                       "(default %(default)s; put a TLS reverse proxy in front, see README)")
    serve.add_argument("--port", type=int, default=8808, help="port (default %(default)s; 0: any)")
    serve.add_argument("--rate-limit", default="300/minute", metavar="N/PERIOD",
                       help="requests per token (default %(default)s)")
    serve.set_defaults(func=_cmd_serve)
