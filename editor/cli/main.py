"""Command line of FAP Studio: ``fap-studio COMMAND ...`` (``--help`` on every command).

Every user error (bad file, no face, malformed value) prints one line
``fap-studio: error: ...`` on stderr and exits with code 2; no traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from editor import __version__
from editor.errors import FapStudioError

from .anim import add_anim_parser
from .bilinear import add_bilinear_parser
from .clone import add_clone_parser
from .facs import add_facs_parser
from .study import add_study_parser
from .util import PHOTO_HELP, SAMPLE_KEYWORD, detector_option, image_out_arg, photo_arg

#: ``fap-studio NAME`` opens NAME in the editor when it ends so (photos and projects).
EDITOR_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".fapproj")


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # usage errors: exit 2 with one line
        cmd = self.prog.removeprefix("fap-studio").strip()
        hint = f" (see fap-studio {cmd + ' ' if cmd else ''}--help)"
        self.exit(2, f"fap-studio: error: {' '.join(message.split())}{hint}\n")


def _fap_pairs(items: Sequence[str] | None) -> dict[str, float]:
    out: dict[str, float] = {}
    for it in items or []:
        if "=" not in it:
            raise FapStudioError(f"--fap {it!r}: expected NAME=VALUE or NUMBER=VALUE")
        k, v = it.split("=", 1)
        if k.strip().lower() in ("1", "2", "viseme", "expression"):
            # (the high-level FAPs pick a viseme or an emotion by number and blend: a preset)
            raise FapStudioError(f"--fap {it!r}: FAPs 1 and 2 (viseme, expression) are set "
                                 "with --preset NAME[:INTENSITY] (e.g. --preset viseme_aa, "
                                 "--preset joy)")
        try:
            out[k.strip()] = float(v)
        except ValueError as e:
            raise FapStudioError(f"--fap {it!r}: {v!r} is not a number") from e
    return out


def _load_face(photo: str, neutral: bool = False):
    """The photo's Face; its own expression is estimated unless ``neutral`` declares it so."""
    from editor.engine.face import Face

    return Face.from_image(photo, own_expression=not neutral)


def _expression_note(face, keep: bool) -> None:
    """Say on stderr what the photo already shows and how the FAPs relate to it."""
    if face.has_expression:
        how = ("added to it" if keep else
               "applied to the neutralised face; --keep-expression adds them to the photo's")
        print(f"fap-studio: the photo shows: {face.expression_words} (FAPs {how})",
              file=sys.stderr)


def cmd_landmarks(a: argparse.Namespace) -> int:
    from editor.engine.imageio import save_image
    from editor.engine.overlay import draw_landmarks

    face = _load_face(a.photo)
    lm = face.landmarks
    if a.output:
        save_image(a.output, draw_landmarks(face.image, lm, a.scale))
    if a.json:
        data = {
            "image": str(a.photo), "size": list(face.image.shape[1::-1]),
            "detector": lm.detector, "box": [round(float(x), 2) for x in lm.box],
            "points": {str(i): [float(x), float(y)] for i, (x, y) in enumerate(lm.points)},
            "fdp": {k: [round(x, 2), round(y, 2)] for k, (x, y) in lm.fdp_points().items()},
            "iris": {"3.5": lm.iris_left.as_list(), "3.6": lm.iris_right.as_list()},
            # the centre of each iris's visible part (below the circle's when a lid covers it)
            "pupils": {k: [round(x, 2), round(y, 2)] for k, (x, y) in lm.pupils().items()},
            "confidence": round(float(lm.confidence), 4),
        }
        if lm.mesh is not None:  # MediaPipe's 468 points (its canonical vertex order)
            data["mesh"] = [[round(float(x), 2), round(float(y), 2)] for x, y in lm.mesh]
        _write_json(a.json, data)
    if not a.output and not a.json:
        print(json.dumps({k: [round(x, 1), round(y, 1)] for k, (x, y) in lm.fdp_points().items()}))
    return 0


def _mesh_json(face, v=None) -> dict:
    verts = face.vertices if v is None else v
    return {
        "vertices": [[round(float(x), 3), round(float(y), 3)] for x, y in verts],
        "triangles": face.triangles.tolist(),
        "names": list(face.mesh.names),
        "regions": [str(r) for r in face.mesh.regions],
        "fdp": {k: [round(float(verts[i, 0]), 3), round(float(verts[i, 1]), 3)]
                for k, i in face.fdp.items()},
        "fdp_index": dict(face.fdp),
        "fapu": {k: float(v) for k, v in face.fapu.items()},
    }


def cmd_mesh(a: argparse.Namespace) -> int:
    from editor.engine.imageio import save_image
    from editor.engine.overlay import draw_mesh

    face = _load_face(a.photo)
    if a.output:
        save_image(a.output, draw_mesh(face.image, face.vertices, face.triangles, face.fdp,
                                       a.scale, face.mesh.holes))
    if a.json:
        _write_json(a.json, _mesh_json(face))
    if not a.output and not a.json:
        print(json.dumps({k: round(v * 1024, 2) for k, v in face.fapu.items() if k != "AU"}))
    return 0


