"""Reading and writing measurement files; `load` picks the reader from the file.

| format | suffix | reader |
|---|---|---|
| brdfjax CSV | ``.csv`` | `brdfjax.data.formats.csv` |
| NIST PTFE (Germer 2017) | ``.csv``, ``lambda,thetai,...`` header | `brdfjax.data.formats.nist` |
| ASTM E1392 | ``.astm`` (or text with a ``VARS theta_i,...`` line) | `brdfjax.data.formats.astm` |
| Starlink ScatterWorks (lumos-sat) | text with a ``phi_i theta_i phi_o theta_o brdf`` line | `brdfjax.data.formats.starlink` |
| J&C RT-300S export | ``.xls`` | `brdfjax.data.formats.rt300s` |
| Zemax tabular BSDF | ``.bsdf`` | `brdfjax.data.formats.zemax` |

`load` reads one wavelength, `load_spectral` every wavelength of a file, and
`load_geometry` also a CSV that lists angles without measured values (for predictions).
"""

from __future__ import annotations

import dataclasses
import inspect
import json
import math
import os
import secrets
import stat
from pathlib import Path

from brdfjax.data.measurements import DataError, Measurements

# How much of a text file is looked at to tell its format.
SNIFF_CHARACTERS = 65536
WRITERS = {".csv": "csv", ".bsdf": "zemax", ".astm": "astm"}
# The suffixes `load` reads (a folder given to ``brdfjax batch`` yields these files).
READABLE = (".csv", ".astm", ".xls", ".bsdf")


def load(path, **options) -> Measurements:
    """Read measurements from any supported file.

    Args:
        path: the file.
        **options: reader options: ``blank=`` (RT-300S blank file), ``in_plane=True``
            (RT-300S: the plane of incidence only, not the whole 3-D scan),
            ``wavelength_nm=`` (NIST, ASTM and Zemax files).

    Returns:
        The validated `Measurements`.
    """
    return _read_from(path, _reader(path, options).read(path, **options))


def _read_from(path, data: Measurements) -> Measurements:
    """``data`` with the file it was read from (`Measurements.path`: errors name it)."""
    return dataclasses.replace(data, path=str(path))


def load_geometry(path, **options) -> Measurements:
    """Read the geometry of a file, which need not hold measured values.

    A brdfjax CSV may lack the ``brdf`` column (``theta_i,theta_r,phi_r``): its points
    then come back with ``brdf`` NaN (``Measurements.has_brdf`` is False), the angles
    checked as `load` checks them. Files with values load as with `load`, values kept.

    Args:
        path: the file.
        **options: as for `load`.

    Returns:
        The `Measurements` (angles in radians, as always).
    """
    reader = _reader(path, options)
    only = {"geometry_only": True} if reader.__name__ == "brdfjax.data.formats.csv" else {}
    return _read_from(path, reader.read(path, **only, **options))


def load_spectral(path, wavelengths=None) -> dict[float, Measurements]:
    """Read every wavelength of a file (or the listed ones) as separate measurements.

    NIST PTFE tables and ASTM files with spectral columns (``550nm``, ...) give one entry
    per wavelength; any other file gives its single wavelength, which it must record
    (``metadata["wavelength_nm"]``).

    Args:
        path: the file.
        wavelengths: wavelengths in nm to read (each matched to 0.5 nm), or None for all.

    Returns:
        ``{wavelength_nm: Measurements}``, in the file's order or the order asked.

    Raises:
        DataError: for a wavelength the file does not hold, or a file without one.
    """
    from brdfjax.data.formats import spectral

    reader = _reader(path)
    if hasattr(reader, "read_spectral"):
        return {wavelength: _read_from(path, data)
                for wavelength, data in reader.read_spectral(path, wavelengths).items()}
    data = _read_from(path, reader.read(path))
    try:
        wavelength = float(data.metadata["wavelength_nm"])
    except (KeyError, ValueError):
        raise DataError("the file records no wavelength in nm", path,
                        hint="load it with load(); a brdfjax CSV records one in a "
                             "'# wavelength_nm: 633' line") from None
    spectral.pick_many([wavelength], wavelengths, path)
    return {wavelength: data}


def save(data: Measurements, path) -> None:
    """Write measurements as brdfjax CSV (``.csv``), Zemax (``.bsdf``) or ASTM (``.astm``)."""
    from importlib import import_module

    suffix = Path(path).suffix.lower()
    if suffix not in WRITERS:
        raise DataError(f"cannot write {suffix!r}", path, hint="write .csv, .bsdf or .astm")
    import_module(f"brdfjax.data.formats.{WRITERS[suffix]}").write(data, path)


