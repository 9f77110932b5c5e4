"""Commands that fit: ``fit``, ``demo`` (the paper's white-paint fit) and ``compare``."""

from __future__ import annotations

import dataclasses
import re
import warnings
from pathlib import Path

import numpy as np

from brdfjax.commands import (
    add_model_option,
    add_reader_options,
    angles,
    check_writable,
    edited_command,
    positive_int,
    reader_options,
    zeniths,
)
from brdfjax.prediction.intervals import DISCREPANCIES  # NumPy only: --help imports no JAX

DATA = Path(__file__).resolve().parents[2] / "data"
# --predict with the default model names another model when that one's held-out error is
# this many times lower.
BETTER_MODEL_FACTOR = 2.0
BETTER_MODEL = "ggx"
UNCERTAINTY_METHODS = ("none", "laplace", "mcmc")
# Incidences (deg) of the reflectance intervals written to --json.
REFLECTANCE_INCIDENCES = tuple(range(0, 90, 10))
# Incidences (deg) of the reflectance line of the printed summary.
SUMMARY_INCIDENCES = (0.0, 30.0, 60.0)
# An incidence whose E exceeds the overall E by more than this factor gets a warning.
INCIDENCE_WARNING = 3.0
POOR_SHOWN = 6  # poor incidences named in fit's warning (scattered sets may have many)
FILE_HELP = ("the measurement file: brdfjax .csv, NIST PTFE .csv, ASTM E1392 .astm, J&C "
             "RT-300S .xls or Zemax .bsdf")
SEED_HELP = ("seeds the genetic search, the random starts and the uncertainty's draws: the "
             "same seed gives the same result (default 0)")


def register(subparsers) -> None:
    p = subparsers.add_parser("fit", help="fit a model to a measurement file",
                              description="Fit a model's parameters (kb, kr, a, b, kd of the "
                                          "paper's model by default) by minimising E of "
                                          "Eq. (6).")
    p.add_argument("file", help=FILE_HELP)
    add_model_option(p, "the model to fit (auto: the model brdfjax models recommends: of "
                        "those whose cv_error is within one standard error of the lowest, "
                        "the fewest parameters; with --predict or --export and the learned "
                        "discrepancy, the one it recommends for prediction: that model "
                        "unless its corrected cv_error is more than one standard error above "
                        "the lowest)")
    p.add_argument("--method", choices=("hybrid", "ga", "lm"), default="hybrid",
                   help="hybrid: genetic search then Levenberg-Marquardt (default)")
    p.add_argument("--seed", type=int, default=0, help=SEED_HELP)
    group = p.add_mutually_exclusive_group()
    group.add_argument("--train-incidence", type=angles, metavar="DEG",
                       help="fit on these incidences only; the others are held out")
    group.add_argument("--validate-incidence", type=angles, metavar="DEG",
                       help="hold these incidences out of the fit and score them after")
    p.add_argument("--bound", action="append", default=[], metavar="NAME=LO:HI",
                   help="override a parameter's search range, e.g. b=-80:10")
    p.add_argument("--json", metavar="OUT", help="write the result as JSON")
    p.add_argument("--plot", metavar="OUT",
                   help="draw data and fitted curves (PNG); with --uncertainty laplace or "
                        "mcmc, the posterior's curves in 68 and 95 %% bands")
    p.add_argument("--plot-3d", metavar="OUT",
                   help="draw the fitted f_r cos(theta_r) over the hemisphere (PNG)")
    p.add_argument("--incidences-3d", type=zeniths, metavar="DEG",
                   help="incidences for --plot-3d (default: those of the data, up to 3)")
    p.add_argument("--log", action="store_true", help="log vertical axis in --plot")
    p.add_argument("--uncertainty", choices=UNCERTAINTY_METHODS, default="laplace",
                   help="laplace: Gaussian at the optimum, milliseconds (default); mcmc: "
                        "emcee posterior samples, seconds; none: no intervals")
    p.add_argument("--uncertainty-table", action="store_true",
                   help="print the uncertainty's full table (std, 68 and 95 %% intervals, "
                        "the three strongest correlations, every warning) instead of its "
                        "few-line summary; --json has it all either way")
    p.add_argument("--walkers", type=positive_int, default=32,
                   help="mcmc: ensemble size (default 32; at least twice the sampled "
                        "coordinates, with --model auto those of the largest model it may "
                        "choose, checked before any fit)")
    p.add_argument("--mcmc-steps", type=positive_int, default=20000,
                   help="mcmc: cap on the chain length; it stops earlier once longer than 50 "
                        "autocorrelation times (default 20000)")
    p.add_argument("--chain", metavar="FILE.h5",
                   help="mcmc: keep the chain in this HDF5 file; an existing chain resumes")
    p.add_argument("--plot-corner", metavar="OUT",
                   help="corner plot of the parameters' posterior (PNG; needs --uncertainty "
                        "laplace or mcmc)")
    p.add_argument("--loss", choices=("eq6", "relative", "balanced"), default="eq6",
                   help="what the fit minimises: eq6, E of Eq. (6) (default); relative, each "
                        "point's relative error; balanced, each incidence weighted equally "
                        "(for data spanning decades, where Eq. 6 follows the brightest "
                        "incidence); cv_error is always Eq. (6)")
    p.add_argument("--cv", action="store_true",
                   help="cross-validate by incidence: hold out each incidence in turn and "
                        "report its E (all folds one batched fit)")
    p.add_argument("--predict", metavar="GEOMETRY",
                   help="predict at the geometry of this file (any format, or a CSV of "
                        "theta_i,theta_r,phi_r), with 68/95 %% predictive intervals "
                        "calibrated on cross-validation; needs --predict-out. Of --in-plane, "
                        "--blank and --wavelength it takes those its format reads (a geometry "
                        "CSV none, an RT-300S .xls all three)")
    p.add_argument("--predict-out", metavar="PRED.csv",
                   help="where --predict writes theta_i,theta_r,phi_r,brdf,model_brdf,lo68,"
                        "hi68,lo95,hi95[,measured] (brdf: the prediction; model_brdf: the "
                        "analytic model alone); PRED.csv-metadata.json beside it says what "
                        "made it (model, discrepancy, parameters, calibration, training file, "
                        "command)")
    p.add_argument("--discrepancy", choices=DISCREPANCIES, default="gp",
                   help="what --predict and the plot's predictive bands add to the model: gp, "
                        "a Gaussian process learned from the model's log residual, which "
                        "corrects the prediction and narrows the intervals where the data "
                        "teach it (default); none, the model alone with intervals relative "
                        "to it")
    p.add_argument("--export", action="append", default=[], metavar="OUT.bsdf|OUT.astm",
                   help="tabulate the prediction for optical software: a Zemax tabular .bsdf "
                        "or an ASTM E1392 .astm (by suffix; repeatable), with the learned "
                        "discrepancy unless --discrepancy none; the TIS of each incidence is "
                        "printed")
    p.add_argument("--export-incidences", type=angles, metavar="DEG", default="0:80:10",
                   help="incidences of --export's tables (default 0:80:10)")
    p.add_argument("--export-step", type=float, metavar="DEG", default=5.0,
                   help="--export's grid step in scatter angle and azimuth, a divisor of "
                        "180 deg of at most 90 (default 5 deg); the scatter angles reach the "
                        "whole hemisphere")
    p.add_argument("--per-incidence", action="store_true",
                   help="fit each incidence on its own (all in one batched call) and print "
                        "one parameter row per incidence; with --model abg, also the TIS "
                        "checks and the parameters FRED takes")
    p.add_argument("--abg-out", metavar="OUT",
                   help="with --model abg --per-incidence: write the rows as a Zemax ABg "
                        "data catalog entry (text: NAME WAVELENGTH, then ANGLE A B G rows)")
    p.add_argument("--abg-name", metavar="NAME",
                   help="the catalog entry's name (default: the sample's name)")
    p.add_argument("--wavelength-um", type=float, metavar="UM",
                   help="the entry's wavelength in micrometres (default: the data's, else 0, "
                        "which Zemax reads as no wavelength scaling)")
    add_reader_options(p)
    p.set_defaults(run=run_fit)

    p = subparsers.add_parser("demo", help="the paper's white-paint fit on bundled data",
                              description="Reflectance of the paper's five samples, then a "
                                          "fit of the bundled (synthetic) white-paint data "
                                          "as the paper did, beside the paper's numbers.")
    p.add_argument("--out", default="out", help="folder for the figures (default: out)")
    p.set_defaults(run=run_demo)

    p = subparsers.add_parser("compare", help="GA vs gradient vs scipy on one file",
                              description="Run time against error of each fitting method "
                                          "on the same data, in one process.")
    p.add_argument("file", help=FILE_HELP)
    add_model_option(p, "the model to fit")
    p.add_argument("--seed", type=int, default=0, help=SEED_HELP)
    p.add_argument("--repeats", type=positive_int, default=3,
                   help="timed runs per method (default 3)")
    add_reader_options(p)
    p.set_defaults(run=run_compare)


