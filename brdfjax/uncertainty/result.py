"""What an uncertainty estimate reports, from either method (Laplace or MCMC): the
`UncertaintyResult`, its summaries and its warnings."""

from __future__ import annotations

import textwrap
from dataclasses import dataclass, field

import numpy as np

from brdfjax.fitting.fit import FitResult
from brdfjax.fitting.objective import projected
from brdfjax.models import Model
from brdfjax.models.bounds import Bounds, default_bounds, from_unit, to_unit
from brdfjax.models.paper import FIVE
from brdfjax.uncertainty.likelihood import NOISE_NAMES, Posterior

# Quantiles of the reported central intervals: 68.27 % (one normal standard deviation each
# side) and 95 %.
INTERVALS = {"ci68": (0.158655, 0.841345), "ci95": (0.025, 0.975)}

# A reduced chi-square outside this range says the given sigma do not describe the scatter.
CHI2_RANGE = (0.5, 2.0)


# Which estimate the intervals are about, and what to report (the table, the JSON and the
# README say the same). Measured in BENCHMARKS.md, section uncertainty-consistency: on
# synthetic white paint the posterior's 95 % intervals held the truth in 91-98 % of 100
# replicates, while intervals about the Eq. (6) fit held it in 17-32 % (least squares'
# textbook interval) or 72-91 % (White's sandwich), and the posterior median was 1.5-3x
# closer to the truth than the fit.
ABOUT = ("the intervals are about the posterior median, whose likelihood weights each point "
         "by 1 / its variance; the fit minimises Eq. (6), which weights every point alike, so "
         "it is another estimate and may lie outside them. Report the posterior median with "
         "its intervals (calibrated on synthetic data: 91-98 % of 95 % intervals hold the "
         "truth); quote the fit and its E to compare with the paper.")


# The explanatory lines of `UncertaintyResult.table` wrap here: the width of its rows.
TABLE_WIDTH = 92

# `UncertaintyResult.brief` names the most correlated pair when its correlation is at least
# this strong (the white paint's a-b, 0.98, and the AnoBlack coating's kd-kb, -0.994).
STRONG_CORRELATION = 0.95

# Distance of a unit-cube coordinate from 0 or 1 below which a value is at its bound (as
# `brdfjax.fitting.fit.FitResult.at_bounds` counts it).
AT_BOUND = 1e-6


class UncertaintyWarning(UserWarning):
    """An uncertainty estimate that should not be trusted as it is (the message says why)."""


def fitted_of(fit) -> dict:
    """``fitted`` and ``fitted_loss`` of an `UncertaintyResult` computed from ``fit``: the
    fit's parameters and loss when it is a `brdfjax.fitting.fit.FitResult`, else nothing."""
    if not isinstance(fit, FitResult):
        return {}
    return {"fitted": np.asarray(fit.vector, dtype=float), "fitted_loss": fit.loss}


def summarize(samples) -> dict:
    """Median, standard deviation and central intervals of each column of ``samples``.

    Returns:
        ``{"median": (D,), "std": (D,), "ci68": (D, 2), "ci95": (D, 2)}``.
    """
    samples = np.asarray(samples, dtype=float)
    summary = {"median": np.median(samples, axis=0), "std": np.std(samples, axis=0, ddof=1)}
    for name, levels in INTERVALS.items():
        summary[name] = np.quantile(samples, levels, axis=0).T
    return summary


def correlation(covariance) -> np.ndarray:
    """The correlation matrix of a covariance matrix."""
    scale = np.sqrt(np.diag(covariance))
    return covariance / np.outer(scale, scale)


def chi2_warning(x, post: Posterior) -> str | None:
    """A sentence when given sigma do not describe the scatter at ``x``, else None."""
    if post.sigma is None:
        return None
    model = np.asarray(projected(from_unit(np.asarray(x)[:post.size], post.bounds), post.scene,
                                 post.model))
    dof = max(post.target.shape[0] - post.size, 1)
    reduced = float(np.sum(((np.asarray(post.target) - model) / np.asarray(post.sigma)) ** 2)) / dof
    if CHI2_RANGE[0] <= reduced <= CHI2_RANGE[1]:
        return None
    return (f"chi-square per degree of freedom is {reduced:.3g}, not near 1: the data's sigma "
            "do not describe the scatter about the model (misfit or mis-stated errors), so "
            "the intervals are " + ("too narrow" if reduced > 1 else "too wide") +
            "; remove the sigma column to infer the noise instead")


