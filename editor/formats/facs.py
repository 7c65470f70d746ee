"""FACS Action Units <-> MPEG-4 FAPs (no Qt), from the table ``editor/data/mappings/au_faps.json``.

The table gives each supported AU's FAP values (FAPU) at intensity 1.0 (FACS E). A *sided* AU
(FACS scores it on one side) has two columns, ``12L`` and ``12R`` (the subject's left and right
FAPs, midline FAPs halved in each); a bilateral AU sets both. AU -> FAPs is the linear sum of
columns times intensities; FAPs -> AUs is the least-squares fit of the columns bounded to
0..1 with a small ridge (:func:`fit_columns`), so what the columns cannot reach (gaze, head,
tongue, asymmetry of a midline AU, ...) is lost; the table's ``cannot_express`` lists it.

Intensities are 0..1 or FACS letters A-E (``A`` 0.2 ... ``E`` 1.0; the table says why).
AU keys: ``12``, ``AU12``, ``AU12L``, ``L12``, ``12R``; ``45`` (blink) = ``43``, ``46`` (wink)
needs a side.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from editor.engine.faps import FAPS
from editor.resources import MAPPINGS_DIR

__all__ = ["ActionUnit", "AuTable", "au_table", "aus_to_faps", "column_keys", "column_weights",
           "faps_to_aus", "fit_columns", "parse_au_spec", "parse_intensity", "side_of"]

N_FAPS = 68
_KEY = re.compile(r"(?i)\s*(?:au)?\s*([lr])?\s*0*(\d{1,3})\s*([lr])?\s*\Z")
_LEFT = re.compile(r"(^|_)(l|lm)(_|$)")
_RIGHT = re.compile(r"(^|_)(r|rm)(_|$)")


def side_of(fap: int) -> str:
    """``"L"``, ``"R"`` (the subject's side of the FAP's feature point) or ``""`` (midline)."""
    f = FAPS[fap]
    if f.mirror is None:
        return ""
    return "L" if _LEFT.search(f.name) else "R" if _RIGHT.search(f.name) else ""


@dataclass(frozen=True)
class ActionUnit:
    """One AU of the table: its FAP vector at intensity 1.0 (both sides)."""

    number: int
    name: str
    region: str  # "upper" | "lower"
    sided: bool
    faps: np.ndarray  # (68,) FAPU at intensity 1.0
    source: str

    @property
    def label(self) -> str:
        return f"AU{self.number} {self.name}"


@dataclass(frozen=True, eq=False)
class AuTable:
    """The AU table: AUs in table order, columns (``"1L"``, ``"1R"``, ..., ``"17"``, ...)
    and the (68, K) matrix whose column k is the FAP vector of ``columns[k]`` at 1.0."""

    aus: tuple[ActionUnit, ...]
    columns: tuple[str, ...]
    matrix: np.ndarray
    letters: Mapping[str, float]
    aliases: Mapping[int, int]
    cannot_express: tuple[str, ...]

    def au(self, number: int) -> ActionUnit:
        for a in self.aus:
            if a.number == number:
                return a
        raise KeyError(number)

    @property
    def numbers(self) -> tuple[int, ...]:
        return tuple(a.number for a in self.aus)

    def column_index(self, key: str) -> int:
        return self.columns.index(key)

    def columns_of(self, number: int) -> list[int]:
        """Column indices of an AU (two for a sided AU: L, R)."""
        a = self.au(number)
        keys = [f"{number}L", f"{number}R"] if a.sided else [str(number)]
        return [self.columns.index(k) for k in keys]

    def to_bilateral(self, weights: np.ndarray) -> np.ndarray:
        """(N, K) column weights -> (N, len(aus)) one intensity per AU (mean of L and R)."""
        w = np.atleast_2d(np.asarray(weights, np.float64))
        return np.stack([w[:, self.columns_of(a.number)].mean(axis=1) for a in self.aus], 1)

    def from_bilateral(self, values: np.ndarray) -> np.ndarray:
        """(N, len(aus)) per-AU intensities -> (N, K) column weights (both sides equal)."""
        v = np.atleast_2d(np.asarray(values, np.float64))
        out = np.zeros((v.shape[0], len(self.columns)))
        for j, a in enumerate(self.aus):
            out[:, self.columns_of(a.number)] = v[:, j:j + 1]
        return out


def _fap_vector(faps: Mapping[str, float], label: str) -> np.ndarray:
    v = np.zeros(N_FAPS)
    for name, value in faps.items():
        try:
            n = FAPS.number(name)
        except (KeyError, ValueError) as e:
            raise ValueError(f"{label}: unknown FAP {name!r}") from e
        v[n - 1] = float(value)
    return v


def _split(vec: np.ndarray, side: str) -> np.ndarray:
    """The ``side`` half of a bilateral FAP vector: that side's FAPs, half of the midline."""
    out = np.zeros(N_FAPS)
    for i in np.flatnonzero(vec):
        s = side_of(int(i) + 1)
        out[i] = vec[i] if s == side else 0.5 * vec[i] if s == "" else 0.0
    return out


