"""Zemax (OpticStudio) tabular BSDF files (``.bsdf``): read, write, export a fitted model.

The text format, as OpticStudio documents it and the University of Arizona files use it::

    # comment lines
    Source  Measured
    Symmetry  PlaneSymmetrical
    SpectralContent  Monochrome
    ScatterType  BRDF
    SampleRotation  1
    0
    AngleOfIncidence  2
    10  30
    ScatterAzimuth  19
    0  10  ...  180
    ScatterRadial  12
    0  5  ...  90
    Monochrome
    DataBegin
    TIS  0.0387
    <one row per azimuth, one value per radial angle>   (for each angle of incidence)
    ...
    DataEnd

The scatter direction is given relative to the specular direction, not the surface normal:
``ScatterRadial`` is the angle between the scattered and the specular ray, and
``ScatterAzimuth`` turns about the specular ray, with azimuth 0 pointing from the specular
direction toward the surface normal. So in the plane of incidence, for incidence ``I``,
azimuth 0 at radial ``R`` is ``theta_r = |I - R|`` (specular side while ``R < I``, source
side beyond the normal) and azimuth 180 is ``theta_r = I + R`` on the specular side.
Azimuths increase counter-clockwise seen from above the surface; we take azimuth 90 toward
``+y`` (the project's ``0 < phi_r < 180``). Only that handedness is a choice, and it does
not matter for ``PlaneSymmetrical`` files or for the model, which is even in ``phi_r``.

Tables pad directions they have no data for with 0 (below the horizon, and often near
grazing), so the reader drops directions at or below the horizon and exact zeros.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from brdfjax.data.formats import read_text, split_lines
from brdfjax.data.measurements import DataError, Measurements, geometry_keys, validate

SYMMETRIES = ("PlaneSymmetrical", "Asymmetrical")
HORIZON_DEG = 90.0
# Angles that agree to this many decimals of a degree are the same direction.
DECIMALS = 6


# --- geometry ---------------------------------------------------------------------------

def _specular_frame(incidence_deg):
    """Unit vectors (specular, toward the normal, +y) at the specular direction, shape (..., 3)."""
    t = np.radians(np.asarray(incidence_deg, dtype=float))
    zero, one = np.zeros_like(t), np.ones_like(t)
    specular = np.stack([-np.sin(t), zero, np.cos(t)], axis=-1)
    toward_normal = np.stack([np.cos(t), zero, np.sin(t)], axis=-1)
    side = np.stack([zero, one, zero], axis=-1)
    return specular, toward_normal, side


def zemax_to_angles(incidence_deg, azimuth_deg, radial_deg):
    """The project's ``(theta_r, phi_r)`` in degrees of Zemax scatter angles.

    Args:
        incidence_deg: Zemax ``AngleOfIncidence`` (the specular angle), broadcastable.
        azimuth_deg: ``ScatterAzimuth`` about the specular ray, 0 toward the normal.
        radial_deg: ``ScatterRadial``, the angle from the specular ray.

    Returns:
        ``(theta_r, phi_r)`` in degrees, ``phi_r`` in (-180, 180] with 180 the specular
        side; ``theta_r > 90`` lies below the horizon. In-plane points get ``phi_r``
        exactly 0 or 180, and the normal ``phi_r = 0``.
    """
    incidence, azimuth, radial = np.broadcast_arrays(
        *(np.asarray(x, dtype=float) for x in (incidence_deg, azimuth_deg, radial_deg)))
    specular, toward_normal, side = _specular_frame(incidence)
    a, r = np.radians(azimuth)[..., None], np.radians(radial)[..., None]
    direction = np.cos(r) * specular + np.sin(r) * (np.cos(a) * toward_normal
                                                    + np.sin(a) * side)
    x, y, z = np.moveaxis(direction, -1, 0)
    # sin(180 deg) is 1e-16, not 0: snap in-plane points onto the plane.
    y = np.where(np.abs(y) < 1e-12, 0.0, y)
    theta_r = np.degrees(np.arctan2(np.hypot(x, y), z))
    phi_r = np.where(theta_r < 10.0 ** -DECIMALS, 0.0, np.degrees(np.arctan2(y, x)))
    return theta_r, phi_r


def angles_to_zemax(theta_i_deg, theta_r_deg, phi_r_deg):
    """Zemax ``(azimuth, radial)`` in degrees of the project's angles (inverse of above).

    Returns:
        ``(azimuth, radial)``: azimuth in [0, 360), 0 at the specular direction itself.
    """
    theta_i, theta_r, phi_r = np.broadcast_arrays(
        *(np.radians(np.asarray(x, dtype=float)) for x in (theta_i_deg, theta_r_deg,
                                                           phi_r_deg)))
    direction = np.stack([np.sin(theta_r) * np.cos(phi_r), np.sin(theta_r) * np.sin(phi_r),
                          np.cos(theta_r)], axis=-1)
    specular, toward_normal, side = _specular_frame(np.degrees(theta_i))
    along = np.sum(direction * specular, axis=-1)
    u = np.sum(direction * toward_normal, axis=-1)
    v = np.sum(direction * side, axis=-1)
    # atan2 keeps the radial angle accurate next to the specular direction.
    radial = np.degrees(np.arctan2(np.hypot(u, v), along))
    azimuth = np.mod(np.degrees(np.arctan2(v, u)), 360.0)
    azimuth = np.where(radial < 10.0 ** -DECIMALS, 0.0, azimuth)
    return azimuth, radial


# --- reading ----------------------------------------------------------------------------

class _Lines:
    """The file's non-comment lines as (line number, tokens), read front to back."""

    def __init__(self, path, text: str):
        self.path = path
        self.comments = []
        self.items = []
        for number, raw in enumerate(split_lines(text), start=1):
            line = raw.strip()
            if line.startswith("#"):
                self.comments.append(line[1:].strip())
            elif line:
                self.items.append((number, line.split()))
        self.position = 0
        # The last line, named when the file ends early; an empty file has none.
        self.last = len(split_lines(text.rstrip("\r\n"))) if text.strip() else None

    def next(self, expecting: str):
        """The next (line number, tokens); `DataError` at the end of the file."""
        if self.position >= len(self.items):
            raise DataError(f"the file ends where {expecting} should follow", self.path,
                            self.last, "the file looks truncated: it must end with DataEnd")
        item = self.items[self.position]
        self.position += 1
        return item

    def numbers(self, count: int, expecting: str) -> tuple[np.ndarray, list]:
        """The next ``count`` numbers (over as many lines as they take) and their lines."""
        values, lines = [], []
        while len(values) < count:
            number, tokens = self.next(expecting)
            for token in tokens:
                values.append(_number(token, self.path, number, expecting))
                lines.append(number)
        if len(values) != count:
            raise DataError(f"{len(values)} values for {expecting}, expected {count}",
                            self.path, lines[-1], "the count must match the values listed")
        return np.array(values), lines


