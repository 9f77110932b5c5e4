"""The five-parameter BRDF model of Zhang, Wu, Cao and Zhang, Eq. (5).

    f_r = kb * D(alpha) * R0(gamma) * G(ti, tr, pr) / cos(tr) + kd

with the ellipsoidal facet distribution ``D = kr^2 cos a / (1 + (kr^2 - 1) cos^2 a)`` (the
paper's text; Eq. 5 as printed drops the square), the Fresnel stand-in
``R0 = exp(b (1 - cos g)^a)`` and the empirical shadowing factor G of Eq. (3)-(4). The
parameters are always ordered ``kb, kr, a, b, kd``.

`evaluate` takes a precomputed `~brdfjax.geometry.Scene`, so that many parameter vectors
on one measurement set cost only the parameter-dependent part; `brdf` is the convenience
form on angles. Both are pure JAX: jit, vmap and grad pass through.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from brdfjax.angles import check_radians
from brdfjax.geometry import PAPER_CONSTANTS, Scene, ShadowingConstants, scene

PARAMETER_NAMES = ("kb", "kr", "a", "b", "kd")
"""The parameters' names, in the order of every array, file and table."""


class Params(NamedTuple):
    """The five model parameters by name (a pytree: jit, vmap and grad see five leaves)."""

    kb: float
    kr: float
    a: float
    b: float
    kd: float

    @classmethod
    def from_vector(cls, vector) -> Params:
        """Params from an array whose last axis is (kb, kr, a, b, kd)."""
        vector = jnp.asarray(vector)
        if vector.shape[-1:] != (5,):
            raise ValueError(f"expected 5 parameters (kb, kr, a, b, kd), got shape {vector.shape}")
        return cls(*(vector[..., k] for k in range(5)))

    def vector(self) -> jax.Array:
        """The parameters stacked on a last axis of length 5."""
        xp = array_module(*self)
        return xp.stack([xp.asarray(x) for x in self], axis=-1)


# The paper's fitted parameters (Section 4), at 1.06 um, and its error E in percent.
PAPER_SAMPLES = {
    "white_paint": Params(kb=5.708, kr=2.240, a=0.452, b=-58.722, kd=0.220),
    "cement": Params(kb=0.003, kr=2.961, a=15.572, b=-18.301, kd=0.067),
    "khaki_paint": Params(kb=0.0698, kr=0.478, a=0.777, b=-28.935, kd=0.107),
    "forged_steel": Params(kb=0.072, kr=16.125, a=0.959, b=-29.917, kd=0.081),
    "polyimide": Params(kb=5.439, kr=3.257, a=0.495, b=-23.098, kd=2.267),
}
"""The paper's fitted `Params` of its five samples (Section 4, 1.06 um), by sample name."""
PAPER_ERRORS_PERCENT = {"white_paint": 4.17, "cement": 5.98, "khaki_paint": 0.69,
                        "forged_steel": 0.95, "polyimide": 10.1}


def as_vector(params) -> jax.Array:
    if isinstance(params, Params):
        return params.vector()
    return array_module(params).asarray(params)


def array_module(*values):
    """``jax.numpy`` if any value holds a JAX array (or tracer), else ``numpy``.

    Host-side bookkeeping (a parameter vector, a bounds transform) then runs in NumPy: in a
    new process every JAX operation outside a compiled stage costs a compilation.
    """
    return jnp if any(isinstance(v, jax.Array) for v in jax.tree.leaves(values)) else np


def evaluate(params, geometry: Scene) -> jax.Array:
    """f_r of Eq. (5) on a precomputed scene.

    Args:
        params: a `Params` or an array of shape (5,) ordered kb, kr, a, b, kd.
        geometry: the scene of the measurement points.

    Returns:
        The BRDF (1/sr), with the scene's shape.
    """
    kb, kr, a, b, kd = (as_vector(params)[k] for k in range(5))
    return kb * lobe(kr, a, b, geometry) + kd


def lobe(kr, a, b, geometry: Scene, offset=0.0) -> jax.Array:
    """The specular term of Eq. (5) per unit kb, ``D R0 G / cos(tr)``, times ``exp(-offset)``.

    f_r is linear in kb and kd, so a search over (kr, a, b) can solve for them exactly
    (`brdfjax.objective.linear_coefficients`). An ``offset`` of ``max(b, 0)`` keeps the
    lobe finite however large b is (``R0 <= exp(max(b, 0))``).
    """
    kr2 = kr * kr
    cos_alpha = geometry.cos_alpha
    facets = kr2 * cos_alpha / (geometry.sin2_alpha + kr2 * cos_alpha**2)
    # (1 - cos g)^a, exactly 0 at back-scatter with a finite derivative in a there.
    power = jnp.where(geometry.is_backscatter, 0.0,
                      jnp.exp(a * geometry.log_one_minus_cos_gamma))
    return facets * jnp.exp(b * power - offset) * geometry.shadowing


def evaluate_projected(params, geometry: Scene) -> jax.Array:
    """The projected BRDF ``f_r cos(theta_r)`` that Eq. (6) compares with the data."""
    return evaluate(params, geometry) * geometry.cos_theta_r


def brdf(params, theta_i, theta_r, phi_r,
         constants: ShadowingConstants = PAPER_CONSTANTS) -> jax.Array:
    """The BRDF of Eq. (5) at broadcastable angles in radians (``phi_r = pi``: specular side).

    Args:
        params: a `Params` or an array of shape (5,) ordered kb, kr, a, b, kd.
        theta_i, theta_r: zenith angles in [0, pi/2].
        phi_r: reflection azimuth relative to the incident plane.
        constants: the shadowing constants of Eq. (3) (the paper's by default).

    Returns:
        f_r in 1/sr, finite with finite gradients on the whole hemisphere.
    """
    check_radians(("phi_r",), theta_i=theta_i, theta_r=theta_r, phi_r=phi_r)
    return evaluate(params, scene(theta_i, theta_r, phi_r, constants))


def projected_brdf(params, theta_i, theta_r, phi_r,
                   constants: ShadowingConstants = PAPER_CONSTANTS) -> jax.Array:
    """``f_r cos(theta_r)``, the quantity fitted in Eq. (6)."""
    check_radians(("phi_r",), theta_i=theta_i, theta_r=theta_r, phi_r=phi_r)
    return evaluate_projected(params, scene(theta_i, theta_r, phi_r, constants))
