"""Cross-validation by incidence: how well a fit predicts an incidence it never saw.

Users fit a BRDF model to predict the geometry they did not measure, so the honest score
of a model is its error there. `cross_validate` holds out each incidence in turn, fits on
all the others, and scores the held-out incidence alone with E of Eq. (6):

- folds holding out an *interior* incidence (neither the smallest nor the largest)
  measure interpolation; their mean held-out E is ``cv_error``, the score models are
  ranked by (`brdfjax.prediction.selection`);
- folds holding out the smallest or the largest incidence measure extrapolation and are
  reported separately.

All folds are samples of one `brdfjax.fitting.batch.fit_batch` call, not a loop of fits. The
folds fit whatever loss the data's weights carry (`brdfjax.fitting.objective.with_loss`); the
held-out E is always the paper's Eq. (6) with weights 1, so that models and losses compare
on one scale.

Scattered geometry, where incidences hardly repeat (NIST's random-direction PTFE set has
1760 points at 1760 incidences), is grouped into `brdfjax.data.measurements.SCATTERED_BINS` bins of
equal point count along the incidence angle, whose edges are rounded to whole degrees; each bin is a
fold. Data are taken as scattered when they have more distinct incidences than
`brdfjax.data.measurements.MAX_FOLDS`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from brdfjax.data.measurements import DataError, Measurements, incidence_groups
from brdfjax.fitting.batch import fit_batch
from brdfjax.fitting.objective import brdf_values, prepare, targets
from brdfjax.models import get


@dataclass
class Fold:
    """One held-out group of points.

    Attributes:
        label: the held-out incidence (``"30"``) or bin (``"20-35"``), degrees.
        low, high: the incidence range held out, degrees.
        interior: True unless it holds out the smallest or the largest incidences.
        train_error: E of Eq. (6) on the training points.
        terms: each held-out point's term of E of Eq. (6) (`held_out_terms`), whose mean is
            ``held_error``.
        params: the fold's fitted parameters.
        status: the fold fit's status.
        predicted: the fold model's BRDF at the held-out points (for calibration).
        index: positions of the held-out points in the data.
    """

    label: str
    low: float
    high: float
    interior: bool
    train_error: float
    terms: np.ndarray = field(repr=False)
    params: np.ndarray
    status: str
    predicted: np.ndarray = field(repr=False)
    index: np.ndarray = field(repr=False)

    @property
    def held_error(self) -> float:
        """E of Eq. (6) on the held-out points."""
        return float(np.mean(self.terms))

    @property
    def ratio(self) -> float:
        """Held-out E over training E: how much worse the fit does where it did not look."""
        return self.held_error / self.train_error if self.train_error > 0 else np.inf

    def to_dict(self) -> dict:
        return {"held_out": self.label, "interior": self.interior,
                "train_error": self.train_error, "held_error": self.held_error,
                "ratio": self.ratio, "status": self.status}


@dataclass
class CrossValidation:
    """The folds of `cross_validate` and their summary.

    Attributes:
        model: the model's name.
        folds: every `Fold`, in incidence order.
        cv_error: mean held-out E over the interior folds (NaN without interior folds).
        extrapolation_error: mean held-out E over the two end folds.
        full: the fit on all the data (a `brdfjax.fitting.fit.FitResult`), when asked for.
    """

    model: str
    folds: list
    full: object = field(default=None, repr=False)

    @property
    def interior(self) -> list:
        return [f for f in self.folds if f.interior]

    @property
    def cv_error(self) -> float:
        inner = self.interior
        return float(np.mean([f.held_error for f in inner])) if inner else float("nan")

    @property
    def extrapolation_error(self) -> float:
        ends = [f for f in self.folds if not f.interior]
        return float(np.mean([f.held_error for f in ends])) if ends else float("nan")

    @property
    def cv_folds(self) -> str:
        """What ``cv_error`` averages, in words: on a 4-incidence run only the 2 interior
        incidences are held out for it, so a reader should know how few folds it is."""
        inner = [f.label for f in self.interior]
        ends = [f.label for f in self.folds if not f.interior]
        count = f"{len(inner)} interior fold{'s' if len(inner) != 1 else ''}"
        text = f"mean held-out E of {count} ({', '.join(inner) or 'none'} deg)"
        if ends:
            text += f"; the end incidences {' and '.join(ends)} deg are extrapolation, not in it"
        return text

    @property
    def by_incidence(self) -> dict:
        """Held-out E of every fold by its label."""
        return {f.label: f.held_error for f in self.folds}

    def to_dict(self) -> dict:
        return {"model": self.model, "cv_error": self.cv_error, "cv_folds": self.cv_folds,
                "extrapolation_error": self.extrapolation_error,
                "cv_by_incidence": self.by_incidence,
                "folds": [f.to_dict() for f in self.folds]}

    def table(self) -> str:
        """A readable table of the folds."""
        lines = [(f"cross-validation by incidence ({self.model}): cv_error = "
                 f"{100 * self.cv_error:.4g} % ({self.cv_folds})"),
                 (f"  {'held out (deg)':>15} {'train E (%)':>12} {'held-out E (%)':>15} "
                 f"{'ratio':>8}")]
        for f in self.folds:
            kind = "" if f.interior else "  (extrapolation)"
            lines.append(f"  {f.label:>15} {100 * f.train_error:12.4g} "
                         f"{100 * f.held_error:15.4g} {f.ratio:8.3g}{kind}")
        return "\n".join(lines)


def held_out_error(values, data: Measurements, mask) -> float:
    """E of Eq. (6) of the f_r ``values`` (1/sr, one per point of ``data``) on the points
    ``mask`` alone, unweighted: cv_error's scale, whatever loss the fit minimised."""
    return float(np.mean(held_out_terms(values, data, mask)))


