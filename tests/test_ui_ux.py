"""Issue 17: the editor as a desktop user expects it (defects 1-9, each with a test that fails
without its fix). Real widgets, offscreen."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pytestqt")

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
