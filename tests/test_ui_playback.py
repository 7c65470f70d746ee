"""Playback (fake clock), keyframe authoring, .fap save and MP4/PNG export in the main window."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

pytest.importorskip("pytestqt")

from PySide6.QtWidgets import QPushButton  # noqa: E402

from editor.core import FAPS, Face  # noqa: E402
from editor.formats.fapfile import FapSequence, read_fap, write_fap  # noqa: E402
from editor.formats.playhead import Playhead  # noqa: E402
from editor.resources import SAMPLE_FACE
from editor.ui.main_window import MainWindow  # noqa: E402
from editor.ui.playback_panel import PlaybackPanel  # noqa: E402

pytestmark = [pytest.mark.gui, pytest.mark.usefixtures("isolated_settings")]
SAMPLE = SAMPLE_FACE
JAW = FAPS["open_jaw"].number


class FakeClock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def face(sample_neutral) -> Face:
    return sample_neutral




@pytest.fixture
def window(qtbot, face, warnings) -> MainWindow:
    w = MainWindow()
    qtbot.addWidget(w)
    w.load_face(face)
    yield w
    w.playback_panel.shutdown()
    w.close_without_prompt()


@pytest.fixture
def clock() -> FakeClock:
    return FakeClock()


@pytest.fixture
def panel(window, clock) -> PlaybackPanel:
    p = window.playback_panel
    p.playhead.clock = clock
    return p


def ramp(n: int = 10, fps: float = 10.0) -> FapSequence:
    """Frame k opens the jaw by 100·k FAPU."""
    frames = np.zeros((n, 68), np.float32)
    frames[:, JAW - 1] = 100 * np.arange(n)
    return FapSequence(frames, fps=fps, name="ramp")


@pytest.fixture
def ramp_file(tmp_path) -> Path:
    return write_fap(ramp(), tmp_path / "ramp.fap")


def jaw(window: MainWindow) -> float:
    return window.model.doc.fap("open_jaw")


def test_playhead_drops_frames_and_loops():
    c = FakeClock()
    ph = Playhead(10, 10.0, c)
    ph.play()
    assert ph.frame() == 0
    c.t += 0.1
    assert ph.frame() == 1
    c.t += 0.55  # late: 2-5 are skipped
    assert ph.frame() == 6
    c.t += 10
    assert ph.frame() == 9 and not ph.playing  # stops on the last frame
    ph.loop = True
    ph.play()  # from the start again
    c.t += 2.35
    assert ph.frame() == 3 and ph.playing


def test_open_file_menu_and_timeline(window, panel, ramp_file):
    titles = [a.text() for a in window.menu("&Animation").actions()]
    for t in ("Open FAP Sequence…", "Save FAP Sequence…", "Export Video…", "Export Frames…"):
        assert t in titles
    assert panel.open_file(str(ramp_file))
    assert panel.seq.n_frames == 10 and panel.playhead.fps == 10
    assert panel.slider.maximum() == 9
    assert "10 frames at 10 fps" in panel.info.text()
    assert panel.shown == 0 and window.model.undo_stack.count() == 1  # opening is undoable
    assert window.model.undo_stack.undoText() == "Open sequence ramp.fap"


def test_playback_with_fake_clock_shows_the_frame_for_the_time(window, panel, clock, qtbot):
    window.model.set_faps({"raise_l_i_eyebrow": 50}, "before")
    panel.load_sequence(ramp())
    shown: list[int] = []
    panel.frameShown.connect(shown.append)
    assert panel.shown == 0 and jaw(window) == 0  # frame 0 is shown on load
    panel.play()
    assert panel.playhead.playing and panel.play_button.text() == "Pause"
    clock.t += 0.1
    panel.tick()
    assert jaw(window) == 100 and panel.slider.value() == 1
    assert window.fap_panel.rows[JAW].value() == 100  # the sliders follow
    clock.t += 0.45  # t = 0.55 -> frame 5; 2-4 are dropped
    panel.tick()
    assert jaw(window) == 500 and "6 / 10" in panel.frame_label.text()
    clock.t += 0.02  # same frame: nothing new is shown
    panel.tick()
    assert shown == [1, 5]
    # the QTimer path: advance the clock, the timer picks the frame up
    clock.t += 0.3
    qtbot.waitUntil(lambda: panel.shown == 8, timeout=2000)
    clock.t += 5
    qtbot.waitUntil(lambda: not panel.playhead.playing, timeout=2000)
    assert panel.shown == 9 and jaw(window) == 900
    assert window.model.undo_stack.count() == 2  # FAPs, sequence; playback added none
    panel.stop()  # restores the FAPs from before playback
    assert jaw(window) == 0 and window.model.doc.fap("raise_l_i_eyebrow") == 50
    assert window.model.undo_stack.count() == 2


def test_loop_wraps(window, panel, clock):
    panel.load_sequence(ramp())
    panel.set_loop(True)
    assert panel.loop_box.isChecked()
    panel.play()
    clock.t += 1.25  # 10 frames at 10 fps: 1.25 s wraps to frame 2
    panel.tick()
    assert panel.shown == 2 and panel.playhead.playing and jaw(window) == 200
    clock.t += 3.0
    panel.tick()
    assert panel.shown == 2
    panel.pause()
    assert not panel.timer.isActive()


def test_scrub_and_keep_frame_is_one_undo_entry(window, panel):
    panel.load_sequence(ramp())
    panel.slider.setValue(7)
    assert jaw(window) == 700 and window.model.undo_stack.count() == 1  # the sequence
    panel.keep_frame()
    stack = window.model.undo_stack
    assert stack.count() == 2 and stack.undoText() == "Playback frame 8"
    stack.undo()
    assert jaw(window) == 0


def test_quick_action_keyframes_and_save(window, panel, tmp_path):
    window.model.set_faps({"open_jaw": 400, "raise_l_cornerlip": 120}, "pose")
    assert panel.quick_neutral_current_neutral()
    seq = panel.seq
    assert seq.n_frames == 51 and seq.fps == 25
    v = panel.vectors
    assert v[0].any() == 0 and v[-1].any() == 0
    assert v[25][JAW - 1] == 400 and v[25][FAPS["raise_l_cornerlip"].number - 1] == 120
    assert 0 < v[12][JAW - 1] < 400
    out = tmp_path / "quick.fap"
    assert panel.save_file(str(out))
    back = read_fap(out)
    assert back.n_frames == 51 and np.array_equal(back.frames, seq.frames)
    # keyframes by hand: neutral at 0, current at 1 s, smoothstep
    panel.stop()
    keys = panel.keys
    keys.clear()
    keys.time.setValue(0.0)
    window.model.reset_faps()
    keys.add_button.click()
    window.model.set_faps({"open_jaw": 800}, "pose")
    keys.time.setValue(1.0)
    keys.add_button.click()
    assert [t for t, _ in keys.keys] == [0.0, 1.0]
    keys.fps.setValue(10)
    keys.interp.setCurrentText("smoothstep")
    keys.build_button.click()
    assert panel.seq.n_frames == 11
    assert panel.vectors[5][JAW - 1] == 400 and panel.vectors[2][JAW - 1] < 160
    keys.list.setCurrentRow(0)
    keys.remove_button.click()
    assert [t for t, _ in keys.keys] == [1.0]


def test_bad_file_is_a_message_not_a_crash(window, panel, tmp_path, warnings):
    bad = tmp_path / "bad.fap"
    bad.write_text("2.1 x 25 3\n0 0 1\n", encoding="utf-8")
    assert not panel.open_file(str(bad))
    assert warnings and "bad.fap" in warnings[-1] and "\n" not in warnings[-1]
    assert panel.seq is None


def _export(panel, qtbot, kind, out):
    with qtbot.waitSignal(panel.exportFinished, timeout=20000) as sig:
        job = panel.export(kind, str(out))
        assert job is not None and job.dialog is not None
    return job, sig.args


def test_export_mp4_frame_count_and_size(window, panel, qtbot, tmp_path, face):
    panel.load_sequence(ramp(12, 25.0))
    out = tmp_path / "anim.mp4"
    _job, (result, message) = _export(panel, qtbot, "video", out)
    assert message == "" and result.frames == 12 and not result.cancelled
    cap = cv2.VideoCapture(str(out))
    h, w = face.image.shape[:2]
    assert int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)) == w
    assert int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)) == h
    n = 0
    while cap.read()[0]:
        n += 1
    cap.release()
    assert n == 12
    assert "12 frames" in window.statusBar().currentMessage()


def test_export_frames_folder(window, panel, qtbot, tmp_path):
    panel.load_sequence(ramp(5))
    out = tmp_path / "frames"
    _job, (result, message) = _export(panel, qtbot, "frames", out)
    assert message == "" and result.frames == 5
    assert len(list(out.glob("frame_*.png"))) == 5


def test_cancel_export_removes_partial_mp4(window, panel, qtbot, tmp_path):
    panel.load_sequence(ramp(600, 25.0))
    out = tmp_path / "cancelled.mp4"
    with qtbot.waitSignal(panel.exportFinished, timeout=20000) as sig:
        job = panel.export("video", str(out))
        job.dialog.findChild(QPushButton).click()  # the dialog's Cancel button
    result, message = sig.args
    assert message == "" and result.cancelled and result.frames < 600
    assert not out.exists()
    assert panel.video_button.isEnabled()


def test_preset_during_paused_playback_is_one_entry_and_pauses(window, panel, clock):
    panel.load_sequence(ramp())
    panel.play()
    clock.t += 0.3
    panel.tick()
    assert jaw(window) == 300
    window.presets_panel.apply("joy", 1.0, "replace")
    assert not panel.playhead.playing  # an edit stops playback
    stack = window.model.undo_stack
    assert stack.count() == 2 and stack.undoText() == "Apply preset joy 100 %"
    assert not window.model.in_gesture
    stack.undo()
    assert not window.model.doc.faps.any()  # back to before playback


def test_export_without_sequence_says_so(window, panel, warnings):
    assert panel.export("video", "unused.mp4") is None
    assert warnings and "nothing to export" in warnings[-1]