def parse_bounds(items) -> dict:
    """``["b=-80:10", ...]`` as ``{"b": (-80.0, 10.0)}``."""
    ranges = {}
    for item in items:
        name, _, span = item.partition("=")
        low, _, high = span.partition(":")
        try:
            ranges[name.strip()] = (float(low), float(high))
        except ValueError:
            raise ValueError(f"--bound {item!r}: write NAME=LO:HI, e.g. b=-80:10") from None
    return ranges


def held_out(data, args) -> list:
    """Incidences to hold out, from --train-incidence or --validate-incidence."""
    if args.validate_incidence is not None:
        return list(args.validate_incidence)
    if args.train_incidence is None:
        return []
    train = np.round(args.train_incidence, 6)
    missing = set(train) - set(data.incidences_deg)
    if missing:
        raise ValueError(f"--train-incidence {sorted(missing)} deg not in the data "
                         f"(it has {list(data.incidences_deg)})")
    return [x for x in data.incidences_deg if x not in set(train)]


def run_fit(args) -> None:
    from brdfjax.cache import enable
    from brdfjax.data.formats import load
    from brdfjax.models.bounds import make_bounds
    from brdfjax.uncertainty.mcmc import inline_dispatch

    inline_dispatch()  # one device and many small calls (emcee): no worker-thread hand-off
    enable()
    from brdfjax.fitting.fit import fit

    if args.plot_corner and args.uncertainty == "none":
        raise ValueError("--plot-corner needs --uncertainty laplace or mcmc")
    if bool(args.predict) != bool(args.predict_out):
        raise ValueError("--predict GEOMETRY and --predict-out PRED.csv go together")
    if args.abg_out and (args.model != "abg" or not args.per_incidence):
        raise ValueError(f"--abg-out exports ABg rows: it needs --model abg --per-incidence, "
                         f"not --model {args.model}"
                         + ("" if args.per_incidence else " without --per-incidence"))
    if args.uncertainty == "mcmc":
        from brdfjax.uncertainty.mcmc import require_emcee

        require_emcee()  # before the fit, not after it
    if args.plot_corner:
        from brdfjax.optional import require

        require("corner", "mcmc", "the corner plot (--plot-corner)")
    for path in args.export:
        if not path.endswith(EXPORTS):
            raise ValueError(f"--export {path}: name a Zemax .bsdf or an ASTM E1392 .astm file")
    if args.export:
        check_export_grid(args.export_step, args.export_incidences)
    described = sidecar_path(args.predict_out) if args.predict_out else None
    if described and args.json and Path(described).resolve() == Path(args.json).resolve():
        raise ValueError(f"--predict-out {args.predict_out} is described in {described}, "
                         "which --json names too: give one of them another name")
    check_writable({**{f"--export {path}": path for path in args.export},
                    "--json": args.json, "--predict-out": args.predict_out,
                    "--predict-out's description": described,
                    "--chain": args.chain if args.uncertainty == "mcmc" else None,
                    "--abg-out": args.abg_out},
                   figures={"--plot": args.plot, "--plot-3d": args.plot_3d,
                            "--plot-corner": args.plot_corner})
    data = load(args.file, **reader_options(args))
    geometry = None
    if args.predict:  # read and checked like the output paths: before any fitting
        from brdfjax.data.formats import load_geometry
        from brdfjax.data.measurements import DataError

        try:
            geometry = load_geometry(args.predict, **predict_reader_options(args))
        except DataError as error:  # which of the two files: the option says
            raise DataError(f"--predict {error}") from None
    if args.uncertainty == "mcmc" and not args.per_incidence:  # before any fit
        check_model_walkers(args.model, args.walkers, data.sigma is not None)
    if args.model == "auto":  # chosen on the training incidences alone, as the fit sees them
        training = data.select(~data.incidence_mask(held_out(data, args)))
        args.model = choose_model(training, args.seed, predicting=bool(
            (args.predict or args.export) and args.discrepancy == "gp"))
    if args.per_incidence:
        run_per_incidence(data, args)
        return
    result = fit(data, args.method, model=args.model, seed=args.seed, loss=args.loss,
                 validate_incidences_deg=held_out(data, args),
                 bounds=make_bounds(parse_bounds(args.bound), model=args.model))
    print(summary(result, data.name))
    if result.status == "failed":
        result = dataclasses.replace(result, message=failure_reason())
        if args.json:
            from brdfjax.data.formats import json_text, write_atomically

            write_atomically(args.json, json_text(result.to_dict()))
        written = f" (the result, status failed, is in {args.json})" if args.json else ""
        raise ValueError(f"{args.file}: the fit failed: {result.message}{written}")
    calibration, prediction = (validate_and_predict(result, data, args, geometry)
                               if args.cv or args.predict or args.export else (None, None))
    uncertainty = estimate_uncertainty(result, data, args)
    if uncertainty is not None:
        print(uncertainty_block(uncertainty, result, args.uncertainty_table))
    write_outputs(result, data, args, uncertainty, calibration, prediction)


