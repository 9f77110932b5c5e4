"""The posterior of a model's parameters: likelihood, prior, and sampling it with emcee.

Likelihood: Gaussian on the projected BRDF, the quantity Eq. (6) compares,

    y_k = f_r0 cos(tr_k),   m_k = f_r(x) cos(tr_k)                (Eq. 5, 6)
    log L = -1/2 sum_k [(y_k - m_k)^2 / v_k + log(2 pi v_k)]

with ``v_k = (sigma_k cos tr_k)^2`` when the data carry a ``sigma`` column, and otherwise the
goniometer noise model ``v_k = (s_rel m_k)^2 + s_abs^2`` (relative plus absolute: the paper's
instrument quotes under 5 % relative error), whose two scales are inferred with the
parameters, not assumed. The Eq. (6) weights are a choice of fit objective, not a statement
about noise, so the likelihood does not use them (points of weight zero are left out).

Prior, stated plainly: uniform in the coordinates the fit searches, i.e. uniform on the unit
cube of `brdfjax.bounds` (log10 of kb, kr, a, kd and asinh b, within the bounds), and, for
the noise model, uniform in log10 s_rel on [1e-4, 1] and in log10 s_abs on
[1e-8, 1] x max|y|; zero outside. The posterior is therefore the likelihood restricted to
that box, and its mode is the maximum-likelihood point.

Sampling coordinates ``x``: the model's P unit-cube coordinates (five for the default
model), then (noise model only) log10 s_rel and log10 s_abs. `log_posterior` is pure JAX; `sample_posterior` hands its jitted,
walker-vmapped form to emcee's ``EnsembleSampler(vectorize=True)``. emcee (and h5py) are
imported only inside `sample_posterior`, so importing this module stays light.

emcee 3.1.6's ``DESnookerMove`` samples the wrong distribution: it projects on
``delta / sqrt(|delta|)`` instead of the unit vector and weights the acceptance by
``(|q - z| / |x - z|)^((d - 1) / 2)`` instead of ``^(d - 1)`` (the snooker update of ter
Braak and Vrugt, Statistics and Computing 18, 435, 2008). On a 5-D Gaussian it gives
variances 25 % too small alone and 3-5 % too small in the 0.8 DE / 0.2 snooker mix, where the
corrected move gives them to 1 % (``benchmarks/bench_uncertainty.py`` repeats the check).
`sample_posterior` uses that mix with the corrected move, `snooker_move`. emcee's main branch
fixed the move in January 2025 (PR #531), in no release yet: `snooker_move` hands over to
emcee's own once the installed emcee is a final release after 3.1.6.
"""

from __future__ import annotations

import textwrap
import time
import warnings
from dataclasses import dataclass, field
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from brdfjax.bounds import Bounds, default_bounds, from_unit
from brdfjax.measurements import Measurements
from brdfjax.model import FIVE, evaluate_projected
from brdfjax.models import Model, get
from brdfjax.objective import prepare, projected
from brdfjax.optional import require

# Log-uniform prior ranges of the noise model's scales: relative 0.01 % to 100 %; absolute
# 1e-8 to 1 times the largest measured projected BRDF.
RELATIVE_NOISE_RANGE = (1e-4, 1.0)
ABSOLUTE_NOISE_RANGE = (1e-8, 1.0)
NOISE_NAMES = ("sigma_rel", "sigma_abs")

# Quantiles of the reported central intervals: 68.27 % (one normal standard deviation each
# side) and 95 %.
INTERVALS = {"ci68": (0.158655, 0.841345), "ci95": (0.025, 0.975)}

# emcee's convergence rule: trust the chain once it is longer than 50 integrated
# autocorrelation times (emcee's ``integrated_time(tol=50)``); burn-in 2 tau, thinning tau/2
# (the emcee documentation's "Autocorrelation analysis" tutorial).
AUTOCORRELATION_LENGTHS = 50

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


class UncertaintyWarning(UserWarning):
    """An uncertainty estimate that should not be trusted as it is (the message says why)."""


