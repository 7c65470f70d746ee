"""FAP Studio's editor window (PySide6 + pyqtgraph): a thin layer over one ``DocumentModel``.

Flow: widget -> :class:`~editor.ui.document_model.DocumentModel` (immutable ``Document``
snapshots, one ``QUndoCommand`` per gesture) -> ``changed(old, new)`` -> views and the
latest-only :class:`~editor.ui.render_scheduler.RenderScheduler` -> preview. Start it with
:func:`editor.ui.app.run`.
"""

from .qt_compat import guard_singleton_refcounts

guard_singleton_refcounts()