def check_model_walkers(model: str, walkers: int, sigma: bool) -> None:
    """Refuse too few emcee ``walkers`` for ``model`` (``sigma``: the data give one), before
    any work: with ``auto``, for the largest model it may choose, before the comparison."""
    from brdfjax.models import get
    from brdfjax.prediction.selection import DEFAULT_CANDIDATES
    from brdfjax.uncertainty.likelihood import coordinate_names
    from brdfjax.uncertainty.mcmc import check_walkers

    sizes = {name: len(coordinate_names(get(name), sigma))
             for name in (DEFAULT_CANDIDATES if model == "auto" else [model])}
    largest = max(sizes, key=sizes.get)
    try:
        check_walkers(walkers, sizes[largest])
    except ValueError as error:
        if model != "auto":
            raise
        raise ValueError(f"--model auto may choose {largest}: {error}") from None


def predict_reader_options(args) -> dict:
    """The reader options (`brdfjax.commands.reader_options`) that apply to the ``--predict``
    file: those its format's reader takes, no others.

    ``--in-plane``, ``--blank`` and ``--wavelength`` are given for the measurement file, and
    ``--predict`` may name a file of another format: a geometry CSV takes none of the first
    two, so ``fit X.xls --in-plane --predict grid.csv`` was refused. An RT-300S ``--predict``
    file takes all three (read as the training scan is: in the plane if that one is, with the
    same blank), a NIST, ASTM, Zemax or CSV file the wavelength (a CSV's is checked against its
    ``# wavelength_nm:`` line). A file that is missing, a folder or of no known format still
    fails, in `run_fit`, with the ``--predict`` option named.
    """
    import inspect

    from brdfjax.data.formats import _format_reader

    taken = inspect.signature(_format_reader(args.predict).read).parameters
    return {name: value for name, value in reader_options(args).items() if name in taken}


def run_per_incidence(data, args) -> None:
    """``--per-incidence``: each incidence fitted on its own, in one batched call; with
    ``--model abg`` the TIS checks, FRED's parameters and the Zemax catalog entry."""
    from brdfjax.data.formats import json_text, write_atomically
    from brdfjax.models import get
    from brdfjax.models.bounds import make_bounds
    from brdfjax.prediction.cross_validation import fit_per_incidence

    model = get(args.model)
    unsupported = [flag for flag, value in (("--plot", args.plot), ("--cv", args.cv),
                                            ("--predict", args.predict),
                                            ("--plot-corner", args.plot_corner),
                                            ("--validate-incidence", args.validate_incidence))
                   if value]
    if unsupported:
        raise ValueError(f"--per-incidence does not combine with {', '.join(unsupported)}")
    if args.train_incidence is not None:
        data = data.at_incidences(args.train_incidence)
    fits = fit_per_incidence(data, model, seed=args.seed,
                             bounds=make_bounds(parse_bounds(args.bound), model=model))
    print(f"{data.name}: {len(data)} points, {model.name} fitted at each of {len(fits)} "
          "incidences on its own")
    width = max(len(result.status) for _, result in fits) if fits else 9
    print(f"  {'incidence':>9}  {'E (%)':>8}  {'status':<{width}} " + " ".join(
        f"{name:>12}" for name in model.names))
    for degrees, result in fits:
        print(f"  {degrees:9g}  {100 * result.error:8.4g}  {result.status:<{width}} "
              + " ".join(f"{v:12.5g}" for v in result.vector))
    payload = {"model": model.name, "per_incidence": [
        {"incidence_deg": degrees, **result.to_dict()} for degrees, result in fits]}
    if model.name == "abg":
        from brdfjax.data.formats.abg import abg_rows, catalog_entry, report

        rows = abg_rows(fits)
        print(report(rows))
        payload["abg"] = [row.to_dict() for row in rows]
        if args.abg_out:
            wavelength = args.wavelength_um
            if wavelength is None:
                nm = data.wavelength_nm
                wavelength = nm / 1000 if nm else 0.0
            name = args.abg_name or re.sub(r"[^A-Za-z0-9_-]+", "_", data.name)[:32]
            write_atomically(args.abg_out, catalog_entry(name, rows, wavelength))
            print(f"Zemax ABg catalog entry {name.upper()} ({wavelength:g} um, {len(rows)} "
                  f"rows) written to {args.abg_out}")
    if args.json:
        write_atomically(args.json, json_text(payload))


def fitted_points(geometry, training) -> np.ndarray:
    """Which points of ``geometry`` are at a geometry of the ``training`` data (a mask)."""
    trained = set(map(tuple, training.geometries()))
    return np.array([key in trained for key in map(tuple, geometry.geometries())], bool)


def failure_reason() -> str:
    """Why a fit found no finite E of Eq. (6), in words a user can act on.

    (Extreme values that would overflow Eq. 6 are refused when the data are read,
    `brdfjax.data.measurements.validate`, so a failed fit is the model's doing.)
    """
    return ("no Levenberg-Marquardt start reached a finite E of Eq. (6): the model "
            "overflowed or gave NaN wherever it was tried; check the data for extreme "
            "values, or narrow the search box with --bound")


def choose_model(data, seed: int, predicting: bool = False) -> str:
    """``--model auto``, said aloud: the model ``brdfjax models`` recommends
    (`brdfjax.prediction.selection.Comparison.best`: of the models whose cv_error is within
    one standard error of the lowest, the fewest parameters), or, ``predicting`` with the
    learned discrepancy, the one it recommends for prediction
    (`~brdfjax.prediction.selection.Comparison.predictor`: of the models whose cv_error
    corrected by their discrepancy is within one standard error of the lowest, the first
    that the rule on cv_error alone prefers). Choosing for prediction by the corrected
    cv_error gives narrower intervals than correcting the model chosen by cv_error alone
    (BENCHMARKS.md, predictive-discrepancy, under the rule before 2026-12-07: median
    half-width 21 % against 27 % on the 14 RT-300S runs, 68 % coverage 69 against 79 %,
    at a 95 % coverage of 91.1 against 96.3 % and a median error of 4.8 against 4.5 %).
    The model so chosen may fit poorly on its own (lambert on NiTE on steel A) and predict
    well only with its correction."""
    from brdfjax.prediction.selection import compare_models

    comparison = compare_models(data, seed=seed, discrepancy="gp" if predicting else "none")
    print(f"--model auto: {comparison.recommendation()}")
    chosen = comparison.predictor if predicting else comparison.best
    if predicting and np.isfinite(chosen.corrected_cv_error):
        print(f"--model auto: predicting with {chosen.name} and its learned discrepancy")
        best = comparison.best
        if chosen is not best and chosen.fit.error > 3 * best.fit.error:
            print(f"--model auto: {chosen.name} alone fits these data far worse than "
                  f"{best.name} (E {100 * chosen.fit.error:.3g} % against "
                  f"{100 * best.fit.error:.3g} %): its learned discrepancy carries the shape, "
                  "and the fit below is the analytic part alone")
    return chosen.name


