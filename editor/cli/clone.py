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
import re
import sys
import time
from pathlib import Path

import numpy as np

from editor.errors import FapStudioError
from editor.resources import JAFFE_ENV, SAMPLE_FACE, jaffe_dir

from .util import ProgressBar, guarded

SAMPLE = SAMPLE_FACE
JAFFE_CODES = {"HA": "joy", "SU": "surprise", "AN": "anger", "SA": "sadness", "FE": "fear",
               "DI": "disgust"}


def _write_text(path: str | Path, text: str) -> None:
    from editor.safeio import atomic_write_text

    atomic_write_text(Path(path), text)


def faps_document(faps: np.ndarray, name: str, source: str, extra: dict | None = None) -> dict:
    """A preset document (``fap-studio-preset``, kind custom) of a FAP vector, rounded."""
    from editor.engine.faps import FAPS
    from editor.formats.fapfile import round_half_away
    from editor.formats.presets import PRESET_FORMAT, PRESET_VERSION, preset_from_dict

    clean = re.sub(r"[^A-Za-z0-9_-]", "_", name)[:64] or "cloned"
    v = round_half_away(FAPS.clamp(np.asarray(faps, np.float32)))
    doc = {"format": PRESET_FORMAT, "version": PRESET_VERSION, "kind": "custom", "name": clean,
           "mpeg4_index": None, "source": source,
           "faps": {FAPS[i + 1].name: int(x) for i, x in enumerate(v) if i >= 2 and x != 0}}
    doc.update(extra or {})
    preset_from_dict(doc, clean)  # validate
    return doc


def cmd_clone(a: argparse.Namespace) -> int:
    from editor.engine.face import Face
    from editor.engine.imageio import load_image, save_image
    from editor.engine.landmarks import detect_landmarks
    from editor.errors import NoFaceError
    from editor.safeio import finite_in
    from editor.synthesis.cloning import clone
    from editor.synthesis.fap_estimate import FapEstimator

    finite_in(a.mu, 0, 1e6, "--mu", lo_open=True)
    src_neutral = Face.from_image(a.source_neutral, own_expression=False)
    try:
        expr = detect_landmarks(load_image(a.source)).points
    except NoFaceError as e:
        raise NoFaceError(f"{a.source}: {e}") from None
    target = Face.from_image(a.target)
    est = FapEstimator(src_neutral)
    res = clone(src_neutral, expr, target, a.method, estimator=est, mu=a.mu)
    save_image(a.output, res.image)
    fit = est.estimate(expr)
    if a.faps_json:
        doc = faps_document(fit.faps, Path(a.faps_json).stem,
                            f"estimated from {a.source} against {a.source_neutral}",
                            {"fit": {"residual_px": round(fit.residual_px, 3),
                                     "head_angle_deg": round(-fit.head_angle_deg, 2),
                                     "head_scale": round(1.0 / fit.head_scale, 4)},
                             "method": a.method})
        _write_text(a.faps_json, json.dumps(doc, indent=2) + "\n")
    n = int(np.count_nonzero(np.round(fit.faps)))
    print(f"{a.method}: {n} FAPs estimated (fit residual {fit.residual_px:.2f} px) -> "
          f"{a.output}", file=sys.stderr)
    return 0


def cmd_track(a: argparse.Namespace) -> int:
    from editor.formats.fapfile import write_fap
    from editor.synthesis.fap_estimate import track_video

    with ProgressBar("track", quiet=a.quiet) as bar:
        seq, rep = track_video(a.video, fps=a.fps, smoothing=a.smoothing, progress=bar)
    write_fap(seq, a.output)
    print(f"{rep.summary()} -> {a.output}", file=sys.stderr)
    return 0


