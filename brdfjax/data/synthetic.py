"""Synthetic stand-ins for the paper's five samples (its measured data are not published).

Geometry as the paper describes its measurements: in-plane, reflection zenith from -89 to
89 deg in 1 deg steps (negative: the source side, ``phi_r = 0``; positive: the specular
side, ``phi_r = 180``), 179 points per incidence. White paint at incidences 10, 21, 30, 45,
52 and 60 deg (the paper fits 10/30/45/60 and validates on 21/52), the others at 10, 30,
45 and 60 deg.

Noise model: each value is the model BRDF times ``1 + noise * N(0, 1)``, with
``noise = 0.025`` (2.5 % relative, half the paper's quoted instrument error of "under 5 %"),
drawn from ``numpy.random.default_rng(seed)``; ``sigma = noise * model`` is written beside it.
"""

from __future__ import annotations

import numpy as np

from brdfjax.data.measurements import Measurements
from brdfjax.models.paper import PAPER_SAMPLES, brdf

PAPER_INCIDENCES = {"white_paint": (10, 21, 30, 45, 52, 60)}
DEFAULT_INCIDENCES = (10, 30, 45, 60)
RELATIVE_NOISE = 0.025


def paper_geometry(sample: str = "white_paint"):
    """(theta_i, theta_r, phi_r) in degrees of the paper's in-plane scans of a sample."""
    incidences = PAPER_INCIDENCES.get(sample, DEFAULT_INCIDENCES)
    signed = np.arange(-89, 90, dtype=float)
    theta_i = np.repeat(np.asarray(incidences, dtype=float), signed.size)
    signed = np.tile(signed, len(incidences))
    return theta_i, np.abs(signed), np.where(signed > 0, 180.0, 0.0)


def synthesize(params, theta_i, theta_r, phi_r, noise: float = RELATIVE_NOISE, seed: int = 0,
               metadata: dict | None = None) -> Measurements:
    """Model values at the given angles (degrees), with relative Gaussian noise."""
    clean = np.asarray(brdf(params, *np.radians([theta_i, theta_r, phi_r])), dtype=float)
    rng = np.random.default_rng(seed)
    values = clean * (1 + noise * rng.standard_normal(clean.shape)) if noise else clean
    return Measurements.from_degrees(theta_i, theta_r, phi_r, values,
                                     sigma=noise * clean if noise else None,
                                     metadata=dict(metadata or {}))


def paper_sample(sample: str, noise: float = RELATIVE_NOISE, seed: int = 0) -> Measurements:
    """A synthetic stand-in for one of the paper's samples on the paper's geometry."""
    params = PAPER_SAMPLES[sample]
    metadata = {"sample": sample, "wavelength_nm": 1060,
                "source": f"SYNTHETIC: model of Eq. (5) with the paper's parameters "
                          f"{dict(params._asdict())}, {noise:g} relative noise, seed {seed}"}
    return synthesize(params, *paper_geometry(sample), noise=noise, seed=seed,
                      metadata=metadata)
