"""Measured BRDF data: the `Measurements` type and the checks every reader applies.

Host-side only (numpy): readers build a `Measurements`, the fitter turns it into arrays.
Angles are stored in radians with the project's convention (``docs/model.md``): ``phi_r = pi``
is the specular half of the plane of incidence, ``phi_r = 0`` the source side.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np


class DataError(ValueError):
    """Bad input data: says which file, which line, what is wrong and what to do."""

    def __init__(self, message: str, path=None, line: int | None = None, hint: str = ""):
        where = ""
        if path is not None:
            where = f"{path}:{line}: " if line is not None else f"{path}: "
        text = where + message + (f" ({hint})" if hint else "")
        super().__init__(text)
        self.path, self.line, self.hint = path, line, hint


# A measured BRDF may dip below zero by noise (blank subtraction), not by much more.
NEGATIVE_TOLERANCE = 0.05


@dataclass(frozen=True)
class Measurements:
    """BRDF measurements at N points.

    Attributes:
        theta_i, theta_r, phi_r: angles in radians, shape (N,).
        brdf: measured BRDF in 1/sr, shape (N,).
        sigma: optional per-point standard uncertainty of ``brdf`` (1/sr), shape (N,).
        weights: optional per-point weights of Eq. (6) (g1 g2 of the paper), shape (N,).
        metadata: sample name, wavelength, source and anything else worth keeping.
    """

    theta_i: np.ndarray
    theta_r: np.ndarray
    phi_r: np.ndarray
    brdf: np.ndarray
    sigma: np.ndarray | None = None
    weights: np.ndarray | None = None
    metadata: dict = field(default_factory=dict)

    def __post_init__(self):
        for name in ("theta_i", "theta_r", "phi_r", "brdf", "sigma", "weights"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, np.asarray(value, dtype=float).reshape(-1))
        n = self.brdf.size
        for name in ("theta_i", "theta_r", "phi_r", "sigma", "weights"):
            value = getattr(self, name)
            if value is not None and value.size != n:
                raise ValueError(f"{name} has {value.size} values, brdf has {n}")

    @classmethod
    def from_degrees(cls, theta_i, theta_r, phi_r, brdf, **kwargs) -> Measurements:
        """Measurements from angles in degrees."""
        return cls(np.radians(theta_i), np.radians(theta_r), np.radians(phi_r), brdf, **kwargs)

    def __len__(self) -> int:
        return self.brdf.size

    @property
    def name(self) -> str:
        return str(self.metadata.get("sample", "sample"))

    @property
    def incidences_deg(self) -> np.ndarray:
        """The distinct incidence angles in degrees, sorted."""
        return np.unique(np.round(np.degrees(self.theta_i), 6))

    @property
    def in_plane(self) -> bool:
        """True when every point lies in the plane of incidence."""
        return bool(np.all(np.abs(np.sin(self.phi_r)) < 1e-9))

    def select(self, mask) -> Measurements:
        """The subset of points where ``mask`` is true."""
        mask = np.asarray(mask, dtype=bool)
        pick = {k: (None if v is None else v[mask]) for k, v in self._arrays().items()}
        return dataclasses.replace(self, **pick)

    def at_incidences(self, degrees) -> Measurements:
        """The points whose incidence angle is one of ``degrees`` (to 1e-6 deg)."""
        return self.select(self.incidence_mask(degrees))

    def incidence_mask(self, degrees) -> np.ndarray:
        """True at the points whose incidence angle is one of ``degrees`` (to 1e-6 deg)."""
        theta = np.degrees(self.theta_i)
        wanted = np.asarray(degrees, dtype=float).reshape(-1)
        return np.any(np.abs(theta[:, None] - wanted[None, :]) < 1e-6, axis=1)

    def _arrays(self) -> dict:
        return {k: getattr(self, k)
                for k in ("theta_i", "theta_r", "phi_r", "brdf", "sigma", "weights")}


def validate(data: Measurements, path=None, lines=None) -> Measurements:
    """Check measurements for what would silently spoil a fit; raise `DataError` if any.

    Args:
        data: the measurements.
        path: the file they came from, for the message.
        lines: the file line number of each point, for the message.

    Returns:
        ``data`` unchanged.
    """

    def fail(index, message, hint=""):
        line = None if lines is None or index is None else int(lines[index])
        raise DataError(message, path, line, hint)

    if len(data) == 0:
        fail(None, "no measurements", "the file has a header but no data lines")
    for name, values in data._arrays().items():
        if values is None:
            continue
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            fail(bad[0], f"{name} is {values[bad[0]]}", "every value must be a finite number")
    theta = np.degrees(np.concatenate([data.theta_i, data.theta_r]))
    if len(data) > 3 and 0 < theta.max() <= np.pi / 2 + 1e-6:
        fail(None, f"all zenith angles are at most {theta.max():.4f} deg",
             "they look like radians; files hold degrees (multiply by 180/pi)")
    for name in ("theta_i", "theta_r"):
        deg = np.degrees(getattr(data, name))
        bad = np.flatnonzero((deg < -1e-9) | (deg > 90 + 1e-9))
        if bad.size:
            fail(bad[0], f"{name} = {deg[bad[0]]:g} deg is outside [0, 90]",
                 "zenith angles are measured from the surface normal; a signed in-plane "
                 "angle must be converted to a zenith angle and an azimuth (0 or 180)")
    scale = max(float(np.max(np.abs(data.brdf))), 1e-300)
    bad = np.flatnonzero(data.brdf < -NEGATIVE_TOLERANCE * scale)
    if bad.size:
        fail(bad[0], f"brdf = {data.brdf[bad[0]]:g} is negative beyond noise",
             f"values below -{NEGATIVE_TOLERANCE:g} x the largest |brdf| are not noise: "
             "check the blank subtraction or the sign convention")
    for name in ("sigma", "weights"):
        values = getattr(data, name)
        if values is not None:
            bad = np.flatnonzero(values < 0 if name == "weights" else values <= 0)
            if bad.size:
                fail(bad[0], f"{name} = {values[bad[0]]:g} is not positive")
    key = np.round(np.degrees(np.stack([data.theta_i, data.theta_r,
                                        np.mod(data.phi_r, 2 * np.pi)], axis=1)), 6)
    key[key[:, 1] == 0, 2] = 0  # the normal direction has no azimuth
    _, first, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
    if np.any(counts > 1):
        dup = first[np.argmax(counts > 1)]
        fail(dup, f"geometry (theta_i, theta_r, phi_r) = {tuple(key[dup])} deg appears "
                  f"{counts.max()} times", "average repeated readings before fitting")
    return data
