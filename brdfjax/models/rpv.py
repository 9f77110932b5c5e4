"""Rahman, Pinty and Verstraete (1993): the remote-sensing standard for land surfaces.

    f_r = (rho0 / pi) M(ti, tr) F_HG(g) H(ti, tr, pr)
    M = cos^(k-1) ti cos^(k-1) tr / (cos ti + cos tr)^(1-k)
    F_HG = (1 - asymmetry^2) / (1 + 2 asymmetry cos g + asymmetry^2)^(3/2),  cos g = w_i . w_r
    H = 1 + (1 - rhoc) / (1 + Gd),  Gd = sqrt(tan^2 ti + tan^2 tr - 2 tan ti tan tr cos pr)

``cos g`` is 1 at back-scatter, so ``asymmetry < 0`` means back-scattering; ``Gd = 0`` there
(the hot spot). ``M = exp((k - 1) L)`` with ``L = log cos ti + log cos tr + log(cos ti +
cos tr)``, and ``1 / (1 + Gd)`` is written with the cosines multiplied through.

At exactly 90 deg (``ti`` or ``tr``) RPV is outside its domain: M diverges for k < 1. The
code takes each cosine as at least `GRAZING_COSINE` in M (about 89.99999994 deg), so values
and gradients stay finite there: huge for k < 1, while the fitted projected BRDF
``f_r cos tr`` still goes to 0. ``rho0`` and ``rho0 (1 - rhoc)`` enter linearly (solved as
the weights of RPV at rhoc's two bounds, `Rpv.columns`); k and asymmetry are searched.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import jax.numpy as jnp

from brdfjax.models.base import (
    NON_NEGATIVE,
    Model,
    Parameter,
    broadcast_angles,
    mixture,
    safe_divide,
    safe_sqrt,
)

GRAZING_COSINE = 1e-9


class RpvGeometry(NamedTuple):
    """Parameter-free terms of RPV at each point.

    Attributes:
        log_cosines: ``L``, so that ``M = exp((k - 1) L)``.
        cos_phase: ``cos g = w_i . w_r``.
        hot_spot: ``1 / (1 + Gd)``, 1 at back-scatter.
        cos_theta_r: the projection of Eq. (6).
    """

    log_cosines: jnp.ndarray
    cos_phase: jnp.ndarray
    hot_spot: jnp.ndarray
    cos_theta_r: jnp.ndarray


def henyey_greenstein(asymmetry, cos_phase):
    """The Henyey-Greenstein phase function of RPV (no 1/(4 pi) factor)."""
    return (1.0 - asymmetry**2) / (1.0 + 2.0 * asymmetry * cos_phase + asymmetry**2) ** 1.5


@dataclass(frozen=True)
class Rpv(Model):
    """The RPV model: a Minnaert-like bowl, a Henyey-Greenstein lobe and a hot spot."""

    name = "rpv"
    summary = ("Rahman-Pinty-Verstraete, the remote-sensing standard: vegetation, soils, "
               "snow and other volume scatterers with a hot spot; no specular facets")
    parameters = (
        Parameter("rho0", 1e-6, 10.0, "log10", "overall level, >= 0: black to bright",
                  limits=NON_NEGATIVE),
        Parameter("k", 0.05, 3.0, "linear",
                  "bowl (k < 1) or bell (k > 1) shape; 1 is Lambert-like"),
        Parameter("asymmetry", -0.95, 0.95, "linear",
                  "Henyey-Greenstein asymmetry, within -1 to 1 (its phase function's "
                  "domain): back- (< 0) or forward-scattering (> 0)", limits=(-1.0, 1.0)),
        Parameter("rhoc", -2.0, 1.95, "linear",
                  "hot-spot strength: H = 2 - rhoc at back-scatter, not negative for rhoc "
                  "<= 2; kept above 0.05", limits=(-float("inf"), 2.0)),
    )
    linear = ("rho0 at rhoc's lower bound", "rho0 at rhoc's upper bound")
    peak = "backscatter"
    scales = ("rho0",)
    order_by = "k"

    def geometry(self, theta_i, theta_r, phi_r, in_plane):
        theta_i, theta_r, phi_r = broadcast_angles(theta_i, theta_r, phi_r)
        cos_i, sin_i = jnp.cos(theta_i), jnp.sin(theta_i)
        cos_r, sin_r = jnp.cos(theta_r), jnp.sin(theta_r)
        cos_pr = jnp.cos(phi_r)
        floor_i, floor_r = (jnp.maximum(x, GRAZING_COSINE) for x in (cos_i, cos_r))
        log_cosines = jnp.log(floor_i) + jnp.log(floor_r) + jnp.log(floor_i + floor_r)
        # Gd cos ti cos tr, with the tangents multiplied through by the cosines.
        spread = safe_sqrt(jnp.maximum((sin_i * cos_r) ** 2 + (sin_r * cos_i) ** 2
                                       - 2 * sin_i * sin_r * cos_i * cos_r * cos_pr, 0.0))
        both = cos_i * cos_r
        hot_spot = safe_divide(both, both + spread, both + spread > 0, 0.0)
        cos_phase = cos_i * cos_r + sin_i * sin_r * cos_pr
        return RpvGeometry(log_cosines, cos_phase, hot_spot, cos_r)

    def _base(self, k, asymmetry, geometry):
        return (jnp.exp((k - 1.0) * geometry.log_cosines)
                * henyey_greenstein(asymmetry, geometry.cos_phase) / jnp.pi)

    def evaluate(self, params, geometry):
        rho0, k, asymmetry, rhoc = (params[j] for j in range(4))
        return rho0 * self._base(k, asymmetry, geometry) * (1.0 + (1.0 - rhoc)
                                                           * geometry.hot_spot)

    def columns(self, params, geometry, bounds):
        """RPV per unit rho0 at rhoc's lower and upper bounds (`mixture`: the solve then
        keeps rhoc within its bounds; ``rho0`` and ``rho0 (1 - rhoc)`` boxed separately let
        it pick a hot spot that rhoc's bounds forbid)."""
        base = self._base(params[1], params[2], geometry)
        return [base * (1.0 + (1.0 - rhoc) * geometry.hot_spot)
                for rhoc in (bounds.lower[3], bounds.upper[3])], [1.0, 1.0]

    def coefficient_bounds(self, bounds):
        zero = jnp.zeros_like(bounds.upper[0])
        return jnp.stack([zero, zero]), jnp.stack([bounds.upper[0], bounds.upper[0]])

    def scale_sum(self, bounds):
        return bounds.lower[0], bounds.upper[0]

    def assemble(self, coefficients, params, bounds):
        """rho0 and rhoc from the weights at rhoc's bounds (`mixture`); rhoc kept where
        rho0 is 0."""
        rho0, rhoc = mixture(coefficients[0], coefficients[1], bounds.lower[3], bounds.upper[3],
                             params[3])
        return params.at[0].set(jnp.clip(rho0, bounds.lower[0], bounds.upper[0])).at[3].set(rhoc)
