"""Document model, undo commands and the latest-only render scheduler (editor/ui)."""

from __future__ import annotations

import threading

import numpy as np
import pytest

pytest.importorskip("pytestqt")

from editor.core import FAPS  # noqa: E402
from editor.formats.document import Document  # noqa: E402
from editor.ui.render_scheduler import RenderRequest, RenderResult, RenderScheduler  # noqa: E402

pytestmark = [pytest.mark.gui, pytest.mark.usefixtures("isolated_settings")]




# ---------------------------------------------------------------------- Document
def test_document_is_immutable_and_clamped(sample_neutral):
    doc = Document.neutral(sample_neutral)
    assert not doc.vertices.flags.writeable and not doc.faps.flags.writeable
    with pytest.raises(ValueError):
        doc.faps[0] = 1.0
    hi = FAPS["open_jaw"].range[1]
    d2 = doc.with_faps({"open_jaw": 10 * hi, 4: -1e9})
    assert d2.fap("open_jaw") == hi and d2.fap(4) == FAPS[4].range[0]
    assert doc.fap("open_jaw") == 0.0  # the original is untouched
    assert doc.with_faps({"open_jaw": 0}) is doc  # no change, same object
    assert doc.equals(doc.replace()) and not doc.equals(d2)
    with pytest.raises(ValueError, match="unknown FAP"):
        doc.with_faps({"no_such_fap": 1})


def test_document_rejects_wrong_shapes(sample_neutral):
    with pytest.raises(ValueError):
        Document(None, np.zeros((5, 3)), np.zeros(68))
    with pytest.raises(ValueError):
        Document(None, sample_neutral.vertices, np.zeros(67))


# ---------------------------------------------------------------------- model + commands
def test_gesture_is_one_undo_entry(model):
    changes = []
    model.changed.connect(lambda old, new: changes.append(new))
    model.begin_gesture()
    for v in range(0, 500, 10):
        model.preview_faps({"open_jaw": v})
    model.commit_gesture("Set open_jaw")
    assert model.undo_stack.count() == 1 and model.doc.fap("open_jaw") == 490
    assert len(changes) == 49  # every preview is shown (v=0 changes nothing)
    model.undo_stack.undo()
    assert model.doc.fap("open_jaw") == 0
    model.undo_stack.redo()
    assert model.doc.fap("open_jaw") == 490


def test_empty_gesture_and_abort_leave_no_history(model):
    model.set_faps({"open_jaw": 100}, "a")
    model.set_faps({"open_jaw": 200}, "b")
    model.undo_stack.undo()  # a redo branch exists now
    model.begin_gesture()
    model.commit_gesture("nothing")
    assert model.undo_stack.count() == 2 and model.undo_stack.canRedo()
    model.begin_gesture()
    model.preview_faps({"open_jaw": 999})
    model.abort_gesture()
    assert model.doc.fap("open_jaw") == 100 and model.undo_stack.count() == 2


def test_keyed_edits_merge_until_sealed_and_vanish_when_undone(model):
    for v in (10, 20, 30):
        model.set_faps({3: v}, "Set open_jaw", key="fap3")
    assert model.undo_stack.count() == 1
    model.set_faps({3: 0}, "Set open_jaw", key="fap3")  # back to the start: obsolete
    assert model.undo_stack.count() == 0 and not model.is_dirty()
    model.set_faps({3: 50}, "Set open_jaw", key="fap3")
    model.seal()
    model.set_faps({3: 60}, "Set open_jaw", key="fap3")
    model.set_faps({4: 60}, "Set lower_t_midlip", key="fap4")
    assert model.undo_stack.count() == 3


def test_vertex_edit_changes_face_and_fapu(model, sample_neutral):
    i = sample_neutral.fdp["8.3"]  # a lip corner: MW follows
    mw0 = model.face.fapu["MW"]
    model.begin_gesture()
    for dx in (1, 2, 3, 4):
        model.preview_vertex(i, sample_neutral.vertices[i] + (dx, 0))
    model.commit_gesture("Move vertex")
    assert model.undo_stack.count() == 1
    assert model.face is not sample_neutral
    assert model.face.fapu["MW"] == pytest.approx(mw0 + 4 / 1024, rel=1e-3)
    model.reset_mesh()
    assert model.face is sample_neutral
    assert np.array_equal(model.doc.vertices, sample_neutral.vertices)
    model.undo_stack.undo()
    assert model.face.fapu["MW"] > mw0


def test_folded_mesh_is_reported(model, sample_neutral):
    i = sample_neutral.fdp["8.3"]
    assert model.folded_triangles() == 0
    model.begin_gesture()
    model.preview_vertex(i, sample_neutral.vertices[sample_neutral.fdp["8.4"]])  # across the mouth
    model.commit_gesture("Move vertex")
    assert model.folded_triangles() > 0
    model.undo_stack.undo()
    assert model.folded_triangles() == 0


