"""Model choice: every model fitted the same way, cross-validated, and ranked.

`compare_models` fits each model of `brdfjax.models` to all the data and cross-validates
it by incidence (`brdfjax.prediction.cross_validation`), the full fit and the folds in one batched
call. Models are ranked by ``cv_error``, the mean E of Eq. (6) on held-out interior incidences: the
error a user meets at an incidence they did not measure, on one scale for every model. Beside it the
table reports ``cv_error`` of the model corrected by its learned discrepancy
(`brdfjax.prediction.discrepancy`, the prediction ``brdfjax fit --predict`` makes), E on all data,
AIC and BIC, the reflectance of Eq. (9) with the energy flag, and parameters at a bound.

One model is recommended, by the one-standard-error rule (Hastie, Tibshirani and Friedman,
The Elements of Statistical Learning, 2009, section 7.10): of the models whose cv_error is
within one standard error of the lowest, the one with the fewest parameters
(`Comparison.best`, the compact analytic model a ray tracer or a report can use on its
own). Where the book takes the standard error of the lowest model's cv_error, the one here
is that of each model's difference from it, the two models' held-out points paired
(`paired_standard_error`): two or three folds are too few for a spread of their own. With
the learned discrepancy scored, the same model predicts unmeasured geometry unless its
corrected cv_error is measurably above the lowest; then the first model whose corrected
cv_error is within one standard error of the lowest, in the order the rule prefers them
(`Comparison.predictor`).

AIC and BIC use a Gaussian likelihood of the projected BRDF with one variance, estimated
by maximum likelihood from the fit's residuals (``sigma^2 = RSS / n``, counted as one more
parameter): ``AIC = 2 k - 2 log L``, ``BIC = k log n - 2 log L``. They rank models by
in-sample fit penalised for size; ``cv_error`` measures prediction directly and is what the
recommendation uses.
"""

from __future__ import annotations

import os
import shlex
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from brdfjax.data.measurements import Measurements

REFLECTANCE_INCIDENCES = (0.0, 30.0, 60.0)
# The candidates of `compare_models` by default: the six models of the paper's comparison,
# the two-lobe sums that predict the hardest real materials best (a back-scatter lobe for
# the RT-300S black coatings, two GGX lobes for Aeroglaze and anodize), ABg with a diffuse
# floor (stray light) and Ross-Li (remote sensing). backscatter and abg alone are left out:
# a lone back-scatter lobe describes no real surface, and abg is abg+lambert without kd.
DEFAULT_CANDIDATES = ("five", "beckmann", "ggx", "lambert", "rpv", "torrance-sparrow",
                      "ggx+backscatter", "ggx+ggx", "abg+lambert", "ross-li")


@dataclass
class ModelScore:
    """One model's fit, cross-validation and criteria."""

    name: str
    fit: object
    validation: object
    aic: float
    bic: float
    reflectance: dict
    # per interior fold, the terms of the held-out E of Eq. (6) of the model times its
    # learned correction (`brdfjax.prediction.intervals.corrected_cv_terms`; empty where
    # it was not scored)
    corrected_terms: tuple = ()

    @property
    def cv_error(self) -> float:
        return self.validation.cv_error

    @property
    def terms(self) -> tuple:
        """Per interior fold, each held-out point's term of cv_error (`Fold.terms`): two
        models' terms, paired, give the standard error of the difference of their
        cv_errors (`paired_standard_error`)."""
        return tuple(fold.terms for fold in self.validation.interior)

    @property
    def corrected_cv_error(self) -> float:
        """cv_error of the model times its learned correction (NaN where not scored)."""
        from brdfjax.prediction.intervals import cv_error_of

        return cv_error_of(self.corrected_terms)

    def to_dict(self) -> dict:
        return {"params": dict(zip(self.fit.model.names, map(float, self.fit.params))),
                "error": self.fit.error, "cv_error": self.cv_error,
                "cv_by_incidence": self.validation.by_incidence,
                "cv_error_with_discrepancy": self.corrected_cv_error, "aic": self.aic,
                "bic": self.bic, "reflectance": self.reflectance,
                "energy_conserving": all(v <= 1.0 for v in self.reflectance.values()),
                "at_bounds": self.fit.at_bounds, "status": self.fit.status}