class Posterior(NamedTuple):
    """What the log-posterior needs (a pytree of arrays; shapes (N,) unless noted).

    Attributes:
        scene: the model's geometry terms of the N points.
        target: measured projected BRDF ``y = f_r0 cos(tr)``.
        sigma: standard uncertainty of ``y`` (``sigma cos tr``), or None: noise model.
        bounds: the parameter box; its unit cube is the prior's support.
        lower, upper: the prior box of the sampling coordinates, (ndim,).
        model: the `brdfjax.models.Model` (static: no leaves).
    """

    scene: NamedTuple
    target: jax.Array
    sigma: jax.Array | None
    bounds: Bounds
    lower: jax.Array
    upper: jax.Array
    model: Model = FIVE

    @property
    def size(self) -> int:
        """The model's parameter count P (the first P sampling coordinates)."""
        return self.model.size

    @property
    def ndim(self) -> int:
        """P with given sigma, P + 2 with the two noise scales."""
        return int(self.lower.shape[0])

    @property
    def names(self) -> tuple:
        """Names of the sampling coordinates."""
        return self.model.names + (() if self.sigma is not None else NOISE_NAMES)


def build_posterior(data: Measurements, bounds: Bounds | None = None,
                    model: Model = FIVE) -> Posterior:
    """The likelihood's arrays and the prior box for a measurement set.

    Points at ``theta_r = 90 deg`` (projected BRDF 0 whatever the parameters) and points of
    weight zero carry no information and are left out.

    Args:
        data: the measurements (the training subset: held-out incidences already removed).
        bounds: the parameter box (the model's `brdfjax.bounds.default_bounds` if None).
        model: the `brdfjax.models.Model`.

    Returns:
        A `Posterior`.
    """
    bounds = default_bounds(model) if bounds is None else bounds
    keep = np.cos(data.theta_r) > 1e-12
    if data.weights is not None:
        keep &= data.weights > 0
    data = data.select(keep)
    if len(data) == 0:
        raise ValueError(f"{data.name}: no measurement with theta_r < 90 deg and weight > 0")
    cos_r = np.cos(data.theta_r)
    target = data.brdf * cos_r
    lower, upper = np.zeros(model.size), np.ones(model.size)
    sigma = None
    if data.sigma is not None:
        sigma = data.sigma * cos_r
    else:
        scale = max(float(np.max(np.abs(target))), np.finfo(float).tiny)
        lower = np.concatenate([lower, np.log10([RELATIVE_NOISE_RANGE[0],
                                                 ABSOLUTE_NOISE_RANGE[0] * scale])])
        upper = np.concatenate([upper, np.log10([RELATIVE_NOISE_RANGE[1],
                                                 ABSOLUTE_NOISE_RANGE[1] * scale])])
    return Posterior(prepare(data, model), target, sigma, bounds, lower, upper, model)


def training_setup(data: Measurements, fit, bounds: Bounds | None = None,
                   model: str | Model | None = None,
                   validate_incidences_deg=None) -> tuple[Posterior, np.ndarray]:
    """The posterior of the points a fit used, and the fitted parameters to start from.

    Args:
        data: all measurements.
        fit: a `brdfjax.fitting.FitResult` (its model, bounds and held-out incidences are
            used, and the arguments below ignored) or parameters (P,) of ``model``.
        bounds, model, validate_incidences_deg: as for `brdfjax.fitting.fit`, when ``fit`` is
            bare parameters.

    Returns:
        The `Posterior` of the training points and the starting parameters (P,).
    """
    from brdfjax.fitting import FitResult, split

    if isinstance(fit, FitResult):
        bounds, model = fit.bounds, fit.model
        validate_incidences_deg = fit.validation_incidences
        start = fit.vector
    else:
        model = get(model)
        start = np.asarray(fit, dtype=float).reshape(-1)
        if start.shape != (model.size,):
            raise ValueError(f"expected a FitResult or {model.size} parameters of the "
                             f"{model.name} model, got shape {start.shape}")
    train, _ = split(data, validate_incidences_deg)
    return build_posterior(train, bounds, model), start


