"""The MODIS RossThick-LiSparseReciprocal kernel model (MCD43; h/b = 2, b/r = 1).

    f_r = (f_iso + f_vol K_vol + f_geo K_geo) / pi
    K_vol = ((pi/2 - xi) cos xi + sin xi) / (cos ti + cos tr) - pi/4,   cos xi = cos g
    K_geo = O - sec ti - sec tr + (1 + cos xi) sec ti sec tr / 2
    O = (t - sin t cos t) (sec ti + sec tr) / pi
    cos t = (h/b) sqrt(D^2 + (tan ti tan tr sin pr)^2) / (sec ti + sec tr), clipped to [-1, 1]
    D = sqrt(tan^2 ti + tan^2 tr - 2 tan ti tan tr cos pr)

``cos g = w_i . w_r`` is 1 at back-scatter: the phase angle xi of W. Wanner, X. Li and A. H.
Strahler, "On the derivation of kernels for kernel-driven models of bidirectional
reflectance", J. Geophys. Res. 100(D10), 21077-21089 (1995), with phi_r = 0 on the source
side as everywhere in brdfjax; the kernels are theirs, with MODIS's h/b and b/r (W. Lucht,
C. B. Schaaf and A. H. Strahler, "An algorithm for the retrieval of albedo from space using
semiempirical BRDF models", IEEE Trans. Geosci. Remote Sens. 38(2), 977-998, 2000). With
b/r = 1 the primed angles of the literature are the true ones. The angles xi and t are taken as
``atan2(sin, cos)`` of a sine computed without cancellation (``sin xi = |w_i x w_r|``), so
that the derivatives stay finite where ``arccos`` has an infinite one (xi = 0 at
back-scatter, t = 0 where the shadows vanish); ``D^2`` is written with the cosines
multiplied through.

All three coefficients enter linearly: the fit is one exact, bounded linear solve
(`brdfjax.fitting.objective.solve_linear`), nothing is searched. Each is >= 0 by default
(negative kernel weights are unphysical).

Where the published kernels leave a choice: at exactly 90 deg (``ti`` or ``tr``) the kernels are
outside their domain (sec diverges; MODIS uses them below about 70 deg). The code takes each
cosine as at least `GRAZING_COSINE` in the secants and tangents (about 89.99999994 deg),
as RPV does, so that values and gradients stay finite there: K_geo is then of order
``-1e9`` (f_r hugely negative for f_geo > 0), while the fitted projected BRDF ``f_r cos tr``
at ``tr = 90`` deg is ``-f_geo / pi`` times a bounded factor. Nothing else is clipped: K_geo
is negative at grazing angles for any f_geo > 0, as the kernel is.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import jax.numpy as jnp

from brdfjax.models.base import NON_NEGATIVE, Model, Parameter, phase_terms, safe_sqrt

GRAZING_COSINE = 1e-9
HEIGHT_RATIO = 2.0  # h/b of MCD43 (LiSparse-R); b/r = 1


class KernelGeometry(NamedTuple):
    """The two kernels at each point (parameter-free: the model is linear).

    Attributes:
        volume: K_vol (RossThick).
        geometric: K_geo (LiSparse-Reciprocal).
        cos_theta_r: the projection of Eq. (6).
    """

    volume: jnp.ndarray
    geometric: jnp.ndarray
    cos_theta_r: jnp.ndarray


def kernels(theta_i, theta_r, phi_r) -> KernelGeometry:
    """K_vol and K_geo (module docstring) at broadcastable angles in radians."""
    cos_i, sin_i, cos_r, sin_r, cos_p, sin_p, cos_xi, cross2 = phase_terms(theta_i, theta_r,
                                                                           phi_r)
    xi = jnp.arctan2(safe_sqrt(cross2), cos_xi)
    sum_cos = jnp.maximum(cos_i + cos_r, GRAZING_COSINE)
    volume = ((jnp.pi / 2 - xi) * cos_xi + jnp.sin(xi)) / sum_cos - jnp.pi / 4
    floor_i, floor_r = jnp.maximum(cos_i, GRAZING_COSINE), jnp.maximum(cos_r, GRAZING_COSINE)
    sec_i, sec_r = 1.0 / floor_i, 1.0 / floor_r
    # D^2 + (tan ti tan tr sin pr)^2, the cosines multiplied through: a sum of squares
    # (tan ti - tan tr cos pr)^2 + (tan tr sin pr)^2 (1 + tan^2 ti), never negative.
    spread2 = ((sin_i * floor_r - sin_r * floor_i * cos_p) ** 2
               + (sin_r * sin_p) ** 2 * (floor_i**2 + sin_i**2)) / (floor_i * floor_r) ** 2
    secants = sec_i + sec_r
    cos_t = jnp.clip(HEIGHT_RATIO * safe_sqrt(spread2) / secants, -1.0, 1.0)
    sin_t = safe_sqrt(1.0 - cos_t**2)
    t = jnp.arctan2(sin_t, cos_t)
    overlap = (t - sin_t * cos_t) * secants / jnp.pi
    geometric = overlap - secants + (1.0 + cos_xi) * sec_i * sec_r / 2
    return KernelGeometry(volume, geometric, cos_r)


@dataclass(frozen=True)
class RossLi(Model):
    """MODIS's linear kernel model: isotropic, RossThick volume and LiSparse-R geometric."""

    name = "ross-li"
    summary = ("MODIS RossThick-LiSparseReciprocal kernels, the remote-sensing per-pixel "
               "standard; linear, so its fit is one exact solve")
    parameters = (
        Parameter("f_iso", 0.0, 10.0, "linear",
                  "isotropic weight >= 0 (negative weights are unphysical), up to 10 albedos",
                  limits=NON_NEGATIVE),
        Parameter("f_vol", 0.0, 10.0, "linear", "RossThick volume-scattering weight >= 0",
                  limits=NON_NEGATIVE),
        Parameter("f_geo", 0.0, 10.0, "linear", "LiSparse-R geometric-optics weight >= 0",
                  limits=NON_NEGATIVE),
    )
    linear = ("f_iso", "f_vol", "f_geo")
    peak = "backscatter"
    scales = ("f_iso", "f_vol", "f_geo")

    def geometry(self, theta_i, theta_r, phi_r, in_plane):
        return kernels(theta_i, theta_r, phi_r)

    def evaluate(self, params, geometry):
        return (params[0] + params[1] * geometry.volume + params[2] * geometry.geometric) / jnp.pi

    def columns(self, params, geometry, bounds):
        one = jnp.ones_like(geometry.volume)
        return [one / jnp.pi, geometry.volume / jnp.pi, geometry.geometric / jnp.pi], [1.0] * 3

    def coefficient_bounds(self, bounds):
        return bounds.lower, bounds.upper

    def assemble(self, coefficients, params, bounds):
        return coefficients
