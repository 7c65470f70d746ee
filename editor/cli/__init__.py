"""The ``fap-studio`` command line: one module per command group, registered statically.

:mod:`~editor.cli.main` (``landmarks``, ``mesh``, ``render``, ``gui`` and the parser),
:mod:`~editor.cli.anim` (``animate``, ``fap``), :mod:`~editor.cli.clone` (``clone``, ``track``,
``clone-eval``), :mod:`~editor.cli.study` (``study``), :mod:`~editor.cli.bilinear` (``bilinear``),
shared helpers in :mod:`~editor.cli.util`. ``python -m editor.cli`` runs :func:`main`.
"""

from .main import build_parser, main

__all__ = ["build_parser", "main"]