@dataclass
class Comparison:
    """Every model's `ModelScore` (``scores``, in the order the models were asked for), and
    their ranking by ``cv_error``; ``path``: the file of the data (`Measurements.path`),
    for the command the recommendation gives."""

    scores: list
    path: str | None = None

    @property
    def ranking(self) -> list:
        """The model names, lowest cv_error first (`ranked`: ties go to fewer parameters)."""
        return ranked({s.name: s.cv_error for s in self.scores})

    @property
    def lowest(self) -> ModelScore:
        """The lowest cv_error (the first of `ranking`)."""
        return self.score(self.ranking[0])

    @property
    def preference(self) -> list:
        """The model names in the order the one-standard-error rule prefers them on
        cv_error: the models whose cv_error exceeds the `lowest` by at most the standard
        error of the difference (`within_one_standard_error`), fewest parameters first (of
        equal counts, the lower cv_error); then the others, as `ranking` has them."""
        near = self.within_one_standard_error()
        close = sorted((n for n in self.ranking if n in near),
                       key=lambda n: size(self.score(n)))
        return close + [n for n in self.ranking if n not in near]

    @property
    def best(self) -> ModelScore:
        """The compact analytic model, by the one-standard-error rule on cv_error: of the
        models within one standard error of the lowest, the one with the fewest parameters
        (the first of `preference`). A model with more parameters, a sum of two lobes most
        often, is chosen only where its cv_error is lower by more than the noise of the
        held-out points can explain; without the rule a sum with a lobe pinned at its
        bounds won on 1.2x (ggx+ggx against ggx on NiTE on invar A)."""
        return self.score(self.preference[0])

    @property
    def lowest_corrected(self) -> ModelScore | None:
        """The lowest cv_error of a model times its learned discrepancy (None where no
        discrepancy was scored)."""
        scored = {s.name: s.corrected_cv_error for s in self.scores
                  if np.isfinite(s.corrected_cv_error)}
        return self.score(ranked(scored)[0]) if scored else None

    @property
    def predictor(self) -> ModelScore:
        """The model to predict with, by the one-standard-error rule. The candidates are
        the models whose corrected cv_error exceeds the `lowest_corrected` by at most the
        standard error of the difference (`within_one_standard_error`, ``corrected``); of
        them, the one that comes first in `preference`, the rule on cv_error alone: `best`
        wherever its corrected cv_error is within the noise of the lowest. Where no
        discrepancy was scored, `best`.

        The corrected cv_errors of the models lie close together (each process takes up
        most of its model's shape error), and the lowest rests on the few dozen points of
        an interior fold or two: the rule keeps to the model recommended on its own unless
        another, corrected, predicts measurably better; where the difference cannot be
        measured (a fold of one point), it keeps to it too. Ranking by the lowest corrected
        cv_error, the rule before the one-standard-error rule, chose on noise (on NiTE on
        invar B, beckmann and rpv on one fold's 30 points; BENCHMARKS.md and
        benchmarks/NOTES.md, predictive-discrepancy)."""
        lowest = self.lowest_corrected
        if lowest is None:
            return self.best
        near = self.within_one_standard_error(corrected=True, unmeasured=True)
        return self.score(next(name for name in self.preference if name in near))

    def score(self, name: str) -> ModelScore:
        """The `ModelScore` of model ``name``."""
        return next(s for s in self.scores if s.name == name)

    def recommendation(self, command=None) -> str:
        """One recommendation, and why: the model to use (`best`); with the learned
        discrepancy scored, a second line: the model to predict with (`predictor`, the same
        model unless its corrected cv_error is measurably above the lowest, and then why)
        and ``command(name)``, the command line that predicts with model ``name`` (by
        default ``brdfjax fit FILE --model NAME --predict GEOMETRY.csv --predict-out
        PRED.csv``, FILE the data's `path`)."""
        best, lowest = self.best, self.lowest
        errors = {s.name: s.cv_error for s in self.scores}
        if best is lowest:
            line = f"recommended: {choice_line(errors, 'held-out error', 'cv_error ')}"
            line += self._lower_than(best, [s for s in self.scores
                                            if s.name not in tied_first(errors)])
        else:
            pinned = len(lowest.fit.at_bounds)
            line = (f"recommended: {best.name}, the fewest parameters ({size(best)}) of the "
                    "models within one standard error of the lowest held-out error (cv_error "
                    f"{100 * best.cv_error:.3g} % against {lowest.name}'s "
                    f"{100 * lowest.cv_error:.3g} %, {size(lowest)} parameters"
                    f"{f', {pinned} at bounds' if pinned else ''}; standard error "
                    f"{100 * self.standard_error(best):.2g} %)")
            line += self._lower_than(best, [])
        predictor = self.predictor
        if np.isfinite(predictor.corrected_cv_error):
            if command is None:
                file = "FILE" if self.path is None else shlex.quote(str(self.path))
                command = (lambda name: f"brdfjax fit {file} --model {name} --predict "
                           "GEOMETRY.csv --predict-out PRED.csv")
            lowest = self.lowest_corrected
            why = ("the lowest" if predictor is lowest else
                   "within one standard error "
                   f"({100 * self.standard_error(predictor, corrected=True):.2g} %) of the "
                   f"lowest, {lowest.name}'s {100 * lowest.corrected_cv_error:.3g} %")
            if predictor is not best:
                why += (f"; {best.name}'s, {100 * best.corrected_cv_error:.3g} %, is more than "
                        "one standard error "
                        f"({100 * self.standard_error(best, corrected=True):.2g} %) above the "
                        if np.isfinite(best.corrected_cv_error) else
                        f"; {best.name}'s was not scored, so not compared with the ")
                why += f"lowest: {best.name} stays the compact analytic model on its own"
            line += (f"\nto predict unmeasured geometry: {predictor.name} with its learned "
                     f"discrepancy (cv_error {100 * predictor.corrected_cv_error:.3g} %, "
                     f"{why}): {command(predictor.name)}")
        return line

    def _lower_than(self, best: ModelScore, others: list) -> str:
        """How much lower ``best``'s cv_error is than the lowest of ``others`` (finite ones),
        and than the paper's model's where that is another and higher."""
        others = [s for s in others if s is not best and np.isfinite(s.cv_error)]
        default = next((s for s in self.scores if s.name == "five"
                        and s.cv_error > best.cv_error), None)
        runner = min(others, key=lambda s: s.cv_error) if others else None
        parts = []
        if runner is not None:
            parts.append(f"{runner.cv_error / best.cv_error:.3g}x lower than {runner.name}'s"
                         + (" (the paper's model)" if runner is default else ""))
        if default is not None and default is not best and default is not runner:
            parts.append(f"{default.cv_error / best.cv_error:.3g}x lower than the paper's "
                         "model")
        return ", " + " and ".join(parts) if parts else ""

    def to_dict(self) -> dict:
        """For JSON: every model's scores, the ranking, ``best`` (the model recommended, the
        compact analytic model) and ``predictor`` (the model to predict with, None where no
        discrepancy was scored), with the standard errors the one-standard-error rule
        compared."""
        predictor, lowest = self.predictor, self.lowest_corrected
        models = {s.name: s.to_dict() for s in self.scores}
        for s in self.scores:
            if np.isfinite(s.cv_error):
                models[s.name]["standard_error_from_lowest"] = self.standard_error(s)
            if lowest is not None and np.isfinite(s.corrected_cv_error):
                models[s.name]["standard_error_from_lowest_with_discrepancy"] = (
                    self.standard_error(s, corrected=True))
        return {"models": models, "ranking": self.ranking, "best": self.best.name,
                "predictor": (predictor.name if np.isfinite(predictor.corrected_cv_error)
                              else None),
                "lowest_with_discrepancy": None if lowest is None else lowest.name}

    def within_one_standard_error(self, corrected: bool = False,
                                  unmeasured: bool = False) -> set:
        """The names of the models whose cv_error (with ``corrected``, corrected cv_error;
        finite) exceeds the `lowest`'s (`lowest_corrected`'s) by at most the
        `standard_error` of the difference. Where that cannot be measured (a fold of one
        point), every model counts as within it with ``unmeasured``, none but those as low
        as the lowest without."""
        lowest = self.lowest_corrected if corrected else self.lowest

        def error(score: ModelScore) -> float:
            return score.corrected_cv_error if corrected else score.cv_error

        def close(score: ModelScore) -> bool:
            if not np.isfinite(error(score)):
                return False
            se = self.standard_error(score, corrected)
            if not np.isfinite(se):
                return unmeasured or error(score) <= error(lowest)
            return bool(error(score) - error(lowest) <= se)

        return {s.name for s in self.scores if close(s)}

    def standard_error(self, score: ModelScore, corrected: bool = False) -> float:
        """The standard error of ``score``'s cv_error minus the `lowest`'s, or with
        ``corrected``, of its corrected cv_error minus the `lowest_corrected`'s
        (`paired_standard_error`; 0 for the lowest itself)."""
        lowest = self.lowest_corrected if corrected else self.lowest
        if score is lowest:
            return 0.0
        terms = (lambda s: s.corrected_terms) if corrected else (lambda s: s.terms)
        return paired_standard_error(terms(score), terms(lowest))

    def table(self, command=None) -> str:
        """The ranked table a user reads (the ``+ discrepancy`` column where it was scored),
        and the `recommendation` (``command``: as it takes it)."""
        corrected = any(np.isfinite(s.corrected_cv_error) for s in self.scores)
        column = f" {'+ discrepancy':>13}" if corrected else ""
        lines = [(f"  {'model':<17} {'cv_error (%)':>12}{column} {'E all (%)':>10} "
                 f"{'AIC':>10} {'BIC':>10}  rho(0/30/60 deg)        at bounds")]
        for name in self.ranking:
            s = next(x for x in self.scores if x.name == name)
            rho = "/".join(f"{v:.3f}" for v in s.reflectance.values())
            flag = " >1!" if any(v > 1 for v in s.reflectance.values()) else ""
            column = f" {100 * s.corrected_cv_error:13.4g}" if corrected else ""
            lines.append(f"  {name:<17} {100 * s.cv_error:12.4g}{column} "
                         f"{100 * s.fit.error:10.4g} {s.aic:10.1f} {s.bic:10.1f}  "
                         f"{rho + flag:<23} {', '.join(s.fit.at_bounds) or '-'}")
        for name in self.ranking:
            s = next(x for x in self.scores if x.name == name)
            params = ", ".join(f"{k}={v:.4g}" for k, v in zip(s.fit.model.names, s.fit.params))
            lines.append(f"  {name}: {params}")
        lines.append(self.recommendation(command))
        return "\n".join(lines)


