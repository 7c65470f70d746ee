"""Tools-menu actions of issue 10: "Clone from Photo…" and "Track Video…".

Both measure FAPs from a performer (:mod:`editor.synthesis.fap_estimate`, the FAP route of SPEC §6):
the neutral/expression pair or every video frame against the first, in the performer's own
FAPU, so the vector applies unchanged to the current photo. Clone results land on the sliders as
one undo entry; a tracked video is saved as a .fap sequence (frames without a face are filled by
interpolation and reported). Errors become a message box with the one-line error text.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from PySide6.QtCore import Qt
from PySide6.QtGui import QGuiApplication
from PySide6.QtWidgets import QFileDialog, QMessageBox, QWidget

from editor.errors import Cancelled

from .qt_utils import error_text, run_guarded
from .tasks import Progress, run_task

IMAGE_FILTER = "Images (*.png *.jpg *.jpeg *.bmp *.tif *.tiff);;All files (*)"
VIDEO_FILTER = "Videos (*.mp4 *.avi *.mov *.mkv *.webm);;All files (*)"


class WaitCursor:
    """Context manager: the wait cursor while a long computation runs."""

    def __enter__(self) -> WaitCursor:
        QGuiApplication.setOverrideCursor(Qt.CursorShape.WaitCursor)
        return self

    def __exit__(self, *exc: object) -> None:
        QGuiApplication.restoreOverrideCursor()


def report_error(parent: QWidget | None, title: str, exc: BaseException) -> None:
    """One-line message box for an exception (see :func:`qt_utils.error_text`)."""
    QMessageBox.warning(parent, title, error_text(exc))


def guarded(parent: QWidget | None, title: str, fn: Callable[[], Any]) -> Any:
    """Run ``fn`` with the wait cursor; any exception becomes a message box (returns None)."""
    return run_guarded(parent, title, fn, busy=True)[1]


def estimate_clone_faps(neutral: str | Path, expression: str | Path) -> np.ndarray:
    """(68,) FAPs (performer FAPU) of the performer's expression photo against the neutral."""
    from editor.engine.face import Face
    from editor.engine.imageio import load_image
    from editor.engine.landmarks import detect_landmarks
    from editor.errors import NoFaceError
    from editor.synthesis.fap_estimate import FapEstimator

    src = Face.from_image(neutral, own_expression=False)
    try:
        lm = detect_landmarks(load_image(expression))
    except NoFaceError as exc:
        raise NoFaceError(f"{expression}: {exc}") from None
    return np.asarray(FapEstimator(src).estimate(lm.points).faps, np.float32)


class CloneTools:
    """The two Tools-menu actions, bound to a main window."""

    def __init__(self, window: Any) -> None:
        self.window = window
        tools = window.menu("&Tools")
        self.act_clone = tools.addAction("Clone from &Photo…")
        self.act_clone.setStatusTip("Measure FAPs from a performer's neutral and expression "
                                    "photos and put them on the sliders")
        self.act_clone.triggered.connect(lambda _c=False: self.clone_from_photos())
        self.act_track = tools.addAction("&Track Video…")
        self.act_track.setStatusTip("Measure FAPs in every frame of a performer video and save "
                                    "them as a .fap animation")
        self.act_track.triggered.connect(lambda _c=False: self.track_video())
        self.last_track: Any = None

    # ------------------------------------------------------------------ clone
    def clone_from_photos(self, neutral: str | None = None, expression: str | None = None
                          ) -> np.ndarray | None:
        """Ask for the two photos (unless given), estimate, apply as one undo entry."""
        w = self.window
        if w.model.doc is None:
            QMessageBox.warning(w, "Clone from Photo", "Open a photo first.")
            return None
        if neutral is None:
            neutral, _ = QFileDialog.getOpenFileName(w, "Performer's neutral photo", "",
                                                     IMAGE_FILTER)
            if not neutral:
                return None
        if expression is None:
            expression, _ = QFileDialog.getOpenFileName(w, "Performer's expression photo",
                                                        str(Path(neutral).parent), IMAGE_FILTER)
            if not expression:
                return None
        faps = guarded(w, "Clone from Photo", lambda: run_task(
            w, "Measuring the performer's expression…",
            lambda _p: estimate_clone_faps(neutral, expression), title="Clone from Photo"))
        if faps is None:
            return None
        values = {i + 1: float(v) for i, v in enumerate(faps) if i >= 2}
        w.model.set_faps(values, f"Clone from {Path(expression).name}")
        w.statusBar().showMessage(f"Cloned {Path(expression).name}: "
                                  f"{int(np.count_nonzero(np.round(faps)))} FAPs set", 6000)
        return faps

    # ------------------------------------------------------------------ track
    def track_video(self, video: str | None = None, output: str | None = None) -> Any:
        """Ask for a video and a .fap file (unless given), track on the thread pool with a
        cancellable progress dialog, save, and report the frames without a face. Returns the
        TrackReport."""
        from editor.formats.fapfile import write_fap
        from editor.synthesis.fap_estimate import track_video

        w = self.window
        if video is None:
            video, _ = QFileDialog.getOpenFileName(w, "Performer video", "", VIDEO_FILTER)
            if not video:
                return None
        if output is None:
            output, _ = QFileDialog.getSaveFileName(w, "Save FAP animation",
                                                    str(Path(video).with_suffix(".fap")),
                                                    "FAP animation (*.fap)")
            if not output:
                return None
        cancelled = False

        def track(progress: Progress) -> Any:
            nonlocal cancelled

            def step(done: int, total: int) -> bool:
                if progress.cancelled:
                    return False  # track_video stops and reports a cancelled track
                progress(done, total, f"Tracking frame {done} of {total}…")
                return True

            seq, rep = track_video(video, progress=step)
            cancelled = bool(rep.cancelled) or progress.cancelled  # nothing is written then
            return rep if cancelled else (rep, write_fap(seq, output))

        try:
            got = run_task(w, "Tracking the video…", track, title="Track Video")
        except Cancelled:
            got = None
        except Exception as exc:  # noqa: BLE001
            report_error(w, "Track Video", exc)
            return None
        if got is None or cancelled:
            w.statusBar().showMessage("Tracking cancelled: nothing saved", 6000)
            self.last_track = got if got is not None else self.last_track
            return got
        rep, path = got
        self.last_track = rep
        dropped = (f"{len(rep.missing)} frame(s) without a face were interpolated."
                   if rep.missing else "A face was found in every frame.")
        QMessageBox.information(w, "Track Video",
                                f"Saved {rep.frames} frames to {path}.\n{dropped}\n"
                                f"{rep.summary()}")
        return rep