@lru_cache(maxsize=1)
def au_table() -> AuTable:
    """The shipped AU table (read once)."""
    data = json.loads((MAPPINGS_DIR / "au_faps.json").read_text("utf-8"))
    aus, cols, mat = [], [], []
    for row in data["aus"]:
        vec = _fap_vector(row["faps"], f"AU{row['au']}")
        a = ActionUnit(int(row["au"]), row["name"], row["region"], bool(row["sided"]), vec,
                       row["source"])
        aus.append(a)
        if a.sided:
            cols += [f"{a.number}L", f"{a.number}R"]
            mat += [_split(vec, "L"), _split(vec, "R")]
        else:
            cols.append(str(a.number))
            mat.append(vec)
    matrix = np.stack(mat, axis=1)
    matrix.setflags(write=False)
    aliases = {int(k): int(v["au"]) for k, v in data["aliases"].items()}
    return AuTable(tuple(aus), tuple(cols), matrix, dict(data["intensity"]["letters"]),
                   aliases, tuple(data["cannot_express"]))


def parse_intensity(text: str | float) -> float:
    """An intensity 0..1 from a number or a FACS letter A-E; ValueError otherwise."""
    if isinstance(text, str):
        t = text.strip()
        letters = au_table().letters
        if t.upper() in letters:
            return float(letters[t.upper()])
        try:
            value = float(t)
        except ValueError:
            raise ValueError(f"intensity {text!r}: expected a number 0-1 or a FACS letter "
                             "A-E") from None
    else:
        value = float(text)
    if not 0.0 <= value <= 1.0:  # also refuses nan
        raise ValueError(f"intensity {text!r}: expected 0-1 (or a letter A-E)")
    return value


def column_keys(key: str | int) -> list[str]:
    """Column keys of an AU key: ``"12"`` -> ``["12L", "12R"]``, ``"L12"`` -> ``["12L"]``,
    ``"26"`` -> ``["26"]``, ``"45"`` -> AU43's. ValueError for unknown AUs or bad sides."""
    m = _KEY.match(str(key))
    if not m or (m.group(1) and m.group(3)):
        raise ValueError(f"AU {key!r}: expected AU12, 12, L12 or 12R")
    table = au_table()
    number, side = int(m.group(2)), (m.group(1) or m.group(3) or "").upper()
    if number == 46 and not side:
        raise ValueError(f"AU {key!r}: AU46 (wink) is one-sided: write L46 or R46")
    number = table.aliases.get(number, number)
    if number not in table.numbers:
        known = ", ".join(str(n) for n in table.numbers)
        raise ValueError(f"AU {key!r}: no 2-D mapping for AU{number} (supported: {known}, "
                         "45 blink, 46 wink)")
    a = table.au(number)
    if side and not a.sided:
        raise ValueError(f"AU {key!r}: AU{number} ({a.name}) has no sides here")
    if not a.sided:
        return [str(number)]
    return [f"{number}{side}"] if side else [f"{number}L", f"{number}R"]


def parse_au_spec(spec: str) -> tuple[list[str], float]:
    """``"AU12=0.8"``, ``"6=B"``, ``"L12=C"`` -> (column keys, intensity). ValueError else."""
    key, sep, value = spec.partition("=")
    if not sep:
        raise ValueError(f"{spec!r}: expected AU=INTENSITY (e.g. AU12=0.8 or 6=B)")
    return column_keys(key), parse_intensity(value)


def column_weights(values: Mapping[str | int, float] | Iterable[tuple[str | int, float]]
                   ) -> np.ndarray:
    """(K,) column weights of AU key -> intensity pairs (repeated keys add up)."""
    table = au_table()
    w = np.zeros(len(table.columns))
    items = values.items() if isinstance(values, Mapping) else values
    for key, inten in items:
        for c in column_keys(key):
            w[table.column_index(c)] += float(inten)
    return w


def aus_to_faps(values: Mapping[str | int, float] | np.ndarray) -> np.ndarray:
    """AU intensities -> FAP vector(s) in FAPU (not clamped).

    ``values``: a mapping of AU keys to intensities (-> (68,)), or an (N, K) / (K,) array of
    column weights in :attr:`AuTable.columns` order (-> (N, 68) / (68,)).
    """
    table = au_table()
    if isinstance(values, Mapping):
        return table.matrix @ column_weights(values)
    w = np.asarray(values, np.float64)
    return w @ table.matrix.T


#: Ridge weight of :func:`fit_columns` (FAPU per unit intensity): an AU at intensity 1 costs
#: as much as a 30 FAPU error on one FAP, so the fit prefers few AUs to opposite pairs that
#: cancel (AU12 + AU15 to lower a corner by 100).
RIDGE = 30.0


