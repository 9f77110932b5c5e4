"""Beckmann (Cook-Torrance) microfacet model with the exact Smith shadowing for Beckmann.

    f_r = kd + ks D_B G_B F / (4 cos ti cos tr)
    D_B = exp(-tan^2 th / alpha^2) / (pi alpha^2 cos^4 th)
    G_B = G1(ti) G1(tr),  G1 = 1 / (1 + Lambda),  m = 1 / (alpha tan t)
    Lambda = (erf(m) - 1) / 2 + exp(-m^2) / (2 m sqrt(pi))
    F = f0 + (1 - f0) (1 - cos td)^5                          (Schlick)

Written to stay finite on the whole hemisphere: ``D_B`` in log space (0 at ``cos th = 0``,
its limit), and ``(1 + Lambda) cos t`` multiplied through as
``cos t (1 + erf m) / 2 + alpha sin t exp(-m^2) / (2 sqrt(pi))`` (``cos t`` at normal
incidence where ``m`` is infinite, ``alpha / (2 sqrt(pi))`` at 90 deg).
"""

from __future__ import annotations

from dataclasses import dataclass

import jax.numpy as jnp
from jax.scipy.special import erf

from brdfjax.models._microfacet import HalfVector, SpecularMicrofacet
from brdfjax.models.base import NON_NEGATIVE, Parameter, safe_divide

# Beyond these the exponentials are exactly 0 (and erf exactly 1) in float64: the terms take
# their limits there, which keeps every gradient finite.
EXPONENT_CAP = 1e4   # exp(-q) for q above this
M_CAP = 1e8          # m = 1 / (alpha tan t) above this: Lambda = 0


def smith_over_cos(alpha, cos_t, sin_t):
    """``G1(t) / cos t`` of Beckmann's Smith shadowing, finite for t up to 90 deg."""
    tilted = alpha * sin_t * M_CAP > cos_t
    m = safe_divide(cos_t, alpha * sin_t, tilted, M_CAP)
    tail = jnp.where(tilted, alpha * sin_t * jnp.exp(-m * m), 0.0)
    shadow_cos = cos_t * (1.0 + jnp.where(tilted, erf(m), 1.0)) / 2 + tail / (2 * jnp.sqrt(jnp.pi))
    return 1.0 / shadow_cos


@dataclass(frozen=True)
class Beckmann(SpecularMicrofacet):
    """Beckmann microfacets, exact Smith shadowing, Schlick Fresnel, plus a Lambertian kd."""

    name = "beckmann"
    summary = ("Beckmann microfacets (Gaussian-like specular lobe, short tails): rough "
               "metals and ground surfaces; compare with ggx on the tails")
    parameters = (
        Parameter("ks", 1e-6, 1e3, "log10",
                  "specular scale, >= 0: from near-matte to mirror-like", limits=NON_NEGATIVE),
        Parameter("alpha", 2e-3, 2.0, "log10",
                  "rms facet slope, > 0: 0.002 (a lobe of about 0.1 deg) to 2 (very rough)",
                  limits=NON_NEGATIVE),
        Parameter("f0", 0.0, 1.0, "linear", "Schlick's normal-incidence reflectance",
                  limits=(0.0, 1.0)),
        Parameter("kd", 1e-8, 1e2, "log10", "diffuse level, >= 0: down to black coatings",
                  limits=NON_NEGATIVE),
    )

    def lobe(self, alpha, geometry: HalfVector):
        cos_h, sin2_h = geometry.cos_h, geometry.sin2_h
        steep = (cos_h * alpha) ** 2 * EXPONENT_CAP > sin2_h  # else exp(-tan^2 th / alpha^2) = 0
        cos_safe = jnp.where(steep, cos_h, 1.0)
        slope2 = jnp.where(steep, sin2_h, 0.0) / (cos_safe**2 * alpha**2)
        facets = jnp.where(steep, jnp.exp(-slope2 - 4 * jnp.log(cos_safe)), 0.0) / (
            jnp.pi * alpha**2)
        return (facets * smith_over_cos(alpha, geometry.cos_ti, geometry.sin_ti)
                * smith_over_cos(alpha, geometry.cos_theta_r, geometry.sin_tr) / 4.0)
