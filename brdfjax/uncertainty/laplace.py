"""Laplace approximation of the posterior at its mode: error bars in milliseconds.

The posterior of `brdfjax.uncertainty.likelihood` (Gaussian likelihood on the projected BRDF, prior
uniform in the fit's unit-cube coordinates ``z``: for the default model log10 of kb, kr, a,
kd and asinh b) is
approximated by a Gaussian at its mode ``x*`` whose inverse covariance is the expected
Fisher information of the Gaussian likelihood,

    F = (J_m / sqrt(v))^T (J_m / sqrt(v)) + 1/2 J_logv^T J_logv,

with ``J_m = dm/dx`` and ``J_logv = d log v / dx`` computed by ``jax.jacfwd`` in the
sampling coordinates ``x`` (``z``, then log10 of the noise scales when they are inferred).
With given sigma ``v`` does not depend on ``x`` and ``F = J^T J`` of the weighted residuals
``(m - y) / sigma``: the usual ``cov = (J^T J)^{-1}``, unscaled because sigma is taken as
stated (a chi-square per degree of freedom far from 1 is reported as a warning).

The physical covariance is linearised, ``C_p = D C_z D`` with ``D = diag(dp/dz)``; the
intervals are Gaussian quantiles in ``z`` mapped through the bounds' transform, so they are
asymmetric for the log10 parameters (and positive) and for asinh b.

The mode is not the fit's optimum: Eq. (6) weights every point alike, the likelihood by
``1 / v``. So the fit's parameters are polished again with Levenberg-Marquardt
(`brdfjax.fitting.polish.polish`) on the residuals ``(m - y) / sqrt(v)``. For the noise model the
scales are first estimated at the fit (maximum likelihood at fixed parameters, by Fisher
scoring), the parameters polished with those variances, and both repeated once.

The approximation says when it should not be trusted (status ``untrustworthy``, with the
reasons and a pointer to `brdfjax.uncertainty.mcmc.sample_posterior`): a parameter at a bound, a
singular or ill-conditioned information matrix, a 95 % interval that the bounds cut, or a
log-posterior that is not the Gaussian's two standard deviations from the mode along one of
its principal axes (`axis_falls`: the check that gives ``ok`` its meaning where parameters
are strongly correlated, which the condition number alone let pass up to 1 - 2e-6). The
short reasons are in ``diagnostics["reasons"]``, each axis' falls in
``diagnostics["axis_falls"]``.
"""

from __future__ import annotations

import time
import warnings
from statistics import NormalDist

import jax
import jax.numpy as jnp
import numpy as np

from brdfjax.cache import stage
from brdfjax.data.measurements import Measurements
from brdfjax.fitting.fit import placed
from brdfjax.fitting.objective import Problem, bucket, pad, padded_scene
from brdfjax.fitting.polish import polish, start_count
from brdfjax.models import Model
from brdfjax.models.bounds import Bounds, from_unit, to_free, to_unit
from brdfjax.models.paper import evaluate_projected
from brdfjax.uncertainty.likelihood import (
    Posterior,
    draw_inside,
    log_posterior_batch,
    model_variance,
    physical,
    training_setup,
)
from brdfjax.uncertainty.result import (
    INTERVALS,
    UncertaintyResult,
    UncertaintyWarning,
    chi2_warning,
    correlation,
    fitted_of,
    noise_summary,
)

# Largest acceptable condition number of the information matrix scaled to unit diagonal
# (its "correlation form", independent of units and of the log/linear scaling). Above it
# some combination of parameters is determined more than 1000 times worse than the
# parameters one at a time (two parameters correlated beyond 1 - 2e-6), and the Gaussian
# would have to hold over a posterior 1000 times longer than it is wide. Measured: 60-800 on
# the white paint and the black coatings at their modes; 1.2e7 in the kb-b degeneracy of
# the AnoBlack coatings' Eq. (6) optimum (kb 1e-14, b +32).
CONDITION_LIMIT = 1e6

