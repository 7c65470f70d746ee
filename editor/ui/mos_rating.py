"""The rating session window of a MOS study: one stimulus at a time, keyboard-only.

Keys (shown on the instructions page and under every image):

* step 1, the emotion label: ``1`` … ``N`` pick the study's labels, ``0`` or ``C`` "cannot tell";
  picking a label moves to step 2;
* step 2, naturalness: ``1`` … ``5`` (only in step 2) or ``F1`` … ``F5`` (always);
  ``Backspace`` / ``Esc`` returns to step 1 of the *same* image to change the label;
* ``Enter`` / ``Space`` confirm once both are given; the answer is committed immediately;
* ``Page Up`` goes back to the previous image only if the study allows revising answers;
* ``F11`` toggles full screen.

The response time runs from the moment the image is shown to the confirming key. Every answer
goes straight to the study database (:class:`editor.study.mos.RaterSession`), so closing the
window (or killing the app) loses nothing; reopening with the same rater id resumes in the same
order at the first unanswered image.
"""

from __future__ import annotations

from collections.abc import Callable

from PySide6.QtCore import QElapsedTimer, QRectF, Qt, Signal
from PySide6.QtGui import QCloseEvent, QKeyEvent, QPainter, QPaintEvent, QPixmap
from PySide6.QtWidgets import (
    QHBoxLayout,
    QInputDialog,
    QLabel,
    QMessageBox,
    QPushButton,
    QStackedWidget,
    QVBoxLayout,
    QWidget,
)

from editor.errors import FapStudioError
from editor.study.mos import CANNOT_TELL, NATURALNESS, RaterSession, Stimulus, Study

from .qt_utils import run_guarded

_DIGITS = {getattr(Qt.Key, f"Key_{i}"): i for i in range(10)}
_FKEYS = {getattr(Qt.Key, f"Key_F{i}"): i for i in range(1, 6)}
_CONFIRM = (Qt.Key.Key_Return, Qt.Key.Key_Enter, Qt.Key.Key_Space)
_SELECTED = "QPushButton { background: #2d6cdf; color: white; font-weight: bold; }"


def ask_rater(parent: QWidget | None) -> str | None:
    """Prompt for a rater id (None when cancelled or empty)."""
    text, ok = QInputDialog.getText(parent, "Rate study", "Rater id (e.g. initials or a code):")
    return text.strip() or None if ok else None