def validate_and_predict(result, data, args, geometry=None):
    """``--cv`` prints the cross-validation; ``--predict`` makes the predictive intervals
    (written with the other files, `write_outputs`).

    ``geometry`` is the ``--predict`` file, read before the fit (`run_fit`).

    Returns:
        The conformal `brdfjax.prediction.intervals.Calibration` (for the plot's predictive bands
        and the JSON) and the `brdfjax.prediction.intervals.Prediction` (None without --predict).
    """
    from brdfjax.prediction.intervals import predict

    calibration, validation = calibrated(result, args)
    if args.cv:
        print(validation.table())
        if calibration.discrepancy is not None:
            print(f"  with the discrepancy (model x learned correction): cv_error = "
                  f"{100 * calibration.corrected_cv_error:.4g} %")
    prediction = None
    if geometry is not None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # printed below, with the rest
            prediction = predict(result, geometry, calibration)
        what = ("the model times its learned correction, --discrepancy gp"
                if prediction.discrepancy == "gp" else "the model alone, --discrepancy none")
        line = (f"predictions at {len(geometry)} points for {args.predict_out} "
                f"({what}); median 95 % half-width "
                f"{100 * np.median(prediction.half_width()):.3g} % of the prediction")
        if prediction.measured is not None:
            line += f"; measured values inside the intervals: {scores(prediction)}"
            fitted = fitted_points(geometry, result.training)
            if fitted.all():
                line += (f" (all {fitted.sum()} points were fitted: in-sample, not a "
                         "validation; --validate-incidence DEG holds an incidence out)")
            elif fitted.any():
                line += (f" ({fitted.sum()} of the {len(geometry)} points were fitted: "
                         f"in-sample, not a validation; on the {(~fitted).sum()} others: "
                         f"{scores(prediction, ~fitted)})")
        print(line)
        for note in prediction.warnings:
            print(f"  warning: {note}")
        if result.model.name == "five":
            suggest_model(result, args, validation, calibration)
    return calibration, prediction


def scores(prediction, where=None) -> str:
    """How a prediction met its measured values (of the points ``where``, all if None): its
    intervals' coverage and its median relative error, in words."""
    return (f"95 %: {100 * prediction.coverage('95', where):.1f} %, 68 %: "
            f"{100 * prediction.coverage('68', where):.1f} %, median relative error "
            f"{100 * prediction.median_error(where):.3g} %")


def calibrated(result, args):
    """The conformal calibration of ``result``, and the cross-validation it came from."""
    from brdfjax.prediction.cross_validation import cross_validate
    from brdfjax.prediction.intervals import calibrate

    validation = cross_validate(result.training, result.model, seed=args.seed,
                                bounds=result.bounds)
    return calibrate(result.training, validation, discrepancy=args.discrepancy,
                     fitted=result.vector), validation


def suggest_model(result, args, validation, calibration) -> None:
    """Say so when `BETTER_MODEL` predicts the held-out incidences much better than the
    paper's model, with the command that uses it. Only its held-out error is needed: its
    cross-validation, corrected by its discrepancy on the interior folds where the
    prediction has one (`brdfjax.prediction.intervals.corrected_cv_terms`), not a fit to
    all the data nor intervals."""
    from brdfjax.prediction.cross_validation import cross_validate
    from brdfjax.prediction.intervals import corrected_cv_terms, cv_error_of

    other = cross_validate(result.training, BETTER_MODEL, seed=args.seed)
    ours, theirs = validation.cv_error, other.cv_error
    if calibration.discrepancy is not None:
        ours = calibration.corrected_cv_error
        theirs = cv_error_of(corrected_cv_terms(result.training, [other])[0])
    if np.isfinite(ours) and theirs * BETTER_MODEL_FACTOR < ours:
        print(f"  note: {BETTER_MODEL} predicts the held-out incidences {ours / theirs:.3g}x "
              f"better than the paper's model (cv_error {100 * theirs:.3g} % against "
              f"{100 * ours:.3g} %): {rerun_command(args, BETTER_MODEL)}")


# The options that name a file the command writes (`rerun_command` renames them).
OUTPUT_OPTIONS = ("--predict-out", "--json", "--plot", "--plot-3d", "--plot-corner",
                  "--export", "--chain", "--abg-out")


def rerun_command(args, model: str) -> str:
    """The command line the user gave (``args.argv``) with ``--model model`` instead of
    theirs (`brdfjax.commands.edited_command`): each file it writes renamed
    ``NAME-MODEL.EXT``, so that the rerun keeps this run's files, and each ``--bound`` on a
    parameter ``model`` lacks left out."""
    from brdfjax.models import get

    names = get(model).names
    edits = {"--model": lambda _: None,
             "--bound": lambda item: item if item.partition("=")[0].strip() in names else None,
             **dict.fromkeys(OUTPUT_OPTIONS, lambda path: renamed(path, model))}
    return edited_command(args.argv, "fit", edits, append=["--model", model])


def renamed(path: str, model: str) -> str:
    """``path`` with ``-model`` before its suffix: ``out.csv`` -> ``out-ggx.csv``."""
    name = Path(path)
    return str(name.with_name(f"{name.stem}-{model}{name.suffix}"))


def predictive_bands(result, incidences_deg, calibration) -> dict:
    """The prediction and its 68/95 % bands of ``f_r cos(theta_r)`` along the plot's in-plane
    curves: ``{incidence: (signed_deg, prediction, lo68, hi68, lo95, hi95)}``."""
    from brdfjax.data.measurements import Measurements
    from brdfjax.plot import curve_angles
    from brdfjax.prediction.intervals import predict

    bands = {}
    for incidence in incidences_deg:
        angles, signed = curve_angles(incidence)
        geometry = Measurements(*angles, np.full(signed.size, np.nan))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the plot's incidences are the data's own
            prediction = predict(result, geometry, calibration)
        cos_r = np.cos(angles[1])
        bands[incidence] = (signed, *(getattr(prediction, k) * cos_r
                                      for k in ("brdf", "lo68", "hi68", "lo95", "hi95")))
    return bands


def estimate_uncertainty(result, data, args):
    """The `~brdfjax.uncertainty.result.UncertaintyResult` asked for by ``--uncertainty``, or None.

    Nothing of the other method is imported or computed: ``none`` does no work at all, and
    ``laplace`` never imports emcee. Warnings go into the printed table, not to stderr.
    """
    if args.uncertainty == "none":
        return None
    if result.status in ("failed", "underdetermined"):
        print("uncertainty: none, the fit "
              + ("failed" if result.status == "failed" else "is underdetermined"))
        return None
    from brdfjax.uncertainty.result import UncertaintyWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UncertaintyWarning)
        if args.uncertainty == "laplace":
            from brdfjax.uncertainty.laplace import laplace_approximation

            return laplace_approximation(data, result, seed=args.seed)
        from brdfjax.uncertainty.mcmc import sample_posterior

        return sample_posterior(data, result, walkers=args.walkers, max_steps=args.mcmc_steps,
                                seed=args.seed, chain_path=args.chain)


