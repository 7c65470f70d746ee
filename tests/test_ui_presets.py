"""The preset panel in the real main window: apply, intensity, add, blends, user presets."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pytestqt")

from PySide6.QtWidgets import QInputDialog, QMessageBox  # noqa: E402

from editor.core import FAPS, Face  # noqa: E402
from editor.formats.blends import blend_expressions, blend_visemes  # noqa: E402
from editor.formats.presets import apply_preset, shipped_presets  # noqa: E402
from editor.resources import SAMPLE_FACE
from editor.ui.main_window import MainWindow  # noqa: E402
from editor.ui.presets_panel import ADD, REPLACE, PresetsPanel  # noqa: E402

pytestmark = [pytest.mark.gui, pytest.mark.usefixtures("isolated_settings")]
SAMPLE = SAMPLE_FACE
LIP_CORNERS = ("raise_l_cornerlip", "raise_r_cornerlip", "raise_l_cornerlip_o",
               "raise_r_cornerlip_o")


@pytest.fixture
def face(sample_neutral) -> Face:
    return sample_neutral




@pytest.fixture
def data_dir(tmp_path, monkeypatch) -> Path:
    d = tmp_path / "data"
    monkeypatch.setenv("FAP_STUDIO_DATA_DIR", str(d))
    return d


@pytest.fixture
def window(qtbot, face, warnings, data_dir) -> MainWindow:
    w = MainWindow()
    qtbot.addWidget(w)
    w.load_face(face)
    yield w
    w.close_without_prompt()


@pytest.fixture
def panel(window) -> PresetsPanel:
    return window.presets_panel


def _fap(window: MainWindow, name: str) -> float:
    return window.model.doc.fap(name)


def test_panel_is_docked_and_lists_emotions_visemes(window, panel):
    assert window.extensions["presets_panel"] is panel
    assert window.presets_dock.widget() is panel
    names = {panel.list.item(i).data(256) for i in range(panel.list.count())}
    for n in ("joy", "sadness", "anger", "fear", "disgust", "surprise", "viseme_aa"):
        assert n in names
    assert panel.problems_label.isHidden()


def test_apply_joy_is_one_undo_entry_and_undo_restores(window, panel):
    stack = window.model.undo_stack
    panel.select("joy")
    panel.intensity.setValue(80)
    panel.apply_button.click()
    assert stack.count() == 1
    assert stack.undoText() == "Apply preset joy 80 %"
    for n in LIP_CORNERS:
        assert _fap(window, n) > 0
    assert _fap(window, "open_jaw") > 0
    expected = apply_preset(shipped_presets()["joy"], 0.8)
    assert np.allclose(window.model.doc.faps, expected)
    # the FAP sliders follow
    assert window.fap_panel.rows[FAPS["open_jaw"].number].value() == pytest.approx(
        float(expected[2]))
    stack.undo()
    assert not window.model.doc.faps.any()


def test_intensity_scales_and_clamps(window, panel):
    joy = shipped_presets()["joy"].vector
    panel.apply("joy", 0.5)
    half = window.model.doc.faps.copy()
    assert np.allclose(half, joy * 0.5)
    panel.apply("joy", 1.5)
    full = window.model.doc.faps
    assert np.allclose(full, FAPS.clamp(joy * 1.5))
    assert _fap(window, "open_jaw") == pytest.approx(1.5 * joy[2])
    assert window.model.undo_stack.undoText() == "Apply preset joy 150 %"


def test_replace_vs_add(window, panel):
    window.model.set_faps({"raise_l_i_eyebrow": 100}, "brow")
    panel.mode.setCurrentIndex(panel.mode.findData(REPLACE))
    panel.apply("surprise", 1.0)
    surprise = shipped_presets()["surprise"].vector
    assert np.allclose(window.model.doc.faps, surprise)
    window.model.undo_stack.undo()
    panel.mode.setCurrentIndex(panel.mode.findData(ADD))
    panel.apply("joy", 1.0)
    joy = shipped_presets()["joy"].vector
    brow = FAPS["raise_l_i_eyebrow"].number - 1
    assert _fap(window, "raise_l_i_eyebrow") == pytest.approx(100 + joy[brow])
    assert _fap(window, "open_jaw") == pytest.approx(joy[2])
    assert window.model.undo_stack.undoText() == "Add preset joy 100 %"


def test_expression_and_viseme_blends(window, panel):
    panel.expr1.setCurrentIndex(1)  # joy
    panel.int1.setValue(63)
    panel.expr2.setCurrentIndex(6)  # surprise
    panel.int2.setValue(21)
    panel.blend_expr_button.click()
    assert np.allclose(window.model.doc.faps, blend_expressions(1, 63, 6, 21))
    assert window.model.undo_stack.count() == 1
    panel.vis1.setCurrentIndex(10)  # aa
    panel.vis2.setCurrentIndex(14)  # u
    panel.vis_blend.setValue(42)
    panel.blend_vis_button.click()
    assert np.allclose(window.model.doc.faps, blend_visemes(10, 14, 42))
    assert window.model.undo_stack.count() == 2


def test_save_user_preset_and_refuse_shipped_name(window, panel, data_dir, warnings,
                                                  monkeypatch):
    window.model.set_faps({"open_jaw": 300, "raise_l_cornerlip": 80}, "edit")
    monkeypatch.setattr(QInputDialog, "getText", lambda *a, **k: ("my_grin", True))
    assert panel.save_current()
    saved = data_dir / "presets" / "my_grin.json"
    assert saved.is_file()
    assert panel.selected_name() == "my_grin"
    assert panel.presets["my_grin"].faps == {"open_jaw": 300.0, "raise_l_cornerlip": 80.0}
    window.model.reset_faps()
    panel.apply("my_grin", 1.0)
    assert _fap(window, "open_jaw") == 300
    # saving again under the same name asks first (the fixture answers Discard = no)
    window.model.set_faps({"open_jaw": 10}, "edit")
    assert not panel.save_current("my_grin")
    monkeypatch.setattr(QMessageBox, "question", lambda *a, **k: QMessageBox.StandardButton.Yes)
    assert panel.save_current("my_grin")
    assert panel.presets["my_grin"].faps["open_jaw"] == 10
    # a shipped name (any case) is refused with a message, nothing written
    assert not panel.save_current("Joy")
    assert warnings and "shipped" in warnings[-1]
    assert not (data_dir / "presets" / "Joy.json").exists()
    assert "\n" not in warnings[-1]


def test_malformed_user_preset_is_listed_not_raised(qtbot, face, warnings, data_dir):
    d = data_dir / "presets"
    d.mkdir(parents=True)
    (d / "broken.json").write_text("{not json", encoding="utf-8")
    (d / "joy.json").write_text('{"format": "fap-studio-preset", "version": 1, "kind": '
                                '"custom", "name": "joy", "faps": {}}', encoding="utf-8")
    w = MainWindow()
    qtbot.addWidget(w)
    w.load_face(face)
    p = w.presets_panel
    assert not p.problems_label.isHidden()
    assert "broken.json" in p.problems_label.text()
    assert "shipped name" in p.problems_label.text()
    assert p.presets["joy"].shipped  # the shipped joy is untouched
    p.apply("nope", 1.0)
    assert warnings and "unknown preset" in warnings[-1]
    w.close_without_prompt()