# ---------------------------------------------------------------------------- evaluation
def upscaled_face(rgb: np.ndarray, points: np.ndarray, scale: float = 3.0) -> np.ndarray:
    """The face region of a photo (landmark box + margins), enlarged ``scale`` times (cubic).

    dlib returns integer landmarks: on a small face one pixel is a large part of a FAPU, so the
    recovery round trip runs on an enlarged copy.
    """
    import cv2

    p = np.asarray(points, np.float64)
    (x0, y0), (x1, y1) = p.min(0), p.max(0)
    w = x1 - x0
    h, wd = rgb.shape[:2]
    box = np.round([max(0, x0 - 0.6 * w), max(0, y0 - 0.9 * w), min(wd, x1 + 0.6 * w),
                    min(h, y1 + 0.4 * w)]).astype(int)
    crop = np.ascontiguousarray(rgb[box[1]:box[3], box[0]:box[2]])
    return cv2.resize(crop, None, fx=scale, fy=scale, interpolation=cv2.INTER_CUBIC)


def roundtrip_vectors(n_random: int = 4, seed: int = 0) -> tuple[list[str], np.ndarray]:
    """The six emotion presets restricted to the observable FAPs, plus random vectors
    (each observable FAP uniform in +-25 % of its larger range end, left/right independent)."""
    from editor.engine.faps import FAPS
    from editor.formats.presets import apply_preset
    from editor.synthesis.fap_estimate import OBSERVABLE

    obs = np.array(OBSERVABLE) - 1
    names, out = [], []
    for e in ("joy", "sadness", "surprise", "anger", "fear", "disgust"):
        v = np.zeros(68, np.float32)
        v[obs] = apply_preset(e)[obs]
        names.append(e)
        out.append(v)
    rng = np.random.default_rng(seed)
    amp = np.maximum(np.abs(FAPS.lo), FAPS.hi)[obs]
    for k in range(n_random):
        v = np.zeros(68, np.float32)
        v[obs] = rng.uniform(-0.25, 0.25, len(obs)) * amp
        names.append(f"random{k + 1}")
        out.append(FAPS.clamp(v))
    return names, np.array(out)


def roundtrip_table(face, vectors: np.ndarray) -> tuple[str, np.ndarray]:
    """Markdown table of the per-FAP recovery error; also the (n, 68) errors."""
    from editor.engine.faps import FAPS
    from editor.synthesis.cloning import round_trip
    from editor.synthesis.fap_estimate import OBSERVABLE

    err = round_trip(face, vectors) - vectors
    lines = ["| FAP | name | RMS error (FAPU) | max abs (FAPU) | RMS, % of range |",
             "|---|---|---|---|---|"]
    pct = []
    for n in OBSERVABLE:
        e = err[:, n - 1]
        rms = float(np.sqrt(np.nanmean(e ** 2)))
        pct.append(100 * rms / (FAPS.hi[n - 1] - FAPS.lo[n - 1]))
        lines.append(f"| {n} | {FAPS[n].name} | {rms:.0f} | {np.nanmax(np.abs(e)):.0f} | "
                     f"{pct[-1]:.1f} |")
    lines.append(f"| | **mean** | | | **{np.mean(pct):.1f}** |")
    return "\n".join(lines), err


