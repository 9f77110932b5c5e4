"""Many samples in one HDF5 file: the measurement cube and its results.

A cube holds N samples of up to P readings each (per-pixel captures, satellite pixels)::

    theta_i, theta_r, phi_r   float, degrees, (P,) when every sample shares the geometry,
                              or (N, P), one row per sample; each may be either
    brdf                      float, 1/sr, (N, P); NaN where a reading is missing
    sigma                     optional, like brdf: standard uncertainty of each reading
    sample                    optional, (N,) names (strings)

Other datasets and attributes are ignored. A NetCDF-4 file with these variables is an HDF5
file and reads the same (``.nc``). `Cube` reads it a block of samples at a time, so memory
stays bounded whatever N is; `write_cube` writes one.

``brdfjax batch CUBE.h5 --out RESULTS.h5`` writes, for the same sample axis (N,):

    one dataset per parameter of the model (kb, kr, ...; NaN where the fit failed),
    error (E of Eq. 6, a fraction), status (converged, max_steps, underdetermined: no more
    distinct geometries than parameters, or failed),
    message (why, where there is more to say), sample (copied when the cube has names),
    std_NAME with ``--uncertainty laplace``;
    attributes: model, source (the cube) and options (JSON, the options that change results).

While it runs, every finished block of samples is journalled as one small file in
``RESULTS.h5.parts/`` (written whole or not at all), and the results file is assembled
from them at the end: a run killed at any moment (even ``kill -9``) loses at most the
blocks in flight, and a rerun fits only the samples no journal holds. An HDF5 file that
is being written when the process dies can be left unreadable, which is why the results
file is not updated in place.
"""

from __future__ import annotations

import json
import os
import secrets
from pathlib import Path

import numpy as np

from brdfjax.data.measurements import DataError, Measurements, validate

SUFFIXES = (".h5", ".hdf5", ".nc")
ANGLES = ("theta_i", "theta_r", "phi_r")
# A results file's statuses (`brdfjax.fitting.fit.STATUSES` of a hybrid fit), and the width
# of its status column.
STATUSES = ("converged", "max_steps", "underdetermined", "failed")
STATUS_WIDTH = max(map(len, STATUSES))
SCHEMA = ("a cube needs datasets theta_i, theta_r, phi_r (degrees, (P,) or (N, P)) and "
          "brdf (N, P), with optional sigma (N, P) and sample (N,): see brdfjax.data.formats.cube")


def is_cube(path) -> bool:
    """Whether ``path`` names a cube (by its suffix)."""
    return Path(path).suffix.lower() in SUFFIXES


def _h5py():
    from brdfjax.optional import require

    require("h5py", "cube", "an HDF5 cube")
    import h5py

    return h5py


