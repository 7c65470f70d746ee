"""Playback, keyframe authoring and export of FAP sequences (.fap), docked as "Playback".

Playback drives the document through the model's *gesture* path: the first frame shown starts a
gesture, each frame is a ``preview`` (no undo entries, the FAP sliders follow), **Stop** aborts
the gesture (back to the FAPs from before playback) and **Keep frame** commits it as one undo
entry. The frame shown is the one for the elapsed time of the (injectable) clock
(:class:`~editor.formats.playhead.Playhead`), so slow rendering drops frames, not drifting; the
render scheduler is latest-only, so the GUI never queues up frames either.

The sequence and the keyframes live in the document (:class:`~editor.formats.document.Animation`):
opening a .fap, building from keys and every key edit is one undo command, saved in the project;
the panel shows whatever the current document holds (undo included).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from PySide6.QtCore import QCoreApplication, Qt, QTimer, Signal
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import (
    QCheckBox,
    QFileDialog,
    QHBoxLayout,
    QLabel,
    QMessageBox,
    QPushButton,
    QSlider,
    QVBoxLayout,
    QWidget,
)

from editor.errors import FapStudioError
from editor.formats.document import NO_ANIMATION, Animation
from editor.formats.playhead import Clock, Playhead

from .document_model import DocumentModel
from .playback_export import ExportJob
from .playback_keys import KeyframeEditor, low_level
from .qt_utils import run_guarded, signals_blocked
from .tasks import run_task

if TYPE_CHECKING:
    from editor.formats.fapfile import FapSequence
    from editor.formats.video import ExportResult

# editor.formats.video (OpenCV, the render pool) and the .fap reader/writer are imported when a
# sequence is shown, read, saved or exported, not when the window is built (issue 15,
# gui_ready_s).

FAP_FILTER = "MPEG-4 FAP files (*.fap);;All files (*)"
NO_SEQUENCE = "No sequence. Open a .fap file or build one from keyframes."
VIDEO_FILTER = "MP4 video (*.mp4);;AVI video (*.avi)"


class PlaybackPanel(QWidget):
    """Timeline with play/pause/stop/loop/scrub, keyframes, save and export.

    Signals
    -------
    frameShown(int)
        A frame of the sequence was put on the document (playback or scrub).
    exportFinished(object, str)
        An export ended: ``ExportResult`` and '' or None and the error message.
    """

    frameShown = Signal(int)
    exportFinished = Signal(object, str)

    def __init__(self, model: DocumentModel, clock: Clock = time.perf_counter,
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.model = model
        self.playhead = Playhead(1, 25.0, clock)
        self.vectors: np.ndarray | None = None
        self._shown_seq: FapSequence | None = None
        self.shown: int | None = None
        self.job: ExportJob | None = None
        self._gesture = False
        self.timer = QTimer(self)
        self.timer.setTimerType(Qt.TimerType.PreciseTimer)
        self.timer.timeout.connect(self.tick)

        self.info = QLabel(NO_SEQUENCE)
        self.info.setWordWrap(True)
        self.open_button = QPushButton("Open…")
        self.play_button = QPushButton("Play")
        self.stop_button = QPushButton("Stop")
        self.stop_button.setToolTip("Stop and restore the FAPs from before playback")
        self.keep_button = QPushButton("Keep frame")
        self.keep_button.setToolTip("Stop and keep the frame shown (one undo step)")
        self.loop_box = QCheckBox("Loop")
        self.slider = QSlider(Qt.Orientation.Horizontal)
        self.slider.setRange(0, 0)
        self.frame_label = QLabel("– / –")
        self.frame_label.setMinimumWidth(120)
        self.keys = KeyframeEditor()
        self.quick_button = QPushButton("Neutral → current → neutral (2 s)")
        self.save_button = QPushButton("Save .fap…")
        self.video_button = QPushButton("Export video…")
        self.frames_button = QPushButton("Export frames…")

        transport = QHBoxLayout()
        for w in (self.open_button, self.play_button, self.stop_button, self.keep_button):
            transport.addWidget(w)
        transport.addWidget(self.loop_box)
        timeline = QHBoxLayout()
        timeline.addWidget(self.slider, 1)
        timeline.addWidget(self.frame_label)
        out = QHBoxLayout()
        for w in (self.save_button, self.video_button, self.frames_button):
            out.addWidget(w)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(4, 4, 4, 4)
        lay.addWidget(self.info)
        lay.addLayout(transport)
        lay.addLayout(timeline)
        lay.addWidget(self.keys)
        lay.addWidget(self.quick_button)
        lay.addLayout(out)
        lay.addStretch(1)

        self.open_button.clicked.connect(lambda: self.open_file())
        self.play_button.clicked.connect(self.toggle_play)
        self.stop_button.clicked.connect(self.stop)
        self.keep_button.clicked.connect(self.keep_frame)
        self.loop_box.toggled.connect(self.set_loop)
        self.slider.valueChanged.connect(self.scrub)
        self.keys.addRequested.connect(self._add_key)
        self.keys.buildRequested.connect(self.build_from_keys)
        self.keys.edited.connect(self._keys_edited)
        # clicked(bool) would pass False as the duration
        self.quick_button.clicked.connect(lambda: self.quick_neutral_current_neutral())
        self.save_button.clicked.connect(lambda: self.save_file())
        self.video_button.clicked.connect(lambda: self.export("video"))
        self.frames_button.clicked.connect(lambda: self.export("frames"))
        model.loaded.connect(self._on_loaded)
        model.changed.connect(self._on_changed)
        model.undo_stack.indexChanged.connect(self._on_history)
        app = QCoreApplication.instance()
        if app is not None:
            app.aboutToQuit.connect(self.shutdown)
        self._update_enabled()

    # ------------------------------------------------------------------ helpers
    def guarded(self, title: str, action: Callable[[], object]) -> bool:
        return run_guarded(self, title, action)[0]

    def _update_enabled(self) -> None:
        has_seq, has_doc = self.seq is not None, self.model.doc is not None
        busy = self.job is not None and self.job.running
        for w in (self.play_button, self.stop_button, self.keep_button, self.slider):
            w.setEnabled(has_seq and has_doc)
        self.save_button.setEnabled(has_seq or bool(self.keys.keys))
        for w in (self.video_button, self.frames_button):
            w.setEnabled(has_seq and has_doc and not busy)
        self.keys.add_button.setEnabled(has_doc)
        self.quick_button.setEnabled(has_doc)
        self.play_button.setText("Pause" if self.playhead.playing else "Play")

    def _owns_gesture(self) -> bool:
        """True while the model's running gesture is the one playback started."""
        self._gesture = self._gesture and self.model.in_gesture
        return self._gesture

    # ------------------------------------------------------------------ sequence
    @property
    def animation(self) -> Animation:
        doc = self.model.doc
        return doc.animation if doc is not None else NO_ANIMATION

    @property
    def seq(self) -> FapSequence | None:
        """The document's sequence (opened or built), None when there is none."""
        return self.animation.sequence

    @property
    def path(self) -> str | None:
        return self.animation.source or None

    def _release_playback(self) -> None:
        """Stop playing and give the model's gesture back (before an undoable change)."""
        self.pause()
        if self._owns_gesture():
            self.model.abort_gesture()
        self._gesture = False

    def _set_animation(self, anim: Animation, text: str) -> None:
        if self.model.doc is None or anim.equals(self.animation):
            return
        self._release_playback()
        self.model.set_animation(anim, text)

    def load_sequence(self, seq: FapSequence, path: str | None = None,
                      keys: Animation | None = None, text: str = "") -> None:
        """Make ``seq`` the document's sequence (one undo command; paused at frame 0, shown
        on the face); ``keys`` also sets the keyframes in the same command."""
        base = keys if keys is not None else self.animation
        name = Path(path).name if path else seq.name
        self._set_animation(base.replace(sequence=seq, source=path or ""),
                            text or f"Open sequence {name}")
        if self.seq is seq:
            self.show_frame(0)

    def _keys_edited(self, text: str) -> None:
        self._set_animation(self.keys.animation(self.animation), text)
        self.keys.show_animation(self.animation)  # an edit without a document is undone

    def _on_changed(self, old: object, new: object) -> None:
        anim = getattr(new, "animation", NO_ANIMATION)
        if old is None or getattr(old, "animation", None) is not anim:
            self._sync(anim)

    def _sync(self, anim: Animation) -> None:
        """Show the document's animation: keys, and the sequence on the timeline."""
        self.keys.show_animation(anim)
        seq = anim.sequence
        if seq is not self._shown_seq:
            self._shown_seq = seq
            self.pause()
            self.shown = None
            if seq is None:
                self.vectors = None
                self.playhead.reset(1, 25.0)
                with signals_blocked(self.slider):
                    self.slider.setRange(0, 0)
                self.frame_label.setText("– / –")
                self.info.setText(NO_SEQUENCE)
                self.info.setToolTip("")
            else:
                from editor.formats.video import sequence_vectors

                self.vectors = sequence_vectors(seq)
                self.playhead.reset(seq.n_frames, seq.fps)
                with signals_blocked(self.slider):
                    self.slider.setRange(0, seq.n_frames - 1)
                    self.slider.setValue(0)
                name = Path(anim.source).name if anim.source else seq.name
                used = len([n for n in seq.used_faps() if n > 2])
                self.info.setText(f"{name}: {seq.n_frames} frames at {seq.fps:g} fps "
                                  f"({seq.duration:.2f} s), {used} FAPs")
                self.info.setToolTip(anim.source)
        self._update_enabled()

    def open_file(self, path: str | None = None) -> bool:
        if path is None:
            path, _ = QFileDialog.getOpenFileName(self, "Open FAP sequence", "", FAP_FILTER)
            if not path:
                return False
        def read() -> None:
            from editor.formats.fapfile import read_fap

            seq = run_task(self, f"Reading {Path(path).name}…", lambda _p: read_fap(path),
                           title="Open FAP Sequence")
            self.load_sequence(seq, str(path))

        return self.guarded("Open FAP sequence", read)

    def save_file(self, path: str | None = None) -> bool:
        """Write the current sequence (built from the keys if there is none) as .fap."""
        if self.seq is None and not self.build_from_keys():
            return False
        if path is None:
            start = self.path or f"{self.seq.name}.fap"
            path, _ = QFileDialog.getSaveFileName(self, "Save FAP sequence", start, FAP_FILTER)
            if not path:
                return False
            if not Path(path).suffix:
                path += ".fap"
        seq = self.seq
        from editor.formats.fapfile import write_fap

        ok = self.guarded("Save FAP sequence", lambda: write_fap(seq, path))
        win = self.window()
        if ok and hasattr(win, "statusBar"):
            win.statusBar().showMessage(f"Saved {seq.n_frames} frames to {path}", 8000)
        return ok

    def build_from_keys(self) -> bool:
        """Interpolate the keyframes into a sequence and load it (one undo command)."""
        return self.guarded("Build sequence",
                            lambda: self.load_sequence(self.keys.build(), text="Build sequence"))

    def quick_neutral_current_neutral(self, duration: float = 2.0) -> bool:
        """Keys neutral (0 s) → current FAPs (duration/2) → neutral (duration), built and
        loaded as one undo command."""
        doc = self.model.doc
        if doc is None:
            return False
        zero = np.zeros(68)
        keys = self.animation.replace(keys=((0.0, zero), (duration / 2, low_level(doc.faps)),
                                            (float(duration), zero)))

        def build() -> None:
            try:
                seq = keys.build()
            except ValueError as e:
                raise FapStudioError(f"cannot build the sequence: {e}") from None
            self.load_sequence(seq, keys=keys, text="Neutral → current → neutral")

        return self.guarded("Build sequence", build)

    def _add_key(self, t: float) -> None:
        if self.model.doc is not None:
            self.keys.add_key(t, self.model.doc.faps)
            self._update_enabled()

    # ------------------------------------------------------------------ transport
    def show_frame(self, k: int) -> None:
        """Put frame ``k`` on the document as a preview of the playback gesture."""
        if self.vectors is None:
            return
        k = max(0, min(len(self.vectors) - 1, int(k)))
        self.shown = k
        with signals_blocked(self.slider):
            self.slider.setValue(k)
        fps = self.playhead.fps
        self.frame_label.setText(f"{k + 1} / {len(self.vectors)} · {k / fps:.2f} s")
        with signals_blocked(self.keys.time):
            self.keys.time.setValue(k / fps)
        doc = self.model.doc
        if doc is not None:
            if not self._owns_gesture():
                if self.model.in_gesture:  # someone else's drag: leave it alone
                    return
                self.model.begin_gesture()
                self._gesture = True
            self.model.preview(doc.with_fap_vector(self.vectors[k]))
        self.frameShown.emit(k)

    def tick(self) -> None:
        """Timer: show the frame for the elapsed time (skipping late frames)."""
        k = self.playhead.frame()
        if k != self.shown:
            self.show_frame(k)
        if not self.playhead.playing:
            self.timer.stop()
            self._update_enabled()

    def play(self) -> None:
        if self.seq is None or self.model.doc is None or self.playhead.playing:
            return
        self.playhead.play()
        self.timer.start(max(4, min(40, int(500 / self.playhead.fps))))
        self.tick()
        self._update_enabled()

    def pause(self) -> None:
        self.playhead.pause()
        self.timer.stop()
        self._update_enabled()

    def toggle_play(self) -> None:
        self.pause() if self.playhead.playing else self.play()

    def set_loop(self, on: bool) -> None:
        self.playhead.loop = bool(on)
        with signals_blocked(self.loop_box):
            self.loop_box.setChecked(bool(on))

    def scrub(self, k: int) -> None:
        """Timeline moved by the user: seek (playing continues from there) and show."""
        self.show_frame(self.playhead.seek(k))

    def stop(self) -> None:
        """Stop, rewind, and put back the FAPs from before playback (no undo entry)."""
        self.pause()
        self.playhead.seek(0)
        if self._owns_gesture():
            self.model.abort_gesture()
        self._gesture = False
        self.shown = None
        with signals_blocked(self.slider):
            self.slider.setValue(0)

    def keep_frame(self) -> None:
        """Stop and keep the frame shown as one undo entry."""
        self.pause()
        if self._owns_gesture():
            k = self.shown if self.shown is not None else 0
            self.model.commit_gesture(f"Playback frame {k + 1}")
        self._gesture = False

    def _on_loaded(self) -> None:  # a new photo/project: the model dropped the gesture
        self.pause()
        self._gesture = False
        self.shown = None
        self._update_enabled()

    def _on_history(self, _index: int) -> None:  # an edit or undo ended our preview
        if self.playhead.playing:
            self.pause()

    # ------------------------------------------------------------------ export
    def export(self, kind: str, path: str | None = None, dialog: bool = True
               ) -> ExportJob | None:
        """Render the sequence to an MP4 (``kind`` "video") or PNG folder ("frames") in the
        background with a cancellable progress dialog; returns the running job."""
        face = self.model.face if self.model.doc is not None else None
        if self.seq is None or face is None:
            self.guarded("Export", _raise("nothing to export: open a .fap file or build a "
                                          "sequence from keyframes first"))
            return None
        if self.job is not None and self.job.running:
            QMessageBox.information(self, "Export", "An export is already running.")
            return None
        if path is None:
            if kind == "video":
                path, _ = QFileDialog.getSaveFileName(self, "Export video",
                                                      f"{self.seq.name}.mp4", VIDEO_FILTER)
                if path and not Path(path).suffix:
                    path += ".mp4"
            else:
                path = QFileDialog.getExistingDirectory(self, "Export frames to folder")
            if not path:
                return None
        self.pause()
        job = ExportJob(face, self.seq, str(path), self, dialog=dialog)
        job.finished.connect(self._on_export_finished)
        self.job = job.start()
        self._update_enabled()
        return job

    def _on_export_finished(self, result: ExportResult | None, message: str) -> None:
        self._update_enabled()
        if message:
            QMessageBox.warning(self, "Export", message.splitlines()[0])
        elif result is not None:
            what = "cancelled" if result.cancelled else "done"
            text = f"Export {what}: {result.frames} frames → {result.path}"
            win = self.window()
            if hasattr(win, "statusBar"):
                win.statusBar().showMessage(text, 8000)
        self.exportFinished.emit(result, message)

    def shutdown(self) -> None:
        """Cancel a running export and wait for its thread (application exit)."""
        if self.job is not None and self.job.running:
            self.job.cancel()
            self.job.wait(10000)


