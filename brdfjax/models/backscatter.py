"""A GGX-shaped lobe around the source direction: the back-scatter (retro-reflection) part
of a sum of models, brdfjax's own (the GGX distribution of B. Walter, S. R. Marschner, H. Li
and K. E. Torrance, "Microfacet models for refraction through rough surfaces", Eurographics
Symposium on Rendering 2007, taken in the phase angle g instead of the facet tilt).

    f_r = kb D_GGX(c; beta),  D_GGX(c; beta) = beta^2 / (pi (c^2 (beta^2 - 1) + 1)^2)
    c = max(cos g, 0),  cos g = w_i . w_r = cos ti cos tr + sin ti sin tr cos pr

the GGX distribution with the phase cosine in place of the facet tilt's: largest
(``1 / (pi beta^2)``) at back-scatter ``w_r = w_i``, and the constant ``beta^2 / pi`` more than
90 deg from the source. ``c^2 (beta^2 - 1) + 1`` is written ``sin^2 g + beta^2 c^2`` with
``sin^2 g = |w_i x w_r|^2`` (1 where ``cos g <= 0``), free of cancellation near the peak,
where a narrow lobe (beta 0.002) is decided. kb enters linearly; only beta is searched.
Defined on the whole hemisphere, 90 deg included: nothing divides by a cosine. Alone it is
rarely useful; it is meant as a part of a sum such as ``ggx+backscatter``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import jax.numpy as jnp

from brdfjax.models.base import NON_NEGATIVE, Parameter, ScaledShape, phase_terms


class PhaseGeometry(NamedTuple):
    """The phase angle g between w_i and w_r at each point.

    Attributes:
        cos2_phase: ``c^2``, c = max(cos g, 0).
        sin2_phase: ``1 - c^2``: ``|w_i x w_r|^2`` where cos g > 0, else 1.
        cos_theta_r: the projection of Eq. (6).
    """

    cos2_phase: jnp.ndarray
    sin2_phase: jnp.ndarray
    cos_theta_r: jnp.ndarray


def phase_geometry(theta_i, theta_r, phi_r) -> PhaseGeometry:
    """``c^2`` and ``1 - c^2`` of the clipped phase cosine, for angles in radians."""
    terms = phase_terms(theta_i, theta_r, phi_r)
    forward = terms.cos_phase > 0
    return PhaseGeometry(jnp.where(forward, terms.cos_phase, 0.0) ** 2,
                         jnp.where(forward, jnp.minimum(terms.cross2, 1.0), 1.0), terms.cos_r)


def ggx_distribution(beta, geometry: PhaseGeometry):
    """``D_GGX(c; beta)`` as ``beta^2 / (pi (sin^2 g + beta^2 c^2)^2)``."""
    beta2 = beta * beta
    return beta2 / (jnp.pi * (geometry.sin2_phase + beta2 * geometry.cos2_phase) ** 2)


@dataclass(frozen=True)
class Backscatter(ScaledShape):
    """A GGX lobe in the phase angle, peaked at the source direction."""

    name = "backscatter"
    summary = ("a GGX-shaped lobe around the source direction (retro-reflection); a part of "
               "sums such as ggx+backscatter rather than a model on its own")
    parameters = (
        Parameter("kb", 1e-10, 1e3, "log10",
                  "kb >= 0: down to 1e-10, where even the narrowest lobe is below any "
                  "measurement (log10 needs a positive floor), up to a retro-reflector",
                  limits=NON_NEGATIVE),
        Parameter("beta", 2e-3, 2.0, "log10",
                  "width, > 0, like GGX's alpha: 0.002 (about 0.1 deg) to 2 (broader than "
                  "diffuse)", limits=NON_NEGATIVE),
    )
    linear = ("kb",)
    peak = "backscatter"
    scales = ("kb",)
    order_by = "beta"

    def geometry(self, theta_i, theta_r, phi_r, in_plane):
        return phase_geometry(theta_i, theta_r, phi_r)

    def shape(self, params, geometry):
        return ggx_distribution(params[1], geometry)