def fitted_of(fit) -> dict:
    """``fitted`` and ``fitted_loss`` of an `UncertaintyResult` computed from ``fit``: the
    fit's parameters and loss when it is a `brdfjax.fitting.FitResult`, else nothing."""
    from brdfjax.fitting import FitResult

    if not isinstance(fit, FitResult):
        return {}
    return {"fitted": np.asarray(fit.vector, dtype=float), "fitted_loss": fit.loss}


def model_variance(x, model, post: Posterior) -> jax.Array:
    """Variance of each projected measurement: given, or ``(s_rel m)^2 + s_abs^2``."""
    if post.sigma is not None:
        return post.sigma**2
    size = post.size
    return (10.0 ** x[size] * model) ** 2 + (10.0 ** x[size + 1]) ** 2


def log_likelihood(x, post: Posterior) -> jax.Array:
    """Gaussian log-likelihood of the projected BRDF at sampling coordinates ``x`` (ndim,)."""
    model = evaluate_projected(from_unit(x[:post.size], post.bounds), post.scene, post.model)
    variance = model_variance(x, model, post)
    return -0.5 * jnp.sum((post.target - model) ** 2 / variance
                          + jnp.log(2 * jnp.pi * variance))


def log_posterior(x, post: Posterior) -> jax.Array:
    """Unnormalised log-posterior: the log-likelihood inside the prior box, -inf outside."""
    inside = jnp.all((x >= post.lower) & (x <= post.upper))
    value = log_likelihood(jnp.clip(x, post.lower, post.upper), post)
    return jnp.where(inside & jnp.isfinite(value), value, -jnp.inf)


# Plain jit, not a `brdfjax.cache.stage`: emcee calls it thousands of times, and a stage's
# per-call bookkeeping would cost more than the evaluation.
log_posterior_batch = jax.jit(jax.vmap(log_posterior, in_axes=(0, None)))
log_posterior_batch.__doc__ = "`log_posterior` of each row of x (walkers, ndim), jitted."


def physical(x, post: Posterior) -> np.ndarray:
    """Physical parameters (..., P) from sampling coordinates (..., ndim)."""
    return np.asarray(from_unit(np.asarray(x)[..., :post.size], post.bounds))


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
        method: ``laplace`` (`brdfjax.laplace.laplace_approximation`) or ``mcmc``
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
            by default), when a `brdfjax.fitting.FitResult` was given; None otherwise. The
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
        }

    def fit_outside(self, fitted=None) -> list:
        """Names of the parameters whose fitted value lies outside its 95 % interval."""
        fitted = self.fitted if fitted is None else np.asarray(fitted, dtype=float)
        return [name for k, name in enumerate(self.model.names)
                if not self.ci95[k][0] <= fitted[k] <= self.ci95[k][1]]

    def table(self, fitted=None, loss: str | None = None) -> str:
        """A readable table of the intervals, the strongest correlations and any warnings.

        With the ``fitted`` parameters (the optimum of the fit's ``loss``: Eq. 6 by
        default; the fit this result was computed from when not given), a ``fit`` column
        stands beside the posterior ``median``, a fitted value outside its 95 % interval is
        marked, and the table says which of the two to report (`ABOUT`).
        """
        if fitted is None:
            fitted, loss = self.fitted, loss or self.fitted_loss
        loss = loss or "eq6"
        noise = self.noise["model"]
        for name in NOISE_NAMES:
            if name in self.noise:
                interval = self.noise[name]["ci95"]
                noise += (f", {name} {self.noise[name]['median']:.3g} " +
                          ("(at the edge of its prior)" if interval is None else
                           f"[{interval[0]:.3g}, {interval[1]:.3g}]"))
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
        lines = [f"uncertainty ({self.method}, {self.status}); noise: {noise}"]
        lines += [_wrap(note) for note in notes]
        lines.append(f"  {'':>{width}}{fit_header} {'median':>12} {'std':>11}   "
                     f"{'68 % interval':<27} 95 % interval")
        outside = []
        for k, name in enumerate(names):
            fit_cell = ""
            if fitted is not None:
                fit_cell = f" {fitted[k]:{fit_width}.6g}"
                if not self.ci95[k][0] <= fitted[k] <= self.ci95[k][1]:
                    fit_cell += "*"
                    outside.append(name)
            lines.append(f"  {name:>{width}}{fit_cell} {self.median[k]:12.6g} "
                         f"{self.std[k]:11.4g}   {_interval(self.ci68[k]):<27} "
                         f"{_interval(self.ci95[k])}")
        if outside:
            verb = "lies outside its" if len(outside) == 1 else "lie outside their"
            lines.append(_wrap(f"* the fit's {', '.join(outside)} {verb} 95 % interval: "
                               "expected, the interval is about the posterior median, not "
                               f"about {optimum}"))
        size = len(names)
        pairs = sorted(((abs(self.correlation[i, j]), i, j) for i in range(size)
                        for j in range(i + 1, size)), reverse=True)[:3]
        if pairs:
            lines.append("  strongest correlations: " + ", ".join(
                f"{names[i]}-{names[j]} {self.correlation[i, j]:+.3f}" for _, i, j in pairs))
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


