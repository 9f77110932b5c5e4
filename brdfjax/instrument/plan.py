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

A plan may instead list its geometries, measured in the order given (``brdfjax plan``
writes such files)::

    geometries = [[30, 20, 180], [30, 45, 0], [50, 10, 90]]  # [theta_i, theta_r, phi_r], deg
    average = 5

with no ``incidence``, ``theta_r`` or ``azimuth``. Each geometry goes to motors as
`motor_angles` says (``phi_r`` below 180: ``A = phi_r`` and ``C = -theta_r``; from 180:
``A = phi_r - 180`` and ``C = theta_r``; the normal keeps the arm's azimuth). A geometry past
a motor's range (`MOTOR_LIMITS`, those of the protocol) or with the detector within
``beam_margin`` of the source, or one listed twice, is refused with the entry named; the
instrument's own limits are checked again when it answers (`Plan.check_limits`).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, fields
from functools import cached_property

import numpy as np

from brdfjax.data.measurements import DataError, geometry_keys
from brdfjax.instrument.protocol import MOTOR_NAMES, detector_direction, source_detector_angle
from brdfjax.instrument.simulator import MOTOR_LIMITS

# Degrees: a geometry with the detector closer than this to the source is not measured
# (the default ``beam_margin``; the detector head itself blocks within
# `brdfjax.instrument.simulator.BLOCKED_DEGREES`).
BEAM_MARGIN = 5.0
GRID_KEYS = ("incidence", "theta_r", "azimuth")


def motor_angles(theta_i: float, theta_r: float, phi_r: float,
                 normal_azimuth: float = 0.0) -> tuple[float, float, float]:
    """The motor angles ``(A, B, C)`` in degrees that put the detector at ``(theta_r,
    phi_r)`` for the incidence ``theta_i`` (degrees): ``phi_r`` in [0, 180) by ``A = phi_r``
    and ``C = -theta_r`` (the source side of the arm's plane), in [180, 360) by ``A = phi_r
    - 180`` and ``C = theta_r``, so that ``A`` stays in [0, 180) and the plane of incidence
    is ``A = 0``; the normal (``theta_r = 0``) at ``A = normal_azimuth``, where the arm
    already is. `Point.angles` is its inverse."""
    if abs(theta_r) < 1e-9:
        return float(normal_azimuth), float(theta_i), 0.0
    phi = round(float(phi_r) % 360.0, 6) % 360.0
    if phi < 180.0:
        return phi, float(theta_i), -float(theta_r)
    return phi - 180.0, float(theta_i), float(theta_r)


def unreachable(theta_i: float, theta_r: float, phi_r: float, *,
                beam_margin: float = BEAM_MARGIN, limits: dict | None = None) -> str | None:
    """Why the instrument cannot measure this geometry (degrees), or None if it can: a motor
    past its range (``limits``, ``{motor: (low, high)}``, by default `MOTOR_LIMITS`) or the
    detector within ``beam_margin`` degrees of the source."""
    if not all(np.isfinite([theta_i, theta_r, phi_r])):
        return "an angle is not a finite number"
    if theta_r < 0:
        return f"theta_r {theta_r:g} deg is negative (theta_r is a zenith angle, 0 to 90)"
    a, b, c = motor_angles(theta_i, theta_r, phi_r)
    for motor, value in zip("ABC", (a, b, c)):
        low, high = (MOTOR_LIMITS if limits is None else limits)[motor]
        if not low - 1e-9 <= value <= high + 1e-9:
            return (f"needs motor {motor} ({MOTOR_NAMES[motor]}) at {value:g} deg, outside "
                    f"its range {low:g} to {high:g} deg")
    angle = source_detector_angle(b, a, c)
    if round(angle, 6) < beam_margin:
        return (f"the detector would be {angle:.3g} deg from the source, in its beam (the "
                f"plan's beam_margin is {beam_margin:g} deg)")
    return None


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
        beam_margin: degrees; closer to the source direction, a geometry is skipped (a
            grid's) or refused (a listed one).
        geometries: ``((theta_i, theta_r, phi_r), ...)`` in degrees, measured in this order,
            instead of the grid of ``incidence``, ``theta_r`` and ``azimuth``.
    """

    incidence: tuple[float, ...] = ()
    theta_r: tuple[float, float, float] = (-85.0, 85.0, 1.0)
    azimuth: tuple[float, ...] = (0.0,)
    average: int = 5
    integration_ms: float = 20.0
    beam_margin: float = BEAM_MARGIN
    geometries: tuple[tuple[float, float, float], ...] = ()

    def __post_init__(self):
        for name in ("incidence", "theta_r", "azimuth"):
            object.__setattr__(self, name, tuple(float(x) for x in getattr(self, name)))
        object.__setattr__(self, "geometries", _geometries(self.geometries))
        start, stop, step = self.theta_r if len(self.theta_r) == 3 else (0, -1, 0)
        problems = [
            (bool(self.incidence) and bool(self.geometries),
             "give either incidence (a grid) or geometries, not both"),
            (not self.incidence and not self.geometries, "no incidence angles"),
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
        self._check_geometries()

    def _check_geometries(self, limits: dict | None = None) -> None:
        """Raise `ValueError` naming the first listed geometry the instrument cannot measure
        (``limits`` as in `unreachable`), or one listed twice."""
        seen = {}
        for k, geometry in enumerate(self.geometries):
            why = unreachable(*geometry, beam_margin=self.beam_margin, limits=limits)
            key = tuple(geometry_keys(*geometry)[0])
            if why is None and key in seen:
                why = f"the same geometry as geometries[{seen[key]}]"
            if why is not None:
                raise ValueError(f"measurement plan: geometries[{k}] = "
                                 f"[{', '.join(f'{x:g}' for x in geometry)}]: {why}; nothing "
                                 "was moved: change the plan")
            seen[key] = k

    @classmethod
    def from_dict(cls, table: dict, source=None) -> Plan:
        """A plan from the keys of `to_dict` (a TOML file's, or a journal's)."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(table) - known)
        if unknown:
            raise DataError(f"unknown plan key(s) {', '.join(unknown)}", source,
                            hint=f"known keys: {', '.join(sorted(known))}")
        if "geometries" in table:
            grid = [key for key in GRID_KEYS if key in table]
            if grid:
                raise DataError(f"the plan lists geometries and also has {', '.join(grid)}",
                                source, hint="give either the geometries or a grid")
        elif "incidence" not in table:
            raise DataError("the plan has no 'incidence' list (nor 'geometries')", source)
        try:
            return cls(**table)
        except (TypeError, ValueError) as problem:
            raise DataError(str(problem), source) from None

    def to_dict(self) -> dict:
        """The plan as plain values (the TOML file's keys): the grid's keys, or
        ``geometries``."""
        skip = GRID_KEYS if self.geometries else ("geometries",)
        return {f.name: _plain(getattr(self, f.name)) for f in fields(self)
                if f.name not in skip}

    def to_toml(self, comment: str = "") -> str:
        """The plan as a TOML file that `load_plan` reads back (``comment`` lines first)."""
        lines = [f"# {line}" for line in ["brdfjax measurement plan", *comment.splitlines()]]
        for key, value in self.to_dict().items():
            if key == "geometries":
                lines.append("geometries = [  # [theta_i, theta_r, phi_r], deg, in this order")
                lines += [f"  [{', '.join(_number(x) for x in g)}]," for g in value]
                lines.append("]")
            elif isinstance(value, list):
                lines.append(f"{key} = [{', '.join(_number(x) for x in value)}]")
            else:
                lines.append(f"{key} = {_number(value)}")
        return "\n".join(lines) + "\n"

    @property
    def signed_zeniths(self) -> np.ndarray:
        """The detector's signed zenith angles (motor C), degrees."""
        start, stop, step = self.theta_r
        return np.round(np.arange(start, stop + step / 2, step), 6)

    @cached_property
    def _layout(self) -> tuple[tuple[Point, ...], int]:
        if self.geometries:
            points, a = [], 0.0
            for geometry in self.geometries:
                a, b, c = motor_angles(*geometry, normal_azimuth=a)
                points.append(Point(len(points), a, b, c))
            return tuple(points), 0
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
        if self.geometries:  # names the entry
            self._check_geometries({**MOTOR_LIMITS, **limits})
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


def _geometries(given) -> tuple:
    """``given`` as a tuple of ``(theta_i, theta_r, phi_r)`` float tuples; `ValueError`
    naming the first entry that is not three numbers."""
    rows = []
    for k, row in enumerate(given):
        try:
            values = () if isinstance(row, str) else tuple(float(x) for x in row)
        except (TypeError, ValueError):
            values = ()
        if len(values) != 3:
            raise ValueError(f"measurement plan: geometries[{k}] = {row!r}: give "
                             "[theta_i, theta_r, phi_r] in degrees")
        rows.append(values)
    return tuple(rows)


def _plain(value):
    """Tuples (nested too) as lists, for TOML and JSON."""
    return [_plain(v) for v in value] if isinstance(value, tuple) else value


def _number(value) -> str:
    """A number as TOML writes it: integers without a decimal point."""
    return str(int(value)) if float(value).is_integer() else repr(float(value))