# cv_errors within this relative (and absolute) distance of the lowest are a tie, which the
# model with fewer parameters wins: a sum whose second part is switched off (weight at its
# lower bound) predicts as its first part alone, to the last digits its own search reaches
# (ggx+backscatter, its lobe off, against ggx on NiTE on steel A: cv_error 0.728579 against
# 0.728644 %, 9e-5 apart), and noise-free data of one model are predicted to rounding by any
# sum containing it. 0.1 % is far below what held-out incidences can tell apart: one model's
# cv_error differs from fold to fold by tens of per cent.
TIE_RELATIVE = 1e-3
TIE_ABSOLUTE = 1e-12


def ranked(cv_errors: dict) -> list:
    """Model names by cv_error, lowest first; a NaN (no interior fold) ranks last. Ties go
    to fewer parameters all the way down, not only at the top: models tied with the lowest
    (`tied_first`) come first, fewest parameters first, then the same with the lowest of
    the rest, and so on. So a sum with its second part switched off follows its first part
    wherever the two rank, below another model too, as the README's rule reads."""
    rest = {n: v for n, v in cv_errors.items() if np.isfinite(v)}
    order = []
    while rest:
        tied = tied_first(rest)
        order += tied
        rest = {n: v for n, v in rest.items() if n not in tied}
    return order + [n for n in cv_errors if n not in order]


