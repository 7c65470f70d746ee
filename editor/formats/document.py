"""The editor's document: an immutable snapshot of one editing state (no Qt).

A :class:`Document` is a frozen snapshot (photo path, edited neutral mesh, FAP vector) whose
arrays are read-only, so undo keeps two references per command and a render request needs no
lock. :class:`editor.ui.document_model.DocumentModel` holds the current one and the undo stack;
:mod:`editor.formats.project` stores one in a project file.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from editor.engine.face import Face
from editor.engine.faps import FAPS


def _frozen(a: object, shape: tuple[int | None, ...]) -> np.ndarray:
    """``a`` as a read-only C-contiguous float32 array (the same object if it already is one)."""
    arr = np.asarray(a, np.float32)
    if arr.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, arr.shape,
                                                                              strict=True)):
        raise ValueError(f"expected an array of shape {shape}, got {arr.shape}")
    if arr.flags.writeable or not arr.flags.c_contiguous or arr is not a:
        arr = np.array(arr, np.float32, order="C")
        arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class Document:
    """One state of the editor.

    Attributes
    ----------
    photo : str | None
        Path of the neutral frontal photo.
    vertices : (V, 2) float32, read-only
        The neutral personalized mesh (possibly edited), image pixels (x, y), y down.
    faps : (68,) float32, read-only
        FAP values in FAPU (index i = FAP i + 1), clamped to the FAP table's ranges.
    photo_neutral : bool
        The photo is declared neutral: FAPs apply to the photo itself (0 = the photo), not to
        the neutralised face with the photo's own expression estimated.
    """

    photo: str | None
    vertices: np.ndarray
    faps: np.ndarray
    photo_neutral: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "vertices", _frozen(self.vertices, (None, 2)))
        object.__setattr__(self, "faps", _frozen(self.faps, (68,)))

    @classmethod
    def neutral(cls, face: Face) -> Document:
        """The fitted mesh of ``face`` with every FAP at 0 (the neutralised face)."""
        return cls(face.source, face.vertices, np.zeros(68, np.float32))

    @classmethod
    def initial(cls, face: Face, photo_neutral: bool = False) -> Document:
        """A new photo's document: its FAPs are the photo's own expression (zero when the
        photo is declared neutral), so the untouched document renders the photo unchanged."""
        if photo_neutral:
            return cls(face.source, face.vertices, np.zeros(68, np.float32), True)
        return cls(face.source, face.vertices, face.expression)

    def replace(self, **changes: Any) -> Document:
        return dataclasses.replace(self, **changes)

    def equals(self, other: Document | None) -> bool:
        """Same photo, mesh and FAP values (array ``==`` is ambiguous, hence a method)."""
        if other is self:
            return True
        return (other is not None and self.photo == other.photo
                and self.photo_neutral == other.photo_neutral
                and np.array_equal(self.vertices, other.vertices)
                and np.array_equal(self.faps, other.faps))

    def fap(self, key: object) -> float:
        """Value of one FAP (name or number) in FAPU."""
        return float(self.faps[FAPS.number(key) - 1])

    def with_faps(self, values: Mapping[Any, float]) -> Document:
        """A copy with some FAPs set (names or numbers), clamped; ``self`` if nothing changes."""
        v = self.faps.copy()
        for key, val in values.items():
            v[FAPS.number(key) - 1] = FAPS.vector({key: val})[FAPS.number(key) - 1]
        v = FAPS.clamp(v)
        return self if np.array_equal(v, self.faps) else self.replace(faps=v)

    def with_fap_vector(self, faps: np.ndarray) -> Document:
        v = FAPS.clamp(FAPS.vector(np.asarray(faps, np.float32)))
        return self if np.array_equal(v, self.faps) else self.replace(faps=v)

    def with_vertex(self, index: int, xy: tuple[float, float] | np.ndarray) -> Document:
        """A copy with one neutral mesh vertex moved to ``xy`` (image pixels)."""
        v = self.vertices.copy()
        p = np.asarray(xy, np.float64).reshape(2)
        if not (np.abs(p) < 1e9).all():
            raise ValueError(f"vertex {index}: position {xy!r} is not two finite numbers")
        v[index] = p
        return self if np.array_equal(v, self.vertices) else self.replace(vertices=v)
