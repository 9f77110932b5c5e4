"""What the fit minimises: the relative squared error of Eq. (6) and its residual vector.

    E(x) = sum g (f_r cos tr - f_r0 cos tr)^2 / sum g (f_r0 cos tr)^2

over the measurement points, with ``g = g1(ti) g2(tr)`` the paper's weights (1 in the paper;
here the data's per-point ``weights`` when given). A `Problem` holds the scene and the
measured projected BRDF with the weights already normalised by the denominator, so that
``E = sum(weight * (model - target)^2)`` and the least-squares residual is
``sqrt(weight) * (model - target)``. All arrays are traced: refitting same-shaped data with
other values never recompiles.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from brdfjax.geometry import PAPER_CONSTANTS, Scene, ShadowingConstants, scene
from brdfjax.measurements import Measurements
from brdfjax.model import evaluate_projected


class Problem(NamedTuple):
    """A measurement set ready for the objective (a pytree of arrays of shape (N,)).

    Attributes:
        scene: the parameter-free geometry terms.
        target: the measured projected BRDF f_r0 cos(tr).
        weight: g / sum(g target^2); zero for padding points.
    """

    scene: Scene
    target: jax.Array
    weight: jax.Array


def problem(data: Measurements, constants: ShadowingConstants = PAPER_CONSTANTS,
            dtype=jnp.float64) -> Problem:
    """Precompute the geometry of a measurement set and normalise its weights."""
    geometry = scene(*(np.asarray(x, dtype=dtype) for x in (data.theta_i, data.theta_r,
                                                              data.phi_r)),
                     constants, in_plane=data.in_plane)
    target = np.asarray(data.brdf * np.cos(data.theta_r), dtype=dtype)
    weight = np.ones_like(target) if data.weights is None else np.asarray(data.weights, dtype)
    denominator = np.sum(weight * target**2)
    if not denominator > 0:
        raise ValueError(f"{data.name}: every weighted measurement is zero; nothing to fit")
    return Problem(geometry, jnp.asarray(target), jnp.asarray(weight / denominator))


def residuals(params, prob: Problem) -> jax.Array:
    """Residual vector whose squared norm is E of Eq. (6)."""
    return jnp.sqrt(prob.weight) * (evaluate_projected(params, prob.scene) - prob.target)


def error(params, prob: Problem) -> jax.Array:
    """E of Eq. (6) as a fraction (the paper prints it in percent)."""
    return jnp.sum(prob.weight * (evaluate_projected(params, prob.scene) - prob.target) ** 2)
