"""``fap-studio study ...``: create, report and export MOS rating studies (no Qt).

Besides the argparse sub-command (:func:`add_study_parser`) this module holds the study builders
and the CSV export that both the CLI and the rating panel use: :func:`from_folder` (images + a
CSV of true labels), :func:`create_from_renders` (rendered faces x presets, see
:func:`render_stimuli`) and :func:`export_answers_csv` (long format).
(They live here rather than in ``editor/core/mos.py`` to keep that module under 400 lines.)
"""

from __future__ import annotations

import argparse
import csv
import io
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from editor.cli_util import guarded, photo_arg
from editor.core.errors import ImageError, StudyError
from editor.core.imageio import MAX_FILE_BYTES
from editor.core.mos import StimulusSpec, Study
from editor.core.safeio import atomic_write_text, read_bounded


def encode_png(rgb: np.ndarray) -> bytes:
    """Encode an H x W x 3 uint8 RGB array as PNG (lossless, ``cv2.imencode``)."""
    if not (isinstance(rgb, np.ndarray) and rgb.dtype == np.uint8 and rgb.ndim == 3
            and rgb.shape[2] == 3 and rgb.shape[0] > 0 and rgb.shape[1] > 0):
        raise ImageError("a rendered stimulus must be a non-empty H x W x 3 uint8 RGB array")
    import cv2

    ok, buf = cv2.imencode(".png", np.ascontiguousarray(rgb[..., ::-1]))
    if not ok:  # pragma: no cover - OpenCV encodes any valid uint8 image
        raise ImageError("cannot encode the stimulus as PNG")
    return buf.tobytes()


def create_from_renders(path: str | Path, name: str, labels: Sequence[str],
                        renders: Sequence[tuple[str, str, float, np.ndarray]],
                        allow_revise: bool = False, break_every: int = 0) -> Study:
    """Create a study from already-rendered images: (face, expression, intensity, RGB uint8).

    This is the hook for the faces x presets x intensities route (the paper's design); the
    images are stored losslessly as PNG inside the study.
    """
    specs = [StimulusSpec(face, expr, encode_png(img), float(k), f"{face}/{expr}@{float(k):g}")
             for face, expr, k, img in renders]
    return Study.create(path, name, labels, specs, allow_revise, break_every)


def from_folder(path: str | Path, folder: str | Path, csv_path: str | Path,
                name: str | None = None, labels: Sequence[str] | None = None,
                allow_revise: bool = False, break_every: int = 0) -> Study:
    """Create a study from a folder of images and a CSV of their true labels.

    The CSV has a header with columns ``file`` and ``label`` (required) and optionally ``face``
    (default: the file's stem) and ``intensity`` (default 1). ``file`` is relative to
    ``folder``. ``labels`` defaults to the CSV labels in order of first appearance.
    """
    folder, csv_path = Path(folder), Path(csv_path)
    if not folder.is_dir():
        raise StudyError(f"{folder}: image folder not found")
    try:
        raw = read_bounded(csv_path, MAX_CSV_BYTES, error=StudyError, what="a CSV file")
    except StudyError as e:
        why = str(e).partition(": cannot read ")[2] or str(e)
        raise StudyError(f"{csv_path}: cannot read labels CSV {why}") from None
    try:
        with io.StringIO(raw.decode("utf-8-sig"), newline="") as f:
            reader = csv.DictReader(f)
            fields = [(h or "").strip().lower() for h in reader.fieldnames or []]
            if not {"file", "label"} <= set(fields):
                raise StudyError(f"{csv_path}: header must name columns 'file' and 'label' "
                                 f"(got {fields or 'an empty file'})")
            reader.fieldnames = fields
            rows = [(reader.line_num, row) for row in reader]
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise StudyError(f"{csv_path}: cannot read labels CSV ({e})") from e
    specs, seen = [], set()
    for line, row in rows:
        file, label = (row.get("file") or "").strip(), (row.get("label") or "").strip()
        if not file or not label:
            raise StudyError(f"{csv_path}:{line}: 'file' and 'label' must not be empty")
        if file in seen:
            raise StudyError(f"{csv_path}:{line}: {file} is listed twice")
        seen.add(file)
        try:
            intensity = float((row.get("intensity") or "1").strip())
        except ValueError as e:
            raise StudyError(f"{csv_path}:{line}: bad intensity ({e})") from e
        if not math.isfinite(intensity):
            raise StudyError(f"{csv_path}:{line}: bad intensity ({intensity})")
        data = read_bounded(folder / file, MAX_FILE_BYTES, error=ImageError,
                            label=f"{folder / file}", what="an image file")
        face = (row.get("face") or "").strip() or Path(file).stem
        specs.append(StimulusSpec(face, label, data, intensity, file))
    if not specs:
        raise StudyError(f"{csv_path}: no stimuli listed")
    labels = list(dict.fromkeys(s.label for s in specs)) if labels is None else list(labels)
    return Study.create(path, name or Path(path).stem, labels, specs, allow_revise, break_every)


MAX_CSV_BYTES = 16 * 1024 * 1024

EXPORT_COLUMNS = ("study", "rater", "stimulus_id", "face", "intensity", "true_label",
                  "chosen_label", "correct", "naturalness", "response_ms", "timestamp",
                  "order_position", "revisions")


def export_answers_csv(study: Study, out: str | Path) -> int:
    """Write all answers in long format (one row per answer, :data:`EXPORT_COLUMNS`).

    Returns the number of answer rows written.
    """
    answers = study.answers()
    buf = io.StringIO(newline="")
    writer = csv.writer(buf)
    writer.writerow(EXPORT_COLUMNS)
    for a in answers:
        writer.writerow([a.study, a.rater, a.stimulus_id, a.face, a.intensity,
                         a.true_label, a.label, int(a.correct), a.naturalness,
                         a.response_ms, a.answered_at, a.position, a.revisions])
    atomic_write_text(out, buf.getvalue(), error=StudyError, label=f"{out} (CSV)")
    return len(answers)


#: The paper's design (SPEC §4): these five expressions on every face, full intensity.
PAPER_EXPRESSIONS = ("joy", "sadness", "anger", "fear", "surprise")


def face_crop(face) -> tuple[int, int, int, int]:
    """Box ``(x0, y0, x1, y1)`` around the face with hair, chin and some background."""
    return face.crop_box(0.55, 0.8, 0.55, 0.45)


def render_stimuli(faces: Sequence[str | Path], presets: Sequence[str],
                   intensities: Sequence[float], crop: bool = True
                   ) -> list[tuple[str, str, float, np.ndarray]]:
    """Render faces x presets x intensities: (face name, expression, intensity, RGB image).

    With ``crop`` (default) each stimulus is cut to the face region (:func:`face_crop`), so
    that raters judge the face, not the photo around it.
    """
    from editor.core import Face
    from editor.core.expressions import apply_preset, get_preset

    out = []
    names: set[str] = set()
    for path in faces:
        face = Face.from_image(path)
        name = Path(path).stem
        while name in names:
            name += "_"
        names.add(name)
        x0, y0, x1, y1 = face_crop(face) if crop else (0, 0, face.image.shape[1],
                                                          face.image.shape[0])
        for p in presets:
            preset = get_preset(p)
            for k in intensities:
                img = face.render(apply_preset(preset, k))[y0:y1, x0:x1]
                out.append((name, preset.name, float(k), np.ascontiguousarray(img)))
    return out


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
    from editor.core.mos_stats import analyse, format_report  # scipy: import lazily

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
