"""MOS rating studies in the editor: the "Study" menu (new / open / rate / results).

``install(window)`` adds the menu and returns the :class:`MosPanel` controller. The rating
session (:mod:`editor.ui.mos_rating`) and the results (:mod:`editor.ui.mos_results`) open in
their own top-level windows; the study data lives in one SQLite file per study
(:mod:`editor.study.mos`), so nothing here needs saving.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from PySide6.QtCore import QObject, Qt
from PySide6.QtGui import QAction
from PySide6.QtWidgets import QFileDialog, QMainWindow, QWidget

from .qt_utils import run_guarded, settings
from .tasks import Progress, run_task

if TYPE_CHECKING:
    from .mos_new import NewStudyDialog
    from .mos_rating import RatingWindow
    from .mos_results import ResultsWindow

# The study store, the dialogs and the results (statistics, plots, the stimulus renderer) are
# imported by the actions that open them: the menu is all the editor window needs at start
# (issue 15, gui_ready_s).

STUDY_FILTER = "FAP Studio study (*.db);;All files (*)"
_LAST = "mos/lastStudy"


class MosPanel(QObject):
    """Owns the Study menu actions, the current study path and the windows it opened."""

    def __init__(self, window: QMainWindow) -> None:
        super().__init__(window)
        self.window = window
        self.path: Path | None = None
        self.windows: list[QWidget] = []
        last = settings().value(_LAST, "")
        if last and Path(str(last)).is_file():
            self.path = Path(str(last))
        menu = window.menu("&Study")  # type: ignore[attr-defined]
        self.act_new = self._action(menu, "&New Study from Faces…", self.new_study,
                                    "Render faces × presets × intensities into a new MOS "
                                    "rating study")
        self.act_open = self._action(menu, "&Open Study…", self.open_study,
                                     "Choose the study to rate or to see the results of")
        menu.addSeparator()
        self.act_rate = self._action(menu, "&Rate…", self.rate)
        self.act_results = self._action(menu, "Re&sults…", self.results,
                                        "Recognition, naturalness, agreement and rater "
                                        "screening of the study")
        self._update()

    def _action(self, menu: object, text: str, slot: Callable[[], object],
                tip: str = "") -> QAction:
        a = QAction(text, self.window)
        a.setStatusTip(tip)
        a.triggered.connect(lambda _=False: slot())
        menu.addAction(a)  # type: ignore[attr-defined]
        return a

    def _update(self) -> None:
        for a in (self.act_rate, self.act_results):
            a.setEnabled(self.path is not None)
        name = self.path.name if self.path else "no study open"
        self.act_rate.setStatusTip(f"Rate the study {name}")

    def guarded(self, title: str, action: Callable[[], object]) -> object | None:
        """Run ``action`` with a wait cursor; errors become a one-line message box."""
        return run_guarded(self.window, title, action, busy=True)[1]

    def set_study(self, path: str | Path) -> bool:
        """Check that ``path`` is a study (message box if not) and make it the current one."""
        def check() -> Path:
            from editor.study.mos import Study

            Study.open(path).close()
            return Path(path)

        ok = self.guarded("Cannot open the study", check)
        if ok is None:
            return False
        self.path = Path(path)
        settings().setValue(_LAST, str(self.path))
        self._update()
        return True

    # ------------------------------------------------------------------ actions
    def current_photo(self) -> str | None:
        doc = getattr(getattr(self.window, "model", None), "doc", None)
        photo = getattr(doc, "photo", None)
        return str(photo) if photo else None

    def new_study(self, dialog: NewStudyDialog | None = None) -> Path | None:
        """Ask for faces × presets × intensities, render them and create the study."""
        from .mos_new import NewStudyDialog

        photo = self.current_photo()
        dialog = dialog or NewStudyDialog([photo] if photo else [], self.window)
        # a failure after OK (a photo without a face, an unwritable file) reopens the same
        # dialog, its input kept
        while dialog.exec() == NewStudyDialog.DialogCode.Accepted:
            path = self.create_study(dialog)
            if path is not None:
                return path
        return None

    def create_study(self, dialog: NewStudyDialog) -> Path | None:
        """Render the stimuli and write the study off the GUI thread (progress, Cancel)."""
        got = self.guarded("Cannot create the study", dialog.values)
        if got is None:
            return None
        faces, presets, ks, name, path, every, revise = got  # type: ignore[misc]

        def make(progress: Progress) -> Path:
            from editor.study.stimuli import create_from_renders, render_stimuli

            renders = render_stimuli(faces, presets, ks, progress=lambda d, t: progress(
                d, t, f"Rendering the stimuli: {d} of {t}…"))
            progress.check()
            create_from_renders(path, name, presets, renders, revise, every).close()
            return path

        made = self.guarded("Cannot create the study", lambda: run_task(
            self.window, f"Creating the study {path.name}…", make, title="New Study"))
        if isinstance(made, Path) and self.set_study(made):
            self.window.statusBar().showMessage(f"Created study {made.name}", 5000)
            return made
        return None

    def open_study(self, path: str | None = None) -> bool:
        if not path:
            start = str(self.path.parent) if self.path else ""
            path, _ = QFileDialog.getOpenFileName(self.window, "Open study", start, STUDY_FILTER)
        return bool(path) and self.set_study(path)

    def rate(self, rater: str | None = None, seed: int | None = None) -> RatingWindow | None:
        """Ask for the rater id and open the rating window (resumes a known rater)."""
        from .mos_rating import RatingWindow, ask_rater

        if self.path is None and not self.open_study():
            return None
        rater = rater or ask_rater(self.window)
        if not rater:
            return None
        path = self.path
        win = self.guarded("Cannot start the rating session",
                           lambda: RatingWindow(str(path), rater, seed))
        if not isinstance(win, RatingWindow):
            return None
        self._keep(win)
        return win

    def results(self) -> ResultsWindow | None:
        from .mos_results import ResultsWindow

        if self.path is None and not self.open_study():
            return None
        path = self.path
        win = self.guarded("Cannot show the results", lambda: ResultsWindow(path))
        if not isinstance(win, ResultsWindow):
            return None
        self._keep(win)
        return win

    def _keep(self, win: QWidget) -> None:
        win.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
        self.windows.append(win)
        win.destroyed.connect(lambda _=None, w=win: self.windows.remove(w)
                              if w in self.windows else None)
        win.show()
        win.raise_()
        win.activateWindow()


def install(window: QMainWindow) -> MosPanel:
    """Add the Study menu to the editor window (called by ``MainWindow``)."""
    return MosPanel(window)