def _number(token: str, path, line: int, what: str) -> float:
    try:
        return float(token)
    except ValueError:
        raise DataError(f"{token!r} in {what} is not a number", path, line) from None


def _read_header(lines: _Lines) -> tuple[dict, dict]:
    """The keywords up to ``DataBegin`` (name -> text, or array of angles) and their lines."""
    header, where = {}, {}
    while True:
        number, tokens = lines.next("the header or DataBegin")
        keyword = tokens[0]
        if keyword == "DataBegin":
            return header, where
        where[keyword] = number
        if keyword in ("SampleRotation", "AngleOfIncidence", "ScatterAzimuth",
                       "ScatterRadial"):
            if len(tokens) != 2 or not tokens[1].isdigit():
                raise DataError(f"{keyword} must be followed by its count", lines.path, number,
                                f"e.g. '{keyword} 3' and the 3 angles on the next line")
            header[keyword] = lines.numbers(int(tokens[1]), keyword)[0]
        else:
            # Source, Symmetry, SpectralContent, ScatterType, and the spectral label line
            # ("Monochrome") before DataBegin.
            header[keyword] = " ".join(tokens[1:])


def _check_header(header: dict, lines: dict, path) -> None:
    """`DataError` for what the reader cannot turn into BRDF measurements."""
    for keyword in ("AngleOfIncidence", "ScatterAzimuth", "ScatterRadial"):
        if keyword not in header:
            raise DataError(f"no {keyword} in the header", path,
                            hint="a Zemax tabular BSDF header lists AngleOfIncidence, "
                                 "ScatterAzimuth and ScatterRadial before DataBegin")
    scatter = header.get("ScatterType", "BRDF")
    if scatter.upper() != "BRDF":
        raise DataError(f"ScatterType is {scatter}", path, lines.get("ScatterType"),
                        "brdfjax fits reflection (BRDF) data, not transmission")
    spectral = header.get("SpectralContent", "Monochrome")
    if spectral.lower() != "monochrome":
        raise DataError(f"SpectralContent is {spectral}", path, lines.get("SpectralContent"),
                        "brdfjax reads Monochrome tables; export one wavelength per file")
    symmetry = header.get("Symmetry", "PlaneSymmetrical")
    if symmetry.lower() not in (s.lower() for s in SYMMETRIES):
        raise DataError(f"Symmetry is {symmetry}", path, lines.get("Symmetry"),
                        f"brdfjax reads {' or '.join(SYMMETRIES)} tables")
    if len(header.get("SampleRotation", [0.0])) != 1:
        raise DataError("several SampleRotation values (anisotropic data)", path,
                        lines.get("SampleRotation"),
                        "the model is isotropic: export a single sample rotation")


