"""Shared pieces of the command-line modules."""

from __future__ import annotations

import argparse
import functools
import sys
from collections.abc import Callable
from pathlib import Path

from .core.errors import FapStudioError
from .resources import SAMPLE_FACE

Handler = Callable[[argparse.Namespace], int | None]

#: A photo argument of this name (when no such file exists) means the bundled sample face.
SAMPLE_KEYWORD = "sample"
PHOTO_HELP = f"photo (PNG/JPEG/...); '{SAMPLE_KEYWORD}' = the bundled sample face"


def photo_arg(text: str) -> str:
    """argparse ``type`` of photo arguments: ``sample`` -> the bundled sample's path."""
    if text == SAMPLE_KEYWORD and not Path(text).exists():
        return str(SAMPLE_FACE)
    return text


def guarded(handler: Handler) -> Callable[[argparse.Namespace], int]:
    """Wrap a command so that a :class:`FapStudioError` prints one line
    ``fap-studio: error: ...`` on stderr and returns exit code 2 (no traceback)."""

    @functools.wraps(handler)
    def run(args: argparse.Namespace) -> int:
        try:
            return int(handler(args) or 0)
        except FapStudioError as e:
            print(f"fap-studio: error: {e}", file=sys.stderr)
            return 2

    return run
