"""Measured BRDF data: the `Measurements` type and the checks every reader applies.

Host-side only (numpy): readers build a `Measurements`, the fitter turns it into arrays.
Angles are stored in radians with the project's convention (``docs/model.md``): ``phi_r = pi``
is the specular half of the plane of incidence, ``phi_r = 0`` the source side.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from brdfjax.angles import TOLERANCE, check_radians


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
# A brdf value more than 10**OUTLIER_DECADES times the median |brdf| of its file is an
# outlier. The real files of `brdfjax.datasets` peak at most 150 times
# their median (NiTE black on steel, specular at 70 deg); a specular peak of a glossy sample over
# its diffuse floor reaches 1e4-1e6 on instruments with apertures of 1e-4 to 1e-3 sr
# (f_r <= 1 / (aperture cos theta_r)). Eight decades leave that margin, and still catch
# every corrupt value a fit would choke on (1e30, 1e308) and mistyped exponents (e+10).
# The median is robust: a few corrupt values cannot move it, so they stand out against it
# however many decades they lie above. Data whose median is 0 have no scale and no outliers.
OUTLIER_DECADES = 8


@dataclass(frozen=True)
class IncidenceBins:
    """Points grouped by incidence (`Measurements.incidence_bins`).

    Attributes:
        index: the bin of each point, shape (N,), 0 for the lowest incidences.
        labels: one label per bin, e.g. ``"30 deg"`` or ``"20-35 deg"``.
    """

    index: np.ndarray
    labels: tuple

    def label_of_points(self) -> np.ndarray:
        """The label of each point's bin, shape (N,)."""
        return np.asarray(self.labels, dtype=object)[self.index]


@dataclass(frozen=True)
class Measurements:
    """BRDF measurements at N points.

    Attributes:
        theta_i, theta_r, phi_r: angles in radians, shape (N,).
        brdf: measured BRDF in 1/sr, shape (N,).
        sigma: optional per-point standard uncertainty of ``brdf`` (1/sr), shape (N,).
        weights: optional per-point weights of Eq. (6) (g1 g2 of the paper), shape (N,).
        metadata: sample name, wavelength, source and anything else worth keeping (a
            brdfjax CSV's ``source`` line keeps where its data first came from).
        path: the file they were read from (set by `brdfjax.load`; errors name it), None
            for data made in memory.
    """

    theta_i: np.ndarray
    theta_r: np.ndarray
    phi_r: np.ndarray
    brdf: np.ndarray
    sigma: np.ndarray | None = None
    weights: np.ndarray | None = None
    metadata: dict = field(default_factory=dict)
    path: str | None = None

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
    def wavelength_nm(self) -> float | None:
        """The metadata's wavelength in nm as a number (a CSV header gives it as text), or
        None."""
        value = self.metadata.get("wavelength_nm")
        return None if value in (None, "") else float(value)

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

    @property
    def has_brdf(self) -> bool:
        """False for geometry alone (`brdfjax.data.formats.load_geometry`: every brdf NaN)."""
        return not bool(np.all(np.isnan(self.brdf)))

    def geometries(self) -> np.ndarray:
        """Each point's `geometry_keys` row, (N, 3): equal rows, the same geometry."""
        return geometry_keys(*np.degrees([self.theta_i, self.theta_r, self.phi_r]))

    def repeat_groups(self) -> np.ndarray:
        """The index of each point's geometry among the distinct geometries, shape (N,).

        Points with the same index were measured at the same geometry (`geometry_keys`);
        each is kept as its own reading.
        """
        return np.unique(self.geometries(), axis=0, return_inverse=True)[1].reshape(-1)

    def incidence_bins(self, max_bins: int = 8) -> IncidenceBins:
        """Group the points by incidence angle, for summaries and cross-validation folds.

        With at most ``max_bins`` distinct incidences (to 1e-6 deg), each is its own bin.
        Otherwise (scattered geometry, every point with its own incidence) the range is cut
        into at most ``max_bins`` bins holding about the same number of points: the edges
        are quantiles of theta_i rounded to whole degrees (so bins read as "20-35 deg"),
        repeated edges merged, and the outer edges the floor of the smallest and the
        ceiling of the largest incidence. A bin holds ``lower <= theta_i < upper``; the last
        also its upper edge.

        Args:
            max_bins: the most bins to make (at least 1).

        Returns:
            `IncidenceBins`: ``index`` (N,) in 0..k-1, ordered by incidence; ``labels``.
        """
        if max_bins < 1:
            raise ValueError(f"max_bins must be at least 1, got {max_bins}")
        theta = np.round(np.degrees(self.theta_i), 6)
        distinct, index = np.unique(theta, return_inverse=True)
        if len(distinct) <= max_bins:
            return IncidenceBins(index.reshape(-1), tuple(f"{d:g} deg" for d in distinct))
        quantiles = np.quantile(theta, np.linspace(0, 1, max_bins + 1)[1:-1])
        edges = np.unique(np.concatenate([[np.floor(theta.min())], np.round(quantiles),
                                          [np.ceil(theta.max())]]))
        raw = np.clip(np.searchsorted(edges, theta, side="right") - 1, 0, len(edges) - 2)
        used, index = np.unique(raw, return_inverse=True)
        labels = tuple(f"{edges[k]:g}-{edges[k + 1]:g} deg" for k in used)
        return IncidenceBins(index.reshape(-1), labels)

    def _arrays(self) -> dict:
        return {k: getattr(self, k)
                for k in ("theta_i", "theta_r", "phi_r", "brdf", "sigma", "weights")}


