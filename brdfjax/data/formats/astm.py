"""ASTM E1392 scatter files (``.astm``): read, write, and export a fitted model.

The text format, as ALTA and libbsdf read it (the Cornell measurements use it)::

    SOURCE Cornell University Program of Computer Graphics
    SAMPLE_NAME white paint
    NUM_POINTS 2
    VARS theta_i,phi_i,theta_s,phi_s,550nm,650nm
    0.5236,0,0.5236,3.14159,0.213,0.220
    0.5236,0,0.3491,3.14159,0.208,0.215

``KEY value`` header lines (the key one word, upper case by custom) end at the ``VARS``
line, which names the comma-separated columns of the data lines that follow. The four
angles are in **radians**: ``theta_i, phi_i`` the direction toward the source,
``theta_s, phi_s`` the direction toward the detector, both pointing away from the
surface. The remaining columns are the outputs: one BRDF column (any name that is not a
wavelength, e.g. ``BRDF``), or one column per wavelength named ``<nm>nm`` (``550nm``);
several outputs that are not wavelengths (``R,G,B``, ``X,Y,Z``) are refused. ``NUM_POINTS``,
when present, must match the number of data lines. Blank lines and ``#`` lines are skipped.

**Turning the angles into the project's convention** (``MODEL.md``: the source at azimuth
0, ``phi_r = 180 deg`` the specular side). Both directions point away from the surface, so
the specular direction of ``(theta_i, phi_i)`` is ``(theta_i, phi_i + 180 deg)``; libbsdf
reads the files this way, rotating every ``phi_s`` by ``-phi_i`` when ``phi_i`` is not 0.
The reader, in degrees:

1. A negative polar angle is the positive angle on the opposite azimuth
   (``theta -> -theta``, ``phi -> phi + 180``).
2. ``phi_r = phi_s - phi_i``, wrapped into (-180, 180]; values within 1e-6 deg of 0 or 180
   are set to exactly 0 or 180 (in-plane points stay in-plane), and ``phi_r = 0`` at
   ``theta_r = 0``, where the azimuth is undefined.

No sign is flipped: ``phi_s - phi_i = 180`` is the specular side, as in the project. The
model is isotropic, so rotating both directions about the normal changes nothing.

Header keys become metadata (``SAMPLE_NAME`` the sample name, any other key its name in
lower case) and metadata header keys when written. The writer puts the source at
``phi_i = 0``, so ``phi_s`` is the project's ``phi_r`` (in (-pi, pi]), writes
``NUM_POINTS`` and one output column: ``<wavelength>nm`` when the wavelength is
known (``metadata["wavelength_nm"]``), else ``BRDF``. The format has no column for
``sigma`` or ``weight``; they are not written.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from brdfjax.data.formats import read_text, spectral, split_lines
from brdfjax.data.formats.directions import relative_azimuth, unsign
from brdfjax.data.measurements import DataError, Measurements, validate

ANGLES = ("theta_i", "phi_i", "theta_s", "phi_s")
SPECTRAL = re.compile(r"^(\d+(?:\.\d*)?)\s*nm$", re.IGNORECASE)
# The header key of the sample name; every other key is its metadata name in upper case.
SAMPLE_KEY = "SAMPLE_NAME"
# Metadata that the file records elsewhere (the VARS line, the data) or that is ours.
NOT_IN_HEADER = ("format", "wavelength_nm", "NUM_POINTS", "VARS")


def looks_like(text: str) -> bool:
    """Whether the text starts like an E1392 file: a ``VARS`` line naming the angles."""
    match = re.search(r"^\s*VARS\s+(.*)$", text, re.MULTILINE)
    return match is not None and "theta_i" in match.group(1).lower()


def read(path, wavelength_nm: float | None = None) -> Measurements:
    """Read an ASTM E1392 file as measurements in the project's convention.

    Args:
        path: the file.
        wavelength_nm: with several spectral columns, the one to read (nm).

    Returns:
        The validated `Measurements`, one point per data line.
    """
    table = _read_table(Path(path))
    return _measurements(table, _pick_output(table, wavelength_nm))


def read_spectral(path, wavelengths_nm=None) -> dict[float, Measurements]:
    """Read every spectral column of an E1392 file (or the listed wavelengths).

    Returns:
        ``{wavelength_nm: Measurements}``.

    Raises:
        DataError: when the output column is not a wavelength (``BRDF``).
    """
    table = _read_table(Path(path))
    available = table.wavelengths()
    if available is None:
        raise DataError(f"the output column {table.outputs[0]!r} is not a wavelength",
                        table.path, table.vars_line,
                        hint="spectral columns are named like 550nm; read it with load()")
    chosen = spectral.pick_many(available, wavelengths_nm, table.path)
    return {w: _measurements(table, available.index(w)) for w in chosen}


def write(data: Measurements, path) -> None:
    """Write measurements as an E1392 file (radians, source at ``phi_i = 0``)."""
    header = {SAMPLE_KEY if name == "sample" else name.upper().replace(" ", "_"): value
              for name, value in data.metadata.items() if name not in NOT_IN_HEADER}
    _write_table(path, header, data.theta_i, data.theta_r, data.phi_r, data.brdf,
                 _output_name(data.wavelength_nm))


def write_model_astm(path, params, incidences_deg, theta_r_deg=tuple(range(0, 90, 5)),
                phi_r_deg=tuple(range(0, 181, 10)), sample: str = "brdfjax model",
                wavelength_nm: float | None = None, model=None, correction=None) -> None:
    """Export a fitted model (any of `brdfjax.models`) as an E1392 file tabulated on a grid.

    Evaluates the model at every (incidence, theta_r, phi_r) combination through
    `brdfjax.data.formats.zemax.evaluate_model`, the same call the Zemax export uses, and
    writes one point per combination (the normal once per incidence).

    Args:
        path: the file to write.
        params: the model's parameters (for the default model a `~brdfjax.models.paper.Params` or
            kb, kr, a, b, kd).
        incidences_deg: the angles of incidence.
        theta_r_deg: reflection zenith angles (below 90).
        phi_r_deg: reflection azimuths (180 = specular side); the model is even in
            ``phi_r``, so 0 to 180 covers the hemisphere.
        sample: written as ``SAMPLE_NAME``.
        wavelength_nm: names the output column (``<nm>nm``) when given, else ``BRDF``.
        model: a model name or `brdfjax.models.Model` (None: the model of a named tuple,
            else the five-parameter model; `brdfjax.models.model_for`).
        correction: a learned discrepancy to apply
            (`brdfjax.prediction.discrepancy.Discrepancy`), or None.
    """
    from brdfjax.data.formats.zemax import evaluate_model, model_comment, parameter_comment
    from brdfjax.models import model_for

    model = model_for(params, model)  # once, for the table and its header

    grid = np.meshgrid(*(np.asarray(x, dtype=float).reshape(-1)
                         for x in (incidences_deg, theta_r_deg, phi_r_deg)), indexing="ij")
    theta_i, theta_r, phi_r = (g.reshape(-1) for g in grid)
    # The normal is one direction: keep it once per incidence, at azimuth 0.
    keep = (theta_r > 0) | (phi_r == phi_r.min())
    theta_i, theta_r, phi_r = theta_i[keep], theta_r[keep], phi_r[keep] * (theta_r[keep] > 0)
    values = evaluate_model(params, theta_i, theta_r, phi_r, model, correction)
    header = {SAMPLE_KEY: sample, "SOURCE": model_comment(model, correction),
              "COMMENT": parameter_comment(params, model)}
    _write_table(path, header, *np.radians([theta_i, theta_r, phi_r]), values,
                 _output_name(wavelength_nm))


# --- reading ----------------------------------------------------------------------------

class _Table:
    """The parsed file: header, output names, values (rows x columns) and their lines."""

    def __init__(self, path, header, outputs, values, lines, vars_line):
        self.path, self.header, self.outputs = path, header, outputs
        self.values, self.lines, self.vars_line = values, lines, vars_line

    def wavelengths(self) -> list | None:
        """The wavelength of each output column (nm), or None if they are not spectral."""
        matches = [SPECTRAL.match(name) for name in self.outputs]
        if all(matches):
            return [float(m.group(1)) for m in matches]
        if len(self.outputs) > 1:
            raise DataError(f"outputs {', '.join(self.outputs)} are neither one BRDF column "
                            "nor wavelengths", self.path, self.vars_line,
                            "brdfjax reads one BRDF column or spectral columns named like "
                            "550nm (not R,G,B or X,Y,Z)")
        return None


def _read_table(path) -> _Table:
    header, header_lines, columns, vars_line = {}, {}, None, None
    rows, lines = [], []
    for number, raw in enumerate(split_lines(read_text(path)), start=1):
        text = raw.strip()
        if not text or text.startswith("#"):
            continue
        if columns is None:
            key, value = (text.split(None, 1) + [""])[:2]
            if key == "VARS":
                columns, vars_line = _check_vars(value, path, number), number
            else:
                header[key], header_lines[key] = value.strip(), number
            continue
        cells = text.split(",") if "," in text else text.split()
        if len(cells) != len(columns):
            raise DataError(f"{len(cells)} values, VARS names {len(columns)}", path, number,
                            "one point per line: the four angles and every output")
        rows.append([_number(c, name, path, number) for c, name in zip(cells, columns)])
        lines.append(number)
    if columns is None:
        raise DataError("no VARS line", path, hint="an ASTM E1392 header ends with "
                        "VARS theta_i,phi_i,theta_s,phi_s,<outputs>")
    if not rows:
        raise DataError("no data lines after VARS", path, vars_line)
    _check_count(header, header_lines, len(rows), path)
    values = np.array(rows)
    order = [columns.index(name) for name in ANGLES]
    order += [k for k in range(len(columns)) if columns[k] not in ANGLES]
    outputs = [columns[k] for k in order[4:]]
    return _Table(path, header, outputs, values[:, order], np.array(lines), vars_line)


def _check_vars(text, path, line) -> list:
    names = [name.strip() for name in text.split(",") if name.strip()]
    lower = [name.lower() for name in names]
    missing = [name for name in ANGLES if name not in lower]
    if missing:
        raise DataError(f"VARS has no {', '.join(missing)}", path, line,
                        "VARS must name theta_i,phi_i,theta_s,phi_s and the outputs")
    if len(names) < 5:
        raise DataError("VARS names no output column", path, line,
                        "add a BRDF column (or spectral columns such as 550nm)")
    repeated = sorted({n for n in lower if lower.count(n) > 1})
    if repeated:
        raise DataError(f"VARS names {', '.join(repeated)} twice", path, line)
    return [name if name.lower() not in ANGLES else name.lower() for name in names]


def _check_count(header, header_lines, rows, path) -> None:
    if "NUM_POINTS" not in header:
        return
    text = header["NUM_POINTS"]
    if not text.isdigit() or int(text) != rows:
        raise DataError(f"NUM_POINTS is {text!r}, but {rows} data lines follow", path,
                        header_lines["NUM_POINTS"], "the file looks truncated or edited: "
                        "NUM_POINTS must count the data lines")


def _number(cell: str, name: str, path, line: int) -> float:
    try:
        return float(cell)
    except ValueError:
        raise DataError(f"{name} = {cell.strip()!r} is not a number", path, line) from None


def _pick_output(table: _Table, wavelength_nm) -> int:
    available = table.wavelengths()
    if available is None:
        if wavelength_nm is not None:
            raise DataError(f"no wavelength columns; the output is {table.outputs[0]!r}",
                            table.path, table.vars_line, "read it without a wavelength")
        return 0
    return available.index(spectral.pick_one(available, wavelength_nm, table.path))


def _measurements(table: _Table, output: int) -> Measurements:
    for column, name in ((0, "theta_i"), (2, "theta_s")):
        bad = np.flatnonzero(~(np.abs(table.values[:, column]) <= np.pi / 2 + 1e-9))
        if bad.size:
            raise DataError(f"{name} = {table.values[bad[0], column]:g} is not a polar angle "
                            "in radians (|angle| <= pi/2)", table.path, table.lines[bad[0]],
                            "E1392 angles are radians: was the file written in degrees?")
    with np.errstate(over="ignore", invalid="ignore"):  # huge azimuths: validate says so
        theta_i, phi_i, theta_s, phi_s = np.degrees(table.values[:, :4].T)
        theta_i, phi_i = unsign(theta_i, phi_i)
        theta_r, phi_s = unsign(theta_s, phi_s)
        phi_r = relative_azimuth(phi_s, phi_i, theta_r)
    metadata = {"sample" if key == SAMPLE_KEY else key.lower(): value
                for key, value in table.header.items() if key not in NOT_IN_HEADER}
    metadata.setdefault("sample", table.path.stem)
    wavelengths = table.wavelengths()
    if wavelengths is not None:
        metadata["wavelength_nm"] = wavelengths[output]
    metadata.setdefault("source", str(table.path))
    metadata["format"] = "ASTM E1392"
    data = Measurements.from_degrees(theta_i, theta_r, phi_r, table.values[:, 4 + output],
                                     metadata=metadata)
    return validate(data, table.path, table.lines)


# --- writing ----------------------------------------------------------------------------

def _output_name(wavelength_nm) -> str:
    return "BRDF" if wavelength_nm is None else f"{float(wavelength_nm):g}nm"


def _write_table(path, header, theta_i, theta_r, phi_r, values, output) -> None:
    """Write the header, ``NUM_POINTS``, ``VARS`` and one line per point (radians)."""
    from brdfjax.data.formats import write_atomically

    lines = [f"{key} {' '.join(str(value).split())}" for key, value in header.items()]
    lines.append(f"NUM_POINTS {len(values)}")
    lines.append(f"VARS {','.join(ANGLES)},{output}")
    phi_r = np.pi - np.mod(np.pi - np.asarray(phi_r, dtype=float), 2 * np.pi)  # (-pi, pi]
    for row in zip(theta_i, np.zeros(len(values)), theta_r, phi_r, values):
        lines.append(",".join(f"{x:.17g}" for x in row))  # lossless
    write_atomically(path, "\n".join(lines) + "\n")
