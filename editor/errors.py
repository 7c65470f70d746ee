"""Typed errors of FAP Studio's core.

Every failure a user can cause (bad file, no face, malformed FAP data, ...) raises a subclass
of :class:`FapStudioError` with a one-line, human-readable message. The CLI prints that line
and exits with code 2; the GUI shows it in a message box and keeps the document unchanged.
"""

from __future__ import annotations


class FapStudioError(Exception):
    """Base class of all errors FAP Studio reports to a user."""


class ImageError(FapStudioError):
    """An image file is missing, unreadable, corrupt, not an image, or too large."""


class NoFaceError(FapStudioError):
    """No face was found in an image."""


class FapFileError(FapStudioError):
    """A .fap file is malformed (the message names the line and what was expected)."""


class PresetError(FapStudioError):
    """A preset file is malformed or names unknown FAPs."""


class ProjectError(FapStudioError):
    """A project file is malformed or of an unsupported version."""


class StudyError(FapStudioError):
    """A rating-study database is corrupt, foreign, or of an unsupported version."""


class ModelError(FapStudioError):
    """A bilinear model file or its training data is invalid."""


class Cancelled(FapStudioError):
    """The user cancelled a long operation (nothing was changed; not an error to report)."""
