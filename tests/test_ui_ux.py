"""Issue 17: the editor as a desktop user expects it (defects 1-9, each with a test that fails
without its fix). Real widgets, offscreen."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pytestqt")

from PySide6.QtCore import Qt  # noqa: E402
from PySide6.QtWidgets import QDialogButtonBox, QMessageBox  # noqa: E402

from editor.resources import SAMPLE_FACE  # noqa: E402
from editor.ui.main_window import MainWindow  # noqa: E402

pytestmark = [pytest.mark.gui, pytest.mark.usefixtures("isolated_settings")]


class Boxes:
    """Message boxes recorded instead of shown; the unsaved-changes prompt says Discard."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.shown: list[str] = []
        for kind in ("warning", "information", "critical"):
            monkeypatch.setattr(QMessageBox, kind,
                                lambda _p, _t, text, *a, **k: self.shown.append(text))
        monkeypatch.setattr(QMessageBox, "question",
                            lambda *a, **k: QMessageBox.StandardButton.Discard)


@pytest.fixture
def boxes(monkeypatch) -> Boxes:
    return Boxes(monkeypatch)


@pytest.fixture
def window(qtbot, sample_neutral, boxes) -> MainWindow:
    w = MainWindow()
    qtbot.addWidget(w)
    w.load_face(sample_neutral)
    w.show()
    qtbot.waitExposed(w)
    yield w
    w.playback_panel.shutdown()
    w.close_without_prompt()


# ---------------------------------------------------------------- defect 2
def test_quick_button_builds_a_two_second_sequence(window):
    """The dock's button passes clicked(bool) -- it must not become the duration."""
    window.model.set_faps({"open_jaw": 400}, "pose")
    panel = window.playback_panel
    panel.quick_button.click()
    assert panel.seq is not None
    assert panel.seq.n_frames == 51 and abs(panel.seq.duration - 2.0) < 0.05


# ---------------------------------------------------------------- defect 3
def test_new_study_dialog_keeps_its_input_after_a_validation_error(window, qtbot):
    from editor.ui.mos_new import NewStudyDialog

    dialog = NewStudyDialog([str(SAMPLE_FACE)], window)
    qtbot.addWidget(dialog)
    dialog.name.setText("my pilot")
    dialog.intensities.setText("0.5, 1.0")
    dialog.show()
    dialog.findChild(QDialogButtonBox).button(QDialogButtonBox.StandardButton.Ok).click()
    assert dialog.isVisible() and dialog.result() != NewStudyDialog.DialogCode.Accepted
    assert "choose a file" in dialog.error_label.text() and dialog.error_label.isVisible()
    assert dialog.name.text() == "my pilot" and dialog.intensities.text() == "0.5, 1.0"
    assert dialog.faces.count() == 1
    dialog.intensities.setText("2")
    dialog.output.setText("x.db")
    dialog.findChild(QDialogButtonBox).button(QDialogButtonBox.StandardButton.Ok).click()
    assert dialog.isVisible() and "0 … 1.5" in dialog.error_label.text()
    dialog.intensities.setText("1")
    dialog.findChild(QDialogButtonBox).button(QDialogButtonBox.StandardButton.Ok).click()
    assert not dialog.isVisible() and dialog.result() == NewStudyDialog.DialogCode.Accepted


# ---------------------------------------------------------------- defect 5
def test_model_thumbnail_cleared_when_another_photo_opens(window, sample_neutral, sample_face):
    from editor.synthesis.bilinear_photo import synthetic_model68

    panel = window.extensions["model_panel"].panel
    panel.set_model(synthetic_model68(sample_neutral.landmarks.points))
    panel.expression.setCurrentText("surprise")
    assert panel.synthesize() is not None and not panel.preview.pixmap().isNull()
    window.load_face(sample_face)
    assert panel.preview.pixmap().isNull() and panel.result is None
    assert "Synthesize" in panel.preview.text()
    assert np.isfinite(window.model.doc.faps).all()


# ---------------------------------------------------------------- defect 4
def _save_project_beside(window, folder, name="p.fapproj"):
    import shutil

    folder.mkdir(parents=True, exist_ok=True)
    photo = folder / "face.png"
    shutil.copy(SAMPLE_FACE, photo)
    assert window.docs.open_photo(str(photo), ask=False)
    window.model.set_faps({"open_jaw": 300}, "jaw")
    project = folder / name
    assert window.docs.save_to(str(project))
    return photo, project


