"""P.808-style quality control of a MOS study: training, gold and trapping trials (no Qt).

ITU-T P.808 (crowdsourced ACR tests) asks for a qualification/training part, gold questions
(stimuli with a known answer) and trapping questions (a stimulus that itself tells the rater
which answer to give); raters who fail them are removed before the MOS is computed. Here:

* **training** trials come first; the page shows the intended emotion after each answer. They
  are the qualification: a rater may get at most a third of their labels wrong.
* **gold** trials are mixed into the rating part: the unchanged photo (accepted answers: "cannot
  tell", or "neutral" if that is a study label; naturalness 3-5; a photo that shows an
  expression of its own is neutralised first, as for every stimulus) and an extreme (150 %)
  preset (its emotion; any naturalness).
* **trap** trials are mixed in too: a stimulus image with a printed instruction ("choose the
  emotion X and naturalness N"); only exactly that answer passes.

The items and the answers to them live in two extra tables of the study file (``qc_items``,
``qc_answers``), created when the first item is added; answers to them are never MOS answers.
:data:`QC_RULE` states who is excluded; :func:`mos_answers` applies it. Raters of the in-app
window see no QC trials and are kept.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from editor.errors import StudyError
from editor.study.mos import CANNOT_TELL, NATURALNESS, AnswerRecord, Study, _sniff

KINDS = ("training", "gold", "trap")
QC_SCHEMA = """
CREATE TABLE IF NOT EXISTS qc_items (id INTEGER PRIMARY KEY,
    kind TEXT NOT NULL CHECK (kind IN ('training', 'gold', 'trap')), face TEXT NOT NULL,
    accept TEXT NOT NULL, nat_min INTEGER NOT NULL, nat_max INTEGER NOT NULL,
    note TEXT NOT NULL, mime TEXT NOT NULL, image BLOB NOT NULL,
    CHECK (1 <= nat_min AND nat_min <= nat_max AND nat_max <= 5));
CREATE TABLE IF NOT EXISTS qc_answers (rater TEXT NOT NULL,
    item INTEGER NOT NULL REFERENCES qc_items(id), label TEXT NOT NULL,
    naturalness INTEGER NOT NULL CHECK (naturalness BETWEEN 1 AND 5),
    response_ms REAL NOT NULL CHECK (response_ms >= 0), answered_at TEXT NOT NULL,
    passed INTEGER NOT NULL, PRIMARY KEY (rater, item));
