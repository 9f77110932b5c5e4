"""Evaluating any model of the family on angles: the BRDF and the projected BRDF.

The default model is the paper's five-parameter model of Eq. (5),

    f_r = kb * D(alpha) * R0(gamma) * G(ti, tr, pr) / cos(tr) + kd

(`brdfjax.models.five`); ``model=`` picks another of `brdfjax.models` (``ggx``, ...).
`evaluate` takes a precomputed geometry (`brdfjax.models.Model.geometry`), so that many
parameter vectors on one measurement set cost only the parameter-dependent part; `brdf`
is the convenience form on angles. Both are pure JAX: jit, vmap and grad pass through.
"""

from __future__ import annotations

import jax

from brdfjax.angles import check_radians
from brdfjax.models import model_for
from brdfjax.models.base import array_module, as_vector
from brdfjax.models.five import (
    PAPER_ERRORS_PERCENT,
    PAPER_SAMPLES,
    PARAMETER_NAMES,
    FiveParameter,
    Params,
    lobe,
)
from brdfjax.models.geometry import is_in_plane

__all__ = ["PAPER_ERRORS_PERCENT", "PAPER_SAMPLES", "PARAMETER_NAMES", "Params", "array_module",
           "as_vector", "brdf", "evaluate", "evaluate_projected", "lobe", "projected_brdf"]

FIVE = FiveParameter()


def evaluate(params, geometry, model=FIVE) -> jax.Array:
    """f_r of ``model`` (the five-parameter model by default) on a precomputed geometry.

    Args:
        params: the model's named tuple, or an array whose first axis is its parameters.
        geometry: ``model.geometry(...)`` of the points (for the default model, a
            `brdfjax.models.geometry.Scene`).
        model: a `brdfjax.models.Model`.

    Returns:
        The BRDF (1/sr), with the geometry's shape.
    """
    return model.evaluate(as_vector(params), geometry)


def evaluate_projected(params, geometry, model=FIVE) -> jax.Array:
    """The projected BRDF ``f_r cos(theta_r)`` that Eq. (6) compares with the data."""
    return evaluate(params, geometry, model) * geometry.cos_theta_r


def _geometry(model, theta_i, theta_r, phi_r):
    check_radians(("phi_r",), theta_i=theta_i, theta_r=theta_r, phi_r=phi_r)
    try:
        in_plane = is_in_plane(phi_r)
    except jax.errors.TracerArrayConversionError:  # traced: take the general path
        in_plane = False
    return model.geometry(theta_i, theta_r, phi_r, in_plane)


def brdf(params, theta_i, theta_r, phi_r, constants=None, model=None) -> jax.Array:
    """The BRDF at broadcastable angles in radians (``phi_r = pi``: specular side).

    Args:
        params: the model's parameters (a named tuple or an array; for the default model
            a `Params` or (5,) ordered kb, kr, a, b, kd).
        theta_i, theta_r: zenith angles in [0, pi/2] (radians: 30 is refused, not read as
            1719 degrees).
        phi_r: reflection azimuth relative to the incident plane.
        constants: the shadowing constants of Eq. (3) (the paper's by default), for models
            with a G term.
        model: a model name or `brdfjax.models.Model`; if None, the model whose named tuple
            ``params`` is, and the five-parameter model for an array
            (`brdfjax.models.model_for`, which refuses parameters of another model).

    Returns:
        f_r in 1/sr, finite with finite gradients on the whole hemisphere.
    """
    model = model_for(params, model, constants)
    return evaluate(params, _geometry(model, theta_i, theta_r, phi_r), model)


def projected_brdf(params, theta_i, theta_r, phi_r, constants=None, model=None) -> jax.Array:
    """``f_r cos(theta_r)``, the quantity fitted in Eq. (6) (arguments as `brdf`)."""
    model = model_for(params, model, constants)
    return evaluate_projected(params, _geometry(model, theta_i, theta_r, phi_r), model)
