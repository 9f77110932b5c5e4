"""Measurement geometry: everything in the model that does not depend on the parameters.

Conventions (``docs/model.md``): directions point away from the surface, ``z`` is the mean
surface normal, the incident direction is ``w_i = (sin ti, 0, cos ti)`` and the reflected
one ``w_r = (sin tr cos pr, sin tr sin pr, cos tr)``, so ``pr = pi`` is the specular half
of the plane of incidence and ``pr = 0`` the source (back-scatter) side.

With ``s = w_i + w_r`` the facet normal is the half vector ``s / |s|``, ``|s| = 2 cos g``
(Eq. 1) and ``h = |s_xy| = 2 sin(alpha) cos(g)`` is the denominator of all three tangents of
Eq. (4). Of the model of Eq. (5) only ``kb``, ``kr``, ``a``, ``b`` and ``kd`` are free, so
the facet angle ``alpha``, the local incidence angle ``gamma`` and the whole shadowing
factor ``G / cos tr`` are fixed by the geometry. A `Scene` holds them, computed once per
measurement set; evaluating a parameter vector then costs two exponentials per point.

Where the paper's formulas break (``docs/model.md``, "Where the formulas break"):

1. Specular direction: ``h = 0`` and the tangents of Eq. (4) are 0/0. The in-plane limits
   are used: both azimuth cosines squared are 1 and ``tan g' = tan(ti) / 2``.
2. Grazing angles: ``G / cos tr`` is written with the cosines multiplied through, so no
   ``tan`` or division by ``cos tr`` appears; the only remaining 0/0 is the antipodal
   point ``w_r = -w_i`` (``ti = tr = 90 deg``, ``pr = 180``), where the limit along the
   specular direction, 0, is used.
3. Back-scatter: ``1 - cos g`` is computed as ``sin^2 g / (1 + cos g)`` and its logarithm is
   kept finite (`Scene.log_one_minus_cos_gamma`, with `Scene.is_backscatter` marking
   ``1 - cos g = 0``) so that ``(1 - cos g)^a`` has a finite derivative in ``a``.

In the plane of incidence (every ``pr`` is 0 or 180 deg) the same quantities have closed
forms in half-angles, exact to the last bit at the specular point; `scene` takes that fast
path whenever it can tell the data are in-plane.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from brdfjax.angles import check_radians
from brdfjax.models.base import broadcast_angles, safe_divide, safe_sqrt


class ShadowingConstants(NamedTuple):
    """The four empirical constants of the shadowing function G, Eq. (3).

    The defaults are the paper's; they are fixed during a fit, not fitted.
    """

    sigma_sph: float = 0.0136
    sigma_r: float = 0.0141
    u_sph: float = 9.0
    v_sph: float = 1.0


PAPER_CONSTANTS = ShadowingConstants()


class Scene(NamedTuple):
    """Parameter-free terms of Eq. (5) at each measurement point (all arrays, same shape).

    Attributes:
        cos_alpha: cosine of the facet tilt alpha.
        sin2_alpha: sin^2 alpha, computed without cancellation.
        log_one_minus_cos_gamma: log(1 - cos gamma) where it is positive, 0 elsewhere.
        is_backscatter: True where 1 - cos gamma == 0 (w_r equal to w_i).
        shadowing: G / cos(theta_r), finite on the whole hemisphere.
        cos_theta_r: cos(theta_r), the projection factor of Eq. (6).
    """

    cos_alpha: jnp.ndarray
    sin2_alpha: jnp.ndarray
    log_one_minus_cos_gamma: jnp.ndarray
    is_backscatter: jnp.ndarray
    shadowing: jnp.ndarray
    cos_theta_r: jnp.ndarray


def is_in_plane(phi_r) -> bool:
    """True if every azimuth is (numerically) 0 or 180 deg; angles in radians."""
    sin_phi = np.sin(np.asarray(phi_r, dtype=float))
    return bool(np.all(np.abs(sin_phi) < 1e-12))


def scene(theta_i, theta_r, phi_r, constants: ShadowingConstants = PAPER_CONSTANTS,
          in_plane: bool | None = None) -> Scene:
    """Geometry terms of Eq. (1)-(5) for broadcastable angle arrays (radians).

    Args:
        theta_i, theta_r: incidence and reflection zenith angles in [0, pi/2].
        phi_r: reflection azimuth; pi is the specular side.
        constants: the shadowing constants of Eq. (3).
        in_plane: use the exact in-plane formulas (every phi_r is 0 or pi). ``None``
            decides from the values when they are concrete, and takes the general path
            under tracing.

    Returns:
        A `Scene` with the broadcast shape of the inputs.

    Raises:
        ValueError: host angles outside their domain (degrees given for radians, say).
    """
    check_radians(("phi_r",), theta_i=theta_i, theta_r=theta_r, phi_r=phi_r)
    if in_plane is None:
        try:
            in_plane = is_in_plane(phi_r)
        except jax.errors.TracerArrayConversionError:  # traced: take the general path
            in_plane = False
    theta_i, theta_r, phi_r = broadcast_angles(theta_i, theta_r, phi_r)
    terms = _in_plane_terms if in_plane else _general_terms
    return terms(theta_i, theta_r, phi_r, constants)


def _assemble(cos_ti, sin_ti, cos_tr, sin_tr, cos_alpha, sin_alpha, one_minus_cos_gamma,
              azimuth_i2, azimuth_r2, azimuth_ir, damping, constants) -> Scene:
    """Build a `Scene` from the angle terms that both paths compute.

    ``azimuth_i2``, ``azimuth_r2`` and ``azimuth_ir`` are the squares and the absolute
    product of the two azimuth-cosine fractions of Eq. (4); ``damping`` is
    ``1 / (1 + sigma_r tan g')``.
    """
    sigma_sph, _, u_sph, v_sph = constants
    # w(alpha) of Eq. (3), written with sin and cos so it stays finite at alpha = 90 deg.
    tilt = safe_divide(sin_alpha, sin_alpha + v_sph * cos_alpha,
                        sin_alpha + v_sph * cos_alpha > 0, 1.0)
    w = sigma_sph * (1.0 + u_sph * tilt)
    # G / cos tr of Eq. (3)-(4) with cos ti and cos tr multiplied through.
    denom_i = cos_ti**2 + w * sin_ti**2 * azimuth_i2
    denom_r = cos_tr**2 + w * sin_tr**2 * azimuth_r2
    numerator = cos_ti * (cos_ti * cos_tr + w * sin_ti * sin_tr * azimuth_ir * damping)
    denominator = denom_i * denom_r
    shadowing = safe_divide(numerator, denominator, denominator > 0, 0.0)
    positive = one_minus_cos_gamma > 0
    log_x = jnp.log(jnp.where(positive, one_minus_cos_gamma, 1.0))
    return Scene(cos_alpha=cos_alpha, sin2_alpha=sin_alpha**2,
                 log_one_minus_cos_gamma=log_x, is_backscatter=~positive,
                 shadowing=shadowing, cos_theta_r=cos_tr)


def _in_plane_terms(theta_i, theta_r, phi_r, constants):
    """Closed forms in the plane of incidence.

    With ``t = -cos(pr) tr`` the signed reflection angle (positive on the specular side),
    ``gamma = (ti + t) / 2`` and ``alpha = (ti - t) / 2``; the 0/0 of ``tan g'`` cancels
    analytically to ``|sin((3 ti + t) / 4)| / (2 cos((t - ti) / 4) cos gamma)``.
    """
    sigma_r = constants.sigma_r
    signed = -jnp.sign(jnp.cos(phi_r)) * theta_r
    cos_ti, sin_ti = jnp.cos(theta_i), jnp.sin(theta_i)
    cos_tr, sin_tr = jnp.cos(theta_r), jnp.sin(theta_r)
    half_alpha = (theta_i - signed) / 2
    cos_alpha, sin_alpha = jnp.cos(half_alpha), jnp.abs(jnp.sin(half_alpha))
    gamma = (theta_i + signed) / 2
    cos_gamma = jnp.cos(gamma)
    one_minus_cos_gamma = 2.0 * jnp.sin(gamma / 2) ** 2
    # damping = 1 / (1 + sigma_r tan g'), multiplied through by the cos gamma in tan g'.
    scaled = 2.0 * jnp.cos((signed - theta_i) / 4) * cos_gamma
    damping = scaled / (scaled + sigma_r * jnp.abs(jnp.sin((3 * theta_i + signed) / 4)))
    ones = jnp.ones_like(theta_i)
    return _assemble(cos_ti, sin_ti, cos_tr, sin_tr, cos_alpha, sin_alpha,
                     one_minus_cos_gamma, ones, ones, ones, damping, constants)


def _general_terms(theta_i, theta_r, phi_r, constants):
    """Vector forms anywhere on the hemisphere, with the in-plane limits at ``h = 0``."""
    sigma_r = constants.sigma_r
    cos_ti, sin_ti = jnp.cos(theta_i), jnp.sin(theta_i)
    cos_tr, sin_tr = jnp.cos(theta_r), jnp.sin(theta_r)
    cos_pr, sin_pr = jnp.cos(phi_r), jnp.sin(phi_r)
    # s = w_i + w_r and d = w_i - w_r, by components.
    s_x, s_y, s_z = sin_ti + sin_tr * cos_pr, sin_tr * sin_pr, cos_ti + cos_tr
    d_x, d_y, d_z = sin_ti - sin_tr * cos_pr, -s_y, cos_ti - cos_tr
    h = safe_sqrt(s_x**2 + s_y**2)
    s_norm = safe_sqrt(h**2 + s_z**2)                    # 2 cos g
    cos_gamma = s_norm / 2
    sin2_gamma = (d_x**2 + d_y**2 + d_z**2) / 4
    one_minus_cos_gamma = sin2_gamma / (1.0 + cos_gamma)
    nonzero = s_norm > 0                                    # false only at w_r = -w_i
    cos_alpha = safe_divide(s_z, s_norm, nonzero, 0.0)
    sin_alpha = safe_divide(h, s_norm, nonzero, 1.0)
    off_specular = h > 1e-12 * (1.0 + s_norm)
    along_i = s_x                                           # h * cos(azimuth of s - 0)
    along_r = s_x * cos_pr + s_y * sin_pr                   # h * cos(azimuth of s - pr)
    azimuth_i2 = safe_divide(along_i**2, h**2, off_specular, 1.0)
    azimuth_r2 = safe_divide(along_r**2, h**2, off_specular, 1.0)
    azimuth_ir = safe_divide(jnp.abs(along_i * along_r), h**2, off_specular, 1.0)
    # 1 / (1 + sigma_r tan g') = h / (h + sigma_r |cos ti - cos g|); specular limit
    # tan g' = tan(ti) / 2 gives 2 cos ti / (2 cos ti + sigma_r sin ti).
    damping_specular = 2 * cos_ti / (2 * cos_ti + sigma_r * sin_ti)
    damping = safe_divide(h, h + sigma_r * jnp.abs(cos_ti - cos_gamma), off_specular,
                           damping_specular)
    return _assemble(cos_ti, sin_ti, cos_tr, sin_tr, cos_alpha, sin_alpha,
                     one_minus_cos_gamma, azimuth_i2, azimuth_r2, azimuth_ir, damping,
                     constants)
