"""Every data file FAP Studio ships, in one place (``editor/data``, read via importlib.resources).

The files are package data, so they are found the same way from a source checkout, an editable
install and a wheel installed into site-packages. Reading code uses the constants below (real
file-system paths); scripts that regenerate a file write it to ``source_path(CONSTANT)``, which
refuses an installed copy.

====================  ======================================================================
``MESH``              the standard mesh (``scripts/build_mesh.py``)
``NEUTRAL_PRIOR``     the neutral-shape prior (``scripts/build_neutral_prior.py``)
``MOUTH_DIR``         mouth-interior textures ``<name>.png`` for :data:`MOUTH_TEXTURES`
                      (``scripts/draw_mouth_textures.py``)
``PRESETS_DIR``       the shipped emotion and viseme presets (``scripts/derive_presets.py``)
``SAMPLE_FACE``       the bundled sample photo (NASA, public domain)
``MODELS_DIR``        MediaPipe's face detector, face mesh and iris models (Apache-2.0,
                      ``LICENSE`` and ``NOTICE`` beside them; :data:`MODEL_CREDITS`)
``WEB_DIR``           the remote rating page (``index.html``, ``app.js``, ``app.css``)
``MAPPINGS_DIR``      FACS AU -> FAP and ARKit blendshape -> FAP tables (``au_faps.json``,
                      ``arkit.json``; :mod:`editor.formats.facs`, :mod:`editor.formats.arkit`)
``DATA_README``       origins and licences of the files above
====================  ======================================================================
"""

from __future__ import annotations

import atexit
import os
from contextlib import ExitStack
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from importlib.resources.abc import Traversable


def _data_folder() -> Traversable:
    """``editor/data``: the folder itself when the package is plain files (pip, editable,
    source tree: what ``importlib.resources.files`` gives then), else importlib.resources'
    Traversable (a zipped install). importlib.resources is imported only in the latter case:
    it costs ~25 ms of every start, a tenth of ``fap-studio --help`` (issue 15)."""
    folder = Path(__file__).parent / "data"
    if folder.is_dir():
        return folder
    from importlib.resources import files

    return files("editor") / "data"


#: The package data folder as an importlib.resources Traversable.
DATA: Traversable = _data_folder()
#: Names of the mouth textures (``MOUTH_DIR / f"{name}.png"``).
MOUTH_TEXTURES = ("upper_teeth", "lower_teeth", "tongue")

_extracted = ExitStack()
atexit.register(_extracted.close)


def data_path(*parts: str) -> Path:
    """A real file-system path of a data file or folder. An unpacked install (pip, editable,
    source tree) gives the file itself; a zipped one a copy extracted for the process's life."""
    item = DATA.joinpath(*parts)
    if isinstance(item, Path):
        return item
    from importlib.resources import as_file

    return _extracted.enter_context(as_file(item))


def source_path(path: Path) -> Path:
    """``path`` (one of the constants below) as a script's output: allowed only in a source
    checkout (``editor/data`` beside ``pyproject.toml``); an installed copy raises
    ``RuntimeError`` (regenerate the data in the repository, then rebuild the wheel)."""
    root = Path(__file__).resolve().parent / "data"
    target = Path(path).resolve()
    if not (root.parent.parent / "pyproject.toml").is_file() or not target.is_relative_to(root):
        raise RuntimeError(f"{target}: not in a source checkout of FAP Studio; run the script "
                           "from the repository")
    return target


MESH = data_path("mesh.json")
NEUTRAL_PRIOR = data_path("neutral_prior.json")
MOUTH_DIR = data_path("mouth")
PRESETS_DIR = data_path("presets")
SAMPLE_FACE = data_path("sample_face.png")
MODELS_DIR = data_path("models")
WEB_DIR = data_path("web")
MAPPINGS_DIR = data_path("mappings")
DATA_README = data_path("README.md")

#: The landmark models FAP Studio can use, as (model, source, licence) for an About box. The
#: first three ship inside the package (the default detector); dlib's is an optional extra.
MODEL_CREDITS: tuple[tuple[str, str, str], ...] = (
    ("BlazeFace short-range face detector (face_detection_short_range.tflite)",
     "Google MediaPipe 0.10.18, https://github.com/google-ai-edge/mediapipe", "Apache-2.0"),
    ("Face mesh, 468 points (face_landmark.tflite)",
     "Google MediaPipe 0.10.18, https://github.com/google-ai-edge/mediapipe", "Apache-2.0"),
    ("Iris landmarks (iris_landmark.tflite)",
     "Google MediaPipe 0.10.18, https://github.com/google-ai-edge/mediapipe", "Apache-2.0"),
    ("dlib 68-point shape predictor (optional extra: pip install fap-studio[dlib])",
     "dlib (Davis King) via face-recognition-models, trained on iBUG 300-W",
     "model: iBUG 300-W terms, non-commercial use only; dlib code: Boost Software License"),
)

