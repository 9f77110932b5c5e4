"""The Lambertian model: a constant BRDF ``f_r = kd`` (reflectance ``pi kd`` at every
incidence). One linear parameter: the fit is a weighted mean, solved exactly."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import jax.numpy as jnp

from brdfjax.models.base import NON_NEGATIVE, Parameter, ScaledShape, broadcast_angles


class LambertGeometry(NamedTuple):
    """The only geometry a constant BRDF needs: the projection of Eq. (6)."""

    cos_theta_r: jnp.ndarray


@dataclass(frozen=True)
class Lambert(ScaledShape):
    """A perfectly diffuse surface."""

    name = "lambert"
    summary = ("a constant BRDF: the null model every other must beat, and matte "
               "references such as PTFE or Spectralon at small angles")
    parameters = (Parameter("kd", 1e-8, 1e2, "log10",
                            "kd >= 0: from black coatings to well above any physical albedo "
                            "(1/pi)", limits=NON_NEGATIVE),)
    linear = ("kd",)
    constant = "kd"
    scales = ("kd",)

    def geometry(self, theta_i, theta_r, phi_r, in_plane):
        theta_i, theta_r, phi_r = broadcast_angles(theta_i, theta_r, phi_r)
        return LambertGeometry(jnp.cos(theta_r))

    def shape(self, params, geometry):
        return jnp.ones_like(geometry.cos_theta_r)
