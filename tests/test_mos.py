"""MOS study storage (editor.study.mos), builders and export (editor.study.stimuli) and the
``study`` CLI (editor.cli.study)."""

from __future__ import annotations

import argparse
import csv
import os
import sqlite3
import subprocess
import sys
import textwrap
from pathlib import Path

import cv2
import numpy as np
import pytest

from editor.cli.study import add_study_parser
from editor.errors import ImageError, StudyError
from editor.study.mos import APPLICATION_ID, CANNOT_TELL, SCHEMA_VERSION, StimulusSpec, Study
from editor.study.stimuli import (
    EXPORT_COLUMNS,
    create_from_renders,
    encode_png,
    export_answers_csv,
    from_folder,
)

REPO = Path(__file__).resolve().parents[1]
LABELS = ["joy", "sadness", "fear"]


def _image(i: int) -> np.ndarray:
    rng = np.random.default_rng(i)
    return rng.integers(0, 256, (6 + i, 5, 3), dtype=np.uint8)


def _renders() -> list[tuple[str, str, float, np.ndarray]]:
    return [(face, label, 1.0, _image(3 * f + e)) for f, face in enumerate(["Ann", "Bob"])
            for e, label in enumerate(LABELS)]


@pytest.fixture()
def study_path(tmp_path: Path) -> Path:
    path = tmp_path / "study.db"
    create_from_renders(path, "pilot", LABELS, _renders()).close()
    return path


def _answer_n(session, n: int, label: str | None = None, nat: int = 4) -> list[int]:
    done = []
    for _ in range(n):
        stim = session.next_stimulus()
        session.answer(stim, label or stim.label, nat, 1500.0)
        done.append(stim.id)
    return done


def _n_answers(path: Path) -> int:
    with Study.open(path) as study:
        return len(study.answers())


def test_create_open_roundtrip_and_pragmas(study_path: Path) -> None:
    with Study.open(study_path) as study:
        assert (study.name, study.labels, study.allow_revise, study.break_every) == (
            "pilot", tuple(LABELS), False, 0)
        stimuli = study.stimuli()
        assert [(s.id, s.face, s.label) for s in stimuli] == [
            (i + 1, f, lab) for i, (f, lab, _, _) in enumerate(_renders())]
        for s, (_, _, _, img) in zip(stimuli, _renders(), strict=True):
            data = study.image_bytes(s.id)
            decoded = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
            np.testing.assert_array_equal(decoded[..., ::-1], img)  # lossless PNG, RGB order
        assert study._con.execute("PRAGMA synchronous").fetchone()[0] == 2  # FULL
        with pytest.raises(StudyError, match="no stimulus 99"):
            study.image_bytes(99)
    con = sqlite3.connect(study_path)
    assert con.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    assert con.execute("PRAGMA application_id").fetchone()[0] == APPLICATION_ID
    assert con.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION
    con.close()


def test_seeded_order_is_recorded_and_reproducible(study_path: Path) -> None:
    with Study.open(study_path) as study:
        a, b = study.start_session("r1", seed=7), study.start_session("r2", seed=7)
        c = study.start_session("r3")
        assert a.order == b.order and sorted(a.order) == [1, 2, 3, 4, 5, 6]
        assert sorted(c.order) == [1, 2, 3, 4, 5, 6]
        assert study.start_session("r3").seed == c.seed  # a fresh seed is stored
        orders = {study.start_session(f"r{i}", seed=i).order for i in range(10, 20)}
        assert len(orders) > 1
        assert study.raters() == ["r1", "r2", "r3", *(f"r{i}" for i in range(10, 20))]
        with pytest.raises(StudyError, match="already started with seed 7"):
            study.start_session("r1", seed=8)
        with pytest.raises(StudyError, match="must not be empty"):
            study.start_session("  ")


def test_resume_continues_same_order(study_path: Path) -> None:
    with Study.open(study_path) as study:
        session = study.start_session("ann", seed=123)
        order = session.order
        assert _answer_n(session, 3) == list(order[:3])
    with Study.open(study_path) as study:
        session = study.start_session("ann")
        assert session.order == order and session.seed == 123
        assert session.progress == (3, 6)
        assert session.next_stimulus().id == order[3]
        assert _answer_n(session, 3) == list(order[3:])
        assert session.next_stimulus() is None and session.progress == (6, 6)
        answers = study.answers("ann")
        assert [a.stimulus_id for a in answers] == list(order)
        assert [a.position for a in answers] == [1, 2, 3, 4, 5, 6]
        assert all(a.correct and a.naturalness == 4 and a.response_ms == 1500.0 for a in answers)


