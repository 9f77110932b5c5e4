"""NIST Mueller-matrix BRDF tables of sintered PTFE (T. A. Germer, Applied Optics 2017).

A CSV file with the header ``lambda,thetai,phii,thetar,phir,fr11,m12,...`` (the published
files spell two of them ``phi`` and ``f_r11``): wavelength in micrometres, angles in degrees,
``fr11`` the unpolarized BRDF in 1/sr; the normalized Mueller elements are ignored.

Each direction is a polar angle and an azimuth, and a negative polar angle means the same
angle on the opposite azimuth: the regular grid stores the source as ``thetai < 0`` with
``phii = 0``, i.e. on the ``phi = 180`` side. ``(thetai, phii)`` points toward the source
(checked against the data: with it the randomly sampled file agrees with the regular grid,
with the opposite reading it does not). The reader makes both polar angles positive, then
turns the azimuths so the source has azimuth 0, which puts the specular side at
``phi_r = 180`` as the project wants.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from brdfjax.data.formats import read_text, spectral, split_lines
from brdfjax.data.formats.directions import relative_azimuth, unsign
from brdfjax.data.measurements import DataError, Measurements, validate

# The columns used, with the spellings found in the published files.
COLUMNS = {"lambda": ("lambda",), "thetai": ("thetai",), "phii": ("phii", "phi"),
           "thetar": ("thetar",), "phir": ("phir",), "fr11": ("fr11", "f_r11")}


def read(path, wavelength_nm: float | None = None, in_plane_only: bool = False) -> Measurements:
    """Read one wavelength of a NIST PTFE BRDF table in the project's convention.

    Args:
        path: the ``.csv`` file.
        wavelength_nm: the wavelength to read, in nanometres; may be omitted when the file
            holds a single wavelength.
        in_plane_only: keep only the points in the plane of incidence.

    Returns:
        The validated `Measurements`, one point per row (a repeated geometry is kept
        as another reading).

    Raises:
        DataError: for a malformed file, or a missing or ambiguous wavelength.
    """
    path = Path(path)
    table, lines = _read_table(path)
    wavelength = spectral.pick_one(_wavelengths_nm(table), wavelength_nm, path)
    return _measurements(table, lines, wavelength, path, in_plane_only)


def read_spectral(path, wavelengths_nm=None) -> dict[float, Measurements]:
    """Read every wavelength of a NIST PTFE table (or the listed ones), parsing it once.

    Returns:
        ``{wavelength_nm: Measurements}`` in the order asked (ascending by default).
    """
    path = Path(path)
    table, lines = _read_table(path)
    chosen = spectral.pick_many(_wavelengths_nm(table), wavelengths_nm, path)
    return {w: _measurements(table, lines, w, path) for w in chosen}


def _wavelengths_nm(table) -> np.ndarray:
    return np.unique(np.round(table["lambda"] * 1000.0, 3))


def _measurements(table, lines, wavelength, path, in_plane_only=False) -> Measurements:
    """The validated measurements of the rows at one of the file's wavelengths."""
    pick = np.abs(table["lambda"] * 1000.0 - wavelength) <= spectral.WAVELENGTH_TOLERANCE_NM
    table = {name: values[pick] for name, values in table.items()}
    lines = lines[pick]
    theta_i, phi_source = unsign(table["thetai"], table["phii"])
    theta_r, phi_detector = unsign(table["thetar"], table["phir"])
    phi_r = relative_azimuth(phi_detector, phi_source, theta_r)
    angles = np.stack([theta_i, theta_r, phi_r], axis=1)
    brdf = table["fr11"]
    wavelength = float(np.round(np.mean(table["lambda"]) * 1000.0, 3))
    metadata = {"sample": path.name.split(".")[0], "wavelength_nm": wavelength,
                "source": str(path), "format": "NIST PTFE BRDF table (Germer 2017)"}
    if in_plane_only:
        plane = np.abs(np.sin(np.radians(angles[:, 2]))) < 1e-9
        if not plane.any():
            raise DataError(f"no points in the plane of incidence at {wavelength:g} nm", path,
                            hint="read the file without in_plane_only")
        angles, brdf, lines = angles[plane], brdf[plane], lines[plane]
        metadata["selection"] = "in-plane points only"
    data = Measurements.from_degrees(*angles.T, brdf, metadata=metadata)
    return validate(data, path, lines)


def _read_table(path) -> tuple[dict, np.ndarray]:
    """The used columns as arrays, and the file line of each row."""
    text = read_text(path)
    numbered = [(n, line.strip()) for n, line in enumerate(split_lines(text), start=1)
                if line.strip()]
    if not numbered:
        raise DataError("empty file", path)
    number, first = numbered[0]
    header = [cell.strip() for cell in first.split(",")]
    where = _column_indices(header, path, number)
    rows, lines = [], []
    for number, line in numbered[1:]:
        cells = line.split(",")
        if len(cells) != len(header):
            raise DataError(f"{len(cells)} cells, the header has {len(header)}", path, number,
                            "the file looks truncated or corrupted")
        row = []
        for index in where.values():
            try:
                row.append(float(cells[index]))
            except ValueError:
                raise DataError(f"{header[index]} = {cells[index].strip()!r} is not a number",
                                path, number) from None
        rows.append(row)
        lines.append(number)
    if not rows:
        raise DataError("no data rows after the header", path)
    table = dict(zip(where, np.array(rows).T))
    # Light from 10 nm to 1 mm, in micrometres; anything else is not a wavelength in um.
    bad = np.flatnonzero(~((table["lambda"] >= 0.01) & (table["lambda"] <= 1000)))
    if bad.size:
        raise DataError(f"lambda = {table['lambda'][bad[0]]:g} is not a wavelength in "
                        "micrometres", path, lines[bad[0]], "NIST tables give lambda in um")
    return table, np.array(lines)


def _column_indices(header, path, line) -> dict:
    where = {}
    for name, spellings in COLUMNS.items():
        found = [header.index(s) for s in spellings if s in header]
        if not found:
            raise DataError(f"no column {name} in the header", path, line,
                            "a NIST PTFE table starts lambda,thetai,phii,thetar,phir,fr11")
        where[name] = found[0]
    return where
