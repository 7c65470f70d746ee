"""The editor window: canvas in the middle, FAP panel and gaze pad docked on the right.

Wiring (one way): widgets -> :class:`DocumentModel` -> ``changed(old, new)`` -> views; every
change submits the current face + FAP vector to the latest-only :class:`RenderScheduler`, whose
frames go to the preview and whose timing goes to the status bar.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from PySide6.QtCore import QByteArray, Qt
from PySide6.QtGui import (
    QAction,
    QCloseEvent,
    QDragEnterEvent,
    QDropEvent,
    QKeySequence,
)
from PySide6.QtWidgets import (
    QDockWidget,
    QLabel,
    QMainWindow,
    QMenu,
    QToolBar,
    QVBoxLayout,
    QWidget,
)

from .canvas import Canvas
from .document_model import Document, DocumentModel
from .documents import Documents
from .fap_panel import FapPanel
from .gaze_pad import GazePad
from .help_panel import AboutDialog, FirstRunHint, HelpPanel
from .qt_utils import settings
from .render_scheduler import RenderResult, RenderScheduler
from .tasks import cancel_all

if TYPE_CHECKING:  # the renderer (editor.engine.face, OpenCV) is imported when a photo is opened,
    # on the thread pool after the window is shown (issue 15, gui_ready_s)
    from editor.engine.face import Face

FAPU_SHOWN = ("MNS", "MW", "ENS", "ES", "IRISD")

#: Optional panels: modules of ``editor.ui`` with ``install(window) -> None``. Each adds its own
#: docks, menus and actions (``window.add_panel_dock``, ``window.menu(title)``), so panels are
#: developed and tested independently of this file. A module that is missing is skipped.
EXTENSIONS = ("presets_panel", "playback_panel", "au_panel", "mos_panel", "model_panel",
              "detector_menu")

#: The smallest window in which every dock's controls still fit.
MINIMUM_SIZE = (960, 640)


class MainWindow(QMainWindow):
    """FAP Studio's main window."""

    def __init__(self, model: DocumentModel | None = None,
                 scheduler: RenderScheduler | None = None,
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.model = model or DocumentModel(self)
        self.scheduler = scheduler or RenderScheduler(parent=self)
        self.docs = Documents(self, self.model)
        self.canvas = Canvas(self.model)
        self.hint = FirstRunHint()
        central = QWidget()
        lay = QVBoxLayout(central)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.setSpacing(0)
        lay.addWidget(self.hint)
        lay.addWidget(self.canvas, 1)
        self.setCentralWidget(central)
        self.fap_panel = FapPanel(self.model)
        self.gaze_pad = GazePad(self.model)
        self.fap_dock = self._dock("FAPs", self.fap_panel, "fapDock")
        self.gaze_dock = self._dock("Eye gaze", self.gaze_pad, "gazeDock")
        self.splitDockWidget(self.fap_dock, self.gaze_dock, Qt.Orientation.Vertical)
        self.resizeDocks([self.fap_dock], [470], Qt.Orientation.Horizontal)
        self.resizeDocks([self.fap_dock, self.gaze_dock], [640, 190], Qt.Orientation.Vertical)

        self.render_label = QLabel("render – ms")
        self.expression_label = QLabel("")
        self.expression_label.setToolTip(
            "The expression the photo already shows, estimated against a neutral face. FAPs "
            "apply to the neutralised face; the sliders start at the photo's own expression.")
        self.statusBar().addPermanentWidget(self.expression_label)
        self.fapu_label = QLabel("")
        self.statusBar().addPermanentWidget(self.fapu_label)
        self.statusBar().addPermanentWidget(self.render_label)
        self.last_result: RenderResult | None = None
        self._closing_ok = False

        self._make_actions()
        self._make_menus()
        self._install_extensions()
        self._finish_layout()
        self.setAcceptDrops(True)
        self.setMinimumSize(*MINIMUM_SIZE)
        self.resize(1400, 860)

        m = self.model
        m.loaded.connect(self.scheduler.cancel)
        m.changed.connect(self._on_changed)
        m.pathChanged.connect(self._update_title)
        m.undo_stack.cleanChanged.connect(self._update_title)
        m.undo_stack.indexChanged.connect(lambda i: self.hint.done() if i > 0 else None)
        self.docs.recentChanged.connect(self._fill_recent)
        self.scheduler.resultReady.connect(self._on_result)
        self.scheduler.failed.connect(self._on_render_failed)
        self._update_title()
        if m.doc is not None:
            self._on_changed(None, m.doc)

    # ------------------------------------------------------------------ construction
    def _dock(self, title: str, widget: QWidget, name: str) -> QDockWidget:
        dock = QDockWidget(title, self)
        dock.setObjectName(name)
        dock.setWidget(widget)
        dock.setFeatures(QDockWidget.DockWidgetFeature.DockWidgetMovable
                         | QDockWidget.DockWidgetFeature.DockWidgetFloatable
                         | QDockWidget.DockWidgetFeature.DockWidgetClosable)
        self.addDockWidget(Qt.DockWidgetArea.RightDockWidgetArea, dock)
        return dock

    def _action(self, text: str, slot: object, shortcut: str | QKeySequence.StandardKey |
                None = None, tip: str = "") -> QAction:
        a = QAction(text, self)
        if shortcut is not None:
            a.setShortcut(QKeySequence(shortcut))
        if tip:
            a.setStatusTip(tip)
        a.triggered.connect(slot)
        self.addAction(a)
        return a

    def _make_actions(self) -> None:
        d = self.docs
        self.act_open = self._action("&Open Photo…", lambda: d.open_photo(),
                                     QKeySequence.StandardKey.Open, "Open a neutral frontal photo")
        self.act_open_project = self._action("Open &Project…", lambda: d.open_project(),
                                             "Ctrl+Shift+O", "Open a FAP Studio project "
                                             "(.fapproj): photo, mesh, FAPs and animation")
        self.act_save = self._action("&Save Project", d.save, QKeySequence.StandardKey.Save,
                                     "Save the photo reference, mesh, FAPs and animation")
        self.act_save_as = self._action("Save Project &As…", d.save_as, "Ctrl+Shift+S",
                                        "Save the project under another name")
        self.act_embed = self._action(
            "Embed Photo in Project", self.model.set_embed_photo, tip=(
                "Save the photo itself inside the project file, so that the project opens "
                "anywhere (the file grows by the photo's size)"))
        self.act_embed.setCheckable(True)
        self.act_export = self._action("&Export Image…", lambda: d.export(), "Ctrl+E",
                                       "Save the rendered expression as PNG or JPEG")
        self.act_quit = self._action("&Quit", self.close, QKeySequence.StandardKey.Quit,
                                     "Quit FAP Studio (asks to save unsaved changes)")
        stack = self.model.undo_stack
        self.act_undo = stack.createUndoAction(self, "&Undo")
        self.act_undo.setShortcut(QKeySequence("Ctrl+Z"))
        self.act_undo.setStatusTip("Undo the last change (every slider drag is one step)")
        self.act_redo = stack.createRedoAction(self, "&Redo")
        self.act_redo.setShortcuts([QKeySequence("Ctrl+Shift+Z"), QKeySequence("Ctrl+Y")])
        self.act_redo.setStatusTip("Redo the change undone last")
        self.addActions([self.act_undo, self.act_redo])
        self.act_reset_faps = self._action(
            "Reset All &FAPs", lambda: self.model.reset_faps(None, "Reset all FAPs"),
            tip="Every FAP back to 0 (the neutralised face)")
        self.act_neutralize = self._action(
            "&Neutralize", self.model.neutralize, "Ctrl+Shift+N",
            "Remove the photo's own expression: every FAP to 0 (the neutral face)")
        self.act_photo_expression = self._action(
            "Back to the &Photo's Expression", self.model.restore_photo_expression,
            "Ctrl+Shift+P", "Set the FAPs to what the photo shows (the photo unchanged)")
        self.act_photo_neutral = self._action(
            "Photo Is Ne&utral", self.model.set_photo_neutral, tip=(
                "Declare the photo neutral: FAPs apply to the photo as it is (its own "
                "expression is not estimated or removed)"))
        self.act_photo_neutral.setCheckable(True)
        self.act_reset_mesh = self._action("Reset &Mesh", self.model.reset_mesh,
                                           tip="Put every vertex back where it was fitted")
        self.act_overlay = self._action("Show &Mesh", self.canvas.set_overlay_visible, "M",
                                        "Show or hide the fitted mesh over the photo")
        self.act_overlay.setCheckable(True)
        self.act_overlay.setChecked(True)
        self.act_creases = self._action("Skin &Creases", self._set_creases, tip=(
            "Darken the skin folds the expression compresses (nasolabial, crow's feet, "
            "forehead, glabella, nose)"))
        self.act_creases.setCheckable(True)
        self.act_creases.setChecked(True)
        self.act_fit = self._action("&Fit to View", self.canvas.fit, "F",
                                    "Show the whole photo")
        self.act_fit_face = self._action("Zoom to F&ace", self.canvas.fit_face, "Shift+F",
                                         "Zoom onto the face")
        self.act_about = self._action("&About FAP Studio", self._about,
                                      tip="Versions and the licences of every component")
        self.act_help = self._action("FAP Studio &Help", self.show_help, "F1",
                                     "Show the help panel: what to do first, every shortcut")
        self.act_reset_layout = self._action(
            "&Reset Layout", self.reset_layout,
            tip="Show every panel again where it was at the first start")

    def _make_menus(self) -> None:
        mb = self.menuBar()
        f = mb.addMenu("&File")
        f.addActions([self.act_open, self.act_open_project])
        self.recent_menu = f.addMenu("Open &Recent")
        f.addSeparator()
        f.addActions([self.act_save, self.act_save_as, self.act_embed, self.act_export])
        f.addSeparator()
        f.addAction(self.act_quit)
        e = mb.addMenu("&Edit")
        e.addActions([self.act_undo, self.act_redo])
        e.addSeparator()
        e.addActions([self.act_neutralize, self.act_photo_expression, self.act_photo_neutral,
                      self.act_reset_faps, self.act_reset_mesh])
        v = mb.addMenu("&View")
        v.addActions([self.act_overlay, self.act_creases, self.act_fit, self.act_fit_face])
        v.addSeparator()
        v.addAction(self.act_reset_layout)
        v.addSeparator()
        v.addActions([self._view_action(self.fap_dock), self._view_action(self.gaze_dock)])
        h = mb.addMenu("&Help")
        h.addActions([self.act_help, self.act_about])
        self._fill_recent()

    def _view_action(self, dock: QDockWidget) -> QAction:
        a = dock.toggleViewAction()
        a.setStatusTip(f"Show or hide the {dock.windowTitle()} panel")
        return a

    def _finish_layout(self) -> None:
        """After every panel is in: the help dock, the toolbar, the Presets tab in front,
        and this arrangement kept for View > Reset Layout."""
        self.help_panel = HelpPanel(self)
        self.help_dock = self._dock("Help", self.help_panel, "helpDock")
        self.removeDockWidget(self.help_dock)
        self.addDockWidget(Qt.DockWidgetArea.LeftDockWidgetArea, self.help_dock)
        self.help_dock.hide()
        self.menu("&View").addAction(self._view_action(self.help_dock))
        tb = QToolBar("Main toolbar", self)
        tb.setObjectName("mainToolBar")
        tb.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextOnly)
        tb.addActions([self.act_open, self.act_open_project, self.act_save, self.act_export])
        tb.addSeparator()
        tb.addActions([self.act_undo, self.act_redo])
        tb.addSeparator()
        tb.addActions([self.act_neutralize, self.act_fit, self.act_fit_face])
        play = getattr(getattr(self, "playback_panel", None), "act_play", None)
        if play is not None:
            tb.addSeparator()
            tb.addAction(play)
        tb.addSeparator()
        tb.addAction(self.act_help)
        self.addToolBar(Qt.ToolBarArea.TopToolBarArea, tb)
        self.toolbar = tb
        presets = getattr(self, "presets_dock", None)
        if presets is not None:
            presets.raise_()
        self._default_state = self.saveState()

    def reset_layout(self) -> None:
        """View > Reset Layout: every panel back where it was at the first start."""
        self.restoreState(self._default_state)
        for dock in self.findChildren(QDockWidget):
            if dock is not self.help_dock:
                dock.show()
        presets = getattr(self, "presets_dock", None)
        if presets is not None:
            presets.raise_()

    def show_help(self) -> None:
        """F1: the help panel (rebuilt: extensions may have added actions)."""
        self.help_panel.refresh()
        was_hidden = self.help_dock.isHidden()
        self.help_dock.show()
        self.help_dock.raise_()
        if was_hidden and not self.help_dock.isFloating():
            self.resizeDocks([self.help_dock], [420], Qt.Orientation.Horizontal)

    def menu(self, title: str) -> QMenu:
        """The top-level menu titled ``title`` (e.g. "&Tools"), created before Help if needed."""
        mb = self.menuBar()
        for a in mb.actions():
            if a.menu() is not None and a.text().replace("&", "") == title.replace("&", ""):
                return a.menu()
        help_action = mb.actions()[-1] if mb.actions() else None
        m = QMenu(title, self)
        mb.insertMenu(help_action, m) if help_action else mb.addMenu(m)
        return m

    def add_panel_dock(self, title: str, widget: QWidget, name: str,
                       area: Qt.DockWidgetArea = Qt.DockWidgetArea.RightDockWidgetArea
                       ) -> QDockWidget:
        """Add an extension's dock (tabbed with the gaze pad on the right by default); its
        show/hide action goes into the View menu."""
        dock = self._dock(title, widget, name)
        if area == Qt.DockWidgetArea.RightDockWidgetArea:
            self.tabifyDockWidget(self.gaze_dock, dock)
            self.gaze_dock.raise_()
        else:
            self.addDockWidget(area, dock)
        self.menu("&View").addAction(self._view_action(dock))
        return dock

    def _install_extensions(self) -> None:
        import importlib

        self.extensions: dict[str, object] = {}
        for name in EXTENSIONS:
            try:
                mod = importlib.import_module(f"editor.ui.{name}")
            except ModuleNotFoundError as e:
                if e.name == f"editor.ui.{name}":
                    continue
                raise
            self.extensions[name] = mod.install(self)

    def _fill_recent(self) -> None:
        self.recent_menu.clear()
        items = self.docs.recent()
        for path in items:
            a = self.recent_menu.addAction(Path(path).name)
            a.setToolTip(path)
            a.setStatusTip(path)
            a.triggered.connect(lambda _c=False, p=path: self.docs.open_path(p))
        if items:
            self.recent_menu.addSeparator()
            clear = self.recent_menu.addAction("Clear Menu", self.docs.clear_recent)
            clear.setStatusTip("Forget the recently opened files")
        self.recent_menu.setEnabled(bool(items))

    # ------------------------------------------------------------------ documents
    def load_face(self, face: Face, doc: Document | None = None) -> None:
        """Show an already detected face (a new, clean document)."""
        self.model.load(face, doc)

    def _show_photo_expression(self, declared_neutral: bool) -> None:
        """Status bar and Edit menu after a load or a change of how the photo is read."""
        fitted = self.model.fitted
        words = fitted.expression_words if fitted is not None else "neutral"
        if declared_neutral:
            self.expression_label.setText("photo declared neutral")
        else:
            self.expression_label.setText(f"photo shows: {words}")
        shows = fitted is not None and fitted.has_expression and not declared_neutral
        self.act_neutralize.setEnabled(shows)
        self.act_photo_expression.setEnabled(shows)
        self.act_photo_neutral.setEnabled(fitted is not None)
        self.act_photo_neutral.blockSignals(True)
        self.act_photo_neutral.setChecked(declared_neutral)
        self.act_photo_neutral.blockSignals(False)

    def _on_changed(self, old: Document | None, new: Document) -> None:
        face = self.model.face
        if face is None:
            return
        if (old is None or old.faps is not new.faps or old.vertices is not new.vertices
                or old.photo_neutral != new.photo_neutral):
            self.scheduler.submit(face, new.faps, creases=self.act_creases.isChecked())
        if old is None or old.photo_neutral != new.photo_neutral:
            self._show_photo_expression(new.photo_neutral)
        if old is None or old.embed_photo != new.embed_photo:
            self.act_embed.blockSignals(True)
            self.act_embed.setChecked(new.embed_photo)
            self.act_embed.blockSignals(False)
        if (old is None or old.vertices is not new.vertices
                or old.photo_neutral != new.photo_neutral):
            self._show_fapu(face)
            folded = self.model.folded_triangles()
            if folded:
                self.statusBar().showMessage(
                    f"Warning: {folded} mesh triangles are folded (inside out); move the vertex "
                    "back or use Edit > Reset Mesh", 8000)
        if old is None:
            self._update_title()

    def _set_creases(self, on: bool) -> None:
        """View > Skin Creases: re-render the preview with or without the folds (and export
        images so)."""
        self.docs.creases = bool(on)
        face, doc = self.model.face, self.model.doc
        if face is not None and doc is not None:
            self.scheduler.submit(face, doc.faps, creases=bool(on))

    def _on_result(self, result: RenderResult) -> None:
        self.last_result = result
        self.canvas.set_result(result)
        self.render_label.setText(f"render {result.ms:.1f} ms · shown after "
                                  f"{result.latency_ms:.1f} ms")

    def _on_render_failed(self, message: str) -> None:
        self.statusBar().showMessage(message, 5000)

    def _show_fapu(self, face: Face) -> None:
        parts = [f"{k}0 {face.fapu[k] * 1024:.1f}" for k in FAPU_SHOWN]
        self.fapu_label.setText("FAPU (px): " + "  ".join(parts))
        self.fapu_label.setToolTip("Facial Animation Parameter Units of this face, in pixels "
                                   "per 1024 units:\n" + "\n".join(
                                       f"{k}: {v:.6g} px/unit" for k, v in face.fapu.items()))

    def _update_title(self, *_args: object) -> None:
        doc = self.model.doc
        if self.model.path:
            name = Path(self.model.path).name
        elif doc is not None and doc.photo:
            name = Path(doc.photo).name
        else:
            name = "untitled"
        self.setWindowTitle(f"{name}[*] — FAP Studio")
        self.setWindowModified(self.model.is_dirty())

    def _about(self) -> AboutDialog:
        dialog = AboutDialog(self)
        dialog.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
        dialog.show()
        return dialog

    # ------------------------------------------------------------------ events
    def dragEnterEvent(self, e: QDragEnterEvent) -> None:
        if e.mimeData().hasUrls() and any(u.isLocalFile() for u in e.mimeData().urls()):
            e.acceptProposedAction()
        else:
            e.ignore()

    def dropEvent(self, e: QDropEvent) -> None:
        files = [u.toLocalFile() for u in e.mimeData().urls() if u.isLocalFile()]
        if not files:
            e.ignore()
            return
        e.acceptProposedAction()
        self.docs.open_path(files[0])

    def closeEvent(self, e: QCloseEvent) -> None:
        if not self._closing_ok and not self.docs.maybe_save():
            e.ignore()
            return
        if not self._closing_ok:  # a user's close: remember the layout
            s = settings()
            s.setValue("window/geometry", self.saveGeometry())
            s.setValue("window/state", self.saveState())
        self.scheduler.shutdown()
        cancel_all()  # a task still running (an export, a study) stops at its next step
        e.accept()

    def close_without_prompt(self) -> None:
        """Close even with unsaved changes (headless screenshots, tests)."""
        self._closing_ok = True
        self.close()

    def restore_layout(self) -> None:
        """Restore the window geometry and dock layout saved at the last close."""
        s = settings()
        geo, state = s.value("window/geometry"), s.value("window/state")
        if isinstance(geo, QByteArray):
            self.restoreGeometry(geo)
        if isinstance(state, QByteArray):
            self.restoreState(state)