# killed at a quiet moment, or inside the (k+1)-th answer's transaction: its statements ran,
# SIGKILL arrives just before COMMIT (that answer must vanish, the k before it must stay)
_KILL_IN_TX = """
class _KillAtCommit:
    def __init__(self, con):
        self._con = con
    def execute(self, sql, *a):
        if sql == "COMMIT":
            os.kill(os.getpid(), signal.SIGKILL)
        return self._con.execute(sql, *a)
    def __getattr__(self, name):
        return getattr(self._con, name)
study._con = _KillAtCommit(study._con)
stim = session.next_stimulus()
session.answer(stim, "joy", 5, 900)
os._exit(0)
"""


@pytest.mark.parametrize("how", ["os._exit(1)", "os.kill(os.getpid(), signal.SIGKILL)",
                                 _KILL_IN_TX])
def test_killed_session_keeps_exactly_k_answers(study_path: Path, how: str) -> None:
    k = 4
    script = textwrap.dedent(f"""
        import os, signal, sys
        from editor.study.mos import Study
        study = Study.open(sys.argv[1])
        session = study.start_session("victim", seed=99)
        for _ in range({k}):
            stim = session.next_stimulus()
            session.answer(stim, "{CANNOT_TELL}", 3, 800)
    """) + textwrap.dedent(how)
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.run([sys.executable, "-c", script, str(study_path)], env=env,
                          capture_output=True, timeout=60)
    assert proc.returncode != 0, proc.stderr.decode()
    assert proc.stderr == b""
    with Study.open(study_path) as study:
        answers = study.answers("victim")
        session = study.start_session("victim")
        assert len(answers) == k
        assert [a.stimulus_id for a in answers] == list(session.order[:k])
        assert all(a.label == CANNOT_TELL and not a.correct for a in answers)
        assert session.progress == (k, 6)
        assert session.next_stimulus().id == session.order[k]


def test_answer_validation_commits_nothing_bad(study_path: Path, tmp_path: Path) -> None:
    other_path = tmp_path / "other.db"
    with Study.open(study_path) as study, create_from_renders(
            other_path, "other", LABELS, _renders()) as other:
        session = study.start_session("r", seed=1)
        stim = session.next_stimulus()
        for label, nat, ms, match in [
                ("anger", 3, 10, "label 'anger'"), ("Joy", 3, 10, "label 'Joy'"),
                (stim.label, 0, 10, "naturalness"), (stim.label, 6, 10, "naturalness"),
                (stim.label, 3.5, 10, "naturalness"), (stim.label, True, 10, "naturalness"),
                (stim.label, "3", 10, "naturalness"), (stim.label, 3, -1, "response time"),
                (stim.label, 3, float("nan"), "response time")]:
            with pytest.raises(StudyError, match=match):
                session.answer(stim, label, nat, ms)
        not_next = next(s for s in study.stimuli() if s.id != stim.id)
        with pytest.raises(StudyError, match="not the next one"):
            session.answer(not_next, not_next.label, 3, 10)
        with pytest.raises(StudyError, match="not part of study"):
            session.answer(999, "joy", 3, 10)
        foreign = other.start_session("r", seed=1).next_stimulus()
        assert foreign.id == stim.id  # same id, other study: must still be refused
        with pytest.raises(StudyError, match="belongs to another study"):
            session.answer(foreign, foreign.label, 3, 10)
        assert study.answers() == []
        session.answer(stim.id, CANNOT_TELL, np.int64(5), 0)
        with pytest.raises(StudyError, match="already answered.*does not allow"):
            session.answer(stim, stim.label, 3, 10)
        with pytest.raises(StudyError, match="does not allow changing"):
            session.revise(stim, stim.label, 3, 10)
        assert [(a.label, a.naturalness) for a in study.answers()] == [(CANNOT_TELL, 5)]


def test_revise_when_allowed_keeps_history(tmp_path: Path) -> None:
    specs = [StimulusSpec(f, lab, encode_png(img), k) for f, lab, k, img in _renders()]
    with Study.create(tmp_path / "r.db", "rev", LABELS, specs, allow_revise=True,
                      break_every=2) as study:
        session = study.start_session("r", seed=5)
        first, second = _answer_n(session, 1, nat=2)[0], session.order[1]
        with pytest.raises(StudyError, match="has not answered"):
            session.revise(second, "joy", 3, 10)
        assert not session.break_due
        session.revise(first, CANNOT_TELL, 5, 2000)
        (a,) = study.answers()
        assert (a.stimulus_id, a.label, a.naturalness, a.revisions) == (first, CANNOT_TELL, 5, 1)
        hist = study._con.execute("SELECT stimulus, naturalness FROM answer_history").fetchall()
        assert hist == [(first, 2)]
        _answer_n(session, 1)
        assert session.break_due  # after every 2nd answer ...
        _answer_n(session, 3)
        assert not session.break_due  # ... but not after the 5th
        _answer_n(session, 1)
        assert session.progress == (6, 6) and not session.break_due  # nor at the very end


