"""The "Model" dock (issue 9 item 4) and the cloning actions of issue 10 (Tools menu).

``install(window)`` adds the dock (load a dlib-68 bilinear model, pick a target expression or a
mix, method plain / ridge / MALS, λ; "Synthesize" previews the expression on the current photo in
the dock; "Convert to FAPs" puts the FAP vector that best reproduces the synthesized landmarks on
the sliders as one undo entry) and the Tools-menu actions of :mod:`editor.ui.model_tools`.
Loading a model and synthesizing run on the thread pool (a progress dialog when they take a
while);
errors are shown as a message box with the one-line error text.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from PySide6.QtCore import Qt
from PySide6.QtGui import QImage, QPixmap
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from .model_tools import CloneTools, guarded
from .qt_utils import settings
from .tasks import run_task

METHODS = (("Plain ALS", "plain"), ("Ridge", "ridge"), ("MALS", "mals"))
PREVIEW_HINT = "Synthesize to see the expression here"


class ModelPanel(QWidget):
    """Bilinear-model synthesis on the current photo."""

    def __init__(self, window: Any, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.window = window
        self.bilinear: Any = None  # BilinearModel
        self.result: Any = None  # PhotoSynthesis of the last "Synthesize"
        self._result_key: tuple[Any, ...] | None = None

        self.load_button = QPushButton("Load Model…")
        self.load_button.clicked.connect(lambda: self.load_model())
        self.model_label = QLabel("no model loaded")
        self.model_label.setWordWrap(True)
        self.expression = QComboBox()
        self.mix = QLineEdit()
        self.mix.setPlaceholderText("mix, e.g. joy:0.5, surprise:0.5 (overrides)")
        self.method = QComboBox()
        for text, key in METHODS:
            self.method.addItem(text, key)
        self.method.setCurrentIndex(2)
        self.lam = QDoubleSpinBox()
        self.lam.setDecimals(4)
        self.lam.setRange(0.0, 1000.0)
        self.lam.setSingleStep(0.005)
        self.lam.setSpecialValueText("model default")
        self.lam.setToolTip("λ of ridge / MALS (0 = the value stored in the model)")
        self.keep = QCheckBox("keep identity residual")
        self.keep.setToolTip("Add back the part of the photo's shape the model does not "
                             "reconstruct (not in the paper)")
        self.synth_button = QPushButton("Synthesize")
        self.synth_button.clicked.connect(lambda: self.synthesize())
        self.faps_button = QPushButton("Convert to FAPs")
        self.faps_button.setToolTip("Put the FAP vector that best reproduces the synthesized "
                                    "landmarks on the sliders (one undo step)")
        self.faps_button.clicked.connect(lambda: self.convert_to_faps())
        self.preview = QLabel(PREVIEW_HINT)
        self.preview.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.preview.setMinimumSize(200, 200)

        form = QFormLayout()
        form.addRow("Expression", self.expression)
        form.addRow("Mix", self.mix)
        form.addRow("Method", self.method)
        form.addRow("λ", self.lam)
        form.addRow("", self.keep)
        buttons = QHBoxLayout()
        buttons.addWidget(self.synth_button)
        buttons.addWidget(self.faps_button)
        lay = QVBoxLayout(self)
        lay.addWidget(self.load_button)
        lay.addWidget(self.model_label)
        lay.addLayout(form)
        lay.addLayout(buttons)
        lay.addWidget(self.preview, 1)
        self._update_enabled()
        window.model.loaded.connect(self.clear_result)

    def clear_result(self) -> None:
        """Forget the last synthesis (another photo or project was opened)."""
        self.result, self._result_key = None, None
        self.preview.clear()
        self.preview.setText(PREVIEW_HINT)

    # ------------------------------------------------------------------ model
    def load_model(self, path: str | None = None) -> bool:
        """Load a dlib-68 model file (asks for one when ``path`` is None)."""
        from editor.synthesis.bilinear import load_model
        from editor.synthesis.bilinear_photo import check_model68

        if path is None:
            start = str(settings().value("model/last", "") or "")
            path, _ = QFileDialog.getOpenFileName(self, "Load bilinear model", start,
                                                  "Bilinear model (*.npz);;All files (*)")
            if not path:
                return False

        def load() -> Any:
            m = load_model(path)
            check_model68(m)
            return m

        model = guarded(self.window, "Load Model", lambda: run_task(
            self.window, f"Loading the model {Path(path).name}…", lambda _p: load(),
            title="Load Model"))
        if model is None:
            return False
        self.bilinear = model
        settings().setValue("model/last", str(path))
        self.expression.clear()
        self.expression.addItems(list(model.expressions))
        if "joy" in model.expressions:
            self.expression.setCurrentText("joy")
        self.model_label.setText(f"{Path(path).name}: {len(model.identities)} people × "
                                 f"{len(model.expressions)} expressions")
        self.result, self._result_key = None, None
        self._update_enabled()
        return True

    def set_model(self, model: Any, label: str = "model") -> None:
        """Use an in-memory model (tests, scripts)."""
        self.bilinear = model
        self.expression.clear()
        self.expression.addItems(list(model.expressions))
        self.model_label.setText(label)
        self._update_enabled()

    def _update_enabled(self) -> None:
        on = self.bilinear is not None
        for w in (self.expression, self.mix, self.method, self.lam, self.keep,
                  self.synth_button, self.faps_button):
            w.setEnabled(on)

    # ------------------------------------------------------------------ settings
    def target(self) -> Any:
        from editor.synthesis.bilinear_photo import parse_mix

        text = self.mix.text().strip()
        return parse_mix(text) if text else self.expression.currentText()

    def settings_key(self) -> tuple[Any, ...]:
        face = self.window.model.face
        return (id(face), self.mix.text().strip() or self.expression.currentText(),
                self.method.currentData(), self.lam.value(), self.keep.isChecked())

    # ------------------------------------------------------------------ actions
    def _compute(self, render: bool) -> Any:
        """Synthesize with the dock's settings, read here on the GUI thread; the computation
        runs on the thread pool (progress dialog when it takes a while)."""
        from editor.synthesis.bilinear_photo import synthesize_on_face

        face, model, target = self.window.model.face, self.bilinear, self.target()
        method, lam, keep = self.method.currentData(), self.lam.value() or None, \
            self.keep.isChecked()
        return run_task(self.window, "Synthesizing the expression…", lambda _p: (
            synthesize_on_face(face, model, target, method, lam, keep_residual=keep,
                               render=render)), title="Synthesize")

    def _ready(self, title: str) -> bool:
        from PySide6.QtWidgets import QMessageBox

        if self.bilinear is None:
            QMessageBox.warning(self.window, title, "Load a model first.")
            return False
        if self.window.model.face is None:
            QMessageBox.warning(self.window, title, "Open a photo first.")
            return False
        return True

    def synthesize(self) -> Any:
        """Synthesize the target on the current photo and show it in the dock."""
        if not self._ready("Synthesize"):
            return None
        key = self.settings_key()
        res = guarded(self.window, "Synthesize", lambda: self._compute(True))
        if res is None:
            return None
        self.result, self._result_key = res, key
        self._show(res.image)
        return res

    def _show(self, rgb: np.ndarray) -> None:
        img = np.ascontiguousarray(rgb)
        h, w = img.shape[:2]
        qimg = QImage(img.data, w, h, 3 * w, QImage.Format.Format_RGB888).copy()
        pix = QPixmap.fromImage(qimg)
        face = self.window.model.face
        if face is not None:  # crop to the face
            x0, y0, x1, y1 = face.crop_box(0.45, 0.45, 0.45, 0.45)
            pix = pix.copy(x0, y0, x1 - x0, y1 - y0)
        self.preview.setPixmap(pix.scaled(max(self.preview.width(), 200),
                                          max(self.preview.height(), 200),
                                          Qt.AspectRatioMode.KeepAspectRatio,
                                          Qt.TransformationMode.SmoothTransformation))

    def convert_to_faps(self) -> np.ndarray | None:
        """Estimate the FAPs of the synthesized shape and apply them (one undo entry)."""
        from editor.synthesis.bilinear_photo import faps_for_points

        if not self._ready("Convert to FAPs"):
            return None
        face = self.window.model.face

        def run() -> np.ndarray:
            res = self.result if self._result_key == self.settings_key() else None
            if res is None:
                res = self._compute(False)
            points = res.points68
            return run_task(self.window, "Converting to FAPs…",
                            lambda _p: faps_for_points(face, points), title="Convert to FAPs")

        faps = guarded(self.window, "Convert to FAPs", run)
        if faps is None:
            return None
        values = {i + 1: float(v) for i, v in enumerate(faps) if i >= 2}
        name = self.mix.text().strip() or self.expression.currentText()
        self.window.model.set_faps(values, f"Model expression {name} to FAPs")
        return np.asarray(faps)


class ModelExtension:
    """What :func:`install` returns: the panel, its dock and the Tools actions."""

    def __init__(self, window: Any) -> None:
        self.panel = ModelPanel(window)
        self.dock = window.add_panel_dock("Model", self.panel, "modelDock")
        self.tools = CloneTools(window)


def install(window: Any) -> ModelExtension:
    """Add the Model dock and the Tools-menu cloning actions to the main window."""
    return ModelExtension(window)
