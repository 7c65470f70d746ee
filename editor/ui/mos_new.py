"""The "New Study from Faces…" dialog: faces × presets × intensities → a rendered study."""

from __future__ import annotations

from pathlib import Path

from PySide6.QtWidgets import (
    QCheckBox,
    QDialog,
    QDialogButtonBox,
    QFileDialog,
    QFormLayout,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QListWidget,
    QPushButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from editor.errors import StudyError
from editor.study.stimuli import PAPER_EXPRESSIONS

IMAGE_FILTER = "Images (*.png *.jpg *.jpeg *.bmp *.tif *.tiff)"


def expression_presets() -> list[str]:
    """Names of the available expression presets (visemes left out), paper's five first."""
    from editor.formats.presets import all_presets

    names = [n for n, p in all_presets([]).items() if not n.startswith("viseme")
             and getattr(p, "kind", "expression") != "viseme"]
    return [*[n for n in PAPER_EXPRESSIONS if n in names],
            *sorted(n for n in names if n not in PAPER_EXPRESSIONS)]


class NewStudyDialog(QDialog):
    """Collects faces, presets, intensities and study settings (no rendering here)."""

    def __init__(self, faces: list[str], parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("New Study from Faces")
        self.faces = QListWidget()
        self.faces.addItems(faces)
        add, remove = QPushButton("Add Photos…"), QPushButton("Remove")
        add.clicked.connect(self._add_faces)
        remove.clicked.connect(lambda: [self.faces.takeItem(self.faces.row(i))
                                        for i in self.faces.selectedItems()])
        face_buttons = QHBoxLayout()
        face_buttons.addWidget(add)
        face_buttons.addWidget(remove)
        face_buttons.addStretch(1)
        self.presets: dict[str, QCheckBox] = {}
        grid = QGridLayout()
        for i, name in enumerate(expression_presets()):
            box = QCheckBox(name)
            self.presets[name] = box
            grid.addWidget(box, i // 4, i % 4)
        paper = QPushButton("Paper's design (5 expressions at 100 %)")
        paper.clicked.connect(self.paper_design)
        self.intensities = QLineEdit("1.0")
        self.intensities.setToolTip("comma-separated preset intensities 0–1.5, e.g. 0.5, 1.0")
        self.name = QLineEdit("pilot")
        self.break_every = QSpinBox()
        self.break_every.setRange(0, 1000)
        self.break_every.setSpecialValueText("never")
        self.allow_revise = QCheckBox("raters may go back and change answers")
        self.output = QLineEdit()
        browse = QPushButton("…")
        browse.clicked.connect(self._browse)
        out_row = QHBoxLayout()
        out_row.addWidget(self.output, 1)
        out_row.addWidget(browse)
        form = QFormLayout()
        form.addRow("Study name", self.name)
        form.addRow("Intensities", self.intensities)
        form.addRow("Break every N images", self.break_every)
        form.addRow("", self.allow_revise)
        form.addRow("Study file", out_row)
        box = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok
                               | QDialogButtonBox.StandardButton.Cancel)
        box.accepted.connect(self.accept)
        box.rejected.connect(self.reject)
        self.error_label = QLabel()
        self.error_label.setWordWrap(True)
        self.error_label.setStyleSheet("color: #b00020; font-weight: bold")
        self.error_label.hide()
        lay = QVBoxLayout(self)
        lay.addWidget(self.faces)
        lay.addLayout(face_buttons)
        lay.addLayout(grid)
        lay.addWidget(paper)
        lay.addLayout(form)
        lay.addWidget(self.error_label)
        lay.addWidget(box)
        self.paper_design()

    def accept(self) -> None:
        """OK: close only when the input is valid; otherwise say why and keep everything
        entered."""
        try:
            self.values()
        except StudyError as e:
            self.show_error(str(e))
            return
        self.error_label.hide()
        super().accept()

    def show_error(self, message: str) -> None:
        """Show ``message`` above the buttons (the dialog stays open with its input)."""
        self.error_label.setText(message)
        self.error_label.show()

    def paper_design(self) -> None:
        """Check exactly the paper's five expressions at intensity 1.0."""
        for name, box in self.presets.items():
            box.setChecked(name in PAPER_EXPRESSIONS)
        self.intensities.setText("1.0")

    def _add_faces(self) -> None:
        paths, _ = QFileDialog.getOpenFileNames(self, "Neutral face photos", "", IMAGE_FILTER)
        self.faces.addItems(paths)

    def _browse(self) -> None:
        path, _ = QFileDialog.getSaveFileName(self, "New study file", "study.fapstudy.db",
                                              "FAP Studio study (*.db)")
        if path:
            self.output.setText(path)

    def values(self) -> tuple[list[str], list[str], list[float], str, Path, int, bool]:
        """(faces, presets, intensities, name, path, break_every, allow_revise); raises
        :class:`StudyError` on missing or invalid input."""
        faces = [self.faces.item(i).text() for i in range(self.faces.count())]
        presets = [n for n, b in self.presets.items() if b.isChecked()]
        try:
            ks = [float(x) for x in self.intensities.text().split(",") if x.strip()]
        except ValueError as e:
            raise StudyError(f"intensities {self.intensities.text()!r}: not numbers") from e
        if not faces or not presets or not ks:
            raise StudyError("choose at least one face, one preset and one intensity")
        if any(not 0 <= k <= 1.5 for k in ks):
            raise StudyError("intensities must be within 0 … 1.5")
        if not self.output.text().strip():
            raise StudyError("choose a file for the new study")
        return (faces, presets, ks, self.name.text().strip() or "study",
                Path(self.output.text().strip()), self.break_every.value(),
                self.allow_revise.isChecked())
