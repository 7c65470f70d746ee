"""The main window: preview, undo, vertex drags, projects, errors, drops, screenshots."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pytestqt")

from PySide6.QtCore import QMimeData, QPointF, Qt, QUrl  # noqa: E402
from PySide6.QtGui import QDropEvent, QImage  # noqa: E402
from PySide6.QtWidgets import QMessageBox  # noqa: E402

from editor.core import FAPS, load_image  # noqa: E402
from editor.formats.project import FORMAT, VERSION, load_project  # noqa: E402
from editor.resources import SAMPLE_FACE
from editor.ui import app as app_module  # noqa: E402
from editor.ui.main_window import MainWindow  # noqa: E402
from editor.ui.qt_utils import settings  # noqa: E402

pytestmark = [pytest.mark.gui, pytest.mark.usefixtures("isolated_settings")]
SAMPLE = SAMPLE_FACE


class Boxes:
    """Records message boxes instead of showing them."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, answer=QMessageBox.StandardButton.Cancel):
        self.warnings: list[str] = []
        self.questions: list[str] = []
        self.answer = answer
        monkeypatch.setattr(QMessageBox, "warning",
                            lambda _parent, _title, text, *a, **k: self.warnings.append(text))
        monkeypatch.setattr(QMessageBox, "question", self._question)

    def _question(self, _parent, _title, text, *a, **k):
        self.questions.append(text)
        return self.answer


@pytest.fixture
def boxes(monkeypatch) -> Boxes:
    return Boxes(monkeypatch)


@pytest.fixture
def window(qtbot, sample_face, boxes) -> MainWindow:
    w = MainWindow()
    qtbot.addWidget(w)
    w.load_face(sample_face)
    w.resize(1200, 800)
    w.show()
    qtbot.waitExposed(w)
    assert w.scheduler.wait(5000)
    yield w
    w.close_without_prompt()


def _shown(window: MainWindow) -> np.ndarray:
    assert window.scheduler.wait(5000)
    img = window.canvas.preview_image()
    assert img is not None
    return img


class FakeDrag:
    """The parts of pyqtgraph's MouseDragEvent that MeshItem uses."""

    def __init__(self, down, pos, start=False, finish=False):
        self._down, self._pos, self._start, self._finish = down, pos, start, finish
        self.accepted = False

    def button(self):
        return Qt.MouseButton.LeftButton

    def isStart(self):
        return self._start

    def isFinish(self):
        return self._finish

    def buttonDownPos(self):
        return QPointF(*self._down)

    def pos(self):
        return QPointF(*self._pos)

    def accept(self):
        self.accepted = True

    def ignore(self):
        self.accepted = False


# ---------------------------------------------------------------------- preview + undo
def test_slider_changes_preview_only_where_the_fap_acts_and_undo_restores(window, sample_face):
    neutral = _shown(window)
    assert np.array_equal(neutral, sample_face.image)  # zero FAPs reproduce the photo
    assert "FAPU" in window.fapu_label.text() and "ms" in window.render_label.text()
    slider = window.fap_panel.rows[FAPS["open_jaw"].number].slider
    slider.setSliderDown(True)
    for v in range(50, 650, 50):
        slider.setValue(v)
    slider.setSliderDown(False)
    opened = _shown(window)
    changed = np.abs(opened.astype(int) - neutral).max(2) > 0
    ys, xs = np.nonzero(changed)
    assert changed.sum() > 200
    fp = sample_face.feature_points()
    assert ys.min() > max(fp["3.5"][1], fp["3.6"][1])  # nothing above the eyes changes ...
    v0, v1 = sample_face.vertices, sample_face.deform({"open_jaw": 600})
    tris = sample_face.triangles
    moved = tris[(np.abs(v1 - v0).max(1) > 1e-3)[tris].any(1)]
    pts = np.concatenate([v0[moved].reshape(-1, 2), v1[moved].reshape(-1, 2)])
    lo, hi = pts.min(0) - 2, pts.max(0) + 2
    assert changed.mean() < 0.05  # a small part of the photo
    assert (xs >= lo[0]).all() and (xs <= hi[0]).all()  # ... nor outside the moved triangles
    assert (ys >= lo[1]).all() and (ys <= hi[1]).all()
    assert window.model.undo_stack.count() == 1
    window.act_undo.trigger()
    assert np.array_equal(_shown(window), neutral)  # undo restores the exact image
    window.act_redo.trigger()
    assert np.array_equal(_shown(window), opened)