def uncertainty_block(uncertainty, result, full: bool = False) -> str:
    """What ``fit`` prints of the uncertainty: a few lines, or with ``full``
    (``--uncertainty-table``) the whole table and its warnings."""
    if full:
        return uncertainty.table(fitted=result.vector, loss=result.loss)
    count = len(uncertainty.warnings)
    said = f"its {count} warning{'s' if count != 1 else ''}, " if count else ""
    return uncertainty.brief(fitted=result.vector, loss=result.loss,
                             hint=f"std, 68 % intervals, {said}correlations: "
                                  "--uncertainty-table; everything: --json")


def write_outputs(result, data, args, uncertainty=None, calibration=None,
                  prediction=None) -> None:
    """The files asked for (--predict-out's CSV of the ``prediction`` among them), each
    written whole or not at all, after all computing is done.

    With an ``uncertainty`` result, --json gains an "uncertainty" entry (parameter
    intervals and the reflectance's at `REFLECTANCE_INCIDENCES`), --plot draws its 68 % and
    95 % curve bands around the fitted curves (not where the approximation is
    untrustworthy: the reason is printed instead), and --plot-corner draws the posterior.
    With a ``calibration`` (--cv or --predict), --plot also draws the predictive bands
    (the legend names each shade): where a new measurement falls (`brdfjax.prediction.intervals`),
    around the prediction (dotted where the discrepancy corrects the model), and --json
    gains a "prediction" entry (the calibration, the learned process, and the
    ``prediction``'s summary). Data that are not in the
    plane of incidence are drawn as polar maps of data, model and residual.
    """
    from brdfjax.data.formats import json_text, replace_atomically, write_atomically

    record = result.to_dict()
    if calibration is not None:
        record["prediction"] = {**calibration.to_dict(),
                                **(prediction.to_dict() if prediction is not None else {})}
    bands, note = None, ""
    if uncertainty is not None:
        from brdfjax.uncertainty.bands import band_note, curve_bands, reflectance_bands

        if args.json:
            record["uncertainty"] = uncertainty.to_dict()
            record["uncertainty"]["reflectance"] = reflectance_bands(
                uncertainty.samples, REFLECTANCE_INCIDENCES, model=result.model,
                seed=args.seed).to_dict()
        if args.plot and uncertainty.status in ("ok", "converged"):
            bands = curve_bands(uncertainty.samples, data.incidences_deg,
                                model=result.model)
            note = band_note(uncertainty, bands)
            if note:
                print(f"plot: {note}")
        elif args.plot and data.in_plane:
            print(f"plot: no curve band drawn, the {uncertainty.method} result is "
                  f"{uncertainty.status.replace('_', ' ')} (why: the uncertainty line "
                  "above)")
    if prediction is not None:
        text = prediction.to_csv()
        write_atomically(args.predict_out, text)
        write_atomically(sidecar_path(args.predict_out), json_text(prediction.sidecar(
            text, **prediction_context(result, data, args, calibration))))
    if args.json:
        write_atomically(args.json, json_text(record))
    if args.plot and not data.in_plane:
        from brdfjax.fitting.objective import brdf_values, prepare
        from brdfjax.plot import plot_polar_maps

        predicted = np.asarray(brdf_values(result.vector, prepare(data, result.model),
                                           result.model))
        replace_atomically(args.plot, lambda path: plot_polar_maps(
            data, predicted, path, title=f"{data.name}: {result.model.name} fit, "
                                         f"E = {100 * result.error:.3g} %"))
    elif args.plot:
        from brdfjax.plot import plot_fit

        errors = {**result.error_by_incidence, **result.validation_by_incidence}
        # --predict's incidences that were not measured are drawn too: the curve asked for,
        # and the --predict file's own readings where the data lack them
        asked = [] if prediction is None else [
            t for t in np.unique(np.round(prediction.theta_i, 6))
            if not np.any(np.isclose(t, data.incidences_deg))]
        readings = predicted_readings(prediction, data, args.predict)
        predictive = (None if calibration is None else
                      predictive_bands(result, [*data.incidences_deg, *asked], calibration))
        kinds = " and ".join(name for name, shown in (
            ("68/95 % posterior bands", bands), ("95 % predictive bands", predictive))
            if shown)
        replace_atomically(args.plot, lambda path: plot_fit(
            data, result.vector, path, model=result.model,
            held_out=result.validation_incidences, log=args.log, bands=bands,
            predictive=predictive, errors=errors, note=note, readings=readings,
            bands_method=uncertainty.method if bands else "",
            title=f"{data.name}: {result.model.name} fit, E = {100 * result.error:.3g} %"
                  + (f"; {kinds}" if kinds else "")))
    if args.plot_3d:
        from brdfjax.plot import figure_title, plot_hemisphere

        incidences = data.incidences_deg  # spread over the data's range by default
        incidences = (args.incidences_3d if args.incidences_3d is not None else incidences[
            np.unique(np.round(np.linspace(0, len(incidences) - 1, 3)).astype(int))])
        replace_atomically(args.plot_3d, lambda path: plot_hemisphere(
            result.vector, incidences, path, model=result.model,
            title=figure_title(data.name, result.model.name, "over the hemisphere")))
    if args.plot_corner:
        from brdfjax.plot import figure_title, plot_corner

        replace_atomically(args.plot_corner, lambda path: plot_corner(
            uncertainty, path, title=figure_title(data.name, result.model.name,
                                                  f"{uncertainty.method} posterior")))
    for path in args.export:
        export(path, result, data, args, calibration)
    written = [path for path in (args.predict_out if prediction is not None else None,
                                 sidecar_path(args.predict_out) if prediction else None,
                                 args.json, args.plot, args.plot_3d, args.plot_corner,
                                 *args.export) if path]
    if written:
        print(f"wrote {', '.join(written)}")


def sidecar_path(predict_out: str) -> str:
    """Where ``--predict-out PRED.csv``'s description goes: ``PRED.csv-metadata.json``
    beside it (`brdfjax.prediction.intervals.Prediction.sidecar` says why a sidecar). The name
    is the one W3C's CSV on the Web gives a CSV's metadata file (its content is brdfjax's
    own, not a CSVW table description); ``PRED.json`` was often the name users give
    ``--json`` for the same run."""
    return f"{predict_out}-metadata.json"


def prediction_context(result, data, args, calibration) -> dict:
    """What the ``--predict-out`` sidecar adds to the prediction's own description: the
    file it was read from and fitted on, the parameters, the calibration (its conformal
    factors and learned process), the geometry file and the command that made it."""
    import shlex

    return {"csv": Path(args.predict_out).name,
            "params": dict(zip(result.model.names, map(float, result.params))),
            "training": {"file": str(args.file), "sample": data.name,
                         "reader_options": reader_options(args),
                         "fitted_incidences_deg": [float(t) for t in np.unique(np.round(
                             np.degrees(result.training.theta_i), 6))],
                         "held_out_incidences_deg": [float(t) for t in
                                                     result.validation_incidences]},
            "geometry_file": str(args.predict),
            "calibration": calibration.to_dict(),
            "command": shlex.join(["brdfjax", *args.argv])}