def test_load_clears_history(model, sample_neutral):
    model.set_faps({3: 100}, "x")
    assert model.is_dirty()
    seen = []
    model.changed.connect(lambda old, new: seen.append(old))
    model.load(sample_neutral)
    assert model.undo_stack.count() == 0 and not model.is_dirty() and seen == [None]


def test_pyside_singleton_refcount_guard(qtbot):
    """PySide6 6.12 on Python 3.11 drops a reference to None/True per call; editor.ui guards."""
    import sys

    from PySide6.QtWidgets import QSlider

    from editor.ui.qt_compat import bindings_drop_singletons

    slider = QSlider()
    before = sys.getrefcount(None)
    for i in range(20_000):  # would abort the interpreter (none_dealloc) without the guard
        slider.setValue(i % 7)
    # what matters on any bindings: 20 000 calls did not use up None's references
    assert sys.getrefcount(None) > before - 1000
    assert not bindings_drop_singletons() or sys.getrefcount(None) > 2**39


def test_singleton_guard_applies_when_bindings_drop(monkeypatch):
    """The guard itself, whatever the installed PySide6 does: with dropping bindings (faked
    here) it gives None/True a huge reference count; without, it changes nothing."""
    import sys

    from editor.ui import qt_compat

    if sys.implementation.name != "cpython" or sys.version_info >= (3, 12):
        pytest.skip("immortal singletons: no guard needed")
    monkeypatch.setattr(qt_compat, "_APPLIED", False)
    monkeypatch.setattr(qt_compat, "bindings_drop_singletons", lambda: False)
    before = sys.getrefcount(True)
    assert qt_compat.guard_singleton_refcounts() is False
    assert abs(sys.getrefcount(True) - before) < 1000
    monkeypatch.setattr(qt_compat, "bindings_drop_singletons", lambda: True)
    already = sys.getrefcount(True) > 2**39  # applied earlier in this process
    assert qt_compat.guard_singleton_refcounts() is True
    assert sys.getrefcount(True) > 2**39 and sys.getrefcount(None) > 2**39
    if not already:  # leave the counts as found (the extra references are harmless anyway)
        import ctypes

        for obj in (None, True, False, NotImplemented, Ellipsis):
            ctypes.c_ssize_t.from_address(id(obj)).value -= 1 << 40


# ---------------------------------------------------------------------- scheduler
def _fake_result(req: RenderRequest) -> RenderResult:
    return RenderResult(req, np.zeros((4, 4, 3), np.uint8), np.zeros((2, 3), np.float32))


def test_scheduler_renders_only_the_latest(qtbot):
    gate, started, first_done, ran = threading.Event(), threading.Event(), threading.Event(), []

    def render(req: RenderRequest) -> RenderResult:
        ran.append(int(req.faps[0]))
        if len(ran) == 1:
            started.set()
            gate.wait(5)
            first_done.set()
        return _fake_result(req)

    sched = RenderScheduler(render)
    shown = []
    sched.resultReady.connect(lambda r: shown.append(int(r.request.faps[0])))
    sched.submit(None, np.array([1.0]))  # type: ignore[arg-type]
    assert started.wait(2)
    sched.submit(None, np.array([2.0]))  # type: ignore[arg-type]
    sched.submit(None, np.array([3.0]))  # type: ignore[arg-type]
    # the GUI thread never waits for the worker: both submits returned while it is still held
    assert not first_done.is_set() and ran == [1]
    gate.set()
    assert sched.wait(3000)
    assert ran == [1, 3]  # the middle request never ran
    assert shown == [1, 3]
    sched.shutdown()


def test_scheduler_drops_results_after_cancel(qtbot):
    gate, started = threading.Event(), threading.Event()

    def render(req: RenderRequest) -> RenderResult:
        started.set()
        gate.wait(5)
        return _fake_result(req)

    sched = RenderScheduler(render)
    shown = []
    sched.resultReady.connect(shown.append)
    sched.submit(None, np.array([1.0]))  # type: ignore[arg-type]
    assert started.wait(2)
    sched.cancel()  # e.g. another photo was opened
    gate.set()
    qtbot.wait(100)
    assert shown == [] and sched.is_idle()
    sched.shutdown()


def test_scheduler_reports_render_errors(qtbot):
    def render(req: RenderRequest) -> RenderResult:
        raise ValueError("boom")

    sched = RenderScheduler(render)
    with qtbot.waitSignal(sched.failed, timeout=2000) as blocker:
        sched.submit(None, np.zeros(68))  # type: ignore[arg-type]
    assert "boom" in blocker.args[0]
    assert sched.is_idle()
    sched.shutdown()


def test_scheduler_renders_real_face(qtbot, sample_neutral):
    sched = RenderScheduler()
    faps = FAPS.vector({"open_jaw": 400})
    with qtbot.waitSignal(sched.rendered, timeout=5000) as blocker:
        sched.submit(sample_neutral, faps)
    image, ms = blocker.args
    assert image.shape == sample_neutral.image.shape and ms > 0
    assert np.array_equal(image, sample_neutral.render(faps))
    sched.shutdown()