def _read_blocks(lines: _Lines, header: dict):
    """The TIS and the (azimuth x radial) table of each angle of incidence, and row lines."""
    n_az, n_rad = len(header["ScatterAzimuth"]), len(header["ScatterRadial"])
    tis, tables, rows = [], [], []
    for aoi in header["AngleOfIncidence"]:
        what = f"the data of AngleOfIncidence {aoi:g}"
        number, tokens = lines.next(what)
        if tokens[0] != "TIS" or len(tokens) != 2:
            raise DataError(f"expected 'TIS value' to start {what}, found "
                            f"{' '.join(tokens)[:40]!r}", lines.path, number,
                            f"each angle of incidence has a TIS line and {n_az} rows of "
                            f"{n_rad} values")
        tis.append(_number(tokens[1], lines.path, number, "TIS"))
        table, row_lines = [], []
        for k in range(n_az):
            number, tokens = lines.next(f"row {k + 1} of {n_az} of {what}")
            if len(tokens) != n_rad:
                raise DataError(f"{len(tokens)} values in a row of {what}, expected {n_rad} "
                                "(one per ScatterRadial angle)", lines.path, number)
            table.append([_number(t, lines.path, number, what) for t in tokens])
            row_lines.append(number)
        tables.append(table)
        rows.append(row_lines)
    number, tokens = lines.next("DataEnd")
    if tokens[0] != "DataEnd":
        raise DataError(f"expected DataEnd, found {' '.join(tokens)[:40]!r}", lines.path,
                        number, "more data blocks than AngleOfIncidence values")
    return np.array(tis), np.array(tables, dtype=float), np.array(rows)


def read(path, incidence=None, wavelength_nm: float | None = None,
         keep_zeros: bool = False) -> Measurements:
    """Read a Zemax tabular BSDF (BRDF) file as measurements in the project's convention.

    Every table entry becomes a point ``(theta_i, theta_r, phi_r)`` (see the module
    docstring for the conversion). Directions at or below the horizon are dropped, as are
    entries that are exactly 0 (tables pad missing data with 0) unless ``keep_zeros``.
    The specular direction (radial 0), listed once per azimuth row, is one reading when
    its entries agree; entries at one direction with different values are all kept, each
    an independent reading (as the CSV reader keeps repeated rows).

    Args:
        path: the ``.bsdf`` file.
        incidence: an angle of incidence in degrees, or several, to keep (default all).
        wavelength_nm: the wavelength to record in the metadata (the format has none).
        keep_zeros: keep exact zeros above the horizon.

    Returns:
        The validated `Measurements`; ``metadata["tis"]`` holds the file's TIS values.
    """
    path = Path(path)
    lines = _Lines(path, read_text(path))
    header, where = _read_header(lines)
    _check_header(header, where, path)
    tis, tables, rows = _read_blocks(lines, header)
    incidences = header["AngleOfIncidence"]
    keep_aoi = _pick_incidences(incidences, incidence, path)
    aoi, azimuth, radial = np.meshgrid(incidences, header["ScatterAzimuth"],
                                       header["ScatterRadial"], indexing="ij")
    line = np.broadcast_to(rows[:, :, None], tables.shape)
    theta_r, phi_r = zemax_to_angles(aoi, azimuth, radial)
    keep = keep_aoi[:, None, None] & (theta_r < HORIZON_DEG - 1e-9)
    zeros = keep & (tables == 0)
    if not keep_zeros:
        keep &= tables != 0
    angles = np.stack([aoi[keep], theta_r[keep], phi_r[keep]], axis=1)
    angles, brdf, first_lines, copies = _drop_copies(angles, tables[keep], line[keep])
    metadata = _metadata(path, lines.comments, header, wavelength_nm)
    metadata["tis"] = ", ".join(f"{a:g}: {t:g}" for a, t in zip(incidences, tis))
    if not keep_zeros and zeros.any():
        metadata["zeros_dropped"] = int(zeros.sum())
    if copies:
        metadata["copies_dropped"] = (f"{copies} table entries repeating the direction and "
                                      "value of an earlier one (radial 0 in each azimuth row)")
    data = Measurements.from_degrees(*angles.T, brdf, metadata=metadata)
    return validate(data, path, first_lines)