def tied_first(cv_errors: dict) -> list:
    """The models tied with the lowest cv_error (within `TIE_RELATIVE`, `TIE_ABSOLUTE`), by
    parameter count, fewest first: the first is the one chosen, the others tie with it."""
    from brdfjax.models import get

    finite = [v for v in cv_errors.values() if np.isfinite(v)]
    if not finite:
        return []
    lowest = min(finite)
    tied = [n for n, v in cv_errors.items() if v <= lowest * (1 + TIE_RELATIVE) + TIE_ABSOLUTE]
    return sorted(tied, key=lambda name: (get(name).size, cv_errors[name]))


def choice_line(cv_errors: dict, what: str, label: str = "") -> str:
    """Why the first of `ranked` was chosen, for a user: ``NAME, the lowest WHAT (LABEL v
    %)``, or where models tie with it, ``NAME, the fewest parameters of A, B, tied within
    0.1 % for the lowest WHAT (LABEL v %)``."""
    tied = tied_first(cv_errors)
    if len(tied) > 1:
        return (f"{tied[0]}, the fewest parameters of {', '.join(tied)}, tied within "
                f"{100 * TIE_RELATIVE:g} % for the lowest {what} "
                f"({label}{100 * min(cv_errors[n] for n in tied):.4g} %)")
    first = ranked(cv_errors)[0]
    return f"{first}, the lowest {what} ({label}{100 * cv_errors[first]:.3g} %)"


