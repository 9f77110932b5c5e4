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

from brdfjax.measurements import DataError, Measurements, validate

# The columns used, with the spellings found in the published files.
COLUMNS = {"lambda": ("lambda",), "thetai": ("thetai",), "phii": ("phii", "phi"),
           "thetar": ("thetar",), "phir": ("phir",), "fr11": ("fr11", "f_r11")}
# Wavelengths that agree to this many nanometres are the same.
WAVELENGTH_TOLERANCE_NM = 0.5
# In-plane points come out of the azimuth subtraction within rounding of 0 or 180 deg.
IN_PLANE_TOLERANCE_DEG = 1e-6


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
    pick = _pick_wavelength(table["lambda"] * 1000.0, wavelength_nm, path)
    table = {name: values[pick] for name, values in table.items()}
    lines = lines[pick]
    theta_i, phi_source = _unsign(table["thetai"], table["phii"])
    theta_r, phi_detector = _unsign(table["thetar"], table["phir"])
    phi_r = _relative_azimuth(phi_detector, phi_source, theta_r)
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
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as error:
        raise DataError(f"cannot read the file ({error.strerror})", path) from None
    numbered = [(n, line.strip()) for n, line in enumerate(text.splitlines(), start=1)
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
    values = np.array(rows).T
    return dict(zip(where, values)), np.array(lines)


def _column_indices(header, path, line) -> dict:
    where = {}
    for name, spellings in COLUMNS.items():
        found = [header.index(s) for s in spellings if s in header]
        if not found:
            raise DataError(f"no column {name} in the header", path, line,
                            "a NIST PTFE table starts lambda,thetai,phii,thetar,phir,fr11")
        where[name] = found[0]
    return where


def _pick_wavelength(wavelengths_nm, wanted_nm, path) -> np.ndarray:
    """The rows of the wanted wavelength; `DataError` if it is absent or not chosen."""
    available = np.unique(np.round(wavelengths_nm, 3))
    listing = ", ".join(f"{w:g}" for w in available) + " nm"
    if wanted_nm is None:
        if len(available) > 1:
            raise DataError(f"the file holds {len(available)} wavelengths: {listing}", path,
                            hint="choose one with wavelength_nm= (CLI: --wavelength)")
        return np.ones(len(wavelengths_nm), dtype=bool)
    pick = np.abs(wavelengths_nm - float(wanted_nm)) <= WAVELENGTH_TOLERANCE_NM
    if not pick.any():
        raise DataError(f"no data at {float(wanted_nm):g} nm; the file holds {listing}", path,
                        hint="choose one of the listed wavelengths")
    return pick


def _unsign(polar, azimuth) -> tuple[np.ndarray, np.ndarray]:
    """A negative polar angle is the positive angle on the opposite azimuth."""
    negative = polar < 0
    return np.abs(polar), np.where(negative, azimuth + 180.0, azimuth)


def _relative_azimuth(phi_detector, phi_source, theta_r) -> np.ndarray:
    """``phi_r`` in (-180, 180] with the source at 0; in-plane values exactly 0 or 180."""
    phi = 180.0 - np.mod(180.0 - (phi_detector - phi_source), 360.0)
    phi = np.where(np.abs(phi) < IN_PLANE_TOLERANCE_DEG, 0.0, phi)
    phi = np.where(np.abs(np.abs(phi) - 180.0) < IN_PLANE_TOLERANCE_DEG, 180.0, phi)
    # The normal has no azimuth.
    return np.where(theta_r == 0, 0.0, phi)
