"""CLI for expression cloning and performance capture: ``clone``, ``track``, ``clone-eval``.

* ``fap-studio clone --source-neutral A.jpg --source B.jpg --target C.jpg [--method fap|laplacian]
  -o out.png [--faps-json out.json]`` - the performer's expression (A -> B) on the photo C;
  ``--faps-json`` writes the estimated FAPs as a preset file (loadable as a custom preset).
* ``fap-studio track VIDEO -o anim.fap [--smoothing savgol:5] [--fps F]`` - a .fap sequence
  from a performer video (first frame with a face = neutral), progress bar on stderr.
* ``fap-studio clone-eval [--jaffe DIR]`` - the evaluation of issue 10 (FAP-recovery round trip
  and the JAFFE cloning comparison), as Markdown tables on stdout; the JAFFE folder comes from
  ``--jaffe`` or ``$FAP_STUDIO_JAFFE`` (research-only data, never shipped).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from editor.errors import FapStudioError
from editor.resources import JAFFE_ENV, SAMPLE_FACE, jaffe_dir

from .util import ProgressBar, detector_option, fast_option, guarded, image_out_arg, photo_arg

SAMPLE = SAMPLE_FACE


def _write_text(path: str | Path, text: str) -> None:
    from editor.safeio import atomic_write_text

    atomic_write_text(Path(path), text)


def cmd_clone(a: argparse.Namespace) -> int:
    import numpy as np

    from editor.engine.face import Face
    from editor.engine.faps import FAPS
    from editor.engine.imageio import load_image, save_image
    from editor.engine.landmarks import detect_landmarks
    from editor.errors import NoFaceError
    from editor.formats.presets import preset_document, preset_name
    from editor.safeio import finite_in
    from editor.synthesis.cloning import MU, clone
    from editor.synthesis.fap_estimate import FapEstimator

    if a.mu is None:
        a.mu = MU
    elif a.method != "laplacian":
        print("fap-studio: note: --mu weighs the Laplacian route's constraints; --method fap "
              "does not use it", file=sys.stderr)
    finite_in(a.mu, 0, 1e6, "--mu", lo_open=True)
    src_neutral = Face.from_image(a.source_neutral, own_expression=False)
    try:
        expr = detect_landmarks(load_image(a.source)).points
    except NoFaceError as e:
        raise NoFaceError(f"{a.source}: {e}") from None
    target = Face.from_image(a.target)
    est = FapEstimator(src_neutral)
    res = clone(src_neutral, expr, target, a.method, estimator=est, mu=a.mu, sharp=not a.fast)
    save_image(a.output, res.image)
    fit = est.estimate(expr)
    if a.faps_json:
        fit_info = {"residual_px": round(fit.residual_px, 3),
                    "head_angle_deg": round(-fit.head_angle_deg, 2),
                    "head_scale": round(1.0 / fit.head_scale, 4)}
        doc = preset_document(FAPS.clamp(fit.faps), preset_name(Path(a.faps_json).stem, "cloned"),
                              f"estimated from {a.source} against {a.source_neutral}",
                              extra={"fit": fit_info, "method": a.method})
        _write_text(a.faps_json, json.dumps(doc, indent=2) + "\n")
    n = int(np.count_nonzero(np.round(fit.faps)))
    if target.has_expression:  # (as render says it; after the output: an error stays one line)
        print(f"fap-studio: the target shows: {target.expression_words} (the expression is "
              "cloned onto its neutralised face)", file=sys.stderr)
    what = (f"{n} FAPs estimated" if a.method == "fap" else
            f"landmark motion transferred; the FAP estimate ({n} FAPs) is what --faps-json "
            "writes")
    print(f"{a.method}: {what} (fit residual {fit.residual_px:.2f} px) -> {a.output}",
          file=sys.stderr)
    return 0


def cmd_track(a: argparse.Namespace) -> int:
    from editor.formats.fapfile import write_fap
    from editor.synthesis.fap_estimate import track_video

    with ProgressBar("track", quiet=a.quiet) as bar:
        seq, rep = track_video(a.video, fps=a.fps, smoothing=a.smoothing, progress=bar)
    write_fap(seq, a.output)
    print(f"{rep.summary()} -> {a.output}", file=sys.stderr)
    return 0


def cmd_clone_eval(a: argparse.Namespace) -> int:
    from editor.engine.face import Face
    from editor.engine.imageio import load_image
    from editor.synthesis.clone_eval import (
        jaffe_evaluation,
        roundtrip_table,
        roundtrip_vectors,
        upscaled_face,
    )

    t0 = time.perf_counter()
    if not a.skip_roundtrip:
        rgb = load_image(a.roundtrip_photo)
        base = Face.from_image(rgb)
        face = Face.from_image(upscaled_face(rgb, base.landmarks.points, a.scale),
                               own_expression=False)
        names, vecs = roundtrip_vectors(a.random)
        table, _ = roundtrip_table(face, vecs)
        print(f"FAP recovery round trip on {Path(a.roundtrip_photo).name} (face crop x{a.scale:g},"
              f" inter-ocular {face.interocular:.0f} px); vectors: {', '.join(names)} "
              f"(observable FAPs only):\n")
        print(table)
    if not a.skip_jaffe:
        root = jaffe_dir(a.jaffe)
        if root is None:
            raise FapStudioError(f"no JAFFE folder given: use --jaffe DIR or set {JAFFE_ENV} "
                                 "(the data set is not shipped), or --skip-jaffe")
        images = root / "images"
        if not images.is_dir():
            raise FapStudioError(f"{images}: JAFFE images not found (--jaffe DIR must hold "
                                 "images/*.tiff)")
        with ProgressBar("clone-eval", unit="pair", quiet=a.quiet) as bar:
            print(jaffe_evaluation(images, a.persons.split(",") if a.persons else None,
                                   Path(a.renders) if a.renders else None, bar))
    print(f"\n({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
    return 0


def add_clone_parser(sub) -> None:
    """Register ``clone``, ``track`` and ``clone-eval`` on an argparse subparsers object."""
    s = sub.add_parser("clone", help="clone a performer's expression (neutral + expression "
                       "photo) onto another photo")
    s.add_argument("--source-neutral", required=True, metavar="A", type=photo_arg,
                   help="performer, neutral (a photo, or 'sample')")
    s.add_argument("--source", required=True, metavar="B", type=photo_arg,
                   help="performer, expression (a photo, or 'sample')")
    s.add_argument("--target", required=True, metavar="C", type=photo_arg,
                   help="photo to animate (or 'sample', the bundled face)")
    s.add_argument("--method", choices=("fap", "laplacian"), default="fap",
                   help="fap: estimated FAPs rendered on C (default); laplacian: landmark "
                   "motion transferred by Laplacian mesh deformation")
    s.add_argument("--mu", type=float, default=None,
                   help="Laplacian constraint weight (10; --method laplacian only)")
    s.add_argument("-o", "--output", type=image_out_arg, required=True,
                   help="output image (PNG/JPEG)")
    s.add_argument("--faps-json", metavar="OUT.json",
                   help="write the estimated FAPs as a preset file")
    fast_option(s)
    detector_option(s)
    s.set_defaults(func=guarded(cmd_clone))

    t = sub.add_parser("track", help="FAP sequence (.fap) from a performer video")
    t.add_argument("video")
    t.add_argument("-o", "--output", required=True, help="output .fap file")
    t.add_argument("--smoothing", default="savgol:5",
                   help="none | savgol:W[:P] (Savitzky-Golay, odd window W frames, order P, "
                   "default savgol:5) | ema:A (forward-backward exponential, 0 < A <= 1)")
    t.add_argument("--fps", type=float, help="frame rate (default: the video's)")
    t.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    detector_option(t)
    t.set_defaults(func=guarded(cmd_track))

    e = sub.add_parser("clone-eval", help="evaluate FAP recovery and cloning (JAFFE)")
    e.add_argument("--jaffe", metavar="DIR",
                   help=f"JAFFE folder with images/ (default: ${JAFFE_ENV}; required unless "
                   "--skip-jaffe)")
    e.add_argument("--persons", help="comma-separated JAFFE person codes (default all)")
    e.add_argument("--renders", help="folder for contact sheets of the results")
    e.add_argument("--roundtrip-photo", default=str(SAMPLE))
    e.add_argument("--scale", type=float, default=3.0, help="round-trip face crop scale (3)")
    e.add_argument("--random", type=int, default=4, help="random round-trip vectors (4)")
    e.add_argument("--skip-roundtrip", action="store_true")
    e.add_argument("--skip-jaffe", action="store_true")
    e.add_argument("-q", "--quiet", action="store_true")
    detector_option(e)
    e.set_defaults(func=guarded(cmd_clone_eval))
