"""FAP panel (sliders, spin boxes, groups, filter, link, resets) and the gaze pad."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pytestqt")

from PySide6.QtCore import QPoint, Qt  # noqa: E402
from PySide6.QtWidgets import QStyle, QStyleOptionSlider  # noqa: E402

from editor.core import FAPS  # noqa: E402
from editor.ui.fap_panel import FapPanel  # noqa: E402
from editor.ui.gaze_pad import GazePad  # noqa: E402

pytestmark = [pytest.mark.gui, pytest.mark.usefixtures("isolated_settings")]




@pytest.fixture
def panel(qtbot, model) -> FapPanel:
    p = FapPanel(model)
    qtbot.addWidget(p)
    p.resize(480, 900)
    p.show()
    qtbot.waitExposed(p)
    return p


def _handle_center(slider) -> QPoint:
    opt = QStyleOptionSlider()
    slider.initStyleOption(opt)
    r = slider.style().subControlRect(QStyle.ComplexControl.CC_Slider, opt,
                                      QStyle.SubControl.SC_SliderHandle, slider)
    return r.center()


def test_every_fap_has_a_row_with_range_and_tooltip(panel):
    assert sorted(panel.rows) == list(range(3, 69))
    assert [g.name for g in panel.groups][:3] == ["jaw, chin, inner lips", "eyes", "eyebrows"]
    for n, row in panel.rows.items():
        lo, hi = FAPS[n].range
        assert (row.slider.minimum(), row.slider.maximum()) == (lo, hi)
        assert (row.spin.minimum(), row.spin.maximum()) == (lo, hi)
        assert row.slider.toolTip() == FAPS[n].tooltip and FAPS[n].unit in row.spin.suffix()


def test_model_to_widgets(panel, model):
    model.set_faps({"open_jaw": 321, "raise_l_i_eyebrow": -120}, "x")
    assert panel.rows[3].slider.value() == 321 and panel.rows[3].spin.value() == 321
    assert panel.rows[31].slider.value() == -120
    assert model.undo_stack.count() == 1  # writing back did not echo into the model
    model.undo_stack.undo()
    assert panel.rows[3].slider.value() == 0 and panel.rows[31].spin.value() == 0


def test_spin_box_to_model_merges_steps(panel, model, qtbot):
    spin = panel.rows[3].spin
    spin.setFocus()
    for _ in range(5):
        qtbot.keyClick(spin, Qt.Key.Key_Up)
    step = spin.singleStep()
    assert model.doc.fap(3) == 5 * step and panel.rows[3].slider.value() == 5 * step
    assert model.undo_stack.count() == 1  # steps on one FAP merge into one entry
    spin.editingFinished.emit()  # focus out / Enter ends the merge
    qtbot.keyClick(spin, Qt.Key.Key_Up)
    assert model.undo_stack.count() == 2


def test_out_of_range_values_cannot_be_entered(panel, model, qtbot):
    row = panel.rows[3]  # open_jaw: 0 .. 1080 MNS
    lo, hi = FAPS[3].range
    row.spin.setValue(10**6)
    assert row.spin.value() == hi and model.doc.fap(3) == hi
    row.spin.lineEdit().selectAll()
    qtbot.keyClicks(row.spin.lineEdit(), "-500")
    qtbot.keyClick(row.spin.lineEdit(), Qt.Key.Key_Return)
    assert lo <= model.doc.fap(3) <= hi
    row.slider.setValue(-99999)
    assert model.doc.fap(3) == lo
    model.set_faps({3: 99999}, "clamped in the model too")
    assert model.doc.fap(3) == hi


def test_slider_drag_is_one_undo_entry(panel, model, qtbot):
    slider = panel.rows[3].slider
    start = _handle_center(slider)
    seen = []
    model.changed.connect(lambda old, new: seen.append(new.fap(3)))
    qtbot.mousePress(slider, Qt.MouseButton.LeftButton, pos=start)
    assert model.in_gesture
    for dx in range(5, 80, 5):
        qtbot.mouseMove(slider, QPoint(start.x() + dx, start.y()))
    qtbot.mouseRelease(slider, Qt.MouseButton.LeftButton, pos=QPoint(start.x() + 80, start.y()))
    assert not model.in_gesture
    assert len(set(seen)) > 3  # the preview followed the drag
    assert model.doc.fap(3) > 0 and model.undo_stack.count() == 1
    assert model.undo_stack.undoText() == "Set open_jaw"
    model.undo_stack.undo()
    assert model.doc.fap(3) == 0 and slider.value() == 0


def test_link_toggle_moves_the_mirror(panel, model):
    stretch_l = FAPS["stretch_l_cornerlip"]
    assert stretch_l.mirror == FAPS["stretch_r_cornerlip"].number
    panel.rows[stretch_l.number].spin.setValue(120)
    assert model.doc.fap(stretch_l.mirror) == 0  # not linked yet
    panel.link.setChecked(True)
    panel.rows[stretch_l.number].spin.setValue(200)
    assert model.doc.fap(stretch_l.mirror) == 200
    assert panel.rows[stretch_l.mirror].slider.value() == 200
    # a linked slider drag: still one entry, both FAPs move
    n = model.undo_stack.count()
    row = panel.rows[FAPS["raise_l_i_eyebrow"].number]
    row.slider.setSliderDown(True)
    for v in (50, 100, 150):
        row.slider.setValue(v)
    row.slider.setSliderDown(False)
    assert model.undo_stack.count() == n + 1
    assert model.doc.fap("raise_r_i_eyebrow") == 150
    panel.rows[stretch_l.number].reset.click()
    assert model.doc.fap(stretch_l.number) == 0 and model.doc.fap(stretch_l.mirror) == 0


def test_filter_by_name_and_number(panel):
    assert panel.apply_filter("eyebrow") == 8
    visible = [n for n, r in panel.rows.items() if not r.isHidden()]
    assert all("eyebrow" in FAPS[n].name for n in visible) and len(visible) == 8
    assert panel.apply_filter("23") == 1 and not panel.rows[23].isHidden()
    assert panel.rows[3].isHidden()
    shown_groups = [g.name for g in panel.groups if not g.isHidden()]
    assert shown_groups == ["eyes"]
    panel.filter.setText("zzz")
    assert panel.empty.isVisible()
    panel.filter.setText("")
    assert all(not r.isHidden() for r in panel.rows.values()) and not panel.empty.isVisible()
    panel.groups[0].set_expanded(False)  # a closed group opens while its FAPs match ...
    panel.filter.setText("open")
    assert panel.groups[0].is_expanded() and not panel.rows[3].isHidden()
    panel.filter.setText("")  # ... and closes again when the filter is cleared
    assert not panel.groups[0].is_expanded() and panel.groups[1].is_expanded()


def test_collapsible_groups(panel):
    g = panel.groups[0]
    g.header.click()
    assert not g.is_expanded() and g.body.isHidden()
    panel.expand_all.click()
    assert all(x.is_expanded() for x in panel.groups)
    panel.collapse_all.click()
    assert not any(x.is_expanded() for x in panel.groups)


def test_resets_per_fap_group_and_all(panel, model):
    model.set_faps({3: 300, 4: 100, 31: 200, 48: 5000}, "x")
    panel.rows[3].reset.click()
    assert model.doc.fap(3) == 0 and model.doc.fap(4) == 100
    panel.groups[0].reset.click()  # jaw group
    assert model.doc.fap(4) == 0 and model.doc.fap(31) == 200
    panel.reset_all.click()
    assert not model.doc.faps.any()
    assert model.undo_stack.count() == 4
    model.undo_stack.undo()
    assert model.doc.fap(31) == 200 and model.doc.fap(48) == 5000


def test_gaze_pad_moves_both_irises(qtbot, model):
    pad = GazePad(model)
    qtbot.addWidget(pad)
    pad.resize(200, 200)
    pad.show()
    qtbot.waitExposed(pad)
    iris0 = model.face.feature_points(model.doc.faps)
    r = pad.pad_rect()
    target = QPoint(int(r.right() - 10), int(r.bottom() - 10))  # right and down
    qtbot.mousePress(pad, Qt.MouseButton.LeftButton, pos=r.center().toPoint())
    qtbot.mouseMove(pad, target)
    qtbot.mouseRelease(pad, Qt.MouseButton.LeftButton, pos=target)
    f = model.doc
    assert f.fap(23) == f.fap(24) > 0 and f.fap(25) == f.fap(26) > 0
    assert model.undo_stack.count() == 1
    iris1 = model.face.feature_points(f.faps)
    for k in ("3.5", "3.6"):  # both irises move right (x) and down (y)
        assert iris1[k][0] > iris0[k][0] + 0.5 and iris1[k][1] > iris0[k][1] + 0.5
    assert pad.position[0] > 0.5 and pad.position[1] > 0.5
    qtbot.mouseDClick(pad, Qt.MouseButton.LeftButton, pos=target)
    assert not model.doc.faps[22:26].any() and np.allclose(pad.position, 0)
    model.set_faps({23: -25000, 24: -25000}, "from elsewhere")
    assert pad.position[0] == pytest.approx(-0.5)
