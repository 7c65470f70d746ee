"""File formats (no Qt): MPEG-4 ``.fap`` sequences (:mod:`.fapfile`), expression presets and
keyframe authoring (:mod:`.expressions`), video export (:mod:`.video`), ``.fapproj`` projects
(:mod:`.project`) and the editor's Qt-free :class:`~.document.Document`. Built on
:mod:`editor.engine` (the FAP table, image encoding).
"""