def emcee_snooker_is_fixed(version: str) -> bool:
    """Whether emcee ``version`` carries the snooker fix: a final release after 3.1.6.

    Development and pre-release versions count as unfixed (the corrected move is right
    either way; emcee's own is used only where it is known to be).
    """
    import re

    release = re.fullmatch(r"(\d+)\.(\d+)(?:\.(\d+))?(?:\.post\d+)?", version)
    return release is not None and tuple(int(p or 0) for p in release.groups()) > (3, 1, 6)


def snooker_move(gamma: float = 1.7):
    """ter Braak and Vrugt's (2008) snooker update, as emcee's ``DESnookerMove`` should be.

    The ensemble is split in two halves, as for emcee's DE move. For each walker ``x`` of one
    half: pick three distinct walkers ``z, z1, z2`` of the other half (a uniformly random
    ordered triple, so the roles are symmetric), move along the unit vector
    ``u = (x - z) / |x - z|`` by ``gamma u.(z1 - z2)``, and accept with the extra factor
    ``(|q - z| / |x - z|)^(d - 1)``. emcee's move draws the three from three quarters of the
    ensemble instead, which costs two more log-probability calls per step. Vectorised over
    the walkers; ``gamma`` 1.7 as ter Braak and Vrugt recommend. See the module docstring for
    what emcee 3.1.6 does wrong. With an emcee release that carries the fix
    (`emcee_snooker_is_fixed`), emcee's own ``DESnookerMove``.
    """
    import emcee
    from emcee.moves.red_blue import RedBlueMove

    if emcee_snooker_is_fixed(emcee.__version__):
        return emcee.moves.DESnookerMove(gammas=gamma)

    class SnookerMove(RedBlueMove):
        def get_proposal(self, s, c, random):
            others = np.concatenate(c, axis=0)
            count, ndim = s.shape
            triple = np.argsort(random.random_sample((count, len(others))), axis=1)[:, :3]
            z, z1, z2 = (others[triple[:, k]] for k in range(3))
            delta = s - z
            norm = np.sqrt(np.einsum("ij,ij->i", delta, delta))
            unit = delta / norm[:, None]
            step = gamma * np.einsum("ij,ij->i", unit, z1 - z2)
            # q - z = (norm + step) u, so |q - z| / |x - z| = |1 + step / norm|.
            return s + unit * step[:, None], (ndim - 1.0) * np.log(np.abs(1.0 + step / norm))

    return SnookerMove()


