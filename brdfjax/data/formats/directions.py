"""Directions written as (polar angle, azimuth) pairs, turned into the project's angles.

Shared by the readers whose files give the incident and the scattered direction each with
its own azimuth (NIST, ASTM E1392). Angles in degrees.
"""

from __future__ import annotations

import numpy as np

# In-plane points come out of the azimuth subtraction within rounding of 0 or 180 deg.
IN_PLANE_TOLERANCE_DEG = 1e-6


def unsign(polar, azimuth) -> tuple[np.ndarray, np.ndarray]:
    """A negative polar angle is the positive angle on the opposite azimuth."""
    negative = polar < 0
    return np.abs(polar), np.where(negative, azimuth + 180.0, azimuth)


def relative_azimuth(phi_detector, phi_source, theta_r) -> np.ndarray:
    """``phi_r`` in (-180, 180] with the source at 0; in-plane values exactly 0 or 180.

    Both azimuths describe directions pointing away from the surface, so the specular
    direction lies at ``phi_detector = phi_source + 180``, which becomes ``phi_r = 180``.
    """
    phi = 180.0 - np.mod(180.0 - (phi_detector - phi_source), 360.0)
    phi = np.where(np.abs(phi) < IN_PLANE_TOLERANCE_DEG, 0.0, phi)
    phi = np.where(np.abs(np.abs(phi) - 180.0) < IN_PLANE_TOLERANCE_DEG, 180.0, phi)
    # The normal has no azimuth.
    return np.where(theta_r == 0, 0.0, phi)
