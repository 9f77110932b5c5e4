"""Starlink v1.5 ScatterWorks BRDF tables, in the "lumos-sat" convention.

F. Fankhauser, J. A. Tyson and J. Askari, "Satellite Optical Brightness" (2023),
arXiv:2305.11123, published the laboratory in-plane BRDF of two Starlink v1.5 materials
(the chassis deck and the solar array), measured by ScatterWorks at 532 nm, as text tables
that satellite-brightness tools (lumos-sat) share::

    # This data was measured by Scatterworks
    # and is at a wavelength lambda = 532 nm
    #
    # phi_i     theta_i     phi_o     theta_o     brdf
    75.00     -180.00     -90.00     0.00     1.00000e-04
    75.00     -180.00     -89.00     0.00     1.56196e-04

Whitespace-separated columns (commas are accepted too) after ``#`` comment lines; the column
line may be a comment or a plain line, and names the five columns in any order. In this
convention **phi is the zenith and theta the azimuth** (the reverse of brdfjax's names), in
degrees:

- ``phi_i``: incidence zenith; ``theta_i``: azimuth of the direction toward the source
  (-180 in the published files);
- ``phi_o``: *signed* scatter zenith; ``theta_o``: scatter azimuth (0 in the published
  files). With the source at azimuth -180, ``phi_o > 0`` is the specular (forward) side:
  the specular peak sits at ``phi_o = +phi_i``; ``phi_o < 0`` is the source side;
- ``brdf``: the BRDF in 1/sr.

A negative zenith is the positive zenith on the opposite azimuth; the reader then takes the
scatter azimuth relative to the source's (`brdfjax.data.formats.directions`), so that for
the published in-plane tables ``theta_r = |phi_o|`` and ``phi_r = 180`` deg where
``phi_o > 0`` (specular side), ``phi_r = 0`` where ``phi_o < 0`` (source side), and
``phi_o = 0`` is the normal, ``theta_r = 0``, ``phi_r = 0``.

**Fill values are dropped.** Near grazing the tables hold placeholder readings of exactly
``1.0e-4`` (`FILL_VALUE`) at ``|phi_o| >= 88`` deg (`FILL_FROM_DEG`): 15 in the chassis
file, 13 in the solar-array file, none elsewhere. They are not measurements (a fit would
take them for a dark grazing floor), so rows with both are dropped and counted in
``metadata["fill_values_dropped"]``; every other reading, including real ones at 88-90 deg,
is kept.

The wavelength is the one the comment header states (``lambda = 532 nm``, ``wavelength:
532 nm`` or ``wavelength_nm: 532``); a table that states none is taken as ScatterWorks'
532 nm data (`DEFAULT_WAVELENGTH_NM`) unless ``wavelength_nm=`` says otherwise. The comment
lines are kept, joined by `` / ``, as ``metadata["header"]``.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from brdfjax.data.formats import read_text, spectral, split_lines
from brdfjax.data.formats.directions import relative_azimuth, unsign
from brdfjax.data.measurements import DataError, Measurements, validate

COLUMNS = ("phi_i", "theta_i", "phi_o", "theta_o", "brdf")
# Placeholder readings near grazing: exactly this value at |phi_o| >= FILL_FROM_DEG.
FILL_VALUE = 1.0e-4
FILL_FROM_DEG = 88.0
# The published tables are ScatterWorks 532 nm data (Fankhauser et al. 2023).
DEFAULT_WAVELENGTH_NM = 532.0
FORMAT = "Starlink v1.5 ScatterWorks BRDF (lumos-sat convention, Fankhauser et al. 2023)"
_SEPARATOR = re.compile(r"[\s,]+")
# "lambda = 532 nm", "wavelength: 532 nm", "wavelength_nm: 532".
_WAVELENGTH = re.compile(
    r"\b(?:(?:lambda|wavelength)\s*[=:]?\s*([0-9]+(?:\.[0-9]*)?)\s*nm\b"
    r"|wavelength_nm\s*[=:]\s*([0-9]+(?:\.[0-9]*)?))", re.IGNORECASE)


def _column_names(text: str) -> list[str] | None:
    """The names of a column line (``# phi_i theta_i phi_o theta_o brdf``), or None."""
    cells = [c.lower() for c in _SEPARATOR.split(text.lstrip("#").strip()) if c]
    return cells if set(COLUMNS) <= set(cells) and len(cells) == len(set(cells)) else None


def looks_like(head: str) -> bool:
    """Whether a text (a file's first characters) is such a table: a line naming the
    columns ``phi_i theta_i phi_o theta_o brdf``, among the comment lines before the
    first data line or as that line itself."""
    for line in split_lines(head):
        text = line.strip()
        if not text:
            continue
        if _column_names(text) is not None:
            return True
        if not text.startswith("#"):
            return False
    return False


def read(path, wavelength_nm: float | None = None) -> Measurements:
    """Read a Starlink / lumos-sat BRDF table in the project's convention.

    Args:
        path: the file.
        wavelength_nm: the wavelength the data must be at: checked against the one the
            header states (to 0.5 nm), recorded where it states none (else 532 nm).

    Returns:
        The validated `Measurements`, one point per row, fill values dropped (see the
        module docstring); ``metadata["fill_values_dropped"]`` counts them.

    Raises:
        DataError: naming the file and line of a malformed row, or a missing column line.
    """
    path = Path(path)
    comments, header, rows, lines = [], None, [], []
    for number, raw in enumerate(split_lines(read_text(path)), start=1):
        text = raw.strip()
        if not text:
            continue
        if header is None and (names := _column_names(text)) is not None:
            header, header_line = names, number
            continue
        if text.startswith("#"):
            comment = text.lstrip("#").strip()
            if comment and header is None:
                comments.append(comment)
            continue
        if header is None:
            raise DataError("a data line before the column line", path, number,
                            "the table must name its columns first: "
                            "# phi_i theta_i phi_o theta_o brdf")
        cells = [c for c in _SEPARATOR.split(text) if c]
        if len(cells) != len(header):
            raise DataError(f"{len(cells)} cells, the column line (line {header_line}) "
                            f"names {len(header)}", path, number,
                            "the file looks truncated or corrupted")
        row = {}
        for name, cell in zip(header, cells):
            if name not in COLUMNS:
                continue
            try:
                row[name] = float(cell)
            except ValueError:
                raise DataError(f"{name} = {cell!r} is not a number", path, number) from None
        rows.append([row[name] for name in COLUMNS])
        lines.append(number)
    if header is None:
        raise DataError("no column line", path,
                        hint="a lumos-sat table names its columns: "
                             "# phi_i theta_i phi_o theta_o brdf")
    if not rows:
        raise DataError("no measurements after the column line", path, header_line)
    table = dict(zip(COLUMNS, np.array(rows).T))
    lines = np.array(lines)

    fill = (table["brdf"] == FILL_VALUE) & (np.abs(table["phi_o"]) >= FILL_FROM_DEG)
    keep = ~fill
    table = {name: values[keep] for name, values in table.items()}
    lines = lines[keep]

    theta_i, phi_source = unsign(table["phi_i"], table["theta_i"])
    theta_r, phi_detector = unsign(table["phi_o"], table["theta_o"])
    phi_r = relative_azimuth(phi_detector, phi_source, theta_r)
    metadata = {"sample": path.stem,
                "wavelength_nm": _wavelength(comments, wavelength_nm, path),
                "source": str(path), "format": FORMAT,
                "fill_values_dropped": int(fill.sum())}
    if comments:
        metadata["header"] = " / ".join(comments)
    data = Measurements.from_degrees(theta_i, theta_r, phi_r, table["brdf"],
                                     metadata=metadata)
    return validate(data, path, lines)


def _wavelength(comments, wanted_nm, path) -> float:
    """The wavelength the header states, checked against ``wanted_nm``; else ``wanted_nm``,
    else `DEFAULT_WAVELENGTH_NM`."""
    stated = {float(a or b) for comment in comments
              for a, b in _WAVELENGTH.findall(comment)}
    if len(stated) > 1:
        raise DataError(f"the header states several wavelengths: {spectral.listing(sorted(stated))}",
                        path, hint="a table holds one wavelength")
    if not stated:
        return float(wanted_nm) if wanted_nm is not None else DEFAULT_WAVELENGTH_NM
    recorded = stated.pop()
    if wanted_nm is not None:
        spectral.pick_many([recorded], [wanted_nm], path)
    return recorded