def ensemble_sampler(walkers: int, ndim: int, log_probability, **options):
    """emcee's ``EnsembleSampler(vectorize=True)``, taking the log-probability array as it is.

    For a vectorised log-probability emcee looks for blobs and converts the result walker by
    walker in Python, about 50 us per call with 16 walkers, 10 % of a run here. This
    subclass checks the coordinates and the result as emcee does (no infinite or NaN
    coordinate, no NaN log-probability) and returns the array; it supports no blobs.
    """
    import emcee

    class VectorizedSampler(emcee.EnsembleSampler):
        def compute_log_prob(self, coords):
            if not np.all(np.isfinite(coords)):
                raise ValueError("a walker has an infinite or NaN coordinate")
            log_prob = np.array(self.log_prob_fn(coords), dtype=float)  # emcee writes to it
            if np.any(np.isnan(log_prob)):
                raise ValueError("the log-probability is NaN")
            return log_prob, None

    return VectorizedSampler(walkers, ndim, log_probability, vectorize=True, **options)


def draw_inside(rng: np.random.Generator, mean, covariance, lower, upper, count: int,
                rounds: int = 100) -> np.ndarray:
    """Draws (count, D) from a Gaussian truncated to the box [lower, upper], by rejection.

    Draws still outside after ``rounds`` rounds (a Gaussian mostly outside the box, which
    the Laplace approximation has already flagged) are clipped into it.
    """
    draws = np.empty((count, len(mean)))
    missing = np.arange(count)
    for _ in range(rounds):
        if missing.size == 0:
            return draws
        new = rng.multivariate_normal(mean, covariance, size=missing.size, method="eigh",
                                      check_valid="ignore")
        inside = np.all((new >= lower) & (new <= upper), axis=1)
        draws[missing[inside]] = new[inside]
        missing = missing[~inside]
    draws[missing] = np.clip(rng.multivariate_normal(mean, covariance, size=missing.size,
                                                     method="eigh", check_valid="ignore"),
                             lower, upper)
    return draws


def _starting_walkers(start: UncertaintyResult, post: Posterior, walkers: int,
                      rng: np.random.Generator) -> np.ndarray:
    """Walkers drawn from the Laplace Gaussian, each spread capped at a quarter of the box.

    The cap keeps a flat or unidentified direction (an absolute noise scale of zero, a
    singular curvature) from throwing walkers across the whole prior.
    """
    lower, upper = np.asarray(post.lower), np.asarray(post.upper)
    covariance = np.asarray(start.center_covariance, dtype=float)
    scale = np.sqrt(np.clip(np.diag(covariance), 0, None))
    cap = np.minimum(1.0, (upper - lower) / 4 / np.where(scale > 0, scale, np.inf))
    return draw_inside(rng, np.clip(start.center, lower, upper),
                       covariance * np.outer(cap, cap), lower, upper, walkers)


def inline_dispatch() -> None:
    """Run JAX's CPU computations on the calling thread instead of handing them to a worker.

    emcee calls the log-posterior twice per step, each call about 0.1 ms of work. With JAX's
    default asynchronous dispatch every call also waits for a worker thread and back; on
    this 2-core machine that doubled the time per call inside an emcee run (325 against
    164 us, exploratory) and made 32 walkers x 5000 steps take 6-7 s instead of about 4 s
    (``BENCHMARKS.md``, section uncertainty-speed). The setting is process-wide and takes
    effect only before JAX starts its backend (later it changes nothing); ``brdfjax fit``
    makes it. Not for `brdfjax.fit_batch` on several devices, which needs to dispatch to
    every device before it waits for any.
    """
    jax.config.update("jax_cpu_enable_async_dispatch", False)


def autocorrelation_time(chain) -> np.ndarray:
    """emcee's integrated autocorrelation time of each coordinate of a chain (steps, walkers, D).

    Computed with ``tol=0``, so that it never raises or logs: callers judge the length.
    """
    from emcee.autocorr import integrated_time

    return integrated_time(np.asarray(chain), tol=0)


def require_emcee():
    """emcee, or `brdfjax.optional.MissingDependency` saying how to install it."""
    return require("emcee", "mcmc", "MCMC sampling (--uncertainty mcmc)")


