"""File formats (no Qt): MPEG-4 ``.fap`` sequences (:mod:`.fapfile`), expression presets and
keyframe authoring (:mod:`.expressions`), video export (:mod:`.video`) and ``.fapproj`` projects
(:mod:`.project`). Built on :mod:`editor.engine` (the FAP table, image encoding).
"""
