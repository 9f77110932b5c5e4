"""What to measure: incidences, reflection zeniths and azimuths, as motor positions.

A plan comes from the CLI's options or from a TOML file (`load_plan`) with the same keys as
`Plan.to_dict`::

    # brdfjax measurement plan
    incidence = [10, 30, 50]   # incidence angles, deg (motor B)
    theta_r = [-85, 85, 1]     # signed reflection zenith: start, stop, step, deg (motor C);
                               # negative: the source side, positive: the specular side
    azimuth = [0]              # detector-arm azimuths, deg (motor A); 0: in plane
    average = 5                # integrations averaged per reading
    integration_ms = 20        # milliseconds per integration
    beam_margin = 5            # skip geometries with the detector this close to the source, deg

Only ``incidence`` is required. For each incidence and each azimuth the detector sweeps the
zenith list, alternately up and down so it never travels back across. Geometries where the
detector is within ``beam_margin`` of the source direction are skipped: there the detector
arm stands in the incident beam (in plane, the signed angle near ``-incidence``). A
geometry reached twice (``C = 0`` at every azimuth is the surface normal) is measured once.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, fields
from functools import cached_property

import numpy as np

from brdfjax.data.measurements import DataError
from brdfjax.instrument.protocol import MOTOR_NAMES, detector_direction, source_detector_angle


@dataclass(frozen=True)
class Point:
    """One geometry of a plan: its position in the plan and the motor angles (degrees)."""

    index: int
    a: float
    b: float
    c: float

    @property
    def angles(self) -> tuple[float, float, float]:
        """(theta_i, theta_r, phi_r) in degrees, ``phi_r = 180`` on the specular side."""
        return (self.b, *detector_direction(self.a, self.c))


@dataclass(frozen=True)
class Plan:
    """A measurement plan.

    Attributes:
        incidence: incidence angles in degrees (motor B).
        theta_r: signed reflection zenith (start, stop, step) in degrees, stop included.
        azimuth: detector-arm azimuths in degrees (motor A).
        average: integrations per reading.
        integration_ms: milliseconds per integration.
        beam_margin: degrees; closer to the source direction, a geometry is skipped.
    """

    incidence: tuple[float, ...]
    theta_r: tuple[float, float, float] = (-85.0, 85.0, 1.0)
    azimuth: tuple[float, ...] = (0.0,)
    average: int = 5
    integration_ms: float = 20.0
    beam_margin: float = 5.0

    def __post_init__(self):
        for name in ("incidence", "theta_r", "azimuth"):
            object.__setattr__(self, name, tuple(float(x) for x in getattr(self, name)))
        start, stop, step = self.theta_r if len(self.theta_r) == 3 else (0, -1, 0)
        problems = [
            (not self.incidence, "no incidence angles"),
            (len(self.theta_r) != 3, "theta_r must be [start, stop, step]"),
            (not (step > 0 and start <= stop), "theta_r needs start <= stop and step > 0"),
            (not self.azimuth, "no azimuths"),
            (int(self.average) != self.average or self.average < 1,
             "average must be a whole number >= 1"),
            (not self.integration_ms > 0, "integration_ms must be positive"),
            (not self.beam_margin >= 0, "beam_margin must not be negative"),
        ]
        for bad, message in problems:
            if bad:
                raise ValueError(f"measurement plan: {message}")
        object.__setattr__(self, "average", int(self.average))

    @classmethod
    def from_dict(cls, table: dict, source=None) -> Plan:
        """A plan from the keys of `to_dict` (a TOML file's, or a journal's)."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(table) - known)
        if unknown:
            raise DataError(f"unknown plan key(s) {', '.join(unknown)}", source,
                            hint=f"known keys: {', '.join(sorted(known))}")
        if "incidence" not in table:
            raise DataError("the plan has no 'incidence' list", source)
        try:
            return cls(**table)
        except (TypeError, ValueError) as problem:
            raise DataError(str(problem), source) from None

    def to_dict(self) -> dict:
        """The plan as plain values (the TOML file's keys)."""
        return {f.name: (list(v) if isinstance(v := getattr(self, f.name), tuple) else v)
                for f in fields(self)}

    @property
    def signed_zeniths(self) -> np.ndarray:
        """The detector's signed zenith angles (motor C), degrees."""
        start, stop, step = self.theta_r
        return np.round(np.arange(start, stop + step / 2, step), 6)

    @cached_property
    def _layout(self) -> tuple[tuple[Point, ...], int]:
        points, seen, blocked = [], set(), 0
        zeniths = self.signed_zeniths
        for b in self.incidence:
            for a in self.azimuth:
                for c in map(float, zeniths):
                    theta_i, theta_r, phi_r = Point(0, a, b, c).angles
                    key = (theta_i, theta_r, 0.0 if theta_r == 0 else round(phi_r, 6))
                    if key in seen:
                        continue
                    seen.add(key)
                    if round(source_detector_angle(b, a, c), 6) < self.beam_margin:
                        blocked += 1
                        continue
                    points.append(Point(len(points), a, b, c))
                zeniths = zeniths[::-1]
        return tuple(points), blocked

    @property
    def points(self) -> tuple[Point, ...]:
        """Every geometry to measure, in measuring order."""
        return self._layout[0]

    @property
    def blocked(self) -> int:
        """How many geometries were skipped because the detector would block the source."""
        return self._layout[1]

    def check_limits(self, limits: dict) -> None:
        """Raise `ValueError` if a point needs a motor outside its range.

        Args:
            limits: ``{motor: (min_deg, max_deg)}`` as the instrument reports them.
        """
        for motor, (low, high) in limits.items():
            used = [getattr(p, motor.lower()) for p in self.points]
            outside = [x for x in used if not low <= x <= high]
            if outside:
                worst = max(outside, key=lambda x: max(low - x, x - high))
                raise ValueError(
                    f"the plan needs motor {motor} ({MOTOR_NAMES[motor]}) at {worst:g} deg, "
                    f"outside the instrument's range {low:g} to {high:g} deg; nothing was "
                    "moved: change the plan")


def load_plan(path) -> Plan:
    """Read a TOML measurement plan (see the module docstring)."""
    try:
        with open(path, "rb") as handle:
            table = tomllib.load(handle)
    except FileNotFoundError:
        raise DataError("no such plan file", path) from None
    except tomllib.TOMLDecodeError as problem:
        raise DataError(f"not valid TOML: {problem}", path) from None
    return Plan.from_dict(table, source=path)
