"""FAP Studio core: pure numpy/OpenCV, no Qt.

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

from .errors import (
    FapFileError,
    FapStudioError,
    ImageError,
    ModelError,
    NoFaceError,
    PresetError,
    ProjectError,
    StudyError,
)
from .face import Face
from .faps import FAPS, Fap
from .imageio import MAX_PIXELS, load_image, save_image
from .landmarks import LandmarkDetector, Landmarks, detect_landmarks
from .mesh import StandardMesh, signed_areas, standard_mesh

__all__ = [
    "FAPS", "MAX_PIXELS", "Face", "Fap", "FapFileError", "FapStudioError", "ImageError",
    "Landmarks", "LandmarkDetector", "ModelError", "NoFaceError", "PresetError",
    "ProjectError", "StandardMesh", "StudyError", "detect_landmarks", "load_image",
    "save_image", "signed_areas", "standard_mesh",
]