def test_project_copied_elsewhere_finds_its_photo_by_the_absolute_path(window, tmp_path):
    import json
    import shutil

    photo, project = _save_project_beside(window, tmp_path / "a")
    data = json.loads(project.read_text())
    assert data["photo"] == "face.png" and data["photo_absolute"] == str(photo.resolve())
    copy = tmp_path / "elsewhere" / "p.fapproj"
    copy.parent.mkdir()
    shutil.copy(project, copy)
    assert window.docs.open_project(str(copy), ask=False)
    assert window.model.doc.photo == str(photo.resolve())
    assert window.model.doc.fap("open_jaw") == 300 and not window.model.is_dirty()


def test_missing_photo_is_located_by_the_user(window, tmp_path, monkeypatch):
    from PySide6.QtWidgets import QFileDialog

    photo, project = _save_project_beside(window, tmp_path / "a")
    moved = tmp_path / "b" / "renamed.png"
    moved.parent.mkdir()
    photo.rename(moved)
    asked: list[str] = []
    monkeypatch.setattr(QMessageBox, "question",
                        lambda _p, _t, text, *a, **k: asked.append(text)
                        or QMessageBox.StandardButton.Open)
    monkeypatch.setattr(QFileDialog, "getOpenFileName",
                        lambda *a, **k: (str(moved), "Photos"))
    assert window.docs.open_project(str(project), ask=False)
    assert len(asked) == 1 and "face.png" in asked[0]
    assert window.model.doc.photo == str(moved.resolve())
    assert window.model.doc.fap("open_jaw") == 300
    assert window.model.is_dirty()  # the new location is saved only when the user saves
    # giving up leaves the current document alone
    before = window.model.doc
    moved.rename(tmp_path / "gone.png")
    monkeypatch.setattr(QFileDialog, "getOpenFileName", lambda *a, **k: ("", ""))
    window.model.mark_clean()
    assert not window.docs.open_project(str(project), ask=False)
    assert window.model.doc is before


def test_embedded_photo_travels_with_the_project(window, tmp_path, monkeypatch):
    monkeypatch.setenv("FAP_STUDIO_CACHE", str(tmp_path / "cache"))
    photo, project = _save_project_beside(window, tmp_path / "a")
    small = project.stat().st_size
    window.act_embed.trigger()
    assert window.model.doc.embed_photo and window.model.is_dirty()
    window.model.undo_stack.undo()
    assert not window.model.doc.embed_photo and not window.act_embed.isChecked()
    window.model.undo_stack.redo()
    assert window.docs.save_to(str(project))
    assert project.stat().st_size > small + photo.stat().st_size
    photo.unlink()
    assert window.docs.open_project(str(project), ask=False)
    doc = window.model.doc
    assert doc.embed_photo and window.act_embed.isChecked() and doc.fap("open_jaw") == 300
    assert (tmp_path / "cache") in __import__("pathlib").Path(doc.photo).parents
    from editor.engine.imageio import load_image

    assert np.array_equal(load_image(doc.photo), load_image(SAMPLE_FACE))


def test_old_version_1_project_still_opens(window, tmp_path):
    import json

    old = tmp_path / "old.fapproj"
    old.write_text(json.dumps({"format": "fap-studio-project", "version": 1,
                               "photo": str(SAMPLE_FACE), "faps": {"open_jaw": 120}}))
    assert window.docs.open_project(str(old), ask=False)
    assert window.model.doc.fap("open_jaw") == 120 and window.model.doc.animation.empty