def geometry_keys(theta_i_deg, theta_r_deg, phi_r_deg) -> np.ndarray:
    """One row per point that is equal for points at the same geometry, shape (N, 3).

    Angles agree when they agree to 1e-6 deg; ``phi_r`` is taken modulo 360, and the
    normal direction (``theta_r = 0``) is one direction whatever its azimuth.
    """
    key = np.round(np.stack([np.asarray(x, dtype=float).reshape(-1)
                             for x in (theta_i_deg, theta_r_deg, phi_r_deg)], axis=1), 6)
    key[:, 2] = np.mod(key[:, 2], 360.0)
    key[key[:, 1] == 0, 2] = 0.0
    return key


@dataclass(frozen=True)
class RepeatSummary:
    """How often geometries repeat in a data set, and how much their readings differ.

    Attributes:
        geometries: the number of geometries read more than once.
        readings: the readings at those geometries, all together.
        most: the most readings at one geometry.
        median_spread, max_spread: over the repeated geometries, the relative standard
            deviation of their readings (``std / |mean|``, ddof 1); NaN where undefined.
    """

    geometries: int
    readings: int
    most: int
    median_spread: float
    max_spread: float


def repeat_summary(data: Measurements) -> RepeatSummary:
    """Count the repeated geometries of ``data`` and the spread of their readings."""
    groups = data.repeat_groups()
    counts = np.bincount(groups)
    repeated = np.flatnonzero(counts > 1)
    spreads = []
    for group in repeated:
        values = data.brdf[groups == group]
        mean = abs(float(np.mean(values)))
        spreads.append(float(np.std(values, ddof=1)) / mean if mean > 0 else np.nan)
    finite = [s for s in spreads if np.isfinite(s)]
    return RepeatSummary(
        geometries=int(repeated.size), readings=int(counts[repeated].sum()),
        most=int(counts.max()) if counts.size else 0,
        median_spread=float(np.median(finite)) if finite else np.nan,
        max_spread=float(np.max(finite)) if finite else np.nan)


