"""``fap-studio bilinear`` sub-commands: ``train``, ``eval`` and ``synth``.

``train`` fits the Stasm-77 model on a landmark set, or (``--detect IMAGES_DIR``, or a directory
of images without ``all_features.txt``) the dlib-68 photo model on landmarks detected in
JAFFE-style images (:mod:`editor.synthesis.bilinear_photo`).
``synth`` detects the photo's landmarks,
synthesizes the target expression with a dlib-68 model, maps it onto the personalized mesh and
warps the photo. Each handler is registered with
``set_defaults(func=handler)``; it takes the parsed namespace and returns an exit code
(0 success, 2 for a :class:`~editor.errors.FapStudioError`, printed as one line
``fap-studio: error: ...`` on stderr).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

from editor.cli.util import (
    PHOTO_HELP,
    detector_option,
    fast_option,
    guarded,
    image_out_arg,
    photo_arg,
)
from editor.errors import ModelError

Handler = Callable[[argparse.Namespace], int]


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def _grid(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(t) for t in text.split(",") if t.strip())
    except ValueError:
        values = ()
    if not values or any(not v > 0 or v == float("inf") for v in values):
        raise argparse.ArgumentTypeError(f"expected comma-separated positive λ values: {text!r}")
    return values


def _model_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("-I", "--expression-dim", type=_positive_int, default=None, metavar="I",
                   help="expression-vector length (default: number of expressions, 7)")
    p.add_argument("-J", "--identity-dim", type=_positive_int, default=None, metavar="J",
                   help="identity-vector length (default: number of training people)")
    p.add_argument("--grid", type=_grid, default=None, metavar="L1,L2,...",
                   help="λ values for the cross-validation (default 15 values 1e-4 … 1e3)")
    p.add_argument("--tol", type=_positive_float, default=1e-3,
                   help="translation stops when the cost falls by less than tol·f (1e-3)")
    p.add_argument("--max-iter", type=_positive_int, default=50,
                   help="translation iteration cap (50)")


def add_bilinear_parser(subparsers: Any) -> None:
    """Register ``bilinear train`` and ``bilinear eval`` on an argparse sub-parser set."""
    p = subparsers.add_parser(
        "bilinear", help="bilinear identity × expression landmark model",
        description="Train and evaluate the bilinear identity × expression model (SPEC §5).")
    sub = p.add_subparsers(dest="bilinear_command", metavar="COMMAND", required=True)

    t = sub.add_parser(
        "train", help="train a model on labelled landmarks",
        description="Train on every person × 7 expressions of a Stasm-77 landmark set (the "
                    "JAFFE landmarks_stasm77 layout: all_features.txt, all_names.txt, "
                    "all_labels.txt) and store λ chosen by cross-validation in the model.")
    t.add_argument("landmarks", metavar="LANDMARKS_DIR_OR_FILE", nargs="?", default=None)
    t.add_argument("--detect", metavar="IMAGES_DIR", default=None,
                   help="train the dlib-68 photo model on landmarks detected in JAFFE-style "
                        "images (PERSON.EXPRn.ID.tiff); detections are cached outside the "
                        "project")
    t.add_argument("-o", "--output", required=True, metavar="MODEL.npz")
    t.add_argument("--people", default=None, metavar="P1,P2,...",
                   help="train on these person codes only (default: all)")
    t.add_argument("--no-cv", action="store_true",
                   help="skip choosing λ (the model then stores none)")
    _model_options(t)
    detector_option(t)
    t.set_defaults(func=guarded(run_train))

    e = sub.add_parser(
        "eval", help="rotated train/test evaluation, printed as a table",
        description="Train on all but a group of test people, translate every test image "
                    "with plain ALS / ridge / MALS and print ER_FP, S_w and synthesis errors "
                    "beside the paper's values.")
    e.add_argument("landmarks", metavar="LANDMARKS_DIR")
    e.add_argument("--folds", type=_positive_int, default=None,
                   help="number of folds (default: enough to test every person once)")
    e.add_argument("--test-size", type=_positive_int, default=3,
                   help="people tested per fold (3)")
    e.add_argument("--lambda-ridge", type=_positive_float, default=None, metavar="λ",
                   help="fixed ridge λ (default: cross-validation)")
    e.add_argument("--lambda-mals", type=_positive_float, default=None, metavar="λ",
                   help="fixed MALS λ (default: cross-validation)")
    _model_options(e)
    e.set_defaults(func=guarded(run_eval))

    y = sub.add_parser(
        "synth", help="synthesize an expression on a photo",
        description="Detect the photo's 68 landmarks, translate them with a dlib-68 model "
                    "(bilinear train --detect), rebuild the target expression with the face's "
                    "identity, map it onto the personalized mesh and warp the photo.")
    y.add_argument("photo", metavar="PHOTO", type=photo_arg, help=PHOTO_HELP)
    y.add_argument("--model", required=True, metavar="MODEL.npz")
    y.add_argument("--expression", default="joy", metavar="NAME|NAME:W,...",
                   help="target expression or a mix, e.g. joy or joy:0.5,surprise:0.5")
    y.add_argument("--method", choices=("plain", "ridge", "mals"), default="mals")
    y.add_argument("--lambda", dest="lam", type=_positive_float, default=None, metavar="λ",
                   help="λ for ridge / MALS (default: the model's)")
    y.add_argument("--keep-residual", action="store_true",
                   help="keep the part of the input shape the model does not reconstruct")
    y.add_argument("--faps-json", default=None, metavar="FILE.json",
                   help="also write the FAP vector that best reproduces the shape (a preset)")
    y.add_argument("-o", "--output", type=image_out_arg, required=True, metavar="OUT.png")
    fast_option(y)
    detector_option(y)
    y.set_defaults(func=guarded(run_synth))


def run_train(args: argparse.Namespace) -> int:
    """``bilinear train``: fit, choose λ, save."""
    from pathlib import Path

    from editor.synthesis.bilinear import save_model
    from editor.synthesis.bilinear_data import load_stasm77, train_model
    from editor.synthesis.bilinear_eval import DEFAULT_GRID, choose_lambdas

    if args.detect or (args.landmarks and Path(args.landmarks).is_dir()
                       and not (Path(args.landmarks) / "all_features.txt").exists()):
        return _train_detect(args, args.detect or args.landmarks)
    if not args.landmarks:
        raise ModelError("give a landmark set or --detect IMAGES_DIR")
    data = load_stasm77(args.landmarks)
    people = data.people
    if args.people:
        people = tuple(p.strip() for p in args.people.split(",") if p.strip())
        unknown = sorted(set(people) - set(data.people))
        if unknown:
            raise ModelError(f"unknown person code(s): {', '.join(unknown)}")
    model, errors = train_model(data, people, args.expression_dim, args.identity_dim)
    if not args.no_cv:
        if len(people) < 3:
            raise ModelError("choosing λ needs at least 3 people (or use --no-cv)")
        grid = args.grid or DEFAULT_GRID
        model.meta["lambda"] = choose_lambdas(data, people, ("ridge", "mals"), grid,
                                              args.expression_dim, args.identity_dim,
                                              args.tol, args.max_iter)
        model.meta["lambda_selection"] = "leave-one-person-out synthesis error"
    save_model(model, args.output)
    print(f"trained on {len(people)} people × {len(model.expressions)} expressions "
          f"({len(data.names)} images)")
    for name, reg in model.regions.items():
        print(f"  {name:6s} K={reg.K:3d} I={reg.I} J={reg.J} "
              f"relative training error {errors[name][-1]:.2e} ({len(errors[name])} iterations)")
    if "lambda" in model.meta:
        print("  λ: " + ", ".join(f"{m} {v:g}" for m, v in model.meta["lambda"].items()))
    print(f"wrote {args.output}")
    return 0


def run_eval(args: argparse.Namespace) -> int:
    """``bilinear eval``: print the evaluation table."""
    from editor.synthesis.bilinear_data import load_stasm77
    from editor.synthesis.bilinear_eval import DEFAULT_GRID, evaluate, format_report

    data = load_stasm77(args.landmarks)
    if args.test_size >= len(data.people):
        raise ModelError(f"--test-size must be below the number of people ({len(data.people)})")
    fixed = {m: v for m, v in (("ridge", args.lambda_ridge), ("mals", args.lambda_mals))
             if v is not None}
    result = evaluate(data, args.folds, args.test_size, grid=args.grid or DEFAULT_GRID,
                      fixed_lambda=fixed, I=args.expression_dim, J=args.identity_dim,
                      tol=args.tol, max_iter=args.max_iter)
    print(format_report(result))
    return 0


def _train_detect(args: argparse.Namespace, images: str) -> int:
    """``bilinear train --detect``: dlib-68 detections -> photo model."""
    from editor.synthesis.bilinear import save_model
    from editor.synthesis.bilinear_photo import detect_training_set, train_model68

    people = (tuple(p.strip() for p in args.people.split(",") if p.strip())
              if args.people else None)
    data = detect_training_set(images, people)
    model = train_model68(data, None, args.expression_dim, args.identity_dim)
    model.meta["training"] = f"dlib-68 detections on {len(data.names)} images"
    save_model(model, args.output)
    print(f"trained the dlib-68 photo model on {len(model.identities)} people × "
          f"{len(model.expressions)} expressions ({len(data.names)} images with a face)")
    print("  λ: " + ", ".join(f"{m} {v:g}" for m, v in model.meta["lambda"].items())
          + " (fixed defaults)")
    print(f"wrote {args.output} (derived from the training images: do not commit it)")
    return 0


def run_synth(args: argparse.Namespace) -> int:
    """``bilinear synth``: photo -> synthesized expression -> PNG."""
    import json

    from editor.engine.face import Face
    from editor.engine.imageio import save_image
    from editor.synthesis.bilinear import load_model
    from editor.synthesis.bilinear_photo import (
        check_model68,
        faps_for_points,
        parse_mix,
        synthesize_on_face,
    )

    model = load_model(args.model)
    check_model68(model)
    target = parse_mix(args.expression)
    face = Face.from_image(args.photo)
    res = synthesize_on_face(face, model, target, args.method, args.lam,
                             keep_residual=args.keep_residual, render=True,
                             sharp=not args.fast)
    assert res.image is not None
    save_image(args.output, res.image)
    if args.faps_json:
        from editor.engine.faps import FAPS
        from editor.formats.presets import preset_document, preset_name
        from editor.safeio import atomic_write_text

        faps = FAPS.clamp(faps_for_points(face, res.points68))
        doc = preset_document(faps, preset_name(f"bilinear_{args.expression}_{args.method}"),
                              f"bilinear synth {args.photo}")

        atomic_write_text(args.faps_json, json.dumps(doc, indent=2) + "\n", error=ModelError)
    print(f"{args.expression} ({args.method}) -> {args.output}")
    return 0
