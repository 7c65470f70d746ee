"""Shared pieces of the command-line modules."""

from __future__ import annotations

import argparse
import functools
import sys
from collections.abc import Callable

from .core.errors import FapStudioError

Handler = Callable[[argparse.Namespace], int | None]


def guarded(handler: Handler) -> Callable[[argparse.Namespace], int]:
    """Wrap a command so that a :class:`FapStudioError` prints one line
    ``fap-studio: error: ...`` on stderr and returns exit code 2 (no traceback)."""

    @functools.wraps(handler)
    def run(args: argparse.Namespace) -> int:
        try:
            return int(handler(args) or 0)
        except FapStudioError as e:
            print(f"fap-studio: error: {' '.join(str(e).split())}", file=sys.stderr)
            return 2

    return run
