"""Remote raters of a MOS study: invite tokens and web sessions (no Qt, no HTTP).

``study invite`` creates one random 128-bit token per remote rater; only its SHA-256 is stored
(table ``web_tokens``), so the study file alone does not let anyone rate. A web rater is an
ordinary rater of the study (ids ``web-001`` …): :class:`WebRater` starts the same
:class:`~editor.study.mos.RaterSession` as the in-app window (seeded random order, stored) and
adds a stored *plan* (table ``web_plan``): the training trials first, then the rater's order with
the gold and trapping trials (:mod:`editor.study.qc`) at seeded random places. Each answer is
validated here and committed in its own transaction: study stimuli into ``answers`` (through
``RaterSession.answer``, exactly like in-app answers), QC trials into ``qc_answers``.
:class:`editor.study.web` is the HTTP face of this module.
"""

from __future__ import annotations

import hashlib
import math
import secrets
from dataclasses import dataclass
from typing import Any

import numpy as np

from editor.errors import StudyError
from editor.study.mos import CANNOT_TELL, NATURALNESS, RaterSession, Study, _now
from editor.study.qc import QcItem, ensure_tables, has_table, qc_image, qc_items

TOKEN_BYTES = 16  # 128 bits
WEB_SCHEMA = """
CREATE TABLE IF NOT EXISTS web_tokens (rater TEXT PRIMARY KEY,
    token_sha256 TEXT NOT NULL UNIQUE, created_at TEXT NOT NULL, revoked_at TEXT);
CREATE TABLE IF NOT EXISTS web_plan (rater TEXT NOT NULL, position INTEGER NOT NULL,
    stimulus INTEGER REFERENCES stimuli(id), item INTEGER, PRIMARY KEY (rater, position),
    CHECK ((stimulus IS NULL) != (item IS NULL)));
"""
#: The longest response time an answer may report (one hour, in ms).
MAX_RESPONSE_MS = 3_600_000.0


class AnswerRejected(StudyError):
    """An answer the server refuses; ``status`` is the HTTP status that says why (400 malformed,
    409 not the current trial: replayed, double or out of order). Nothing was written."""

    def __init__(self, message: str, status: int) -> None:
        super().__init__(message)
        self.status = status


def token_hash(token: str) -> str:
    return hashlib.sha256(token.encode("utf-8", "surrogatepass")).hexdigest()


@dataclass(frozen=True)
class Invite:
    rater: str
    token: str


def invite(study: Study, n: int) -> list[Invite]:
    """Create ``n`` new web raters with fresh tokens (one transaction); the tokens are returned
    once and only their hashes stored."""
    if not isinstance(n, int) or not 1 <= n <= 10_000:
        raise StudyError(f"the number of raters must be 1 … 10000, got {n!r}")
    ensure_tables(study, WEB_SCHEMA)
    out = []
    with study._tx() as con:
        taken = {r for (r,) in con.execute("SELECT rater FROM web_tokens")}
        taken |= {r for (r,) in con.execute("SELECT id FROM raters")}
        k = 1
        for _ in range(n):
            while f"web-{k:03d}" in taken:
                k += 1
            rater, token = f"web-{k:03d}", secrets.token_urlsafe(TOKEN_BYTES)
            taken.add(rater)
            con.execute("INSERT INTO web_tokens VALUES (?, ?, ?, NULL)",
                        (rater, token_hash(token), _now()))
            out.append(Invite(rater, token))
    return out


def revoke(study: Study, who: str) -> str:
    """Revoke a web rater's token, given the rater id or the token; returns the rater id.
    Their answers stay in the study (exclude them with QC or by hand)."""
    if not has_table(study, "web_tokens"):
        raise StudyError(f"study {study.name!r} has no web raters")
    with study._tx() as con:
        row = con.execute("SELECT rater FROM web_tokens WHERE rater=? OR token_sha256=?",
                          (who, token_hash(who))).fetchone()
        if row is None:
            raise StudyError(f"no web rater or token {who[:12]!r}… in study {study.name!r}")
        con.execute("UPDATE web_tokens SET revoked_at=COALESCE(revoked_at, ?) WHERE rater=?",
                    (_now(), row[0]))
    return str(row[0])


