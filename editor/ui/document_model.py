"""The editor's single source of truth: the ``DocumentModel`` over immutable ``Document``s.

A :class:`~editor.formats.document.Document` (Qt-free, in :mod:`editor.formats.document`) is a
frozen snapshot (photo path, edited neutral mesh, FAP vector) whose
arrays are read-only, so undo keeps two references per command and a render request needs no
lock. The :class:`DocumentModel` holds the current snapshot, the fitted :class:`Face` of the
photo, and a ``QUndoStack``; every change goes through it and is announced once as
``changed(old, new)``. Gestures (slider or vertex drags) preview freely and push one command on
release.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np
from PySide6.QtCore import QObject, Signal
from PySide6.QtGui import QUndoStack

from editor.engine.faps import FAPS
from editor.engine.mesh import signed_areas
from editor.formats.document import Animation, Document

from .commands import SetDocument

if TYPE_CHECKING:  # the renderer is imported where a photo is opened, after the window shows
    from editor.engine.face import Face


class DocumentModel(QObject):
    """Current document, its face, the undo stack and gestures.

    Signals
    -------
    changed(old, new)
        After every change of the current document (``old`` is None after a load: views
        refresh everything).
    loaded()
        A new photo or project replaced the document (views reset the image and fit).
    pathChanged(str)
        The project file path changed ('' for an unsaved document).
    """

    changed = Signal(object, object)
    loaded = Signal()
    pathChanged = Signal(str)

    def __init__(self, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.undo_stack = QUndoStack(self)
        self._doc: Document | None = None
        self._fitted: Face | None = None
        self._fitted_neutral: Face | None = None
        self._faces: OrderedDict[tuple[int, bool], tuple[np.ndarray, Face]] = OrderedDict()
        self._start: Document | None = None
        self._path: str | None = None

    # ------------------------------------------------------------------ state
    @property
    def doc(self) -> Document | None:
        return self._doc

    @property
    def fitted(self) -> Face | None:
        """The face as detected and fitted (target of *Reset mesh*)."""
        return self._fitted

    @property
    def face(self) -> Face | None:
        """The face for the current (possibly edited) mesh: FAPU and rendering follow it."""
        if self._doc is None:
            return None
        return self.face_for(self._doc.vertices, self._doc.photo_neutral)

    @property
    def base_face(self) -> Face | None:
        """The fitted face as the current document reads the photo: its own expression
        estimated, or (declared neutral) none."""
        if self._doc is None or self._fitted is None:
            return None
        return self._base(self._doc.photo_neutral)

    def _base(self, photo_neutral: bool) -> Face:
        assert self._fitted is not None
        if not photo_neutral:
            return self._fitted
        if self._fitted_neutral is None:
            self._fitted_neutral = self._fitted.with_expression(None)
        return self._fitted_neutral

    @property
    def path(self) -> str | None:
        """Project file of the document, None until it is saved or opened as a project."""
        return self._path

    def set_path(self, path: str | None) -> None:
        self._path = path
        self.pathChanged.emit(path or "")

    def is_dirty(self) -> bool:
        return not self.undo_stack.isClean()

    def mark_clean(self) -> None:
        self.undo_stack.setClean()

    def face_for(self, vertices: np.ndarray, photo_neutral: bool = False) -> Face:
        """A Face for a photo mesh (cached by array identity; arrays are read-only), with the
        photo's own expression or, ``photo_neutral``, declared neutral."""
        assert self._fitted is not None
        key = (id(vertices), photo_neutral)
        hit = self._faces.get(key)
        if hit is not None and hit[0] is vertices:
            self._faces.move_to_end(key)
            return hit[1]
        base = self._base(photo_neutral)
        face = base if np.array_equal(vertices, base.vertices) else base.with_vertices(vertices)
        self._faces[key] = (vertices, face)
        while len(self._faces) > 8:
            self._faces.popitem(last=False)
        return face

    # ------------------------------------------------------------------ loading
    def load(self, face: Face, doc: Document | None = None, path: str | None = None) -> None:
        """Replace the document by a new photo (``doc`` None) or a project's document.

        The undo history is cleared and the new document is clean.
        """
        doc = doc if doc is not None else Document.initial(face)
        if doc.vertices.shape != face.vertices.shape:
            raise ValueError(f"the mesh has {len(doc.vertices)} vertices, expected "
                             f"{len(face.vertices)}")
        self._start = None
        self.undo_stack.clear()
        self._fitted = face
        self._fitted_neutral = None
        self._faces.clear()
        self._doc = doc
        self.undo_stack.setClean()
        self.set_path(path)
        self.loaded.emit()
        self.changed.emit(None, doc)

    def set_document(self, doc: Document) -> None:
        """Show ``doc`` without touching the history (commands and previews use this)."""
        if doc is self._doc:
            return
        old, self._doc = self._doc, doc
        self.changed.emit(old, doc)

    # ------------------------------------------------------------------ history
    def push(self, doc: Document, text: str, key: str | None = None) -> None:
        """Make ``doc`` current as one undo command; commands with the same ``key`` merge."""
        if self._doc is None:
            return
        if self._start is not None:
            self.commit_gesture(text)
        if not doc.equals(self._doc):  # an empty push would still drop the redo branch
            self.undo_stack.push(SetDocument(self, self._doc, doc, text, key))

    def seal(self) -> None:
        """Stop the top command from merging with the next one (end of a key/spin edit)."""
        top = self.undo_stack.command(self.undo_stack.index() - 1)
        if isinstance(top, SetDocument):
            top.committed = True

    @property
    def in_gesture(self) -> bool:
        return self._start is not None

    def begin_gesture(self) -> None:
        """Start a drag: previews follow, and :meth:`commit_gesture` pushes one command."""
        if self._doc is not None and self._start is None:
            self._start = self._doc

    def preview(self, doc: Document) -> None:
        """Show an intermediate state of the running gesture (no history)."""
        if self._start is None:
            self.begin_gesture()
        self.set_document(doc)

    def commit_gesture(self, text: str) -> None:
        """End the gesture with one undo command (none if nothing changed)."""
        start, self._start = self._start, None
        if start is None or self._doc is None or start.equals(self._doc):
            return
        self.undo_stack.push(SetDocument(self, start, self._doc, text))

    def abort_gesture(self) -> None:
        """Cancel the gesture: back to the state before it, no history."""
        start, self._start = self._start, None
        if start is not None:
            self.set_document(start)

    # ------------------------------------------------------------------ edits
    def set_faps(self, values: Mapping[object, float], text: str,
                 key: str | None = None) -> None:
        """Set FAPs (names or numbers -> FAPU) as one command (clamped to the table)."""
        if self._doc is not None:
            self.push(self._doc.with_faps(values), text, key)

    def preview_faps(self, values: Mapping[object, float]) -> None:
        """During a gesture: show FAP values without history."""
        if self._doc is not None:
            self.preview(self._doc.with_faps(values))

    def preview_vertex(self, index: int, xy: tuple[float, float] | np.ndarray) -> None:
        """During a gesture: move one neutral mesh vertex (FAPU and rendering follow)."""
        if self._doc is not None:
            self.preview(self._doc.with_vertex(index, xy))

    def folded_triangles(self) -> int:
        """How many triangles of the current mesh are inside out (0 for a valid mesh)."""
        if self._doc is None or self._fitted is None:
            return 0
        return int((signed_areas(self._doc.vertices, self._fitted.triangles) <= 0).sum())

    def reset_faps(self, numbers: list[int] | None = None, text: str = "Reset all FAPs") -> None:
        """Set the given FAPs (all when None) back to 0 as one command."""
        if self._doc is None:
            return
        nums = range(1, 69) if numbers is None else numbers
        self.push(self._doc.with_faps(dict.fromkeys(nums, 0.0)), text)

    def neutralize(self) -> None:
        """Every FAP to 0 as one command: the neutral face (the photo's own expression gone)."""
        self.reset_faps(None, "Neutralize")

    def restore_photo_expression(self) -> None:
        """The FAPs back to the photo's own expression (the photo unchanged), one command."""
        base = self.base_face
        if self._doc is not None and base is not None:
            self.push(self._doc.with_fap_vector(base.expression), "Back to the photo's expression")

    def set_photo_neutral(self, neutral: bool) -> None:
        """Declare the photo neutral (FAPs then apply to the photo itself) or let its own
        expression be estimated again, as one command. The FAPs keep what they add to the
        photo: declaring subtracts the photo's estimated expression, undeclaring adds it."""
        doc, fitted = self._doc, self._fitted
        if doc is None or fitted is None or doc.photo_neutral == neutral:
            return
        f0 = fitted.expression
        faps = doc.faps - f0 if neutral else doc.faps + f0
        new = doc.replace(photo_neutral=neutral, faps=FAPS.clamp(faps))
        self.push(new, "Declare the photo neutral" if neutral else
                  "Estimate the photo's expression")

    def set_embed_photo(self, embed: bool) -> None:
        """Save the photo inside the project file (or refer to it only), as one command."""
        if self._doc is not None and self._doc.embed_photo != bool(embed):
            self.push(self._doc.replace(embed_photo=bool(embed)),
                      "Embed the photo" if embed else "Refer to the photo")

    def set_animation(self, animation: Animation, text: str) -> None:
        """Replace the animation (keyframes, sequence) as one command."""
        if self._doc is not None:
            self.push(self._doc.replace(animation=animation), text)

    def reset_mesh(self) -> None:
        """Put the mesh back to the fitted one (one command)."""
        if self._doc is not None and self._fitted is not None:
            self.push(self._doc.replace(vertices=self._fitted.vertices), "Reset mesh")