def _foreign_sqlite(path: Path) -> None:
    con = sqlite3.connect(path)
    con.execute("CREATE TABLE meta (key TEXT, value TEXT)")
    con.execute("INSERT INTO meta VALUES ('magic', 'something else')")
    con.commit()
    con.close()


def _ours_without_meta(path: Path) -> None:
    con = sqlite3.connect(path)
    con.execute(f"PRAGMA application_id={APPLICATION_ID}")
    con.execute(f"PRAGMA user_version={SCHEMA_VERSION}")
    con.execute("CREATE TABLE other (x)")
    con.close()


def _newer_version(path: Path) -> None:
    create_from_renders(path, "x", LABELS, _renders()).close()
    con = sqlite3.connect(path)
    con.execute("PRAGMA user_version=99")
    con.close()


def _truncated(path: Path) -> None:
    create_from_renders(path, "x", LABELS, _renders() * 40).close()
    with path.open("r+b") as f:
        f.truncate(path.stat().st_size // 2)


@pytest.mark.parametrize("make, match", [
    (lambda p: p.write_bytes(np.random.default_rng(0).bytes(5000)), "not an SQLite database"),
    (lambda p: p.write_bytes(b""), "empty file"),
    (_foreign_sqlite, "not a FAP Studio study"),
    (_newer_version, "schema version 99 is not supported"),
    (_ours_without_meta, "corrupt or unreadable.*no such table: meta"),
    (_truncated, "corrupt"),
    (lambda p: p.mkdir(), "cannot read"),
    (lambda p: None, "cannot read"),
])
def test_open_rejects_non_studies(tmp_path: Path, make, match: str) -> None:
    path = tmp_path / "bad.db"
    make(path)
    before = path.read_bytes() if path.is_file() else None
    with pytest.raises(StudyError, match=match) as info:
        Study.open(path)
    assert "\n" not in str(info.value)
    if before is not None:
        assert path.read_bytes() == before  # never modified
    assert not Path(f"{path}-wal").exists()


def test_create_rejects_bad_designs(tmp_path: Path, study_path: Path) -> None:
    png = encode_png(_image(0))
    ok = [StimulusSpec("Ann", "joy", png)]
    for labels, stimuli, match in [
            (["joy", "joy"], ok, "unique"), (["joy", CANNOT_TELL], ok, "unique"),
            (["joy"], [], "at least one"), (["fear"], ok, "label 'joy' is not one of")]:
        with pytest.raises(StudyError, match=match):
            Study.create(tmp_path / "x.db", "x", labels, stimuli)
    with pytest.raises(ImageError, match="not a PNG"):
        Study.create(tmp_path / "x.db", "x", ["joy"], [StimulusSpec("Ann", "joy", b"hello")])
    with pytest.raises(StudyError, match="already exists"):
        Study.create(study_path, "x", ["joy"], ok)
    with pytest.raises(ImageError, match="H x W x 3 uint8"):
        create_from_renders(tmp_path / "x.db", "x", ["joy"],
                            [("Ann", "joy", 1.0, np.zeros((4, 4), np.uint8))])
    assert not (tmp_path / "x.db").exists()


def _folder(tmp_path: Path, rows: str) -> tuple[Path, Path]:
    folder = tmp_path / "imgs"
    folder.mkdir(exist_ok=True)
    for i in range(3):
        (folder / f"img{i}.png").write_bytes(encode_png(_image(i)))
    ok, jpg = cv2.imencode(".jpg", _image(5))
    (folder / "photo.jpg").write_bytes(jpg.tobytes())
    (folder / "notes.txt").write_text("not an image")
    csv_path = tmp_path / "labels.csv"
    csv_path.write_text(rows)
    return folder, csv_path


def test_from_folder(tmp_path: Path) -> None:
    folder, csv_path = _folder(tmp_path, "File,Label,face,intensity\nimg0.png,joy,Ann,0.5\n"
                               "img1.png,fear,,\nphoto.jpg,joy,Bob,1\n")
    with from_folder(tmp_path / "f.db", folder, csv_path) as study:
        assert study.name == "f" and study.labels == ("joy", "fear")
        assert [(s.face, s.label, s.intensity, s.source) for s in study.stimuli()] == [
            ("Ann", "joy", 0.5, "img0.png"), ("img1", "fear", 1.0, "img1.png"),
            ("Bob", "joy", 1.0, "photo.jpg")]
        assert study.image_bytes(3) == (folder / "photo.jpg").read_bytes()


@pytest.mark.parametrize("rows, error, match", [
    ("", StudyError, "header must name"),
    ("file,emotion\nimg0.png,joy\n", StudyError, "header must name"),
    ("file,label\n", StudyError, "no stimuli"),
    ("file,label\nimg0.png,joy\nmissing.png,joy\n", ImageError, "missing.png: cannot read"),
    ("file,label\nimg0.png,joy\nimg0.png,fear\n", StudyError, r"labels.csv:3: img0.png is listed"),
    ("file,label\nimg0.png,\n", StudyError, "must not be empty"),
    ("file,label,intensity\nimg0.png,joy,strong\n", StudyError, "bad intensity"),
    ("file,label\nnotes.txt,joy\n", ImageError, "notes.txt: not a PNG"),
])
def test_from_folder_errors(tmp_path: Path, rows: str, error: type, match: str) -> None:
    folder, csv_path = _folder(tmp_path, rows)
    with pytest.raises(error, match=match):
        from_folder(tmp_path / "f.db", folder, csv_path)
    assert not (tmp_path / "f.db").exists()


def test_from_folder_missing_inputs_and_label_list(tmp_path: Path) -> None:
    folder, csv_path = _folder(tmp_path, "file,label\nimg0.png,joy\n")
    with pytest.raises(StudyError, match="image folder not found"):
        from_folder(tmp_path / "f.db", tmp_path / "nope", csv_path)
    with pytest.raises(StudyError, match="cannot read labels CSV"):
        from_folder(tmp_path / "f.db", folder, tmp_path / "nope.csv")
    with pytest.raises(StudyError, match="label 'joy' is not one of"):
        from_folder(tmp_path / "f.db", folder, csv_path, labels=["anger"])
    with from_folder(tmp_path / "f.db", folder, csv_path, labels=["fear", "joy"]) as study:
        assert study.labels == ("fear", "joy")


def test_export_csv_round_trip(study_path: Path, tmp_path: Path) -> None:
    with Study.open(study_path) as study:
        _answer_n(study.start_session("a", seed=1), 6)
        _answer_n(study.start_session("b", seed=2), 2, label=CANNOT_TELL, nat=1)
        out = tmp_path / "answers.csv"
        assert export_answers_csv(study, out) == 8
        records = study.answers()
    with out.open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(records) == 8
    assert tuple(rows[0]) == EXPORT_COLUMNS
    assert [(r["rater"], int(r["stimulus_id"]), int(r["order_position"])) for r in rows] == [
        (a.rater, a.stimulus_id, a.position) for a in records]
    assert [r["correct"] for r in rows] == ["1"] * 6 + ["0"] * 2
    assert {r["study"] for r in rows} == {"pilot"}
    assert rows[7]["chosen_label"] == CANNOT_TELL and rows[7]["naturalness"] == "1"


def _cli(*argv: str) -> int:
    parser = argparse.ArgumentParser(prog="fap-studio")
    add_study_parser(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    return args.func(args)


def test_cli_create_report_export(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder, csv_path = _folder(tmp_path, "file,label,face\nimg0.png,joy,Ann\n"
                               "img1.png,fear,Ann\nimg2.png,joy,Bob\nphoto.jpg,fear,Bob\n")
    db = tmp_path / "cli.db"
    assert _cli("study", "create", str(db), "--folder", str(folder), "--labels-csv",
                str(csv_path), "--name", "cli test", "--labels", "joy,fear") == 0
    assert "4 stimuli" in capsys.readouterr().out
    with Study.open(db) as study:
        for rater, seed in [("a", 1), ("b", 2), ("c", 3)]:
            _answer_n(study.start_session(rater, seed=seed), 4)
    assert _cli("study", "report", str(db)) == 0
    out = capsys.readouterr().out
    assert "Study 'cli test': 4 stimuli, 3 raters, 12 answers" in out
    assert "Table 5" in out and "Table 6" in out and "Fleiss' kappa" in out
    assert next(x for x in out.splitlines() if x.startswith("Ann")).split()[1:] == [
        "100/4", "100/4"]
    assert _cli("study", "export", str(db), "-o", str(tmp_path / "a.csv")) == 0
    assert "wrote 12 answers" in capsys.readouterr().out
    assert len((tmp_path / "a.csv").read_text().splitlines()) == 13


def test_cli_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.db"
    bad.write_bytes(b"\x00" * 100)
    for argv in (["report", str(bad)], ["export", str(bad), "-o", str(tmp_path / "o.csv")],
                 ["create", str(bad), "--folder", str(tmp_path), "--labels-csv", "x.csv"]):
        assert _cli("study", *argv) == 2
        err = capsys.readouterr().err
        assert err.startswith("fap-studio: error: ") and err.count("\n") == 1, err
    assert not (tmp_path / "o.csv").exists()
