"""Predictive intervals for new measurements at any geometry, calibrated on held-out data.

A band on the model curve (`brdfjax.uncertainty.bands`) says where the best-fitting curve lies; a
user predicting an unmeasured incidence needs where a new *measurement* falls, and on real
materials the model is wrong in ways no curve uncertainty covers (held-out incidences of
the RT-300S coatings fall outside the 95 % Laplace band 53-90 % of the time). So the
intervals here are calibrated on the data's own cross-validation
(`brdfjax.prediction.cross_validation`): split-conformal prediction over incidence folds.

With ``discrepancy="gp"`` (the default) the prediction is the model corrected by a
Gaussian process of its log residual (`brdfjax.prediction.discrepancy`), and the score follows the
process's own uncertainty:

1. Every fold's model and a process fitted to that fold's training residuals predict the
   held-out incidence: ``mu`` and ``sigma`` of the log residual. Each held-out point gets the
   score ``r = |log(max(y, 0) + floor) - log(y_hat + floor) - mu| / sigma^g``, with the
   process's own ``floor`` (`brdfjax.prediction.discrepancy.residual_floor`) and ``g`` =
   `SIGMA_POWER` (1/2): where the process knows less the interval widens, but by the square
   root of its ``sigma``. A calibration fold predicts its incidence across a wider gap than
   the final prediction does (one incidence fewer), and the process's ``sigma`` shrinks
   with the gap faster than its errors do: with ``g = 1``, predicting 30 deg of the 8
   RT-300S runs read whole from 10, 50 and 70 deg (calibrated at 50 deg from 10 and 70),
   the 95 % intervals held 65-84 % of the held-out readings on 4 runs.
2. At level ``p`` (68.27 % or 95 %) the factor ``q`` is the ``ceil((n + 1) p)``-th smallest
   of the n scores (infinite when n is too small).
3. At a new geometry the full fit's model ``y_hat`` and the process fitted to all training
   residuals give the prediction ``(y_hat + floor) exp(mu) - floor`` and the interval
   ``(y_hat + floor) exp(mu +- q sigma^g) - floor``: wide where the process is unsure.

Where the process cannot take up the model's shape error (the paper's model on the RT-300S
coatings, from three training incidences) that score's quantile is large and the intervals,
exponentiated, grow wider than the model's own. So the score is chosen per data set: the
one above, or the relative score of the corrected prediction ``r = |y - y_c| / (|y_c| +
floor)`` (interval ``y_c +- q (|y_c| + floor)``): the first unless its median 95 % interval
on the interior held-out points is more than `SIGMA_PREFERENCE` times the second's
(`Calibration.score`). Choosing between two scores
on the calibration points costs at most a few points of coverage, which the benchmarks
measure (BENCHMARKS.md, predictive-discrepancy).

With ``discrepancy="none"`` the prediction is the model itself and the score
``r = |y - y_hat| / (|y_hat| + floor)`` (the interval ``y_hat +- q (|y_hat| + floor)``).
In both relative scores ``floor`` is `FLOOR_FRACTION` of the median measured |BRDF| (a
stand-in for the instrument's absolute noise). Interior folds calibrate geometry inside the
fitted incidence range; geometry outside it (extrapolation) uses every fold, the end folds
included. The end folds extrapolate by the spacing of the two outermost incidences on their
side: that is how far beyond the measured range a prediction is calibrated
(`Calibration.reach`). Predictions are still given past it, with a warning
(`Prediction.warnings`).

Assumptions, stated plainly: the score of a new measurement is exchangeable with the
scores of the held-out incidences (the model errs at an unmeasured incidence as it errs
at a held-out one). That is what "leave one incidence out" imitates; it does not hold for
geometry far from anything measured, and the intervals are pointwise (each contains its
own new measurement with the stated probability, not all of them at once). With few
incidences the calibration set is small: 3 incidences give one interior fold.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from brdfjax.data.measurements import Measurements

LEVELS = {"68": 0.6827, "95": 0.95}
FLOOR_FRACTION = 0.05
DISCREPANCIES = ("gp", "none")
# With a discrepancy, the process-scaled score is kept unless its intervals on the interior
# held-out points are this many times wider than the relative score's (`calibrate_all`).
# Chosen on the four runs bench_predictive.DECIDE (ggx and five; 1, 1.25, 1.5, 2 and never
# tried), with the previous process (angles only, before 03048ac): 1.25 gave ggx 93 % coverage
# at a 15 % median half-width and five 97 % at 55 %. Not re-chosen for the incidence-aware one,
# nor for the score over the square root of sigma (`SIGMA_POWER`).
SIGMA_PREFERENCE = 1.25
# The power of the process's sigma that the process-scaled score divides by (the module
# docstring). Chosen on 2026-12-07 with ggx on the 14 RT-300S runs (in the plane and, for 8,
# read whole), NIST's PTFE and the sets of section predictive-unseen all in view (1, 0.75,
# 0.5, 0.25 and 0 tried, and a floor on sigma at the calibration's median; benchmarks/NOTES.md,
# predictive-3d): 1/2 is the one with every RT-300S run's 95 % coverage at least 85 %, both
# ways of reading them, at the narrowest median half-width.
SIGMA_POWER = 0.5


@dataclass
class Calibration:
    """Conformal scores from cross-validation (see the module docstring).

    Attributes:
        interior: scores of the interior folds' held-out points.
        every: scores of every fold's held-out points.
        floor: the absolute floor of the relative scores (1/sr); the process-scaled score
            uses the process's own floor (``discrepancy.floor``).
        low, high: the fitted incidence range (deg): inside it ``interior`` calibrates.
        reach: the incidences (deg) up to which extrapolation is calibrated (`reach_of`).
        discrepancy: the process fitted to all training residuals (None: no correction).
        corrected_errors: with a discrepancy, each fold's held-out E of Eq. (6) of the
            corrected prediction, by the fold's label.
        interior_labels: the labels of the interior folds.
        score: ``sigma`` (the log residual's error over the process's sigma to the power
            `SIGMA_POWER`) or ``relative`` (``|y - prediction| / (|prediction| + floor)``):
            with a discrepancy, as `calibrate_all` chooses; without one, ``relative``.
    """

    interior: np.ndarray
    every: np.ndarray
    floor: float
    low: float
    high: float
    reach: tuple = (-np.inf, np.inf)
    discrepancy: object = None
    corrected_errors: dict = field(default_factory=dict)
    interior_labels: tuple = ()
    score: str = "relative"

    @property
    def kind(self) -> str:
        return "none" if self.discrepancy is None else "gp"

    @property
    def corrected_cv_error(self) -> float:
        """Mean held-out E of Eq. (6) of the corrected predictions over the interior folds
        (cv_error with the discrepancy; NaN without one)."""
        values = [self.corrected_errors[k] for k in self.interior_labels
                  if k in self.corrected_errors]
        return float(np.mean(values)) if values else float("nan")

    def factor(self, level: float, extrapolating: bool) -> float:
        """The half-width factor q at ``level`` (the conformal quantile of the scores)."""
        scores = self.every if extrapolating or self.interior.size == 0 else self.interior
        rank = math.ceil((scores.size + 1) * level)
        return float(np.sort(scores)[rank - 1]) if rank <= scores.size else np.inf

    def to_dict(self) -> dict:
        record = {"discrepancy": self.kind, "score": self.score,
                  "relative_floor": self.floor,
                  "calibration_points": {"interior": int(self.interior.size),
                                         "every": int(self.every.size)},
                  "factor95": {"interior": self.factor(LEVELS["95"], False),
                               "extrapolation": self.factor(LEVELS["95"], True)},
                  "calibrated_incidences_deg": list(self.reach)}
        if self.discrepancy is not None:
            record["process"] = self.discrepancy.to_dict()
            record["cv_error_with_discrepancy"] = self.corrected_cv_error
        return record


def reach_of(incidences) -> tuple[float, float]:
    """How far beyond the measured incidences extrapolation is calibrated: the end folds
    predict an end incidence from the next one in, so by that spacing on each side."""
    x = np.sort(np.asarray(incidences, float))
    if x.size < 2:
        return float(x[0]), float(x[-1])
    return float(max(0.0, x[0] - (x[1] - x[0]))), float(min(90.0, x[-1] + (x[-1] - x[-2])))


def calibrate(data: Measurements, validation, *, discrepancy: str = "gp",
              fitted=None) -> Calibration:
    """Conformal scores of a `brdfjax.prediction.cross_validation.CrossValidation` of ``data``.

    Args:
        data: the training measurements the cross-validation ran on.
        validation: its `CrossValidation`.
        discrepancy: ``gp`` (a process per fold, and one on every point of ``data``) or
            ``none``.
        fitted: the parameter vector fitted to all of ``data`` (for the process on every
            point; needed with ``gp``).
    """
    return calibrate_all(data, [(validation, fitted)], discrepancy=discrepancy)[0]


def check_discrepancy(discrepancy: str) -> None:
    """Refuse a ``discrepancy`` other than `DISCREPANCIES`, before any work."""
    if discrepancy not in DISCREPANCIES:
        raise ValueError(f"unknown discrepancy {discrepancy!r}; choose one of "
                         f"{', '.join(DISCREPANCIES)}")


def calibrate_all(data: Measurements, validations: list, *,
                  discrepancy: str = "gp") -> list[Calibration]:
    """`calibrate` of several cross-validations of ``data`` (``[(validation, fitted)]``, one
    per model), every process of every model fitted in one batched call.

    Call it from one thread: XLA's LAPACK calls (the processes' Cholesky factorisations)
    can deadlock when several threads run them at once.
    """
    check_discrepancy(discrepancy)
    floor = _floor(data)
    incidences = data.incidences_deg
    common = {"floor": floor, "low": float(incidences.min()),
              "high": float(incidences.max()), "reach": reach_of(incidences)}
    if discrepancy == "none":
        return [Calibration(*_split(v.folds, [
            np.abs(data.brdf[f.index] - f.predicted) / (np.abs(f.predicted) + floor)
            for f in v.folds]), **common, interior_labels=_interior(v)) for v, _ in validations]
    if any(fitted is None for _, fitted in validations):
        raise ValueError("calibrate(discrepancy='gp') needs the full fit's parameters")
    from brdfjax.prediction.discrepancy import log_residual

    calibrations = []
    for validation, (folds, full_process) in zip(
            (v for v, _ in validations), _corrected_folds(data, validations)):
        scores = {"sigma": [], "relative": []}
        corrected, widths = {}, []
        for c in folds:
            measured = data.brdf[c.held]
            residual = log_residual(measured, c.value[c.held], full_process.floor)
            scores["sigma"].append(np.abs(residual - c.mu) / c.sigma**SIGMA_POWER)
            scores["relative"].append(np.abs(measured - c.centre) / (np.abs(c.centre) + floor))
            corrected[c.fold.label] = float(np.mean(_corrected_terms(c, data)))
            if c.fold.interior:
                widths.append((c.value[c.held], c.mu, c.sigma))
        candidates = [Calibration(*_split(validation.folds, found), **common,
                                  interior_labels=_interior(validation),
                                  discrepancy=full_process, corrected_errors=corrected,
                                  score=kind) for kind, found in scores.items()]
        sigma_width, relative_width = (_median_width(c, widths) for c in candidates)
        calibrations.append(candidates[0] if sigma_width <= SIGMA_PREFERENCE * relative_width
                            else candidates[1])
    return calibrations


def corrected_cv_terms(data: Measurements, validations: list) -> list[tuple]:
    """For cross-validations of ``data`` (one per model), each model's held-out terms of E
    of Eq. (6) corrected by its learned discrepancy, one array per interior fold
    (`brdfjax.prediction.cross_validation.held_out_terms`): a fold's E is the mean of its
    terms, and the mean of the folds' E is the corrected cv_error that
    `Calibration.corrected_cv_error` reports. Only the interior folds' processes are fitted
    (all of them in one batched call; the intervals also need the end folds' and the full
    data's, `calibrate_all`). Empty for a model without interior folds. Call it from one
    thread, as `calibrate_all`."""
    return [tuple(_corrected_terms(c, data) for c in folds)
            for folds, _ in _corrected_folds(data, [(v, None) for v in validations],
                                             interior_only=True)]


def cv_error_of(terms: tuple) -> float:
    """The cv_error of `corrected_cv_terms`' folds: the mean of their E (NaN for none)."""
    return float(np.mean([fold.mean() for fold in terms])) if terms else float("nan")


def compile_corrected_cv_terms(data: Measurements, validation, models: int) -> None:
    """Compile what `corrected_cv_terms` of ``models`` cross-validations of ``data`` folded
    as ``validation`` runs, without running it (no LAPACK call, so safe while other
    threads fit): ``brdfjax models`` so compiles it while the other models fit, instead of
    after them all (about 2 s of one core's time at the end of the first run)."""
    from brdfjax.prediction.discrepancy import compile_discrepancies

    masks = [~held for held in _held_out(data, validation, interior_only=True)[1]] * models
    if masks:  # the sets' sizes are what matters: the data stand in for the models' values
        compile_discrepancies(_training_sets(data, [data.brdf] * len(masks), masks))


class _Corrected(NamedTuple):
    """One fold's held-out points predicted by its model corrected by a process fitted to
    the fold's training points: the model's values on all points (N,), the held-out mask,
    and on the held-out points the process's ``mu`` and ``sigma`` and the corrected BRDF."""

    fold: object
    value: np.ndarray
    held: np.ndarray
    mu: np.ndarray
    sigma: np.ndarray
    centre: np.ndarray


def _corrected_folds(data: Measurements, validations: list, *,
                     interior_only: bool = False) -> list:
    """Per ``(validation, fitted)``: every fold's (or every interior fold's) `_Corrected`,
    and the process fitted to all points with the model's ``fitted`` parameters (None with
    ``interior_only``), every process of every model fitted in one batched call."""
    from brdfjax.fitting.objective import brdf_values, prepare
    from brdfjax.models import get

    per_model, values, masks = [], [], []
    for validation, fitted in validations:
        model = get(validation.model)
        geometry = prepare(data, model)
        folds, held = _held_out(data, validation, interior_only)
        vectors = [f.params for f in folds] + ([] if interior_only else [fitted])
        values += [np.asarray(brdf_values(np.asarray(v, float), geometry, model))
                   for v in vectors]
        masks += [~h for h in held] + ([] if interior_only else [np.ones(len(data), bool)])
        per_model.append((folds, held, len(vectors)))
    processes, values = iter(_fit_processes(data, values, masks)), iter(values)
    out = []
    for folds, held, count in per_model:
        sets = [(next(values), next(processes)) for _ in range(count)]  # this model's
        corrected = []
        for fold, mask, (value, process) in zip(folds, held, sets):
            mu, sigma = process.predict(data.theta_i[mask], data.theta_r[mask],
                                        data.phi_r[mask])
            corrected.append(_Corrected(fold, value, mask, mu, sigma,
                                        process.correct(value[mask], mu)))
        out.append((corrected, None if interior_only else sets[-1][1]))
    return out


def _held_out(data: Measurements, validation, interior_only: bool) -> tuple[list, list]:
    """The folds of ``validation`` that get a process (the interior ones alone with
    ``interior_only``) and each one's held-out points as a mask over ``data``."""
    folds = [f for f in validation.folds if f.interior or not interior_only]
    return folds, [np.isin(np.arange(len(data)), f.index) for f in folds]


def _floor(data: Measurements) -> float:
    """The absolute floor of the scores' scale: `FLOOR_FRACTION` of the median |BRDF|."""
    return FLOOR_FRACTION * float(np.median(np.abs(data.brdf)))


def _corrected_terms(corrected: _Corrected, data: Measurements) -> np.ndarray:
    """The terms of the held-out E of Eq. (6) of one fold's corrected prediction (E is their
    mean)."""
    from brdfjax.prediction.cross_validation import held_out_terms

    full = corrected.value.copy()
    full[corrected.held] = corrected.centre
    return held_out_terms(full, data, corrected.held)


def _median_width(calibration: Calibration, interior: list) -> float:
    """The median 95 % half-width (relative to the prediction) that ``calibration`` gives
    its own interior held-out points: what `calibrate_all` chooses the score by."""
    q = calibration.factor(LEVELS["95"], False)
    if not np.isfinite(q) or not interior:
        return np.inf
    widths = []
    for value, mu, sigma in interior:
        centre = calibration.discrepancy.correct(value, mu)
        low, high = _interval(calibration, q, value, centre, mu, sigma)
        widths.append((high - low) / 2 / np.abs(centre))
    return float(np.median(np.concatenate(widths)))


def _interval(calibration: Calibration, q, values, centre, mu, sigma):
    """``(low, high)`` at factor ``q`` around ``centre`` (the model's ``values``, corrected
    by ``mu`` where there is a discrepancy), in the form of ``calibration.score``."""
    if calibration.discrepancy is None or calibration.score == "relative":
        scale = np.abs(centre) + calibration.floor
        return centre - q * scale, centre + q * scale
    scale = q * sigma**SIGMA_POWER
    with np.errstate(over="ignore", invalid="ignore"):
        return (calibration.discrepancy.correct(values, mu - scale),
                calibration.discrepancy.correct(values, mu + scale))


def _interior(validation) -> tuple:
    return tuple(f.label for f in validation.folds if f.interior)


def _split(folds, scores) -> tuple[np.ndarray, np.ndarray]:
    """(interior scores, every score) of the folds' score arrays."""
    interior = [s for f, s in zip(folds, scores) if f.interior]
    return (np.concatenate(interior) if interior else np.zeros(0), np.concatenate(scores))


def _fit_processes(data: Measurements, values: list, masks: list) -> list:
    """One `brdfjax.prediction.discrepancy.Discrepancy` per (model values, training mask), fitted in
    one batched call on at most `brdfjax.prediction.discrepancy.MAX_POINTS` of each mask's
    points."""
    from brdfjax.prediction.discrepancy import fit_discrepancies, residual_floor

    return fit_discrepancies(_training_sets(data, values, masks), residual_floor(data.brdf),
                             not data.in_plane)


def _training_sets(data: Measurements, values: list, masks: list) -> list:
    """Each process's (features, log residuals) on at most
    `brdfjax.prediction.discrepancy.MAX_POINTS` of its mask's points."""
    from brdfjax.prediction.discrepancy import (
        MAX_POINTS,
        features,
        log_residual,
        residual_floor,
        subsample,
    )

    floor = residual_floor(data.brdf)
    x = features(data.theta_i, data.theta_r, data.phi_r, not data.in_plane)
    sets = []
    for value, mask in zip(values, masks):
        index = np.flatnonzero(mask)
        keep = index[subsample(data.theta_i[index], data.theta_r[index], data.phi_r[index],
                               MAX_POINTS)]
        sets.append((x[keep], log_residual(data.brdf[keep], value[keep], floor)))
    return sets


@dataclass
class Prediction:
    """Predictions and predictive intervals at a list of geometries (arrays (M,)).

    Attributes:
        theta_i, theta_r, phi_r: the geometry in degrees (the `Measurements` given hold radians).
        brdf: the prediction (1/sr): the model corrected by the discrepancy, or the model.
        model_brdf: the fitted analytic model's BRDF alone.
        lo68, hi68, lo95, hi95: where a new measurement falls with 68.27 % and 95 %
            probability.
        measured: the geometry file's measured BRDF, or None.
        model: the model's name.
        discrepancy: ``gp`` or ``none``.
        warnings: what the user should know (geometry beyond the calibrated range, or out
            of the plane of in-plane training data).
    """

    theta_i: np.ndarray
    theta_r: np.ndarray
    phi_r: np.ndarray
    brdf: np.ndarray
    model_brdf: np.ndarray
    lo68: np.ndarray
    hi68: np.ndarray
    lo95: np.ndarray
    hi95: np.ndarray
    measured: np.ndarray | None
    model: str
    discrepancy: str = "none"
    warnings: list = field(default_factory=list)

    def coverage(self, level: str = "95", where=None) -> float:
        """The share of measured values inside the interval (NaN without measurements), of
        the points ``where`` (a mask; all if None)."""
        if self.measured is None:
            return float("nan")
        low, high = getattr(self, f"lo{level}"), getattr(self, f"hi{level}")
        inside = (self.measured >= low) & (self.measured <= high)
        return float(np.mean(inside if where is None else inside[where]))

    def median_error(self, where=None) -> float:
        """The median of |prediction - measured| / |measured| (NaN without measurements), of
        the points ``where`` (a mask; all if None)."""
        if self.measured is None:
            return float("nan")
        error = np.abs(self.brdf - self.measured) / np.abs(self.measured)
        return float(np.median(error if where is None else error[where]))

    def half_width(self) -> np.ndarray:
        """The 95 % half-width relative to the prediction."""
        return (self.hi95 - self.lo95) / 2 / np.abs(self.brdf)

    def to_csv(self) -> str:
        """CSV text: ``theta_i,theta_r,phi_r,brdf,model_brdf,lo68,hi68,lo95,hi95[,measured]``."""
        columns = ["theta_i", "theta_r", "phi_r", "brdf", "model_brdf", "lo68", "hi68",
                   "lo95", "hi95"]
        if self.measured is not None:
            columns.append("measured")
        table = np.stack([getattr(self, c) for c in columns], axis=1)
        lines = [",".join(columns)]
        lines += [",".join(f"{v:.10g}" for v in row) for row in table]
        return "\n".join(lines) + "\n"

    def sidecar(self, csv_text: str, **context) -> dict:
        """What made the CSV text ``csv_text`` (`to_csv`), for a JSON file beside it
        (``PRED.csv-metadata.json`` beside ``PRED.csv``, as ``brdfjax fit --predict-out``
        writes it).

        A sidecar, not columns or comment lines: the CSV stays one header line and numbers,
        which ``pandas.read_csv``, ``numpy.loadtxt(..., delimiter=",", skiprows=1)`` and the
        ``csv`` module read without options (a ``#`` line would need ``comment="#"``; text
        columns would repeat one string on every row of up to 100,000 and stop NumPy's
        readers), and the description can nest what columns cannot (the calibration, the
        learned process, the parameters). The two files can travel apart: the sidecar names
        the CSV and its SHA-256, so a reader can tell whether it describes the CSV at hand.

        Args:
            csv_text: the CSV as written.
            **context: what the caller knows and the prediction does not (the training file,
                the parameters, the calibration, the command), added as given.

        Returns:
            A JSON-ready dict: ``model``, ``discrepancy``, ``points``, ``columns`` (each
            column's meaning), ``csv_sha256``, ``brdfjax_version``, ``warnings``, then
            ``context``.
        """
        import hashlib

        from brdfjax import __version__

        meaning = {"theta_i": "incidence (deg)", "theta_r": "reflection zenith (deg)",
                   "phi_r": "reflection azimuth (deg; 180: the specular side)",
                   "brdf": f"the prediction (1/sr): {self.model}"
                           + (" x its learned discrepancy" if self.discrepancy == "gp" else ""),
                   "model_brdf": f"the fitted {self.model} model alone (1/sr)",
                   "lo68": "68.27 % predictive interval, low (1/sr)", "hi68": "its high end",
                   "lo95": "95 % predictive interval, low (1/sr)", "hi95": "its high end",
                   "measured": "the geometry file's measured BRDF (1/sr)"}
        header = csv_text.split("\n", 1)[0].split(",")
        return {"model": self.model, "discrepancy": self.discrepancy,
                "points": int(self.brdf.size),
                "columns": {name: meaning[name] for name in header},
                "csv_sha256": hashlib.sha256(csv_text.encode()).hexdigest(),
                "brdfjax_version": __version__, "warnings": list(self.warnings), **context}

    def to_dict(self) -> dict:
        """A summary for JSON (the values themselves go to the CSV)."""
        record = {"model": self.model, "discrepancy": self.discrepancy,
                  "points": int(self.brdf.size),
                  "median_half_width95": float(np.median(self.half_width())),
                  "warnings": self.warnings}
        if self.measured is not None:
            record["coverage"] = {"95": self.coverage("95"), "68": self.coverage("68")}
        return record


def predict(result, geometry: Measurements, calibration: Calibration | None = None, *,
            discrepancy: str = "gp", seed: int = 0) -> Prediction:
    """Predictive intervals of a fit at the geometry of ``geometry`` (any brdfjax file).

    Args:
        result: a `brdfjax.fitting.fit.FitResult` (its model, bounds and training data are used).
        geometry: where to predict (a `Measurements`; its BRDF, if any, is reported as
            ``measured``; a geometry-only file has NaN there).
        calibration: conformal scores; if None, computed by
            `brdfjax.prediction.cross_validation.cross_validate` of the fit's training data
            (all folds in one batched fit) once per fit, discrepancy and seed, and kept in
            ``result.calibrations``: predicting elsewhere from the same fit reuses them.
        discrepancy: ``gp`` (model times the learned correction, the default) or ``none``
            (the model alone); ignored when ``calibration`` is given (it carries its kind).
        seed: the seed of the cross-validation fits.

    Returns:
        A `Prediction`.
    """
    from brdfjax.data.measurements import checked
    from brdfjax.fitting.objective import brdf_values, prepare

    if not hasattr(result, "training"):
        raise TypeError(f"predict takes a fit's result (brdfjax.fit), got "
                        f"{type(result).__name__}")
    checked(geometry, "predict", geometry_only=True)
    check_discrepancy(discrepancy)
    if calibration is None:
        if (discrepancy, seed) not in result.calibrations:
            from brdfjax.prediction.cross_validation import cross_validate

            validation = cross_validate(result.training, result.model, seed=seed,
                                        bounds=result.bounds)
            result.calibrations[discrepancy, seed] = calibrate(
                result.training, validation, discrepancy=discrepancy, fitted=result.vector)
        calibration = result.calibrations[discrepancy, seed]
    values = np.asarray(brdf_values(result.vector, prepare(geometry, result.model),
                                    result.model))
    incidence = np.degrees(geometry.theta_i)
    outside = (incidence < calibration.low - 1e-6) | (incidence > calibration.high + 1e-6)
    process = calibration.discrepancy
    centre, mu, sigma = values, None, None
    if process is not None:
        mu, sigma = process.predict(geometry.theta_i, geometry.theta_r, geometry.phi_r)
        centre = process.correct(values, mu)
    bounds = {}
    for name, level in LEVELS.items():
        q = np.where(outside, calibration.factor(level, True), calibration.factor(level, False))
        bounds[f"lo{name}"], bounds[f"hi{name}"] = _interval(calibration, q, values, centre,
                                                              mu, sigma)
    notes = range_notes(calibration, result.training.in_plane, geometry.theta_i,
                        geometry.theta_r, geometry.phi_r)
    for note in notes:
        warnings.warn(note, PredictionWarning, stacklevel=2)
    measured = geometry.brdf if not np.all(np.isnan(geometry.brdf)) else None
    return Prediction(incidence, np.degrees(geometry.theta_r), np.degrees(geometry.phi_r),
                      centre, values, measured=measured, model=result.model.name,
                      discrepancy=calibration.kind, warnings=notes, **bounds)


def range_notes(calibration: Calibration, in_plane: bool, theta_i, theta_r, phi_r, *,
                what: str = "points") -> list:
    """What predictions at these angles (radians) should say (`Prediction.warnings`): the
    points whose incidence lies beyond `Calibration.reach`, and, for training data in the
    plane of incidence (``in_plane``), the points out of it. ``what`` names them:
    ``points`` (a prediction, with its intervals) or ``table nodes`` (an export: values
    alone)."""
    notes = []
    intervals = " and intervals" if what == "points" else ""
    incidence = np.degrees(theta_i)
    low, high = calibration.reach
    beyond = (incidence < low - 1e-6) | (incidence > high + 1e-6)
    if beyond.any():
        notes.append(f"{int(beyond.sum())} of {beyond.size} {what} have incidences beyond "
                     f"{low:g}-{high:g} deg, the range the end folds calibrate (the measured "
                     f"{calibration.low:g}-{calibration.high:g} deg widened by the spacing of "
                     f"the outermost incidences): their predictions{intervals} assume the "
                     "model errs there as it does one incidence step out; measure nearer "
                     "incidences to trust them")
    outside_plane = (np.abs(np.sin(phi_r)) > 1e-9) & (theta_r > 1e-9)
    if in_plane and outside_plane.any():
        applied = ("" if calibration.discrepancy is None else ", the learned correction is "
                   "applied as at the same half and difference angles in the plane")
        calibrated = ", and the intervals are calibrated in the plane only" if intervals else ""
        notes.append(f"{int(outside_plane.sum())} of {outside_plane.size} {what} lie out of "
                     "the plane of incidence, where the training data have none: the model's "
                     f"shape there is untested{applied}{calibrated}; measure out of the plane "
                     "to trust them")
    return notes


class PredictionWarning(UserWarning):
    """A prediction the calibration does not cover (geometry beyond `Calibration.reach`, or
    out of the plane of in-plane training data)."""
