"""Settings > Landmark Detector: the choice is shown, applied and remembered (QSettings)."""

from __future__ import annotations

import pytest

pytest.importorskip("pytestqt")

from editor.engine import landmarks  # noqa: E402
from editor.ui.detector_menu import KEY  # noqa: E402
from editor.ui.main_window import MainWindow  # noqa: E402
from editor.ui.qt_utils import settings  # noqa: E402

pytestmark = [pytest.mark.gui, pytest.mark.usefixtures("isolated_settings")]


@pytest.fixture(autouse=True)
def session_default(monkeypatch):
    """Each test starts from the installed default and leaves the process's default alone."""
    monkeypatch.delenv(landmarks.DETECTOR_ENV, raising=False)
    monkeypatch.setattr(landmarks, "_DEFAULT_NAME", None)
    monkeypatch.setattr(landmarks, "_EXPLICIT", False)


def _window(qtbot) -> MainWindow:
    w = MainWindow()
    qtbot.addWidget(w)
    return w


def test_menu_shows_mediapipe_by_default(qtbot):
    w = _window(qtbot)
    menu = w.extensions["detector_menu"]
    assert w.menu("&Settings").actions()[0].text().replace("&", "") == "Landmark Detector"
    assert menu.actions["mediapipe"].isChecked()
    assert menu.actions["dlib"].isEnabled() == landmarks.dlib_available()
    assert landmarks.default_detector_name() == "mediapipe"
    w.close_without_prompt()


@pytest.mark.skipif(not landmarks.dlib_available(), reason="dlib (optional extra) not installed")
def test_choice_is_applied_and_remembered(qtbot):
    w = _window(qtbot)
    w.extensions["detector_menu"].choose("dlib")
    assert landmarks.default_detector_name() == "dlib" and settings().value(KEY) == "dlib"
    w.close_without_prompt()
    landmarks._DEFAULT_NAME = None  # a new session: the stored choice is applied at start
    w2 = _window(qtbot)
    assert landmarks.default_detector_name() == "dlib"
    assert w2.extensions["detector_menu"].actions["dlib"].isChecked()
    w2.close_without_prompt()


def test_command_line_choice_wins_over_the_stored_one(qtbot):
    settings().setValue(KEY, "dlib")
    landmarks.set_default_detector("mediapipe")  # as `fap-studio gui --detector mediapipe`
    w = _window(qtbot)
    assert landmarks.default_detector_name() == "mediapipe"
    assert w.extensions["detector_menu"].actions["mediapipe"].isChecked()
    w.close_without_prompt()


@pytest.mark.skipif(landmarks.dlib_available(), reason="dlib is installed here")
def test_missing_dlib_is_refused_with_a_message(qtbot):
    settings().setValue(KEY, "dlib")  # chosen once, since uninstalled: ignored
    w = _window(qtbot)
    menu = w.extensions["detector_menu"]
    assert landmarks.default_detector_name() == "mediapipe"
    menu.choose("dlib")
    assert landmarks.default_detector_name() == "mediapipe"
    assert "fap-studio[dlib]" in w.statusBar().currentMessage()
    w.close_without_prompt()
