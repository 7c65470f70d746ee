"""FAP Studio's public API for scripts: re-exports from the subpackages, no Qt.

The code lives in :mod:`editor.engine` (photo -> mesh -> FAPU, deformation, warp, layers,
:class:`Face`), :mod:`editor.formats` (.fap files, presets, video, projects), :mod:`editor.study`
(MOS studies) and :mod:`editor.synthesis` (FAP estimation, cloning, bilinear model); errors in
:mod:`editor.errors`. Names not listed in ``__all__`` are internal to those modules.

Data flow::

    photo --load_image--> RGB uint8 --detect_landmarks--> 68 points + irises
          --fit_vertices--> personalized mesh (V, 2) --measure_fapu--> FAPU
    FAP vector (68,) --deform_points--> (V, 2) --warp--> H x W x 3 uint8

Public API::

    from editor.core import Face, FAPS
    face = Face.from_image("photo.jpg")          # NoFaceError on a non-face
    v = face.deform({"open_jaw": 400, 53: 120})  # (V, 2) float32
    img = face.render({"open_jaw": 400})         # H x W x 3 uint8
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
