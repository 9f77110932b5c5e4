"""The ``models`` command: every model fitted, cross-validated by incidence, and ranked."""

from __future__ import annotations

from brdfjax.commands import (
    add_reader_options,
    check_writable,
    edited_command,
    reader_options,
)
from brdfjax.prediction.intervals import DISCREPANCIES  # NumPy only: --help imports no JAX


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "models", help="fit every model, cross-validate by incidence, rank them",
        description="Fit each model on all incidences, hold out each incidence in turn to "
                    "measure how well it predicts what it did not see, and rank the models "
                    "by cv_error (the mean held-out E of Eq. 6 over interior incidences); "
                    "beside it, cv_error of each model corrected by its learned discrepancy "
                    "(what brdfjax fit --predict predicts with).")
    p.add_argument("file", help="the measurement file (any format brdfjax reads)")
    p.add_argument("--models", metavar="A,B,...",
                   help="models to compare, sums A+B included (default: five, beckmann, ggx, "
                        "lambert, rpv, torrance-sparrow, ggx+backscatter, ggx+ggx, abg+lambert, "
                        "ross-li)")
    p.add_argument("--seed", type=int, default=0, help="the seed of every fit (default 0)")
    p.add_argument("--discrepancy", choices=DISCREPANCIES, default="gp",
                   help="gp: also score each model with its learned discrepancy (default); "
                        "none: the analytic models alone")
    p.add_argument("--json", metavar="OUT", help="write the comparison as JSON")
    p.add_argument("--plot", metavar="OUT",
                   help="the four lowest cv_error and the paper's model over the data, one "
                        "panel per incidence, with each fold's prediction of the incidence it "
                        "did not see dashed (PNG)")
    add_reader_options(p)
    p.set_defaults(run=run_models)


def run_models(args) -> None:
    from brdfjax.cache import enable
    from brdfjax.data.formats import json_text, load, replace_atomically, write_atomically
    from brdfjax.prediction.selection import compare_models

    enable()
    check_writable({"--json": args.json}, figures={"--plot": args.plot})
    data = load(args.file, **reader_options(args))
    names = [n.strip() for n in args.models.split(",")] if args.models else None
    comparison = compare_models(data, names, seed=args.seed, progress=True,
                                discrepancy=args.discrepancy)
    print(f"{data.name}: {len(data)} points, models ranked by cv_error, the "
          f"{comparison.best.validation.cv_folds}")

    def fit_command(name: str) -> str:
        """The user's file and options, as a fit that predicts with model ``name``."""
        return edited_command(args.argv, "fit",
                              dict.fromkeys(("--models", "--json", "--plot"), lambda _: None),
                              append=["--model", name, "--predict", "GEOMETRY.csv",
                                      "--predict-out", "PRED.csv"])

    print(comparison.table(command=fit_command))
    if args.json:
        write_atomically(args.json, json_text(comparison.to_dict()))
    if args.plot:
        from brdfjax.plot import plot_models

        replace_atomically(args.plot, lambda path: plot_models(data, comparison, path))
    written = [path for path in (args.json, args.plot) if path]
    if written:
        print(f"wrote {', '.join(written)}")
