"""Directional-hemispherical reflectance, Eq. (9): rho(ti) = integral of f_r cos(tr) d(omega).

Models can be sharply peaked: the five-parameter model's Fresnel stand-in
``R0 = exp(b (1 - cos g)^a)`` with the paper's strongly negative ``b`` is a peak only a
degree or two wide around the back-scatter direction ``w_r = w_i`` (with a cusp there when
``a < 1/2``), and a GGX or Beckmann lobe of alpha 0.01 is as narrow around the specular
direction. A grid in (theta_r, phi_r) misses such peaks (a 45 x 90 midpoint grid is wrong in
the third digit for the paper's white paint). So the integral is taken in polar
coordinates centred on the direction where the model peaks (`brdfjax.models.Model.peak`:
``w_i`` for back-scatter, its mirror image for specular): ``beta`` is the angle from that
centre and ``psi`` the azimuth around it. For each ``psi`` the upper hemisphere ends at a
``beta_max(psi)`` known in closed form, so the integrand has no discontinuity; ``beta`` is
graded as ``u^3`` towards the peak and both variables use Gauss-Legendre nodes. The
smallest value of f_r over the nodes is integrated exactly (``pi`` times it) and only the
rest by the nodes, so a constant BRDF ``kd`` gives ``pi kd`` to rounding whatever the
incidence (the nodes alone integrate a constant to ``pi`` within 1e-4 up to 85 deg).
"""

from __future__ import annotations

import warnings

import jax
import jax.numpy as jnp
import numpy as np

from brdfjax.angles import check_radians
from brdfjax.cache import stage
from brdfjax.models import Model, model_for
from brdfjax.models.base import array_module, as_vector
from brdfjax.models.paper import evaluate

# Node counts: the white-paint and polyimide peaks need about 100 radial nodes for 1e-6;
# 160 x 96 converges every paper sample to better than 1e-6 at every incidence, and GGX and
# Beckmann lobes down to alpha 0.01 to 1e-4 (see tests/test_reflectance.py, which doubles
# both).
RADIAL_NODES = 160
AZIMUTH_NODES = 96
GRADING = 3


def _nodes(count: int, grading: int):
    """Gauss-Legendre nodes and weights on [0, 1], graded as u**grading towards 0."""
    x, w = np.polynomial.legendre.leggauss(count)
    u, wu = (x + 1) / 2, w / 2
    return u**grading, wu * grading * u ** (grading - 1)


@stage(static_argnames=("radial_nodes", "azimuth_nodes"))
def _reflectance(params, theta_i, model, radial_nodes, azimuth_nodes):
    """rho at each incidence of the flat ``theta_i`` (M,)."""
    return jax.vmap(lambda t: _rho(as_vector(params), t, model, radial_nodes,
                                   azimuth_nodes))(theta_i)


def hemisphere_nodes(theta_i, radial_nodes: int, azimuth_nodes: int, mirrored: bool):
    """Quadrature nodes (theta_r, phi_r) and weights of ``integral g(w_r) cos(tr) d(omega)``.

    The nodes are polar around ``w_i`` (``mirrored``: around its specular mirror image),
    graded towards that centre; ``sum(weight * g(nodes))`` is the integral for a smooth g
    that is symmetric under ``phi_r -> -phi_r`` (every BRDF here is).
    """
    t, wt = (jnp.asarray(v) for v in _nodes(radial_nodes, GRADING))
    v, wv = (jnp.asarray(x) for x in _nodes(azimuth_nodes, 1))
    psi, w_psi = jnp.pi * v, jnp.pi * wv                # psi in [0, pi]; mirror symmetry
    cos_ti, sin_ti = jnp.cos(theta_i), jnp.sin(theta_i)
    # w_r = cos(beta) w_i + sin(beta) (cos(psi) e1 + sin(psi) e2), e1 = (cos ti, 0, -sin ti),
    # e2 = (0, 1, 0); its z component is >= 0 for beta <= pi/2 - atan2(sin ti cos psi, cos ti).
    beta_max = jnp.pi / 2 - jnp.arctan2(sin_ti * jnp.cos(psi), cos_ti)
    beta = beta_max[:, None] * t[None, :]
    cos_b, sin_b = jnp.cos(beta), jnp.sin(beta)
    cos_psi, sin_psi = jnp.cos(psi)[:, None], jnp.sin(psi)[:, None]
    x = cos_b * sin_ti + sin_b * cos_psi * cos_ti
    y = sin_b * sin_psi
    z = jnp.clip(cos_b * cos_ti - sin_b * cos_psi * sin_ti, 0.0, 1.0)
    theta_r = jnp.arccos(z)
    # Mirroring x (w_i's mirror image is the specular direction) maps the upper hemisphere
    # onto itself, so the same nodes cover it centred on the specular peak.
    phi_r = jnp.arctan2(y, -x if mirrored else x)
    weight = (2 * w_psi * beta_max)[:, None] * wt[None, :] * sin_b * z
    return theta_r, phi_r, weight