def predicted_readings(prediction, data, source) -> dict:
    """The ``--predict`` file's measured values that `plot_fit` draws: those in the plane of
    incidence at geometries the fitted file lacks (its own points are drawn as data), by
    incidence, ``{incidence: (Measurements, legend label)}``; the label says which file they
    come from and how many of them the 95 % intervals hold, as the console does."""
    from brdfjax.data.measurements import Measurements

    if prediction is None or prediction.measured is None:
        return {}
    known = {tuple(row) for row in np.round(np.degrees(
        [data.theta_i, data.theta_r, np.mod(data.phi_r, 2 * np.pi)]).T, 6)}
    geometry = np.stack([prediction.theta_i, prediction.theta_r,
                         np.mod(prediction.phi_r, 360.0)], axis=1)
    new = np.array([tuple(row) not in known for row in np.round(geometry, 6)], bool)
    in_plane = np.abs(np.sin(np.radians(prediction.phi_r))) < 1e-9
    keep = new & in_plane & np.isfinite(prediction.measured)
    inside = (prediction.measured >= prediction.lo95) & (prediction.measured <= prediction.hi95)
    readings = {}
    for incidence in np.unique(np.round(prediction.theta_i[keep], 6)):
        at = keep & np.isclose(prediction.theta_i, incidence, rtol=0, atol=1e-6)
        points = Measurements(*np.radians([prediction.theta_i[at], prediction.theta_r[at],
                                           prediction.phi_r[at]]), prediction.measured[at])
        readings[float(incidence)] = (points, (
            f"{incidence:g} deg measured ({Path(source).name}, not fitted),\n"
            f"{inside[at].sum()} of {at.sum()} in the 95 % band"))
    return readings


EXPORTS = (".bsdf", ".astm")


def check_export_grid(step: float, incidences) -> None:
    """``--export-step`` and ``--export-incidences``, checked in degrees before the fit: the
    step by `brdfjax.data.formats.zemax.is_grid_step`, the incidences in [0, 90)."""
    from brdfjax.data.formats.zemax import is_grid_step

    if not is_grid_step(step):
        raise ValueError(f"--export-step {step:g}: give a step in degrees of at most 90 that "
                         "divides 180, such as 1, 2, 2.5, 5 or 10")
    outside = [f"{t:g}" for t in np.atleast_1d(incidences) if not 0 <= t < 90]
    if outside:
        raise ValueError(f"--export-incidences: {', '.join(outside)} deg is not an incidence "
                         "in [0, 90) deg")


def export(path, result, data, args, calibration) -> None:
    """Write ``--export``'s table (`brdfjax.data.formats.zemax.write_model` or
    `brdfjax.data.formats.astm.write_model_astm`) of the prediction (corrected by
    ``calibration``'s discrepancy, if any; `run_fit` calibrates whenever it exports) on the
    ``--export-*`` grid, say its TIS, and warn of the table's nodes the calibration does
    not cover, as ``--predict`` does (`brdfjax.prediction.intervals.range_notes`)."""
    from brdfjax.data.formats.astm import write_model_astm
    from brdfjax.data.formats.zemax import HORIZON_DEG, grid_angles, write_model
    from brdfjax.prediction.intervals import range_notes

    step = args.export_step
    incidences = np.sort(np.asarray(args.export_incidences, float))
    correction = calibration.discrepancy
    options = {"sample": data.name, "model": result.model, "correction": correction,
               "wavelength_nm": data.wavelength_nm}
    azimuths, radials = zemax_axes(incidences, step)
    if path.endswith(".bsdf"):
        totals = write_model(path, result.params, incidences, azimuths, radials, **options)
        aoi, theta_r, phi_r = grid_angles(incidences, azimuths, radials)
        above = theta_r < HORIZON_DEG - 1e-9
        nodes = np.stack([aoi[above], theta_r[above], phi_r[above]], axis=1)
    else:
        zeniths = np.arange(0, 90, step)
        write_model_astm(path, result.params, incidences, zeniths, azimuths, **options)
        # the TIS of the same prediction on Zemax's grid, for comparison with the .bsdf
        totals = zemax_tis(result, correction, incidences, step)
        nodes = np.stack([g.ravel() for g in np.meshgrid(incidences, zeniths, azimuths,
                                                         indexing="ij")], axis=1)
    what = "model x learned discrepancy" if correction is not None else "model"
    print(f"{path}: {what} on a {step:g} deg grid; TIS at "
          + ", ".join(f"{aoi:g} deg {t:.4g}" for aoi, t in zip(incidences, totals)))
    if step >= 2:  # half the step: four times the nodes (the default grid, with the
        # discrepancy, on 2 cores: 0.5 s warm, 1.4 s the first time)
        finer = zemax_tis(result, correction, incidences, step / 2)
        drift = np.abs(np.asarray(totals) - finer) / np.maximum(np.abs(finer),
                                                                np.finfo(float).tiny)
        worst = int(np.argmax(drift))
        if drift[worst] > TIS_DRIFT:
            print(f"  note: {path}: with half the step ({step / 2:g} deg) the TIS at "
                  f"{incidences[worst]:g} deg moves by {100 * drift[worst]:.2g} %: the grid is "
                  "coarse for this lobe, and a ray tracer interpolating it errs as much; a "
                  "finer --export-step follows the prediction better")
    note = tis_note(result, correction, incidences, step, totals)
    if note:
        print(f"  note: {path}: {note}")
    for note in range_notes(calibration, result.training.in_plane,
                            *np.radians(distinct_directions(nodes).T), what="table nodes"):
        print(f"  warning: {path}: {note}")


# The relative change of an exported table's TIS with half its step above which `export`
# says the grid is coarse: GGX alone on NiTE on invar A at 80 deg incidence moves by 2.3 %
# from the default 5 deg to 2.5 deg (TIS 0.1891 and 0.1935), by 11 % from 10 deg to 5.
TIS_DRIFT = 0.05


# The relative difference between an exported table's TIS and the fitted model's reflectance
# (Eq. 9, what fit prints as rho) above which `tis_note` says why. The same 5 % as
# `TIS_DRIFT`: below it the export's own quadrature may account for the difference (the grid
# alone is let err up to that before it is called coarse); above it a user comparing the two
# printed numbers reads a contradiction. GGX with its learned correction on NiTE on invar A at
# 0 deg: 0.06396 against 0.07335, -12.8 %, of which the 5 deg grid -0.4 %.
TIS_MISMATCH = 0.05