def _pick_incidences(incidences, wanted, path) -> np.ndarray:
    if wanted is None:
        return np.ones(len(incidences), dtype=bool)
    wanted = np.atleast_1d(np.asarray(wanted, dtype=float))
    keep = np.any(np.abs(incidences[:, None] - wanted[None, :]) < 1e-6, axis=1)
    missing = [w for w in wanted if not np.any(np.abs(incidences - w) < 1e-6)]
    if missing:
        raise DataError(f"no AngleOfIncidence {', '.join(f'{m:g}' for m in missing)}", path,
                        hint="the file has " + ", ".join(f"{a:g}" for a in incidences))
    return keep


def _metadata(path, comments, header, wavelength_nm) -> dict:
    """Sample name (a ``Sample:`` comment, else the file name) and what the header says."""
    metadata = {"sample": path.stem}
    for comment in comments:
        key, sep, value = comment.partition(":")
        if sep and key.strip().lower() == "sample" and value.strip():
            metadata["sample"] = value.strip()
        elif sep and key.strip().lower() == "wavelength_nm" and wavelength_nm is None:
            wavelength_nm = _number(value.strip(), path, None, "the wavelength_nm comment")
    if wavelength_nm is not None:
        metadata["wavelength_nm"] = float(wavelength_nm)
    metadata["source"] = str(path)
    metadata["format"] = "Zemax tabular BSDF"
    metadata["symmetry"] = header.get("Symmetry", "PlaneSymmetrical")
    return metadata


def merge_repeats(angles_deg, values, lines=None):
    """Average the values of points that share a geometry (one value per table cell).

    Two points share a geometry when `~brdfjax.data.measurements.geometry_keys` says so:
    ``(theta_i, theta_r, phi_r mod 360)`` agree to 1e-6 deg, and the normal direction
    ``theta_r = 0`` is one point whatever its azimuth.

    Args:
        angles_deg: ``(theta_i, theta_r, phi_r)`` in degrees, shape (N, 3).
        values: the measured values, shape (N,).
        lines: optional file line of each point, shape (N,).

    Returns:
        ``(angles, values, lines, merged)``: one point per geometry in the order of its first
        appearance (with the line of that appearance) and how many points were merged away.
    """
    angles = np.asarray(angles_deg, dtype=float)
    values = np.asarray(values, dtype=float)
    key = geometry_keys(*angles.T)
    _, first, inverse, counts = np.unique(key, axis=0, return_index=True,
                                          return_inverse=True, return_counts=True)
    order = np.argsort(first)
    means = (np.bincount(inverse.reshape(-1), weights=values) / counts)[order]
    picked = first[order]
    lines = None if lines is None else np.asarray(lines)[picked]
    return angles[picked], means, lines, int(len(values) - len(picked))


def _drop_copies(angles_deg, values, lines):
    """Keep one of the entries that repeat both a direction and its value exactly.

    The format lists the specular direction (radial 0) once per azimuth row: those cells
    are one direction, and a table that writes the same value in each holds one reading,
    written several times. Entries at one direction with different values are different
    readings and are all kept, as the CSV reader keeps repeated rows.
    """
    key = np.column_stack([geometry_keys(*np.asarray(angles_deg, dtype=float).T), values])
    _, first = np.unique(key, axis=0, return_index=True)
    first = np.sort(first)
    return angles_deg[first], values[first], lines[first], int(len(values) - len(first))


# --- writing ----------------------------------------------------------------------------

