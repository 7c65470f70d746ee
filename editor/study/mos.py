"""Storage of a MOS rating study: one self-contained SQLite file per study (no Qt).

A study holds its stimuli (the image bytes themselves, so it is reproducible), its raters with
their seeded presentation orders, and their answers. WAL mode, ``synchronous=FULL``; each answer
is committed in its own transaction, so killing the process loses nothing already answered.
Identity: ``PRAGMA application_id`` = :data:`APPLICATION_ID`, ``PRAGMA user_version`` = schema
version, and :data:`MAGIC` + a random study uid in ``meta``. Any other file (empty, random bytes,
foreign SQLite, other schema version) raises :class:`StudyError` and is never modified.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import secrets
import sqlite3
import uuid
from collections.abc import Iterator, Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from editor.errors import ImageError, StudyError
from editor.study.design import PAPER_EXPRESSIONS  # noqa: F401 (re-export)

CANNOT_TELL = "cannot tell"

#: The paper's naturalness wording (SPEC §4, ITU-T P.800 ACR style), shared by the rating
#: window and the web page.
NATURALNESS = {1: "very unnatural", 2: "rather unnatural", 3: "acceptable",
               4: "rather natural", 5: "very realistic"}
APPLICATION_ID = 0x46415053  # "FAPS"
MAGIC = "fap-studio/mos-study"
SCHEMA_VERSION = 1
_SQLITE_HEADER = b"SQLite format 3\x00"
_IMAGE_SIGNATURES = {b"\x89PNG\r\n\x1a\n": "image/png", b"\xff\xd8\xff": "image/jpeg",
                     b"BM": "image/bmp"}
_SCHEMA = """
CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE stimuli (id INTEGER PRIMARY KEY, face TEXT NOT NULL, label TEXT NOT NULL,
    intensity REAL NOT NULL, source TEXT NOT NULL, mime TEXT NOT NULL, sha256 TEXT NOT NULL,
    image BLOB NOT NULL);
CREATE TABLE raters (id TEXT PRIMARY KEY, seed INTEGER NOT NULL, started_at TEXT NOT NULL);
CREATE TABLE rater_order (rater TEXT NOT NULL REFERENCES raters(id),
    position INTEGER NOT NULL, stimulus INTEGER NOT NULL REFERENCES stimuli(id),
    PRIMARY KEY (rater, position), UNIQUE (rater, stimulus));
CREATE TABLE answers (rater TEXT NOT NULL, stimulus INTEGER NOT NULL, label TEXT NOT NULL,
    naturalness INTEGER NOT NULL CHECK (naturalness BETWEEN 1 AND 5),
    response_ms REAL NOT NULL CHECK (response_ms >= 0), answered_at TEXT NOT NULL,
    revisions INTEGER NOT NULL DEFAULT 0, PRIMARY KEY (rater, stimulus),
    FOREIGN KEY (rater, stimulus) REFERENCES rater_order (rater, stimulus));
CREATE TABLE answer_history (rater TEXT NOT NULL, stimulus INTEGER NOT NULL,
    label TEXT NOT NULL, naturalness INTEGER NOT NULL, response_ms REAL NOT NULL,
    answered_at TEXT NOT NULL, replaced_at TEXT NOT NULL);
