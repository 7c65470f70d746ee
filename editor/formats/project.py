"""Project files: photo reference + edited mesh + FAP values + animation as readable JSON.

Example (``version`` 2)::

    {
      "format": "fap-studio-project",
      "version": 2,
      "photo": "sample_face.png",
      "photo_absolute": "/home/ann/faces/sample_face.png",
      "faps": {"open_jaw": 400, "raise_l_cornerlip_o": 120.5},
      "photo_is_neutral": false,
      "mesh": {"vertices": {"brow_r_e0": [180.25, 96.5], ...}},
      "photo_embedded": {"name": "sample_face.png", "base64": "iVBORw0..."},
      "animation": {"fps": 25, "interpolation": "linear",
                    "keyframes": [{"t": 0, "faps": {}}, {"t": 1, "faps": {"open_jaw": 400}}],
                    "sequence": {"source": "/home/ann/smile.fap", "fap": "2.1 smile 25 51\n..."}}
    }

``photo`` is relative to the project file's folder when possible and ``photo_absolute`` is
where it was when saved: a project copied elsewhere finds its photo by either; when neither
exists the reader says so (:attr:`ProjectData.photo_found`) and the editor asks where it is.
``photo_embedded`` (optional) holds the photo file itself, so the project travels alone.
``faps`` lists the non-zero FAPs by MPEG-4 name (numbers are accepted too), applied to the
neutralised face, or to the photo itself when ``photo_is_neutral`` is true (absent: false).
``mesh.vertices`` maps every vertex name of the standard mesh to its position (x, y) in image
pixels, y down. Numbers are written as the shortest decimal that reads back to the same
float32, so a project reopens bit-identical. ``mesh`` may be absent: the fitted mesh is used.
``animation`` (optional) holds the keyframes and the loaded sequence as ``.fap`` text.
Version 1 files (no ``photo_absolute``, embedding or animation) are still read. No Qt here.
"""

from __future__ import annotations

import base64
import binascii
import json
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from editor.engine.faps import FAPS
from editor.errors import FapFileError, ProjectError
from editor.formats.document import NO_ANIMATION, Animation
from editor.resources import user_cache_dir
from editor.safeio import atomic_write_bytes, atomic_write_text, read_bounded

FORMAT = "fap-studio-project"
VERSION = 2
SUFFIX = ".fapproj"
#: An embedded photo (base64) makes projects large; one without stays far below.
MAX_EMBEDDED_PHOTO_BYTES = 96 * 1024 * 1024
MAX_PROJECT_BYTES = MAX_EMBEDDED_PHOTO_BYTES * 4 // 3 + 16 * 1024 * 1024


def _no_constant(name: str) -> None:
    raise ValueError(f"{name} is not a number JSON allows")


def _num(x: float) -> str:
    """Shortest decimal that reads back as the same float32 (valid JSON)."""
    return np.format_float_positional(np.float32(x), unique=True, trim="-")


@dataclass(frozen=True, eq=False)
class ProjectData:
    """A project read from disk.

    photo : absolute path of the photo: the relative reference if that file exists, else the
        absolute one if it exists, else the embedded photo's copy in the cache folder, else
        the relative reference (``photo_found`` False: ask the user where it is)
    vertices : (V, 2) float32 neutral mesh in image pixels, or None (use the fitted mesh)
    faps : (68,) float32 FAP values in FAPU (not clamped; the document clamps)
    photo_neutral : the photo is declared neutral (FAPs apply to the photo itself)
    photo_found : ``photo`` exists
    embed_photo : the project embeds its photo (saved again so)
    animation : keyframes and sequence (empty for version 1)
    """

    photo: str
    vertices: np.ndarray | None
    faps: np.ndarray
    photo_neutral: bool = False
    photo_found: bool = True
    embed_photo: bool = False
    animation: Animation = NO_ANIMATION


def _faps_json(vec: np.ndarray, indent: str) -> str:
    items = [f"{indent}  {json.dumps(FAPS[i + 1].name)}: {_num(v)}"
             for i, v in enumerate(np.asarray(vec, np.float32)) if v != 0]
    return "{\n" + ",\n".join(items) + f"\n{indent}}}" if items else "{}"


def _animation_json(anim: Animation) -> str:
    keys = [f'      {{"t": {_num(t)}, "faps": {_faps_json(v, "      ")}}}' for t, v in anim.keys]
    parts = [f'    "fps": {_num(anim.fps)}', f'    "interpolation": "{anim.interpolation}"',
             '    "keyframes": [' + ("\n" + ",\n".join(keys) + "\n    ]" if keys else "]")]
    if anim.sequence is not None:
        from editor.formats.fapfile import format_fap  # the .fap writer: when there is a sequence

        parts.append('    "sequence": {"source": ' + json.dumps(anim.source) + ', "fap": '
                     + json.dumps(format_fap(anim.sequence)) + "}")
    return "{\n" + ",\n".join(parts) + "\n  }"