# ---------------------------------------------------------------- defect 1
def test_opening_a_large_photo_never_blocks_the_event_loop(window, qtbot, tmp_path, monkeypatch):
    """Decoding, fitting and rendering a 12 MP photo happen off the GUI thread, and the GUI
    thread's event loop runs meanwhile (a timer keeps ticking). Not a timing test: it asks
    *where* the work runs; how long the loop may stall is the bench row ``gui_open_gap_ms``."""
    import threading

    import cv2
    from PySide6.QtCore import QTimer

    from editor.engine.face import Face
    from editor.engine.imageio import load_image
    from editor.ui import documents

    big = tmp_path / "big.png"  # 12 MP
    rgb = cv2.resize(load_image(SAMPLE_FACE), (3000, 4000), interpolation=cv2.INTER_CUBIC)
    cv2.imwrite(str(big), rgb[:, :, ::-1])
    assert window.scheduler.wait(5000)

    gui = threading.get_ident()
    threads: dict[str, set[int]] = {"fit": set(), "render": set()}
    fit, render = documents._face_from_image, Face.render

    def spy_fit(path):
        threads["fit"].add(threading.get_ident())
        return fit(path)

    def spy_render(self, *args, **kwargs):
        if self.image.shape[:2] == (4000, 3000):
            threads["render"].add(threading.get_ident())
        return render(self, *args, **kwargs)

    monkeypatch.setattr(documents, "_face_from_image", spy_fit)
    monkeypatch.setattr(Face, "render", spy_render)
    ticks: list[int] = []
    timer = QTimer()
    timer.timeout.connect(lambda: ticks.append(len(threads["fit"])))
    timer.start(10)
    assert window.docs.open_photo(str(big), ask=False)
    opened = len(ticks)
    qtbot.waitUntil(lambda: window.last_result is not None
                    and window.last_result.image.shape[:2] == (4000, 3000), timeout=20000)
    timer.stop()
    assert window.model.face.image.shape[:2] == (4000, 3000)
    assert threads["fit"] and gui not in threads["fit"]  # detect + fit on a worker
    assert threads["render"] and gui not in threads["render"]  # the render too
    # the loop ran while the fit worked (the timer fired), and after it while the render did
    assert opened >= 3 and len(ticks) > opened


def test_long_task_shows_progress_and_cancel_stops_it(window, qtbot):
    """A long task's dialog shows real progress and its Cancel stops the work -- even while
    background jobs (the preset thumbnails the window started) keep Qt's global pool busy."""
    import threading
    import time

    from PySide6.QtCore import QTimer
    from PySide6.QtWidgets import QProgressDialog, QPushButton

    from editor.errors import Cancelled
    from editor.ui.tasks import run_task

    steps: list[int] = []
    seen: list[tuple[int, int]] = []
    ended = threading.Event()

    def work(progress) -> str:
        try:
            for i in range(500):
                progress(i, 500, f"step {i}")
                steps.append(i)
                time.sleep(0.01)
            return "done"
        finally:
            ended.set()

    tries: list[int] = []

    def press_cancel() -> None:
        tries.append(1)
        dialogs = [d for d in window.findChildren(QProgressDialog) if d.isVisible()]
        # wait for the first progress (at most ~10 s; then press anyway and fail below)
        if dialogs and (dialogs[0].maximum() == 500 or len(tries) > 500):
            seen.append((dialogs[0].value(), dialogs[0].maximum()))
            dialogs[0].findChild(QPushButton).click()  # the user's Cancel
        else:
            QTimer.singleShot(20, press_cancel)

    from PySide6.QtCore import QRunnable, QThreadPool

    release = threading.Event()

    class Busy(QRunnable):  # background work filling the global pool, as thumbnails do
        def run(self) -> None:
            release.wait(60)

    pool = QThreadPool.globalInstance()
    for _ in range(pool.maxThreadCount()):
        pool.start(Busy())
    try:
        QTimer.singleShot(450, press_cancel)
        with pytest.raises(Cancelled):
            run_task(window, "Working…", work)
        assert seen and seen[0][1] == 500 and 0 < seen[0][0] < 500  # a real progress bar
        qtbot.waitUntil(ended.is_set, timeout=10000)
        assert 0 < len(steps) < 500  # the work saw the cancel and stopped
        assert run_task(window, "Quick", lambda _p: 42) == 42  # short work: no dialog at all
    finally:
        release.set()
        pool.waitForDone(10000)