# Distance (as a fraction of the range) below which a coordinate counts as at its bound;
# the same threshold as `brdfjax.fit` uses for `FitResult.at_bounds`.
AT_BOUND = 1e-6

# Rounds of (estimate noise scales, polish) for the noise model; one with given sigma.
NOISE_ROUNDS = 2

# `axis_falls`: the log-posterior is compared with the Gaussian's CHECK_STEP standard
# deviations from the mode along each principal axis (2: where the 95 % intervals end), and
# trusted while its fall is within a factor CHECK_TOLERANCE of the Gaussian's (the width
# within a factor 1.4). Measured: within 3 % of the Gaussian's on every axis of the
# synthetic white paint (given sigma); on the in-plane AnoBlack EC1 coating with
# ggx+backscatter, 621 and 1235 times along the kd-kb-beta axis and 0.06 to 1.7 on two
# others, where emcee (20 000 steps, 17 autocorrelation times: not converged) puts kd's
# 95 % interval at [1.4e-8, 3.1e-3] against the Gaussian's [8.4e-5, 0.024].
CHECK_STEP = 2.0
CHECK_TOLERANCE = 2.0
# A parameter names a principal axis (`_axis_names`) when its component is at least this
# share of the axis' largest; at most AXIS_NAMES of them.
AXIS_SHARE = 0.4
AXIS_NAMES = 3

ADVICE = "; use --uncertainty mcmc (brdfjax.sample_posterior) for honest intervals"