def write(data: Measurements, path) -> None:
    """Write measurements that lie on a full Zemax grid as a tabular BSDF file.

    Each point is turned into Zemax ``(AngleOfIncidence, ScatterAzimuth, ScatterRadial)``;
    the distinct azimuths and radial angles (to 1e-6 deg) make the table's axes, and every
    cell above the horizon must hold a measurement (radial 0 is one point, written at every
    azimuth). Cells below the horizon are written as 0. The file is ``PlaneSymmetrical``
    when all azimuths lie in [0, 180].

    Raises:
        DataError: when a cell above the horizon has no measurement.
    """
    angles, brdf, _, merged = merge_repeats(
        np.degrees(np.stack([data.theta_i, data.theta_r, data.phi_r], axis=1)), data.brdf)
    theta_i = np.round(angles[:, 0], DECIMALS)
    azimuth, radial = angles_to_zemax(theta_i, angles[:, 1], angles[:, 2])
    azimuth, radial = np.round(azimuth, DECIMALS), np.round(radial, DECIMALS)
    incidences = np.unique(theta_i)
    azimuths = np.unique(azimuth[radial > 0]) if np.any(radial > 0) else np.array([0.0])
    radials = np.unique(radial)
    table = np.full((len(incidences), len(azimuths), len(radials)), np.nan)
    i = np.searchsorted(incidences, theta_i)
    j = np.searchsorted(radials, radial)
    specular = radial == 0
    table[i[specular], :, j[specular]] = brdf[specular, None]
    table[i[~specular], np.searchsorted(azimuths, azimuth[~specular]), j[~specular]] = \
        brdf[~specular]
    theta_r, _ = zemax_to_angles(*np.meshgrid(incidences, azimuths, radials, indexing="ij"))
    below = theta_r >= HORIZON_DEG - 1e-9
    table[below & np.isnan(table)] = 0.0
    if np.isnan(table).any():
        a, b, c = np.argwhere(np.isnan(table))[0]
        raise DataError(f"no measurement at AngleOfIncidence {incidences[a]:g}, "
                        f"ScatterAzimuth {azimuths[b]:g}, ScatterRadial {radials[c]:g} deg "
                        f"({int(np.isnan(table).sum())} grid cells are empty)", path,
                        hint="a Zemax table needs every (azimuth, radial) cell above the "
                             "horizon; save as .csv instead, or export a fitted model with "
                             "brdfjax.data.formats.zemax.write_model")
    comments = [f"{key}: {value}" for key, value in data.metadata.items()
                if key in ("sample", "wavelength_nm")]
    comments.insert(0, "Measured BRDF written by brdfjax")
    if merged:
        comments.append(f"repeats_averaged: {merged} repeated readings averaged into their "
                        "table cells")
    _write_table(path, incidences, azimuths, radials, table, comments)


def is_grid_step(step: float) -> bool:
    """Whether ``step`` (deg) can space a table's radials and azimuths: at most 90 and a
    divisor of 180 (the azimuths end at 180, the radials on a node)."""
    return 0 < step <= 90 and abs(180 / step - round(180 / step)) < 1e-9


def hemisphere_radials(incidences_deg, step: float = 5.0) -> np.ndarray:
    """Radial angles ``0, step, ...`` far enough from the specular ray to reach the whole
    upper hemisphere at every incidence: at incidence ``I`` the farthest direction above the
    horizon lies ``90 + I`` deg from it (the grazing one on the source side), so radials up
    to 90 alone leave out the back-scatter side of an oblique table. ``step`` (deg) must
    pass `is_grid_step`, so that the last radial ends the hemisphere exactly."""
    if not is_grid_step(step):
        raise ValueError(f"radial step {step:g} deg: give one of at most 90 that divides 180, "
                         "such as 1, 2, 2.5, 5 or 10")
    reach = min(180.0, 90.0 + float(np.max(incidences_deg)))
    return np.arange(0.0, step * np.ceil(reach / step - 1e-9) + step / 2, step)


