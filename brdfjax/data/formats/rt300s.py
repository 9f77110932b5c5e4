"""J&C RT-300S scatterometer exports (``.xls``), as measured by the University of Arizona.

The instrument writes one column per measurement, spread over several sheets, with rows
labelled in column 0: ``Azimuth`` (A), ``Incidence`` (I) and ``Receive`` (R), in degrees,
and ``RT`` (its reflectance reading). A file of the current layout is a full 3-D scan:
4 incidences x 19 azimuths (A = -90..90 step 10) x 33 receive angles (R = -80..80 step 5),
2,508 readings; the legacy 1-degree files hold the plane of incidence only (A = -90).
Every reading is read; ``in_plane=True`` keeps the A = -90 scan alone, as brdfjax did
before it read the files whole.

Each reading becomes a BRDF as the instrument's users convert it,

    f_r = (RT_sample - RT_blank) / (pi cos(Receive)),

with ``RT_blank`` the reading of a blank (the empty sample holder) at the same
(Azimuth, Incidence, Receive): the blank of a 3-D scan is a 3-D scan too, and its readings
depend on the azimuth (offsets of a few 1e-3 that jump between azimuths), so they are
matched on all three angles. A blank of the plane of incidence alone (one azimuth) is
matched on (Incidence, Receive) and subtracted at every azimuth. The blank is a second
``.xls`` file; by default the one file named ``blank_*.xls`` next to the sample is used.

Geometry. The detector turns on an arm at a fixed distance from the sample, along a great
circle through the surface normal: ``|R|`` is the angle of the detector from the normal
(R = 0 looks straight down the normal at every azimuth), and A turns the plane of that
circle about the normal. At A = -90 it is the plane of incidence with R > 0 on the specular
side; at A = 0 it is the plane through the normal perpendicular to the plane of incidence;
at A = +90 it is the plane of incidence again, traversed the other way (R > 0 on the source
side). In brdfjax's frame (z the normal, the source at azimuth 0, so the specular half at
``phi_r = 180``, directions pointing away from the surface) the reading (A, R) looks along

    d = (sin A sin R, -cos A sin R, cos R),   i.e.   theta_r = |R|,
    phi_r = A - 90 deg (R > 0) or A + 90 deg (R < 0), taken into (-180, 180].

This is the authors' own conversion (``rt300s_to_bsdf_iso.m`` in ``ua-loft/bsdf-tools``,
v1.2.2): their ``IAR_to_AzRz`` gives the direction about the specular ray as
``X = sin I cos R + sin A cos I sin R``, ``Y = -cos A sin R``,
``Z = cos I cos R - sin A sin I sin R`` (X toward the normal, Z the specular ray, Zemax's
scatter frame, `brdfjax.data.formats.zemax`); turned back by I into the surface frame it
is ``d`` above, whose z is ``cos R`` whatever A and I are. Their FRED export writes the
same thing directly (scatter zenith ``|R|``, scatter azimuth ``90 + A``, plus 180 when
R < 0, with the specular side at 0 there). The checks:

- A = -90 gives ``d = (-sin R, 0, cos R)``: ``theta_r = |R|`` with ``phi_r = 180`` for
  R > 0 and 0 for R < 0, exactly the in-plane reading brdfjax made before;
- (A, R) and (-A, -R) give ``d`` with the same x and z and opposite y: mirror images in
  the plane of incidence (``phi_r`` -> ``-phi_r``), which an isotropic sample cannot tell
  apart. That is the authors' statement that (A in [-90, 0], R) and (A in [0, 90], -R) are
  the same geometry of an isotropic sample, and why their tables average both halves;
- (A = +90, R) is (A = -90, -R) exactly, the same direction read twice, and R = 0 is the
  normal at every azimuth: such repeats are kept, one point per reading, as any repeated
  reading is (`brdfjax.data.measurements.repeat_summary`).

The sign of y (which side of the plane of incidence is ``0 < phi_r < 180``) follows the
authors' frame as `brdfjax.data.formats.zemax` orients Zemax's azimuths (90 toward +y); the
isotropic models are even in ``phi_r`` and do not depend on it.

Beam crossing. Where the detector passes in front of the incident beam it shadows the
sample (the reading drops to about 0). In the plane of incidence the instrument's users
drop ``|Receive + Incidence| <= 5`` deg; that is the set of readings whose direction lies
within 5 deg of the direction of the source, the rule applied here at every azimuth
(at incidence 10 the shadow reaches A = -70, 3.5 deg from the source; at A = -60, 5.2 deg
away, the reading is normal).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from brdfjax.data.formats.directions import relative_azimuth
from brdfjax.data.measurements import DataError, Measurements, validate

IN_PLANE_AZIMUTH = -90.0
# The detector shadows the incident beam when it looks from near the source's direction;
# the instrument's users drop |Receive + Incidence| <= 5 deg in the plane of incidence
# (their legacy script keeps only R < -I - 5 or R > -I + 5): readings within this angle
# of the source's direction, at any azimuth.
BEAM_CROSSING_DEG = 5.0
LABELS = ("Azimuth", "Incidence", "Receive", "RT")
INSTRUMENT = "J&C RT-300S"
# The laser of the University of Arizona instrument; the file itself does not record it.
LASER_WAVELENGTH_NM = 650.0
# Angles that agree to this many decimals of a degree are the same instrument setting.
DECIMALS = 6


@dataclass(frozen=True)
class Scan:
    """The measurements of one RT-300S file, one entry per column, in file order.

    Attributes:
        azimuth, incidence, receive: instrument angles in degrees.
        rt: the instrument's reflectance reading.
        cells: where each measurement sits, as ``Sheet!Column``, for messages.
    """

    azimuth: np.ndarray
    incidence: np.ndarray
    receive: np.ndarray
    rt: np.ndarray
    cells: tuple

    def select(self, mask) -> Scan:
        """The measurements where ``mask`` is true."""
        mask = np.asarray(mask, dtype=bool)
        cells = tuple(c for c, keep in zip(self.cells, mask) if keep)
        return Scan(self.azimuth[mask], self.incidence[mask], self.receive[mask],
                    self.rt[mask], cells)

    @property
    def azimuths(self) -> np.ndarray:
        """The distinct azimuths, sorted."""
        return np.unique(np.round(self.azimuth, DECIMALS))


def read(path, blank=None, keep_beam_crossing: bool = False,
         wavelength_nm: float = LASER_WAVELENGTH_NM, in_plane: bool = False) -> Measurements:
    """Read an RT-300S ``.xls`` export, every azimuth of it, as BRDF measurements.

    The blank reading at the same (Azimuth, Incidence, Receive) is subtracted (at the same
    (Incidence, Receive) for a blank of one azimuth) and the difference divided by
    ``pi cos(Receive)``. The reading (A, R) becomes ``theta_r = |R|`` and ``phi_r = A - 90``
    (R > 0) or ``A + 90`` (R < 0) degrees, in (-180, 180] (the module docstring derives
    it); at A = -90 that is ``phi_r = 180`` (specular side) for R > 0 and 0 otherwise. A
    geometry the sample was read at more than once gives one point per reading; the
    blank's repeats are averaged (it is a correction, subtracted from every reading).

    Args:
        path: the sample's ``.xls`` file.
        blank: the blank's ``.xls`` file; by default the single ``blank_*.xls`` file in the
            sample's folder.
        keep_beam_crossing: keep the readings within 5 deg of the source's direction
            (``|Receive + Incidence| <= 5`` deg in the plane of incidence), where the
            detector shadows the incident beam (dropped by default, as upstream).
        wavelength_nm: the laser wavelength to record (the file does not store it).
        in_plane: read the plane of incidence only (``Azimuth == -90``), as brdfjax read
            these files before it read them whole (132 readings per file of 4 incidences).

    Returns:
        The validated `Measurements`.
    """
    path = Path(path)
    if is_blank_name(path):
        raise DataError("this is a blank (empty holder) measurement, not a sample", path,
                        hint="read the sample's file; its blank is subtracted from it")
    # The sample's own format errors first: a file that is not an RT-300S export (another
    # spreadsheet, a CSV renamed .xls) must say so, not ask for a blank it will never use.
    whole = read_scan(path)
    sample = in_plane_slice(whole, path) if in_plane else whole
    blank_path = Path(blank) if blank is not None else find_blank(path)
    if blank_path.resolve() == path.resolve():
        raise DataError("the sample and the blank are the same file", path,
                        hint="pass blank= the empty-holder measurement")
    blank_scan = read_scan(blank_path)
    if in_plane:
        blank_scan = in_plane_slice(blank_scan, blank_path)
    reference, merged_blank = _average_repeats(blank_scan)
    rt_blank, blank_note = _blank_readings(sample, reference, path, blank_path)
    theta_r, phi_r = directions(sample.azimuth, sample.receive)
    crossing = (source_distance(sample.incidence, theta_r, phi_r)
                <= BEAM_CROSSING_DEG + 1e-9)
    keep = np.ones_like(crossing) if keep_beam_crossing else ~crossing
    brdf = (sample.rt - rt_blank) / (np.pi * np.cos(np.radians(sample.receive)))
    metadata = {
        "sample": path.stem,
        "wavelength_nm": float(wavelength_nm),
        "source": str(path),
        "instrument": INSTRUMENT,
        "blank": blank_path.name,
        "azimuths": _azimuth_note(whole, in_plane),
        "beam_crossing": f"{'kept' if keep_beam_crossing else 'dropped'} "
                         f"{int(crossing.sum())} points within {BEAM_CROSSING_DEG:g} deg of "
                         "the source's direction (|Receive + Incidence| <= "
                         f"{BEAM_CROSSING_DEG:g} deg in the plane of incidence)",
    }
    if blank_note:
        metadata["blank_azimuths"] = blank_note
    if merged_blank:
        metadata["blank_repeats_averaged"] = f"{merged_blank} repeated blank readings"
    data = Measurements.from_degrees(sample.incidence[keep], theta_r[keep], phi_r[keep],
                                     brdf[keep], metadata=metadata)
    return validate(data, path)


def directions(azimuth, receive) -> tuple[np.ndarray, np.ndarray]:
    """``(theta_r, phi_r)`` in degrees of instrument readings (A, R) in degrees:
    ``theta_r = |R|``, ``phi_r = A - 90 sign(R)`` in (-180, 180], exactly 0 or 180 in the
    plane of incidence and 0 at the normal (see the module docstring)."""
    azimuth, receive = (np.asarray(x, dtype=float) for x in (azimuth, receive))
    theta_r = np.abs(receive)
    return theta_r, relative_azimuth(azimuth - 90.0 * np.sign(receive), 0.0, theta_r)


def source_distance(incidence, theta_r, phi_r) -> np.ndarray:
    """The angle in degrees between the detector's direction ``(theta_r, phi_r)`` and the
    source's ``(incidence, 0)`` (all in degrees): ``|Receive + Incidence|`` in the plane of
    incidence."""
    t_i, t_r, p_r = (np.radians(np.asarray(x, dtype=float))
                     for x in (incidence, theta_r, phi_r))
    chord = np.stack([np.sin(t_r) * np.cos(p_r) - np.sin(t_i), np.sin(t_r) * np.sin(p_r),
                      np.cos(t_r) - np.cos(t_i)])
    return np.degrees(2 * np.arcsin(np.minimum(np.linalg.norm(chord, axis=0) / 2, 1.0)))


def is_blank_name(path) -> bool:
    """Whether the file name says blank (``blank_v2.xls``, ``204060_blank.xls``)."""
    return re.search(r"(^|[_\-. ])blank($|[_\-. ])", Path(path).stem.lower()) is not None


def find_blank(path) -> Path:
    """The single ``blank_*.xls`` file in the folder of ``path``.

    Raises:
        DataError: when there is none, or more than one.
    """
    path = Path(path)
    candidates = sorted(p for p in path.parent.glob("*.xls")
                        if p.name.lower().startswith("blank_") and p != path)
    if not candidates:
        raise DataError(f"no blank file (blank_*.xls) next to it in {path.parent}", path,
                        hint="pass blank= the empty-holder measurement taken on the same "
                             "(Azimuth, Incidence, Receive) grid (CLI: --blank FILE)")
    if len(candidates) > 1:
        names = ", ".join(p.name for p in candidates)
        raise DataError(f"several blank files next to it: {names}", path,
                        hint="pass blank= the one measured with this sample (CLI: --blank)")
    return candidates[0]


def read_scan(path) -> Scan:
    """All measurements of an RT-300S ``.xls`` file, in file order.

    Raises:
        DataError: when the file is not a readable RT-300S export.
    """
    import xlrd  # only this reader needs it

    path = Path(path)
    if not path.is_file():
        raise DataError("no such file", path)
    try:
        with open(os.devnull, "w") as quiet:  # xlrd prints its warnings otherwise
            book = xlrd.open_workbook(str(path), logfile=quiet)
    # A damaged workbook fails anywhere inside xlrd's parser (IndexError, struct.error,
    # KeyError, ... found by tests/test_formats_fuzz.py): every failure there means the
    # same thing to the user.
    except Exception as error:  # noqa: BLE001
        raise DataError(f"not a readable .xls workbook ({type(error).__name__}: {error})",
                        path, hint="export the RT-300S data as Excel 97-2003 .xls") from None
    columns = []
    for sheet in book.sheets():
        if sheet.nrows:
            columns += _sheet_columns(sheet, path)
    if not columns:
        raise DataError("no measurements in any sheet", path)
    values = np.array([c[0] for c in columns], dtype=float)
    return Scan(*values.T, tuple(c[1] for c in columns))


def in_plane_slice(scan: Scan, path) -> Scan:
    """The measurements of the plane of incidence (``Azimuth == -90``).

    Raises:
        DataError: when the scan has none.
    """
    picked = scan.select(np.abs(scan.azimuth - IN_PLANE_AZIMUTH) < 1e-9)
    if len(picked.rt) == 0:
        found = ", ".join(f"{a:g}" for a in np.unique(scan.azimuth)[:10])
        raise DataError(f"no in-plane measurements (Azimuth = {IN_PLANE_AZIMUTH:g}); the "
                        f"file has Azimuth {found}", path,
                        hint="read the whole file (in_plane=False; on the command line "
                             "leave out --in-plane)")
    return picked


def _sheet_columns(sheet, path) -> list:
    """``([azimuth, incidence, receive, rt], "Sheet!Column")`` for each filled column."""
    from xlrd.formula import colname

    labels = [str(v).strip() for v in sheet.col_values(0)]
    missing = [name for name in LABELS if name not in labels]
    if missing:
        raise DataError(f"sheet {sheet.name!r} has no row labelled {', '.join(missing)} in "
                        "column A", path,
                        hint="an RT-300S export labels its rows Azimuth, Incidence, Receive, "
                             "RT in the first column")
    rows = [labels.index(name) for name in LABELS]
    columns = []
    for col in range(1, sheet.ncols):
        cells = [sheet.cell_value(row, col) if col < sheet.row_len(row) else ""
                 for row in rows]
        where = f"{sheet.name}!{colname(col)}"
        if all(c == "" for c in cells):
            continue
        numbers = []
        for name, row, cell in zip(LABELS, rows, cells):
            if isinstance(cell, str):
                raise DataError(f"cell {sheet.name}!{colname(col)}{row + 1} ({name}) is "
                                f"{cell!r}, not a number", path,
                                hint="every measurement column needs Azimuth, Incidence, "
                                     "Receive and RT")
            numbers.append(float(cell))
        columns.append((numbers, where))
    return columns


def _average_repeats(scan: Scan) -> tuple[Scan, int]:
    """The scan with repeated (Azimuth, Incidence, Receive) readings averaged; and how many
    were merged."""
    key = np.round(np.stack([scan.azimuth, scan.incidence, scan.receive], axis=1), DECIMALS)
    _, first, inverse, counts = np.unique(key, axis=0, return_index=True,
                                          return_inverse=True, return_counts=True)
    if np.all(counts == 1):
        return scan, 0
    inverse = inverse.reshape(-1)
    means = np.bincount(inverse, weights=scan.rt) / counts
    order = np.argsort(first)  # keep the file's order
    picked = scan.select(np.isin(np.arange(len(scan.rt)), first[order]))
    averaged = Scan(picked.azimuth, picked.incidence, picked.receive, means[order],
                    picked.cells)
    return averaged, int(len(scan.rt) - len(first))


def _azimuth_note(whole: Scan, in_plane: bool) -> str:
    """What the metadata says of the file's azimuths and of those read."""
    azimuths = whole.azimuths
    if len(azimuths) == 1:
        return f"one instrument azimuth ({azimuths[0]:g} deg)"
    text = (f"{len(azimuths)} instrument azimuths, {azimuths[0]:g} to {azimuths[-1]:g} deg "
            f"({len(whole.rt)} readings)")
    if in_plane:
        text += f"; in_plane: only Azimuth {IN_PLANE_AZIMUTH:g} read"
    return text