def validate(data: Measurements, path=None, lines=None,
             geometry_only: bool = False) -> Measurements:
    """Check measurements for what would silently spoil a fit; raise `DataError` if any.

    Repeated geometries are not an error: every reading is an independent measurement
    (see `repeat_summary`). The brdf values are checked for non-finite values, for outliers
    (`OUTLIER_DECADES`) and for negative values beyond noise.

    Args:
        data: the measurements.
        path: the file they came from, for the message.
        lines: the file line number of each point, for the message.
        geometry_only: check the angles only (``brdf`` is NaN, see
            `brdfjax.data.formats.load_geometry`).

    Returns:
        ``data`` unchanged.
    """
    problem = NO_POINTS if len(data) == 0 else _problems(
        {name: values[None] for name, values in data._arrays().items() if values is not None},
        geometry_only).get(0)
    if problem is not None:
        index, message, hint = problem
        line = None if lines is None or index is None else int(lines[index])
        raise DataError(message, path, line, hint)
    return data


def checked(data, what: str, geometry_only: bool = False) -> Measurements:
    """``data`` `validate`-d for a library call named ``what``, which needs `Measurements`
    (built in Python, they have not been through `brdfjax.load`'s checks)."""
    if not isinstance(data, Measurements):
        raise TypeError(f"{what} takes Measurements, got {type(data).__name__}: read a file "
                        "with brdfjax.load(path), or build them with "
                        "Measurements.from_degrees(theta_i, theta_r, phi_r, brdf)")
    try:
        check_radians(("phi_r",), theta_i=data.theta_i, theta_r=data.theta_r, phi_r=data.phi_r)
    except ValueError as problem:
        raise DataError(f"{problem} (Measurements.from_degrees takes degrees)",
                        data.path) from None
    if len(data) == 0:
        raise DataError(NO_READINGS[1], data.path, None, NO_READINGS[2])
    return validate(data, data.path, geometry_only=geometry_only)


def failures(samples) -> dict[int, str]:
    """`validate` of many measurement sets at once: the message of each that fails, by
    position in ``samples`` (each named by its `Measurements.name`).

    Sets of one length (and the same optional arrays) are checked together, as arrays with
    a leading axis: a cube's block of a thousand pixels in milliseconds, where one
    `validate` each took tens of microseconds, more than a Ross-Li pixel's fit.
    """
    groups: dict[tuple, list[int]] = {}
    for position, data in enumerate(samples):
        shape = (len(data), data.sigma is None, data.weights is None)
        groups.setdefault(shape, []).append(position)
    found = {}
    for (points, *_), positions in groups.items():
        rows = [samples[p] for p in positions]
        if points == 0:
            problems = dict.fromkeys(range(len(rows)), NO_READINGS)
        else:
            arrays = {name: np.stack([getattr(data, name) for data in rows])
                      for name, values in rows[0]._arrays().items() if values is not None}
            problems = _problems(arrays)
        for row, (_, message, hint) in problems.items():
            found[positions[row]] = str(DataError(message, rows[row].name, None, hint))
    return found


# The problem of a measurement set without points, as `_problems` gives the others': read
# from a file (`validate`), and a sample of many (`failures`: a cube's pixel whose every
# reading is NaN) or built in Python (`checked`), which has no lines.
NO_POINTS = (None, "no measurements", "the file has a header but no data lines")
NO_READINGS = (None, "the sample has no readings",
               "every reading is NaN or none was given: nothing to fit")


