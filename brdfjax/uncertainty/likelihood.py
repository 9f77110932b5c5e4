"""The posterior of a model's parameters: its likelihood, its prior and its coordinates.

Likelihood: Gaussian on the projected BRDF, the quantity Eq. (6) compares,

    y_k = f_r0 cos(tr_k),   m_k = f_r(x) cos(tr_k)                (Eq. 5, 6)
    log L = -1/2 sum_k [(y_k - m_k)^2 / v_k + log(2 pi v_k)]

with ``v_k = (sigma_k cos tr_k)^2`` when the data carry a ``sigma`` column, and otherwise the
goniometer noise model ``v_k = (s_rel m_k)^2 + s_abs^2`` (relative plus absolute: the paper's
instrument quotes under 5 % relative error), whose two scales are inferred with the
parameters, not assumed. The Eq. (6) weights are a choice of fit objective, not a statement
about noise, so the likelihood does not use them (points of weight zero are left out).

Prior, stated plainly: uniform in the coordinates the fit searches, i.e. uniform on the unit
cube of `brdfjax.models.bounds` (log10 of kb, kr, a, kd and asinh b, within the bounds), and, for
the noise model, uniform in log10 s_rel on [1e-4, 1] and in log10 s_abs on
[1e-8, 1] x max|y|; zero outside. The posterior is therefore the likelihood restricted to
that box, and its mode is the maximum-likelihood point.

Sampling coordinates ``x``: the model's P unit-cube coordinates (five for the default
model), then (noise model only) log10 s_rel and log10 s_abs. `log_posterior` is pure JAX;
the Laplace approximation (`brdfjax.uncertainty.laplace`) finds its mode and curvature, and
emcee samples its jitted, walker-vmapped form (`brdfjax.uncertainty.mcmc`).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from brdfjax.data.measurements import Measurements, checked
from brdfjax.fitting.fit import FitResult, split
from brdfjax.fitting.objective import prepare
from brdfjax.models import Model, get
from brdfjax.models.bounds import Bounds, default_bounds, from_unit
from brdfjax.models.paper import FIVE, evaluate_projected

# Log-uniform prior ranges of the noise model's scales: relative 0.01 % to 100 %; absolute
# 1e-8 to 1 times the largest measured projected BRDF.
RELATIVE_NOISE_RANGE = (1e-4, 1.0)
ABSOLUTE_NOISE_RANGE = (1e-8, 1.0)
NOISE_NAMES = ("sigma_rel", "sigma_abs")


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
        return coordinate_names(self.model, self.sigma is not None)


def coordinate_names(model: Model, sigma_given: bool) -> tuple:
    """The sampling coordinates of ``model``'s posterior: its parameters, then the noise
    model's two scales where the data give no sigma."""
    return model.names + (() if sigma_given else NOISE_NAMES)


def build_posterior(data: Measurements, bounds: Bounds | None = None,
                    model: Model = FIVE) -> Posterior:
    """The likelihood's arrays and the prior box for a measurement set.

    Points at ``theta_r = 90 deg`` (projected BRDF 0 whatever the parameters) and points of
    weight zero carry no information and are left out.

    Args:
        data: the measurements (the training subset: held-out incidences already removed).
        bounds: the parameter box (the model's `brdfjax.models.bounds.default_bounds` if None).
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
        fit: a `brdfjax.fitting.fit.FitResult` (its model, bounds and held-out incidences are
            used, and the arguments below ignored) or parameters (P,) of ``model``.
        bounds, model, validate_incidences_deg: as for `brdfjax.fitting.fit.fit`, when ``fit`` is
            bare parameters.

    Returns:
        The `Posterior` of the training points and the starting parameters (P,).
    """
    if isinstance(data, FitResult):
        raise TypeError("the measurements come first, then the fit: "
                        "laplace_approximation(data, result), sample_posterior(data, result)")
    checked(data, "the posterior")
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