def _requested_vector(a: argparse.Namespace):
    """(68,) FAP vector of the command's ``--preset`` and ``--fap`` options (they add up)."""
    from editor.engine.faps import FAPS

    from .anim import preset_vector
    from .facs import au_vector

    try:
        vec = (preset_vector(a.preset) + au_vector(getattr(a, "au", None))
               + FAPS.vector(_fap_pairs(a.fap)))
    except ValueError as e:
        raise FapStudioError(str(e)) from e
    clamped = FAPS.clamp(vec)
    out = [n for n in range(3, 69) if clamped[n - 1] != vec[n - 1]]
    if out:  # the renderer clamps to the table's ranges: say so (one line)
        print("fap-studio: note: outside their range, clamped: " + ", ".join(
            f"{FAPS[n].name} {vec[n - 1]:g} -> {clamped[n - 1]:g} {FAPS[n].unit}" for n in out),
            file=sys.stderr)
    return vec


def cmd_render(a: argparse.Namespace) -> int:
    from editor.engine.faps import FAPS
    from editor.engine.imageio import save_image

    vec = _requested_vector(a)
    face = _load_face(a.photo, a.photo_is_neutral)
    if a.keep_expression:
        vec = face.expression + vec
    save_image(a.output, face.render(vec, creases=not a.no_creases, sharp=not a.fast))
    if a.mesh_json:
        v, extra = face.deform_all(vec)
        data = _mesh_json(face, v)
        neutral = _mesh_json(face, face.neutral_vertices)
        data["vertices_neutral"] = neutral["vertices"]
        data["fdp_neutral"] = neutral["fdp"]
        data["fdp"].update({k: [round(float(p[0]), 3), round(float(p[1]), 3)]
                            for k, p in extra.items()})
        data["faps"] = {FAPS[i + 1].name: float(x) for i, x in enumerate(vec) if x}
        _write_json(a.mesh_json, data)
    _expression_note(face, a.keep_expression)  # after the output: an error stays one line
    return 0


def _ensure_display(headless_ok: bool) -> None:
    """Without a display Qt aborts (and blames xcb-cursor0): use the offscreen platform for a
    screenshot, or say clearly what is missing."""
    import os

    if os.environ.get("QT_QPA_PLATFORM") or not sys.platform.startswith("linux"):
        return
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        return
    if headless_ok:
        os.environ["QT_QPA_PLATFORM"] = "offscreen"
        return
    raise FapStudioError("no display (DISPLAY is not set): run it in a desktop session, use "
                         "--screenshot for a headless picture, or set QT_QPA_PLATFORM=offscreen")


def cmd_gui(a: argparse.Namespace) -> int:
    for path in (a.photo, getattr(a, "project", None)):  # a missing file is named before Qt starts
        if path and not Path(path).exists():
            raise FapStudioError(f"{path}: no such file")
    _ensure_display(headless_ok=bool(a.screenshot))
    try:
        from editor.ui.app import run
    except ImportError as e:  # pragma: no cover - depends on the installation
        raise FapStudioError(f"the editor window is not available ({e})") from e
    from editor.engine.faps import FAPS

    vec = _requested_vector(a)
    named = {FAPS[i + 1].name: float(x) for i, x in enumerate(vec) if x}
    photo, project = a.photo, getattr(a, "project", None)
    if photo and project is None and Path(photo).suffix.lower() == ".fapproj":
        photo, project = None, photo  # ``fap-studio work.fapproj`` opens the project
    # one preset alone is shown in the Presets panel (selected, at its intensity)
    shown = None
    if len(a.preset or []) == 1 and not a.fap and not getattr(a, "au", None):
        from .anim import parse_preset

        shown = parse_preset(a.preset[0])
    return run(photo=photo, faps=named, screenshot=a.screenshot, project=project,
               photo_neutral=a.photo_is_neutral,
               keep_expression=a.keep_expression, preset=shown)


def _write_json(path: str, data: dict) -> None:
    from editor.safeio import atomic_write_text

    atomic_write_text(path, json.dumps(data))