def paired_standard_error(a: tuple, b: tuple) -> float:
    """The standard error of the difference of two models' cv_errors, from their held-out
    terms ``a`` and ``b`` (one array per interior fold, in the data's order:
    `ModelScore.terms` or `ModelScore.corrected_terms`), paired point by point (the same
    held-out points).

    The points of a fold lie along the instrument's sweeps, and a model's shape error is
    smooth along them, so neighbouring differences are alike: taken as independent they
    gave standard errors half as large or less on the RT-300S runs (NiTE on invar A,
    ggx+ggx against ggx: 0.019 % against 0.037 %). So each fold's differences are cut into
    about sqrt(n) runs of consecutive points, and the spread of the runs' means gives the
    standard error of the fold's mean (batch means); the folds' means are averaged. With
    two folds of 30 points that is 8 degrees of freedom: the standard error is itself
    uncertain by a quarter, and a gap within that of it is a close call either way.
    Infinite where a fold holds one point or none: there the difference cannot be
    measured."""
    def variance(difference: np.ndarray) -> float:  # of the fold's mean, by batch means
        if difference.size < 2:
            return np.inf
        runs = np.array_split(difference, max(2, int(np.sqrt(difference.size))))
        return float(np.var([run.mean() for run in runs], ddof=1) / len(runs))

    variances = [variance(x - y) for x, y in zip(a, b, strict=True)]
    return float(np.sqrt(np.sum(variances)) / len(variances)) if variances else np.inf


def size(score: ModelScore) -> int:
    """The number of parameters of ``score``'s model."""
    from brdfjax.models import get

    return get(score.name).size


def information_criteria(result, data: Measurements) -> tuple[float, float]:
    """Gaussian AIC and BIC of a fit on all of ``data`` (see the module docstring)."""
    from brdfjax.fitting.objective import brdf_values, prepare

    values = np.asarray(brdf_values(result.vector, prepare(data, result.model), result.model))
    residual = (values - data.brdf) * np.cos(data.theta_r)
    count = residual.size
    variance = max(float(np.mean(residual**2)), np.finfo(float).tiny)
    log_likelihood = -0.5 * count * (np.log(2 * np.pi * variance) + 1)
    size = result.model.size + 1
    return 2 * size - 2 * log_likelihood, size * np.log(count) - 2 * log_likelihood


def compare_models(data: Measurements, models=None, *, seed: int = 0,
                   progress: bool = False, discrepancy: str = "gp") -> Comparison:
    """Fit and cross-validate every model (or those named) on ``data``.

    The models run in threads, one per core: loading a model's compiled code (about 0.1 s
    per stage from the caches) and fitting one overlap (warm ``brdfjax models`` on 120
    points: 3.5-3.9 s against 5.2-5.4 s one after another, 2 cores).

    Args:
        data: the measurements (at least three incidences, for the interior folds).
        models: model names, sums such as ``ggx+backscatter`` included, or one string of
            them separated by commas (`DEFAULT_CANDIDATES` if None).
        seed: the seed of every fit.
        progress: show a progress bar (tqdm) of the models done.
        discrepancy: ``gp`` also scores each model corrected by its learned discrepancy
            (`brdfjax.prediction.intervals.corrected_cv_terms`); ``none`` skips that.

    Returns:
        A `Comparison`.
    """
    from brdfjax.data.measurements import checked
    from brdfjax.models import get
    from brdfjax.models.hemispherical import reflectance
    from brdfjax.prediction.cross_validation import cross_validate
    from brdfjax.prediction.intervals import (
        check_discrepancy,
        compile_corrected_cv_terms,
        corrected_cv_terms,
    )

    def score(name: str) -> ModelScore:
        validation = cross_validate(data, name, seed=seed, full_fit=True)  # one batched call
        result = validation.full
        aic, bic = information_criteria(result, data)
        rho = np.asarray(reflectance(result.params, np.radians(REFLECTANCE_INCIDENCES),
                                     model=result.model, warn=False))  # in the table
        return ModelScore(name, result, validation, aic, bic,
                          {f"{d:g}": float(r) for d, r in zip(REFLECTANCE_INCIDENCES, rho)})

    checked(data, "compare_models")
    check_discrepancy(discrepancy)
    names = models.split(",") if isinstance(models, str) else list(models or DEFAULT_CANDIDATES)
    names = [get(name.strip()).name for name in names]  # an unknown name fails here, first
    with (ThreadPoolExecutor(max_workers=os.cpu_count()) as pool,
          tqdm(total=len(names), desc="models", unit="model", disable=not progress) as bar):
        running = [pool.submit(score, name) for name in names]
        ahead = discrepancy == "gp"  # compiled here while the other models fit
        for job in as_completed(running):
            bar.update()
            if ahead and job.exception() is None:
                compile_corrected_cv_terms(data, job.result().validation, len(names))
                ahead = False
        scores = [job.result() for job in running]
    if discrepancy == "gp":  # every model's processes in one call, in this thread
        terms = corrected_cv_terms(data, [s.validation for s in scores])
        for score_, found in zip(scores, terms):
            score_.corrected_terms = found
    return Comparison(scores, data.path)
