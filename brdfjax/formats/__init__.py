"""Reading and writing measurement files; `load` picks the reader from the file.

| format | suffix | reader |
|---|---|---|
| brdfjax CSV | ``.csv`` | `brdfjax.formats.csv` |
| NIST PTFE (Germer 2017) | ``.csv`` with a ``lambda,thetai,...`` header | `brdfjax.formats.nist` |
| J&C RT-300S export | ``.xls`` | `brdfjax.formats.rt300s` |
| Zemax tabular BSDF | ``.bsdf`` | `brdfjax.formats.zemax` |
"""

from __future__ import annotations

import os
import secrets
import stat
from pathlib import Path

from brdfjax.measurements import DataError, Measurements


def load(path, **options) -> Measurements:
    """Read measurements from any supported file.

    Args:
        path: the file.
        **options: reader options: ``blank=`` (RT-300S blank file), ``wavelength_nm=``
            (NIST, Zemax multi-wavelength files).

    Returns:
        The validated `Measurements`.
    """
    path = Path(path)
    if not path.is_file():
        raise DataError("no such file", path)
    suffix = path.suffix.lower()
    if suffix == ".csv":
        from brdfjax.formats import csv, nist

        with open(path, encoding="utf-8", errors="replace") as handle:
            first = handle.readline()
        reader = nist if first.startswith("lambda,") else csv
    elif suffix == ".xls":
        from brdfjax.formats import rt300s as reader
    elif suffix == ".bsdf":
        from brdfjax.formats import zemax as reader
    else:
        raise DataError(f"unknown format {suffix!r}", path,
                        hint="brdfjax reads .csv (its own or NIST's), .xls (J&C RT-300S) "
                             "and .bsdf (Zemax tabular)")
    return reader.read(path, **options)


def save(data: Measurements, path) -> None:
    """Write measurements as brdfjax CSV (``.csv``) or Zemax tabular BSDF (``.bsdf``)."""
    suffix = Path(path).suffix.lower()
    if suffix == ".csv":
        from brdfjax.formats import csv as writer
    elif suffix == ".bsdf":
        from brdfjax.formats import zemax as writer
    else:
        raise DataError(f"cannot write {suffix!r}", path, hint="write .csv or .bsdf")
    writer.write(data, path)


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