def tis_note(result, correction, incidences, step: float, totals) -> str:
    """Why an exported table's TIS (``totals``, one per incidence) differs from the fitted
    model's reflectance (`brdfjax.models.hemispherical.reflectance`, Eq. 9), where it does by
    more than `TIS_MISMATCH`; "" where it does not.

    The two integrate different things: the table gives the model times the learned
    correction (``correction``, None with ``--discrepancy none``) at its nodes, and its TIS
    is a trapezoidal rule over them; the reflectance is the analytic model alone, integrated
    by a quadrature dense around its lobe. The note splits the difference at the worst
    incidence into its two factors: the grid's (the model alone on the same grid against its
    reflectance) and the correction's (the table against the model alone on the grid)."""
    from brdfjax.models.hemispherical import reflectance

    rho = np.asarray(reflectance(result.params, np.radians(incidences), model=result.model,
                                 warn=False), float)
    totals = np.asarray(totals, float)
    difference = totals / np.where(rho > 0, rho, np.nan) - 1
    if not np.nanmax(np.abs(difference), initial=0.0) > TIS_MISMATCH:
        return ""
    worst = int(np.nanargmax(np.abs(difference)))
    alone = float(totals[worst] if correction is None
                  else zemax_tis(result, None, incidences[worst:worst + 1], step)[0])
    grid = alone / rho[worst] - 1
    over = [f"{t:g}" for t, d in zip(incidences, difference) if abs(d) > TIS_MISMATCH]
    text = (f"the table's TIS differs from the {result.model.name} model's reflectance (fit's "
            f"rho) by more than {100 * TIS_MISMATCH:g} % at {', '.join(over)} deg; at "
            f"{incidences[worst]:g} deg {totals[worst]:.4g} against {rho[worst]:.4g} "
            f"({100 * difference[worst]:+.3g} %). The grid's quadrature makes "
            f"{100 * grid:+.2g} % of it (the model alone on this {step:g} deg grid: "
            f"{alone:.4g})")
    if correction is None:
        return text + "; a finer --export-step follows the model closer"
    return (text + f"; the learned correction the table multiplies the model by makes "
            f"{100 * (totals[worst] / alone - 1):+.3g} %: it is the data's departure from "
            "the model, which the reflectance leaves out (--discrepancy none tabulates the "
            "model alone)")


def zemax_axes(incidences, step: float) -> tuple[np.ndarray, np.ndarray]:
    """The azimuths (0-180 deg) and radials (the whole hemisphere) of `export`'s Zemax grid
    at the step ``step`` (deg)."""
    from brdfjax.data.formats.zemax import hemisphere_radials

    return np.arange(0, 180 + step / 2, step), hemisphere_radials(incidences, step)


def zemax_tis(result, correction, incidences, step: float) -> np.ndarray:
    """The TIS of ``result``'s prediction (corrected by ``correction``, if any) at each
    incidence, tabulated on `export`'s Zemax grid with the step ``step`` (deg)."""
    from brdfjax.data.formats.zemax import model_table, tis

    azimuths, radials = zemax_axes(incidences, step)
    _, _, _, table = model_table(result.params, incidences, azimuths, radials, result.model,
                                 correction)
    return np.array([tis(block, aoi, azimuths, radials)
                     for aoi, block in zip(incidences, table)])


def distinct_directions(nodes) -> np.ndarray:
    """The distinct geometries among ``nodes`` (K, 3) of ``(theta_i, theta_r, phi_r)`` in
    degrees: a table repeats the normal (and Zemax's grid the specular ray) at every
    azimuth."""
    nodes = np.array(nodes, dtype=float)
    nodes[:, 2] = np.where(nodes[:, 1] < 1e-9, 0.0, np.mod(nodes[:, 2], 360.0))
    return np.unique(np.round(nodes, 6), axis=0)


def incidence_lines(errors: dict, result) -> list[str]:
    """One line of E per incidence; for scattered incidences, per incidence bin."""
    from brdfjax.data.measurements import MAX_FOLDS, incidence_groups

    if len(errors) <= MAX_FOLDS:
        return [f"        {deg:6g} deg: E = {100 * e:.4g} %" for deg, e in errors.items()]
    from brdfjax.fitting.objective import prepare, projected, relative_error, targets

    data = result.training
    fitted = np.asarray(projected(result.vector, prepare(data, result.model), result.model))
    target, weight = targets(data)
    lines = [f"        {len(errors)} distinct incidences (scattered); E by incidence bin:"]
    for label, _, _, mask in incidence_groups(data):
        lines.append(f"        {label:>9} deg: E = "
                     f"{100 * relative_error(fitted[mask], target[mask], weight[mask]):.4g} % "
                     f"({mask.sum()} points)")
    return lines


def poor_incidences(errors: dict, overall: float) -> list[float]:
    """The incidences (deg) whose E exceeds `INCIDENCE_WARNING` times the ``overall`` E.

    Eq. (6) weighs the brightest incidences most, so a small overall E can hide a poor fit
    at the others; `fit` warns of these and `batch` lists them (``poor_incidences``).
    """
    return sorted(float(deg) for deg, e in errors.items()
                  if np.isfinite(e) and e > INCIDENCE_WARNING * overall)


def summary(result, name: str) -> str:
    """A readable table of a `brdfjax.fitting.fit.FitResult`, with the reflectance of Eq. (9)."""
    from brdfjax.models.bounds import to_unit
    from brdfjax.models.hemispherical import energy_warning, reflectance

    names = result.model.names
    width = max(3, *map(len, names))
    loss = "" if result.loss == "eq6" else f" minimising the {result.loss} loss"
    lines = [f"{name}: {result.method} fit of the {result.model.name} model{loss}, status "
             + result.status]
    lines += [f"  {k:>{width}} = {v:14.6g}" + ("   (at a bound)" if k in result.at_bounds
                                               else "") for k, v in zip(names, result.params)]
    lines.append(f"  {'E':<{width}} = {100 * result.error:.4g} % on {len(result.residuals)} points "
                 f"(incidences {', '.join(f'{x:g}' for x in result.train_incidences)} deg)")
    lines += incidence_lines(result.error_by_incidence, result)
    poor = poor_incidences(result.error_by_incidence, result.error)
    if poor:
        shown = ", ".join(f"{deg:g} deg ({100 * result.error_by_incidence[deg]:.3g} %)"
                          for deg in poor[:POOR_SHOWN])
        more = f" and {len(poor) - POOR_SHOWN} more" if len(poor) > POOR_SHOWN else ""
        lines.append(f"  warning: E exceeds {INCIDENCE_WARNING:g}x the overall "
                     f"{100 * result.error:.3g} % at {shown}{more}: the overall E hides a "
                     "poor fit there (Eq. 6 is dominated by the brightest incidences; try "
                     "another --model, or --loss balanced)")
    if result.validation_error is not None:
        lines.append(f"  held out: E = {100 * result.validation_error:.4g} %")
        lines += incidence_lines(result.validation_by_incidence, result)
    rho = np.asarray(reflectance(result.params, np.radians(SUMMARY_INCIDENCES),
                                 model=result.model, warn=False))
    lines.append("  reflectance rho(" + ", ".join(f"{x:g}" for x in SUMMARY_INCIDENCES)
                 + " deg) = " + ", ".join(f"{r:.4f}" for r in rho))
    warning = energy_warning(rho)
    if warning:
        lines.append(f"  warning: {warning}")
    times = ", ".join(f"{k} {v * 1e3:.0f} ms" for k, v in result.timings.items())
    lines.append(f"  {result.evaluations} model evaluations; {times}")
    if result.at_bounds and result.status != "underdetermined":  # its warning says it all
        unit = np.asarray(to_unit(result.vector, result.bounds))
        sides = {name: "lower" if unit[result.model.index(name)] < 0.5 else "upper"
                 for name in result.at_bounds}
        limits = {p.name: p.limits for p in result.model.parameters if p.limits}
        box = dict(zip(result.model.names, zip(np.asarray(result.bounds.lower).tolist(),
                                               np.asarray(result.bounds.upper).tolist())))
        lines += [f"  note: {text}" for text in
                  bound_notes(result.model.names, result.params, sides, limits, box)]
    return "\n".join(lines)


