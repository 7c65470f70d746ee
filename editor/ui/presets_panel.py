"""The preset panel: emotions, visemes and user presets, applied with an intensity or blended.

Every apply is one undo entry ("Apply preset joy 80 %"), either *replacing* the current FAPs by
the preset's or *adding* the preset to them (values clamped to the FAP table). The blend boxes
follow MPEG-4 FAP 2 (expression p1·i1/63 + p2·i2/63) and FAP 1 (viseme v1·b/63 + v2·(1-b/63)).
"Save current as preset…" stores the current low-level FAPs as a user preset; shipped names are
refused. Malformed user preset files are listed in the panel (never raised).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QComboBox,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QInputDialog,
    QLabel,
    QListWidget,
    QListWidgetItem,
    QMessageBox,
    QPushButton,
    QSlider,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from editor.errors import FapStudioError
from editor.formats.blends import EXPRESSIONS, VISEMES, blend_expressions, blend_visemes
from editor.formats.presets import Preset, all_presets, apply_preset, save_user_preset

from .document_model import DocumentModel
from .qt_utils import run_guarded

REPLACE, ADD = "replace", "add"
_SECTIONS = (("emotion", "Emotions"), ("viseme", "Visemes"), ("custom", "User presets"))


def _label(p: Preset) -> str:
    if p.kind == "viseme":
        phon = f"  ({', '.join(p.phonemes)})" if p.phonemes else ""
        return p.name.removeprefix("viseme_") + phon
    return p.name


class PresetsPanel(QWidget):
    """Preset list + intensity + apply mode, the FAP 1/2 blends and saving user presets."""

    def __init__(self, model: DocumentModel, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.model = model
        self.presets: dict[str, Preset] = {}
        self.problems: list[str] = []

        self.list = QListWidget()
        self.list.setToolTip("Double-click to apply with the intensity below")
        self.intensity = QSlider(Qt.Orientation.Horizontal)
        self.intensity.setRange(0, 150)
        self.intensity.setValue(100)
        self.intensity.setPageStep(10)
        self.intensity_label = QLabel()
        self.intensity_label.setMinimumWidth(42)
        self.mode = QComboBox()
        self.mode.addItem("Replace FAPs", REPLACE)
        self.mode.addItem("Add to FAPs", ADD)
        self.mode.setToolTip("Replace every FAP by the preset's, or add the preset's values to "
                             "the current FAPs")
        self.apply_button = QPushButton("Apply")
        self.save_button = QPushButton("Save current as preset…")
        self.reload_button = QPushButton("Reload")
        self.problems_label = QLabel()
        self.problems_label.setWordWrap(True)
        self.problems_label.setStyleSheet("color: #b00020;")
        self.problems_label.hide()

        row = QHBoxLayout()
        row.addWidget(QLabel("Intensity"))
        row.addWidget(self.intensity, 1)
        row.addWidget(self.intensity_label)
        row2 = QHBoxLayout()
        row2.addWidget(self.mode, 1)
        row2.addWidget(self.apply_button)
        row3 = QHBoxLayout()
        row3.addWidget(self.save_button, 1)
        row3.addWidget(self.reload_button)

        lay = QVBoxLayout(self)
        lay.setContentsMargins(4, 4, 4, 4)
        lay.addWidget(self.list, 1)
        lay.addLayout(row)
        lay.addLayout(row2)
        lay.addWidget(self._blend_box())
        lay.addLayout(row3)
        lay.addWidget(self.problems_label)

        self.intensity.valueChanged.connect(self._show_intensity)
        self.apply_button.clicked.connect(self.apply_selected)
        self.list.itemDoubleClicked.connect(lambda _i: self.apply_selected())
        self.list.currentItemChanged.connect(lambda *_: self._update_enabled())
        self.save_button.clicked.connect(self.save_current)
        self.reload_button.clicked.connect(self.reload)
        model.changed.connect(lambda *_: self._update_enabled())
        self._show_intensity(self.intensity.value())
        self.reload()

    def _blend_box(self) -> QGroupBox:
        box = QGroupBox("Blend (MPEG-4 FAP 2 / FAP 1)")
        g = QGridLayout(box)
        g.setContentsMargins(4, 4, 4, 4)

        def spin(value: int, tip: str) -> QSpinBox:
            s = QSpinBox()
            s.setRange(0, 63)
            s.setValue(value)
            s.setToolTip(tip)
            return s

        self.expr1, self.expr2 = QComboBox(), QComboBox()
        for idx, name in EXPRESSIONS.items():
            self.expr1.addItem(name, idx)
            self.expr2.addItem(name, idx)
        self.expr1.setCurrentIndex(1)
        self.int1 = spin(63, "intensity1 (0-63)")
        self.int2 = spin(0, "intensity2 (0-63)")
        self.blend_expr_button = QPushButton("Apply")
        g.addWidget(QLabel("Expr."), 0, 0)
        g.addWidget(self.expr1, 0, 1)
        g.addWidget(self.int1, 0, 2)
        g.addWidget(self.expr2, 0, 3)
        g.addWidget(self.int2, 0, 4)
        g.addWidget(self.blend_expr_button, 0, 5)

        self.vis1, self.vis2 = QComboBox(), QComboBox()
        for idx, name in VISEMES.items():
            self.vis1.addItem(name.removeprefix("viseme_"), idx)
            self.vis2.addItem(name.removeprefix("viseme_"), idx)
        self.vis1.setCurrentIndex(10)
        self.vis_blend = spin(63, "blend (0-63): weight of the first viseme")
        self.blend_vis_button = QPushButton("Apply")
        g.addWidget(QLabel("Viseme"), 1, 0)
        g.addWidget(self.vis1, 1, 1)
        g.addWidget(self.vis_blend, 1, 2)
        g.addWidget(self.vis2, 1, 3)
        g.addWidget(self.blend_vis_button, 1, 5)
        self.blend_expr_button.clicked.connect(self.apply_expression_blend)
        self.blend_vis_button.clicked.connect(self.apply_viseme_blend)
        return box

    # ------------------------------------------------------------------ list
    def reload(self) -> None:
        """Re-read shipped and user presets; malformed user files are listed, not raised."""
        current = self.selected_name()
        problems: list[str] = []
        try:
            self.presets = all_presets(problems)
        except FapStudioError as e:  # a broken shipped preset: still no crash
            self.presets, problems = {}, [str(e)]
        self.problems = problems
        self.list.clear()
        for kind, title in _SECTIONS:
            items = [p for p in self.presets.values() if p.kind == kind]
            if not items:
                continue
            head = QListWidgetItem(title)
            head.setFlags(Qt.ItemFlag.NoItemFlags)
            font = head.font()
            font.setBold(True)
            head.setFont(font)
            self.list.addItem(head)
            for p in items:
                item = QListWidgetItem("    " + _label(p))
                item.setData(Qt.ItemDataRole.UserRole, p.name)
                item.setToolTip(p.description or p.source or p.name)
                self.list.addItem(item)
                if p.name == current:
                    self.list.setCurrentItem(item)
        if problems:
            self.problems_label.setText("Some user presets could not be loaded:\n"
                                        + "\n".join(problems))
        self.problems_label.setVisible(bool(problems))
        self._update_enabled()

    def selected_name(self) -> str | None:
        item = self.list.currentItem()
        return None if item is None else item.data(Qt.ItemDataRole.UserRole)

    def select(self, name: str) -> None:
        for i in range(self.list.count()):
            if self.list.item(i).data(Qt.ItemDataRole.UserRole) == name:
                self.list.setCurrentRow(i)
                return
        raise KeyError(name)

    def _show_intensity(self, v: int) -> None:
        self.intensity_label.setText(f"{v} %")

    def _update_enabled(self) -> None:
        has_doc = self.model.doc is not None
        self.apply_button.setEnabled(has_doc and self.selected_name() is not None)
        for w in (self.blend_expr_button, self.blend_vis_button, self.save_button):
            w.setEnabled(has_doc)

    # ------------------------------------------------------------------ actions
    def _guard(self, title: str, action: Callable[[], object]) -> bool:
        return run_guarded(self, title, action)[0]

    def _push(self, vector: np.ndarray, text: str, mode: str | None = None) -> None:
        doc = self.model.doc
        if doc is None:
            return
        v = np.asarray(vector, np.float32)
        if (mode or self.mode.currentData()) == ADD:
            v = doc.faps + v
        new = doc.with_fap_vector(v)
        if self.model.in_gesture:  # e.g. a paused playback preview: one entry from before it
            self.model.abort_gesture()
        self.model.push(new, text)
        self.model.seal()

    def apply(self, name: str, intensity: float | None = None, mode: str | None = None) -> None:
        """Apply preset ``name`` at ``intensity`` (0-1.5; default: the slider) as one command."""
        pct = self.intensity.value() if intensity is None else round(intensity * 100)

        def run() -> None:
            preset = self.presets.get(name)
            if preset is None:
                raise FapStudioError(f"unknown preset {name!r}")
            vec = apply_preset(preset, pct / 100.0)
            verb = "Add" if (mode or self.mode.currentData()) == ADD else "Apply"
            self._push(vec, f"{verb} preset {name} {pct} %", mode)

        self._guard("Apply preset", run)

    def apply_selected(self) -> None:
        name = self.selected_name()
        if name is not None:
            self.apply(name)

    def apply_expression_blend(self) -> None:
        """FAP 2 blend of the two chosen expressions with their intensities (0-63)."""
        s1, s2 = self.expr1.currentData(), self.expr2.currentData()
        i1, i2 = self.int1.value(), self.int2.value()

        def run() -> None:
            vec = blend_expressions(s1, i1, s2, i2)
            self._push(vec, f"Blend {EXPRESSIONS[s1]} {i1}/63 + {EXPRESSIONS[s2]} {i2}/63")

        self._guard("Blend expressions", run)

    def apply_viseme_blend(self) -> None:
        """FAP 1 blend: first viseme × blend/63 + second × (1 − blend/63)."""
        s1, s2, b = self.vis1.currentData(), self.vis2.currentData(), self.vis_blend.value()

        def run() -> None:
            vec = blend_visemes(s1, s2, b)
            n1, n2 = (VISEMES[s].removeprefix("viseme_") for s in (s1, s2))
            self._push(vec, f"Blend visemes {n1}/{n2} {b}/63")

        self._guard("Blend visemes", run)

    def save_current(self, name: str | None = None) -> bool:
        """Save the current FAPs as a user preset (asks for a name when ``name`` is None)."""
        doc = self.model.doc
        if doc is None:
            return False
        if name is None:
            name, ok = QInputDialog.getText(self, "Save preset", "Preset name (letters, digits, "
                                            "'_' or '-'):")
            if not ok or not name.strip():
                return False
            name = name.strip()
        vec = np.array(doc.faps, np.float64)
        vec[:2] = 0

        p = {k.lower(): v for k, v in self.presets.items()}.get(name.lower())
        overwrite = False
        if p is not None and not p.shipped:
            ans = QMessageBox.question(self, "Save preset", f"Replace the user preset "
                                       f"{p.name!r}?")
            if ans != QMessageBox.StandardButton.Yes:
                return False
            overwrite = True

        def run() -> None:
            save_user_preset(name, vec, overwrite=overwrite)

        ok = self._guard("Save preset", run)
        if ok:
            self.reload()
            self.select(name)
        return ok


def install(window) -> PresetsPanel:
    """Add the "Presets" dock (tabbed on the right) to the main window."""
    panel = PresetsPanel(window.model)
    window.presets_panel = panel
    window.presets_dock = window.add_panel_dock("Presets", panel, "presetsDock")
    from .preset_gallery import install as install_gallery

    install_gallery(window, panel)
    return panel