def sample_posterior(data: Measurements, fit, *, walkers: int = 32, max_steps: int = 20000,
                     check_every: int = 250, stop_when_converged: bool = True, seed: int = 0,
                     chain_path=None, progress: bool = True,
                     start: UncertaintyResult | None = None, bounds: Bounds | None = None,
                     model: str | Model | None = None,
                     validate_incidences_deg=None) -> UncertaintyResult:
    """Sample the posterior with emcee until the chain is longer than 50 autocorrelation times.

    Walkers start from the Laplace approximation at the fit's optimum (`start`, computed if
    not given). The sampler (``vectorize=True``, moves 0.8 differential evolution and 0.2
    corrected snooker) runs ``check_every`` steps at a time; after each chunk the integrated
    autocorrelation time tau is estimated, and sampling stops once the chain is longer than
    50 max(tau), or at ``max_steps`` with status ``not_converged`` and an
    `UncertaintyWarning`. Burn-in is 2 max(tau), thinning tau/2 (min over coordinates).

    Args:
        data: all measurements.
        fit: a `brdfjax.fitting.FitResult`, or parameters (P,) (see `training_setup`).
        walkers: ensemble size (at least twice the number of sampled coordinates).
        max_steps: cap on the chain length (a resumed chain counts its stored steps).
        check_every: steps between convergence checks.
        stop_when_converged: False runs exactly ``max_steps`` steps (benchmarks).
        seed: seeds the starting walkers and emcee's random state; the same seed gives the
            same chain. A resumed chain continues the random state saved in its file.
        chain_path: an HDF5 file (emcee's ``HDFBackend``) that keeps the chain; if it
            already holds a chain of the same shape, sampling resumes from its last step.
        progress: show a tqdm progress bar.
        start: a Laplace `UncertaintyResult` of the same data to start the walkers from.
        bounds, model, validate_incidences_deg: see `training_setup`.

    Returns:
        An `UncertaintyResult` with method ``mcmc``.
    """
    from tqdm import tqdm

    emcee = require_emcee()
    post, vector = training_setup(data, fit, bounds, model, validate_incidences_deg)
    if walkers < 2 * post.ndim:
        raise ValueError(f"emcee needs at least {2 * post.ndim} walkers for {post.ndim} "
                         f"sampled coordinates, got {walkers}")
    if max_steps < 1 or check_every < 1:
        raise ValueError("max_steps and check_every must be positive")
    tic = time.perf_counter()
    backend = None if chain_path is None else emcee.backends.HDFBackend(str(chain_path))
    resume = backend is not None and backend.initialized and backend.iteration > 0
    if resume and backend.shape != (walkers, post.ndim):
        raise ValueError(f"{chain_path} holds a chain of {backend.shape[0]} walkers x "
                         f"{backend.shape[1]} coordinates, not {walkers} x {post.ndim}; "
                         "use another file or the same settings")
    if backend is not None and not resume:
        backend.reset(walkers, post.ndim)

    on_device = jax.device_put(post)  # once, not at every one of emcee's calls

    def log_probability(x):
        return np.asarray(log_posterior_batch(x, on_device))

    sampler = ensemble_sampler(walkers, post.ndim, log_probability, backend=backend,
                               moves=[(emcee.moves.DEMove(), 0.8), (snooker_move(), 0.2)])
    if resume:
        state = sampler.get_last_sample()
    else:
        if start is None:
            from brdfjax.laplace import laplace_approximation

            start = laplace_approximation(data, fit, bounds=post.bounds, model=post.model,
                                          validate_incidences_deg=validate_incidences_deg, draws=0)
        rng = np.random.default_rng(seed)
        state = _starting_walkers(start, post, walkers, rng)
        sampler.random_state = np.random.RandomState(rng.integers(2**32)).get_state()

    # A resumed chain may be long enough already.
    tau = autocorrelation_time(sampler.get_chain()) if resume else np.full(post.ndim, np.nan)
    with tqdm(total=max_steps, initial=sampler.iteration, disable=not progress,
              desc="emcee", unit="step") as bar:
        while sampler.iteration < max_steps and not (
                stop_when_converged and _converged(tau, sampler.iteration)):
            chunk = min(check_every if stop_when_converged else max_steps,
                        max_steps - sampler.iteration)
            for step in sampler.sample(state, iterations=chunk):
                bar.update(1)
            state = step
            tau = autocorrelation_time(sampler.get_chain())
            bar.set_postfix(tau=f"{np.max(tau):.1f}")
    timings = {"sampling": time.perf_counter() - tic}
    return _mcmc_result(sampler, post, tau, chain_path, timings, fitted_of(fit), vector)


