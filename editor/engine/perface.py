"""One cache of a per-face result for the face's lifetime. No Qt."""

from __future__ import annotations

import functools
import weakref
from collections.abc import Callable
from typing import TypeVar

F = TypeVar("F")
R = TypeVar("R")


def per_face(build: Callable[[F], R]) -> Callable[[F], R]:
    """``build(face)`` computed once per face and kept while the face lives (a result of
    None too: a face without the plan is not asked again)."""
    cache: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
    missing = object()

    @functools.wraps(build)
    def get(face: F) -> R:
        got = cache.get(face, missing)
        if got is missing:
            got = build(face)
            cache[face] = got
        return got

    return get