def test_dragging_a_vertex_moves_it_and_changes_fapu(window, sample_face):
    mesh = window.canvas.mesh
    i = sample_face.fdp["8.3"]  # outer lip corner: the mouth width MW follows
    x, y = (float(c) for c in sample_face.vertices[i])
    mw0 = window.model.face.fapu["MW"]
    label0 = window.fapu_label.text()
    mesh.hoverEvent(type("H", (), {"isExit": lambda s: False, "pos": lambda s: QPointF(x, y),
                                   "acceptDrags": lambda s, b: True})())
    assert mesh.label.isVisible() and "8.3" in mesh.label.toPlainText()
    ev = FakeDrag((x + 0.3, y), (x + 0.3, y), start=True)
    mesh.mouseDragEvent(ev)
    assert ev.accepted and window.model.in_gesture
    for dx in (1, 2, 3):
        mesh.mouseDragEvent(FakeDrag((x + 0.3, y), (x + 0.3 + dx, y)))
    mesh.mouseDragEvent(FakeDrag((x + 0.3, y), (x + 3.3 + 3, y), finish=True))
    v = window.model.doc.vertices[i]
    assert v[0] == pytest.approx(x + 6, abs=1e-3) and v[1] == pytest.approx(y, abs=1e-3)
    assert np.allclose(mesh.vertices[i], v)
    assert window.model.face.fapu["MW"] > mw0 and window.fapu_label.text() != label0
    assert window.model.undo_stack.count() == 1
    far = FakeDrag((5.0, 300.0), (5.0, 300.0), start=True)  # not near a vertex: pan instead
    mesh.mouseDragEvent(far)
    assert not far.accepted
    window.act_reset_mesh.trigger()
    assert np.array_equal(window.model.doc.vertices, sample_face.vertices)
    window.act_undo.trigger()
    assert window.model.doc.vertices[i][0] == pytest.approx(x + 6, abs=1e-3)


def test_standard_shortcuts(window):
    def keys(action):
        return {a.toString() for a in action.shortcuts()}

    assert "Ctrl+O" in keys(window.act_open) and "Ctrl+S" in keys(window.act_save)
    assert "Ctrl+Shift+S" in keys(window.act_save_as) and "Ctrl+E" in keys(window.act_export)
    assert "Ctrl+Z" in keys(window.act_undo) and "Ctrl+Shift+Z" in keys(window.act_redo)
    assert "F" in keys(window.act_fit)


def test_overlay_toggle_and_fit(window):
    window.act_overlay.trigger()
    assert not window.canvas.mesh.isVisible()
    window.act_overlay.trigger()
    assert window.canvas.mesh.isVisible()
    window.act_fit.trigger()
    (x0, x1), (y0, y1) = window.canvas.photo_view.viewRange()
    assert x0 <= 0 and x1 >= 512 and y0 <= 0 and y1 >= 512


