"""Radians in Python, degrees in files: a host-side check that angles lie in their domain.

The model's functions (`brdfjax.brdf`, `brdfjax.projected_brdf`, `brdfjax.reflectance`)
take radians, while files, the command line and the bands' functions take degrees. Given
degrees, a radian function does not fail: ``reflectance(p, 30.0)`` reads 30 rad and returns
a number. So those functions call `check_radians` first, which rejects a zenith outside
[0, pi/2] or an azimuth outside [-2 pi, 2 pi] with a message naming the likely mix-up;
`check_degrees` does the same for zenith angles in degrees.

The check looks only at host values (Python numbers, lists, NumPy arrays). JAX arrays and
tracers pass unchecked: inside jit, vmap or grad the values are not known, and reading a
device array back would cost a transfer, so compiled code pays nothing.
"""

from __future__ import annotations

import numpy as np

# Slack for angles converted from degrees (np.radians(90) may round just above pi / 2).
TOLERANCE = 1e-6


def check_radians(azimuths=(), **angles) -> None:
    """Raise `ValueError` if a host zenith angle leaves [0, pi/2] or an azimuth [-2 pi, 2 pi].

    Args:
        azimuths: names among ``angles`` that are azimuths (any sign, one turn each way).
        **angles: the angles by argument name, in radians.
    """
    for name, value in angles.items():
        values = _host_values(value)
        if values is None:
            continue
        if name in azimuths:
            bad = values[np.abs(values) > 2 * np.pi + TOLERANCE]
            if bad.size:
                raise ValueError(
                    f"{name} = {bad[0]:g} is beyond one turn (2 pi rad): angles in Python are "
                    f"radians (files and the command line take degrees); did you mean "
                    f"np.radians({bad[0]:g})?")
            continue
        bad = values[(values < -TOLERANCE) | (values > np.pi / 2 + TOLERANCE)]
        if not bad.size:
            continue
        if bad[0] < 0:
            raise ValueError(
                f"{name} = {bad[0]:g} is negative: zenith angles lie in [0, pi/2] rad; a signed "
                "in-plane angle t is theta_r = |t| with phi_r = pi on the specular side, else 0")
        degrees = bad[bad > np.pi]  # no radian zenith angle is past pi: degrees by mistake
        if not degrees.size:
            raise ValueError(f"{name} = {bad[0]:g} rad is below the horizon: zenith angles "
                             "lie in [0, pi/2] = [0, 1.5708] rad")
        raise ValueError(
            f"{name} = {degrees[0]:g} is outside [0, pi/2] = [0, 1.5708] rad: angles in Python "
            f"are radians (files and the command line take degrees); did you mean "
            f"np.radians({degrees[0]:g})?")


def check_degrees(**angles) -> None:
    """Raise `ValueError` if a host zenith angle in degrees leaves [0, 90]."""
    for name, value in angles.items():
        values = _host_values(value)
        if values is None:
            continue
        bad = values[(values < -TOLERANCE) | (values > 90 + TOLERANCE)]
        if bad.size:
            raise ValueError(f"{name} = {bad[0]:g} is outside [0, 90] deg: {name} takes "
                             "zenith angles in degrees")


def _host_values(value) -> np.ndarray | None:
    """The finite values of a host number or array, flat; None for JAX arrays and tracers."""
    if not isinstance(value, (int, float, list, tuple, np.ndarray, np.generic)):
        return None  # a JAX array or tracer (or anything else): not looked at
    try:
        values = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):  # e.g. a list holding tracers
        return None
    return values[np.isfinite(values)]