def _blank_readings(sample: Scan, reference: Scan, path,
                    blank_path) -> tuple[np.ndarray, str]:
    """The blank's reading at each sample geometry, and a note when the blank has one
    azimuth and stands for all of the sample's; `DataError` if one is missing."""
    one_azimuth = len(reference.azimuths) == 1
    note = ""
    if one_azimuth and len(sample.azimuths) > 1:
        note = (f"the blank has one azimuth ({reference.azimuths[0]:g} deg): its "
                "(Incidence, Receive) readings are subtracted at every azimuth")

    def keys(scan: Scan):
        columns = [scan.incidence, scan.receive] if one_azimuth else \
            [scan.azimuth, scan.incidence, scan.receive]
        return [tuple(k) for k in np.round(np.stack(columns, axis=1), DECIMALS).tolist()]

    table = dict(zip(keys(reference), reference.rt))
    readings = np.empty_like(sample.rt)
    for k, (key, a, i, r) in enumerate(zip(keys(sample), sample.azimuth, sample.incidence,
                                            sample.receive)):
        value = table.get(key)
        if value is None:
            where = f"Incidence {i:g}, Receive {r:g}" if one_azimuth else \
                f"Azimuth {a:g}, Incidence {i:g}, Receive {r:g}"
            grid = "(Incidence, Receive)" if one_azimuth else "(Azimuth, Incidence, Receive)"
            raise DataError(f"{sample.cells[k]}: the blank {blank_path.name} has no reading "
                            f"at {where} deg", path,
                            hint=f"use a blank measured on the same {grid} grid")
        readings[k] = value
    return readings, note
