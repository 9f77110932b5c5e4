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

from brdfjax.bounds import Bounds
from brdfjax.cache import stage
from brdfjax.geometry import PAPER_CONSTANTS, Scene, ShadowingConstants, scene
from brdfjax.measurements import Measurements
from brdfjax.model import evaluate_projected, lobe


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


_scene = stage(scene, static_argnames=("constants", "in_plane"))

# Fitted point counts are padded up to a multiple of this with zero-weight copies of the
# first point (a valid geometry, so every value stays finite; zero weight, so E is
# unchanged). Data of nearby sizes then share compiled code, and a sample fitted alone
# runs exactly the arithmetic it runs in a batch (`brdfjax.batch`).
POINT_BUCKET = 64


def bucket(count: int) -> int:
    """``count`` rounded up to a multiple of `POINT_BUCKET`."""
    return POINT_BUCKET * -(-count // POINT_BUCKET)


def pad(values, length: int, fill=None) -> np.ndarray:
    """``values`` (N,) extended to ``length`` with ``fill``, or with its first value."""
    values = np.asarray(values)
    extra = np.full(length - values.size, values[0] if fill is None else fill,
                    dtype=values.dtype)
    return np.concatenate([values, extra])


def padded_scene(geometry: Scene, length: int) -> Scene:
    """A scene extended to ``length`` points with copies of its first point."""
    return Scene(*(pad(x, length) for x in geometry))


def prepare(data: Measurements, constants: ShadowingConstants = PAPER_CONSTANTS,
            dtype=jnp.float64) -> Scene:
    """The scene of a measurement set (one compiled call; in-plane data take the fast path)."""
    angles = (np.asarray(x, dtype=dtype) for x in (data.theta_i, data.theta_r, data.phi_r))
    return _scene(*angles, constants=constants, in_plane=data.in_plane)


projected = stage(evaluate_projected)
projected.__doc__ = "`brdfjax.model.evaluate_projected` as one compiled stage (host calls)."


def targets(data: Measurements) -> tuple[np.ndarray, np.ndarray]:
    """The measured projected BRDF f_r0 cos(tr) and the weights g of Eq. (6) (host arrays)."""
    target = data.brdf * np.cos(data.theta_r)
    weight = np.ones_like(target) if data.weights is None else data.weights
    return target, weight


def relative_error(model_projected, target, weight) -> float:
    """E of Eq. (6) on host arrays (for reporting on any subset of points)."""
    return float(np.sum(weight * (model_projected - target) ** 2) / np.sum(weight * target**2))


def problem(data: Measurements, constants: ShadowingConstants = PAPER_CONSTANTS,
            dtype=jnp.float64, geometry: Scene | None = None) -> Problem:
    """The objective's view of a measurement set: scene, target, normalised weights.

    The arrays are padded to ``bucket(len(data))`` points of zero weight.

    Args:
        data: the measurements.
        constants: the shadowing constants of Eq. (3).
        dtype: float64 for fitting; float32 halves the cost of a population evaluation.
        geometry: the scene of ``data`` if already computed, padded or not.
    """
    points = bucket(len(data))
    geometry = prepare(data, constants, dtype) if geometry is None else geometry
    if geometry.cos_alpha.shape[-1] != points:
        geometry = padded_scene(geometry, points)
    target, weight = targets(data)
    denominator = np.sum(weight * target**2)
    if not denominator > 0:
        raise ValueError(f"{data.name}: every weighted measurement is zero; nothing to fit")
    return Problem(geometry, jnp.asarray(pad(target, points, 0.0), dtype),
                   jnp.asarray(pad(weight / denominator, points, 0.0), dtype))


def residuals(params, prob: Problem) -> jax.Array:
    """Residual vector whose squared norm is E of Eq. (6)."""
    return jnp.sqrt(prob.weight) * (evaluate_projected(params, prob.scene) - prob.target)


def error(params, prob: Problem) -> jax.Array:
    """E of Eq. (6) as a fraction (the paper prints it in percent)."""
    return jnp.sum(prob.weight * (evaluate_projected(params, prob.scene) - prob.target) ** 2)


def linear_coefficients(shape, prob: Problem, bounds: Bounds):
    """The kb and kd within their bounds that minimise E for fixed (kr, a, b).

    f_r cos(tr) = kb s + kd cos(tr), with s the projected `brdfjax.model.lobe`, so E is a
    convex quadratic in (kb, kd). Its minimum over the box is the unconstrained minimum
    when that lies inside, else the best of the four edges, where each is a clipped 1-D
    minimum: exact, without iterating (variable projection, Golub and Pereyra 1973).
    E then follows from six weighted sums, without a second pass over the points.
    The lobe is scaled to a maximum of 1, so that a huge ``exp(b ...)`` balanced by a
    tiny kb (real black coatings) neither overflows nor loses precision in float32.

    Args:
        shape: (kr, a, b).
        prob: the measurement set.
        bounds: the search box (only kb's and kd's bounds are used).

    Returns:
        (kb, kd, E).
    """
    kr, a, b = shape
    c, t, w = prob.scene.cos_theta_r, prob.target, prob.weight
    offset = jnp.maximum(b, 0.0)
    s = lobe(kr, a, b, prob.scene, offset) * c
    peak = jnp.max(jnp.abs(s))
    peak = jnp.where(peak > 0, peak, 1.0)
    s = s / peak  # the model is x s + y c with x = kb exp(offset) peak and y = kd
    sc, st = jnp.stack([w * c, w * t]) @ s  # a matrix product under vmap
    ss, cc = jnp.sum(w * s * s), jnp.sum(w * c * c)
    ct, tt = jnp.sum(w * c * t), jnp.sum(w * t * t)
    to_x = jnp.exp(offset) * peak
    (kb_low, kd_low), (kb_high, kd_high) = bounds.lower[::4], bounds.upper[::4]
    lo, hi = jnp.stack([kb_low * to_x, kd_low]), jnp.stack([kb_high * to_x, kd_high])

    def y_given(x):
        return jnp.clip((ct - sc * x) / cc, lo[1], hi[1])

    def x_given(y):
        return jnp.clip((st - sc * y) / jnp.where(ss > 0, ss, 1.0), lo[0], hi[0])

    det = ss * cc - sc * sc
    solvable = det > 1e-6 * ss * cc
    free = jnp.stack([st * cc - sc * ct, ss * ct - sc * st]) / jnp.where(solvable, det, 1.0)
    candidates = jnp.stack([free, jnp.stack([lo[0], y_given(lo[0])]),
                            jnp.stack([hi[0], y_given(hi[0])]),
                            jnp.stack([x_given(lo[1]), lo[1]]),
                            jnp.stack([x_given(hi[1]), hi[1]])])
    x, y = candidates[:, 0], candidates[:, 1]
    e = tt + ss * x * x + 2 * sc * x * y + cc * y * y - 2 * (st * x + ct * y)
    valid = jnp.arange(5) > 0
    valid = valid.at[0].set(solvable & jnp.all((free >= lo) & (free <= hi)))
    e = jnp.where(valid & ~jnp.isnan(e), e, jnp.inf)
    best = jnp.argmin(e)
    x, y = candidates[best]
    return jnp.clip(x / to_x, kb_low, kb_high), y, jnp.maximum(e[best], 0.0)