# ---------------------------------------------------------------- defect 9
def test_animation_is_undoable_and_saved_in_the_project(window, tmp_path):
    from editor.formats.fapfile import FapSequence, write_fap

    panel, stack = window.playback_panel, window.model.undo_stack
    keys = panel.keys
    window.model.set_faps({"open_jaw": 0}, "zero")
    keys.time.setValue(0.0)
    keys.add_button.click()
    window.model.set_faps({"open_jaw": 600}, "jaw")
    keys.time.setValue(1.0)
    keys.add_button.click()
    assert [t for t, _ in window.model.doc.animation.keys] == [0.0, 1.0]
    assert stack.undoText() == "Add key at 1 s"
    stack.undo()  # the key goes, the list follows
    assert [t for t, _ in keys.keys] == [0.0] and len(window.model.doc.animation.keys) == 1
    stack.redo()
    assert [t for t, _ in keys.keys] == [0.0, 1.0]
    keys.interp.setCurrentText("smoothstep")
    assert window.model.doc.animation.interpolation == "smoothstep"
    keys.build_button.click()
    assert panel.seq is not None and panel.seq.n_frames == 26
    stack.undo()  # the built sequence goes away, the keys stay
    assert panel.seq is None and panel.vectors is None and len(keys.keys) == 2
    assert "No sequence" in panel.info.text() and not panel.play_button.isEnabled()
    stack.redo()
    assert panel.seq is not None and panel.slider.maximum() == 25
    # an opened .fap replaces it, saved in the project with the keys
    frames = np.zeros((7, 68), np.float32)
    frames[:, 2] = np.arange(7) * 50
    fap = tmp_path / "ramp.fap"
    write_fap(FapSequence(frames, fps=10, name="ramp"), fap)
    assert panel.open_file(str(fap))
    project = tmp_path / "anim.fapproj"
    assert window.docs.save_to(str(project))
    fap.unlink()  # the project holds the sequence itself
    window.model.undo_stack.clear()
    window.load_face(window.model.fitted)  # anything else
    window.model.set_animation(type(window.model.doc.animation)(), "clear")
    assert panel.seq is None
    assert window.docs.open_project(str(project), ask=False)
    anim = window.model.doc.animation
    assert anim.interpolation == "smoothstep" and [t for t, _ in anim.keys] == [0.0, 1.0]
    assert anim.keys[1][1][2] == 600 and anim.source == str(fap)
    assert panel.seq.n_frames == 7 and np.array_equal(panel.vectors[:, 2], frames[:, 2])
    assert "ramp.fap: 7 frames at 10 fps" in panel.info.text()
    assert [t for t, _ in keys.keys] == [0.0, 1.0] and keys.interp.currentText() == "smoothstep"
    assert not window.model.is_dirty()


# ---------------------------------------------------------------- defect 7
def test_results_window_names_its_tabs_and_explains_a_missing_kappa(qtbot, tmp_path):
    from editor.study.mos import Study
    from editor.study.stimuli import create_from_renders
    from editor.ui.mos_rating import NATURALNESS
    from editor.ui.mos_results import ResultsWindow

    rng = np.random.default_rng(1)
    renders = [("Ann", lab, 1.0, rng.integers(0, 256, (40, 30, 3), dtype=np.uint8))
               for lab in ("joy", "anger")]
    path = tmp_path / "s.db"
    create_from_renders(path, "pilot", ["joy", "anger"], renders).close()
    from editor.ui.mos_rating import RatingWindow

    rating = RatingWindow(str(path), "solo", 3)  # one rater only
    qtbot.addWidget(rating)
    rating.show()
    for _ in range(2):
        qtbot.keyClick(rating, Qt.Key.Key_1)
        qtbot.keyClick(rating, Qt.Key.Key_4)
        qtbot.keyClick(rating, Qt.Key.Key_Return)
    rating.close()
    with Study.open(path) as study:
        assert {a.rater for a in study.answers()} == {"solo"}
    win = ResultsWindow(path)
    qtbot.addWidget(win)
    tabs = [win.tabs.tabText(i) for i in range(win.tabs.count())]
    assert not any(t.startswith("Table") for t in tabs)
    assert {"Face × expression", "Per expression", "Per face", "Raters"} <= set(tabs)
    text = win.summary_label.text()
    assert "over 0 stimuli" not in text and "at least two raters" in text
    raters = win.tables["Raters"]
    headers = [raters.horizontalHeaderItem(j) for j in range(raters.columnCount())]
    assert all(h.toolTip() for h in headers[1:])  # every rater column is explained
    assert "BT.500" in headers[-1].toolTip() and "Pearson" in headers[4].toolTip()
    nat_tip = win.tables["Overall"].horizontalHeaderItem(4).toolTip()
    assert NATURALNESS[1] in nat_tip and NATURALNESS[5] in nat_tip  # the scale raters saw
    assert [raters.horizontalHeaderItem(j).text() for j in (2, 3)] == ["recognition %",
                                                                       "naturalness"]


