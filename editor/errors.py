"""Typed errors of FAP Studio's core.

Every failure a user can cause (bad file, no face, malformed FAP data, ...) raises a subclass
of :class:`FapStudioError` with a one-line, human-readable message. The CLI prints that line
and exits with code 2; the GUI shows it in a message box and keeps the document unchanged.
"""

from __future__ import annotations


class FapStudioError(Exception):
    """Base class of all errors FAP Studio reports to a user.

    The message is one line naming the input and what was expected; catching this class
    catches every error below.

    Examples
    --------
    >>> from editor.core import FapStudioError, load_image
    >>> try:
    ...     load_image("no-such-photo.png")
    ... except FapStudioError as e:
    ...     print(type(e).__name__, "-", e)
    ImageError - no-such-photo.png: no such file
    """


class ImageError(FapStudioError):
    """An image file is missing, unreadable, corrupt, not an image, or too large.

    Examples
    --------
    >>> from editor.core import load_image
    >>> load_image("no-such-photo.png")
    Traceback (most recent call last):
    ...
    editor.errors.ImageError: no-such-photo.png: no such file
    """


class NoFaceError(FapStudioError):
    """No face was found in an image.

    Examples
    --------
    >>> import numpy as np
    >>> from editor.core import Face
    >>> Face.from_image(np.zeros((64, 64, 3), np.uint8))
    Traceback (most recent call last):
    ...
    editor.errors.NoFaceError: no face found in the image
    """


class FapFileError(FapStudioError):
    """A .fap file is malformed (the message names the line and what was expected).

    Examples
    --------
    >>> from editor.core import read_fap
    >>> read_fap("2.1 smile 25 1\\n")
    Traceback (most recent call last):
    ...
    editor.errors.FapFileError: <text> line 2: unexpected end of file: ...
    """


class PresetError(FapStudioError):
    """A preset file is malformed, names unknown FAPs, or a preset is used wrongly.

    Examples
    --------
    >>> from editor.core import apply_preset
    >>> apply_preset("joy", 2.0)
    Traceback (most recent call last):
    ...
    editor.errors.PresetError: intensity must be 0-1.5 (0-150 %), got 2.0
    """


class ProjectError(FapStudioError):
    """A project file is malformed or of an unsupported version.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from editor.core import standard_mesh
    >>> from editor.formats.project import load_project
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "broken.fapproj"
    >>> _ = path.write_text("{}")
    >>> load_project(path, standard_mesh().names)
    Traceback (most recent call last):
    ...
    editor.errors.ProjectError: ...broken.fapproj: not a FAP Studio project (no "format": ...)
    """


class StudyError(FapStudioError):
    """A rating-study database is corrupt, foreign, or of an unsupported version.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from editor.study.mos import Study
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "notes.txt"
    >>> _ = path.write_text("hello")
    >>> Study.open(path)
    Traceback (most recent call last):
    ...
    editor.errors.StudyError: ...notes.txt: not an SQLite database, so not a FAP Studio study
    """


class ModelError(FapStudioError):
    """A bilinear model file or its training data is invalid.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from editor.synthesis.bilinear import load_model
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "model.npz"
    >>> _ = path.write_text("hello")
    >>> load_model(path)
    Traceback (most recent call last):
    ...
    editor.errors.ModelError: ...model.npz is not a FAP Studio bilinear model (.npz) file
    """


class CsvFormatError(FapFileError):
    """A Live Link Face or Action Unit CSV file is malformed (row and column named)."""
    """A bilinear model file or its training data is invalid."""


class Cancelled(FapStudioError):
    """The user cancelled a long operation (nothing was changed; not an error to report)."""