def jaffe_evaluation(images: Path, persons: list[str] | None = None,
                     renders: Path | None = None, progress=None) -> str:
    """Clone every person's expressions (instances >= 2; instance 1 of each emotion are the key
    models) onto the sample face and onto the next person's neutral; closed-loop landmark error
    (inner 17-67, % of the target's inter-ocular distance) per route, as Markdown tables."""
    from editor.engine.face import Face
    from editor.engine.imageio import load_image, save_image
    from editor.engine.landmarks import detect_landmarks
    from editor.engine.mesh import signed_areas
    from editor.errors import NoFaceError
    from editor.synthesis.cloning import (
        clone,
        closed_loop_error,
        face_deformer,
        key_models,
        transfer_motion,
    )
    from editor.synthesis.closed_loop import jaffe_files
    from editor.synthesis.fap_estimate import FapEstimator, remove_head_motion

    files = jaffe_files(images)
    people = [p for p in (persons or sorted(files)) if "NE" in files.get(p, {})]
    if not people:
        raise FapStudioError(f"{images}: no JAFFE neutral images found")
    sample = Face.from_image(SAMPLE)
    neutral = {p: Face.from_image(files[p]["NE"][0], own_expression=False)
               for p in sorted(files) if "NE" in files[p]}
    order = sorted(neutral)
    routes = ("nothing", "fap", "laplacian", "keys")
    cols = (("nothing", "do nothing"), ("fap_mesh", "FAP, mesh"), ("fap", "FAP, detected"),
            ("laplacian_mesh", "Laplacian, mesh"), ("laplacian", "Laplacian, detected"),
            ("keys", "Laplacian + NNLS keys, detected"))
    errs: dict[tuple[str, str, str], list[float]] = {}
    folds = skipped = 0
    jobs = sum(max(len(files[p].get(c, [])) - 1, 0) for p in people for c in JAFFE_CODES)
    done = 0
    for p in people:
        src = neutral[p]
        est = FapEstimator(src)
        pts: dict[str, list[np.ndarray | None]] = {}
        for c in JAFFE_CODES:
            pts[c] = []
            for f in files[p].get(c, []):
                try:
                    pts[c].append(detect_landmarks(load_image(f)).points.astype(np.float64))
                except NoFaceError:
                    pts[c].append(None)
        key_pts = {JAFFE_CODES[c]: v[0] for c, v in pts.items() if v and v[0] is not None}
        other = order[(order.index(p) + 1) % len(order)]
        for tname, tgt in (("sample", sample), ("jaffe", neutral[other])):
            keys = key_models(src, key_pts, tgt) if len(key_pts) >= 2 else None
            sheet = []
            for c in JAFFE_CODES:
                for k, q in enumerate(pts[c][1:]):
                    if q is None:
                        skipped += 1
                        continue
                    al, _ = remove_head_motion(src.landmarks.points, q)
                    exp = tgt.landmarks.points + transfer_motion(src, al - src.landmarks.points,
                                                                 tgt)
                    e0 = np.linalg.norm(exp - tgt.landmarks.points, axis=1)[17:]
                    errs.setdefault((tname, c, "nothing"), []).append(
                        float(e0.mean() * 100 / tgt.interocular))
                    row = []
                    for r in routes[1:]:
                        if r == "keys" and keys is None:
                            continue
                        res = clone(src, q, tgt, "fap" if r == "fap" else "laplacian",
                                    keys=keys if r == "keys" else None, estimator=est)
                        if (signed_areas(res.vertices.astype(np.float64), tgt.triangles)
                                <= 0).any():
                            folds += 1
                        e = closed_loop_error(res.image, res.expected, tgt)
                        errs.setdefault((tname, c, r), []).append(e["inner"])
                        if r != "keys":  # landmarks carried by the mesh, no detector
                            S = face_deformer(tgt).S
                            lm = tgt.landmarks.points + S @ (res.vertices - tgt.vertices)
                            em = np.linalg.norm(lm - res.expected, axis=1)[17:].mean()
                            errs.setdefault((tname, c, r + "_mesh"), []).append(
                                float(em * 100 / tgt.interocular))
                        row.append(res.image)
                    if renders is not None and k == 0:
                        sheet.append(_sheet_row(src.image, load_image(files[p][c][k + 1]),
                                                row, tgt))
                    if tname == "sample":
                        done += 1
                        if progress:
                            progress(done, jobs)
            if renders is not None and sheet:
                renders.mkdir(parents=True, exist_ok=True)
                save_image(renders / f"{p}_on_{tname if tname == 'sample' else other}.png",
                           np.vstack(sheet))
    out = []
    for tname, title in (("sample", "onto the sample face"),
                         ("jaffe", "onto the next JAFFE person's neutral photo")):
        out += [f"\nCloned {title}: landmark error against the transferred motion, mean over "
                "landmarks 17-67, % of the target's inter-ocular distance (lower is better; "
                "'detected' = closed loop, dlib on the result; 'mesh' = where the deformed mesh "
                "puts the landmarks):\n",
                "| expression | n | " + " | ".join(t for _, t in cols) + " |",
                "|---|---|" + "---|" * len(cols)]
        allv: dict[str, list[float]] = {r: [] for r, _ in cols}
        for c in JAFFE_CODES:
            cells = []
            for r, _ in cols:
                v = np.array(errs.get((tname, c, r), []), float)
                allv[r] += list(v)
                cells.append(f"{np.nanmean(v):.2f}" if v.size else "-")
            n = len(errs.get((tname, c, "nothing"), []))
            out.append(f"| {c} ({JAFFE_CODES[c]}) | {n} | " + " | ".join(cells) + " |")
        tot = [f"**{np.nanmean(allv[r]):.2f}**" if allv[r] else "-" for r, _ in cols]
        out.append(f"| all | {len(allv['nothing'])} | " + " | ".join(tot) + " |")
    out.append(f"\nInverted triangles in any result: {folds}. Test images without a face: "
               f"{skipped}. Persons: {', '.join(people)}.")
    return "\n".join(out)