class ImageView(QWidget):
    """Paints a pixmap scaled to fit (aspect kept, centred) on a neutral grey background."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.pixmap = QPixmap()
        self.setMinimumSize(200, 200)

    def set_pixmap(self, pixmap: QPixmap) -> None:
        self.pixmap = pixmap
        self.update()

    def paintEvent(self, event: QPaintEvent) -> None:  # noqa: N802 (Qt override)
        p = QPainter(self)
        p.fillRect(self.rect(), Qt.GlobalColor.darkGray)
        if not self.pixmap.isNull():
            size = self.pixmap.size().scaled(self.size(), Qt.AspectRatioMode.KeepAspectRatio)
            x, y = (self.width() - size.width()) / 2, (self.height() - size.height()) / 2
            p.setRenderHint(QPainter.RenderHint.SmoothPixmapTransform)
            p.drawPixmap(QRectF(x, y, size.width(), size.height()).toRect(), self.pixmap)
        p.end()


def _button(text: str) -> QPushButton:
    b = QPushButton(text)
    b.setFocusPolicy(Qt.FocusPolicy.NoFocus)  # keys always go to the window
    b.setMinimumHeight(44)
    return b


def _page_label(text: str) -> QLabel:
    label = QLabel(text)
    label.setWordWrap(True)
    label.setAlignment(Qt.AlignmentFlag.AlignCenter)
    label.setTextFormat(Qt.TextFormat.RichText)
    label.setStyleSheet("font-size: 16pt;")
    return label


class RatingWindow(QWidget):
    """A rater's session. Raises :class:`FapStudioError` from ``__init__`` if the study or the
    session cannot be opened. ``answered(done, total)`` follows every committed answer."""

    answered = Signal(int, int)
    finished = Signal()

    def __init__(self, study_path: str, rater: str, seed: int | None = None,
                 parent: QWidget | None = None) -> None:
        super().__init__(parent, Qt.WindowType.Window)
        self.study = Study.open(study_path)
        try:
            self.session: RaterSession = self.study.start_session(rater, seed)
        except FapStudioError:
            self.study.close()
            raise
        self.labels: tuple[str, ...] = self.study.labels
        self.stimuli = {s.id: s for s in self.study.stimuli()}
        self.stimulus: Stimulus | None = None
        self.revising = False
        self.label: str | None = None
        self.naturalness: int | None = None
        self.step = "label"
        self.timer = QElapsedTimer()
        self.setWindowTitle(f"Rating – {self.study.name} – rater {self.session.rater}")
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        self.pages = QStackedWidget()
        self.intro = _page_label(self._instructions())
        self.pause = _page_label("")
        self.done_page = _page_label("")
        self.pages.addWidget(self.intro)
        self.pages.addWidget(self._rating_page())
        self.pages.addWidget(self.pause)
        self.pages.addWidget(self.done_page)
        lay = QVBoxLayout(self)
        lay.addWidget(self.pages)
        self.resize(1000, 800)
        if self.session.next_stimulus() is None:
            self._show_done()
        self._refresh()

    # ------------------------------------------------------------------ layout
    def _instructions(self) -> str:
        done, total = self.session.progress
        keys = ", ".join(f"<b>{i + 1}</b> {lab}" for i, lab in enumerate(self.labels[:9]))
        nat = ", ".join(f"<b>{k}</b> {w}" for k, w in NATURALNESS.items())
        resume = (f"<p><i>Welcome back: {done} of {total} images are already rated; you "
                  f"continue where you stopped.</i></p>" if done else "")
        back = ("You may go back with <b>Page Up</b> to change an answer."
                if self.study.allow_revise else "Answers cannot be changed once confirmed.")
        return (f"<h2>{self.study.name}</h2>{resume}<p>You will see {total} face images, one at "
                f"a time. For each image:</p><p>1. Which emotion does the face show? {keys}, "
                f"<b>0</b> or <b>C</b> {CANNOT_TELL}.</p><p>2. How natural does it look? "
                f"{nat} (keys 1–5 after the emotion, or F1–F5).</p><p>Confirm with "
                f"<b>Enter</b> or <b>Space</b>. {back} Your answers are saved immediately. "
                f"Answer spontaneously; response time is recorded. <b>F11</b>: full screen."
                f"</p><p><b>Press Enter or Space to start.</b></p>")

    def _rating_page(self) -> QWidget:
        page = QWidget()
        lay = QVBoxLayout(page)
        top = QHBoxLayout()
        self.progress_label = QLabel()
        self.progress_label.setStyleSheet("font-size: 14pt;")
        self.hint = QLabel()
        top.addWidget(self.progress_label)
        top.addStretch(1)
        top.addWidget(self.hint)
        lay.addLayout(top)
        self.image = ImageView()
        lay.addWidget(self.image, 1)
        self.step_label = QLabel()
        self.step_label.setStyleSheet("font-size: 13pt;")
        lay.addWidget(self.step_label)
        row = QHBoxLayout()
        self.label_buttons: dict[str, QPushButton] = {}
        for i, lab in enumerate((*self.labels, CANNOT_TELL)):
            key = "0/C" if lab == CANNOT_TELL else (str(i + 1) if i < 9 else "")
            b = _button(f"{key}  {lab}" if key else lab)
            b.clicked.connect(lambda _=False, lab=lab: self.choose_label(lab))
            self.label_buttons[lab] = b
            row.addWidget(b)
        lay.addLayout(row)
        row = QHBoxLayout()
        self.nat_buttons: dict[int, QPushButton] = {}
        for k, word in NATURALNESS.items():
            b = _button(f"{k} (F{k})  {word}")
            b.clicked.connect(lambda _=False, k=k: self.choose_naturalness(k))
            self.nat_buttons[k] = b
            row.addWidget(b)
        lay.addLayout(row)
        self.confirm_button = _button("Confirm (Enter / Space)")
        self.confirm_button.clicked.connect(self.confirm)
        lay.addWidget(self.confirm_button)
        return page

    # ------------------------------------------------------------------ state
    def start(self) -> None:
        """Leave the instructions/break page and show the next unanswered stimulus."""
        stim = self.session.next_stimulus()
        if stim is None:
            self._show_done()
        else:
            self._show_stimulus(stim, revising=False)

    def _show_stimulus(self, stim: Stimulus, revising: bool) -> None:
        pixmap = QPixmap()
        if not pixmap.loadFromData(self.study.image_bytes(stim.id)):
            raise FapStudioError(f"stimulus {stim.id}: cannot decode the stored image")
        self.stimulus, self.revising = stim, revising
        self.label, self.naturalness, self.step = None, None, "label"
        self.image.set_pixmap(pixmap)
        self.pages.setCurrentIndex(1)
        self._refresh()
        self.timer.start()  # response time: from the image being shown

    def _show_done(self) -> None:
        self.stimulus = None
        done, total = self.session.progress
        self.done_page.setText(f"<h2>Thank you!</h2><p>All {total} images are rated "
                               f"({done} answers saved). You can close this window.</p>")
        self.pages.setCurrentIndex(3)
        self.finished.emit()

    def _refresh(self) -> None:
        done, total = self.session.progress
        if self.stimulus is not None:
            pos = self.session.order.index(self.stimulus.id) + 1
            extra = "  (changing an earlier answer)" if self.revising else ""
            self.progress_label.setText(f"{pos} / {total}{extra}")
        self.step_label.setText(
            f"Step 1: which emotion? keys 1–{min(len(self.labels), 9)}, 0 or C = {CANNOT_TELL}"
            if self.step == "label" else
            "Step 2: how natural? keys 1–5 or F1–F5; Backspace = change the emotion")
        for lab, b in self.label_buttons.items():
            b.setStyleSheet(_SELECTED if lab == self.label else "")
        for k, b in self.nat_buttons.items():
            b.setStyleSheet(_SELECTED if k == self.naturalness else "")
        self.confirm_button.setEnabled(self.label is not None and self.naturalness is not None)

    def choose_label(self, label: str) -> None:
        self.label, self.step = label, "naturalness"
        self.hint.clear()
        self._refresh()

    def choose_naturalness(self, value: int) -> None:
        self.naturalness = value
        if self.label is not None:
            self.step = "naturalness"
        self.hint.clear()
        self._refresh()

    def confirm(self) -> None:
        """Commit the current answer (or revision) and move on."""
        stim = self.stimulus
        if stim is None or self.label is None or self.naturalness is None:
            self.hint.setText("Choose an emotion and a naturalness score first.")
            return
        ms = self.timer.nsecsElapsed() / 1e6
        try:
            if self.revising:
                self.session.revise(stim, self.label, self.naturalness, ms)
            else:
                self.session.answer(stim, self.label, self.naturalness, ms)
        except FapStudioError as e:
            QMessageBox.warning(self, "Cannot save the answer", str(e))
            return
        done, total = self.session.progress
        self.answered.emit(done, total)
        if self.session.break_due and not self.revising:
            self.stimulus = None
            self.pause.setText(f"<h2>Break</h2><p>{done} of {total} images rated. Take a short "
                               f"rest.</p><p><b>Press Enter or Space to continue.</b></p>")
            self.pages.setCurrentIndex(2)
        else:
            self.start()

    def go_back(self) -> bool:
        """Show the image before the current one to change its answer (only if allowed)."""
        if not self.study.allow_revise:
            self.hint.setText("This study does not allow changing confirmed answers.")
            return False
        if self.stimulus is None:
            return False
        pos = self.session.order.index(self.stimulus.id)
        if pos == 0:
            return False
        prev = self.session.order[pos - 1]
        self._show_stimulus(self.stimuli[prev], revising=True)
        return True

    # ------------------------------------------------------------------ events
    def keyPressEvent(self, event: QKeyEvent) -> None:  # noqa: N802 (Qt override)
        key = event.key()
        if key == Qt.Key.Key_F11:
            self.showNormal() if self.isFullScreen() else self.showFullScreen()
        elif self.pages.currentIndex() in (0, 2):
            if key in _CONFIRM:
                self._guard(self.start)
        elif self.pages.currentIndex() == 1:
            self._guard(lambda: self._rating_key(key))
        else:
            super().keyPressEvent(event)

    def _rating_key(self, key: int) -> None:
        n = len(self.labels)
        if key in _CONFIRM:
            self.confirm()
        elif key in _FKEYS:
            self.choose_naturalness(_FKEYS[key])
        elif key == Qt.Key.Key_PageUp:
            self.go_back()
        elif key in (Qt.Key.Key_Backspace, Qt.Key.Key_Escape):
            self.step = "label"
            self._refresh()
        elif self.step == "label" and (key in (Qt.Key.Key_0, Qt.Key.Key_C)):
            self.choose_label(CANNOT_TELL)
        elif self.step == "label" and key in _DIGITS and 1 <= _DIGITS[key] <= min(n, 9):
            self.choose_label(self.labels[_DIGITS[key] - 1])
        elif self.step == "naturalness" and key in _DIGITS and 1 <= _DIGITS[key] <= 5:
            self.choose_naturalness(_DIGITS[key])

    def _guard(self, action: Callable[[], object]) -> None:
        run_guarded(self, "Rating", action)

    def closeEvent(self, event: QCloseEvent) -> None:  # noqa: N802 (Qt override)
        self.study.close()  # every answer is already committed
        super().closeEvent(event)