# ------------------------------------------------------------------ per-user folders
APP_NAME = "fap-studio"


def user_data_dir() -> Path:
    """``$FAP_STUDIO_DATA_DIR``, else the per-OS user data folder from platformdirs:
    ``$XDG_DATA_HOME/fap-studio`` or ``~/.local/share/fap-studio`` (Linux),
    ``~/Library/Application Support/fap-studio`` (macOS), ``%APPDATA%\\fap-studio`` (Windows).
    Not created here."""
    env = os.environ.get("FAP_STUDIO_DATA_DIR", "").strip()
    if env:
        return Path(env).expanduser()
    import platformdirs

    return Path(platformdirs.user_data_dir(APP_NAME, appauthor=False, roaming=True))


def user_cache_dir() -> Path:
    """``$FAP_STUDIO_CACHE``, else the per-OS cache folder from platformdirs
    (``$XDG_CACHE_HOME/fap-studio`` or ``~/.cache/fap-studio`` on Linux). Not created here."""
    env = os.environ.get("FAP_STUDIO_CACHE", "").strip()
    if env:
        return Path(env).expanduser()
    import platformdirs

    return Path(platformdirs.user_cache_dir(APP_NAME, appauthor=False))

# ------------------------------------------------------------------ external data (not shipped)
#: Environment variable naming the JAFFE folder (``DIR/images/*.tiff``); research-only data that
#: is never shipped or copied into the repository.
JAFFE_ENV = "FAP_STUDIO_JAFFE"


def jaffe_dir(explicit: str | Path | None = None) -> Path | None:
    """The JAFFE folder: ``explicit``, else ``$FAP_STUDIO_JAFFE``, else None (not configured)."""
    if explicit:
        return Path(explicit).expanduser()
    env = os.environ.get(JAFFE_ENV, "").strip()
    return Path(env).expanduser() if env else None


def checkout_jaffe_dir() -> Path:
    """``$FAP_STUDIO_JAFFE``, else the development layout's ``../shared/data/jaffe`` beside the
    source checkout (for tests and scripts/ run from the repository)."""
    return jaffe_dir() or Path(__file__).resolve().parents[2] / "shared" / "data" / "jaffe"


# ---------------------------------------------------------------------- credits
#: What FAP Studio is made of and under which terms: (component, source, licence) entries,
#: shown by the editor's About box. Qt-free, so any layer (and other detectors' modules) can
#: append its own entry with :func:`add_credit`.
CREDITS: list[tuple[str, str, str]] = [
    ("Qt 6 via PySide6 (Qt for Python)", "The Qt Company, https://www.qt.io/qt-for-python",
     "LGPL-3.0 (dynamically linked; you may replace the Qt libraries)"),
    *MODEL_CREDITS,
    ("dlib face detector and shape predictor (optional extra)", "http://dlib.net",
     "Boost Software License 1.0"),
    ("OpenCV (opencv-python-headless)", "https://opencv.org", "Apache-2.0"),
    ("NumPy, SciPy", "https://numpy.org, https://scipy.org", "BSD-3-Clause"),
    ("pyqtgraph", "https://www.pyqtgraph.org", "MIT"),
    ("PyAV and FFmpeg's libraries", "https://pyav.org, https://ffmpeg.org",
     "BSD-3-Clause (PyAV); LGPL-2.1+ (FFmpeg as shipped in the av wheels)"),
    ("platformdirs, tqdm", "https://pypi.org", "MIT; MPL-2.0 and MIT"),
    ("Starlette, uvicorn, limits (study serve)",
     "https://www.starlette.io, https://www.uvicorn.org, https://limits.readthedocs.io",
     "BSD-3-Clause; BSD-3-Clause; MIT"),
    ("Sample face (editor/data/sample_face.png)",
     "NASA portrait of astronaut Eileen Collins (1998), as shipped by scikit-image",
     "public domain in the United States (NASA media usage guidelines)"),
]


def add_credit(component: str, source: str, licence: str) -> None:
    """Add a (component, source, licence) entry to :data:`CREDITS` (once)."""
    entry = (component, source, licence)
    if entry not in CREDITS:
        CREDITS.append(entry)


def sample_face_credit() -> str:
    """The sample photo's line of ``editor/data/README.md`` (origin and licence), or ''."""
    try:
        text = DATA_README.read_text(encoding="utf-8")
    except OSError:
        return ""
    for line in text.splitlines():
        if line.startswith("| `sample_face.png`"):
            return line.strip("| ").split(" | ")[-1].strip()
    return ""