class Cube:
    """An open cube: its shape, and its samples read a block at a time.

    Raises `brdfjax.data.measurements.DataError` naming the file and what is wrong when the
    file does not follow the schema (module docstring).
    """

    def __init__(self, path):
        h5py = _h5py()
        self.path = Path(path)
        try:
            self.file = h5py.File(self.path, "r")
        except OSError as error:
            raise DataError(f"{path}: cannot be read as HDF5 ({error}); {SCHEMA}") from None
        try:
            self._check()
        except Exception:
            self.file.close()
            raise

    def _check(self) -> None:
        missing = [name for name in (*ANGLES, "brdf") if name not in self.file]
        if missing:
            raise DataError(f"{self.path}: no dataset {', '.join(missing)}; {SCHEMA}")
        brdf = self.file["brdf"]
        if brdf.ndim != 2:
            raise DataError(f"{self.path}: brdf has shape {brdf.shape}, not (N, P); {SCHEMA}")
        self.count, self.points = brdf.shape
        for name in (*ANGLES, "sigma"):
            if name not in self.file:
                continue
            shape = self.file[name].shape
            allowed = [(self.count, self.points)] + ([(self.points,)] if name in ANGLES else [])
            if shape not in allowed:
                raise DataError(f"{self.path}: {name} has shape {shape}; brdf is "
                                f"{brdf.shape}, so give {' or '.join(map(str, allowed))}")
        # Shared angles are read once; per-sample ones a block at a time.
        self.shared = {name: np.asarray(self.file[name][...], dtype=float)
                       for name in ANGLES if self.file[name].ndim == 1}
        if self.shares_geometry:
            self._check_geometry()
        self.names = None
        if "sample" in self.file:
            if self.file["sample"].shape != (self.count,):
                raise DataError(f"{self.path}: sample has shape {self.file['sample'].shape}; "
                                f"give one name per sample, ({self.count},)")
            self.names = [_text(x) for x in self.file["sample"][...]]

    def _check_geometry(self) -> None:
        """The angle checks a file's measurements get (`validate`: degrees, not radians;
        zenith angles in [0, 90] deg; azimuths within one turn), once for the geometry that
        every sample shares, so that a mistake there is one error before any fit, not a
        failure of every sample. Angles that are NaN are left out, as `read` leaves them."""
        angles = np.stack([self.shared[name] for name in ANGLES])
        angles = angles[:, np.all(np.isfinite(angles), axis=0)]
        if angles.shape[1]:
            validate(Measurements.from_degrees(*angles, np.full(angles.shape[1], np.nan)),
                     f"{self.path} (the angles every sample shares)", geometry_only=True)

    @property
    def shares_geometry(self) -> bool:
        """Whether every sample has the same angles (all three datasets (P,))."""
        return len(self.shared) == len(ANGLES)

    def name(self, index: int) -> str:
        """Sample ``index``'s name: from ``sample``, else ``FILE[index]``."""
        return self.names[index] if self.names else f"{self.path.name}[{index}]"

    def read(self, indices) -> list[Measurements]:
        """The samples at ``indices`` (increasing), each without its missing (NaN) readings."""
        indices = np.asarray(indices, dtype=int)
        runs = np.split(indices, np.flatnonzero(np.diff(indices) != 1) + 1)

        def rows(name):
            if name in self.shared:
                return None
            return np.concatenate([self.file[name][run[0]:run[-1] + 1] for run in runs])

        values = {name: rows(name) for name in (*ANGLES, "brdf")}
        sigma = rows("sigma") if "sigma" in self.file else None
        samples = []
        for row, index in enumerate(indices):
            angles = [self.shared[n] if values[n] is None else values[n][row] for n in ANGLES]
            brdf = values["brdf"][row]
            keep = np.isfinite(brdf) & np.all(np.isfinite(angles), axis=0)
            samples.append(Measurements.from_degrees(
                *(a[keep] for a in angles), brdf[keep],
                sigma=None if sigma is None else sigma[row][keep],
                metadata={"sample": self.name(int(index)), "source": str(self.path),
                          "index": int(index)}, path=str(self.path)))
        return samples

    def close(self) -> None:
        """Close the file."""
        self.file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _text(value) -> str:
    return value.decode("utf-8") if isinstance(value, bytes) else str(value)


def write_cube(path, theta_i, theta_r, phi_r, brdf, sigma=None, sample=None) -> None:
    """Write a cube (schema in the module docstring); angles in degrees."""
    h5py = _h5py()
    with h5py.File(path, "w") as out:
        for name, values in (("theta_i", theta_i), ("theta_r", theta_r), ("phi_r", phi_r),
                             ("brdf", brdf), ("sigma", sigma)):
            if values is not None:
                out.create_dataset(name, data=np.asarray(values, dtype=float))
        for name in ANGLES:
            out[name].attrs["units"] = "degree"
        out["brdf"].attrs["units"] = "1/sr"
        if sample is not None:
            out.create_dataset("sample", data=[str(s) for s in sample],
                               dtype=h5py.string_dtype())


