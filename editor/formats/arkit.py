"""Apple ARKit blendshapes (and Live Link Face's head/eye rotations) <-> MPEG-4 FAPs (no Qt).

The table ``editor/data/mappings/arkit.json`` gives each of the 52 blendshapes as FACS AU
columns (:mod:`.facs`) and/or FAP values at weight 1.0; the Live Link rotation columns
(radians) map to FAPs 48-50 and the eyeball yaw/pitch FAPs 23-26 (1 FAP unit = 1e-5 rad).

ARKit -> FAPs is linear. FAPs -> ARKit: rotations are read off FAPs 23-26 and 48-50; the 52
weights are the bounded (0..1) least-squares fit of the blendshape columns
(:func:`.facs.fit_columns`; rotation FAPs weighted 1/100 so that their 1e-5 rad units do not
outweigh displacements).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from editor.engine.faps import FAPS
from editor.resources import MAPPINGS_DIR

from .facs import au_table, fit_columns

__all__ = ["ArkitTable", "arkit_table", "arkit_to_faps", "faps_to_arkit"]

N_FAPS = 68
ROTATION_UNIT = 1e-5  # radians per FAP angle unit (MPEG4_FAP.md §1)


@dataclass(frozen=True, eq=False)
class ArkitTable:
    """names: the 52 blendshapes (ARKit camelCase, Live Link order); matrix (68, 52): FAPs at
    weight 1; rotations: the 9 Live Link rotation columns; rotation_faps: the FAP number of
    each (0: none, dropped); signs: +1/-1 (0: dropped); gaze: indices of the eyeLook* shapes."""

    names: tuple[str, ...]
    matrix: np.ndarray
    sources: tuple[str, ...]
    rotations: tuple[str, ...]
    rotation_faps: tuple[int, ...]
    signs: tuple[int, ...]
    gaze: tuple[int, ...]
    cannot_express: tuple[str, ...]

    @property
    def csv_names(self) -> tuple[str, ...]:
        """Live Link Face's column names: the blendshape names with a capital first letter."""
        return tuple(n[0].upper() + n[1:] for n in self.names)

    @property
    def eye_rotation_columns(self) -> tuple[int, ...]:
        """Indices (in :attr:`rotations`) of the eye yaw/pitch columns."""
        return tuple(i for i, f in enumerate(self.rotation_faps) if 23 <= f <= 26)


@lru_cache(maxsize=1)
def arkit_table() -> ArkitTable:
    """The shipped ARKit table (read once)."""
    data = json.loads((MAPPINGS_DIR / "arkit.json").read_text("utf-8"))
    aus = au_table()
    names, cols, sources = [], [], []
    for row in data["blendshapes"]:
        v = np.zeros(N_FAPS)
        for key, w in row.get("aus", {}).items():
            v += aus.matrix[:, aus.column_index(key)] * float(w)
        for name, value in row.get("faps", {}).items():
            v[FAPS.number(name) - 1] += float(value)
        names.append(row["name"])
        cols.append(v)
        sources.append(row["source"])
    matrix = np.stack(cols, axis=1)
    matrix.setflags(write=False)
    rot = data["live_link_rotations"]["columns"]
    gaze = tuple(i for i, n in enumerate(names) if n.startswith("eyeLook"))
    return ArkitTable(tuple(names), matrix, tuple(sources), tuple(r["name"] for r in rot),
                      tuple(FAPS.number(r["fap"]) if r["fap"] else 0 for r in rot),
                      tuple(int(r["sign"]) for r in rot), gaze,
                      tuple(data["cannot_express"]))


def arkit_to_faps(weights: np.ndarray, rotations: np.ndarray | None = None) -> np.ndarray:
    """(N, 52) blendshape weights (+ optional (N, 9) Live Link rotations in radians) ->
    (N, 68) FAPs in FAPU (not clamped). When any eye rotation is non-zero, the rotation
    columns set the gaze FAPs and the eyeLook* shapes are not used for gaze (the table's
    ``gaze_rule``)."""
    t = arkit_table()
    w = np.atleast_2d(np.asarray(weights, np.float64))
    rot = None if rotations is None else np.atleast_2d(np.asarray(rotations, np.float64))
    eyes = rot is not None and bool(rot[:, list(t.eye_rotation_columns)].any())
    if eyes:
        w = w.copy()
        w[:, list(t.gaze)] = 0.0
    out = w @ t.matrix.T
    if rot is not None:
        for j, (fap, sign) in enumerate(zip(t.rotation_faps, t.signs, strict=True)):
            if fap:
                out[:, fap - 1] += sign * rot[:, j] / ROTATION_UNIT
    return out


def faps_to_arkit(faps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 68) FAPs -> ((N, 52) weights in 0..1, (N, 9) Live Link rotations in radians)."""
    t = arkit_table()
    f = np.atleast_2d(np.asarray(faps, np.float64))
    row_w = np.array([0.01 if FAPS[n].unit == "AU" else 1.0 for n in range(1, 69)])
    w = fit_columns(f, t.matrix, row_w)
    rot = np.zeros((f.shape[0], len(t.rotations)))
    for j, (fap, sign) in enumerate(zip(t.rotation_faps, t.signs, strict=True)):
        if fap:
            rot[:, j] = sign * f[:, fap - 1] * ROTATION_UNIT
    return w, rot