def _rho(params, theta_i, model, radial_nodes, azimuth_nodes):
    # A sum of models: each part on nodes around its own peak (reflectance is linear in f_r).
    return sum(_rho_one(part_params, theta_i, part, radial_nodes, azimuth_nodes)
               for part, part_params in model.components(params))


def _rho_one(params, theta_i, model, radial_nodes, azimuth_nodes):
    theta_r, phi_r, weight = hemisphere_nodes(theta_i, radial_nodes, azimuth_nodes,
                                              mirrored=model.peak == "specular")
    f = evaluate(params, model.geometry(theta_i, theta_r, phi_r, in_plane=False), model)
    # A control variate: the constant part integrates to pi exactly, so only f minus its
    # smallest value (the lobe, where the nodes are densest) carries quadrature error.
    floor = jax.lax.stop_gradient(jnp.min(f))
    return jnp.pi * floor + jnp.sum((f - floor) * weight)


def reflectance(params, theta_i, constants=None, radial_nodes: int = RADIAL_NODES,
                azimuth_nodes: int = AZIMUTH_NODES, model: str | Model | None = None,
                warn: bool = True):
    """Directional-hemispherical reflectance rho(theta_i) of Eq. (9).

    Args:
        params: the model's parameters (for the default model a `~brdfjax.models.paper.Params` or
            an array (5,) ordered kb, kr, a, b, kd).
        theta_i: incidence angle(s) in radians, any shape.
        constants: the shadowing constants of Eq. (3), for models with a G term.
        radial_nodes, azimuth_nodes: quadrature sizes (static).
        model: a model name or `brdfjax.models.Model` (as for `brdfjax.models.paper.brdf`:
            None takes the model of a named tuple, else the five-parameter model).
        warn: give an `EnergyWarning` where rho > 1 (False: the caller reports it itself).

    Returns:
        rho with the shape of ``theta_i``. Values above 1 violate energy conservation:
        an `EnergyWarning` says so (where rho is computed, not traced under jit or vmap).
    """
    check_radians(theta_i=theta_i)
    xp = array_module(theta_i)
    theta_i = xp.asarray(theta_i)
    if not xp.issubdtype(theta_i.dtype, xp.floating):  # float32 angles stay float32
        theta_i = theta_i.astype(float)
    flat = _reflectance(params, theta_i.reshape(-1), model_for(params, model, constants),
                        radial_nodes=radial_nodes, azimuth_nodes=azimuth_nodes)
    if warn and not isinstance(flat, jax.core.Tracer) and (text := energy_warning(flat)):
        warnings.warn(text, EnergyWarning, stacklevel=2)
    return flat.reshape(theta_i.shape)


class EnergyWarning(UserWarning):
    """A reflectance above 1: the parameters create energy (`energy_warning`)."""


def energy_warning(rho) -> str | None:
    """A sentence for users when any reflectance exceeds 1, else None."""
    rho = np.asarray(rho)
    if not np.any(rho > 1.0):  # NaN is not above 1
        return None
    return (f"reflectance up to {np.nanmax(rho):.3f} > 1: these parameters create energy "
            "(the surface reflects more than it receives); the fit is not physical")