def laplace_approximation(data: Measurements, fit, *, draws: int = 2000, seed: int = 0,
                          max_steps: int = 1000, condition_limit: float = CONDITION_LIMIT,
                          bounds: Bounds | None = None, model: str | Model | None = None,
                          validate_incidences_deg=None) -> UncertaintyResult:
    """Gaussian approximation of the posterior at its mode, from the Jacobian of the model.

    Polishes the fit to the posterior mode (`find_mode`), inverts the Fisher information
    there (`fisher_information`), and reports medians, standard deviations, 68 % and 95 %
    intervals and correlations; status ``untrustworthy`` with an `UncertaintyWarning` per
    reason when the Gaussian cannot be trusted (see the module docstring).

    Args:
        data: all measurements.
        fit: a `brdfjax.fitting.fit.FitResult`, or parameters (P,) of ``model`` (see
            `brdfjax.uncertainty.likelihood.training_setup`).
        draws: parameter draws kept in ``samples`` (for bands): from the Gaussian truncated
            to the bounds, where the prior is zero.
        seed: seeds the draws.
        max_steps: Levenberg-Marquardt step cap when polishing to the mode (the fit's
            default, so that the hybrid `brdfjax.fit` and this share one compiled LM).
        condition_limit: largest acceptable condition number (see `CONDITION_LIMIT`).
        bounds, model, validate_incidences_deg: as for `brdfjax.fitting.fit.fit` when ``fit`` is
            bare parameters.

    Returns:
        An `~brdfjax.uncertainty.result.UncertaintyResult` with method ``laplace``.
    """
    tic = time.perf_counter()
    post, start = training_setup(data, fit, bounds, model, validate_incidences_deg)
    size = post.size
    center = find_mode(post, start, max_steps)
    information, slope = (np.asarray(v) for v in _curvature(center, post))
    covariance, condition = _invert(information)
    std = np.sqrt(np.diag(covariance))
    ends = {name: center[:, None] + std[:, None] * np.array(
                [NormalDist().inv_cdf(p) for p in levels])
            for name, levels in INTERVALS.items()}
    inside = np.all((ends["ci95"] >= np.asarray(post.lower)[:, None])
                    & (ends["ci95"] <= np.asarray(post.upper)[:, None]), axis=1)
    at_bounds = [name for name, edge in zip(post.model.names, _at_edge(center[:size], 0, 1))
                 if edge]
    reasons, messages = _flags(at_bounds, condition, condition_limit,
                               {post.model.names[k] for k in np.flatnonzero(~inside[:size])})
    falls, axes = axis_falls(_parameter_density(center, post), center[:size],
                             information[:size, :size])
    if not reasons:  # a mode on a bound or a singular curvature fails the check anyway
        reasons, messages = _gaussian_flags(falls, axes, post.model.names)
    idle = post.model.idle_parts(physical(center[None, :size], post)[0], post.bounds)
    messages += idle  # a sum's part of zero weight: its shape's intervals mean nothing
    reasons += [f"{len(idle)} part(s) of zero weight"] if idle else []
    trustworthy = not reasons
    warning = chi2_warning(center, post)
    if warning:
        messages.append(warning)
    if post.ndim > size:  # flagged, not untrustworthy: the parameters' intervals still hold
        lower, upper = np.asarray(post.lower)[size:], np.asarray(post.upper)[size:]
        for k in np.flatnonzero(_at_edge(center[size:], lower, upper)):
            side = "lower" if center[size + k] < (lower[k] + upper[k]) / 2 else "upper"
            messages.append(f"the noise scale {post.names[size + k]} sits at the {side} edge "
                            f"of its prior ({10.0 ** center[size + k]:.3g}): the data do not "
                            "determine it, and it has no interval")
    for text in messages:
        warnings.warn(text, UncertaintyWarning, stacklevel=2)
    # The prior is zero outside its box: intervals end there, and the draws come from the
    # truncated Gaussian.
    clipped = {name: np.clip(e, np.asarray(post.lower)[:, None], np.asarray(post.upper)[:, None])
               for name, e in ends.items()}
    unit_draws = draw_inside(np.random.default_rng(seed), center[:size],
                             covariance[:size, :size], np.zeros(size), np.ones(size), draws)
    # One transform call for the draws, the median and the four interval ends.
    points = np.concatenate([unit_draws, center[None, :size]]
                            + [clipped[n][:size].T for n in INTERVALS])
    mapped = physical(points, post)
    samples, median = mapped[:draws], mapped[draws]
    ci = mapped[draws + 1:].reshape(2, 2, size)
    noise = noise_summary(post)
    if post.ndim > size:
        # A scale at the edge of its prior (typically no absolute noise at all) has no
        # Gaussian interval: it is reported without one.
        edge = _at_edge(center[size:], np.asarray(post.lower)[size:],
                        np.asarray(post.upper)[size:])
        noise = noise_summary(post, center[size:], np.where(edge[:, None], np.nan,
                                                             clipped["ci95"][size:]))
    physical_covariance = covariance[:size, :size] * np.outer(slope, slope)
    return UncertaintyResult(
        method="laplace", status="ok" if trustworthy else "untrustworthy", warnings=messages,
        median=median, std=np.sqrt(np.diag(physical_covariance)), ci68=ci[0].T, ci95=ci[1].T,
        covariance=physical_covariance, correlation=correlation(covariance[:size, :size]),
        samples=samples, noise=noise, center=center, center_covariance=covariance,
        diagnostics={"condition_number": condition, "points": int(post.target.shape[0]),
                     "at_bounds": at_bounds, "reasons": reasons,
                     "axis_falls": falls.tolist()},
        timings={"total": time.perf_counter() - tic}, bounds=post.bounds, model=post.model,
        **fitted_of(fit))


