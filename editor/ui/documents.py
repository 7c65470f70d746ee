"""Opening, saving and exporting: dialogs, recent files, the unsaved-changes prompt, errors.

Every action catches :class:`FapStudioError` (and, as a last resort, any exception), shows the
one-line message in a message box and leaves the current document as it was.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from PySide6.QtCore import QObject, Signal
from PySide6.QtWidgets import QFileDialog, QMessageBox, QWidget

from editor.engine.face import Face
from editor.engine.imageio import save_image
from editor.formats.project import SUFFIX, load_project, save_project

from .document_model import Document, DocumentModel
from .qt_utils import run_guarded, settings

PHOTO_FILTER = "Photos (*.png *.jpg *.jpeg *.bmp *.tif *.tiff *.webp);;All files (*)"
PROJECT_FILTER = f"FAP Studio projects (*{SUFFIX} *.json);;All files (*)"
EXPORT_FILTER = "PNG image (*.png);;JPEG image (*.jpg *.jpeg)"
PROJECT_SUFFIXES = (SUFFIX, ".json")
MAX_RECENT = 10


def is_project(path: str | Path) -> bool:
    return Path(path).suffix.lower() in PROJECT_SUFFIXES


class Documents(QObject):
    """File actions of the main window, on its :class:`DocumentModel`.

    Signals
    -------
    recentChanged()
        The recent-files list in QSettings changed.
    """

    recentChanged = Signal()

    def __init__(self, parent: QWidget, model: DocumentModel) -> None:
        super().__init__(parent)
        self.widget = parent
        self.model = model
        #: Record opened/saved files in QSettings (recent files, last project); headless
        #: screenshots turn this off.
        self.remember = True

    # ------------------------------------------------------------------ error handling
    def guarded(self, title: str, action: Callable[[], object]) -> bool:
        """Run ``action`` (wait cursor); on any error show a message box. True if it succeeded."""
        return run_guarded(self.widget, title, action, busy=True,
                           report=lambda t, m: self.error(t, m))[0]

    def error(self, title: str, message: str) -> None:
        QMessageBox.warning(self.widget, title, message)

    # ------------------------------------------------------------------ opening
    def open_path(self, path: str) -> bool:
        """Open a photo or (by its suffix) a project, after the unsaved-changes prompt."""
        return self.open_project(path) if is_project(path) else self.open_photo(path)

    def open_photo(self, path: str | None = None, ask: bool = True,
                   photo_neutral: bool = False) -> bool:
        """Open a photo (file dialog when ``path`` is None): detect, fit, new document;
        ``photo_neutral`` declares the photo neutral (Edit > Photo Is Neutral)."""
        if path is None:
            path, _ = QFileDialog.getOpenFileName(self.widget, "Open photo", self._dir(),
                                                  PHOTO_FILTER)
            if not path:
                return False
        if ask and not self.maybe_save():
            return False
        path = str(Path(path).resolve())

        def load() -> None:
            face = Face.from_image(path)
            self.model.load(face, Document.initial(face, photo_neutral))

        ok = self.guarded("Cannot open the photo", load)
        if ok:
            self.add_recent(path)
        return ok

    def open_project(self, path: str | None = None, ask: bool = True) -> bool:
        """Open a project file (file dialog when ``path`` is None)."""
        if path is None:
            path, _ = QFileDialog.getOpenFileName(self.widget, "Open project", self._dir(),
                                                  PROJECT_FILTER)
            if not path:
                return False
        if ask and not self.maybe_save():
            return False

        def load() -> None:
            from editor.engine.mesh import standard_mesh

            data = load_project(path, standard_mesh().names)
            face = Face.from_image(data.photo)
            verts = face.vertices if data.vertices is None else data.vertices
            doc = Document(data.photo, verts, face.fap_vector(data.faps), data.photo_neutral)
            self.model.load(face, doc, str(Path(path).resolve()))

        ok = self.guarded("Cannot open the project", load)
        if ok:
            self.add_recent(path)
            if self.remember:
                settings().setValue("lastProject", str(Path(path).resolve()))
        return ok

    # ------------------------------------------------------------------ saving
    def save(self) -> bool:
        """Save to the project's file, or ask for one. True if saved."""
        if self.model.path is None:
            return self.save_as()
        return self.save_to(self.model.path)

    def save_as(self) -> bool:
        if self.model.doc is None:
            return False
        start = self.model.path or str(Path(self._dir()) / (self._stem() + SUFFIX))
        path, _ = QFileDialog.getSaveFileName(self.widget, "Save project", start,
                                              PROJECT_FILTER)
        if not path:
            return False
        if not is_project(path):
            path += SUFFIX
        return self.save_to(path)

    def save_to(self, path: str) -> bool:
        """Write the project file; the document becomes clean. True if saved."""
        doc, face = self.model.doc, self.model.fitted
        if doc is None or face is None:
            return False
        photo = doc.photo
        if photo is None:
            self.error("Cannot save the project", "the photo has no file to refer to")
            return False

        def write() -> None:
            save_project(path, photo, doc.vertices, doc.faps, face.mesh.names,
                         doc.photo_neutral)

        ok = self.guarded("Cannot save the project", write)
        if ok:
            full = str(Path(path).resolve())
            self.model.mark_clean()
            self.model.set_path(full)
            self.add_recent(full)
            if self.remember:
                settings().setValue("lastProject", full)
        return ok

    def export(self, path: str | None = None) -> bool:
        """Export the rendered image (PNG or JPEG by the suffix; dialog when ``path`` is None)."""
        if self.model.doc is None or self.model.face is None:
            return False
        if path is None:
            start = str(Path(self._dir()) / (self._stem() + "_fap.png"))
            path, chosen = QFileDialog.getSaveFileName(self.widget, "Export image", start,
                                                       EXPORT_FILTER)
            if not path:
                return False
            if Path(path).suffix.lower() not in (".png", ".jpg", ".jpeg"):
                path += ".jpg" if chosen.startswith("JPEG") else ".png"
        face, faps = self.model.face, self.model.doc.faps
        out = path
        return self.guarded("Cannot export the image",
                            lambda: save_image(out, face.render(faps)))

    def maybe_save(self) -> bool:
        """Ask to save unsaved changes. False if the user cancels (or saving fails)."""
        if not self.model.is_dirty():
            return True
        name = Path(self.model.path).name if self.model.path else "the document"
        ans = QMessageBox.question(
            self.widget, "Unsaved changes", f"Save the changes to {name}?",
            QMessageBox.StandardButton.Save | QMessageBox.StandardButton.Discard
            | QMessageBox.StandardButton.Cancel, QMessageBox.StandardButton.Save)
        if ans == QMessageBox.StandardButton.Save:
            return self.save()
        return ans == QMessageBox.StandardButton.Discard

    # ------------------------------------------------------------------ recent files
    def recent(self) -> list[str]:
        value = settings().value("recentFiles", [], type=list)
        return [str(v) for v in value if v]

    def add_recent(self, path: str) -> None:
        if not self.remember:
            return
        full = str(Path(path).resolve())
        items = [full] + [p for p in self.recent() if p != full]
        settings().setValue("recentFiles", items[:MAX_RECENT])
        self.recentChanged.emit()

    def clear_recent(self) -> None:
        settings().setValue("recentFiles", [])
        self.recentChanged.emit()

    # ------------------------------------------------------------------ helpers
    def _dir(self) -> str:
        rec = self.recent()
        return str(Path(rec[0]).parent) if rec else str(Path.cwd())

    def _stem(self) -> str:
        doc = self.model.doc
        if self.model.path:
            return Path(self.model.path).stem
        return Path(doc.photo).stem if doc is not None and doc.photo else "untitled"
