"""Undo commands: every edit is a before/after snapshot of the immutable ``Document``."""

from __future__ import annotations

from typing import TYPE_CHECKING

from PySide6.QtGui import QUndoCommand

if TYPE_CHECKING:
    from .document_model import Document, DocumentModel

#: ``QUndoCommand.id`` of mergeable snapshot commands (the ``key`` decides what merges).
MERGE_ID = 0x46415053


class SetDocument(QUndoCommand):
    """Replace the current document by ``after``; undo puts ``before`` back.

    Commands pushed with the same non-None ``key`` (spin-box steps on one FAP, key presses)
    merge into one entry until :attr:`committed` is set; a command whose ``before`` equals its
    ``after`` is obsolete and never enters the stack.
    """

    def __init__(self, model: DocumentModel, before: Document, after: Document, text: str,
                 key: str | None = None) -> None:
        super().__init__(text)
        self.model = model
        self.before = before
        self.after = after
        self.key = key
        self.committed = key is None
        self.setObsolete(before.equals(after))

    def redo(self) -> None:
        self.model.set_document(self.after)

    def undo(self) -> None:
        self.model.set_document(self.before)

    def id(self) -> int:
        return MERGE_ID if self.key is not None else -1

    def mergeWith(self, other: QUndoCommand) -> bool:  # Qt override
        if (self.committed or not isinstance(other, SetDocument) or other.key != self.key
                or other.model is not self.model):
            return False
        self.after = other.after
        self.committed = other.committed
        self.setObsolete(self.before.equals(self.after))
        # Qt deletes ``other`` now, but PySide keeps its Python wrapper alive (seen in 6.12):
        # drop its documents so that only an empty shell leaks.
        other.before = other.after = None  # type: ignore[assignment]
        other.model = None  # type: ignore[assignment]
        return True
