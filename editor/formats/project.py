"""Project files: photo reference + edited mesh + FAP values as human-readable JSON.

Example (``version`` 1)::

    {
      "format": "fap-studio-project",
      "version": 1,
      "photo": "sample_face.png",
      "faps": {"open_jaw": 400, "raise_l_cornerlip_o": 120.5},
      "photo_is_neutral": false,
      "mesh": {"vertices": {"brow_r_e0": [180.25, 96.5], ...}}
    }

``photo`` is relative to the project file's folder when possible. ``faps`` lists the non-zero
FAPs by MPEG-4 name (numbers are accepted too), applied to the neutralised face, or to the
photo itself when ``photo_is_neutral`` is true (absent: false). ``mesh.vertices`` maps every
vertex name of the standard mesh to its position (x, y) in image pixels, y down. Numbers are
written as the shortest decimal that reads back to the same float32, so a project reopens
bit-identical.
``mesh`` may be absent: the fitted mesh is used. No Qt here.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from editor.engine.faps import FAPS
from editor.errors import ProjectError
from editor.safeio import atomic_write_text, read_bounded

FORMAT = "fap-studio-project"
VERSION = 1
SUFFIX = ".fapproj"
MAX_PROJECT_BYTES = 16 * 1024 * 1024


def _no_constant(name: str) -> None:
    raise ValueError(f"{name} is not a number JSON allows")


def _num(x: float) -> str:
    """Shortest decimal that reads back as the same float32 (valid JSON)."""
    return np.format_float_positional(np.float32(x), unique=True, trim="-")


@dataclass(frozen=True, eq=False)
class ProjectData:
    """A project read from disk.

    photo : absolute path of the photo
    vertices : (V, 2) float32 neutral mesh in image pixels, or None (use the fitted mesh)
    faps : (68,) float32 FAP values in FAPU (not clamped; the document clamps)
    photo_neutral : the photo is declared neutral (FAPs apply to the photo itself)
    """

    photo: str
    vertices: np.ndarray | None
    faps: np.ndarray
    photo_neutral: bool = False


def project_text(photo: str, vertices: np.ndarray, faps: np.ndarray, names: Sequence[str],
                 base: Path | None = None, photo_neutral: bool = False) -> str:
    """The JSON text of a project; ``photo`` is written relative to ``base`` when possible."""
    ph = str(Path(photo).resolve())
    if base is not None:
        try:
            ph = os.path.relpath(ph, base.resolve())
        except ValueError:  # another drive (Windows)
            pass
    fap_items = [f"    {json.dumps(FAPS[i + 1].name)}: {_num(v)}"
                 for i, v in enumerate(np.asarray(faps, np.float32)) if v != 0]
    vert_items = [f"      {json.dumps(n)}: [{_num(x)}, {_num(y)}]"
                  for n, (x, y) in zip(names, np.asarray(vertices, np.float32), strict=True)]
    faps_block = "{\n" + ",\n".join(fap_items) + "\n  }" if fap_items else "{}"
    return (
        "{\n"
        f'  "format": "{FORMAT}",\n'
        f'  "version": {VERSION},\n'
        f'  "photo": {json.dumps(ph.replace(os.sep, "/"))},\n'
        f'  "faps": {faps_block},\n'
        + ('  "photo_is_neutral": true,\n' if photo_neutral else "") +
        '  "mesh": {\n    "vertices": {\n' + ",\n".join(vert_items) + "\n    }\n  }\n}\n"
    )


def save_project(path: str | os.PathLike[str], photo: str, vertices: np.ndarray,
                 faps: np.ndarray, names: Sequence[str], photo_neutral: bool = False) -> None:
    """Write a project file atomically; ProjectError if it cannot be written."""
    p = Path(path)
    for what, a in (("FAP values", faps), ("mesh vertices", vertices)):
        if not np.isfinite(np.asarray(a, np.float64)).all():
            raise ProjectError(f"{p}: not saved: the {what} hold NaN or infinite numbers")
    text = project_text(photo, vertices, faps, names, p.parent, photo_neutral)
    atomic_write_text(p, text, error=ProjectError)


def _point(p: Path, name: str, xy: object) -> tuple[float, float]:
    if (not isinstance(xy, list) or len(xy) != 2
            or not all(isinstance(c, (int, float)) and not isinstance(c, bool)
                       and abs(c) < 1e9 for c in xy)):
        raise ProjectError(f"{p}: mesh vertex {name!r} must be [x, y] with two finite numbers")
    return float(xy[0]), float(xy[1])


def load_project(path: str | os.PathLike[str], names: Sequence[str]) -> ProjectData:
    """Read and validate a project file (``names``: vertex names of the standard mesh).

    Raises ProjectError with a one-line message naming the file and what is wrong.
    """
    p = Path(path)
    raw = read_bounded(p, MAX_PROJECT_BYTES, error=ProjectError, what="a project file")
    try:
        d = json.loads(raw.decode("utf-8"), parse_constant=_no_constant)
    except UnicodeDecodeError as e:
        raise ProjectError(f"{p}: not a project file (not UTF-8 text)") from e
    except json.JSONDecodeError as e:
        raise ProjectError(f"{p}: not a project file (invalid JSON at line {e.lineno}: "
                           f"{e.msg})") from e
    except (ValueError, RecursionError) as e:  # NaN/Infinity, a 5000-digit number, nesting
        why = "nested too deeply" if isinstance(e, RecursionError) else str(e)[:80]
        raise ProjectError(f"{p}: not a project file ({why})") from None
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        raise ProjectError(f'{p}: not a FAP Studio project (no "format": "{FORMAT}")')
    version = d.get("version")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise ProjectError(f"{p}: invalid project version {version!r}")
    if version > VERSION:
        raise ProjectError(f"{p}: project version {version} is newer than this FAP Studio "
                           f"reads (up to {VERSION})")
    photo = d.get("photo")
    if not isinstance(photo, str) or not photo.strip():
        raise ProjectError(f'{p}: "photo" must be the path of the photo')
    ph = Path(photo)
    if not ph.is_absolute():
        ph = p.parent / ph
    faps_d = d.get("faps", {})
    if not isinstance(faps_d, dict):
        raise ProjectError(f'{p}: "faps" must map FAP names to values')
    for k, v in faps_d.items():
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not abs(v) < 1e9:
            raise ProjectError(f"{p}: FAP {k!r}: value {v!r} is not a number")
    try:
        faps = FAPS.vector(faps_d)
    except ValueError as e:
        raise ProjectError(f"{p}: {e}") from e
    neutral = d.get("photo_is_neutral", False)
    if not isinstance(neutral, bool):
        raise ProjectError(f'{p}: "photo_is_neutral" must be true or false')
    vertices = None
    mesh = d.get("mesh")
    if mesh is not None:
        verts = mesh.get("vertices") if isinstance(mesh, dict) else None
        if not isinstance(verts, dict):
            raise ProjectError(f'{p}: "mesh" must hold "vertices": {{name: [x, y]}}')
        unknown = sorted(set(verts) - set(names))
        if unknown:
            raise ProjectError(f"{p}: unknown mesh vertex {unknown[0]!r}")
        missing = [n for n in names if n not in verts]
        if missing:
            raise ProjectError(f"{p}: the mesh lacks vertex {missing[0]!r} "
                               f"({len(missing)} missing)")
        vertices = np.array([_point(p, n, verts[n]) for n in names], np.float32)
    return ProjectData(str(ph.resolve()), vertices, faps, neutral)