def find_mode(post: Posterior, start, max_steps: int = 1000) -> np.ndarray:
    """The posterior mode in sampling coordinates (ndim,), polished from ``start`` (P,).

    Levenberg-Marquardt on ``(m - y) / sqrt(v)``; for the noise model, alternated with the
    maximum-likelihood scales (`estimate_noise`). A polish that does not give a finite
    chi-square keeps the previous parameters.

    The polish runs the hybrid fit's compiled LM (`brdfjax.fitting.polish.polish` of as many
    starts as `brdfjax.fitting.polish.polish_population` polishes, on points padded as the
    fit pads them): the start is repeated, and the repeats are skipped; the padding points
    weigh nothing. A first ``brdfjax fit`` so compiles one LM, not two, where the fit ran
    with the default ``starts``, on at most `brdfjax.fitting.fit.DENSE_POINTS` points and in
    one process (otherwise this compiles an LM of its own; the result is the same).
    """
    unit = to_unit(np.asarray(start, dtype=float), post.bounds)
    noise = np.zeros(0)
    points = bucket(post.target.shape[0])
    scene = padded_scene(post.scene, points)
    target = jnp.asarray(pad(post.target, points, 0.0))  # as `problem` makes the fit's
    copies = start_count(post.model, post.bounds)
    for _ in range(1 if post.sigma is not None else NOISE_ROUNDS):
        if post.sigma is None:
            noise = estimate_noise(unit, post)
        free, weight = _weighted_start(unit, noise, post)
        prob = Problem(scene, target, jnp.asarray(pad(weight, points, 0.0)), post.model)
        polished = polish(placed(np.repeat(np.asarray(free), copies, axis=0)), prob,
                          post.bounds, max_steps=max_steps)
        unit = _keep_finite(polished, unit, post.bounds)
    if post.sigma is None:
        noise = estimate_noise(unit, post)
    return np.concatenate([np.asarray(unit), np.asarray(noise)])


@stage
def _weighted_start(unit, noise, post: Posterior) -> tuple[jax.Array, jax.Array]:
    """LM start (1, P) and the weights (N,) that make the residuals ``(m - y) / sqrt(v)``."""
    params = from_unit(unit, post.bounds)
    model = evaluate_projected(params, post.scene, post.model)
    variance = model_variance(jnp.concatenate([unit, noise]), model, post)
    return to_free(params, post.bounds)[None], 1.0 / variance


@stage
def _keep_finite(polished, unit, bounds: Bounds) -> jax.Array:
    """Unit coordinates of the polished parameters if their chi-square is finite, else ``unit``."""
    return jnp.where(jnp.isfinite(polished.errors[0]), to_unit(polished.params[0], bounds), unit)


@stage(static_argnames=("iterations",))
def estimate_noise(unit, post: Posterior, iterations: int = 50) -> jax.Array:
    """Maximum-likelihood noise scales at fixed parameters, as log10 (s_rel, s_abs).

    The squared residuals ``r^2`` have mean ``v = A m^2 + B`` (``A = s_rel^2``,
    ``B = s_abs^2``) and variance ``2 v^2``; Fisher scoring for (A, B) is the weighted
    least-squares fit of ``r^2`` on ``(m^2, 1)`` with weights ``1 / v^2``, iterated, each
    step clipped into the prior's range.

    Args:
        unit: unit-cube parameters (P,).
        post: a `Posterior` of the noise model (no sigma).
        iterations: Fisher-scoring steps (static).

    Returns:
        log10 (s_rel, s_abs), shape (2,).
    """
    model = evaluate_projected(from_unit(unit, post.bounds), post.scene, post.model)
    squared = (post.target - model) ** 2
    basis = jnp.stack([model**2, jnp.ones_like(model)], axis=1)
    low, high = 10.0 ** (2 * post.lower[post.size:]), 10.0 ** (2 * post.upper[post.size:])

    def step(_, variances):
        weight = 1.0 / (basis @ variances) ** 2
        normal = basis.T @ (weight[:, None] * basis)
        return jnp.clip(jnp.linalg.solve(normal, basis.T @ (weight * squared)), low, high)

    guess = 0.5 * jnp.mean(squared) * jnp.array([1.0 / jnp.mean(model**2), 1.0])
    variances = jax.lax.fori_loop(0, iterations, step, jnp.clip(guess, low, high))
    return 0.5 * jnp.log10(variances)