def _raise(message: str) -> Callable[[], None]:
    def fail() -> None:
        raise FapStudioError(message)
    return fail


def _action(window, text: str, slot: Callable[[], object], shortcut: str | None = None,
            tip: str = "") -> QAction:
    a = QAction(text, window)
    if shortcut:
        a.setShortcut(QKeySequence(shortcut))
    if tip:
        a.setStatusTip(tip)
    a.triggered.connect(lambda _checked=False: slot())
    window.addAction(a)
    return a


def install(window) -> PlaybackPanel:
    """Add the "Playback" dock and the Animation menu to the main window."""
    p = PlaybackPanel(window.model)
    window.playback_panel = p
    window.playback_dock = window.add_panel_dock("Playback", p, "playbackDock")
    m = window.menu("&Animation")
    p.act_open = _action(window, "Open FAP Sequence…", p.open_file, "Ctrl+Shift+A",
                         "Open an MPEG-4 .fap animation for playback")
    p.act_save = _action(window, "Save FAP Sequence…", p.save_file,
                         tip="Save the sequence (or the keyframes, interpolated) as .fap")
    p.act_play = _action(window, "Play / Pause", p.toggle_play, "Ctrl+Space",
                         "Play the sequence on the face, or pause it")
    p.act_stop = _action(window, "Stop", p.stop, tip="Stop and restore the FAPs")
    p.act_keep = _action(window, "Keep Frame", p.keep_frame,
                         tip="Stop and keep the frame shown as the FAPs (one undo step)")
    p.act_loop = QAction("Loop", window, checkable=True)
    p.act_loop.setStatusTip("Start the sequence again when it ends")
    p.act_loop.toggled.connect(p.set_loop)
    p.loop_box.toggled.connect(p.act_loop.setChecked)
    p.act_quick = _action(window, "Neutral → Current → Neutral (2 s)",
                          p.quick_neutral_current_neutral,
                          tip="Build a 2 s sequence from neutral to the current FAPs and back")
    p.act_video = _action(window, "Export Video…", lambda: p.export("video"),
                          tip="Render the sequence on the face to an H.264 MP4 (or AVI)")
    p.act_frames = _action(window, "Export Frames…", lambda: p.export("frames"),
                           tip="Render the sequence on the face to a folder of PNG frames")
    m.addActions([p.act_open, p.act_save])
    m.addSeparator()
    m.addActions([p.act_play, p.act_stop, p.act_keep, p.act_loop])
    m.addSeparator()
    m.addAction(p.act_quick)
    m.addSeparator()
    m.addActions([p.act_video, p.act_frames])
    m.addSeparator()
    m.addAction(window.playback_dock.toggleViewAction())
    return p