def _sheet_row(src_neutral: np.ndarray, src_expr: np.ndarray, results: list[np.ndarray],
               target) -> np.ndarray:
    """One row of a contact sheet: source neutral | source expression | each result (face crop),
    all scaled to 240 px high."""
    import cv2

    p = target.landmarks.points
    (x0, y0), (x1, y1) = p.min(0), p.max(0)
    w = x1 - x0
    h, wd = target.image.shape[:2]
    b = np.round([max(0, x0 - 0.25 * w), max(0, y0 - 0.5 * w), min(wd, x1 + 0.25 * w),
                  min(h, y1 + 0.15 * w)]).astype(int)

    def fit(img: np.ndarray) -> np.ndarray:
        s = 240 / img.shape[0]
        return cv2.resize(img, (round(img.shape[1] * s), 240), interpolation=cv2.INTER_AREA
                          if s < 1 else cv2.INTER_CUBIC)

    tiles = [fit(src_neutral), fit(src_expr)] + [fit(r[b[1]:b[3], b[0]:b[2]]) for r in results]
    return np.hstack(tiles)


def cmd_clone_eval(a: argparse.Namespace) -> int:
    from editor.engine.face import Face
    from editor.engine.imageio import load_image

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
    s.add_argument("--source-neutral", required=True, metavar="A", help="performer, neutral")
    s.add_argument("--source", required=True, metavar="B", help="performer, expression")
    s.add_argument("--target", required=True, metavar="C", help="photo to animate")
    s.add_argument("--method", choices=("fap", "laplacian"), default="fap",
                   help="fap: estimated FAPs rendered on C (default); laplacian: landmark "
                   "motion transferred by Laplacian mesh deformation")
    s.add_argument("--mu", type=float, default=10.0, help="Laplacian constraint weight (10)")
    s.add_argument("-o", "--output", required=True, help="output image (PNG/JPEG)")
    s.add_argument("--faps-json", metavar="OUT.json",
                   help="write the estimated FAPs as a preset file")
    s.set_defaults(func=guarded(cmd_clone))

    t = sub.add_parser("track", help="FAP sequence (.fap) from a performer video")
    t.add_argument("video")
    t.add_argument("-o", "--output", required=True, help="output .fap file")
    t.add_argument("--smoothing", default="savgol:5",
                   help="none | savgol:W[:P] (Savitzky-Golay, odd window W frames, order P, "
                   "default savgol:5) | ema:A (forward-backward exponential, 0 < A <= 1)")
    t.add_argument("--fps", type=float, help="frame rate (default: the video's)")
    t.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
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
    e.set_defaults(func=guarded(cmd_clone_eval))
