"""Help for the editor: the F1 panel (every action with its shortcut and what it does), the About
box (versions and every licence, from :data:`editor.resources.CREDITS`) and the first-run hint.
"""

from __future__ import annotations

import html
import platform

from PySide6.QtCore import Qt
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import (
    QDialog,
    QDialogButtonBox,
    QLabel,
    QMainWindow,
    QTextBrowser,
    QVBoxLayout,
    QWidget,
)

from editor import __version__
from editor.resources import CREDITS, sample_face_credit

from .qt_utils import settings

#: QSettings key: the first-run hint was dismissed (or its advice followed).
HINT_DONE = "ui/firstRunHintDone"

HINT_TEXT = ("New here? Pick an expression in the <b>Presets</b> tab (or click one in the "
             "<b>Gallery</b>), drag the dot on the <b>Eye gaze</b> pad, or move any FAP slider. "
             "F1 lists every shortcut.")


def action_rows(window: QMainWindow) -> list[tuple[str, str, str, str]]:
    """(menu, action, shortcut, status tip) of every menu action, in menu order."""
    rows: list[tuple[str, str, str, str]] = []

    def walk(menu_title: str, actions: list[QAction]) -> None:
        for a in actions:
            if a.isSeparator():
                continue
            sub = a.menu()
            if sub is not None:
                walk(f"{menu_title} › {a.text().replace('&', '')}", sub.actions())
                continue
            keys = ", ".join(k.toString(QKeySequence.SequenceFormat.NativeText)
                             for k in a.shortcuts())
            rows.append((menu_title, a.text().replace("&", ""), keys, a.statusTip()))

    for top in window.menuBar().actions():
        if top.menu() is not None:
            walk(top.text().replace("&", ""), top.menu().actions())
    return rows


def help_html(window: QMainWindow) -> str:
    """The help panel's page: what to do first, then every action by menu."""
    out = [f"<h3>FAP Studio {html.escape(__version__)}</h3>",
           "<p>One frontal photo, any expression, through the MPEG-4 Facial Animation "
           "Parameters. Start with a <b>preset</b>, the <b>eye gaze</b> pad or a FAP slider; "
           "drag mesh vertices on the photo to correct the fit; <b>Ctrl+Z</b> undoes any "
           "step.</p>",
           "<p>Canvas: wheel zooms, drag pans, <b>F</b> fits the photo, <b>Shift+F</b> zooms "
           "to the face, <b>M</b> shows or hides the mesh.</p>"]
    menu = None
    for m, name, keys, tip in action_rows(window):
        if m != menu:
            if menu is not None:
                out.append("</table>")
            out.append(f"<h4>{html.escape(m)}</h4><table cellspacing='0' cellpadding='2'>")
            menu = m
        out.append(f"<tr><td><b>{html.escape(name)}</b></td><td><tt>{html.escape(keys)}</tt>"
                   f"</td><td>{html.escape(tip)}</td></tr>")
    if menu is not None:
        out.append("</table>")
    return "\n".join(out)


class HelpPanel(QTextBrowser):
    """The F1 dock: the help page, rebuilt each time it is shown (menus may have grown)."""

    def __init__(self, window: QMainWindow, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.window_ = window
        self.setOpenExternalLinks(True)
        self.refresh()

    def refresh(self) -> None:
        self.setHtml(help_html(self.window_))


def about_html() -> str:
    from PySide6 import __version__ as pyside_version
    from PySide6.QtCore import qVersion

    rows = "".join(f"<tr><td><b>{html.escape(c)}</b></td><td>{html.escape(s)}</td>"
                   f"<td>{html.escape(lic)}</td></tr>" for c, s, lic in CREDITS)
    sample = sample_face_credit()
    return (f"<h3>FAP Studio {html.escape(__version__)}</h3>"
            "<p>One frontal photo, any expression, through the MPEG-4 Facial Animation "
            "Parameters.</p>"
            f"<p>Python {platform.python_version()} · Qt {qVersion()} · PySide6 "
            f"{pyside_version}</p>"
            "<h4>Components and licences</h4>"
            "<table cellspacing='0' cellpadding='3'><tr><th align='left'>component</th>"
            "<th align='left'>source</th><th align='left'>licence</th></tr>"
            f"{rows}</table>"
            + (f"<h4>Sample photo</h4><p>{html.escape(sample)}</p>" if sample else ""))


class AboutDialog(QDialog):
    """Versions and every component's licence (a scrollable page, not a message box)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("About FAP Studio")
        self.text = QTextBrowser()
        self.text.setOpenExternalLinks(True)
        self.text.setHtml(about_html())
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Close)
        buttons.rejected.connect(self.reject)
        lay = QVBoxLayout(self)
        lay.addWidget(self.text)
        lay.addWidget(buttons)
        self.resize(760, 520)


class FirstRunHint(QLabel):
    """A line above the canvas pointing at presets and the gaze pad, until the first edit
    (or a click on it); remembered in QSettings."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(HINT_TEXT + " <a href='#close'>Got it</a>", parent)
        self.setWordWrap(True)
        self.setTextFormat(Qt.TextFormat.RichText)
        self.setStyleSheet("QLabel { background: #fff6cc; color: #333; padding: 6px; "
                           "border-bottom: 1px solid #e0c860; }")
        self.linkActivated.connect(lambda _l: self.done())
        self.setVisible(not bool(settings().value(HINT_DONE, False, type=bool)))

    def done(self) -> None:
        """The user has found their way: hide for good."""
        if self.isVisible() or not settings().value(HINT_DONE, False, type=bool):
            settings().setValue(HINT_DONE, True)
        self.hide()