def fisher_information(x, post: Posterior) -> jax.Array:
    """Expected Fisher information (ndim, ndim) of the Gaussian likelihood at ``x``.

    ``F = (J_m / sqrt(v))^T (J_m / sqrt(v)) + 1/2 J_logv^T J_logv``, the Jacobians by
    forward-mode differentiation in the sampling coordinates.
    """

    def moments(x):
        model = evaluate_projected(from_unit(x[:post.size], post.bounds), post.scene, post.model)
        return model, jnp.log(model_variance(x, model, post))

    _, log_variance = moments(x)
    jac_model, jac_log_variance = jax.jacfwd(moments)(x)
    scaled = jac_model * jnp.exp(-0.5 * log_variance)[:, None]
    return scaled.T @ scaled + 0.5 * jac_log_variance.T @ jac_log_variance


@stage
def _curvature(x, post: Posterior) -> tuple[jax.Array, jax.Array]:
    """Fisher information at ``x`` and the slopes dp/dz of the bounds' transform (P,)."""
    size = post.size
    slope = jax.jvp(lambda z: from_unit(z, post.bounds), (x[:size],), (jnp.ones(size),))[1]
    return fisher_information(x, post), slope


def _invert(information) -> tuple[np.ndarray, float]:
    """Covariance and condition number of an information matrix, through its correlation form.

    Scaling to unit diagonal makes the condition number independent of units. Eigenvalues
    are floored at 1e-300 so that a singular matrix gives huge (flagged) variances instead
    of a failure.
    """
    diagonal = np.diag(information)
    if not np.all(np.isfinite(information)) or np.any(diagonal <= 0):
        size = information.shape[0]
        return np.full((size, size), np.inf), np.inf
    scale = 1.0 / np.sqrt(diagonal)
    values, vectors = np.linalg.eigh(information * np.outer(scale, scale))
    condition = float(values[-1] / values[0]) if values[0] > 0 else np.inf
    inverse = (vectors / np.maximum(values, 1e-300)) @ vectors.T
    return inverse * np.outer(scale, scale), condition


def _at_edge(x, lower, upper) -> np.ndarray:
    """Which coordinates lie within `AT_BOUND` (relative to the range) of a box edge."""
    margin = AT_BOUND * (np.asarray(upper) - np.asarray(lower))
    return (x < lower + margin) | (x > upper - margin)


def _flags(at_bounds: list, condition: float, condition_limit: float,
           cut: set) -> tuple[list, list]:
    """Why the Gaussian approximation should not be trusted: short reasons (for the status
    line) and sentences (the warnings), both empty if it can be; ``at_bounds``: the
    parameters whose mode lies on a bound of the box."""
    reasons, messages = [], []
    if at_bounds:
        reasons.append(f"{', '.join(at_bounds)} at a bound")
        messages.append(f"the posterior's mode puts {', '.join(at_bounds)} at a bound of the "
                        "search box (whatever the fit's value): the posterior is cut there "
                        "and is not Gaussian" + ADVICE)
    if not np.isfinite(condition):
        reasons.append("singular curvature")
        messages.append("the curvature (Fisher information) is singular: some parameter "
                        "combination is not determined by the data" + ADVICE)
    elif condition > condition_limit:
        reasons.append(f"ill-conditioned ({condition:.2g})")
        messages.append(f"the curvature is ill-conditioned (condition number {condition:.3g} "
                        f"> {condition_limit:.3g}): parameters are nearly degenerate and "
                        "the Gaussian approximation is unlikely to hold" + ADVICE)
    cut -= set(at_bounds)
    if cut and np.isfinite(condition):
        reasons.append(f"{', '.join(sorted(cut))} not confined by the box")
        messages.append(f"the data do not confine {', '.join(sorted(cut))} within the search "
                        "box (the 95 % interval of the Gaussian reaches past the bounds)"
                        + ADVICE)
    return reasons, messages


