"""The Action Units dock: AU sliders and FAP sliders stay consistent through the one document
model (with undo); presets as AU combinations; Animation > Import / Export CSV."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pytestqt")

from PySide6.QtCore import QPoint, Qt  # noqa: E402
from PySide6.QtWidgets import QGroupBox, QStyle, QStyleOptionSlider  # noqa: E402

from editor.core import FAPS  # noqa: E402
from editor.formats.facecsv import read_animation  # noqa: E402
from editor.formats.facs import au_table, aus_to_faps  # noqa: E402
from editor.formats.presets import apply_preset, get_preset  # noqa: E402
from editor.ui.main_window import MainWindow  # noqa: E402

pytestmark = [pytest.mark.gui, pytest.mark.usefixtures("isolated_settings")]

CORNER_L, CORNER_R = FAPS.number("raise_l_cornerlip_o") - 1, FAPS.number("raise_r_cornerlip_o") - 1


@pytest.fixture
def window(qtbot, sample_neutral, warnings):
    w = MainWindow()
    qtbot.addWidget(w)
    w.load_face(sample_neutral)
    w.show()
    qtbot.waitExposed(w)
    yield w
    w.close_without_prompt()


def _handle(slider) -> QPoint:
    opt = QStyleOptionSlider()
    slider.initStyleOption(opt)
    return slider.style().subControlRect(QStyle.ComplexControl.CC_Slider, opt,
                                         QStyle.SubControl.SC_SliderHandle, slider).center()


def test_dock_has_a_slider_per_au_side_grouped(window):
    p = window.au_panel
    assert window.au_dock.windowTitle() == "Action Units"
    assert sorted(p.sliders) == sorted(au_table().columns)
    assert "12L" in p.sliders and "12R" in p.sliders and "26" in p.sliders
    boxes = {b.title(): b for b in p.findChildren(QGroupBox)}
    assert set(boxes) == {"Upper face", "Lower face"}
    assert p.sliders["4L"].parent() is boxes["Upper face"]
    assert p.sliders["26"].parent() is boxes["Lower face"]


def test_au_drag_sets_the_faps_in_one_undo_entry(window, qtbot):
    p, model = window.au_panel, window.model
    window.au_dock.raise_()
    qtbot.waitExposed(p)
    s = p.sliders["12L"]
    start = _handle(s)
    qtbot.mousePress(s, Qt.MouseButton.LeftButton, pos=start)
    for dx in range(5, 60, 5):
        qtbot.mouseMove(s, QPoint(start.x() + dx, start.y()))
    qtbot.mouseRelease(s, Qt.MouseButton.LeftButton, pos=QPoint(start.x() + 60, start.y()))
    x = s.value() / 100
    assert x > 0.1 and p.sliders["12R"].value() == s.value()  # linked L/R
    want = aus_to_faps({"12": x})
    assert model.doc.faps[CORNER_L] == pytest.approx(want[CORNER_L], abs=1)
    assert window.fap_panel.rows[CORNER_L + 1].value() == pytest.approx(want[CORNER_L], abs=1)
    assert model.undo_stack.count() == 1 and model.undo_stack.undoText() == "Set AU12"
    model.undo_stack.undo()
    assert model.doc.faps[CORNER_L] == 0 and s.value() == 0 and p.sliders["12R"].value() == 0


def test_unlinked_side_moves_one_corner_and_keeps_other_faps(window):
    p, model = window.au_panel, window.model
    model.set_faps({"yaw_l_eyeball": 20000}, "gaze")
    p.link.setChecked(False)
    p.sliders["12L"].setValue(60)  # keyboard-style edit: one command
    assert model.doc.faps[CORNER_L] == pytest.approx(0.6 * 420, abs=1)
    assert model.doc.faps[CORNER_R] == 0 and p.sliders["12R"].value() == 0
    assert model.doc.fap("yaw_l_eyeball") == 20000  # no AU touches gaze: kept
    assert p.values["12L"].text() == "0.60 C" and model.undo_stack.undoText() == "Set AU12L"


def test_fap_edits_and_presets_show_as_aus(window):
    p, model = window.au_panel, window.model
    model.push(model.doc.with_fap_vector(apply_preset(get_preset("joy"), 1.0)), "joy")
    assert p.sliders["12L"].value() >= 90 and p.sliders["6R"].value() >= 60  # AU6 + AU12
    assert p.sliders["4L"].value() <= 10 and p.sliders["15L"].value() <= 10
    model.undo_stack.undo()
    assert all(s.value() == 0 for s in p.sliders.values())


def test_preset_as_aus_is_one_edit(window):
    p, model = window.au_panel, window.model
    p.preset_as_aus("anger")
    anger = apply_preset(get_preset("anger"), 1.0)
    assert model.undo_stack.undoText() == "anger as AUs"
    err = np.abs(model.doc.faps - anger)[anger != 0]
    assert np.sqrt(np.mean(err ** 2)) < 25  # anger's round-trip tolerance in test_facs
    assert p.sliders["4L"].value() >= 80 and p.sliders["7L"].value() >= 80


def test_import_and_export_csv(window, tmp_path, warnings):
    from editor.ui.au_panel import export_csv, import_csv

    src = tmp_path / "au.csv"
    src.write_text("frame,timestamp,AU12_r,AU26_r\n1,0.00,0,0\n2,0.04,5,2.5\n3,0.08,2.5,5\n")
    assert import_csv(window, str(src))
    pb = window.playback_panel
    assert pb.seq is not None and pb.seq.n_frames == 3 and pb.seq.fps == 25
    out = tmp_path / "out.csv"
    assert export_csv(window, str(out), "arkit")
    seq, kind, _ = read_animation(out)
    assert kind == "arkit" and np.abs(seq.frames - pb.seq.frames).max() < 30
    bad = tmp_path / "bad.csv"
    bad.write_text("frame,timestamp,AU12_r\n1,0.0,9\n")
    assert not import_csv(window, str(bad))
    assert warnings == ["bad.csv line 2, column AU12_r: expected an AU intensity (0 to 5), "
                        "got '9'"]
    assert window.playback_panel.seq.n_frames == 3  # the old sequence stays
    texts = [a.text() for a in window.menu("&Animation").actions()]
    assert any(t.startswith("Import CSV") for t in texts)
