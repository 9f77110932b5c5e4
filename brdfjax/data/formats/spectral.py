"""Choosing wavelengths in files that hold several (NIST PTFE, ASTM spectral columns)."""

from __future__ import annotations

import numpy as np

from brdfjax.data.measurements import DataError

# Wavelengths that agree to this many nanometres are the same.
WAVELENGTH_TOLERANCE_NM = 0.5


def listing(available_nm) -> str:
    """``"351, 532 nm"``."""
    return ", ".join(f"{w:g}" for w in available_nm) + " nm"


def pick_one(available_nm, wanted_nm, path) -> float:
    """The wanted wavelength among those available; may be omitted when there is one.

    Raises:
        DataError: when it is absent, or omitted while the file holds several.
    """
    if wanted_nm is None:
        if len(available_nm) > 1:
            raise DataError(f"the file holds {len(available_nm)} wavelengths: "
                            f"{listing(available_nm)}", path,
                            hint="choose one with wavelength_nm= (CLI: --wavelength)")
        return float(available_nm[0])
    return pick_many(available_nm, [wanted_nm], path)[0]


def pick_many(available_nm, wanted_nm, path) -> list[float]:
    """The available wavelengths matching each wanted one (to 0.5 nm); all when ``None``.

    Raises:
        DataError: naming the wanted wavelengths the file does not hold.
    """
    available = np.asarray(available_nm, dtype=float)
    if wanted_nm is None:
        return [float(w) for w in available]
    chosen, missing = [], []
    for wanted in np.atleast_1d(np.asarray(wanted_nm, dtype=float)):
        close = np.flatnonzero(np.abs(available - wanted) <= WAVELENGTH_TOLERANCE_NM)
        if close.size:
            chosen.append(float(available[close[0]]))
        else:
            missing.append(f"{wanted:g}")
    if missing:
        raise DataError(f"no data at {', '.join(missing)} nm; the file holds "
                        f"{listing(available)}", path, hint="choose one of the listed wavelengths")
    return chosen
