"""A model's parameter box and the maps between physical parameters and the search spaces.

The box belongs to the models layer: a model's own code (`brdfjax.models.five`'s
Fresnel-free start, a sum's ordering of its lobes) maps parameters into it, and the fitting
stage (`brdfjax.fitting`), which imports the models, searches it.

The genetic algorithm searches the unit cube; Levenberg-Marquardt, which has no bounds,
searches an unconstrained ``u`` with ``z = sigmoid(u)``. A unit coordinate ``z`` maps to a
parameter through a per-parameter scale ``T`` (linear, log10 or asinh):

    p = T^-1(T(lower) + (T(upper) - T(lower)) z)

Each model declares its default ranges and scales, each with its reason
(`brdfjax.models.Model.parameters`). For the five-parameter model: the paper's five
samples span kb 0.003-5.7, kr 0.48-16, a 0.45-16, b -59 to -18, kd 0.07-2.3. Real black
coatings push the fit into a degeneracy where ``kb exp(b (1 - cos g)^a)`` trades a tiny kb
(down to 1e-12) against a positive b (up to +35). Searched linearly, such ranges hide the
basin from a global search; in log10 it is found on every real run tried. So kb spans
1e-14..1e3 in log10, kr and a 1e-2..1e2, kd 1e-8..1e2. b takes either sign and matters
from about 0.1 up (it multiplies ``(1 - cos g)^a <= 1`` in an exponent): it spans
-150..80 on an asinh scale, linear near zero and logarithmic beyond 1. Searched linearly,
|b| < 0.3 would be 0.3 % of the range, and the best fit of cement-like data (a weak
Fresnel term) lies there; on the asinh scale it is 6 %. Users can pass their own ranges
and scales.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import numpy as np

from brdfjax.models import get
from brdfjax.models.base import array_module, limits_text

LINEAR, LOG10, ASINH = 0, 1, 2
# Free coordinates beyond ±36 are on a bound: sigmoid(36) = 1 - 2.3e-16, so the parameter
# is within a few float64 roundings of it (`from_free` clips there).
SATURATED = 36.0
SCALES = {"linear": LINEAR, "log10": LOG10, "asinh": ASINH}


class Bounds(NamedTuple):
    """Lower and upper bounds of a model's parameters and the scale each is searched on.

    Arrays of shape (P,), one entry per parameter of the model: NumPy from `make_bounds`, traced
    inside compiled code, so sweeping bounds never recompiles. ``scale`` holds `LINEAR`, `LOG10` or
    `ASINH`.
    """

    lower: jax.Array
    upper: jax.Array
    scale: jax.Array


def default_bounds(model=None) -> Bounds:
    """The default search box of ``model`` (a name or `brdfjax.models.Model`; the
    five-parameter model if None)."""
    return make_bounds({}, model=model)


def make_bounds(ranges: dict, scales: dict | None = None, model=None) -> Bounds:
    """Bounds from ``{name: (low, high)}`` and ``{name: "linear" | "log10" | "asinh"}``.

    Names missing take the model's defaults (`brdfjax.models.Model.parameters`).
    """
    model = get(model)
    names = model.names
    scales = {**{p.name: p.scale for p in model.parameters}, **(scales or {})}
    unknown = (set(ranges) | set(scales)) - set(names)
    if unknown:
        raise ValueError(f"unknown parameter(s) {', '.join(sorted(unknown))} of the "
                         f"{model.name} model; its parameters: {', '.join(names)}")
    bad_scale = {k: v for k, v in scales.items() if v not in SCALES}
    if bad_scale:
        raise ValueError(f"unknown scale(s) {bad_scale}; scales: {tuple(SCALES)}")
    base = {**{p.name: (p.low, p.high) for p in model.parameters}, **ranges}
    for p in model.parameters:
        low, high = base[p.name]
        if p.limits is not None and (low < p.limits[0] or high > p.limits[1]):
            raise ValueError(f"bound of {p.name}: {low:g} to {high:g} leaves its physical "
                             f"range, {limits_text(p.limits)} ({p.reason}); give a "
                             "range inside it")
    lower = np.array([base[k][0] for k in names], dtype=float)
    upper = np.array([base[k][1] for k in names], dtype=float)
    scale = np.array([SCALES[scales[k]] for k in names])
    if np.any(lower >= upper):
        bad = names[int(np.argmax(lower >= upper))]
        raise ValueError(f"bound of {bad}: lower {base[bad][0]} is not below upper {base[bad][1]}")
    if np.any((scale == LOG10) & (lower <= 0)):
        bad = names[int(np.argmax((scale == LOG10) & (lower <= 0)))]
        raise ValueError(f"{bad} is searched in log10, so its lower bound must be positive")
    return Bounds(lower, upper, scale)


def scale_label(name: str, scale) -> str:
    """How a parameter's search coordinate is labelled: ``log10 kb``, ``asinh b``, ``kr``."""
    prefix = {LINEAR: "", LOG10: "log10 ", ASINH: "asinh "}[int(scale)]
    return prefix + name


# The transforms below compute in NumPy when given host arrays (no JAX dispatch: a new
# process compiles nothing for them) and in JAX when given JAX arrays or tracers.


def scaled(params, bounds: Bounds) -> jax.Array:
    """Each parameter on its search scale: log10, asinh or itself (last axis: the parameters)."""
    xp = array_module(params, *bounds)
    params, log10 = xp.asarray(params), bounds.scale == LOG10
    return xp.where(log10, xp.log10(xp.where(log10, xp.abs(params), 1.0)),
                    xp.where(bounds.scale == ASINH, xp.arcsinh(params), params))


def _unscaled(t, bounds: Bounds, xp):
    return xp.where(bounds.scale == LOG10, 10.0**t,
                    xp.where(bounds.scale == ASINH, xp.sinh(t), t))


def from_unit(z, bounds: Bounds) -> jax.Array:
    """Physical parameters from unit-cube coordinates z (last axis: the parameters)."""
    xp = array_module(z, *bounds)
    lower, upper = scaled(bounds.lower, bounds), scaled(bounds.upper, bounds)
    return _unscaled(lower + (upper - lower) * z, bounds, xp)


def to_unit(params, bounds: Bounds) -> jax.Array:
    """Unit-cube coordinates of physical parameters (inverse of `from_unit`)."""
    lower, upper = scaled(bounds.lower, bounds), scaled(bounds.upper, bounds)
    return (scaled(params, bounds) - lower) / (upper - lower)


def from_free(u, bounds: Bounds) -> jax.Array:
    """Physical parameters from the unconstrained coordinates that LM searches.

    ``u`` is clipped to ±`SATURATED`: beyond, a parameter sits on its bound and its
    derivative is exactly zero, not one so small that a scaled LM step would be enormous
    (`brdfjax.fitting.marquardt`).
    """
    xp = array_module(u, *bounds)
    u = xp.clip(xp.asarray(u), -SATURATED, SATURATED)
    if xp is np:
        return from_unit(np.exp(-np.logaddexp(0.0, -u)), bounds)
    return from_unit(jax.nn.sigmoid(u), bounds)


def to_free(params, bounds: Bounds, margin: float = 1e-9) -> jax.Array:
    """Unconstrained coordinates of physical parameters, clipped just inside the box."""
    xp = array_module(params, *bounds)
    z = xp.clip(to_unit(params, bounds), margin, 1 - margin)
    return xp.log(z) - xp.log1p(-z)
