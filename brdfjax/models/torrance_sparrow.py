"""The Torrance-Sparrow model as the paper prints it, Eq. (2): the baseline it argues against.

    f_r = g R(td, n) G(ti, tr, pr) / cos tr * exp(-c^2 th^2) + (rho0 / pi) cos ti

with ``th`` the facet tilt in radians, ``td`` the angle of incidence on the facet, ``G`` the
paper's shadowing of Eq. (3)-(4) with its constants (the same G as the five-parameter
model, `brdfjax.models.geometry`), and ``R`` the unpolarised Fresnel reflectance of a dielectric of
real index ``n``:

    R = ((cos td - n cos tt)^2 / (cos td + n cos tt)^2
         + (n cos td - cos tt)^2 / (n cos td + cos tt)^2) / 2,   sin tt = sin td / n

The diffuse term carries ``cos ti`` because Eq. (2) prints it so (a Lambertian surface
would not); brdfjax follows the print. g and rho0 enter linearly; c and n are searched.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import jax.numpy as jnp

from brdfjax.models._microfacet import half_vector
from brdfjax.models.base import NON_NEGATIVE, Model, Parameter, safe_sqrt
from brdfjax.models.geometry import PAPER_CONSTANTS, ShadowingConstants, scene


class TorranceSparrowGeometry(NamedTuple):
    """Parameter-free terms of Eq. (2) at each point.

    Attributes:
        tilt: the facet tilt th in radians.
        cos_d: cosine of td, the angle of incidence on the facet.
        shadowing: G / cos tr of Eq. (3)-(4), finite on the whole hemisphere.
        diffuse: ``cos ti / pi``.
        cos_theta_r: the projection of Eq. (6).
    """

    tilt: jnp.ndarray
    cos_d: jnp.ndarray
    shadowing: jnp.ndarray
    diffuse: jnp.ndarray
    cos_theta_r: jnp.ndarray


def fresnel(cos_d, n):
    """Unpolarised Fresnel reflectance of a dielectric of real index n >= 1 at cos td."""
    cos_t = jnp.sqrt(1.0 - (1.0 - cos_d**2) / n**2)
    perpendicular = ((cos_d - n * cos_t) / (cos_d + n * cos_t)) ** 2
    parallel = ((n * cos_d - cos_t) / (n * cos_d + cos_t)) ** 2
    return (perpendicular + parallel) / 2


@dataclass(frozen=True)
class TorranceSparrow(Model):
    """The paper's Eq. (2): Gaussian-in-angle facets, Fresnel of index n, the paper's G."""

    constants: ShadowingConstants = PAPER_CONSTANTS

    name = "torrance-sparrow"
    summary = ("the paper's Eq. (2), the Torrance-Sparrow baseline it argues its model "
               "improves on; fit it to measure that claim on your data")
    parameters = (
        Parameter("g", 1e-8, 1e4, "log10",
                  "specular scale, >= 0: from near-matte to mirror-like", limits=NON_NEGATIVE),
        Parameter("c", 1e-2, 1e3, "log10",
                  "exp(-c^2 th^2), c >= 0: lobe widths from radians down to a milliradian",
                  limits=NON_NEGATIVE),
        Parameter("n", 1.01, 5.0, "linear",
                  "refractive index of dielectrics and coatings, >= 1 (R of a real index "
                  "from the outside)", limits=(1.0, float("inf"))),
        Parameter("rho0", 1e-8, 10.0, "log10", "diffuse albedo, >= 0: down to black coatings",
                  limits=NON_NEGATIVE),
    )
    linear = ("g", "rho0")
    peak = "specular"
    scales = ("g",)
    order_by = "c"

    def geometry(self, theta_i, theta_r, phi_r, in_plane):
        facets = half_vector(theta_i, theta_r, phi_r)
        paper = scene(theta_i, theta_r, phi_r, self.constants, in_plane=in_plane)
        return TorranceSparrowGeometry(
            tilt=jnp.arctan2(safe_sqrt(facets.sin2_h), facets.cos_h), cos_d=facets.cos_d,
            shadowing=paper.shadowing, diffuse=facets.cos_ti / jnp.pi,
            cos_theta_r=facets.cos_theta_r)

    def _specular(self, c, n, geometry):
        return (fresnel(geometry.cos_d, n) * geometry.shadowing
                * jnp.exp(-(c * geometry.tilt) ** 2))

    def evaluate(self, params, geometry):
        g, c, n, rho0 = (params[k] for k in range(4))
        return g * self._specular(c, n, geometry) + rho0 * geometry.diffuse

    def columns(self, params, geometry, bounds):
        return [self._specular(params[1], params[2], geometry), geometry.diffuse], [1.0, 1.0]

    def coefficient_bounds(self, bounds):
        return bounds.lower[::3], bounds.upper[::3]

    def assemble(self, coefficients, params, bounds):
        return params.at[0].set(coefficients[0]).at[3].set(coefficients[1])

