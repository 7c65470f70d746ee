"""The Model dock (bilinear synthesis, Convert to FAPs) and the Tools-menu cloning actions."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pytestqt")

from PySide6.QtWidgets import QMessageBox  # noqa: E402

from editor.core import save_image  # noqa: E402
from editor.formats.fapfile import read_fap  # noqa: E402
from editor.formats.presets import apply_preset  # noqa: E402
from editor.resources import SAMPLE_FACE
from editor.synthesis.bilinear import save_model  # noqa: E402
from editor.synthesis.bilinear_photo import synthetic_model68  # noqa: E402
from editor.ui.main_window import MainWindow  # noqa: E402

pytestmark = [pytest.mark.gui, pytest.mark.usefixtures("isolated_settings")]
SAMPLE = SAMPLE_FACE


class Boxes:
    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.warnings: list[str] = []
        self.infos: list[str] = []
        monkeypatch.setattr(QMessageBox, "warning",
                            lambda _p, _t, text, *a, **k: self.warnings.append(text))
        monkeypatch.setattr(QMessageBox, "information",
                            lambda _p, _t, text, *a, **k: self.infos.append(text))
        monkeypatch.setattr(QMessageBox, "question",  # unsaved changes at close: discard
                            lambda *a, **k: QMessageBox.StandardButton.Discard)


@pytest.fixture
def boxes(monkeypatch) -> Boxes:
    return Boxes(monkeypatch)


@pytest.fixture
def window(qtbot, sample_neutral, boxes):
    w = MainWindow()
    qtbot.addWidget(w)
    w.load_face(sample_neutral)
    w.show()
    qtbot.waitExposed(w)
    yield w
    w.close_without_prompt()


def ext(window):
    return window.extensions["model_panel"]


def test_installed(window):
    e = ext(window)
    assert e.dock.windowTitle() == "Model"
    texts = [a.text() for a in window.menu("&Tools").actions()]
    assert "Clone from &Photo…" in texts and "&Track Video…" in texts
    assert not e.panel.synth_button.isEnabled()  # no model yet


def test_load_model_file_and_errors(window, boxes, tmp_path, sample_neutral):
    panel = ext(window).panel
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"junk")
    assert not panel.load_model(str(bad))
    assert len(boxes.warnings) == 1 and "\n" not in boxes.warnings[0]
    good = tmp_path / "toy.npz"
    save_model(synthetic_model68(sample_neutral.landmarks.points), good)
    assert panel.load_model(str(good))
    assert panel.expression.currentText() == "joy" and panel.synth_button.isEnabled()
    panel.mix.setText("joy:x")
    assert panel.synthesize() is None and "bad weight" in boxes.warnings[-1]


def test_synthesize_and_convert_to_faps(window, sample_neutral):
    panel = ext(window).panel
    panel.set_model(synthetic_model68(sample_neutral.landmarks.points))
    panel.expression.setCurrentText("surprise")
    res = panel.synthesize()
    assert res is not None and res.image is not None
    assert not panel.preview.pixmap().isNull()
    stack = window.model.undo_stack
    n0 = stack.count()
    faps = panel.convert_to_faps()
    assert faps is not None
    assert stack.count() == n0 + 1
    doc_faps = window.model.doc.faps
    assert doc_faps[4] < -200 and (doc_faps[30:36] > 100).all()  # lower lip down, brows up
    assert window.fap_panel is not None
    stack.undo()
    assert not window.model.doc.faps.any()
    stack.redo()
    # the mix field overrides the combo
    panel.mix.setText("joy")
    panel.method.setCurrentIndex(1)
    panel.convert_to_faps()
    assert stack.count() == n0 + 2
    assert window.model.doc.faps[11] > 100  # raise_l_cornerlip (FAP 12)


def test_clone_from_photo(window, tmp_path, sample_neutral, boxes):
    # the tool opens the performer's neutral photo declared neutral: the expression photo is
    # joy on that face (joy on the neutralised sample is about the photo's own smile)
    expr = tmp_path / "joy.png"
    preset = apply_preset("joy")
    save_image(expr, sample_neutral.render(preset))
    stack = window.model.undo_stack
    n0 = stack.count()
    faps = ext(window).tools.clone_from_photos(str(SAMPLE), str(expr))
    assert faps is not None and stack.count() == n0 + 1, boxes.warnings
    got = window.model.doc.faps
    big = np.flatnonzero(np.abs(preset) >= 100)
    big = [i for i in big if i + 1 in (4, 5, 6, 7, 12, 13, 31, 32, 33, 34, 35, 36, 51, 52, 53,
                                       54, 59, 60)]
    assert big, "the joy preset moves observable FAPs"
    agree = np.sign(got[big]) == np.sign(preset[big])
    assert agree.mean() >= 0.75, dict(zip([i + 1 for i in big], got[big], strict=True))


def test_clone_errors_never_crash(window, boxes, tmp_path):
    blank = tmp_path / "blank.png"
    save_image(blank, np.full((120, 160, 3), 90, np.uint8))
    n0 = window.model.undo_stack.count()
    assert ext(window).tools.clone_from_photos(str(SAMPLE), str(blank)) is None
    assert ext(window).tools.clone_from_photos(str(tmp_path / "nope.png"), str(SAMPLE)) is None
    assert len(boxes.warnings) == 2 and all("\n" not in t for t in boxes.warnings)
    assert window.model.undo_stack.count() == n0


def test_track_video(window, boxes, tmp_path, sample_neutral):
    import cv2

    video = tmp_path / "perf.avi"
    h, w = sample_neutral.image.shape[:2]
    vw = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (w, h))
    assert vw.isOpened()
    joy = sample_neutral.render(apply_preset("joy"))
    frames = [sample_neutral.image, joy, np.zeros_like(joy), joy]
    for f in frames:
        vw.write(cv2.cvtColor(np.ascontiguousarray(f), cv2.COLOR_RGB2BGR))
    vw.release()
    out = tmp_path / "anim.fap"
    rep = ext(window).tools.track_video(str(video), str(out))
    assert rep is not None and rep.frames == 4 and rep.missing == [2]
    seq = read_fap(out)
    assert seq.n_frames == 4
    assert boxes.infos and "1 frame(s) without a face" in boxes.infos[-1]
    assert ext(window).tools.track_video(str(tmp_path / "none.avi"), str(tmp_path / "x.fap")) \
        is None
    assert boxes.warnings and not (tmp_path / "x.fap").exists()