# ---------------------------------------------------------------------- projects
def test_project_round_trip(window, boxes, tmp_path, sample_face):
    m = window.model
    i = sample_face.fdp["2.1"]
    m.begin_gesture()
    m.preview_vertex(i, sample_face.vertices[i] + (1.25, 2.5))
    m.commit_gesture("Move vertex")
    m.neutralize()  # the sample smiles: start from its neutral face
    m.set_faps({"open_jaw": 420.5, "raise_l_i_eyebrow": -130, "head_yaw": 6000}, "x")
    image = _shown(window)
    path = tmp_path / "proj" / "smile.fapproj"
    path.parent.mkdir()
    assert window.isWindowModified()
    assert window.docs.save_to(str(path))
    assert not window.isWindowModified() and m.path == str(path.resolve())
    data = json.loads(path.read_text())  # human-readable JSON with a format version
    assert data["format"] == FORMAT and data["version"] == VERSION
    assert data["faps"] == {"open_jaw": 420.5, "raise_l_i_eyebrow": -130, "head_yaw": 6000}
    assert Path(path.parent, data["photo"]).resolve() == SAMPLE.resolve()
    saved = m.doc

    m.set_faps({"open_jaw": 0}, "change after saving")
    boxes.answer = QMessageBox.StandardButton.Discard
    assert window.docs.open_project(str(path))
    assert len(boxes.questions) == 1  # unsaved changes: asked first
    doc = m.doc
    assert doc is not saved and doc.equals(saved)  # mesh, values and photo identical
    assert np.array_equal(doc.vertices, saved.vertices) and np.array_equal(doc.faps, saved.faps)
    assert np.array_equal(_shown(window), image)  # and the same rendered pixels
    assert m.undo_stack.count() == 0 and not m.is_dirty()
    assert str(path.resolve()) in window.docs.recent()
    assert settings().value("lastProject") == str(path.resolve())
    assert window.windowTitle().startswith("smile.fapproj")


def test_open_initial_prefers_last_project(qtbot, tmp_path, boxes, sample_face):
    w = MainWindow()
    qtbot.addWidget(w)
    w.load_face(sample_face)
    w.model.set_faps({"open_jaw": 100}, "x")
    p = tmp_path / "last.fapproj"
    assert w.docs.save_to(str(p))
    w2 = MainWindow()
    qtbot.addWidget(w2)
    assert app_module.open_initial(w2)
    assert w2.model.path == str(p.resolve()) and w2.model.doc.fap("open_jaw") == 100
    p.unlink()
    w3 = MainWindow()
    qtbot.addWidget(w3)
    assert app_module.open_initial(w3)  # last project gone: the sample face
    assert w3.model.path is None and Path(w3.model.doc.photo).name == "sample_face.png"
    for x in (w, w2, w3):
        x.close_without_prompt()


# ---------------------------------------------------------------------- errors
BAD_PROJECTS = {
    "not_json.fapproj": "{ this is not json",
    "wrong_format.fapproj": json.dumps({"format": "something-else", "version": 1}),
    "future.fapproj": json.dumps({"format": FORMAT, "version": 99, "photo": "x.png"}),
    "bad_fap.fapproj": json.dumps({"format": FORMAT, "version": 1, "photo": str(SAMPLE),
                                   "faps": {"no_such_fap": 1}}),
    "bad_value.fapproj": json.dumps({"format": FORMAT, "version": 1, "photo": str(SAMPLE),
                                     "faps": {"open_jaw": "wide"}}),
    "bad_mesh.fapproj": json.dumps({"format": FORMAT, "version": 1, "photo": str(SAMPLE),
                                    "mesh": {"vertices": {"nose_tip": [1, 2]}}}),
    "no_photo.fapproj": json.dumps({"format": FORMAT, "version": 1, "photo": "missing.png"}),
}


@pytest.mark.parametrize("kind", ["corrupt.png", "empty.jpg", "no_face.png", "missing.png",
                                  *BAD_PROJECTS])