def _problems(arrays: dict, geometry_only: bool = False) -> dict[int, tuple]:
    """The first problem of each row of stacked measurement arrays (G, N), N > 0, as
    ``{row: (point index or None, message, hint)}`` (rows without one are absent): the
    checks of `validate`, in its order."""
    problems: dict[int, tuple] = {}

    def new(bad) -> list[tuple]:
        """(row, its first bad point) of each row of ``bad`` (G, N) not flagged yet; for
        ``bad`` (G,), of whole rows, the point is None."""
        rows = bad.any(axis=1) if bad.ndim == 2 else bad
        return [(row, int(np.argmax(bad[row])) if bad.ndim == 2 else None)
                for row in np.flatnonzero(rows) if row not in problems]

    angles = ("theta_i", "theta_r", "phi_r")
    for name in (angles if geometry_only else arrays):
        values = arrays[name]
        for row, i in new(~np.isfinite(values)):
            problems[row] = (i, f"{name} is {values[row, i]}",
                             "every value must be a finite number")
    with np.errstate(invalid="ignore", over="ignore"):  # rows flagged above hold NaN or inf
        theta = np.degrees(np.concatenate([arrays["theta_i"], arrays["theta_r"]], axis=1))
        largest = theta.max(axis=1)
        points = arrays["theta_i"].shape[1]
        radians = (largest > 0) & (largest <= np.pi / 2 + 1e-6) & (points > 3)
        for row, _ in new(radians):  # every zenith angle tiny
            problems[row] = (None, f"all zenith angles are at most {largest[row]:.4f} deg",
                             "they look like radians; files hold degrees (multiply by 180/pi)")
        for name in ("theta_i", "theta_r"):
            deg = np.degrees(arrays[name])
            for row, i in new((deg < -1e-9) | (deg > 90 + 1e-9)):
                problems[row] = (i, f"{name} = {deg[row, i]:g} deg is outside [0, 90]",
                                 ("zenith angles are measured from the surface normal; a "
                                  "signed in-plane angle must be converted to a zenith angle "
                                  "and an azimuth (0 or 180)"))
        azimuth = np.degrees(arrays["phi_r"])
        for row, i in new(np.abs(azimuth) > 360 + np.degrees(TOLERANCE)):  # check_radians
            problems[row] = (i, f"phi_r = {azimuth[row, i]:g} deg is beyond one turn",
                             ("azimuths lie in [-360, 360] deg: 0 is the source side, 180 "
                              "the specular side"))
        if geometry_only:
            return problems
        brdf = arrays["brdf"]
        magnitude = np.abs(brdf)
        median = np.median(magnitude, axis=1)
        beyond = (magnitude > median[:, None] * 10.0**OUTLIER_DECADES) & (median[:, None] > 0)
        for row, i in new(beyond):
            problems[row] = (i, (f"brdf = {brdf[row, i]:g} is an outlier: more than "
                                 f"1e{OUTLIER_DECADES} times the median |brdf| "
                                 f"({median[row]:.3g}); {int(beyond[row].sum())} such value(s)"),
                             ("a unit or transcription error? fix or remove the value(s) "
                              "before fitting"))
        scale = np.maximum(magnitude.max(axis=1, keepdims=True), 1e-300)
        for row, i in new(brdf < -NEGATIVE_TOLERANCE * scale):
            problems[row] = (i, f"brdf = {brdf[row, i]:g} is negative beyond noise",
                             (f"values below -{NEGATIVE_TOLERANCE:g} x the largest |brdf| are "
                              "not noise: check the blank subtraction or the sign convention"))
    for name in ("sigma", "weights"):
        values = arrays.get(name)
        if values is not None:
            for row, i in new(values < 0 if name == "weights" else values <= 0):
                problems[row] = (i, f"{name} = {values[row, i]:g} is not positive", "")
    return problems


# More distinct incidences than this and the data count as scattered: their folds are
# `SCATTERED_BINS` bins of about equal point count (`incidence_groups`).
MAX_FOLDS = 24
SCATTERED_BINS = 8


def incidence_groups(data: Measurements) -> list[tuple[str, float, float, np.ndarray]]:
    """The folds' held-out groups: ``(label, low, high, mask)`` in incidence order.

    One group per distinct incidence, or, for scattered geometry (more than `MAX_FOLDS`
    distinct incidences), `SCATTERED_BINS` bins of about equal point count with edges
    rounded to whole degrees (`Measurements.incidence_bins`); ``low``
    and ``high`` are the smallest and largest incidence in the group (degrees).
    """
    degrees = np.round(np.degrees(data.theta_i), 6)
    distinct = np.unique(degrees).size
    bins = data.incidence_bins(max_bins=distinct if distinct <= MAX_FOLDS else SCATTERED_BINS)
    groups = []
    for k, label in enumerate(bins.labels):
        mask = bins.index == k
        groups.append((label.removesuffix(" deg"), float(degrees[mask].min()),
                       float(degrees[mask].max()), mask))
    return groups
