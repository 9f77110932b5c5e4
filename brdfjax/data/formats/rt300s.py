"""J&C RT-300S scatterometer exports (``.xls``), as measured by the University of Arizona.

The instrument writes one column per measurement, spread over several sheets, with rows
labelled in column 0: ``Azimuth``, ``Incidence`` and ``Receive`` (degrees) and ``RT`` (its
reflectance reading). ``Receive`` is a signed in-plane angle, ``> 0`` on the specular side.
Only the in-plane scan (``Azimuth == -90``) is read.

The reading becomes a BRDF as the instrument's users convert it,

    f_r = (RT_sample - RT_blank) / (pi cos(Receive)),

with ``RT_blank`` the reading of a blank (the empty sample holder) at the same
(Incidence, Receive). The blank is a second ``.xls`` file; by default the one file named
``blank_*.xls`` next to the sample is used.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from brdfjax.data.measurements import DataError, Measurements, validate

IN_PLANE_AZIMUTH = -90.0
# The detector shadows the incident beam when Receive is near -Incidence; the instrument's
# users drop |Receive + Incidence| <= 5 deg (their legacy script keeps only R < -I - 5 or
# R > -I + 5).
BEAM_CROSSING_DEG = 5.0
LABELS = ("Azimuth", "Incidence", "Receive", "RT")
INSTRUMENT = "J&C RT-300S"
# The laser of the University of Arizona instrument; the file itself does not record it.
LASER_WAVELENGTH_NM = 650.0


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


def read(path, blank=None, keep_beam_crossing: bool = False,
         wavelength_nm: float = LASER_WAVELENGTH_NM) -> Measurements:
    """Read the in-plane scan of an RT-300S ``.xls`` export as BRDF measurements.

    The blank reading at the same (Incidence, Receive) is subtracted and the difference
    divided by ``pi cos(Receive)``. ``Receive > 0`` is the specular side, so a point becomes
    ``theta_r = |Receive|`` with ``phi_r = 180`` deg when ``Receive > 0`` and 0 otherwise.
    A geometry the sample was read at more than once gives one point per reading; the
    blank's repeats are averaged (it is a correction, subtracted from every reading).

    Args:
        path: the sample's ``.xls`` file.
        blank: the blank's ``.xls`` file; by default the single ``blank_*.xls`` file in the
            sample's folder.
        keep_beam_crossing: keep the points with ``|Receive + Incidence| <= 5`` deg, where
            the detector shadows the incident beam (dropped by default, as upstream).
        wavelength_nm: the laser wavelength to record (the file does not store it).

    Returns:
        The validated `Measurements`.
    """
    path = Path(path)
    if is_blank_name(path):
        raise DataError("this is a blank (empty holder) measurement, not a sample", path,
                        hint="read the sample's file; its blank is subtracted from it")
    # The sample's own format errors first: a file that is not an RT-300S export (another
    # spreadsheet, a CSV renamed .xls) must say so, not ask for a blank it will never use.
    sample = in_plane(read_scan(path), path)
    blank_path = Path(blank) if blank is not None else find_blank(path)
    if blank_path.resolve() == path.resolve():
        raise DataError("the sample and the blank are the same file", path,
                        hint="pass blank= the empty-holder measurement")
    reference, merged_blank = _average_repeats(in_plane(read_scan(blank_path), blank_path))
    rt_blank = _blank_readings(sample, reference, path, blank_path)
    crossing = np.abs(sample.receive + sample.incidence) <= BEAM_CROSSING_DEG + 1e-9
    keep = np.ones_like(crossing) if keep_beam_crossing else ~crossing
    brdf = (sample.rt - rt_blank) / (np.pi * np.cos(np.radians(sample.receive)))
    metadata = {
        "sample": path.stem,
        "wavelength_nm": float(wavelength_nm),
        "source": str(path),
        "instrument": INSTRUMENT,
        "blank": blank_path.name,
        "beam_crossing": f"{'kept' if keep_beam_crossing else 'dropped'} "
                         f"{int(crossing.sum())} points with |Receive + Incidence| <= "
                         f"{BEAM_CROSSING_DEG:g} deg",
    }
    if merged_blank:
        metadata["blank_repeats_averaged"] = f"{merged_blank} repeated blank readings"
    receive = sample.receive[keep]
    data = Measurements.from_degrees(
        sample.incidence[keep], np.abs(receive), np.where(receive > 0, 180.0, 0.0),
        brdf[keep], metadata=metadata)
    return validate(data, path)


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
                             "(Incidence, Receive) grid (CLI: --blank FILE)")
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


def in_plane(scan: Scan, path) -> Scan:
    """The measurements of the in-plane scan (``Azimuth == -90``)."""
    picked = scan.select(np.abs(scan.azimuth - IN_PLANE_AZIMUTH) < 1e-9)
    if len(picked.rt) == 0:
        found = ", ".join(f"{a:g}" for a in np.unique(scan.azimuth)[:10])
        raise DataError(f"no in-plane measurements (Azimuth = {IN_PLANE_AZIMUTH:g}); the "
                        f"file has Azimuth {found}", path,
                        hint="brdfjax reads the RT-300S in-plane scan only")
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
    """The scan with repeated (Incidence, Receive) readings averaged; and how many merged."""
    key = np.round(np.stack([scan.incidence, scan.receive], axis=1), 6)
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


def _blank_readings(sample: Scan, reference: Scan, path, blank_path) -> np.ndarray:
    """The blank's reading at each sample geometry; `DataError` if one is missing."""
    table = {(round(i, 6), round(r, 6)): rt
             for i, r, rt in zip(reference.incidence, reference.receive, reference.rt)}
    readings = np.empty_like(sample.rt)
    for k, (i, r) in enumerate(zip(sample.incidence, sample.receive)):
        value = table.get((round(i, 6), round(r, 6)))
        if value is None:
            raise DataError(f"{sample.cells[k]}: the blank {blank_path.name} has no reading "
                            f"at Incidence {i:g}, Receive {r:g} deg", path,
                            hint="use a blank measured on the same (Incidence, Receive) grid")
        readings[k] = value
    return readings