def test_bad_input_shows_error_and_keeps_document(window, boxes, tmp_path, kind):
    m = window.model
    m.set_faps({"open_jaw": 200}, "x")
    before, count = m.doc, m.undo_stack.count()
    path = tmp_path / kind
    if kind == "corrupt.png":
        path.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 8)
    elif kind == "empty.jpg":
        path.write_bytes(b"")
    elif kind == "no_face.png":
        from editor.core import save_image

        save_image(path, np.full((200, 200, 3), 128, np.uint8))
    elif kind in BAD_PROJECTS:
        path.write_text(BAD_PROJECTS[kind])
    boxes.answer = QMessageBox.StandardButton.Discard
    window.docs.interactive = False  # a missing photo is reported, not asked for
    assert not window.docs.open_path(str(path))
    assert len(boxes.warnings) == 1
    msg = boxes.warnings[0]
    assert "\n" not in msg and (kind in msg or "missing.png" in msg)
    assert m.doc is before and m.undo_stack.count() == count


def test_project_loader_messages(tmp_path):
    p = tmp_path / "x.fapproj"
    p.write_text(BAD_PROJECTS["bad_mesh.fapproj"])
    from editor.core import ProjectError, standard_mesh

    with pytest.raises(ProjectError, match="unknown mesh vertex 'nose_tip'"):
        load_project(p, standard_mesh().names)


def test_drop_a_photo_and_unsaved_prompt(window, boxes, tmp_path, qtbot):
    m = window.model
    m.set_faps({"open_jaw": 200}, "x")
    mime = QMimeData()
    mime.setUrls([QUrl.fromLocalFile(str(SAMPLE))])
    ev = QDropEvent(QPointF(10, 10), Qt.DropAction.CopyAction, mime,
                    Qt.MouseButton.NoButton, Qt.KeyboardModifier.NoModifier)
    boxes.answer = QMessageBox.StandardButton.Cancel
    window.dropEvent(ev)
    assert len(boxes.questions) == 1 and m.doc.fap("open_jaw") == 200  # cancelled
    boxes.answer = QMessageBox.StandardButton.Discard
    window.dropEvent(ev)
    # a new photo starts at its own expression (the photo unchanged), clean
    assert np.array_equal(m.doc.faps, m.fitted.expression) and not m.is_dirty()
    assert str(SAMPLE.resolve()) in window.docs.recent()
    assert "sample_face.png" in [a.text() for a in window.recent_menu.actions()]
    m.set_faps({"open_jaw": 300}, "x")
    boxes.answer = QMessageBox.StandardButton.Cancel
    window.close()
    assert window.isVisible()  # close refused
    boxes.answer = QMessageBox.StandardButton.Discard
    window.close()
    assert not window.isVisible()


def test_export_png_and_jpeg(window, tmp_path):
    """The exported still is the shown expression rendered bicubically (sharp), with the skin
    folds as View > Skin Creases sets them."""
    window.model.set_faps({"open_jaw": 500}, "x")
    face, faps = window.model.face, window.model.doc.faps
    png, jpg = tmp_path / "out.png", tmp_path / "out.jpg"
    assert window.docs.export(str(png)) and window.docs.export(str(jpg))
    assert np.array_equal(load_image(png), face.render(faps, sharp=True))
    assert load_image(jpg).shape == _shown(window).shape
    shown = _shown(window).astype(np.int16)
    assert np.abs(load_image(png) - shown).mean() < 1.0  # the preview's picture, sharper
    window.act_creases.trigger()  # folds off
    assert window.docs.export(str(png))
    assert np.array_equal(load_image(png), face.render(faps, creases=False, sharp=True))


# ---------------------------------------------------------------------- headless screenshot
def test_screenshot(qtbot, tmp_path):
    out = tmp_path / "shot.png"
    assert app_module.run(str(SAMPLE), {"open_jaw": 500, "raise_l_cornerlip_o": 200},
                          screenshot=str(out)) == 0
    img = QImage(str(out))
    assert (img.width(), img.height()) == app_module.SCREENSHOT_SIZE
    assert out.stat().st_size > 100_000
    assert not settings().value("recentFiles")  # headless runs leave the settings alone
    assert app_module.run(str(tmp_path / "nope.png"), screenshot=str(tmp_path / "x.png")) == 2
    assert app_module.run(str(SAMPLE), {"nonsense": 1}, screenshot=str(tmp_path / "y.png")) == 2