"""

#: The exclusion rule, as printed by ``study report`` and the results window.
QC_RULE = ("a rater with QC trials is excluded from MOS if they fail any trapping trial, pass "
           "fewer than 2/3 of their gold trials, or get more than 1/3 of their training labels "
           "wrong (judged on the QC trials answered so far); raters without QC trials (the "
           "in-app window) are kept")


@dataclass(frozen=True)
class QcItemSpec:
    """A QC item to add: ``accept`` holds the labels that pass, naturalness must lie in
    ``nat_min`` … ``nat_max``; ``image`` is PNG, JPEG or BMP bytes."""

    kind: str
    face: str
    accept: tuple[str, ...]
    nat_min: int
    nat_max: int
    note: str
    image: bytes


@dataclass(frozen=True)
class QcItem:
    """A stored QC item (without its image, see :func:`qc_image`)."""

    id: int
    kind: str
    face: str
    accept: tuple[str, ...]
    nat_min: int
    nat_max: int
    note: str

    def passes(self, label: str, naturalness: int) -> bool:
        """True if this answer is the known one."""
        return label in self.accept and self.nat_min <= naturalness <= self.nat_max


def has_table(study: Study, name: str) -> bool:
    """True if the study file has the table ``name`` (extension tables are created lazily)."""
    return bool(study._rows("SELECT 1 FROM sqlite_master WHERE type='table' AND name=?",
                            (name,)))


def ensure_tables(study: Study, schema: str) -> None:
    """Create the extension tables of ``schema`` (``CREATE TABLE IF NOT EXISTS``) at once."""
    with study._tx() as con:
        for statement in schema.split(";"):
            if statement.strip():
                con.execute(statement)


def add_qc_items(study: Study, specs: Sequence[QcItemSpec]) -> list[int]:
    """Store QC items (one transaction; all or nothing) and return their ids."""
    allowed = (*study.labels, CANNOT_TELL)
    rows = []
    for i, s in enumerate(specs):
        if s.kind not in KINDS:
            raise StudyError(f"QC item {i + 1}: kind must be one of {KINDS}, got {s.kind!r}")
        if not s.accept or any(a not in allowed for a in s.accept):
            raise StudyError(f"QC item {i + 1}: accepted labels {list(s.accept)} must be among "
                             f"{list(allowed)}")
        if not 1 <= s.nat_min <= s.nat_max <= 5:
            raise StudyError(f"QC item {i + 1}: naturalness range {s.nat_min}..{s.nat_max} "
                             "is not within 1..5")
        mime = _sniff(bytes(s.image), f"QC item {i + 1}")
        rows.append((s.kind, s.face, json.dumps(list(s.accept)), s.nat_min, s.nat_max, s.note,
                     mime, sqlite3.Binary(bytes(s.image))))
    ensure_tables(study, QC_SCHEMA)
    with study._tx() as con:
        ids = [int(con.execute("INSERT INTO qc_items (kind, face, accept, nat_min, nat_max, "
                               "note, mime, image) VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                               row).lastrowid or 0) for row in rows]
    return ids


def qc_items(study: Study) -> list[QcItem]:
    """All QC items in id order (none when the study has no QC tables)."""
    if not has_table(study, "qc_items"):
        return []
    rows = study._rows("SELECT id, kind, face, accept, nat_min, nat_max, note FROM qc_items "
                       "ORDER BY id")
    try:
        return [QcItem(i, k, f, tuple(json.loads(a)), lo, hi, n)
                for i, k, f, a, lo, hi, n in rows]
    except (ValueError, TypeError) as e:
        raise StudyError(f"{study.path}: corrupt QC items ({e})") from None


def qc_image(study: Study, item: int) -> tuple[bytes, str]:
    """The stored image of a QC item and its MIME type."""
    rows = study._rows("SELECT image, mime FROM qc_items WHERE id=?", (item,))
    if not rows:
        raise StudyError(f"no QC item {item} in study {study.name!r}")
    return bytes(rows[0][0]), str(rows[0][1])


# ---------------------------------------------------------------- building items
def trap_image(base: bytes, label: str, score: int, width: int = 480) -> bytes:
    """A trapping stimulus: ``base`` (an encoded image) scaled to ``width``, darkened, with the
    printed instruction to choose ``label`` and naturalness ``score``; PNG bytes."""
    import cv2

    from editor.study.stimuli import encode_png

    img = cv2.imdecode(np.frombuffer(base, np.uint8), cv2.IMREAD_COLOR)
    if img is None:
        raise StudyError("cannot decode the image a trapping trial is built from")
    h = max(int(round(img.shape[0] * width / img.shape[1])), width * 3 // 4)
    img = cv2.resize(img, (width, h), interpolation=cv2.INTER_AREA if img.shape[1] > width
                     else cv2.INTER_NEAREST)
    img = (img.astype(np.float32) * 0.35).astype(np.uint8)
    lines = ["Attention check:", "please choose the emotion", f"'{label}'",
             f"and naturalness {score}", f"({NATURALNESS[score]})"]
    font, thick = cv2.FONT_HERSHEY_SIMPLEX, 2
    scale = min(1.0, 0.9 * width / max(cv2.getTextSize(t, font, 1.0, thick)[0][0]
                                       for t in lines))
    line_h = int(40 * scale) + 10
    y = (h - line_h * len(lines)) // 2 + line_h
    for text in lines:
        (tw, _), _ = cv2.getTextSize(text, font, scale, thick)
        cv2.putText(img, text, ((width - tw) // 2, y), font, scale, (255, 255, 255), thick,
                    cv2.LINE_AA)
        y += line_h
    return encode_png(np.ascontiguousarray(img[..., ::-1]))


def trap_specs(study: Study, n: int = 2, seed: int = 0) -> list[QcItemSpec]:
    """``n`` trapping items built from the study's own stimulus images: item k asks for a
    label and a naturalness score drawn from ``seed``."""
    stimuli = study.stimuli()
    rng = np.random.default_rng(seed)
    choices = (*study.labels, CANNOT_TELL)
    out = []
    for _ in range(n):
        stim = stimuli[int(rng.integers(len(stimuli)))]
        label, score = choices[int(rng.integers(len(choices)))], int(rng.integers(1, 6))
        out.append(QcItemSpec("trap", stim.face, (label,), score, score,
                              f"asks for {label!r} and {score}",
                              trap_image(study.image_bytes(stim.id), label, score)))
    return out


def render_qc(faces: Sequence[str | Path], labels: Sequence[str], crop: bool = True,
              n_training: int = 3) -> list[QcItemSpec]:
    """Gold items from face photos (per face: the unchanged photo, neutralised if it shows an
    expression, and one label's preset at 150 %) and ``n_training`` training items (the bundled
    sample face, presets at 100 %).

    Only labels that name a preset are rendered; :class:`StudyError` if none does.
    """
    from editor.engine.face import Face
    from editor.errors import PresetError
    from editor.formats.presets import apply_preset, get_preset
    from editor.resources import SAMPLE_FACE
    from editor.study.stimuli import encode_png, face_crop

    presets = []
    for lab in labels:
        try:
            presets.append((lab, get_preset(lab)))
        except PresetError:
            continue
    if not presets:
        raise StudyError(f"gold and training trials are rendered from presets, and none of the "
                         f"labels {list(labels)} names one")
    neutral = tuple(x for x in labels if x.lower() == "neutral") + (CANNOT_TELL,)
    out = []

    def cut(face: Face, img: np.ndarray) -> bytes:
        x0, y0, x1, y1 = face_crop(face) if crop else (0, 0, img.shape[1], img.shape[0])
        return encode_png(np.ascontiguousarray(img[y0:y1, x0:x1]))

    for i, path in enumerate(faces):
        face, name = Face.from_image(path), Path(path).stem
        if face.has_expression:  # a smiling photo is no neutral gold: its neutralised face
            photo = face.render({})
            note = f"the photo neutralised (it shows: {face.expression_words})"
        else:
            photo, note = np.asarray(face.image), "the unchanged photo"
        out.append(QcItemSpec("gold", name, neutral, 3, 5, note, cut(face, photo)))
        lab, preset = presets[i % len(presets)]
        out.append(QcItemSpec("gold", name, (lab,), 1, 5, f"{lab} at 150 %",
                              cut(face, face.render(apply_preset(preset, 1.5)))))
    if n_training > 0:
        sample = Face.from_image(SAMPLE_FACE)
        for k in range(n_training):
            lab, preset = presets[k % len(presets)]
            out.append(QcItemSpec("training", "sample", (lab,), 1, 5, f"sample face, {lab}",
                                  cut(sample, sample.render(apply_preset(preset, 1.0)))))
    return out


# ---------------------------------------------------------------- screening
@dataclass(frozen=True)
class RaterQc:
    """One rater's QC outcome; ``reasons`` is empty unless ``excluded``."""

    rater: str
    training: int
    training_wrong: int
    gold: int
    gold_passed: int
    traps: int
    traps_failed: int
    excluded: bool
    reasons: str


