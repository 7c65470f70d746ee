"""FAP Studio's public API for scripts: re-exports from the subpackages, no Qt.

The public API is exactly what this module exports (``__all__``); each name's docstring has
numpydoc sections and a runnable example (the test suite runs them all). The code lives in
:mod:`editor.engine` (photo -> mesh -> FAPU, deformation, warp, layers, :class:`Face`),
:mod:`editor.formats` (.fap files, presets, video, projects), :mod:`editor.study` (MOS
studies) and :mod:`editor.synthesis` (FAP estimation, cloning, bilinear model); errors in
:mod:`editor.errors`. Names not exported here are internal to those modules and may change.

Data flow::

    photo --load_image--> RGB uint8 --detect_landmarks--> 68 points + irises
          --fit_vertices--> personalized mesh (V, 2) --measure_fapu--> FAPU
    FAP vector (68,) --deform_points--> (V, 2) --warp--> H x W x 3 uint8

Examples
--------
A face, an expression, an image:

>>> from editor.core import FAPS, Face, apply_preset, save_image
>>> from editor.resources import SAMPLE_FACE
>>> face = Face.from_image(SAMPLE_FACE)             # NoFaceError on a non-face
>>> v = face.deform({"open_jaw": 400, 53: 120})     # (V, 2) float32
>>> img = face.render(apply_preset("anger", 0.8))   # H x W x 3 uint8

:data:`FAPS` is the FAP table (a :class:`~editor.engine.faps.FapTable`), by name or number:

>>> FAPS["open_jaw"].number, FAPS[3].unit, FAPS.vector({"open_jaw": 400}).shape
(3, 'MNS', (68,))

:data:`MAX_PIXELS` is the largest image :func:`load_image` accepts (checked before decoding):

>>> from editor.core import MAX_PIXELS, load_image
>>> MAX_PIXELS
64000000

:func:`detect_landmarks` finds the 68 iBUG points and both irises of the largest face
(:class:`Landmarks`); any object with a ``name`` and a ``detect(rgb) -> (points (68, 2),
box (4,))`` method is a :class:`LandmarkDetector` and can replace the bundled one:

>>> import numpy as np
>>> from editor.core import detect_landmarks
>>> rgb = load_image(SAMPLE_FACE)
>>> lm = detect_landmarks(rgb)
>>> lm.points.shape, lm.box.shape
((68, 2), (4,))
>>> bool(lm.iris_left.cx > lm.iris_right.cx)  # the subject's left eye is on the image right
True
>>> class Known:  # a LandmarkDetector: e.g. points from a file or another program
...     name = "known points"
...     def detect(self, rgb):
...         return lm.points, lm.box
>>> again = detect_landmarks(rgb, Known())
>>> again.detector, bool(np.allclose(again.points, lm.points))
('known points', True)
"""

from editor.engine.face import Face
from editor.engine.faps import FAPS, Fap
from editor.engine.imageio import MAX_PIXELS, load_image, save_image
from editor.engine.landmarks import LandmarkDetector, Landmarks, detect_landmarks
from editor.engine.mesh import StandardMesh, signed_areas, standard_mesh
from editor.errors import (
    FapFileError,
    FapStudioError,
    ImageError,
    ModelError,
    NoFaceError,
    PresetError,
    ProjectError,
    StudyError,
)
from editor.formats.fapfile import FapSequence, read_fap, write_fap
from editor.formats.presets import Preset, all_presets, apply_preset, get_preset

__all__ = [
    "FAPS", "MAX_PIXELS", "Face", "Fap", "FapFileError", "FapSequence", "FapStudioError",
    "ImageError", "Landmarks", "LandmarkDetector", "ModelError", "NoFaceError", "Preset",
    "PresetError", "ProjectError", "StandardMesh", "StudyError", "all_presets", "apply_preset",
    "detect_landmarks", "get_preset", "load_image", "read_fap", "save_image", "signed_areas",
    "standard_mesh", "write_fap",
]