def _converged(tau, steps: int) -> bool:
    return bool(np.all(np.isfinite(tau)) and steps > AUTOCORRELATION_LENGTHS * np.max(tau))


def _mcmc_result(sampler, post: Posterior, tau, chain_path, timings,
                 fitted: dict, vector=None) -> UncertaintyResult:
    """Summaries, diagnostics and warnings of a finished emcee run (``vector``: the fit it
    started from, whose parts of zero weight a sum of models names)."""
    steps, walkers = int(sampler.iteration), int(sampler.nwalkers)  # numpy ints from HDF5
    finite = np.all(np.isfinite(tau))
    burn_in = min(int(2 * np.max(tau)), steps // 2) if finite else steps // 2
    thin = max(1, int(0.5 * np.min(tau))) if finite else 1
    flat = sampler.get_chain(discard=burn_in, thin=thin, flat=True)
    samples = physical(flat, post)
    stats = summarize(samples)
    messages = []
    status = "converged"
    if not _converged(tau, steps):
        status = "not_converged"
        messages.append(
            f"the chain did not converge: {steps} steps is "
            f"{steps / np.max(tau):.3g} autocorrelation times (max tau {np.max(tau):.3g}), "
            f"fewer than {AUTOCORRELATION_LENGTHS}; the intervals are unreliable. Run longer "
            "(raise max_steps, the CLI's --mcmc-steps"
            + (f"; the chain in {chain_path} resumes)" if chain_path else ")"))
    warning = chi2_warning(np.median(flat, axis=0), post)
    if warning:
        messages.append(warning)
    if vector is not None:  # a sum of models with a part switched off
        messages += post.model.idle_parts(vector, post.bounds)
    for text in messages:
        warnings.warn(text, UncertaintyWarning, stacklevel=3)
    noise = noise_summary(post)
    if post.ndim > post.size:
        scales = summarize(flat[:, post.size:])
        noise = noise_summary(post, scales["median"], scales["ci95"])
    ess = walkers * (steps - burn_in) / tau
    acceptance = np.asarray(sampler.acceptance_fraction)
    diagnostics = {
        "walkers": walkers, "steps": steps, "burn_in": burn_in, "thin": thin,
        "samples": int(samples.shape[0]),
        "tau": dict(zip(post.names, map(float, tau))),
        "effective_samples": dict(zip(post.names, map(float, ess))),
        "acceptance_fraction": float(np.mean(acceptance)),
        "acceptance_fraction_min": float(np.min(acceptance)),
        "steps_per_tau": float(steps / np.max(tau)),
        "chain_path": None if chain_path is None else str(chain_path),
    }
    return UncertaintyResult(
        method="mcmc", status=status, warnings=messages, median=stats["median"],
        std=stats["std"], ci68=stats["ci68"], ci95=stats["ci95"],
        covariance=np.atleast_2d(np.cov(samples.T)), correlation=np.atleast_2d(np.corrcoef(flat[:, :post.size].T)),
        samples=samples, noise=noise,
        center=np.mean(flat, axis=0), center_covariance=np.cov(flat.T),
        diagnostics=diagnostics, timings=timings, chain=sampler.get_chain(),
        bounds=post.bounds, model=post.model, **fitted)