"""


@dataclass(frozen=True)
class StimulusSpec:
    """A stimulus to put into a new study: encoded image bytes (PNG, JPEG or BMP) + truth."""

    face: str
    label: str
    image: bytes
    intensity: float = 1.0
    source: str = ""


@dataclass(frozen=True)
class Stimulus:
    """A stored stimulus; ``study_uid`` ties it to its study (ids are only unique per study)."""

    id: int
    face: str
    label: str
    intensity: float
    source: str
    study_uid: str


@dataclass(frozen=True)
class AnswerRecord:
    """One committed answer, joined with its stimulus; ``position`` is 1-based in the order."""

    study: str
    rater: str
    stimulus_id: int
    face: str
    true_label: str
    intensity: float
    label: str
    naturalness: int
    response_ms: float
    answered_at: str
    position: int
    revisions: int

    @property
    def correct(self) -> bool:
        """True if the chosen label is the intended one ("cannot tell" is never correct)."""
        return self.label == self.true_label


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="milliseconds")


def _is_int(x: object, real: bool = False) -> bool:
    kinds = int | np.integer | float | np.floating if real else int | np.integer
    return isinstance(x, kinds) and not isinstance(x, bool)


def _sniff(data: bytes, what: str) -> str:
    for signature, mime in _IMAGE_SIGNATURES.items():
        if data.startswith(signature):
            return mime
    raise ImageError(f"{what}: not a PNG, JPEG or BMP image")


class Study:
    """An open study database: :meth:`create` or :meth:`open` it, :meth:`close` it (or ``with``)."""

    def __init__(self, con: sqlite3.Connection, path: Path) -> None:
        self._con, self.path = con, path
        meta = dict(con.execute("SELECT key, value FROM meta").fetchall())
        if meta.get("magic") != MAGIC:
            raise StudyError(f"{path}: not a FAP Studio study (bad magic in meta table)")
        try:
            self.uid: str = meta["uid"]
            self.name: str = meta["name"]
            self.labels: tuple[str, ...] = tuple(json.loads(meta["labels"]))
            self.allow_revise: bool = meta["allow_revise"] == "1"
            self.break_every: int = int(meta["break_every"])
            self.created: str = meta["created"]
        except (KeyError, ValueError, TypeError, RecursionError) as e:
            raise StudyError(f"{path}: corrupt study metadata ({str(e)[:80]})") from None
        if (not all(isinstance(v, str) for v in (self.uid, self.name, self.created))
                or not self.labels or not all(isinstance(x, str) and x for x in self.labels)
                or len(set(self.labels)) != len(self.labels) or self.break_every < 0):
            raise StudyError(f"{path}: corrupt study metadata (labels must be distinct "
                             "non-empty strings; name, uid and created text; break_every >= 0)")

    @staticmethod
    def _check_schema(con: sqlite3.Connection, path: Path) -> None:
        """StudyError unless every table of the schema exists with its columns."""
        ref = sqlite3.connect(":memory:")
        try:
            ref.executescript(_SCHEMA)
            tables = [r[0] for r in ref.execute("SELECT name FROM sqlite_master "
                                                "WHERE type = 'table'")]
            for t in tables:
                want = [r[1:3] for r in ref.execute(f"PRAGMA table_info({t})")]
                got = [r[1:3] for r in con.execute(f"PRAGMA table_info({t})")]
                if not got:
                    raise StudyError(f"{path}: corrupt or unreadable study database (no such "
                                     f"table: {t})")
                if got != want:
                    raise StudyError(f"{path}: corrupt or unreadable study database "
                                     f"(table {t} has other columns)")
        finally:
            ref.close()

    @staticmethod
    def _pragmas(con: sqlite3.Connection) -> None:
        mode = con.execute("PRAGMA journal_mode=WAL").fetchone()[0]
        if str(mode).lower() != "wal":
            raise StudyError(f"cannot switch the study database to WAL mode (got {mode})")
        con.execute("PRAGMA synchronous=FULL")
        con.execute("PRAGMA foreign_keys=ON")

    @classmethod
    def create(cls, path: str | Path, name: str, labels: Sequence[str],
               stimuli: Sequence[StimulusSpec], allow_revise: bool = False,
               break_every: int = 0) -> Study:
        """Create a new study file at ``path`` (which must not exist) and return it open.

        ``labels`` are the emotion labels offered to raters, in display order; "cannot tell" is
        always added. Every stimulus label must be one of ``labels``. ``break_every`` > 0 asks
        the rating UI for a pause after every that many answers (see ``RaterSession.break_due``).
        """
        path = Path(path)
        labels = [str(x).strip() for x in labels]
        if not str(name).strip():
            raise StudyError("a study needs a non-empty name")
        if not labels or "" in labels or len(set(labels)) != len(labels) or CANNOT_TELL in labels:
            raise StudyError(f"labels must be unique, non-empty, without {CANNOT_TELL!r}: {labels}")
        if not stimuli:
            raise StudyError("a study needs at least one stimulus")
        if not _is_int(break_every) or break_every < 0:
            raise StudyError(f"break_every must be an integer >= 0, got {break_every!r}")
        rows = []
        for i, s in enumerate(stimuli):
            if s.label not in labels:
                raise StudyError(f"stimulus {i + 1} ({s.source or s.face}): label {s.label!r} "
                                 f"is not one of {labels}")
            if not s.face.strip() or not math.isfinite(float(s.intensity)):
                raise StudyError(f"stimulus {i + 1}: needs a face name and a finite intensity")
            mime = _sniff(bytes(s.image), s.source or f"stimulus {i + 1}")
            rows.append((i + 1, s.face, s.label, float(s.intensity), s.source, mime,
                         hashlib.sha256(s.image).hexdigest(), sqlite3.Binary(bytes(s.image))))
        if path.exists():
            raise StudyError(f"{path}: already exists; a study file holds exactly one study")
        meta = {"magic": MAGIC, "uid": uuid.uuid4().hex, "name": str(name).strip(),
                "labels": json.dumps(labels), "allow_revise": "1" if allow_revise else "0",
                "break_every": str(break_every), "created": _now()}
        con = None
        tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.part")
        try:
            con = sqlite3.connect(str(tmp), isolation_level=None, timeout=10.0)
            con.execute(f"PRAGMA application_id={APPLICATION_ID}")
            cls._pragmas(con)
            con.execute("BEGIN IMMEDIATE")
            for statement in _SCHEMA.split(";"):
                if statement.strip():
                    con.execute(statement)
            con.executemany("INSERT INTO meta VALUES (?, ?)", meta.items())
            con.executemany("INSERT INTO stimuli VALUES (?, ?, ?, ?, ?, ?, ?, ?)", rows)
            con.execute(f"PRAGMA user_version={SCHEMA_VERSION}")
            con.execute("COMMIT")
            con.close()  # the last connection: SQLite folds the WAL into the file
            con = None
            os.link(tmp, path)  # complete study appears at once, never over an existing file
            tmp.unlink()
        except BaseException as e:  # also Ctrl-C and a full disk: no partial study remains
            if con is not None:
                con.close()
            for leftover in (tmp, Path(f"{tmp}-wal"), Path(f"{tmp}-shm")):
                with suppress(OSError):
                    leftover.unlink()
            if isinstance(e, FileExistsError):
                raise StudyError(f"{path}: already exists; a study file holds exactly one "
                                 "study") from None
            if isinstance(e, (sqlite3.Error, OSError)):
                why = e.strerror if isinstance(e, OSError) and e.strerror else e
                raise StudyError(f"{path}: cannot create study ({why})") from None
            raise
        return cls.open(path)

    @classmethod
    def open(cls, path: str | Path) -> Study:
        """Open an existing study; anything that is not one raises :class:`StudyError`."""
        path = Path(path)
        if path.exists() and not path.is_file():
            raise StudyError(f"{path}: cannot read study file (not a regular file)")
        try:
            with path.open("rb") as f:
                head = f.read(len(_SQLITE_HEADER))
        except OSError as e:
            raise StudyError(f"{path}: cannot read study file ({e.strerror or e})") from e
        if not head:
            raise StudyError(f"{path}: empty file, not a FAP Studio study")
        if head != _SQLITE_HEADER:
            raise StudyError(f"{path}: not an SQLite database, so not a FAP Studio study")
        con = sqlite3.connect(path.resolve().as_uri() + "?mode=rw", uri=True,
                              isolation_level=None, timeout=10.0)
        try:
            if con.execute("PRAGMA application_id").fetchone()[0] != APPLICATION_ID:
                raise StudyError(f"{path}: an SQLite database but not a FAP Studio study")
            version = con.execute("PRAGMA user_version").fetchone()[0]
            if version != SCHEMA_VERSION:
                raise StudyError(f"{path}: study schema version {version} is not supported "
                                 f"(this FAP Studio reads version {SCHEMA_VERSION})")
            check = con.execute("PRAGMA quick_check").fetchone()[0]
            if check != "ok":
                raise StudyError(f"{path}: study database is corrupt ({check})")
            cls._check_schema(con, path)
            study = cls(con, path)  # reads and checks meta before anything is written
            cls._pragmas(con)
            return study
        except (sqlite3.Error, UnicodeDecodeError) as e:
            con.close()
            raise StudyError(f"{path}: corrupt or unreadable study database "
                             f"({str(e)[:80]})") from None
        except StudyError:
            con.close()
            raise

    def close(self) -> None:
        """Close the database (all answers are already committed)."""
        self._con.close()

    def __enter__(self) -> Study:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @contextmanager
    def _tx(self) -> Iterator[sqlite3.Connection]:
        """One write transaction; sqlite errors become :class:`StudyError`."""
        try:
            self._con.execute("BEGIN IMMEDIATE")
            try:
                yield self._con
            except BaseException:
                self._con.execute("ROLLBACK")
                raise
            self._con.execute("COMMIT")
        except sqlite3.Error as e:
            raise StudyError(f"{self.path}: database error ({e})") from e

    def _rows(self, sql: str, params: tuple = ()) -> list[tuple]:
        """All rows of a query; a damaged database (sqlite error, text that is not UTF-8)
        raises :class:`StudyError`."""
        try:
            return self._con.execute(sql, params).fetchall()
        except (sqlite3.Error, UnicodeDecodeError) as e:
            raise StudyError(f"{self.path}: corrupt or unreadable study database "
                             f"({type(e).__name__})") from None

    def stimuli(self) -> list[Stimulus]:
        """All stimuli in id order (without image bytes; see :meth:`image_bytes`)."""
        sql = "SELECT id, face, label, intensity, source FROM stimuli ORDER BY id"
        return [Stimulus(i, face, label, intensity, source, study_uid=self.uid)
                for i, face, label, intensity, source in self._rows(sql)]

    def image_bytes(self, stimulus_id: int) -> bytes:
        """The encoded image stored for a stimulus (PNG, JPEG or BMP bytes)."""
        rows = self._rows("SELECT image FROM stimuli WHERE id=?", (stimulus_id,))
        row = rows[0] if rows else None
        if row is None:
            raise StudyError(f"no stimulus {stimulus_id} in study {self.name!r}")
        return bytes(row[0])

    def raters(self) -> list[str]:
        """Ids of raters who have started a session, in start order."""
        return [r for (r,) in self._rows("SELECT id FROM raters ORDER BY rowid")]

    def answers(self, rater: str | None = None) -> list[AnswerRecord]:
        """All committed answers (optionally of one rater), ordered by rater then position."""
        sql = ("SELECT a.rater, a.stimulus, s.face, s.label, s.intensity, a.label, a.naturalness,"
               " a.response_ms, a.answered_at, o.position + 1, a.revisions FROM answers a"
               " JOIN stimuli s ON s.id = a.stimulus JOIN rater_order o"
               " ON o.rater = a.rater AND o.stimulus = a.stimulus"
               + (" WHERE a.rater = ?" if rater is not None else "")
               + " ORDER BY (SELECT rowid FROM raters WHERE id = a.rater), o.position")
        rows = self._rows(sql, () if rater is None else (rater,))
        return [AnswerRecord(self.name, *row) for row in rows]

    def start_session(self, rater_id: str, seed: int | None = None) -> RaterSession:
        """Start or resume the session of ``rater_id``.

        A new rater gets a random permutation of all stimuli drawn from ``seed`` (a fresh random
        seed when None); seed and order are stored. A returning rater resumes the stored order;
        passing a different ``seed`` then raises :class:`StudyError`.
        """
        rater_id = str(rater_id).strip()
        if not rater_id:
            raise StudyError("a rater id must not be empty")
        with self._tx() as con:
            row = con.execute("SELECT seed FROM raters WHERE id=?", (rater_id,)).fetchone()
            if row is None:
                used = secrets.randbits(63) if seed is None else int(seed)
                if not 0 <= used < 2**63:
                    raise StudyError(f"seed must be in [0, 2**63), got {used}")
                ids = [i for (i,) in con.execute("SELECT id FROM stimuli ORDER BY id")]
                order = np.random.default_rng(used).permutation(ids).tolist()
                con.execute("INSERT INTO raters VALUES (?, ?, ?)", (rater_id, used, _now()))
                con.executemany("INSERT INTO rater_order VALUES (?, ?, ?)",
                                [(rater_id, pos, sid) for pos, sid in enumerate(order)])
            elif seed is not None and int(seed) != row[0]:
                raise StudyError(f"rater {rater_id!r} already started with seed {row[0]}")
            else:
                used = row[0]
            order = [s for (s,) in con.execute(
                "SELECT stimulus FROM rater_order WHERE rater=? ORDER BY position", (rater_id,))]
        return RaterSession(self, rater_id, int(used), tuple(order))


class RaterSession:
    """One rater's pass through the study, in the rater's stored order."""

    def __init__(self, study: Study, rater: str, seed: int, order: tuple[int, ...]) -> None:
        self.study, self.rater, self.seed, self.order = study, rater, seed, order
        self._stimuli = {s.id: s for s in study.stimuli()}

    @property
    def progress(self) -> tuple[int, int]:
        """(answered, total) for this rater."""
        done = self.study._con.execute("SELECT COUNT(*) FROM answers WHERE rater=?",
                                       (self.rater,)).fetchone()[0]
        return int(done), len(self.order)

    @property
    def break_due(self) -> bool:
        """True right after every ``break_every``-th answer (never at the very end)."""
        (done, total), every = self.progress, self.study.break_every
        return every > 0 and 0 < done < total and done % every == 0

    def next_stimulus(self) -> Stimulus | None:
        """The first unanswered stimulus in this rater's order, or None when finished."""
        row = self.study._con.execute(
            "SELECT o.stimulus FROM rater_order o LEFT JOIN answers a ON a.rater = o.rater"
            " AND a.stimulus = o.stimulus WHERE o.rater=? AND a.stimulus IS NULL"
            " ORDER BY o.position LIMIT 1", (self.rater,)).fetchone()
        return None if row is None else self._stimuli[row[0]]

    def _validate(self, stimulus: Stimulus | int, label: str, naturalness: int,
                  response_ms: float) -> int:
        if isinstance(stimulus, Stimulus):
            if stimulus.study_uid != self.study.uid:
                raise StudyError(f"stimulus {stimulus.id} belongs to another study")
            stimulus = stimulus.id
        if not _is_int(stimulus) or int(stimulus) not in self._stimuli:
            raise StudyError(f"stimulus {stimulus!r} is not part of study {self.study.name!r}")
        if label not in self.study.labels and label != CANNOT_TELL:
            raise StudyError(f"label {label!r} is not one of {[*self.study.labels, CANNOT_TELL]}")
        if not _is_int(naturalness) or not 1 <= naturalness <= 5:
            raise StudyError(f"naturalness must be an integer 1..5, got {naturalness!r}")
        if not _is_int(response_ms, real=True) or not math.isfinite(response_ms) or response_ms < 0:
            raise StudyError(f"response time must be a finite number >= 0 ms, got {response_ms!r}")
        return int(stimulus)

    def answer(self, stimulus: Stimulus | int, label: str, naturalness: int,
               response_ms: float) -> None:
        """Commit this rater's answer to ``stimulus``, which must be :meth:`next_stimulus`.

        Raises
        ------
        StudyError
            Unknown or foreign stimulus, not the next one in order, already answered, label not
            among the study labels or "cannot tell", naturalness not an int 1..5, bad time.
        """
        sid = self._validate(stimulus, label, naturalness, response_ms)
        with self.study._tx() as con:
            if con.execute("SELECT 1 FROM answers WHERE rater=? AND stimulus=?",
                           (self.rater, sid)).fetchone():
                raise StudyError(f"rater {self.rater!r} already answered stimulus {sid}"
                                 + ("; use revise()" if self.study.allow_revise else
                                    "; this study does not allow changing answers"))
            expected = self.next_stimulus()
            if expected is None or expected.id != sid:
                raise StudyError(f"stimulus {sid} is not the next one in rater "
                                 f"{self.rater!r}'s order")
            con.execute("INSERT INTO answers VALUES (?, ?, ?, ?, ?, ?, 0)",
                        (self.rater, sid, label, int(naturalness), float(response_ms), _now()))

    def revise(self, stimulus: Stimulus | int, label: str, naturalness: int,
               response_ms: float) -> None:
        """Replace a committed answer (only if the study allows it; old one goes to history)."""
        if not self.study.allow_revise:
            raise StudyError(f"study {self.study.name!r} does not allow changing answers")
        sid = self._validate(stimulus, label, naturalness, response_ms)
        with self.study._tx() as con:
            key = (self.rater, sid)
            moved = con.execute(
                "INSERT INTO answer_history SELECT rater, stimulus, label, naturalness,"
                " response_ms, answered_at, ? FROM answers WHERE rater=? AND stimulus=?",
                (_now(), *key)).rowcount
            if moved != 1:
                raise StudyError(f"rater {self.rater!r} has not answered stimulus {sid} yet")
            con.execute("UPDATE answers SET label=?, naturalness=?, response_ms=?,"
                        " answered_at=?, revisions=revisions+1 WHERE rater=? AND stimulus=?",
                        (label, int(naturalness), float(response_ms), _now(), *key))
