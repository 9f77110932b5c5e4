"""Half-vector geometry shared by the microfacet models (GGX, Beckmann, Torrance-Sparrow).

With ``s = w_i + w_r`` the half vector is ``h = s / |s|``: ``cos th = h_z`` is the facet
tilt and ``cos td = w_i . h = |s| / 2`` the angle of incidence on the facet. At the one
point where ``s = 0`` (``w_r = -w_i``: both directions grazing, opposite azimuths) the facet
lies in the surface plane: ``cos th = 0`` and ``cos td = 0`` are used, the limits along the
specular direction.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp

from brdfjax.models.base import Model, broadcast_angles, mixture, safe_divide, safe_sqrt


class HalfVector(NamedTuple):
    """Parameter-free terms of the microfacet models at each point (arrays of one shape).

    Attributes:
        cos_h, sin2_h: cosine and squared sine of the facet tilt th.
        cos_d: cosine of td, the angle between w_i and the half vector.
        cos_ti, sin_ti, cos_tr, sin_tr: of the two zenith angles.
        cos_theta_r: the projection of Eq. (6) (the same as ``cos_tr``).
    """

    cos_h: jnp.ndarray
    sin2_h: jnp.ndarray
    cos_d: jnp.ndarray
    cos_ti: jnp.ndarray
    sin_ti: jnp.ndarray
    sin_tr: jnp.ndarray
    cos_theta_r: jnp.ndarray


def half_vector(theta_i, theta_r, phi_r) -> HalfVector:
    """The half-vector terms for broadcastable angles in radians."""
    theta_i, theta_r, phi_r = broadcast_angles(theta_i, theta_r, phi_r)
    cos_ti, sin_ti = jnp.cos(theta_i), jnp.sin(theta_i)
    cos_tr, sin_tr = jnp.cos(theta_r), jnp.sin(theta_r)
    s_x = sin_ti + sin_tr * jnp.cos(phi_r)
    s_y = sin_tr * jnp.sin(phi_r)
    s_z = cos_ti + cos_tr
    horizontal2 = s_x**2 + s_y**2
    norm2 = horizontal2 + s_z**2
    nonzero = norm2 > 0
    norm = safe_sqrt(norm2)
    return HalfVector(cos_h=safe_divide(s_z, norm, nonzero, 0.0),
                      sin2_h=safe_divide(horizontal2, norm2, nonzero, 1.0),
                      cos_d=norm / 2, cos_ti=cos_ti, sin_ti=sin_ti, sin_tr=sin_tr,
                      cos_theta_r=cos_tr)


def schlick_weight(cos_d):
    """``(1 - cos td)^5``, the part of Schlick's Fresnel ``f0 + (1 - f0) (1 - cos td)^5``
    that multiplies ``1 - f0``."""
    return (1.0 - cos_d) ** 5


class SpecularMicrofacet(Model):
    """A microfacet model ``kd + ks F lobe`` with Schlick's F; subclasses give the lobe.

    Parameters (ks, alpha, f0, kd). ``ks F = ks f0 + ks (1 - f0) (1 - cos td)^5``: both
    products are non-negative and enter linearly, as kd does, so only alpha is searched.
    They are solved as the weights of the lobe at f0's two bounds (`mixture`), which keeps
    f0 within its bounds however narrow.
    """

    linear = ("ks at f0's lower bound", "ks at f0's upper bound", "kd")
    peak = "specular"
    constant = "kd"
    scales = ("ks",)
    order_by = "alpha"

    def lobe(self, alpha, geometry: HalfVector):
        """``D G / (4 cos ti cos tr)`` per unit ``ks F``."""
        raise NotImplementedError

    def geometry(self, theta_i, theta_r, phi_r, in_plane):
        return half_vector(theta_i, theta_r, phi_r)

    def evaluate(self, params, geometry):
        ks, alpha, f0, kd = (params[k] for k in range(4))
        fresnel = f0 + (1.0 - f0) * schlick_weight(geometry.cos_d)
        return kd + ks * fresnel * self.lobe(alpha, geometry)

    def columns(self, params, geometry, bounds):
        """The lobe times F at f0's lower and upper bounds, and the diffuse 1."""
        lobe, weight = self.lobe(params[1], geometry), schlick_weight(geometry.cos_d)
        return ([lobe * (f0 + (1.0 - f0) * weight) for f0 in (bounds.lower[2], bounds.upper[2])]
                + [jnp.ones_like(lobe)], [1.0, 1.0, 1.0])

    def coefficient_bounds(self, bounds):
        """The two lobe weights in [0, ks_max]; kd in its own bounds."""
        zero = jnp.zeros_like(bounds.lower[0])
        return (jnp.stack([zero, zero, bounds.lower[3]]),
                jnp.stack([bounds.upper[0], bounds.upper[0], bounds.upper[3]]))

    def scale_sum(self, bounds):
        return bounds.lower[0], bounds.upper[0]

    def assemble(self, coefficients, params, bounds):
        """(ks, alpha, f0, kd) from the lobe weights (`mixture`) and kd; f0 kept where ks
        is 0."""
        ks, f0 = mixture(coefficients[0], coefficients[1], bounds.lower[2], bounds.upper[2],
                         params[2])
        return jnp.stack([jnp.clip(ks, bounds.lower[0], bounds.upper[0]), params[1], f0,
                          coefficients[2]])
