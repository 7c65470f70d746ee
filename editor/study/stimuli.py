"""MOS study builders and the answers export, used by ``fap-studio study`` and the rating panel.

:func:`from_folder` (images + a CSV of true labels), :func:`create_from_renders` (rendered
faces x presets, see :func:`render_stimuli`) and :func:`export_answers_csv` (long format).
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Callable, Sequence
from pathlib import Path

import cv2
import numpy as np

from editor.engine.face import Face
from editor.engine.imageio import MAX_FILE_BYTES
from editor.errors import ImageError, StudyError
from editor.formats.presets import apply_preset, get_preset
from editor.safeio import atomic_write_text, read_bounded
from editor.study.mos import PAPER_EXPRESSIONS, StimulusSpec, Study  # noqa: F401 (re-export)


def encode_png(rgb: np.ndarray) -> bytes:
    """Encode an H x W x 3 uint8 RGB array as PNG (lossless, ``cv2.imencode``)."""
    if not (isinstance(rgb, np.ndarray) and rgb.dtype == np.uint8 and rgb.ndim == 3
            and rgb.shape[2] == 3 and rgb.shape[0] > 0 and rgb.shape[1] > 0):
        raise ImageError("a rendered stimulus must be a non-empty H x W x 3 uint8 RGB array")

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




def face_crop(face) -> tuple[int, int, int, int]:
    """Box ``(x0, y0, x1, y1)`` around the face with hair, chin and some background."""
    return face.crop_box(0.55, 0.8, 0.55, 0.45)


def render_stimuli(faces: Sequence[str | Path], presets: Sequence[str],
                   intensities: Sequence[float], crop: bool = True,
                   progress: Callable[[int, int], object] | None = None, jobs: int = 1
                   ) -> list[tuple[str, str, float, np.ndarray]]:
    """Render faces x presets x intensities: (face name, expression, intensity, RGB image).

    With ``crop`` (default) each stimulus is cut to the face region (:func:`face_crop`), so
    that raters judge the face, not the photo around it. ``progress(done, total)`` is called
    after each face fit and each render (it may raise to stop). ``jobs`` > 1 fits and renders
    the faces in that many worker processes (:func:`editor.engine.pool.ordered_map`, a face
    per task; progress then moves a face at a time): the same images, in the same order.
    """
    from editor.engine.landmarks import default_detector_name
    from editor.engine.pool import ordered_map

    out = []
    names: set[str] = set()
    total, done = len(faces) * (1 + len(presets) * len(intensities)), 0
    tasks = [(path, tuple(presets), tuple(float(k) for k in intensities), crop,
              default_detector_name()) for path in faces]
    parallel = jobs > 1 and len(tasks) > 1

    def step() -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(done, total)

    results = (ordered_map(_face_stimuli, tasks, min(jobs, len(tasks))) if parallel
               else (_face_stimuli(t, step) for t in tasks))
    try:
        for path, renders in zip(faces, results, strict=True):
            name = Path(path).stem
            while name in names:
                name += "_"
            names.add(name)
            out += [(name, expr, k, img) for expr, k, img in renders]
            if parallel:
                done += len(renders)
                step()
    finally:
        close = getattr(results, "close", None)
        if close is not None:
            close()
    return out


def _face_stimuli(task: tuple[str | Path, tuple[str, ...], tuple[float, ...], bool, str],
                  step: Callable[[], None] | None = None
                  ) -> list[tuple[str, float, np.ndarray]]:
    """One face's stimuli: fit the photo, render every preset x intensity (cropped);
    ``step()`` after the fit and after each render."""
    from editor.engine.landmarks import get_detector

    path, presets, intensities, crop, detector = task
    face = Face.from_image(path, get_detector(detector))
    if step is not None:
        step()
    x0, y0, x1, y1 = face_crop(face) if crop else (0, 0, face.image.shape[1],
                                                      face.image.shape[0])
    out = []
    for p in presets:
        preset = get_preset(p)
        for k in intensities:
            # (bicubic: raters judge whether it looks like a photo; a bilinear warp softens
            # the skin that moves, next to the sharp skin that does not)
            img = face.render(apply_preset(preset, k), sharp=True)[y0:y1, x0:x1]
            out.append((preset.name, float(k), np.ascontiguousarray(img)))
            if step is not None:
                step()
    return out