def project_text(photo: str, vertices: np.ndarray, faps: np.ndarray, names: Sequence[str],
                 base: Path | None = None, photo_neutral: bool = False, *,
                 embed: bool = False, animation: Animation = NO_ANIMATION) -> str:
    """The JSON text of a project; ``photo`` is written relative to ``base`` when possible
    (and absolute beside it); ``embed`` stores the photo file itself (ProjectError if it
    cannot be read)."""
    absolute = str(Path(photo).resolve())
    ph = absolute
    if base is not None:
        try:
            ph = os.path.relpath(ph, base.resolve())
        except ValueError:  # another drive (Windows)
            pass
    vert_items = [f"      {json.dumps(n)}: [{_num(x)}, {_num(y)}]"
                  for n, (x, y) in zip(names, np.asarray(vertices, np.float32), strict=True)]
    embedded = ""
    if embed:
        data = read_bounded(absolute, MAX_EMBEDDED_PHOTO_BYTES, error=ProjectError,
                            what="a photo to embed")
        embedded = ('  "photo_embedded": {"name": ' + json.dumps(Path(absolute).name)
                    + ', "base64": "' + base64.b64encode(data).decode("ascii") + '"},\n')
    anim = f'  "animation": {_animation_json(animation)},\n' if not animation.empty else ""
    return (
        "{\n"
        f'  "format": "{FORMAT}",\n'
        f'  "version": {VERSION},\n'
        f'  "photo": {json.dumps(ph.replace(os.sep, "/"))},\n'
        f'  "photo_absolute": {json.dumps(absolute)},\n'
        f'  "faps": {_faps_json(faps, "  ")},\n'
        + ('  "photo_is_neutral": true,\n' if photo_neutral else "")
        + embedded + anim +
        '  "mesh": {\n    "vertices": {\n' + ",\n".join(vert_items) + "\n    }\n  }\n}\n"
    )


def save_project(path: str | os.PathLike[str], photo: str, vertices: np.ndarray,
                 faps: np.ndarray, names: Sequence[str], photo_neutral: bool = False, *,
                 embed: bool = False, animation: Animation = NO_ANIMATION) -> None:
    """Write a project file atomically; ProjectError if it cannot be written."""
    p = Path(path)
    for what, a in (("FAP values", faps), ("mesh vertices", vertices)):
        if not np.isfinite(np.asarray(a, np.float64)).all():
            raise ProjectError(f"{p}: not saved: the {what} hold NaN or infinite numbers")
    text = project_text(photo, vertices, faps, names, p.parent, photo_neutral, embed=embed,
                        animation=animation)
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
    absolute = d.get("photo_absolute", "")
    if not isinstance(absolute, str):
        raise ProjectError(f'{p}: "photo_absolute" must be a path')
    ph = Path(photo)
    if not ph.is_absolute():
        ph = p.parent / ph
    embedded = _embedded_photo(p, d.get("photo_embedded"))
    candidates = [ph, *([Path(absolute)] if absolute.strip() else [])]
    found = next((c for c in candidates if c.is_file()), None)
    if found is None and embedded is not None:
        found = embedded
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
    anim = _animation(p, d.get("animation"))
    return ProjectData(str((found or ph).resolve()), vertices, faps, neutral,
                       photo_found=found is not None, embed_photo=embedded is not None,
                       animation=anim)


def _embedded_photo(p: Path, block: object) -> Path | None:
    """The embedded photo written to the cache folder (named by its content hash: the same
    photo is written once), or None when the project embeds none."""
    import hashlib

    if block is None:
        return None
    if not isinstance(block, dict) or not isinstance(block.get("base64"), str):
        raise ProjectError(f'{p}: "photo_embedded" must hold "name" and "base64"')
    try:
        data = base64.b64decode(block["base64"], validate=True)
    except (binascii.Error, ValueError):
        raise ProjectError(f"{p}: the embedded photo is not valid base64") from None
    name = str(block.get("name") or "photo.png")
    suffix = Path(name).suffix.lower()
    if not suffix[1:].isalnum() or len(suffix) > 6:
        suffix = ".png"
    out = user_cache_dir() / "embedded" / (hashlib.sha256(data).hexdigest()[:32] + suffix)
    if not out.is_file():
        out.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(out, data, error=ProjectError)
    return out


def _animation(p: Path, block: object) -> Animation:
    if block is None:
        return NO_ANIMATION
    if not isinstance(block, dict):
        raise ProjectError(f'{p}: "animation" must be an object')
    try:
        keys = []
        for k in block.get("keyframes", []):
            if not isinstance(k, dict) or not isinstance(k.get("faps", {}), dict):
                raise ValueError('every keyframe must be {"t": seconds, "faps": {...}}')
            t = k.get("t")
            if not isinstance(t, (int, float)) or isinstance(t, bool) or not 0 <= t < 1e6:
                raise ValueError(f"keyframe time {t!r} is not a number of seconds")
            keys.append((float(t), FAPS.vector(k.get("faps", {}))))
        seq, source = None, ""
        sblock = block.get("sequence")
        if sblock is not None:
            if not isinstance(sblock, dict) or not isinstance(sblock.get("fap"), str):
                raise ValueError('"sequence" must hold the .fap text as "fap"')
            source = str(sblock.get("source") or "")
            from editor.formats.fapfile import read_fap  # the .fap reader: when there is a sequence

            seq = read_fap(sblock["fap"].encode("utf-8"), label="the sequence")
        return Animation(tuple(keys), float(block.get("fps", 25.0)),
                         str(block.get("interpolation", "linear")), seq, source)
    except (ValueError, TypeError, FapFileError) as e:
        raise ProjectError(f"{p}: animation: {e}") from None

