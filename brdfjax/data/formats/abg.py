"""ABg parameters for optical software: a Zemax ABg data catalog entry, FRED's values, and
the checks both programs make.

Stray-light engineers fit the ABg model (`brdfjax.models.abg`) one incidence at a time
(``brdfjax fit FILE --model abg --per-incidence``) and enter the rows in their ray tracer:

- **Zemax OpticStudio** keeps ABg data in a catalog file of its ``ABg_Data`` folder
  (``ABG_DATA.DAT`` by default, chosen in System Explorer, Files). An entry has a name, the
  wavelength in micrometres at which the data hold (0: A and B are not scaled with
  wavelength) and up to 10 rows of incidence angle (0-90 deg; others are interpolated
  linearly in the cosine of the angle, and the end rows used beyond them), A, B and g,
  sorted by angle. OpticStudio requires ``A >= 0`` and ``B > 1e-12`` unless ``g = 0``, and
  its TIS of an entry must stay below 1 for an accurate scatter.
- **FRED** takes A, B and g of the same formula ``A / (B + |beta - beta0|^g)``, one set per
  scatter model: the row at the incidence of use, or a fit of all incidences together.
  FRED's check: ``A / B`` (the BSDF at the specular) times the projected solid angle
  ``pi`` must be at most 1; the BSDF is nowhere above ``A / B``, so that bounds the
  lobe's total scatter (`brdfjax.models.abg`).

`catalog_entry` writes the entry as text: a header line ``NAME WAVELENGTH_UM`` and one line
``ANGLE A B G`` per incidence. That is the content the catalog dialog takes; the exact
layout of the catalog file itself was not found in OpticStudio's public documentation, so
check a first import against your version (or type the rows into the dialog). The TIS is
the reflectance of Eq. (9) of each row (`brdfjax.models.hemispherical.reflectance`), the total
scatter of the ABg lobe at its own incidence.

How well each row fits is its E of Eq. (6) (`AbgRow.error`), and a row above
`POOR_ROW_ERROR` is flagged as a poor fit in `report` and in the JSON (``poor_fit``): its
catalog line is still written, but the lobe it describes misses that incidence's data, and a
ray tracer interpolates between rows.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

ZEMAX_MIN_B = 1e-12
ZEMAX_MAX_ROWS = 10
# A row whose E of Eq. (6) exceeds this fits poorly. E is a relative squared error, so the
# noise of a measurement sets its floor: between repeat runs of one sample on the RT-300S
# (NiTE on steel rotated, NiTE on invar remounted; the same geometries, run B or C scored
# against run A) E is 0.15-1.3 % per incidence, and it counts the noise of both runs. 5 %
# is about four times the largest of those: a row above it misses its data by far more
# than the instrument repeats, an error of the ABg lobe's shape, not noise (NiTE on steel
# A: rows at 10 and 30 deg 0.68 and 2.8 %, at 50 and 70 deg 13.8 and 17.1 %). Rows are not
# compared with each other: on these coatings half the rows are poor, and a rule relative to
# the median row would flag none of them.
POOR_ROW_ERROR = 0.05


@dataclass
class AbgRow:
    """One incidence's fitted ABg parameters and the checks of optical software.

    Attributes:
        incidence_deg: the angle of incidence.
        A, B, g: the fitted parameters (BSDF in 1/sr).
        error: E of Eq. (6) of this incidence's own fit.
        tis: the total integrated scatter (reflectance of Eq. 9) of the row.
        fred_check: ``pi A / B``, at most 1 for FRED (the module docstring).
        zemax_ok: ``A >= 0`` and ``B > 1e-12`` unless ``g = 0``.
        poor_fit: ``error`` above the threshold it was judged by (`POOR_ROW_ERROR` by
            default): the row misses its data by more than a measurement's noise.
    """

    incidence_deg: float
    A: float
    B: float
    g: float
    error: float
    tis: float
    fred_check: float
    zemax_ok: bool
    poor_fit: bool = False

    def to_dict(self) -> dict:
        return {"incidence_deg": self.incidence_deg, "A": self.A, "B": self.B, "g": self.g,
                "error": self.error, "poor_fit": self.poor_fit, "tis": self.tis,
                "fred_check": self.fred_check, "zemax_ok": self.zemax_ok}


def abg_rows(per_incidence, poor_error: float = POOR_ROW_ERROR) -> list[AbgRow]:
    """`AbgRow` s, sorted by angle, from ``[(incidence_deg, FitResult of abg)]``; a row
    whose E exceeds ``poor_error`` (a fraction; `POOR_ROW_ERROR` says why 5 %) is marked
    ``poor_fit``, as is one without a finite E."""
    from brdfjax.models.hemispherical import reflectance

    rows = []
    for degrees, result in sorted(per_incidence, key=lambda item: item[0]):
        if result.model.name != "abg":
            raise ValueError(f"ABg export needs fits of the abg model, not {result.model.name}")
        a, b, g = (float(x) for x in result.vector)
        tis = float(reflectance(result.vector, np.radians(degrees), model="abg", warn=False))
        rows.append(AbgRow(float(degrees), a, b, g, float(result.error), tis,
                           float(np.pi * a / b) if b > 0 else float("inf"),
                           bool(a >= 0 and (b > ZEMAX_MIN_B or g == 0)),
                           not float(result.error) <= poor_error))
    return rows


def catalog_entry(name: str, rows: list[AbgRow], wavelength_um: float = 0.0) -> str:
    """The Zemax ABg catalog entry of ``rows`` as text (see the module docstring).

    Args:
        name: the entry's name: letters, digits, ``_`` and ``-`` only (no spaces), as a
            catalog name must be one token.
        rows: at most `ZEMAX_MAX_ROWS` incidences, angles within 0-90 deg.
        wavelength_um: the wavelength in micrometres (0: no wavelength scaling).

    Raises:
        ValueError: a name with spaces or other characters, too many rows, an angle out
            of range, or a row OpticStudio refuses (B <= 1e-12 with g != 0).
    """
    if not re.fullmatch(r"[A-Za-z0-9_-]{1,32}", name):
        raise ValueError(f"ABg entry name {name!r}: use 1-32 letters, digits, _ or - "
                         "(no spaces)")
    if not rows:
        raise ValueError("no ABg rows to export")
    if len(rows) > ZEMAX_MAX_ROWS:
        raise ValueError(f"{len(rows)} incidences: a Zemax ABg entry holds at most "
                         f"{ZEMAX_MAX_ROWS} rows; select incidences with --train-incidence")
    if not wavelength_um >= 0:
        raise ValueError(f"wavelength {wavelength_um} um: give a positive value, or 0")
    lines = [f"{name.upper()} {wavelength_um:.6g}"]
    for row in sorted(rows, key=lambda r: r.incidence_deg):
        if not 0 <= row.incidence_deg <= 90:
            raise ValueError(f"incidence {row.incidence_deg} deg outside 0-90")
        if not row.zemax_ok:
            raise ValueError(f"the row at {row.incidence_deg:g} deg has B = {row.B:.3g} <= "
                             f"{ZEMAX_MIN_B:g} with g = {row.g:.3g} != 0, which OpticStudio "
                             "refuses; narrow B with --bound B=1e-10:1")
        lines.append(f"{row.incidence_deg:.6g} {row.A:.8E} {row.B:.8E} {row.g:.8f}")
    return "\n".join(lines) + "\n"


def report(rows: list[AbgRow], poor_error: float = POOR_ROW_ERROR) -> str:
    """The per-incidence table with how well each row fits (E, and ``poor fit`` above
    ``poor_error``, as `abg_rows` judged it) and the TIS checks, then the parameters FRED
    takes."""
    lines = [(f"  {'incidence':>9} {'A':>12} {'B':>12} {'g':>8} {'E (%)':>8} {'TIS':>8} "
              f"{'pi A/B':>10}  checks")]
    for row in rows:
        flags = [f"poor fit: E > {100 * poor_error:g} %"] if row.poor_fit else []
        if row.tis >= 1:
            flags.append("TIS >= 1: Zemax scatter inaccurate")
        if row.fred_check > 1:
            flags.append("pi A/B > 1: FRED refuses")
        if not row.zemax_ok:
            flags.append("B <= 1e-12 with g != 0: Zemax refuses")
        lines.append(f"  {row.incidence_deg:9g} {row.A:12.5g} {row.B:12.5g} {row.g:8.4g} "
                     f"{100 * row.error:8.3g} {row.tis:8.4g} {row.fred_check:10.4g}  "
                     f"{'; '.join(flags) or 'ok'}")
    poor = [row for row in rows if row.poor_fit]
    if poor:
        lines.append(
            f"{len(poor)} of {len(rows)} rows fit poorly (E above {100 * poor_error:g} %, "
            f"several times what repeat measurements differ by): at "
            f"{', '.join(f'{row.incidence_deg:g}' for row in poor)} deg one ABg lobe does not "
            "describe the data, and a ray tracer using these rows scatters otherwise than the "
            "sample there; compare E with your measurement's repeatability before using them")
    lines.append("FRED (ABg scatter model, BSDF = A / (B + |beta - beta0|^g)), one set per "
                 "incidence:")
    for row in rows:
        lines.append(f"  at {row.incidence_deg:g} deg: A = {row.A:.6g}, B = {row.B:.6g}, "
                     f"g = {row.g:.6g}")
    return "\n".join(lines)