# ---------------------------------------------------------------- defects 6 and 8
def test_docks_close_and_reset_layout_minimum_size_toolbar_help_and_about(window, qtbot):
    from PySide6.QtWidgets import QDockWidget

    from editor.resources import CREDITS
    from editor.ui.help_panel import AboutDialog, action_rows

    docks = window.findChildren(QDockWidget)
    assert all(d.features() & QDockWidget.DockWidgetFeature.DockWidgetClosable for d in docks)
    assert all(d.toggleViewAction().isEnabled() for d in docks)
    assert window.presets_dock.isVisible()  # the Presets tab is in front at start
    window.fap_dock.close()
    window.gaze_dock.toggleViewAction().trigger()
    assert not window.fap_dock.isVisible() and not window.gaze_dock.isVisible()
    window.act_reset_layout.trigger()
    qtbot.waitUntil(lambda: all(d.isVisible() for d in (window.fap_dock, window.presets_dock)))
    assert window.minimumWidth() >= 900 and window.minimumHeight() >= 600
    assert window.act_open in window.toolbar.actions()
    assert window.act_help.shortcut().toString() == "F1"
    window.act_help.trigger()
    assert window.help_dock.isVisible() and "Ctrl+Z" in window.help_panel.toPlainText()
    rows = action_rows(window)
    assert len(rows) > 40
    assert [r[:2] for r in rows if not r[3]] == []  # every action has a status tip
    about = window._about()
    qtbot.addWidget(about)
    assert isinstance(about, AboutDialog)
    page = about.text.toPlainText()
    for component, _source, licence in CREDITS:
        assert component in page and licence in page
    assert "LGPL" in page and "300-W" in page and "Eileen Collins" in page


def test_small_things_users_notice(window, qtbot, tmp_path, isolated_settings):
    from editor.ui.fap_panel import FapPanel
    from editor.ui.qt_utils import settings

    # export says where the image went
    out = tmp_path / "x.png"
    assert window.docs.export(str(out))
    assert str(out) in window.statusBar().currentMessage()
    # the save prompt names the photo of an unsaved document
    asked: list[str] = []
    import editor.ui.documents as documents

    orig = documents.QMessageBox.question
    documents.QMessageBox.question = staticmethod(
        lambda _p, _t, text, *a, **k: asked.append(text) or QMessageBox.StandardButton.Discard)
    try:
        window.model.set_faps({"open_jaw": 100}, "x")
        assert window.docs.maybe_save()
    finally:
        documents.QMessageBox.question = orig
    assert "sample_face.png" in asked[0]
    # the sample face never enters Open Recent
    from editor.ui.app import open_initial

    window.docs.clear_recent()
    assert open_initial(window)  # no last project: the sample face
    assert window.docs.recent() == []
    # Link left/right is remembered
    window.fap_panel.link.setChecked(True)
    assert FapPanel(window.model).link.isChecked()
    window.fap_panel.link.setChecked(False)
    assert not settings().value("faps/linkLeftRight", type=bool)
    # gaze in degrees, under the pad
    pad = window.gaze_pad
    window.model.set_faps({23: 20000, 24: 20000}, "gaze")
    assert "°" in pad.readout() and "yaw +11.5°" in pad.readout()
    assert pad.pad_rect().bottom() < pad.height() - 15
    # the first-run hint goes with the first edit and stays gone
    assert not window.hint.isVisible()
    w2 = MainWindow()
    qtbot.addWidget(w2)
    assert w2.hint.isHidden()
    w2.close_without_prompt()


def test_first_run_hint_shows_until_the_first_edit(qtbot, sample_neutral, boxes):
    w = MainWindow()
    qtbot.addWidget(w)
    w.load_face(sample_neutral)
    w.show()
    assert w.hint.isVisible() and "Presets" in w.hint.text() and "gaze" in w.hint.text()
    w.presets_panel.apply("joy", 1.0, "replace")
    assert not w.hint.isVisible()
    w.close_without_prompt()


def test_fap_studio_photo_opens_the_editor_and_bench_help(cli, tmp_path):
    import subprocess
    import sys

    out = tmp_path / "shot.png"
    r = cli(str(SAMPLE_FACE), "--preset", "joy", "--screenshot", str(out))
    assert r.returncode == 0 and out.stat().st_size > 10000 and r.stderr == ""
    r = cli("no_such_photo.jpg", "--screenshot", str(tmp_path / "no.png"))
    assert r.returncode == 2 and "no_such_photo.jpg" in r.stderr
    bench = subprocess.run([sys.executable, "-m", "editor.bench", "--help"],
                           capture_output=True, text=True, timeout=60)
    assert bench.returncode == 0 and "--gui" in bench.stdout and '"bench"' not in bench.stdout