class CubeResults:
    """The results of a cube run: journalled block by block, assembled into one file.

    Args:
        out: the results file (``.h5``).
        count: the cube's sample count N.
        names: the model's parameter names.
        settings: the options that change results (`brdfjax.commands.batch.result_options`);
            a journal or results file written with other settings is refused.
    """

    def __init__(self, out, count: int, names, settings: dict):
        self.out, self.count, self.names = Path(out), count, list(names)
        self.settings = json.dumps(settings, sort_keys=True)
        self.parts = Path(f"{out}.parts")

    def stored_settings(self) -> str | None:
        """The settings of the journal or finished results already there, if any."""
        journal = self.parts / "options.json"
        if journal.exists():
            return journal.read_text(encoding="utf-8")
        if self.out.exists():
            h5py = _h5py()
            try:
                with h5py.File(self.out, "r") as results:
                    return _text(results.attrs["options"])
            except (OSError, KeyError):
                raise ValueError(f"{self.out}: exists and is not a results file of brdfjax "
                                 "batch; give another --out") from None
        return None

    def done(self) -> np.ndarray:
        """(N,) True for every sample already fitted (by a journal or a finished file)."""
        done = np.zeros(self.count, dtype=bool)
        if self.parts.exists():
            for part in self.parts.glob("*.npz"):
                with np.load(part) as block:
                    done[block["index"]] = True
        elif self.out.exists():
            done[:] = True
        return done

    def start(self) -> None:
        """Open the journal (keeping the settings in it) unless it is there already."""
        if self.parts.exists():
            return
        if self.out.exists():  # finished with these settings and nothing left: kept as is
            return
        self.parts.mkdir(parents=True)
        _write_whole(self.parts / "options.json", self.settings.encode())

    def record(self, indices, numbers: dict) -> None:
        """Journal one block: its sample indices and their numbers
        (`brdfjax.cluster.fit_cube_chunk`)."""
        if np.shape(numbers["params"]) != (len(indices), len(self.names)):
            raise ValueError(f"a block of {len(indices)} samples needs parameters of shape "
                             f"({len(indices)}, {len(self.names)}), not "
                             f"{np.shape(numbers['params'])}")
        block = {"index": np.asarray(indices, dtype=np.int64),
                 **{name: np.asarray(numbers[name], dtype=float)
                    for name in ("params", "error", "std")},
                 "status": np.asarray(numbers["status"], dtype=f"U{STATUS_WIDTH}"),
                 "message": np.asarray(numbers["message"], dtype=str)}
        first = int(np.min(indices))
        temporary = self.parts / f".{first:012d}.{secrets.token_hex(4)}.tmp"
        with open(temporary, "wb") as stream:
            np.savez(stream, **block)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(temporary, self.parts / f"{first:012d}.npz")

    def assemble(self, source, sample_names=None, uncertainty: bool = False) -> dict:
        """Write the results file from the journal (through a temporary file), remove the
        journal, and return the count of samples by status."""
        h5py = _h5py()
        if not self.parts.exists():  # already assembled
            with h5py.File(self.out, "r") as results:
                status = np.asarray(results["status"][...]).astype(str)
            return {s: int(np.sum(status == s)) for s in STATUSES}
        params = np.full((self.count, len(self.names)), np.nan)
        std = np.full_like(params, np.nan)
        error = np.full(self.count, np.nan)
        status = np.full(self.count, "", dtype=f"U{STATUS_WIDTH}")
        message = np.full(self.count, "", dtype=object)
        for part in sorted(self.parts.glob("*.npz")):
            with np.load(part) as block:
                index = block["index"]
                params[index], std[index] = block["params"], block["std"]
                error[index], status[index] = block["error"], block["status"]
                message[index] = block["message"].astype(object)
        temporary = self.out.with_name(f".{self.out.name}.{secrets.token_hex(4)}.tmp")
        try:
            with h5py.File(temporary, "w") as results:
                for column, name in enumerate(self.names):
                    results.create_dataset(name, data=params[:, column])
                    if uncertainty:
                        results.create_dataset(f"std_{name}", data=std[:, column])
                results.create_dataset("error", data=error)
                results.create_dataset("status", data=status.astype(f"S{STATUS_WIDTH}"))
                results.create_dataset("message", data=list(message),
                                       dtype=h5py.string_dtype())
                if sample_names is not None:
                    results.create_dataset("sample", data=list(sample_names),
                                           dtype=h5py.string_dtype())
                results["error"].attrs["meaning"] = "E of Eq. (6), a fraction"
                results.attrs["model"] = json.loads(self.settings)["model"]
                results.attrs["source"] = str(source)
                results.attrs["options"] = self.settings
            os.replace(temporary, self.out)
        finally:
            if temporary.exists():
                temporary.unlink()
        for part in self.parts.iterdir():
            part.unlink()
        self.parts.rmdir()
        return {s: int(np.sum(status == s)) for s in STATUSES}


def _write_whole(path: Path, payload: bytes) -> None:
    temporary = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp")
    temporary.write_bytes(payload)
    os.replace(temporary, path)