# Parameters that scale a term of f_r (linear in it): at a lower bound near zero the term is
# simply absent, and widening towards zero cannot lower E.
SCALE_PARAMETERS = ("kb", "kd")


def bound_notes(names, params, at_bounds: dict, limits: dict | None = None,
                box: dict | None = None) -> list[str]:
    """What a parameter at the edge of the search box means, and whether to widen the box.

    Args:
        names: the parameter names, in the order of ``params``.
        params: the fitted values.
        at_bounds: ``{name: "lower" or "upper"}`` for each parameter at an edge.
        limits: ``{name: (low, high)}``, the physical range of the parameters that have one
            (`brdfjax.models.base.Parameter.limits`): at it, no wider box exists, and a
            wider box is offered only within it.
        box: ``{name: (low, high)}``, the search box: a parameter is at the end of its
            physical range where its bound is (without, where its value is within 1e-6).

    Returns:
        One sentence per parameter (or degenerate pair). The hint to widen with ``--bound``
        is given only where widening can lower E: not for a scale parameter at its lower
        bound (its term is absent), and not for kb at its lower bound with a positive b.
        There ``kb exp(b (1 - cos g)^a)`` trades a smaller kb for a larger b, and with ``a``
        small the data determine only the product, about ``kb exp(b)``: a wider box moves
        both along that valley without improving the fit (on the EC1 coating, kb from 1e-14
        to 1.1e-30 moved E from 1.704 % to 1.699 %; issue 15).
    """
    from brdfjax.models.base import limits_text

    values, limits = dict(zip(names, params)), limits or {}
    notes = []

    def at_limit(name, side):
        end = limits[name][side == "upper"]
        if box is not None:
            return box[name][side == "upper"] == end
        return bool(np.isclose(values[name], end, rtol=1e-6, atol=1e-6))

    for name, side in at_bounds.items():
        value = values[name]
        if name == "kb" and side == "lower" and "b" in values and values["b"] > 0:
            notes.append(
                f"kb = {value:.3g} at its lower bound with b = {values['b']:+.3g}: in "
                "kb exp(b (1 - cos g)^a) a smaller kb trades against a larger b, and the data "
                f"determine only their product (kb exp(b) = {value * np.exp(values['b']):.3g}); "
                "read kb and b together. Widening kb's bound moves both without improving E")
        elif name in SCALE_PARAMETERS and side == "lower":
            notes.append(f"{name} = {value:.3g} at its lower bound: its term is negligible "
                         "for these data; widening the bound cannot lower E")
        elif name in limits and at_limit(name, side):
            notes.append(f"{name} = {value:.3g} at its {side} bound, the end of its physical "
                         f"range ({limits_text(limits[name])}): the data ask for more than "
                         "the model can give there; no wider bound exists")
        else:
            within = (f" (within its physical range, {limits_text(limits[name])})"
                      if name in limits else "")
            notes.append(f"{name} = {value:.3g} at its {side} bound: the best fit may lie "
                         f"beyond it; widen it with --bound {name}=LO:HI{within}")
    return notes


def compilations(work):
    """``work()``'s result, and how many functions XLA compiled for it (cache misses)."""
    import jax.monitoring

    misses = [0]

    def listen(event, **_):
        if event == "/jax/compilation_cache/compile_requests_use_cache":
            misses[0] += 1
        elif event == "/jax/compilation_cache/cache_hits":
            misses[0] -= 1

    jax.monitoring.register_event_listener(listen)
    try:
        return work(), misses[0]
    finally:
        jax.monitoring.unregister_event_listener(listen)


def run_demo(args) -> None:
    check_writable(folders={"--out": args.out})
    from brdfjax.cache import enable

    cache = enable()
    from brdfjax.data.formats import load, replace_atomically
    from brdfjax.fitting.fit import fit
    from brdfjax.models.hemispherical import energy_warning, reflectance
    from brdfjax.models.paper import PAPER_ERRORS_PERCENT, PAPER_SAMPLES
    from brdfjax.plot import figure_title, plot_fit, plot_hemisphere

    print("Reflectance rho(theta_i) of Eq. (9) for the paper's parameters")
    print(f"  {'sample':<14} {'0 deg':>8} {'30 deg':>8} {'60 deg':>8}")
    for name, params in PAPER_SAMPLES.items():
        rho = np.asarray(reflectance(params, np.radians([0.0, 30.0, 60.0]), warn=False))
        flag = "   > 1: not energy-conserving" if energy_warning(rho) else ""
        print(f"  {name:<14} " + " ".join(f"{r:8.4f}" for r in rho) + flag)

    path = DATA / "synthetic" / "white_paint.csv"
    data = load(path)
    print(f"\nFit of {path.name} (SYNTHETIC stand-in: the paper's data are not published), "
          "on 10/30/45/60 deg, validated on 21/52 deg as in the paper")
    result, compiled = compilations(lambda: fit(data, validate_incidences_deg=[21, 52]))
    paper = PAPER_SAMPLES["white_paint"]
    print(f"  {'':>3} {'fitted':>12} {'paper':>12}")
    for key in paper._fields:
        print(f"  {key:>3} {getattr(result.params, key):12.5g} {getattr(paper, key):12.5g}")
    print(f"  E (fit)      {100 * result.error:8.4f} %   paper (real data) "
          f"{PAPER_ERRORS_PERCENT['white_paint']} %")
    print(f"  E (held out) {100 * result.validation_error:8.4f} %")
    rho0 = float(reflectance(result.params, 0.0, warn=False))
    print(f"  rho(0 deg)   {100 * rho0:8.2f} %   paper 73.4 % (integrating sphere 79.6 %)")
    print(f"  status {result.status}; fit took {1e3 * result.timings['total']:.0f} ms "
          + (f"(including {compiled} XLA compilations, which later runs load from "
             f"{cache / 'xla'})" if compiled else
             "(its compiled code loaded from the cache)"))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    replace_atomically(out / "demo_fit.png", lambda p: plot_fit(
        data, result.vector, p, held_out=[21, 52],
        title=figure_title("white_paint (synthetic)", result.model.name,
                           "on 10/30/45/60 deg, 21/52 deg held out")))
    replace_atomically(out / "demo_hemisphere.png", lambda p: plot_hemisphere(
        result.vector, [10, 30, 60], p,
        title=figure_title("white_paint (synthetic)", result.model.name, "over the hemisphere")))
    print(f"\nFigures: {out / 'demo_fit.png'}, {out / 'demo_hemisphere.png'}")


def run_compare(args) -> None:
    from brdfjax.compare import compare, format_table
    from brdfjax.data.formats import load

    data = load(args.file, **reader_options(args))
    print(format_table(compare(data, seed=args.seed, repeats=args.repeats, model=args.model)))
