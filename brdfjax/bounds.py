"""Parameter bounds and the maps between physical parameters and the search spaces.

The genetic algorithm searches the unit cube; Levenberg-Marquardt, which has no bounds,
searches an unconstrained ``u`` with ``z = sigmoid(u)``. A unit coordinate ``z`` maps to a
parameter linearly or, for the positive parameters, in log10:

    p = lower + (upper - lower) z            (linear: b)
    p = 10 ** (log10 lower + (log10 upper - log10 lower) z)   (log: kb, kr, a, kd)

Why these defaults: the paper's five samples span kb 0.003-5.7, kr 0.48-16, a 0.45-16,
b -59 to -18, kd 0.07-2.3. Real black coatings push the fit into a degeneracy where
``kb exp(b (1 - cos g)^a)`` trades a tiny kb (down to 1e-12) against a positive b (up to
+35). Searched linearly, such ranges hide the basin from a global search; in log10 it is
found on every real run tried (``FIELD-NOTES.md``). So kb spans 1e-14..1e3 in log10, kr
and a 1e-2..1e2, kd 1e-8..1e2, and b stays linear over -150..80, wide around every value
seen. Users can pass their own.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import numpy as np

from brdfjax.model import PARAMETER_NAMES, array_module


class Bounds(NamedTuple):
    """Lower and upper bounds of (kb, kr, a, b, kd) and which are searched in log10.

    Arrays of shape (5,): NumPy from `make_bounds`, traced inside compiled code, so
    sweeping bounds never recompiles.
    """

    lower: jax.Array
    upper: jax.Array
    log_scale: jax.Array


DEFAULT_RANGES = {"kb": (1e-14, 1e3), "kr": (1e-2, 1e2), "a": (1e-2, 1e2),
                  "b": (-150.0, 80.0), "kd": (1e-8, 1e2)}


def default_bounds() -> Bounds:
    """The default search box (see the module docstring for why)."""
    return make_bounds({})


def make_bounds(ranges: dict, log_scale=(True, True, True, False, True)) -> Bounds:
    """Bounds from ``{name: (low, high)}``; names missing take `DEFAULT_RANGES`."""
    unknown = set(ranges) - set(PARAMETER_NAMES)
    if unknown:
        raise ValueError(f"unknown parameter(s) {sorted(unknown)}; names: {PARAMETER_NAMES}")
    base = {**DEFAULT_RANGES, **ranges}
    lower = np.array([base[k][0] for k in PARAMETER_NAMES], dtype=float)
    upper = np.array([base[k][1] for k in PARAMETER_NAMES], dtype=float)
    log_scale = np.asarray(log_scale, dtype=bool)
    if np.any(lower >= upper):
        bad = PARAMETER_NAMES[int(np.argmax(lower >= upper))]
        raise ValueError(f"bound of {bad}: lower {base[bad][0]} is not below upper {base[bad][1]}")
    if np.any(log_scale & (lower <= 0)):
        bad = PARAMETER_NAMES[int(np.argmax(log_scale & (lower <= 0)))]
        raise ValueError(f"{bad} is searched in log10, so its lower bound must be positive")
    return Bounds(lower, upper, log_scale)


# The transforms below compute in NumPy when given host arrays (no JAX dispatch: a new
# process compiles nothing for them) and in JAX when given JAX arrays or tracers.


def _transformed(bounds: Bounds, xp):
    lower = xp.where(bounds.log_scale, xp.log10(xp.abs(bounds.lower)), bounds.lower)
    upper = xp.where(bounds.log_scale, xp.log10(xp.abs(bounds.upper)), bounds.upper)
    return lower, upper


def from_unit(z, bounds: Bounds) -> jax.Array:
    """Physical parameters from unit-cube coordinates z (last axis 5)."""
    xp = array_module(z, *bounds)
    lower, upper = _transformed(bounds, xp)
    t = lower + (upper - lower) * z
    return xp.where(bounds.log_scale, 10.0**t, t)


def to_unit(params, bounds: Bounds) -> jax.Array:
    """Unit-cube coordinates of physical parameters (inverse of `from_unit`)."""
    xp = array_module(params, *bounds)
    lower, upper = _transformed(bounds, xp)
    params = xp.asarray(params)
    t = xp.where(bounds.log_scale, xp.log10(xp.where(bounds.log_scale, xp.abs(params), 1.0)),
                 params)
    return (t - lower) / (upper - lower)


def from_free(u, bounds: Bounds) -> jax.Array:
    """Physical parameters from the unconstrained coordinates that LM searches."""
    if array_module(u, *bounds) is np:
        return from_unit(np.exp(-np.logaddexp(0.0, -np.asarray(u))), bounds)
    return from_unit(jax.nn.sigmoid(u), bounds)  # finite gradient however large |u|


def to_free(params, bounds: Bounds, margin: float = 1e-9) -> jax.Array:
    """Unconstrained coordinates of physical parameters, clipped just inside the box."""
    xp = array_module(params, *bounds)
    z = xp.clip(to_unit(params, bounds), margin, 1 - margin)
    return xp.log(z) - xp.log1p(-z)