@dataclass
class UncertaintyResult:
    """Posterior summaries of a model's parameters, from either method, with the same fields.

    Attributes:
        method: ``laplace`` (`brdfjax.uncertainty.laplace.laplace_approximation`) or ``mcmc``
            (`sample_posterior`).
        status: ``ok`` or ``untrustworthy`` (laplace); ``converged`` or ``not_converged``
            (mcmc).
        warnings: sentences for the user; empty when nothing is wrong.
        median: posterior medians (P,). For Laplace the posterior mode, which is the median
            of its Gaussian in the prior's coordinates.
        std: standard deviations (P,) in physical units (Laplace: linearised).
        ci68, ci95: central 68.27 % and 95 % credible intervals (P, 2).
        covariance: physical covariance (P, P) (Laplace: linearised).
        correlation: correlation (P, P) of the prior's coordinates (log10 kb, kr, a, kd and
            asinh b for the default model); for Laplace it equals the linearised correlation
            of the physical parameters.
        samples: physical parameter draws (S, P): posterior samples, or draws from the
            Laplace Gaussian; bands are computed from them.
        noise: the noise model and, if inferred, each scale's median and 95 % interval.
        center, center_covariance: mean (ndim,) and covariance (ndim, ndim) of the sampling
            coordinates (Laplace: mode and inverse Fisher information).
        diagnostics: method-specific numbers (condition number; tau, ESS, acceptance).
        timings: wall seconds.
        chain: emcee's chain (steps, walkers, ndim) in sampling coordinates; None for Laplace.
        bounds: the parameter box of the prior.
        model: the `brdfjax.models.Model`.
        fitted, fitted_loss: the fit's own parameters (P,) and the loss it minimised (Eq. 6
            by default), when a `brdfjax.fitting.fit.FitResult` was given; None otherwise. The
            intervals are about the posterior, not about these (see `ABOUT`).
    """

    method: str
    status: str
    warnings: list
    median: np.ndarray
    std: np.ndarray
    ci68: np.ndarray
    ci95: np.ndarray
    covariance: np.ndarray
    correlation: np.ndarray
    samples: np.ndarray = field(repr=False)
    noise: dict
    center: np.ndarray = field(repr=False)
    center_covariance: np.ndarray = field(repr=False)
    diagnostics: dict
    timings: dict
    chain: np.ndarray | None = field(repr=False, default=None)
    bounds: Bounds = field(repr=False, default_factory=default_bounds)
    model: Model = field(default=FIVE)
    fitted: np.ndarray | None = field(repr=False, default=None)
    fitted_loss: str = "eq6"

    def summaries(self) -> dict:
        """``{name: {"median", "std", "ci68": [lo, hi], "ci95": [lo, hi]}}`` per parameter."""
        return {name: {"median": float(self.median[k]), "std": float(self.std[k]),
                       "ci68": [float(v) for v in self.ci68[k]],
                       "ci95": [float(v) for v in self.ci95[k]]}
                for k, name in enumerate(self.model.names)}

    def to_dict(self) -> dict:
        """A JSON-ready summary (what ``brdfjax fit --json`` writes under "uncertainty")."""
        return {
            "method": self.method,
            "status": self.status,
            "warnings": list(self.warnings),
            "params": self.summaries(),
            "correlation": {a: {b: float(self.correlation[i, j])
                                for j, b in enumerate(self.model.names)}
                            for i, a in enumerate(self.model.names)},
            "noise": self.noise,
            "diagnostics": self.diagnostics,
            "timings": self.timings,
            "about": ABOUT,
            "fit_outside_ci95": [] if self.fitted is None else self.fit_outside(),
            "fit_note": None if self.fitted is None else self.fit_note(self.fitted,
                                                                      self.fitted_loss),
        }

    def fit_outside(self, fitted=None) -> list:
        """Names of the parameters whose fitted value lies outside its 95 % interval."""
        fitted = self.fitted if fitted is None else np.asarray(fitted, dtype=float)
        return [name for k, name in enumerate(self.model.names)
                if not self.ci95[k][0] <= fitted[k] <= self.ci95[k][1]]

    def fit_at_bounds(self, fitted=None) -> list:
        """Names of the parameters whose fitted value lies on a bound of the box."""
        fitted = self.fitted if fitted is None else np.asarray(fitted, dtype=float)
        unit = np.asarray(to_unit(np.asarray(fitted, dtype=float), self.bounds))
        return [name for name, z in zip(self.model.names, unit)
                if min(z, 1 - z) < AT_BOUND]

    def brief(self, fitted=None, loss: str | None = None, hint: str = "") -> str:
        """The uncertainty in a few lines (what ``brdfjax fit`` prints; `table` has the rest).

        The status and, when not ``ok``/``converged``, its short reasons; each parameter's
        posterior median and 95 % interval; whether the ``fitted`` parameters (the fit this
        result came from when not given) lie inside those intervals, and if not why
        (`fit_note`); the strongest correlation when it is at least `STRONG_CORRELATION`;
        then ``hint``, a last line (the CLI's pointer to the full table).
        """
        fitted, loss = self._fitted_and_loss(fitted, loss)
        reasons = self.diagnostics.get("reasons") or []
        status = self.status + (f": {'; '.join(reasons)}" if reasons else "")
        trusted = self.status in ("ok", "converged")
        lines = [f"uncertainty ({self.method}, {status}); noise: {self._noise_text()}"]
        lines.append(_wrap(("posterior median [95 % interval]" if trusted else
                            "posterior median [95 % interval], not to be trusted as they are")
                           + ": " + ", ".join(
                               f"{name} {self.median[k]:.3g} [{self.ci95[k][0]:.3g}, "
                               f"{self.ci95[k][1]:.3g}]"
                               for k, name in enumerate(self.model.names))))
        if fitted is not None:
            lines.append(_wrap(self.fit_note(fitted, loss)))
        pair = self.strongest_pairs(1)
        if pair and abs(pair[0][2]) >= STRONG_CORRELATION:
            first, second, value = pair[0]
            lines.append(f"  {first} and {second} are determined together (correlation "
                         f"{value:+.3f}): read them as a pair")
        return "\n".join(lines + ([_wrap(hint)] if hint else []))

    def fit_note(self, fitted, loss: str = "eq6") -> str:
        """One sentence: whether the fitted parameters lie inside the 95 % intervals, and if
        not, why the two estimates differ (the likelihood's weights; a fitted parameter
        pressed against its bound)."""
        label = "the Eq. (6) fit" if loss == "eq6" else f"the fit of the {loss} loss"
        outside = self.fit_outside(fitted)
        if not outside:
            return f"{label} lies inside every 95 % interval"
        index = {name: k for k, name in enumerate(self.model.names)}
        pressed = [name for name in self.fit_at_bounds(fitted) if name in outside]
        bound = ("; the fit's " + ", ".join(f"{name} = {fitted[index[name]]:.3g} sits at a "
                                            f"bound, the posterior's at "
                                            f"{self.median[index[name]]:.3g}"
                                            for name in pressed)) if pressed else ""
        weights = ("weights every point alike" if loss == "eq6" else
                   f"minimises the {loss} loss")
        relative = self.noise.get("sigma_rel", {}).get("median")
        noise = f" (relative noise {100 * relative:.2g} %)" if relative else ""
        return (f"{label} lies outside the 95 % intervals of {', '.join(outside)}{bound}: it "
                f"{weights}, the posterior by 1 / variance{noise}: report the posterior's")

    def strongest_pairs(self, count: int = 3) -> list:
        """The ``count`` most correlated pairs of parameters, ``(name, name, correlation)``,
        strongest first."""
        names, size = self.model.names, len(self.model.names)
        pairs = sorted(((abs(self.correlation[i, j]), i, j) for i in range(size)
                        for j in range(i + 1, size)), reverse=True)[:count]
        return [(names[i], names[j], float(self.correlation[i, j])) for _, i, j in pairs]

    def _fitted_and_loss(self, fitted, loss):
        """The fitted parameters and their loss: those given, else this result's own."""
        if fitted is None:
            return self.fitted, loss or self.fitted_loss
        return np.asarray(fitted, dtype=float), loss or "eq6"

    def _noise_text(self) -> str:
        """The noise model and each inferred scale's median and 95 % interval."""
        noise = self.noise["model"]
        for name in NOISE_NAMES:
            if name in self.noise:
                interval = self.noise[name]["ci95"]
                noise += (f", {name} {self.noise[name]['median']:.3g} " +
                          ("(at the edge of its prior)" if interval is None else
                           f"[{interval[0]:.3g}, {interval[1]:.3g}]"))
        return noise

    def table(self, fitted=None, loss: str | None = None) -> str:
        """A readable table of the intervals, the strongest correlations and any warnings.

        With the ``fitted`` parameters (the optimum of the fit's ``loss``: Eq. 6 by
        default; the fit this result was computed from when not given), a ``fit`` column
        stands beside the posterior ``median``, a fitted value outside its 95 % interval is
        marked, and the table says which of the two to report (`ABOUT`).
        """
        fitted, loss = self._fitted_and_loss(fitted, loss)
        loss = loss or "eq6"
        noise = self._noise_text()
        names = self.model.names
        width = max(3, *map(len, names))
        label, optimum = (("Eq. 6", "the Eq. (6) optimum") if loss == "eq6" else
                          (loss, f"the optimum of the {loss} loss"))
        fit_width = max(12, len(f"fit ({label})"))
        fit_header = "" if fitted is None else f" {f'fit ({label})':>{fit_width}}"
        notes = [("median, std and intervals: the posterior's, whose likelihood weights "
                  "each point by 1 / its variance")]
        if fitted is not None:
            notes += [f"fit column: {optimum}"
                      + (", which weights every point alike: another estimate, which need "
                         "not lie inside the intervals" if loss == "eq6" else ""),
                      ("report: the posterior median with its intervals (calibrated: "
                       "BENCHMARKS.md, uncertainty-consistency); the fit and its E to "
                       "compare with the paper")]
        reasons = self.diagnostics.get("reasons") or []
        status = self.status + (f": {'; '.join(reasons)}" if reasons else "")
        lines = [f"uncertainty ({self.method}, {status}); noise: {noise}"]
        lines += [_wrap(note) for note in notes]
        lines.append(f"  {'':>{width}}{fit_header} {'median':>12} {'std':>11}   "
                     f"{'68 % interval':<27} 95 % interval")
        outside, cut = [], self.diagnostics.get("at_bounds", ())
        for k, name in enumerate(names):
            fit_cell = ""
            if fitted is not None:
                fit_cell = f" {fitted[k]:{fit_width}.6g}"
                if not self.ci95[k][0] <= fitted[k] <= self.ci95[k][1]:
                    fit_cell += "*"
                    outside.append(name)
            lines.append(f"  {name:>{width}}{fit_cell} {self.median[k]:12.6g} "
                         f"{self.std[k]:11.4g}   {_interval(self.ci68[k]):<27} "
                         f"{_interval(self.ci95[k])}" + ("  (cut)" if name in cut else ""))
        if cut:
            lines.append(_wrap(f"(cut) {', '.join(cut)}: the mode lies on a bound of the box, "
                               "where the Gaussian is cut; its std (linearised at the bound) "
                               "and its intervals (of the Gaussian in the search's scale) "
                               "describe no posterior: see the warning"))
        if outside:
            verb = "lies outside its" if len(outside) == 1 else "lie outside their"
            lines.append(_wrap(f"* the fit's {', '.join(outside)} {verb} 95 % interval: "
                               "expected, the interval is about the posterior median, not "
                               f"about {optimum}"))
        pairs = self.strongest_pairs()
        if pairs:
            lines.append("  strongest correlations: " + ", ".join(
                f"{a}-{b} {value:+.3f}" for a, b, value in pairs))
        lines += [f"  warning: {text}" for text in self.warnings]
        return "\n".join(lines)


def _wrap(note: str) -> str:
    """An explanatory line of the table, wrapped to its rows' width and indented."""
    return textwrap.fill(note, TABLE_WIDTH, initial_indent="  ", subsequent_indent="    ",
                         break_on_hyphens=False)


def _interval(pair) -> str:
    return f"[{pair[0]:.5g}, {pair[1]:.5g}]"


def noise_summary(post: Posterior, median=None, ci95=None) -> dict:
    """The "noise" entry of an `UncertaintyResult`.

    Args:
        post: the posterior (given sigma, or the noise model).
        median, ci95: for the noise model, log10 of the scales' medians (2,) and their 95 %
            intervals (2, 2); a NaN interval is reported as None (not determined).
    """
    if post.sigma is not None:
        return {"model": "given sigma"}
    summary = {"model": "relative + absolute, inferred"}
    if median is not None:
        for k, name in enumerate(NOISE_NAMES):
            interval = None if np.any(np.isnan(ci95[k])) else [float(10.0**v) for v in ci95[k]]
            summary[name] = {"median": float(10.0 ** median[k]), "ci95": interval}
    return summary
