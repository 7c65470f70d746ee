"""The editor's document: an immutable snapshot of one editing state (no Qt).

A :class:`Document` is a frozen snapshot (photo path, edited neutral mesh, FAP vector, the
animation being authored) whose arrays are read-only, so undo keeps two references per command
and a render request needs no lock. :class:`editor.ui.document_model.DocumentModel` holds the
current one and the undo stack; :mod:`editor.formats.project` stores one in a project file.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from editor.engine.faps import FAPS

if TYPE_CHECKING:  # annotations only: the editor window imports this module before the renderer
    from editor.engine.face import Face  # and before the .fap reader/writer (issue 15)
    from editor.formats.fapfile import FapSequence

INTERPOLATIONS = ("linear", "smoothstep")


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


def _key_vector(vector: object) -> np.ndarray:
    """A keyframe's (68,) read-only float32 FAP vector with FAP 1/2 zeroed."""
    v = np.array(vector, np.float32).reshape(68)
    v[:2] = 0
    if not np.isfinite(v).all():
        raise ValueError("keyframe FAP values must be finite")
    v.setflags(write=False)
    return v


@dataclass(frozen=True, eq=False)
class Animation:
    """The animation being authored: keyframes, how they are sampled, and the loaded sequence.

    keys : ((t seconds, (68,) float32 read-only FAP vector), ...) sorted by time, unique times
    fps, interpolation : how :meth:`build` samples the keys ("linear" or "smoothstep")
    sequence : the sequence loaded or built (what Playback plays and exports), or None
    source : the .fap file it was read from ('' when built from keys)
    """

    keys: tuple[tuple[float, np.ndarray], ...] = ()
    fps: float = 25.0
    interpolation: str = "linear"
    sequence: FapSequence | None = None
    source: str = ""

    def __post_init__(self) -> None:
        keys: dict[float, np.ndarray] = {}
        for t, v in self.keys:
            keys[round(float(t), 4)] = _key_vector(v)
        object.__setattr__(self, "keys", tuple(sorted(keys.items(), key=lambda k: k[0])))
        if not 0 < float(self.fps) <= 1000:
            raise ValueError(f"keyframe fps must be in (0, 1000], got {self.fps!r}")
        object.__setattr__(self, "fps", float(self.fps))
        if self.interpolation not in INTERPOLATIONS:
            raise ValueError(f"interpolation must be one of {INTERPOLATIONS}, got "
                             f"{self.interpolation!r}")

    @property
    def empty(self) -> bool:
        return not self.keys and self.sequence is None

    def replace(self, **changes: Any) -> Animation:
        return dataclasses.replace(self, **changes)

    def with_key(self, t: float, vector: object) -> Animation:
        """A copy with a key at ``t`` (replacing one at the same time)."""
        t = round(float(t), 4)
        return self.replace(keys=(*[k for k in self.keys if k[0] != t], (t, vector)))

    def without_key(self, index: int) -> Animation:
        return self.replace(keys=self.keys[:index] + self.keys[index + 1:])

    def build(self, name: str = "keyframes") -> FapSequence:
        """The keys interpolated into a sequence (ValueError without keys)."""
        from editor.formats.keyframes import sequence_from_keyframes

        return sequence_from_keyframes(list(self.keys), self.fps, self.interpolation, name=name)

    def equals(self, other: Animation) -> bool:
        if other is self:
            return True
        return (self.fps == other.fps and self.interpolation == other.interpolation
                and self.source == other.source and self.sequence is other.sequence
                and len(self.keys) == len(other.keys)
                and all(a[0] == b[0] and np.array_equal(a[1], b[1])
                        for a, b in zip(self.keys, other.keys, strict=True)))


NO_ANIMATION = Animation()


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
    embed_photo : bool
        Save the photo's file inside the project (a project that travels alone).
    animation : Animation
        Keyframes and the loaded sequence (undoable and saved like everything else).
    """

    photo: str | None
    vertices: np.ndarray
    faps: np.ndarray
    photo_neutral: bool = False
    embed_photo: bool = False
    animation: Animation = field(default=NO_ANIMATION)

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
        """Same photo, mesh, FAP values and animation (array ``==`` is ambiguous, hence a
        method)."""
        if other is self:
            return True
        return (other is not None and self.photo == other.photo
                and self.photo_neutral == other.photo_neutral
                and self.embed_photo == other.embed_photo
                and self.animation.equals(other.animation)
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
