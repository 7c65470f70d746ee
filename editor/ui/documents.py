"""Opening, saving and exporting: dialogs, recent files, the unsaved-changes prompt, errors.

Every action catches :class:`FapStudioError` (and, as a last resort, any exception), shows the
one-line message in a message box and leaves the current document as it was. Reading and
fitting a photo, reading a project and exporting run off the GUI thread (:func:`.tasks.run_task`,
a progress dialog with Cancel when they take a while); the result is applied here, on the GUI
thread, through the document model.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from PySide6.QtCore import QObject, Signal
from PySide6.QtWidgets import QFileDialog, QMessageBox, QWidget

from editor.formats.project import SUFFIX, load_project, save_project

from .document_model import Document, DocumentModel
from .qt_utils import run_guarded, settings
from .tasks import Progress, run_task

if TYPE_CHECKING:
    from editor.engine.face import Face

# The renderer (editor.engine.face, OpenCV) is imported by the tasks that need it, on the thread
# pool: the window is up before it is loaded (issue 15, gui_ready_s).


def _face_from_image(path: str) -> Face:
    """``Face.from_image(path)`` (detect, fit), the renderer imported on first use."""
    from editor.engine.face import Face

    return Face.from_image(path)

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
        #: Ask the user (where is the photo of a project?); headless runs turn this off.
        self.interactive = True
        #: Exported images with the skin folds (View > Skin Creases, as the preview shows)
        self.creases = True

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
                   photo_neutral: bool = False, remember: bool = True) -> bool:
        """Open a photo (file dialog when ``path`` is None): detect, fit, new document;
        ``photo_neutral`` declares the photo neutral (Edit > Photo Is Neutral); ``remember``
        False keeps it out of Open Recent (the bundled sample face)."""
        if path is None:
            path, _ = QFileDialog.getOpenFileName(self.widget, "Open photo", self._dir(),
                                                  PHOTO_FILTER)
            if not path:
                return False
        if ask and not self.maybe_save():
            return False
        path = str(Path(path).resolve())

        def fit(_progress: Progress) -> Face:
            return _face_from_image(path)

        def load() -> None:
            face = run_task(self.widget, f"Opening {Path(path).name}: finding the face…", fit,
                            title="Open Photo")
            # the animation (FAP values, face-independent) comes along to the new photo
            anim = self.model.doc.animation if self.model.doc is not None else None
            doc = Document.initial(face, photo_neutral)
            self.model.load(face, doc if anim is None else doc.replace(animation=anim))

        ok = self.guarded("Cannot open the photo", load)
        if ok and remember:
            self.add_recent(path)
        return ok

    def open_project(self, path: str | None = None, ask: bool = True) -> bool:
        """Open a project file (file dialog when ``path`` is None). A photo found at neither
        its relative nor its absolute path (nor embedded) is asked for."""
        if path is None:
            path, _ = QFileDialog.getOpenFileName(self.widget, "Open project", self._dir(),
                                                  PROJECT_FILTER)
            if not path:
                return False
        if ask and not self.maybe_save():
            return False
        from editor.engine.mesh import standard_mesh

        names = standard_mesh().names
        data = None

        def read() -> None:
            nonlocal data
            data = run_task(self.widget, f"Reading {Path(path).name}…",
                            lambda _p: load_project(path, names), title="Open Project")

        if not self.guarded("Cannot open the project", read) or data is None:
            return False
        photo = data.photo
        moved = False
        if not data.photo_found:
            located = self.locate_photo(photo, path)
            if located is None:
                return False
            photo, moved = str(Path(located).resolve()), True

        def load() -> None:
            face = run_task(self.widget, f"Opening {Path(photo).name}: finding the face…",
                            lambda _p: _face_from_image(photo), title="Open Project")
            verts = face.vertices if data.vertices is None else data.vertices
            doc = Document(photo, verts, face.fap_vector(data.faps), data.photo_neutral,
                           data.embed_photo, data.animation)
            self.model.load(face, doc, str(Path(path).resolve()))
            if moved:  # the project now points elsewhere: saving it is a change
                self.model.undo_stack.resetClean()

        ok = self.guarded("Cannot open the project", load)
        if ok:
            self.add_recent(path)
            if self.remember:
                settings().setValue("lastProject", str(Path(path).resolve()))
        return ok

    def locate_photo(self, missing: str, project: str) -> str | None:
        """Ask where the photo of ``project`` is (it is not at ``missing``); None if the user
        gives up (or nobody can be asked)."""
        if not self.interactive:
            self.error("Cannot open the project",
                       f"{project}: its photo {missing} was not found")
            return None
        ans = QMessageBox.question(
            self.widget, "Locate the photo",
            f"The photo of {Path(project).name} was not found:\n{missing}\n\n"
            "Do you want to locate it?",
            QMessageBox.StandardButton.Open | QMessageBox.StandardButton.Cancel,
            QMessageBox.StandardButton.Open)
        if ans != QMessageBox.StandardButton.Open:
            return None
        start = str(Path(project).parent / Path(missing).name)
        found, _ = QFileDialog.getOpenFileName(self.widget, f"Locate {Path(missing).name}",
                                               start, PHOTO_FILTER)
        return found or None

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
            run_task(self.widget, f"Saving {Path(path).name}…",
                     lambda _p: save_project(path, photo, doc.vertices, doc.faps,
                                             face.mesh.names, doc.photo_neutral,
                                             embed=doc.embed_photo, animation=doc.animation),
                     title="Save Project", cancellable=False)

        ok = self.guarded("Cannot save the project", write)
        if ok:
            full = str(Path(path).resolve())
            self.model.mark_clean()
            self.model.set_path(full)
            self.add_recent(full)
            if self.remember:
                settings().setValue("lastProject", full)
            self.status(f"Saved project {full}")
        return ok

    def export(self, path: str | None = None) -> bool:
        """Export the rendered image (PNG or JPEG by the suffix; dialog when ``path`` is None):
        the preview's expression and skin-fold setting, resampled bicubically (the preview's
        bilinear warp softens the skin that moves; a still is rendered once)."""
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
        face, faps, creases = self.model.face, self.model.doc.faps, self.creases
        out = path
        from editor.engine.imageio import save_image

        ok = self.guarded("Cannot export the image", lambda: run_task(
            self.widget, f"Exporting {Path(out).name}…",
            lambda _p: save_image(out, face.render(faps, creases=creases, sharp=True)),
            title="Export Image", cancellable=False))
        if ok:
            self.status(f"Exported {out}")
        return ok

    def status(self, message: str, ms: int = 8000) -> None:
        """A message in the window's status bar (when there is one)."""
        bar = getattr(self.widget, "statusBar", None)
        if callable(bar):
            bar().showMessage(message, ms)

    def maybe_save(self) -> bool:
        """Ask to save unsaved changes. False if the user cancels (or saving fails)."""
        if not self.model.is_dirty():
            return True
        doc = self.model.doc
        name = (Path(self.model.path).name if self.model.path else
                f"the document of {Path(doc.photo).name}" if doc is not None and doc.photo
                else "the document")
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