def write_model(path, params, incidences_deg, azimuths_deg=tuple(range(0, 181, 10)),
                radial_deg=None, sample: str = "brdfjax model",
                wavelength_nm: float | None = None, model=None, correction=None) -> list:
    """Export the fitted model as a Zemax tabular BSDF file.

    Evaluates `brdfjax.models.paper.brdf` at every (incidence, azimuth, radial) grid point above
    the horizon (0 at and below it) and writes the table with 7 significant digits. The
    model is even in ``phi_r``, so azimuths in [0, 180] make a ``PlaneSymmetrical`` file.

    Args:
        path: the ``.bsdf`` file to write.
        params: the model's parameters (for the default model a `~brdfjax.models.paper.Params` or
            kb, kr, a, b, kd).
        incidences_deg: the angles of incidence.
        azimuths_deg: Zemax scatter azimuths (0 points from the specular ray toward the
            normal).
        radial_deg: Zemax radial angles from the specular ray (default: every 5 deg as far
            as the hemisphere reaches, `hemisphere_radials`).
        sample: the name written in a ``# Sample:`` comment.
        wavelength_nm: recorded in a comment when given.
        model: a model name or `brdfjax.models.Model` (None: the model of a named tuple,
            else the five-parameter model; `brdfjax.models.model_for`).
        correction: a learned discrepancy to apply
            (`brdfjax.prediction.discrepancy.Discrepancy`), or None.

    Returns:
        The TIS of each incidence's table (as written in the file).
    """
    from brdfjax.models import model_for

    model = model_for(params, model)  # once, for the table and its header
    if radial_deg is None:
        radial_deg = hemisphere_radials(incidences_deg)
    incidences, azimuths, radials, table = model_table(
        params, incidences_deg, azimuths_deg, radial_deg, model, correction)
    comments = [f"Sample: {sample}", model_comment(model, correction),
                parameter_comment(params, model)]
    if wavelength_nm is not None:
        comments.append(f"wavelength_nm: {wavelength_nm:g}")
    return _write_table(path, incidences, azimuths, radials, table, comments)


def model_table(params, incidences_deg, azimuths_deg, radial_deg, model=None,
                correction=None):
    """A model's table on Zemax's grid: ``(incidences, azimuths, radials, table)``, the
    angles sorted (degrees) and the table (incidence, azimuth, radial) of its BRDF (1/sr),
    0 at and below the horizon (``correction``: as `evaluate_model` takes it)."""
    incidences, azimuths, radials = (np.sort(np.asarray(x, dtype=float).reshape(-1))
                                     for x in (incidences_deg, azimuths_deg, radial_deg))
    aoi, theta_r, phi_r = grid_angles(incidences, azimuths, radials)
    above = theta_r < HORIZON_DEG - 1e-9
    values = evaluate_model(params, aoi, np.minimum(theta_r, 90.0), phi_r, model, correction)
    return incidences, azimuths, radials, np.where(above, values, 0.0)


def grid_angles(incidences_deg, azimuths_deg, radial_deg):
    """``(theta_i, theta_r, phi_r)`` (degrees, (incidence, azimuth, radial)) of every node
    of Zemax's grid."""
    aoi, azimuth, radial = np.meshgrid(incidences_deg, azimuths_deg, radial_deg, indexing="ij")
    return (aoi, *zemax_to_angles(aoi, azimuth, radial))


def evaluate_model(params, theta_i_deg, theta_r_deg, phi_r_deg, model=None,
                   correction=None) -> np.ndarray:
    """A model's BRDF (1/sr) at the given angles (degrees, broadcast), for the exports.

    The one place the Zemax and ASTM exports evaluate a fitted model (``model``: a name or
    `brdfjax.models.Model`, the five-parameter model if None), corrected by a learned
    discrepancy where ``correction`` (a `brdfjax.prediction.discrepancy.Discrepancy`) is given: then
    the values are those `brdfjax.predict` gives at the same angles, except that a correction
    learned out of the plane of incidence, which may differ between a direction and its
    mirror image across that plane (`brdfjax.prediction.discrepancy.features`), is averaged
    with its mirror image (the mean of the two log corrections): both tables are
    plane-symmetric, and a table's TIS counts its half twice.
    """
    from brdfjax.models.paper import brdf  # JAX only for the export

    shape = np.broadcast_shapes(*(np.shape(x) for x in (theta_i_deg, theta_r_deg, phi_r_deg)))
    angles = [np.radians(np.broadcast_to(np.asarray(x, dtype=float), shape)).reshape(-1)
              for x in (theta_i_deg, theta_r_deg, phi_r_deg)]
    values = np.asarray(brdf(params, *angles, model=model), dtype=float)
    if correction is not None:
        mu = correction.predict(*angles)[0]
        if correction.azimuth:
            mu = (mu + correction.predict(angles[0], angles[1], -angles[2])[0]) / 2
        values = correction.correct(values, mu)
    return values.reshape(shape)


