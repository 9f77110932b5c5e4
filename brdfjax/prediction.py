"""Predictive intervals for new measurements at any geometry, calibrated on held-out data.

A band on the model curve (`brdfjax.bands`) says where the best-fitting curve lies; a user
predicting an unmeasured incidence needs where a new *measurement* falls, and on real
materials the model is wrong in ways no curve uncertainty covers (held-out incidences of
the RT-300S coatings fall outside the 95 % Laplace band 53-90 % of the time). So the
intervals here are calibrated on the data's own cross-validation (`brdfjax.validation`):
split-conformal prediction over incidence folds with a noise-scaled score.

1. Every fold's model predicts its held-out incidence; each held-out point gets the score
   ``r = |y - y_hat| / (|y_hat| + floor)``: relative where the BRDF is well above the
   noise floor, absolute near zero. ``floor`` is `FLOOR_FRACTION` of the median measured
   |BRDF| (a stand-in for the instrument's absolute noise).
2. At level ``p`` (68.27 % or 95 %) the half-width factor is the
   ``ceil((n + 1) p)``-th smallest of the n scores (infinite when n is too small).
3. At a new geometry the interval is ``y_hat +- q (|y_hat| + floor)``, with ``y_hat`` the
   full fit's prediction. Interior folds calibrate geometry inside the fitted incidence
   range; geometry outside it (extrapolation) uses every fold, the end folds included.

Assumptions, stated plainly: the score of a new measurement is exchangeable with the
scores of the held-out incidences (the model errs at an unmeasured incidence as it errs
at a held-out one). That is what "leave one incidence out" imitates; it does not hold for
geometry far from anything measured, and the intervals are pointwise (each contains its
own new measurement with the stated probability, not all of them at once). With few
incidences the calibration set is small: 3 incidences give one interior fold.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from brdfjax.measurements import Measurements

LEVELS = {"68": 0.6827, "95": 0.95}
FLOOR_FRACTION = 0.05


@dataclass
class Calibration:
    """Conformal scores from cross-validation (see the module docstring).

    Attributes:
        interior: scores of the interior folds' held-out points.
        every: scores of every fold's held-out points.
        floor: the absolute floor of the score's scale (1/sr).
        low, high: the fitted incidence range (deg): inside it ``interior`` calibrates.
    """

    interior: np.ndarray
    every: np.ndarray
    floor: float
    low: float
    high: float

    def factor(self, level: float, extrapolating: bool) -> float:
        """The half-width factor q at ``level`` (the conformal quantile of the scores)."""
        scores = self.every if extrapolating or self.interior.size == 0 else self.interior
        rank = math.ceil((scores.size + 1) * level)
        return float(np.sort(scores)[rank - 1]) if rank <= scores.size else np.inf


def calibrate(data: Measurements, validation) -> Calibration:
    """Conformal scores of a `brdfjax.validation.CrossValidation` of ``data``."""
    floor = FLOOR_FRACTION * float(np.median(np.abs(data.brdf)))
    scores = {True: [], False: []}
    for fold in validation.folds:
        measured = data.brdf[fold.index]
        score = np.abs(measured - fold.predicted) / (np.abs(fold.predicted) + floor)
        scores[fold.interior].append(score)
    interior = np.concatenate(scores[True]) if scores[True] else np.zeros(0)
    every = np.concatenate(scores[True] + scores[False])
    incidences = data.incidences_deg
    return Calibration(interior, every, floor, float(incidences.min()), float(incidences.max()))


@dataclass
class Prediction:
    """Predictions and predictive intervals at a list of geometries (arrays (M,)).

    Attributes:
        theta_i, theta_r, phi_r: the geometry, degrees as given.
        brdf: the fitted model's BRDF (1/sr).
        lo68, hi68, lo95, hi95: where a new measurement falls with 68.27 % and 95 %
            probability.
        measured: the geometry file's measured BRDF, or None.
        model: the model's name.
    """

    theta_i: np.ndarray
    theta_r: np.ndarray
    phi_r: np.ndarray
    brdf: np.ndarray
    lo68: np.ndarray
    hi68: np.ndarray
    lo95: np.ndarray
    hi95: np.ndarray
    measured: np.ndarray | None
    model: str

    def coverage(self, level: str = "95") -> float:
        """The share of measured values inside the interval (NaN without measurements)."""
        if self.measured is None:
            return float("nan")
        low, high = getattr(self, f"lo{level}"), getattr(self, f"hi{level}")
        return float(np.mean((self.measured >= low) & (self.measured <= high)))

    def to_csv(self) -> str:
        """CSV text: ``theta_i,theta_r,phi_r,brdf,lo68,hi68,lo95,hi95[,measured]``."""
        columns = ["theta_i", "theta_r", "phi_r", "brdf", "lo68", "hi68", "lo95", "hi95"]
        if self.measured is not None:
            columns.append("measured")
        table = np.stack([getattr(self, c) for c in columns], axis=1)
        lines = [",".join(columns)]
        lines += [",".join(f"{v:.10g}" for v in row) for row in table]
        return "\n".join(lines) + "\n"


def predict(result, geometry: Measurements, calibration: Calibration | None = None, *,
            seed: int = 0) -> Prediction:
    """Predictive intervals of a fit at the geometry of ``geometry`` (any brdfjax file).

    Args:
        result: a `brdfjax.fitting.FitResult` (its model, bounds and training data are used).
        geometry: where to predict (a `Measurements`; its BRDF, if any, is reported as
            ``measured``; a geometry-only file has NaN there).
        calibration: conformal scores; computed by `brdfjax.validation.cross_validate` of
            the fit's training data if None (all folds in one batched fit).
        seed: the seed of the cross-validation fits.

    Returns:
        A `Prediction`.
    """
    from brdfjax.objective import brdf_values, prepare

    if calibration is None:
        from brdfjax.validation import cross_validate

        validation = cross_validate(result.training, result.model, seed=seed,
                                    bounds=result.bounds)
        calibration = calibrate(result.training, validation)
    values = np.asarray(brdf_values(result.vector, prepare(geometry, result.model),
                                    result.model))
    incidence = np.degrees(geometry.theta_i)
    outside = (incidence < calibration.low - 1e-6) | (incidence > calibration.high + 1e-6)
    scale = np.abs(values) + calibration.floor
    bounds = {}
    for name, level in LEVELS.items():
        q = np.where(outside, calibration.factor(level, True), calibration.factor(level, False))
        bounds[f"lo{name}"], bounds[f"hi{name}"] = values - q * scale, values + q * scale
    measured = geometry.brdf if not np.all(np.isnan(geometry.brdf)) else None
    return Prediction(incidence, np.degrees(geometry.theta_r), np.degrees(geometry.phi_r),
                      values, measured=measured, model=result.model.name, **bounds)
