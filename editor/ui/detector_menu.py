"""Settings > Landmark Detector: which detector finds the landmarks of the photos opened next.

``install(window)`` adds the menu (MediaPipe, the default, and dlib, enabled only when its
optional extra is installed) and returns the :class:`DetectorMenu`. The choice is stored with
QSettings (``landmarks/detector``) and applied when the window starts, unless the command line
(``fap-studio gui --detector``) or ``$FAP_STUDIO_DETECTOR`` chose one for this session.
"""

from __future__ import annotations

from typing import Any

from PySide6.QtGui import QAction, QActionGroup

from editor.engine import landmarks
from editor.errors import FapStudioError

from .qt_utils import settings

KEY = "landmarks/detector"
LABELS = {"mediapipe": "&MediaPipe Face Mesh (default, Apache-2.0)",
          "dlib": "&dlib 68 Points (optional extra, non-commercial model)"}
TIPS = {"mediapipe": "Find landmarks with MediaPipe's face mesh and iris models (shipped, "
                     "Apache-2.0; used for the next photo you open)",
        "dlib": "Find landmarks with dlib's 68-point model (optional extra; its iBUG 300-W "
                "training data exclude commercial use; used for the next photo you open)"}


class DetectorMenu:
    """The radio actions of the detector choice."""

    def __init__(self, window: Any) -> None:
        self.window = window
        self.group = QActionGroup(window)
        self.group.setExclusive(True)
        self.actions: dict[str, QAction] = {}
        menu = window.menu("&Settings").addMenu("Landmark &Detector")
        for name in landmarks.DETECTOR_NAMES:
            act = QAction(LABELS[name], window)
            act.setCheckable(True)
            act.setStatusTip(TIPS[name])
            if name == "dlib" and not landmarks.dlib_available():
                act.setEnabled(False)
                act.setToolTip("not installed: pip install 'fap-studio[dlib]'")
                act.setStatusTip("dlib is not installed: pip install 'fap-studio[dlib]'")
            act.triggered.connect(lambda _=False, n=name: self.choose(n))
            self.group.addAction(act)
            menu.addAction(act)
            self.actions[name] = act
        stored = str(settings().value(KEY, "") or "")
        if stored and not landmarks.default_detector_is_explicit():
            try:
                landmarks.set_default_detector(stored, explicit=False)
            except FapStudioError:  # e.g. dlib chosen earlier, since uninstalled
                pass
        self._sync()

    def _sync(self) -> None:
        self.actions[landmarks.default_detector_name()].setChecked(True)

    def choose(self, name: str) -> None:
        """Use ``name`` for the photos opened from now on and remember it."""
        try:
            landmarks.set_default_detector(name, explicit=False)
        except FapStudioError as e:
            self.window.statusBar().showMessage(str(e), 8000)
        else:
            settings().setValue(KEY, name)
            self.window.statusBar().showMessage(
                f"landmark detector: {name} (used for the next photo you open)", 8000)
        self._sync()


def install(window: Any) -> DetectorMenu:
    return DetectorMenu(window)