def model_comment(model=None, correction=None) -> str:
    """Which model an export tabulates, for its header."""
    from brdfjax.models import get

    model = get(model)
    text = f"BRDF model {model.name} ({model.summary.split(':')[0]}), exported by brdfjax"
    if correction is not None:
        text += (", times its learned discrepancy (a Gaussian process of the log residual): "
                 "the table, not the parameters below, is the prediction")
    return text


def parameter_comment(params, model=None) -> str:
    """``"parameters: kb=..., kr=..., ..."`` (the model's names) for an export's header."""
    from brdfjax.models import get
    from brdfjax.models.paper import as_vector

    vector = np.asarray(as_vector(params), dtype=float)
    return "parameters: " + ", ".join(f"{n}={v:.8g}" for n, v in zip(get(model).names, vector))


def tis(table, incidence_deg, azimuths_deg, radial_deg) -> float:
    """The total integrated scatter of one table, ``integral of f_r cos(theta_r) dOmega``.

    Trapezoidal rule over the (azimuth, radial) grid with ``dOmega = sin(R) dR dA``;
    directions below the horizon count as 0. A ``PlaneSymmetrical`` half (azimuths within
    [0, 180]) counts twice. As accurate as the grid is fine.
    """
    azimuths = np.radians(np.asarray(azimuths_deg, dtype=float))
    radials = np.radians(np.asarray(radial_deg, dtype=float))
    a, r = np.meshgrid(np.degrees(azimuths), np.degrees(radials), indexing="ij")
    theta_r, _ = zemax_to_angles(incidence_deg, a, r)
    cosine = np.clip(np.cos(np.radians(theta_r)), 0.0, None)
    integrand = np.asarray(table, dtype=float) * cosine * np.sin(radials)[None, :]
    if len(radials) < 2 or len(azimuths) < 2:
        return 0.0
    over_radial = np.trapezoid(integrand, radials, axis=1)
    if azimuths.max() <= np.pi + 1e-9:
        return float(2 * np.trapezoid(over_radial, azimuths))
    if azimuths[-1] - azimuths[0] < 2 * np.pi - 1e-9:
        # A full circle not listed twice: close it from the last azimuth to the first.
        over_radial = np.append(over_radial, over_radial[0])
        azimuths = np.append(azimuths, azimuths[0] + 2 * np.pi)
    return float(np.trapezoid(over_radial, azimuths))


def _write_table(path, incidences, azimuths, radials, table, comments) -> None:
    """Format and write a Monochrome BRDF table, one block per angle of incidence.

    The header says ``Source Measured`` for a fitted model's table too (its comments say
    which model made it): the value the public files and writers we could read give (the
    University of Arizona's tables, Ansys' Speos-to-Zemax converter, a Radiant imaging
    sphere's export); none writes ``Model``, which OpticStudio's reader is not known to
    take. OpticStudio itself could not be run here."""
    from brdfjax.data.formats import write_atomically

    symmetric = azimuths.min() >= -1e-9 and azimuths.max() <= 180 + 1e-9

    def angles(values):
        return "\t".join(f"{v:.10g}" for v in values)

    out = [f"# {c}" for c in comments]
    out += ["Source\tMeasured",
            f"Symmetry\t{'PlaneSymmetrical' if symmetric else 'Asymmetrical'}",
            "SpectralContent\tMonochrome", "ScatterType\tBRDF",
            "SampleRotation\t1", "0",
            f"AngleOfIncidence\t{len(incidences)}", angles(incidences),
            f"ScatterAzimuth\t{len(azimuths)}", angles(azimuths),
            f"ScatterRadial\t{len(radials)}", angles(radials),
            "", "Monochrome", "DataBegin"]
    totals = [tis(block, aoi, azimuths, radials) for aoi, block in zip(incidences, table)]
    for total, block in zip(totals, table):
        out.append(f"TIS\t{total:.6g}")
        out += ["\t".join(f"{v:.6e}" for v in row) for row in block]
    out.append("DataEnd")
    write_atomically(path, "\n".join(out) + "\n")
    return totals