def judge(rater: str, kinds_passed: Sequence[tuple[str, bool]]) -> RaterQc:
    """Apply :data:`QC_RULE` to one rater's answered QC trials ((kind, passed) pairs)."""
    def count(kind: str, passed: bool | None = None) -> int:
        return sum(1 for k, p in kinds_passed if k == kind and (passed is None or p == passed))

    tr, tr_wrong = count("training"), count("training", False)
    gold, gold_ok = count("gold"), count("gold", True)
    traps, traps_bad = count("trap"), count("trap", False)
    why = []
    if traps_bad:
        why.append(f"failed {traps_bad} of {traps} trapping trials")
    if gold and 3 * gold_ok < 2 * gold:
        why.append(f"passed {gold_ok} of {gold} gold trials")
    if tr and 3 * tr_wrong > tr:
        why.append(f"{tr_wrong} of {tr} training labels wrong")
    return RaterQc(rater, tr, tr_wrong, gold, gold_ok, traps, traps_bad, bool(why),
                   "; ".join(why))


def rater_qc(study: Study) -> list[RaterQc]:
    """The QC outcome of every rater who answered at least one QC trial (start order)."""
    if not has_table(study, "qc_answers"):
        return []
    rows = study._rows("SELECT q.rater, i.kind, q.passed FROM qc_answers q JOIN qc_items i "
                       "ON i.id = q.item LEFT JOIN raters r ON r.id = q.rater "
                       "ORDER BY r.rowid, q.rowid")
    by_rater: dict[str, list[tuple[str, bool]]] = {}
    for rater, kind, passed in rows:
        by_rater.setdefault(rater, []).append((kind, bool(passed)))
    return [judge(r, v) for r, v in by_rater.items()]


def excluded_raters(study: Study) -> set[str]:
    """Raters excluded from MOS by :data:`QC_RULE`."""
    return {r.rater for r in rater_qc(study) if r.excluded}


def mos_answers(study: Study) -> list[AnswerRecord]:
    """The study's answers without those of raters excluded by :data:`QC_RULE`."""
    out = excluded_raters(study)
    return [a for a in study.answers() if a.rater not in out]


def qc_summary(results: Sequence[RaterQc]) -> str:
    """One line for a results view: how many raters QC judged and who was excluded why."""
    if not results:
        return "Quality control: no rater has answered QC trials."
    bad = [r for r in results if r.excluded]
    return (f"Quality control (P.808-style): {len(results)} raters with QC trials, "
            f"{len(bad)} excluded from MOS"
            + (": " + "; ".join(f"{r.rater} ({r.reasons})" for r in bad) if bad else "") + ".")


def format_qc(items: Sequence[QcItem], results: Sequence[RaterQc]) -> str:
    """The QC section of ``study report``: the items, the rule and one row per rater."""
    n = {k: sum(1 for i in items if i.kind == k) for k in KINDS}
    out = ["Quality control (ITU-T P.808-style)",
           f"QC items: {n['training']} training, {n['gold']} gold, {n['trap']} trapping",
           f"Rule: {QC_RULE}."]
    if not results:
        return "\n".join([*out, "No rater has answered QC trials."]) + "\n"
    rows = [[r.rater, f"{r.training - r.training_wrong}/{r.training}",
             f"{r.gold_passed}/{r.gold}", f"{r.traps - r.traps_failed}/{r.traps}",
             f"EXCLUDED: {r.reasons}" if r.excluded else "kept"] for r in results]
    header = ["rater", "training ok", "gold ok", "traps ok", "MOS"]
    widths = [max(len(x) for x in col) for col in zip(header, *rows, strict=True)]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip()
             for r in [header, *rows]]
    return "\n".join([*out, lines[0], "-" * len(lines[0]), *lines[1:]]) + "\n"
