"""Shared pieces of the command-line modules."""

from __future__ import annotations

import argparse
import functools
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from editor.errors import FapStudioError
from editor.resources import SAMPLE_FACE

Handler = Callable[[argparse.Namespace], int | None]

#: A photo argument of this name (when no such file exists) means the bundled sample face.
SAMPLE_KEYWORD = "sample"
PHOTO_HELP = f"photo (PNG/JPEG/...); '{SAMPLE_KEYWORD}' = the bundled sample face"


def detector_option(parser: argparse.ArgumentParser) -> None:
    """``--detector mediapipe|dlib``: the landmark detector of the command (default mediapipe,
    or ``$FAP_STUDIO_DETECTOR``); :func:`editor.cli.main.main` applies it before running."""
    parser.add_argument("--detector", choices=("mediapipe", "dlib"), default=None,
                        help="landmark detector: mediapipe (default; MediaPipe face mesh, "
                        "Apache-2.0 models shipped inside) or dlib (optional extra: pip install "
                        "'fap-studio[dlib]'; its model's terms exclude commercial use)")


def fast_option(parser: argparse.ArgumentParser) -> None:
    """``--fast``: resample the photo bilinearly, as the editor's live preview does (a still
    is bicubic by default, as ``fap-studio render`` writes it)."""
    parser.add_argument("--fast", action="store_true",
                        help="resample bilinearly as the editor's live preview does (a still is "
                             "bicubic by default, as `fap-studio render` writes it)")


def photo_arg(text: str) -> str:
    """argparse ``type`` of photo arguments: ``sample`` -> the bundled sample's path."""
    if text == SAMPLE_KEYWORD and not Path(text).exists():
        return str(SAMPLE_FACE)
    return text


def image_out_arg(text: str) -> str:
    """argparse ``type`` of image outputs: a suffix no image format has (``out.txt``) is
    refused while the arguments are read, before the photo is loaded and rendered."""
    from editor.engine.imageio import ImageError, check_image_path

    try:
        check_image_path(text)
    except ImageError as e:
        raise argparse.ArgumentTypeError(str(e)) from None
    return text


class ProgressBar:
    """A tqdm bar on stderr driven by ``progress(done, total)`` callbacks (``total`` may grow);
    returns True (never cancels). Shown from the first callback on (an error before any
    progress prints only its one line); disabled by ``quiet``; a context manager that closes it.
    """

    def __init__(self, label: str, unit: str = "frame", quiet: bool = False) -> None:
        self.label, self.unit, self.quiet = label, unit, quiet
        self.bar: Any = None

    def __call__(self, done: int, total: int) -> bool:
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(desc=self.label, unit=self.unit, total=total, disable=self.quiet,
                            file=sys.stderr, dynamic_ncols=True)
        if self.bar.total != total:
            self.bar.total = total
        self.bar.update(done - self.bar.n)
        return True

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()

    def __enter__(self) -> ProgressBar:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


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
