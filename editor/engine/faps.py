"""The MPEG-4 FAP table: one source of truth for the deformation, the GUI, files and presets.

Data from ``MPEG4_FAP.md`` §2 (numbers, names, units, uni/bidirectional, positive direction,
groups, feature points). ``range`` is the slider range in FAP units (FAPU): it covers a strong
but plausible expression on a frontal photo, tighter than the bitstream's codable maximum where
that maximum is anatomically absurd (e.g. squeeze_eyebrow ±900 ES would move a brow by almost
the eye separation). Out-of-range values are clamped by :func:`clamp` (the .fap reader itself
never clamps: files keep what they hold).

Left/right are the face's own (the subject's left is the image's right).

2-D approximations (a frontal photo has no depth; chosen here, used by ``deform``):

* 14 thrust_jaw: the chin (2.1) moves down by 0.3 of the value (a protruding jaw looks longer).
* 16 push_b_lip / 17 push_t_lip: the outer lip middle (8.2 / 8.1) moves away from the lip line
  by half the value (a pushed lip shows more red); negative values thin the lip.
* 27/28 thrust eyeball: the iris is scaled by ``1 + value·ES/(4·iris radius)`` (bulging eye).
* 29/30 dilate pupil: the pupil radius grows by value·IRISD/2 (neutral pupil = iris/3).
* 23-26 eyeball yaw/pitch: the iris centre moves by ``IRISD0·sin(value·1e-5)``.
* 43-47 tongue: the tongue feature points 6.1-6.4 (behind the lips) move in the image plane;
  thrust_tongue_tip moves the tip down by half the value (sticking out = lower in a frontal
  view); tongue_roll raises the tongue borders by ``0.3·MW0·sin(value·1e-5·100)``.
* 48 head_pitch / 49 head_yaw: the face is treated as a dome (depth largest at the nose,
  zero on the contour) rotated about the head centre and projected orthographically: features
  shift towards the turn, the contour only foreshortens; the margin ring follows at 40 %,
  the image border stays.
* 50 head_roll: rotation of the face about the top of the spine (7.1, below the chin), the margin
  ring at 40 %, the image border fixed.
* 65-68 ears: the ear region beside the upper face contour moves as a whole.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

GROUP_NAMES = {1: "visemes & expressions", 2: "jaw, chin, inner lips", 3: "eyes",
               4: "eyebrows", 5: "cheeks", 6: "tongue", 7: "head", 8: "outer lips",
               9: "nose", 10: "ears"}


@dataclass(frozen=True)
class Fap:
    """One Facial Animation Parameter.

    Attributes
    ----------
    number : int           1..68
    name : str             MPEG-4 name, e.g. ``open_jaw``
    description : str      what moves
    unit : str             ``MNS``, ``MW``, ``ENS``, ``ES``, ``IRISD``, ``AU`` (or ``-``)
    bidirectional : bool   False for U FAPs (only positive values are anatomically meaningful)
    direction : str        motion for a positive value: up, down, left, right (face's own),
                           forward, growing, concave
    group : int            MPEG-4 FAP group 1..10
    fdp : str | None       the feature point it drives (rotation pivot for eye/head rotations)
    range : (float, float) slider range in FAPU
    mirror : int | None    the left/right partner FAP

    Examples
    --------
    >>> from editor.core import FAPS
    >>> fap = FAPS["raise_l_cornerlip_o"]
    >>> fap.number, fap.unit, fap.direction, fap.fdp, FAPS[fap.mirror].name
    (59, 'MNS', 'up', '8.3', 'raise_r_cornerlip_o')
    >>> fap.group_name
    'outer lips'
    """

    number: int
    name: str
    description: str
    unit: str
    bidirectional: bool
    direction: str
    group: int
    fdp: str | None
    range: tuple[float, float]
    mirror: int | None = None

    @property
    def group_name(self) -> str:
        return GROUP_NAMES[self.group]

    @property
    def tooltip(self) -> str:
        kind = "bidirectional" if self.bidirectional else "unidirectional"
        return (f"FAP {self.number} {self.name}: {self.description}. Positive = {self.direction}; "
                f"unit {self.unit}; {kind}; feature point {self.fdp or '-'}; "
                f"range {self.range[0]:g} … {self.range[1]:g}")


# number, name, description, unit, U/B, +dir, group, FDP, (lo, hi)
_ROWS = [
    (1, "viseme", "blend of two visemes", "-", True, "-", 1, None, (0, 0)),
    (2, "expression", "blend of two expressions", "-", True, "-", 1, None, (0, 0)),
    (3, "open_jaw", "jaw drop (the lower lip follows)", "MNS", False, "down", 2, "2.1", (0, 1080)),
    (4, "lower_t_midlip", "inner upper lip, middle", "MNS", True, "down", 2, "2.2", (-600, 600)),
    (5, "raise_b_midlip", "inner lower lip, middle", "MNS", True, "up", 2, "2.3", (-1100, 600)),
    (6, "stretch_l_cornerlip", "inner lip left corner", "MW", True, "left", 2, "2.4", (-400, 400)),
    (7, "stretch_r_cornerlip", "inner lip right corner", "MW", True, "right", 2, "2.5",
     (-400, 400)),
    (8, "lower_t_lip_lm", "inner upper lip, left mid-point", "MNS", True, "down", 2, "2.6",
     (-600, 600)),
    (9, "lower_t_lip_rm", "inner upper lip, right mid-point", "MNS", True, "down", 2, "2.7",
     (-600, 600)),
    (10, "raise_b_lip_lm", "inner lower lip, left mid-point", "MNS", True, "up", 2, "2.8",
     (-1100, 600)),
    (11, "raise_b_lip_rm", "inner lower lip, right mid-point", "MNS", True, "up", 2, "2.9",
     (-1100, 600)),
    (12, "raise_l_cornerlip", "inner lip left corner", "MNS", True, "up", 2, "2.4", (-600, 600)),
    (13, "raise_r_cornerlip", "inner lip right corner", "MNS", True, "up", 2, "2.5", (-600, 600)),
    (14, "thrust_jaw", "jaw forward (2-D: chin lower)", "MNS", False, "forward", 2, "2.1",
     (0, 600)),
    (15, "shift_jaw", "jaw sideways", "MW", True, "right", 2, "2.1", (-400, 400)),
    (16, "push_b_lip", "lower lip middle forward (2-D: fuller)", "MNS", True, "forward", 2, "2.3",
     (-600, 600)),
    (17, "push_t_lip", "upper lip middle forward (2-D: fuller)", "MNS", True, "forward", 2, "2.2",
     (-600, 600)),
    (18, "depress_chin", "chin boss pushed up", "MNS", True, "up", 2, "2.10", (-420, 420)),
    (19, "close_t_l_eyelid", "left upper eyelid", "IRISD", True, "down", 3, "3.1", (-300, 1080)),
    (20, "close_t_r_eyelid", "right upper eyelid", "IRISD", True, "down", 3, "3.2", (-300, 1080)),
    (21, "close_b_l_eyelid", "left lower eyelid", "IRISD", True, "up", 3, "3.3", (-300, 600)),
    (22, "close_b_r_eyelid", "right lower eyelid", "IRISD", True, "up", 3, "3.4", (-300, 600)),
    (23, "yaw_l_eyeball", "left eyeball yaw", "AU", True, "left", 3, "3.5", (-50000, 50000)),
    (24, "yaw_r_eyeball", "right eyeball yaw", "AU", True, "left", 3, "3.6", (-50000, 50000)),
    (25, "pitch_l_eyeball", "left eyeball pitch", "AU", True, "down", 3, "3.5", (-40000, 40000)),
    (26, "pitch_r_eyeball", "right eyeball pitch", "AU", True, "down", 3, "3.6", (-40000, 40000)),
    (27, "thrust_l_eyeball", "left eyeball forward (2-D: larger iris)", "ES", True, "forward", 3,
     "3.5", (-300, 300)),
    (28, "thrust_r_eyeball", "right eyeball forward (2-D: larger iris)", "ES", True, "forward", 3,
     "3.6", (-300, 300)),
    (29, "dilate_l_pupil", "left pupil size", "IRISD", True, "growing", 3, "3.5", (-300, 300)),
    (30, "dilate_r_pupil", "right pupil size", "IRISD", True, "growing", 3, "3.6", (-300, 300)),
    (31, "raise_l_i_eyebrow", "left brow, inner end", "ENS", True, "up", 4, "4.1", (-400, 400)),
    (32, "raise_r_i_eyebrow", "right brow, inner end", "ENS", True, "up", 4, "4.2", (-400, 400)),
    (33, "raise_l_m_eyebrow", "left brow, middle", "ENS", True, "up", 4, "4.3", (-400, 400)),
    (34, "raise_r_m_eyebrow", "right brow, middle", "ENS", True, "up", 4, "4.4", (-400, 400)),
    (35, "raise_l_o_eyebrow", "left brow, outer end", "ENS", True, "up", 4, "4.5", (-400, 400)),
    (36, "raise_r_o_eyebrow", "right brow, outer end", "ENS", True, "up", 4, "4.6", (-400, 400)),
    (37, "squeeze_l_eyebrow", "left brow towards the middle", "ES", True, "right", 4, "4.1",
     (-150, 150)),
    (38, "squeeze_r_eyebrow", "right brow towards the middle", "ES", True, "left", 4, "4.2",
     (-150, 150)),
    (39, "puff_l_cheek", "left cheek outwards", "ES", True, "left", 5, "5.1", (-300, 300)),
    (40, "puff_r_cheek", "right cheek outwards", "ES", True, "right", 5, "5.2", (-300, 300)),
    (41, "lift_l_cheek", "left cheek bone up", "ENS", False, "up", 5, "5.3", (0, 600)),
    (42, "lift_r_cheek", "right cheek bone up", "ENS", False, "up", 5, "5.4", (0, 600)),
    (43, "shift_tongue_tip", "tongue tip sideways", "MW", True, "right", 6, "6.1", (-500, 500)),
    (44, "raise_tongue_tip", "tongue tip up", "MNS", True, "up", 6, "6.1", (-800, 800)),
    (45, "thrust_tongue_tip", "tongue tip forward (2-D: lower)", "MW", True, "forward", 6, "6.1",
     (-800, 800)),
    (46, "raise_tongue", "tongue body up", "MNS", True, "up", 6, "6.2", (-800, 800)),
    (47, "tongue_roll", "tongue sides curl up", "AU", False, "concave", 6, "6.3", (0, 300)),
    (48, "head_pitch", "head pitch (2-D: dome rotation)", "AU", True, "down", 7, "7.1",
     (-20000, 20000)),
    (49, "head_yaw", "head yaw (2-D: dome rotation)", "AU", True, "left", 7, "7.1",
     (-20000, 20000)),
    (50, "head_roll", "head roll about the neck", "AU", True, "right", 7, "7.1", (-35000, 35000)),
    (51, "lower_t_midlip_o", "outer upper lip, middle", "MNS", True, "down", 8, "8.1", (-600, 600)),
    (52, "raise_b_midlip_o", "outer lower lip, middle", "MNS", True, "up", 8, "8.2", (-1100, 600)),
    (53, "stretch_l_cornerlip_o", "outer lip left corner", "MW", True, "left", 8, "8.3",
     (-400, 400)),
    (54, "stretch_r_cornerlip_o", "outer lip right corner", "MW", True, "right", 8, "8.4",
     (-400, 400)),
    (55, "lower_t_lip_lm_o", "outer upper lip, left mid-point", "MNS", True, "down", 8, "8.5",
     (-600, 600)),
    (56, "lower_t_lip_rm_o", "outer upper lip, right mid-point", "MNS", True, "down", 8, "8.6",
     (-600, 600)),
    (57, "raise_b_lip_lm_o", "outer lower lip, left mid-point", "MNS", True, "up", 8, "8.7",
     (-1100, 600)),
    (58, "raise_b_lip_rm_o", "outer lower lip, right mid-point", "MNS", True, "up", 8, "8.8",
     (-1100, 600)),
    (59, "raise_l_cornerlip_o", "outer lip left corner", "MNS", True, "up", 8, "8.3", (-600, 600)),
    (60, "raise_r_cornerlip_o", "outer lip right corner", "MNS", True, "up", 8, "8.4",
     (-600, 600)),
    (61, "stretch_l_nose", "left nose wing outwards", "ENS", True, "left", 9, "9.1", (-300, 300)),
    (62, "stretch_r_nose", "right nose wing outwards", "ENS", True, "right", 9, "9.2",
     (-300, 300)),
    (63, "raise_nose", "nose tip up", "ENS", True, "up", 9, "9.3", (-300, 300)),
    (64, "bend_nose", "nose tip sideways", "ENS", True, "right", 9, "9.3", (-300, 300)),
    (65, "raise_l_ear", "left ear up", "ENS", True, "up", 10, "10.1", (-400, 400)),
    (66, "raise_r_ear", "right ear up", "ENS", True, "up", 10, "10.2", (-400, 400)),
    (67, "pull_l_ear", "left ear outwards", "ENS", True, "left", 10, "10.3", (-400, 400)),
    (68, "pull_r_ear", "right ear outwards", "ENS", True, "right", 10, "10.4", (-400, 400)),
]

def _mirror_of(name: str) -> str | None:
    for a, b in (("_l_", "_r_"), ("_r_", "_l_"), ("_lm", "_rm"), ("_rm", "_lm")):
        if a in name:
            return name.replace(a, b)
    if name.endswith("_l"):
        return name[:-2] + "_r"
    if name.endswith("_r"):
        return name[:-2] + "_l"
    return None


#: Largest |value| a FAP vector accepts (anything beyond is an input error, never clamped
#: silently): far outside every FAP range, well inside float32.
MAX_VALUE = 1e9


class FapTable(Mapping[object, Fap]):
    """The 68 FAPs, indexable by number (1..68) or name (``FAPS["open_jaw"]``).

    :data:`FAPS` is the one table; iterating yields the numbers 1..68. A FAP vector is a
    (68,) float32 array, index i = FAP i+1, values in FAPU.

    Parameters
    ----------
    rows : list of tuple
        ``(number, name, description, unit, bidirectional, direction, group, fdp, range)``
        per FAP (the MPEG-4 table); the left/right partners are found from the names.

    Attributes
    ----------
    lo, hi : (68,) float32
        The lower and upper ends of each FAP's range.

    Raises
    ------
    ValueError
        Looking up an unknown name or number, or a vector value that is not finite.

    Examples
    --------
    >>> from editor.core import FAPS
    >>> len(FAPS), FAPS[3].name, FAPS["open_jaw"].number, FAPS[3].range
    (68, 'open_jaw', 3, (0.0, 1080.0))
    >>> v = FAPS.vector({"open_jaw": 2000, 53: -50})  # names or numbers, not clamped
    >>> float(v[2]), float(v[52]), float(FAPS.clamp(v)[2])
    (2000.0, -50.0, 1080.0)
    >>> FAPS["smile"]
    Traceback (most recent call last):
    ...
    ValueError: unknown FAP 'smile' (expected a number 1-68 or an MPEG-4 FAP name)
    """

    def __init__(self, rows: list[tuple]) -> None:
        by_name = {r[1]: r[0] for r in rows}
        self._by_number: dict[int, Fap] = {}
        for r in rows:
            number, name, desc, unit, bidir, direction, group, fdp, rng = r
            m = _mirror_of(name)
            self._by_number[number] = Fap(number, name, desc, unit, bidir,
                                          direction, group, fdp,
                                          (float(rng[0]), float(rng[1])),
                                          by_name.get(m) if m else None)
        self._by_name = {f.name: f for f in self._by_number.values()}
        self.lo = np.array([self._by_number[i].range[0] for i in range(1, 69)], np.float32)
        self.hi = np.array([self._by_number[i].range[1] for i in range(1, 69)], np.float32)

    def __getitem__(self, key: object) -> Fap:
        return self._by_number[self.number(key)]

    def __iter__(self) -> Iterator[int]:
        return iter(self._by_number)

    def __len__(self) -> int:
        return len(self._by_number)

    def number(self, key: object) -> int:
        """FAP number of a name or number; ValueError naming the key if unknown."""
        if isinstance(key, (int, np.integer)) and not isinstance(key, bool):
            if int(key) in self._by_number:
                return int(key)
        elif isinstance(key, str):
            k = key.strip()
            if k in self._by_name:
                return self._by_name[k].number
            if k.isdigit() and int(k) in self._by_number:
                return int(k)
        raise ValueError(f"unknown FAP {key!r} (expected a number 1-68 or an MPEG-4 FAP name)")

    def vector(self, faps: Mapping[Any, float] | np.ndarray | None) -> np.ndarray:
        """A (68,) float32 vector (index i = FAP i+1) from a mapping name/number -> value.

        Non-finite values raise ValueError naming the key. Values are *not* clamped here.
        """
        v = np.zeros(68, np.float32)
        if faps is None:
            return v
        if isinstance(faps, np.ndarray):
            a = np.asarray(faps, np.float64)
            if a.shape != (68,):
                raise ValueError(f"a FAP vector has shape (68,), got {a.shape}")
            bad = ~(np.abs(a) <= MAX_VALUE)  # NaN, infinite or beyond float32
            if np.count_nonzero(bad):
                i = int(np.flatnonzero(bad)[0]) + 1
                raise ValueError(f"FAP {i} ({self[i].name}) is not a finite number within "
                                 f"±{MAX_VALUE:g}")
            return a.astype(np.float32)
        for key, val in faps.items():
            n = self.number(key)
            try:
                x = float(val)
            except (TypeError, ValueError, OverflowError) as e:
                raise ValueError(f"FAP {key!r}: value {str(val)[:40]!r} is not a finite "
                                 f"number within ±{MAX_VALUE:g}") from e
            if not abs(x) <= MAX_VALUE:
                raise ValueError(f"FAP {key!r}: value {x!r} is not a finite number within "
                                 f"±{MAX_VALUE:g}")
            v[n - 1] = x
        return v

    def clamp(self, v: np.ndarray) -> np.ndarray:
        """Clamp a (68,) or (B, 68) vector to the table ranges (FAPs 1-2 are left alone)."""
        out = np.minimum(np.maximum(v, self.lo), self.hi)  # (np.clip: the same, slower)
        out[..., :2] = np.asarray(v)[..., :2]
        return out.astype(np.float32)

    def groups(self) -> dict[int, list[Fap]]:
        """Low-level FAPs (3-68) by MPEG-4 group."""
        out: dict[int, list[Fap]] = {}
        for n in range(3, 69):
            f = self._by_number[n]
            out.setdefault(f.group, []).append(f)
        return out


FAPS = FapTable(_ROWS)

#: Left/right partner index of each FAP (0-based, -1 for none): vectorised ``Fap.mirror``.
_MIRROR_INDEX = np.array([(FAPS[n].mirror or 0) - 1 for n in range(1, 69)], np.int64)


def round_half_away(a: np.ndarray | float | list) -> np.ndarray:
    """Round to integers, halves away from zero (as .fap files and presets store values).

    Parameters
    ----------
    a : array_like
        Values in FAPU.

    Returns
    -------
    numpy.ndarray
        float64 array of the same shape, integer-valued.

    Examples
    --------
    >>> round_half_away([12.5, -12.5, 0.4]).tolist()
    [13.0, -13.0, 0.0]
    """
    a = np.asarray(a, np.float64)
    return np.sign(a) * np.floor(np.abs(a) + 0.5)


def check_vector(vector: np.ndarray) -> np.ndarray:
    """A (68,) float64 copy of a finite low-level FAP vector (FAP 1/2 zero).

    Parameters
    ----------
    vector : array_like
        68 values, index i = FAP i+1.

    Returns
    -------
    numpy.ndarray
        (68,) float64 copy.

    Raises
    ------
    ValueError
        Wrong size, a non-finite value, or a non-zero FAP 1/2.

    Examples
    --------
    >>> float(check_vector(FAPS.vector({"open_jaw": 300}))[2])
    300.0
    """
    v = np.array(vector, np.float64).reshape(-1)
    if v.shape != (68,) or not np.isfinite(v).all() or v[0] or v[1]:
        raise ValueError(f"expected 68 finite low-level FAP values (FAP 1/2 zero), got {v}")
    return v


def partner_mask(m: np.ndarray) -> np.ndarray:
    """The (68,) mask ``m`` plus the left/right partner of each masked FAP, FAP 1/2 off.

    Parameters
    ----------
    m : array_like of bool
        (68,) mask, index i = FAP i+1.

    Returns
    -------
    numpy.ndarray
        (68,) bool.

    Examples
    --------
    >>> m = partner_mask(FAPS.vector({"raise_l_cornerlip": 100}) != 0)
    >>> [FAPS[int(i) + 1].name for i in m.nonzero()[0]]
    ['raise_l_cornerlip', 'raise_r_cornerlip']
    """
    out = np.array(m, bool).reshape(68)
    partners = _MIRROR_INDEX[out]
    out[partners[partners >= 0]] = True
    out[:2] = False
    return out
