"""The preset gallery: thumbnails of the current face, click to apply."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pytestqt")

from PySide6.QtCore import Qt  # noqa: E402
from PySide6.QtGui import QImage  # noqa: E402
from PySide6.QtWidgets import QMessageBox  # noqa: E402

from editor.core import FAPS, Face  # noqa: E402
from editor.formats.presets import apply_preset, get_preset, shipped_presets  # noqa: E402
from editor.resources import SAMPLE_FACE
from editor.ui.main_window import MainWindow  # noqa: E402

pytestmark = [pytest.mark.gui, pytest.mark.usefixtures("isolated_settings")]
SAMPLE = SAMPLE_FACE


@pytest.fixture
def face(sample_neutral) -> Face:
    return sample_neutral


@pytest.fixture
def window(qtbot, face, tmp_path, monkeypatch) -> MainWindow:
    monkeypatch.setenv("FAP_STUDIO_DATA_DIR", str(tmp_path / "data"))
    monkeypatch.setattr(QMessageBox, "question",
                        lambda *a, **k: QMessageBox.StandardButton.Discard)
    w = MainWindow()
    qtbot.addWidget(w)
    w.load_face(face)
    w.preset_gallery.rebuild()
    yield w
    w.close_without_prompt()


def _pixels(icon) -> np.ndarray:
    img = icon.pixmap(96, 96).toImage().convertToFormat(QImage.Format.Format_RGB888)
    ptr = np.frombuffer(img.constBits(), np.uint8, img.sizeInBytes())
    return ptr.reshape(img.height(), img.bytesPerLine())[:, : img.width() * 3].copy()


def test_one_thumbnail_per_preset_and_they_differ(window):
    g = window.preset_gallery
    assert set(g.names()) >= set(shipped_presets())
    items = {g.view.item(i).data(Qt.ItemDataRole.UserRole): g.view.item(i)
             for i in range(g.view.count())}
    joy, surprise = _pixels(items["joy"].icon()), _pixels(items["surprise"].icon())
    assert joy.size > 0 and joy.std() > 10  # a real picture
    assert np.abs(joy.astype(int) - surprise.astype(int)).mean() > 1.0


def test_click_applies_with_panel_intensity_as_one_undo_entry(window, qtbot):
    g = window.preset_gallery
    window.presets_panel.intensity.setValue(50)
    before = window.model.undo_stack.count()
    row = g.names().index("joy")
    rect = g.view.visualItemRect(g.view.item(row))
    qtbot.mouseClick(g.view.viewport(), Qt.MouseButton.LeftButton, pos=rect.center())
    assert window.model.undo_stack.count() == before + 1
    expected = FAPS.clamp(apply_preset(get_preset("joy"), 0.5))
    assert np.allclose(window.model.doc.faps, expected)
    window.model.undo_stack.undo()
    assert not window.model.doc.faps.any()