def count_tokens(study: Study) -> tuple[int, int]:
    """(valid, revoked) web rater tokens of a study (without writing anything)."""
    if not has_table(study, "web_tokens"):
        return 0, 0
    rows = study._rows("SELECT revoked_at IS NULL, COUNT(*) FROM web_tokens GROUP BY 1")
    n = dict(rows)
    return int(n.get(1, 0)), int(n.get(0, 0))


def rater_for_token(study: Study, token: str) -> str | None:
    """The web rater a token belongs to, or None (unknown, malformed or revoked)."""
    if not token or len(token) > 64 or not has_table(study, "web_tokens"):
        return None
    rows = study._rows("SELECT rater FROM web_tokens WHERE token_sha256=? AND revoked_at IS NULL",
                       (token_hash(token),))
    return str(rows[0][0]) if rows else None


@dataclass(frozen=True)
class Trial:
    """One position of a web rater's plan: a study stimulus or a QC item."""

    position: int
    stimulus: int | None
    item: QcItem | None

    @property
    def training(self) -> bool:
        return self.item is not None and self.item.kind == "training"


class WebRater:
    """A web rater's pass through the study: start or resume the session and the plan."""

    def __init__(self, study: Study, rater: str) -> None:
        ensure_tables(study, WEB_SCHEMA)
        self.study, self.rater = study, rater
        self.session: RaterSession = study.start_session(rater)
        items = {i.id: i for i in qc_items(study)}
        rows = study._rows("SELECT position, stimulus, item FROM web_plan WHERE rater=? "
                           "ORDER BY position", (rater,))
        if not rows:
            rows = self._make_plan(list(items.values()))
        self.plan = [Trial(p, s, None if i is None else items[i]) for p, s, i in rows]
        self.n_training = sum(t.training for t in self.plan)

    def _make_plan(self, items: list[QcItem]) -> list[tuple[int, int | None, int | None]]:
        """Training first, then the session's order with gold and trapping trials inserted at
        places drawn from the rater's seed; stored in one transaction."""
        rng = np.random.default_rng([self.session.seed, 808])
        main: list[tuple[int | None, int | None]] = [(s, None) for s in self.session.order]
        inline = [i.id for i in items if i.kind != "training"]
        rng.shuffle(inline)
        for item in inline:  # never first, so the rater has seen one real stimulus
            main.insert(int(rng.integers(1, len(main) + 1)), (None, item))
        plan = [(None, i.id) for i in items if i.kind == "training"] + main
        rows = [(pos, s, i) for pos, (s, i) in enumerate(plan)]
        with self.study._tx() as con:
            if not con.execute("SELECT 1 FROM web_plan WHERE rater=?", (self.rater,)).fetchone():
                con.executemany("INSERT INTO web_plan VALUES (?, ?, ?, ?)",
                                [(self.rater, *r) for r in rows])
        return self.study._rows("SELECT position, stimulus, item FROM web_plan WHERE rater=? "
                                "ORDER BY position", (self.rater,))

    # ------------------------------------------------------------------ state
    def _answered(self) -> tuple[set[int], set[int]]:
        stims = {s for (s,) in self.study._rows("SELECT stimulus FROM answers WHERE rater=?",
                                                (self.rater,))}
        items = ({i for (i,) in self.study._rows("SELECT item FROM qc_answers WHERE rater=?",
                                                 (self.rater,))}
                 if has_table(self.study, "qc_answers") else set())
        return stims, items

    def current(self) -> Trial | None:
        """The first unanswered trial of the plan, or None when finished."""
        stims, items = self._answered()
        for t in self.plan:
            if (t.stimulus not in stims) if t.item is None else (t.item.id not in items):
                return t
        return None

    def state(self) -> dict[str, Any]:
        """What the page needs (JSON-able); never the intended label of a trial."""
        trial = self.current()
        done = len(self.plan) if trial is None else trial.position
        rated, every = done - self.n_training, self.study.break_every
        return {
            "study": self.study.name, "labels": list(self.study.labels),
            "cannot_tell": CANNOT_TELL, "naturalness": [[k, w] for k, w in NATURALNESS.items()],
            "total": len(self.plan), "done": done, "training": self.n_training,
            "break_due": bool(every > 0 and trial is not None and not trial.training
                              and rated > 0 and rated % every == 0),
            "trial": None if trial is None else {
                "position": trial.position, "training": trial.training,
                "image": f"img/{trial.position}"},
        }

    def image(self, position: int) -> tuple[bytes, str]:
        """The image of a trial up to the current one (later ones stay hidden)."""
        trial = self.current()
        upto = len(self.plan) - 1 if trial is None else trial.position
        if not 0 <= position <= upto:
            raise AnswerRejected(f"no trial {position} to show yet", 404)
        t = self.plan[position]
        if t.item is not None:
            return qc_image(self.study, t.item.id)
        rows = self.study._rows("SELECT image, mime FROM stimuli WHERE id=?", (t.stimulus,))
        return bytes(rows[0][0]), str(rows[0][1])

    # ------------------------------------------------------------------ answers
    def answer(self, data: object) -> dict[str, Any]:
        """Validate and commit one answer (a JSON object with exactly ``position``, ``label``,
        ``naturalness``, ``response_ms``); returns the new state plus, for a training trial,
        ``feedback``. :class:`AnswerRejected` (nothing written) otherwise."""
        pos, label, nat, ms = _parse_answer(data, (*self.study.labels, CANNOT_TELL))
        trial = self.current()
        if trial is None or pos != trial.position:
            why = ("already answered" if trial is None or pos < trial.position
                   else "not the current trial")
            raise AnswerRejected(f"trial {pos}: {why}", 409)
        if trial.item is None:
            assert trial.stimulus is not None
            self.session.answer(trial.stimulus, label, nat, ms)
            out = self.state()
        else:
            item = trial.item
            with self.study._tx() as con:
                con.execute("INSERT INTO qc_answers VALUES (?, ?, ?, ?, ?, ?, ?)",
                            (self.rater, item.id, label, nat, ms, _now(),
                             int(item.passes(label, nat))))
            out = self.state()
            if item.kind == "training":
                out["feedback"] = {"correct": label in item.accept,
                                   "intended": item.accept[0]}
        return out


def _parse_answer(data: object, labels: tuple[str, ...]) -> tuple[int, str, int, float]:
    keys = {"position", "label", "naturalness", "response_ms"}
    if not isinstance(data, dict) or set(data) != keys:
        raise AnswerRejected(f"an answer is a JSON object with exactly the keys {sorted(keys)}",
                             400)
    pos, label, nat, ms = (data[k] for k in ("position", "label", "naturalness", "response_ms"))
    if not isinstance(pos, int) or isinstance(pos, bool) or pos < 0:
        raise AnswerRejected("position must be an integer >= 0", 400)
    if not isinstance(label, str) or label not in labels:
        raise AnswerRejected(f"label must be one of {list(labels)}", 400)
    if not isinstance(nat, int) or isinstance(nat, bool) or not 1 <= nat <= 5:
        raise AnswerRejected("naturalness must be an integer 1 … 5", 400)
    if (not isinstance(ms, int | float) or isinstance(ms, bool) or not math.isfinite(ms)
            or not 0 <= ms <= MAX_RESPONSE_MS):
        raise AnswerRejected(f"response_ms must be a number 0 … {MAX_RESPONSE_MS:g}", 400)
    return pos, label, nat, float(ms)