def _expression_options(s: argparse.ArgumentParser) -> None:
    g = s.add_mutually_exclusive_group()
    g.add_argument("--keep-expression", action="store_true",
                   help="add the FAPs to the expression the photo already shows (no FAPs: "
                   "the photo unchanged). Default: FAPs apply to the neutralised face (no "
                   "FAPs: the neutral face), so anger on a smiling photo reads as anger")
    g.add_argument("--photo-is-neutral", action="store_true",
                   help="do not estimate the photo's own expression: FAP 0 is the photo")


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="fap-studio", description="MPEG-4 facial animation of a single photo. "
                "With no command, opens the editor on the sample face.")
    p.add_argument("--version", action="version", version=f"fap-studio {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    s = sub.add_parser("landmarks", help="detect landmarks, MPEG-4 feature points and irises")
    s.add_argument("photo", type=photo_arg, help=PHOTO_HELP)
    s.add_argument("-o", "--output", type=image_out_arg,
                   help="PNG with the points drawn over the photo")
    s.add_argument("--json", help="points by detector index and FDP id, iris circles")
    s.add_argument("--scale", type=float, default=1.0, help="drawing scale (default 1)")
    detector_option(s)
    s.set_defaults(func=cmd_landmarks)

    s = sub.add_parser("mesh", help="fit the personalized MPEG-4 mesh and draw it")
    s.add_argument("photo", type=photo_arg, help=PHOTO_HELP)
    s.add_argument("-o", "--output", type=image_out_arg,
                   help="PNG with the mesh drawn over the photo")
    s.add_argument("--json", help="vertices, triangles, fdp, fapu")
    s.add_argument("--scale", type=float, default=1.0, help="drawing scale (default 1)")
    detector_option(s)
    s.set_defaults(func=cmd_mesh)

    s = sub.add_parser("render", help="render the photo with FAP values")
    s.add_argument("photo", type=photo_arg, help=PHOTO_HELP)
    s.add_argument("--fap", action="append", metavar="NAME=VALUE",
                   help="FAP by name or number and its value in FAPU (repeatable)")
    s.add_argument("--preset", action="append", metavar="NAME[:INTENSITY]",
                   help="emotion or viseme preset, intensity 0-1.5 (repeatable; adds up)")
    s.add_argument("--au", action="append", metavar="AU=INTENSITY",
                   help="FACS Action Unit, intensity 0-1 or a letter A-E: AU12=0.8, 6=B, "
                   "L12=C (one side); repeatable, adds to --preset and --fap")
    s.add_argument("-o", "--output", type=image_out_arg, required=True,
                   help="output image (PNG/JPEG)")
    s.add_argument("--mesh-json", help="write the neutral and deformed mesh as JSON")
    resample = s.add_mutually_exclusive_group()
    resample.add_argument("--fast", action="store_true",
                          help="resample the photo bilinearly, as the editor's live preview "
                               "and video frames do (~0.8 x the render time). By default a "
                               "still is resampled bicubically, as the editor's File > Export "
                               "Image and study stimuli are: the skin that moves keeps the "
                               "photo's sharpness")
    resample.add_argument("--sharp", action="store_true",
                          help="bicubic resampling: the default (kept for older scripts)")
    s.add_argument("--no-creases", action="store_true",
                   help="geometry only: no skin folds (nasolabial, forehead, ...)")
    _expression_options(s)
    detector_option(s)
    s.set_defaults(func=cmd_render)

    s = sub.add_parser("gui", help="open the editor window")
    s.add_argument("photo", nargs="?", type=photo_arg, help=PHOTO_HELP)
    s.add_argument("--fap", action="append", metavar="NAME=VALUE")
    s.add_argument("--preset", action="append", metavar="NAME[:INTENSITY]")
    s.add_argument("--project", help="open a project file")
    s.add_argument("--screenshot", help="save a screenshot of the window and exit")
    _expression_options(s)
    detector_option(s)
    s.set_defaults(func=cmd_gui)

    for add in (add_anim_parser, add_clone_parser, add_study_parser, add_bilinear_parser,
                add_facs_parser):
        add(sub)
    return p


def _opens_the_editor(args: list[str], parser: argparse.ArgumentParser) -> bool:
    """The first argument is not a command but a photo (an existing file, ``sample``, or a
    name with an image or project suffix) or an option of ``gui`` (``--fap``, ``--project``):
    it is for the editor. Anything else stays a command (a typo gets argparse's error)."""
    first = args[0]
    if first in ("-h", "--help", "--version"):
        return False
    commands: set[str] = set()
    for action in parser._actions:  # argparse keeps the subcommands here
        if isinstance(action, argparse._SubParsersAction):
            commands.update(action.choices)
    if first in commands:
        return False
    return (first.startswith("--") or first == SAMPLE_KEYWORD or Path(first).is_file()
            or Path(first).suffix.lower() in EDITOR_SUFFIXES)


def main(argv: Sequence[str] | None = None) -> int:
    args_list = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    if not args_list:
        args_list = ["gui"]
    elif _opens_the_editor(args_list, parser):  # ``fap-studio photo.jpg --fap ...`` = gui
        args_list = ["gui", *args_list]
    a = parser.parse_args(args_list)
    if not getattr(a, "func", None):
        parser.print_help()
        return 2
    try:
        if getattr(a, "detector", None):
            from editor.engine.landmarks import set_default_detector

            set_default_detector(a.detector)
        code = int(a.func(a) or 0)
        sys.stdout.flush()
        return code
    except FapStudioError as e:
        print(f"fap-studio: error: {' '.join(str(e).split())}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("fap-studio: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # ``fap-studio fap info x.fap | head``: the reader went away
        import os

        with contextlib.suppress(OSError, ValueError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141


if __name__ == "__main__":
    sys.exit(main())