def held_out_terms(values, data: Measurements, mask) -> np.ndarray:
    """The points' terms of `held_out_error` (which is their mean): each point's squared
    error of the projected BRDF over the mean squared projected measurement. Two models'
    terms on the same points, paired, give the standard error of the difference of their
    errors (`brdfjax.prediction.selection.paired_standard_error`)."""
    target, _ = targets(data)
    projected = np.asarray(values)[mask] * np.cos(data.theta_r[mask])
    measured = target[mask]
    difference = projected - measured
    return difference * difference / np.mean(measured * measured)


def cross_validate(data: Measurements, model=None, *, seed: int = 0, bounds=None,
                   full_fit: bool = False, **options) -> CrossValidation:
    """Leave-one-incidence-out cross-validation of a model, all folds in one batched fit.

    Args:
        data: the measurements (at least three incidences or bins, so that one is interior).
        model: a model name or `brdfjax.models.Model` (the five-parameter model if None).
        seed: the seed of every fold's fit.
        bounds: the search box (the model's default if None).
        full_fit: also fit all the data, as one more sample of the same batched call
            (`CrossValidation.full`; the fit `brdfjax.fit` gives).
        **options: fit options of `brdfjax.fitting.batch.fit_batch` (``starts``, ...).

    Returns:
        A `CrossValidation`.
    """
    model = get(model)
    groups = incidence_groups(data)
    if len(groups) < 3:
        raise DataError(f"cross-validation needs at least 3 incidences, the data have "
                        f"{len(groups)}", data.path,
                        hint=("measure more incidences: each is held out in turn (on the "
                              "command line by --cv, --predict, --export, --model auto and "
                              "brdfjax models)"))
    samples = [data.select(~mask) for _, _, _, mask in groups] + ([data] if full_fit else [])
    results = fit_batch(samples, model=model, seed=seed, bounds=bounds, **options)
    geometry = prepare(data, model)
    folds = []
    for k, ((label, low, high, mask), result) in enumerate(zip(groups, results)):
        values = np.asarray(brdf_values(result.vector, geometry, model))
        folds.append(Fold(
            label=label, low=low, high=high, interior=0 < k < len(groups) - 1,
            train_error=result.error,
            terms=held_out_terms(values, data, mask),
            params=result.vector, status=result.status, predicted=values[mask],
            index=np.flatnonzero(mask)))
    return CrossValidation(model.name, folds, results[-1] if full_fit else None)


def fit_per_incidence(data: Measurements, model=None, *, seed: int = 0, bounds=None,
                      **options) -> list:
    """Each incidence (or incidence bin, `incidence_groups`) fitted on its own, all in one
    batched call (`brdfjax.fitting.batch.fit_batch`): the way stray-light engineers fit ABg, one
    (A, B, g) per incidence.

    Args:
        data: the measurements.
        model: a model name or `brdfjax.models.Model` (the five-parameter model if None).
        seed, bounds, **options: as for `brdfjax.fitting.batch.fit_batch`.

    Returns:
        ``[(incidence in degrees, FitResult)]`` in incidence order (a bin: the middle of
        its incidences).
    """
    groups = incidence_groups(data)
    samples = [data.select(mask) for *_, mask in groups]
    results = fit_batch(samples, model=model, seed=seed, bounds=bounds, **options)
    return [((low + high) / 2, result) for (_, low, high, _), result in zip(groups, results)]
