"""File formats and the editor's Qt-free state (no Qt): MPEG-4 ``.fap`` sequences
(:mod:`.fapfile`), expression presets (:mod:`.presets`), the MPEG-4 FAP 1/2 blends
(:mod:`.blends`), keyframe authoring (:mod:`.keyframes`), FACS Action Units and ARKit
blendshapes (:mod:`.facs`, :mod:`.arkit`, :mod:`.facecsv`), video export (:mod:`.video`),
``.fapproj`` projects (:mod:`.project`), the playhead (:mod:`.playhead`) and the editor's
:class:`~.document.Document`. Built on :mod:`editor.engine` (the FAP table, image encoding).
"""