def fit_columns(faps: np.ndarray, matrix: np.ndarray, row_weights: np.ndarray | None = None,
                upper: float = 1.0, ridge: float = RIDGE) -> np.ndarray:
    """Bounded least squares of FAP vector(s) (N, 68) on ``matrix`` (68, K): (N, K) weights in
    0..``upper`` minimising |W(A x - f)|^2 + ridge^2 |x|^2.

    Rows (FAPs) no column touches are left out (they cannot be fitted); ``row_weights`` scale
    the rest (e.g. to bring rotation units to the size of displacements). One small
    bounded-variable problem per frame (:func:`_bounded_lsq`).
    """
    f = np.atleast_2d(np.asarray(faps, np.float64))
    used = np.flatnonzero(np.abs(matrix).sum(axis=1) > 0)
    w = np.ones(N_FAPS) if row_weights is None else np.asarray(row_weights, np.float64)
    k = matrix.shape[1]
    a = np.vstack([matrix[used] * w[used, None], ridge * np.eye(k)])
    b = np.hstack([f[:, used] * w[used], np.zeros((f.shape[0], k))])
    out = np.zeros((f.shape[0], k))
    for i in np.flatnonzero(b.any(axis=1)):
        out[i] = _bounded_lsq(a, b[i], upper)
    return np.clip(out, 0.0, upper)


def _bounded_lsq(a: np.ndarray, b: np.ndarray, upper: float) -> np.ndarray:
    """argmin |a x - b| over 0 <= x <= ``upper``: non-negative least squares (scipy's NNLS,
    ~15x faster here than its BVLS) with the columns above ``upper`` held there, until the
    solution meets the bounded problem's optimality conditions (an AU rarely exceeds 1: one
    or two NNLS solves a frame). If that does not settle or NNLS stopped short (SciPy 1.17's
    can, on a degenerate frame), an exact active set takes over from there (:func:`_active_set`;
    BVLS, ~20 ms, only if that does not settle either). The problem is strictly convex (the
    ridge rows), so all give its one solution."""
    from scipy.optimize import lsq_linear, nnls  # scipy on first use: a quick start (issue 15)

    k = a.shape[1]
    top = np.zeros(k, bool)  # columns held at the upper bound
    tol = 1e-9 * max(float(np.abs(a.T @ b).max()), 1.0)
    seen: set[bytes] = set()
    for _ in range(k + 1):
        if top.tobytes() in seen:  # the holds cycle (NNLS stopping short on one of them)
            break
        seen.add(top.tobytes())
        rest = ~top
        x = np.full(k, upper)
        x[rest] = nnls(a[:, rest], b - upper * a[:, top].sum(axis=1))[0]
        over = rest & (x > upper)
        if over.any():
            top |= over
            continue
        grad = a.T @ (a @ x - b)
        release = top & (grad > tol)  # held at the top but better lower
        if not release.any():
            # the optimality conditions in full (scipy's NNLS can stop short on a
            # degenerate problem: then BVLS decides)
            free = (x > 0.0) & ~top
            if (np.abs(grad[free]) <= tol).all() and (grad[(x <= 0.0)] >= -tol).all():
                return x
            break
        top[int(np.argmax(np.where(release, grad, -np.inf)))] = False
    # (an exact active set on the normal equations, from where NNLS left off; BVLS last)
    got = _active_set(a.T @ a, a.T @ b, upper, np.clip(x, 0.0, upper), tol)
    return got if got is not None else lsq_linear(a, b, bounds=(0.0, upper), method="bvls").x


def _active_set(H: np.ndarray, g: np.ndarray, upper: float, x: np.ndarray, tol: float
                ) -> np.ndarray | None:
    """argmin 0.5 x'Hx - g'x over 0 <= x <= ``upper`` (H positive definite), a primal active
    set started at the feasible ``x``: the free columns solved with the bounded ones held,
    a step back to the first bound crossed, or the most violating bounded column freed.
    None if it has not settled in its iteration budget."""
    k = len(g)
    state = np.where(x <= 0.0, -1, np.where(x >= upper, 1, 0))  # at 0, free, at the top
    for _ in range(4 * k + 8):
        free = state == 0
        t = np.where(state > 0, upper, 0.0)
        t[free] = x[free]
        if free.any():
            held = ~free
            t[free] = np.linalg.solve(H[np.ix_(free, free)],
                                      g[free] - H[np.ix_(free, held)] @ t[held])
        bad = free & ((t < 0.0) | (t > upper))
        if bad.any():
            d = t - x
            lim = np.where(d[bad] < 0.0, -x[bad] / d[bad], (upper - x[bad]) / d[bad])
            step = float(lim.min())
            x = x + step * d
            hit = np.flatnonzero(bad)[lim <= step + 1e-15]
            low = t[hit] < 0.0
            x[hit[low]], state[hit[low]] = 0.0, -1
            x[hit[~low]], state[hit[~low]] = upper, 1
            continue
        x = t
        grad = H @ x - g
        viol = np.where(state < 0, -grad, np.where(state > 0, grad, -np.inf))
        j = int(np.argmax(viol))
        if viol[j] <= tol:
            return x
        state[j] = 0
    return None


def faps_to_aus(faps: np.ndarray) -> np.ndarray:
    """FAP vector(s) -> AU column weights (N, K) in 0..1 by :func:`fit_columns`."""
    return fit_columns(faps, au_table().matrix)
