"""GGX (Trowbridge-Reitz) microfacet model with separable Smith shadowing.

    f_r = kd + ks D_GGX G_GGX F / (4 cos ti cos tr)
    D_GGX = alpha^2 / (pi (cos^2 th (alpha^2 - 1) + 1)^2)
    G_GGX = G1(ti) G1(tr),  G1(t) = 2 / (1 + sqrt(1 + alpha^2 tan^2 t))
    F = f0 + (1 - f0) (1 - cos td)^5                          (Schlick)

Written without cancellation or division by zero: ``cos^2 th (alpha^2 - 1) + 1`` as
``sin^2 th + alpha^2 cos^2 th``, and ``G1(t) / cos t`` as
``2 / (cos t + sqrt(cos^2 t + alpha^2 sin^2 t))``, finite at grazing angles (``2 / alpha``
at 90 deg). ks F (two weights, `SpecularMicrofacet`) and kd enter linearly: only alpha is
searched.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax.numpy as jnp

from brdfjax.models._microfacet import HalfVector, SpecularMicrofacet
from brdfjax.models.base import NON_NEGATIVE, Parameter


def smith_over_cos(alpha2, cos_t, sin_t):
    """``G1(t) / cos t`` of GGX's Smith shadowing, finite for t up to 90 deg."""
    return 2.0 / (cos_t + jnp.sqrt(cos_t**2 + alpha2 * sin_t**2))


@dataclass(frozen=True)
class Ggx(SpecularMicrofacet):
    """GGX microfacets, Smith shadowing, Schlick Fresnel, plus a Lambertian kd."""

    name = "ggx"
    summary = ("GGX microfacets (long-tailed specular lobe): glossy paints, coatings and "
               "metals; often the best predictor of unmeasured incidences on real data")
    parameters = (
        Parameter("ks", 1e-6, 1e3, "log10",
                  "specular scale, >= 0: from near-matte to mirror-like", limits=NON_NEGATIVE),
        Parameter("alpha", 2e-3, 2.0, "log10",
                  "roughness, > 0: 0.002 (a lobe of about 0.1 deg) to 2 (broader than "
                  "diffuse)", limits=NON_NEGATIVE),
        Parameter("f0", 0.0, 1.0, "linear", "Schlick's normal-incidence reflectance",
                  limits=(0.0, 1.0)),
        Parameter("kd", 1e-8, 1e2, "log10", "diffuse level, >= 0: down to black coatings",
                  limits=NON_NEGATIVE),
    )

    def lobe(self, alpha, geometry: HalfVector):
        alpha2 = alpha * alpha
        facets = alpha2 / (jnp.pi * (geometry.sin2_h + alpha2 * geometry.cos_h**2) ** 2)
        return (facets * smith_over_cos(alpha2, geometry.cos_ti, geometry.sin_ti)
                * smith_over_cos(alpha2, geometry.cos_theta_r, geometry.sin_tr) / 4.0)
