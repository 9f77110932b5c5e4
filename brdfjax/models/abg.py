"""The ABg scatter model of stray-light analysis (Zemax OpticStudio, FRED).

    f_r = A / (B + |beta - beta0|^g)
    |beta - beta0| = hypot(sin tr cos pr + sin ti, sin tr sin pr)

``beta - beta0`` is the 2-D difference of the projections on the surface plane of the
scattered direction and of the specular one, which projects to ``(-sin ti, 0)``: the
direction cosines of Harvey's scatter theory (J. E. Harvey, "Light-scattering
characteristics of optical surfaces", PhD dissertation, University of Arizona, 1976), in
which stray-light programs define ABg (R. N. Pfisterer, "Approximated scatter models for
stray light analysis", Optics & Photonics News 22(10), 2011). The BRDF peaks at ``A / B``
in the specular direction and falls as ``|beta - beta0|^-g`` beyond a shoulder at
``|beta - beta0| = B^(1/g)``; ``g = 0`` is a constant ``A / (B + 1)``.

Where the formula leaves a choice: ``x^g`` at ``x = |beta - beta0| = 0`` (the specular point) is
taken as its limit, 0 for ``g > 0`` and 1 for ``g = 0``, with zero derivatives there
(``g x^(g-1)`` is infinite at 0 for ``g < 1``; the code differentiates through
``exp((g/2) log x^2)`` only where ``x > 0``). Nothing divides by a cosine: 90 deg is inside
the domain. A enters linearly; B (log10, 1e-8..1) and g (linear, 0..4) are searched.
Zemax requires ``B > 1e-12`` unless ``g = 0``, and FRED that ``A / B`` times the projected
solid angle at the specular be at most 1: `brdfjax.data.formats.abg` reports both checks.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import jax.numpy as jnp

from brdfjax.models.base import NON_NEGATIVE, Parameter, ScaledShape, broadcast_angles


class ProjectedGeometry(NamedTuple):
    """The distance in the surface plane from the specular projection.

    Attributes:
        distance2: ``|beta - beta0|^2``.
        cos_theta_r: the projection of Eq. (6).
    """

    distance2: jnp.ndarray
    cos_theta_r: jnp.ndarray


def power(distance2, g):
    """``|beta - beta0|^g`` from its square, with the limits of the module docstring at 0."""
    positive = distance2 > 0
    safe = jnp.where(positive, distance2, 1.0)
    return jnp.where(positive, jnp.exp(0.5 * g * jnp.log(safe)), jnp.where(g == 0, 1.0, 0.0))


@dataclass(frozen=True)
class Abg(ScaledShape):
    """The ABg model, peaked at the specular direction."""

    name = "abg"
    summary = ("the stray-light ABg model of Zemax OpticStudio and FRED: a specular lobe "
               "falling as a power of the projected distance; fit per incidence for export")
    parameters = (
        Parameter("A", 1e-12, 1e3, "log10",
                  "A >= 0: from a black coating's wings up to a mirror's peak A/B",
                  limits=NON_NEGATIVE),
        Parameter("B", 1e-8, 1.0, "log10",
                  "B > 0 (the peak A/B is finite): shoulder B^(1/g) of the lobe, from a "
                  "polished mirror to a diffuser", limits=NON_NEGATIVE),
        Parameter("g", 0.0, 4.0, "linear",
                  "fall-off power, >= 0 (the lobe falls away from the specular): 0 "
                  "(constant, Lambertian) to 4 (steep wings)", limits=NON_NEGATIVE),
    )
    linear = ("A",)
    peak = "specular"
    scales = ("A",)
    order_by = "B"

    def geometry(self, theta_i, theta_r, phi_r, in_plane):
        theta_i, theta_r, phi_r = broadcast_angles(theta_i, theta_r, phi_r)
        sin_r = jnp.sin(theta_r)
        distance2 = (sin_r * jnp.cos(phi_r) + jnp.sin(theta_i)) ** 2 + (sin_r * jnp.sin(phi_r)) ** 2
        return ProjectedGeometry(distance2, jnp.cos(theta_r))

    def shape(self, params, geometry):
        return 1.0 / (params[1] + power(geometry.distance2, params[2]))
