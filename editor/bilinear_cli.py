"""``fap-studio bilinear`` sub-commands: ``train`` and ``eval``.

``bilinear synth`` (photo -> landmarks -> synthesized expression -> warped photo) needs the
face-photo pipeline and is not provided here. Each handler is registered with
``set_defaults(func=handler)``; it takes the parsed namespace and returns an exit code
(0 success, 2 for a :class:`~editor.core.errors.FapStudioError`, printed as one line
``fap-studio: error: ...`` on stderr).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from typing import Any

from editor.core.errors import FapStudioError, ModelError

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


def _guard(handler: Handler) -> Handler:
    def run(args: argparse.Namespace) -> int:
        try:
            return handler(args)
        except FapStudioError as exc:
            print(f"fap-studio: error: {exc}", file=sys.stderr)
            return 2

    run.__name__ = handler.__name__
    run.__doc__ = handler.__doc__
    return run


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
    t.add_argument("landmarks", metavar="LANDMARKS_DIR_OR_FILE")
    t.add_argument("-o", "--output", required=True, metavar="MODEL.npz")
    t.add_argument("--people", default=None, metavar="P1,P2,...",
                   help="train on these person codes only (default: all)")
    t.add_argument("--no-cv", action="store_true",
                   help="skip choosing λ (the model then stores none)")
    _model_options(t)
    t.set_defaults(func=_guard(run_train))

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
    e.set_defaults(func=_guard(run_eval))


def run_train(args: argparse.Namespace) -> int:
    """``bilinear train``: fit, choose λ, save."""
    from editor.core.bilinear import save_model
    from editor.core.bilinear_data import load_stasm77, train_model
    from editor.core.bilinear_eval import DEFAULT_GRID, choose_lambdas

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
    from editor.core.bilinear_data import load_stasm77
    from editor.core.bilinear_eval import DEFAULT_GRID, evaluate, format_report

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
