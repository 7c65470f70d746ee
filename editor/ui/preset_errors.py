"""Error reporting shared by the preset and playback panels."""

from __future__ import annotations

import traceback
from collections.abc import Callable

from PySide6.QtWidgets import QMessageBox, QWidget

from editor.core import FapStudioError


def run_guarded(parent: QWidget, title: str, action: Callable[[], object]) -> bool:
    """Run ``action``; a :class:`FapStudioError` (or, as a last resort, any exception) becomes
    a warning box with its one-line message. True if ``action`` succeeded."""
    try:
        action()
    except FapStudioError as e:
        message = str(e)
    except Exception as e:  # a bug must not take the user's work down
        traceback.print_exc()
        message = f"unexpected error: {type(e).__name__}: {e}"
    else:
        return True
    QMessageBox.warning(parent, title, message.splitlines()[0] if message.strip() else title)
    return False