def axis_falls(log_density, center, information,
               step: float = CHECK_STEP) -> tuple[np.ndarray, np.ndarray]:
    """How far a log-density falls ``step`` standard deviations of the Gaussian of
    ``information`` away from ``center``, along each principal axis of ``information``,
    as a multiple of the Gaussian's own fall ``step**2 / 2``.

    A Gaussian gives 1 on every axis, each way. A fall above 1 means a posterior narrower
    there than the Gaussian, below 1 a wider one (about ``1 / width**2``), negative a
    higher posterior away from ``center`` (not the mode), infinite one that the prior's
    box cuts. A strong correlation is an axis like any other: where the posterior bends
    along it, the fall says so.

    Args:
        log_density: log-density of points (M, D), as (M,).
        center: the Gaussian's centre (D,).
        information: its inverse covariance (D, D).
        step: the distance, in standard deviations along each axis.

    Returns:
        The falls (D, 2), the axis' two ways (minus, plus), and the axes (D, D), one a
        column, in the order of ``np.linalg.eigh`` (the widest first).
    """
    values, axes = np.linalg.eigh(np.asarray(information, dtype=float))
    offsets = (step / np.sqrt(np.maximum(values, 1e-300)) * axes).T  # one axis a row
    center = np.asarray(center, dtype=float)
    points = np.concatenate([center - offsets, center + offsets, center[None]])
    density = np.asarray(log_density(points), dtype=float)
    with np.errstate(invalid="ignore"):  # -inf - -inf where the centre itself is outside
        falls = (density[-1] - density[:-1]) / (step**2 / 2)
    return falls.reshape(2, -1).T, axes


def _parameter_density(center, post: Posterior):
    """The log-posterior of the model's parameters (M, P) at the noise scales of ``center``
    (the conditional posterior, whose curvature is the information's parameter block)."""
    noise = np.asarray(center)[post.size:]

    def density(points):
        rest = np.broadcast_to(noise, (points.shape[0], noise.size))
        return np.asarray(log_posterior_batch(np.concatenate([points, rest], axis=1), post))

    return density


def _gaussian_flags(falls, axes, names) -> tuple[list, list]:
    """A short reason and a sentence naming the principal axes along which the posterior is
    not the Gaussian (`axis_falls` off 1 by more than a factor `CHECK_TOLERANCE`), the
    worst first; empty lists where there are none."""
    off = np.maximum(falls, 1e-300)  # a negative fall (not the mode) is as far off as can be
    badness = np.max(np.abs(np.log(off)), axis=1)
    failed = [k for k in np.argsort(-badness) if badness[k] > np.log(CHECK_TOLERANCE)]
    if not failed:
        return [], []
    along = [_axis_names(axes[:, k], names) for k in failed]
    more = f" and {len(failed) - 1} more ax" + ("es" if len(failed) > 2 else "is")
    reason = f"not Gaussian along {along[0]}" + (more if len(failed) > 1 else "")
    falls_text = "; ".join(f"{a}: {falls[k][0]:.3g} and {falls[k][1]:.3g}"
                           for a, k in zip(along, failed))
    cut = (" (infinite: the prior's box cuts it there)"
           if np.isinf(falls[failed]).any() else "")
    return [reason], [
        f"the posterior is not Gaussian: {CHECK_STEP:g} standard deviations either side of "
        f"the mode along its principal axes, the log-posterior falls this many times as far "
        f"as the Gaussian's (1 for a Gaussian, trusted within {1 / CHECK_TOLERANCE:g} to "
        f"{CHECK_TOLERANCE:g}){cut}: {falls_text}. Its intervals along them are wrong"
        + ADVICE]


def _axis_names(axis, names) -> str:
    """The parameters that make up a principal axis: those of at least `AXIS_SHARE` of its
    largest component, largest first, at most `AXIS_NAMES`."""
    weight = np.abs(axis)
    order = [k for k in np.argsort(-weight) if weight[k] >= AXIS_SHARE * weight.max()]
    return "-".join(names[k] for k in order[:AXIS_NAMES])