def read_text(path) -> str:
    """A text file's content: UTF-8 (a byte-order mark dropped), else Latin-1.

    Latin-1 decodes any bytes, so a file from an older spreadsheet ("CSV" in a Windows
    code page) still reads; its numbers and column names are ASCII either way.

    Raises:
        DataError: when the file cannot be read.
    """
    try:
        raw = Path(path).read_bytes()
    except OSError as error:
        raise DataError(f"cannot read the file ({error.strerror})", path) from None
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def split_lines(text: str) -> list[str]:
    """The lines of a text as an editor numbers them: split at ``\\n``, ``\\r\\n`` or ``\\r``.

    (`str.splitlines` also splits at form feeds and other separators, which would make the
    line numbers in messages disagree with the file.)
    """
    return text.replace("\r\n", "\n").replace("\r", "\n").split("\n")


# The command-line option of each reader option, for an error that names what was typed.
OPTION_FLAGS = {"blank": "--blank", "in_plane": "--in-plane", "wavelength_nm": "--wavelength"}


def _reader(path, options=()):
    """The reader module for a file: by suffix, and for text files by content; a
    `DataError` if it does not take one of the reader ``options`` given (``--blank`` for a
    CSV)."""
    unknown = [name for name in options if name not in OPTION_FLAGS]
    if unknown:
        raise TypeError(f"unexpected reader option {unknown[0]!r}; the options are "
                        f"{', '.join(f'{n}=' for n in OPTION_FLAGS)} (the command line's "
                        f"{', '.join(OPTION_FLAGS.values())})")
    reader = _format_reader(path)
    taken = inspect.signature(reader.read).parameters
    for name in options:
        if name not in taken:
            kind = reader.__name__.rsplit(".", 1)[-1]
            raise DataError(f"{OPTION_FLAGS[name]} does not apply to this file "
                            f"({kind} format)", path,
                            hint="--blank and --in-plane are for RT-300S .xls scans, "
                                 "--wavelength for NIST, ASTM, Zemax and CSV files of several "
                                 "wavelengths")
    return reader


def _format_reader(path):
    from brdfjax.data.formats import astm, csv, nist, rt300s, starlink, zemax

    path = Path(path)
    if path.is_dir():
        raise DataError("is a folder, not a file", path,
                        hint="give one of its files; brdfjax batch FOLDER --out RESULTS.csv "
                             "fits every file of a folder")
    if not path.is_file():
        raise DataError("no such file", path)
    suffix = path.suffix.lower()
    if suffix == ".xls":
        return rt300s
    if suffix == ".bsdf":
        return zemax
    head = read_text(path)[:SNIFF_CHARACTERS]
    if suffix == ".astm" or astm.looks_like(head):
        return astm
    if starlink.looks_like(head):
        return starlink
    if suffix == ".csv":
        first = next((line.strip() for line in head.splitlines() if line.strip()), "")
        return nist if first.startswith("lambda,") else csv
    raise DataError(f"unknown format {suffix!r}", path,
                    hint="brdfjax reads .csv (its own or NIST's), .astm (ASTM E1392), "
                         ".xls (J&C RT-300S) and .bsdf (Zemax tabular)")


def json_text(value) -> str:
    """``value`` as indented JSON with a final newline. A float that is not finite (the E of
    a failed fit) is written as null: strict JSON has no NaN or Infinity, which Python's
    `json` would otherwise write and other readers refuse."""

    def finite(x):
        if isinstance(x, dict):
            return {k: finite(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [finite(v) for v in x]
        if isinstance(x, float) and not math.isfinite(x):
            return None
        return x

    return json.dumps(finite(value), indent=2, allow_nan=False) + "\n"


def write_atomically(path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file, so no half-written file remains."""

    def write(temporary):
        with open(temporary, "w", encoding="utf-8") as out:
            out.write(text)

    replace_atomically(path, write)


def replace_atomically(path, writer) -> None:
    """Call ``writer(temporary_path)``, then move the result onto ``path`` in one step.

    The temporary file sits beside ``path`` with the same suffix (so writers that pick a
    format by suffix, like matplotlib, still can); on any error it is removed and ``path``
    is left as it was. The result has the mode a new file gets from the user's umask (0644
    under umask 022; `tempfile.mkstemp` would give 0600), or the mode of the file it
    replaces.
    """
    path = Path(path)
    temporary = _create_beside(path)
    try:
        if path.exists():
            os.chmod(temporary, stat.S_IMODE(path.stat().st_mode))
        writer(temporary)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def _create_beside(path: Path) -> str:
    """A new empty hidden file beside ``path``, created with mode 0666 less the umask.

    `os.open` applies the umask itself, so nothing reads or changes the process-wide umask
    (which `os.umask` would, racing other threads).
    """
    for _ in range(100):
        temporary = path.parent / f".{path.stem}.{secrets.token_hex(4)}{path.suffix}"
        try:
            os.close(os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
        except FileExistsError:
            continue
        except OSError as error:  # name the path the user gave, not the temporary file
            raise OSError(f"cannot write {path}: {error.strerror}") from None
        return str(temporary)
    raise FileExistsError(f"cannot write {path}: no free temporary name beside it")
