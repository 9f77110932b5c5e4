"""The ``batch`` command: refit a whole catalogue, resumably, here or on a Dask cluster.

Results go to one CSV row per input file (``file``, one column per parameter of the model,
``error, status, message, model, at_bound, poor_incidences``; E as a fraction; the last two
flag what `fit` warns of: parameters at a bound, and incidences whose E exceeds 3x the
overall E). After every chunk the whole CSV is rewritten through a
temporary file and moved into place, so it always holds every finished sample and never a
half-written row. Rerunning the same command skips the files already fitted in it and
tries the failed ones again (a file may have been fixed): an interrupted batch (Ctrl-C, a
crash, a killed job) resumes where it stopped, and the final file is the same as an
uninterrupted run's, rows in input order. Delete a row (or the file) to refit it. The
options that change results (model, seed, bounds, search settings, uncertainty, reader
options) are kept beside the CSV in ``OUT.options.json``; a rerun with other options
refuses, naming what changed, instead of keeping rows fitted otherwise.
"""

from __future__ import annotations

import csv
import glob
import io
import json
import math
import os
import sys
from pathlib import Path

from brdfjax.commands import (
    add_reader_options,
    at_least,
    check_writable,
    positive_int,
    reader_options,
)
from brdfjax.data.formats import READABLE
from brdfjax.data.formats.cube import SUFFIXES as CUBE_SUFFIXES
from brdfjax.data.formats.cube import is_cube

AUTO_SAMPLES = 8  # --model auto chooses on at most this many samples
# --chunk-size by default. A cube's samples are small and come from one file: larger chunks
# spread each chunk's fixed cost (dispatch, reading, one journal file; about 25 ms) over
# more samples (10,000 Ross-Li pixels: 157 chunks of 64 cost more than their fits).
FILE_CHUNK = 64
CUBE_CHUNK = 1024
SEARCH_OPTIONS = {"population_size": "genetic-search population",
                  "max_generations": "genetic-search generations",
                  "starts": "GA members Levenberg-Marquardt starts from, per sample "
                            "(plus the model's own: the five-parameter model's Fresnel-free "
                            "start)",
                  "max_steps": "Levenberg-Marquardt step cap per start"}


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "batch", help="fit many files at once; resumable; local or on a Dask cluster",
        description="Fit every input with the hybrid fit (as `brdfjax fit`), one compiled "
                    "fit per chunk of files, and write one CSV row per file. Rerun the "
                    "same command to resume an interrupted batch.")
    p.add_argument("inputs", nargs="+", metavar="INPUT",
                   help=f"files, directories (every {'/'.join(READABLE)} inside except "
                        "RT-300S blank_*.xls) or glob patterns such as 'runs/*.xls'; or "
                        "one HDF5 cube of many samples (.h5, .hdf5, .nc: datasets theta_i, "
                        "theta_r, phi_r in degrees, brdf (N, P) with NaN missing, optional "
                        "sigma and sample; see brdfjax.data.formats.cube)")
    p.add_argument("--out", required=True, metavar="CSV|H5",
                   help="results file (CSV; for a cube, .h5); samples already fitted in it "
                        "are not refitted, failed ones are tried again (files), and a "
                        "rerun with other options refuses")
    p.add_argument("--json", metavar="DIR", help="also write each result as DIR/NAME.json")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="send chunks to this Dask scheduler (tcp://HOST:8786) "
                        "instead of fitting here")
    p.add_argument("--chunk-size", type=positive_int, metavar="N",
                   help=f"samples per compiled fit and per write (default {FILE_CHUNK} "
                        f"files, or {CUBE_CHUNK} samples of a cube)")
    p.add_argument("--lanes", choices=("auto", "map", "vmap"), default="auto",
                   help="map: each device fits a chunk's samples one after another; vmap: "
                        "side by side, slow ones finished in a second batch; auto (default): "
                        "map on a CPU, vmap on a GPU or TPU")
    p.add_argument("--uncertainty", choices=("laplace",),
                   help="add Laplace standard deviations (std_kb, ...) to every row")
    p.add_argument("--seed", type=int, default=0, help="the seed of every fit (default 0)")
    p.add_argument("--model", default="five", metavar="NAME",
                   help="the model to fit: five (default), torrance-sparrow, ggx, beckmann, "
                        "lambert, rpv, backscatter, abg, ross-li, or a sum such as "
                        "ggx+backscatter; auto: the model brdfjax models recommends most often "
                        f"over the first {AUTO_SAMPLES} samples, for every sample")
    p.add_argument("--bound", action="append", default=[], metavar="NAME=LO:HI",
                   help="override a parameter's search range, e.g. b=-80:10")
    for name, text in SEARCH_OPTIONS.items():  # no LM steps (0) leaves the search's result
        p.add_argument(f"--{name.replace('_', '-')}", metavar="N",
                       type=at_least(0) if name == "max_steps" else positive_int,
                       help=f"{text} (default: as brdfjax fit)")
    add_reader_options(p, spectral=True)
    p.add_argument("--plot", metavar="OUT",
                   help="with --wavelength all or a list: each parameter against wavelength, "
                        "with Laplace standard errors when --uncertainty laplace (PNG)")
    p.set_defaults(run=run_batch)


def expand(inputs, outputs=()) -> list[str]:
    """The files named by files, directories and glob patterns, in order, once each.

    A directory or pattern never yields the batch's own outputs: the files and folders in
    ``outputs`` (the results CSV, the JSON folder) and anything inside them, hidden files
    (the temporaries of an atomic write cut short) and results CSVs of other batches (their
    header is ``file,kb,...``). Naming an output itself as an input is an error.
    """
    outputs = [Path(p).resolve() for p in outputs if p is not None]
    files = []
    for item in inputs:
        if Path(item).is_dir():
            found = sorted(str(p) for p in Path(item).iterdir() if _is_sample(p, outputs))
        elif Path(item).is_file():
            if _is_output(Path(item), outputs):
                raise ValueError(f"{item}: is this batch's output, not an input")
            found = [item]
        elif glob.has_magic(item):
            found = sorted(p for p in glob.glob(item) if _is_sample(Path(p), outputs))
        else:
            raise ValueError(f"{item}: no such file, directory or matching pattern")
        if not found:
            raise ValueError(f"{item}: no {'/'.join(READABLE)} files there")
        files += [os.path.normpath(p) for p in found]
    return list(dict.fromkeys(files))


def _is_sample(path: Path, outputs=()) -> bool:
    """A measurement file, not an RT-300S blank (which is subtracted, not fitted), and none
    of the batch's outputs."""
    return (path.is_file() and path.suffix.lower() in READABLE
            and not (path.suffix.lower() == ".xls" and path.name.startswith("blank_"))
            and not path.name.startswith(".") and not _is_output(path, outputs)
            and not _is_results(path))


def _is_output(path: Path, outputs) -> bool:
    resolved = path.resolve()
    return any(resolved == out or out in resolved.parents for out in outputs)


def _is_results(path: Path) -> bool:
    """A results CSV written by ``brdfjax batch`` (judged by its header)."""
    if path.suffix.lower() != ".csv":
        return False
    try:
        with open(path, encoding="utf-8", errors="replace") as handle:
            header = handle.readline().rstrip("\r\n")
        return header.startswith("file,") and ",error,status,message,model" in header
    except OSError:  # unreadable: the fit reports it
        return False


def read_results(path, columns, settings: dict) -> dict:
    """The rows of an earlier run by file, or nothing if ``path`` does not exist yet; an
    error if they were fitted with other ``settings`` (`check_options`, which names the
    options that changed) or have other columns."""
    if not Path(path).exists():
        return {}
    with open(path, newline="", encoding="utf-8") as handle:
        reader = csv.DictReader(handle)
        records = list(reader)
    ours = options_path(path).exists()  # a results file of brdfjax's, not another CSV
    other_columns = (f"{path}: exists but its columns are not {','.join(columns)}; give "
                     "another --out" if tuple(reader.fieldnames or ()) != columns else None)
    if other_columns and not ours:
        raise ValueError(other_columns)
    rows = {sample_key(row["file"], row.get("wavelength_nm")): row for row in records}
    check_options(path, rows, settings)  # names the options that changed, if any did
    if other_columns:
        raise ValueError(f"{other_columns} (or the same options as the run that wrote it)")
    return rows


def result_options(args, model) -> dict:
    """Every option that changes a batch's numbers, as plain data: what a resume must match.

    The search settings are resolved to the values the fit uses (an option given equal to
    its default is the same run as one left out), and the bounds to the whole box of the
    model (so ``--bound b=-150:80`` equals the default box it spells out). ``--chunk-size``,
    ``--scheduler`` and ``--lanes`` are left out: they change where and how samples are
    grouped and run, not the fit asked for (`brdfjax.fitting.batch.fit_batch`). Like
    another machine or JAX version, ``--lanes`` changes the order of the arithmetic: fits
    agree to 1e-9 in E where measured, and a search that branches on the last bits can,
    rarely, end in another basin.
    """
    from brdfjax.commands.fitting import parse_bounds
    from brdfjax.fitting.batch import FIT_DEFAULTS
    from brdfjax.models.bounds import make_bounds

    box = make_bounds(parse_bounds(args.bound), model=model)
    return {"model": model.name, "seed": args.seed,
            "bounds": {name: [float(low), float(high)]
                       for name, low, high in zip(model.names, box.lower, box.upper)},
            **{name: (getattr(args, name) if getattr(args, name) is not None
                      else FIT_DEFAULTS[name]) for name in SEARCH_OPTIONS},
            "uncertainty": args.uncertainty,
            "reader": {k: (str(v) if k == "blank" else v)
                       for k, v in reader_options(args).items()},
            "wavelength": args.wavelength}


def fit_options(args, model) -> dict:
    """The keyword arguments of `brdfjax.cluster.fit_chunk` for every chunk."""
    from brdfjax.commands.fitting import parse_bounds

    return {"seed": args.seed, "ranges": parse_bounds(args.bound), "model": model.name,
            "chunk_size": args.chunk_size, "uncertainty": args.uncertainty,
            "lanes": args.lanes,
            **{k: getattr(args, k) for k in SEARCH_OPTIONS if getattr(args, k) is not None}}


def options_path(out) -> Path:
    """Where the options of the run that wrote ``out`` are kept: ``OUT.options.json``."""
    return Path(f"{out}.options.json")


def check_options(out, rows: dict, settings: dict) -> None:
    """Refuse to resume ``out`` when its rows were fitted with other options.

    Rows fitted with another seed, box, model or search would otherwise be kept as if they
    were this run's (a rerun with ``--seed 5 --bound b=-10:10`` once kept rows with b =
    32.9). With no rows there is nothing to protect and the run starts afresh.
    """
    import json

    if not rows:
        return
    path = options_path(out)
    try:
        stored = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        raise ValueError(f"{out}: has {len(rows)} rows but no readable record of the options "
                         f"that fitted them ({path}); give another --out, or delete {out} "
                         "to refit every input") from None
    changed = []
    for name, value in settings.items():
        before = stored.get(name)
        if isinstance(value, dict) and isinstance(before, dict):  # say which entries
            changed += [f"{name} {key}: {_shown(before.get(key))} there, "
                        f"{_shown(value.get(key))} here"
                        for key in dict.fromkeys([*before, *value])
                        if before.get(key) != value.get(key)]
        elif before != value:
            changed.append(f"{name}: {_shown(before)} there, {_shown(value)} here")
    if changed:
        raise ValueError(f"{out}: its {len(rows)} rows were fitted with other options "
                         f"({'; '.join(changed)}); give another --out, or delete {out} "
                         "to refit every input with these")


def _shown(value) -> str:
    if isinstance(value, list):
        return ":".join(f"{v:g}" if isinstance(v, float) else str(v) for v in value)
    return "none" if value is None else str(value)


def write_options(out, settings: dict) -> None:
    """Keep ``settings`` beside ``out`` (`options_path`), for `check_options` on a rerun."""
    import json

    from brdfjax.data.formats import write_atomically

    write_atomically(options_path(out), json.dumps(settings, indent=1) + "\n")


def write_results(path, rows: dict, order, columns) -> None:
    """Rewrite the results CSV atomically: rows in input order, then any others."""
    from brdfjax.data.formats import write_atomically

    text = io.StringIO()
    writer = csv.DictWriter(text, columns, lineterminator="\n")
    writer.writeheader()
    ranked = {file: rank for rank, file in enumerate(order)}
    for file in sorted(rows, key=lambda f: ranked.get(f, len(ranked))):
        writer.writerow(rows[file])
    write_atomically(path, text.getvalue())


def columns_of(names, uncertainty: bool, spectral: bool = False) -> tuple:
    """The CSV columns for a model's parameter ``names``, with or without uncertainty, and
    with a ``wavelength_nm`` column when every wavelength is its own sample."""
    columns = ("file", *(("wavelength_nm",) if spectral else ()), *names, "error", "status",
               "message", "model", "at_bound", "poor_incidences")
    if uncertainty:
        columns += (*(f"std_{name}" for name in names), "uncertainty_status")
    return columns


def sample_key(file: str, wavelength_nm=None) -> str:
    """How a sample is known in a batch: its file, or ``FILE@WAVELENGTHnm``."""
    return file if wavelength_nm in (None, "") else f"{file}@{float(wavelength_nm):g}nm"


def split_key(key: str) -> tuple[str, float | None]:
    """The file and wavelength (or None) of a `sample_key`."""
    file, at, wavelength = key.rpartition("@")
    if at and wavelength.endswith("nm"):
        try:
            return file, float(wavelength[:-2])
        except ValueError:
            pass
    return key, None


def row(key: str, result: dict, columns, model: str) -> dict:
    """A CSV row from a `brdfjax.fitting.fit.FitResult.to_dict` (numbers as exact reprs).

    ``at_bound`` names the parameters at a bound of the box and ``poor_incidences`` the
    incidences (deg) whose E exceeds 3x the overall E, space-separated: what `fit` flags.
    """
    from brdfjax.commands.fitting import poor_incidences

    file, wavelength = split_key(key)
    errors = {float(k): v for k, v in result.get("error_by_incidence", {}).items()}
    poor = poor_incidences(errors, result["error"]) if math.isfinite(result["error"]) else []
    values = {"file": file, **{k: repr(float(v)) for k, v in result["params"].items()},
              "error": repr(float(result["error"])), "status": result["status"],
              "message": result["message"], "model": model,
              "at_bound": " ".join(result.get("at_bounds", ())),
              "poor_incidences": " ".join(f"{deg:g}" for deg in poor)}
    if "wavelength_nm" in columns:
        values["wavelength_nm"] = "" if wavelength is None else f"{wavelength:g}"
    if "uncertainty_status" in columns:
        std = result.get("std", {})
        values.update({f"std_{k}": repr(float(std.get(k, float("nan"))))
                       for k in result["params"]})
        values["uncertainty_status"] = result.get("uncertainty_status", "")
    return values


def run_batch(args) -> int:
    from tqdm import tqdm

    from brdfjax.models import get

    check_writable({"--out": args.out}, {"--json": args.json})
    cube = any(is_cube(item) for item in args.inputs)
    if args.chunk_size is None:
        args.chunk_size = CUBE_CHUNK if cube else FILE_CHUNK
    if args.model != "auto":
        get(args.model)  # an unknown name fails before any file is read
    if args.scheduler is not None:
        from brdfjax.cluster import require_dask

        require_dask()  # before any file is read
    if cube:
        return run_cube(args)
    spectral = spectral_request(args.wavelength)
    files = expand(args.inputs, outputs=(args.out, args.json))
    if spectral is not None:
        check_writable(figures={"--plot": args.plot})
        files = spectral_samples(files, spectral)
    elif args.plot:
        raise ValueError("--plot draws parameters against wavelength: give --wavelength all "
                         "or a list of wavelengths")
    # One device per core must be made before any fit (--model auto's) starts JAX.
    devices = _local_devices() if args.scheduler is None else None
    model = get(choose_model(files, args) if args.model == "auto" else args.model)
    columns = columns_of(model.names, bool(args.uncertainty), spectral is not None)
    names = [json_name(f) for f in files]
    if args.json and len(set(names)) < len(names):
        clash = next(n for n in names if names.count(n) > 1)
        raise ValueError(f"--json: two inputs are named {clash!r}; give them separate runs")
    settings = result_options(args, model)
    rows = read_results(args.out, columns, settings)
    # A failed input is tried again: the file may have been fixed since. A spectral file
    # that could not be read had one row; read now, its wavelengths replace that row.
    spread = {split_key(f)[0] for f in files if split_key(f)[1] is not None}
    failed = [f for f in rows if rows[f]["status"] == "failed" and (f in files or f in spread)]
    for key in failed:
        if key not in files:
            del rows[key]
    pending = [f for f in files if f not in rows or f in failed]
    options = fit_options(args, model)
    if args.json:
        Path(args.json).mkdir(parents=True, exist_ok=True)
    if rows or failed:
        print(f"{args.out}: {len(files) - len(pending)} of {len(files)} inputs already done; "
              + (f"fitting the other {len(pending)}" if pending else "nothing left to fit")
              + (f" ({len(failed)} that failed before, tried again)" if failed else ""),
              file=sys.stderr)
    if not pending:
        return _summary(rows, files, [], model, args.out)
    if devices:  # said before the bar opens, so it is not drawn through it
        print(f"fitting on {len(devices)} {devices[0].platform} device(s)", file=sys.stderr)

    progress = tqdm(total=len(pending), unit="file", desc="brdfjax batch", file=sys.stderr)
    unread = {}

    def record(keys, results) -> None:
        """Save a chunk's results and the unreadable files met so far.

        The JSON files are written before the CSV, so a file listed there has its JSON.
        """
        batch = {**unread, **dict(zip(keys, results))}
        unread.clear()
        if not batch:
            return
        if args.json:
            _write_json(args.json, batch)
        rows.update({file: row(file, result, columns, model.name)
                     for file, result in batch.items()})
        # With the first rows, not before the first fit: a run that fails before any row
        # (an option the fit refuses) leaves nothing behind.
        write_options(args.out, settings)
        write_results(args.out, rows, files, columns)
        if progress.n + len(batch) < progress.total:
            progress.update(len(batch))
        else:  # the last step is drawn once, by close(), not also by update()
            progress.n = progress.total

    chunks = _chunks(pending, args, unread, model.names)
    try:
        lost = _fit_chunks(chunks, args.scheduler, options, record)
        record([], [])  # the last unreadable files, if no chunk came after them
    finally:
        progress.close()
    if args.plot:
        _plot_spectral(args.plot, [rows[key] for key in files if key in rows], model)
        print(f"wrote {args.plot}", file=sys.stderr)
    return _summary(rows, files, lost, model, args.out)


def run_cube(args) -> int:
    """``brdfjax batch CUBE.h5 --out RESULTS.h5``: every sample of one HDF5 cube
    (`brdfjax.data.formats.cube`), streamed a chunk at a time, journalled, resumable."""
    import numpy as np
    from tqdm import tqdm

    from brdfjax.data.formats.cube import Cube, CubeResults
    from brdfjax.models import get

    if len(args.inputs) != 1:
        raise ValueError(f"{' '.join(args.inputs)}: give one cube (.h5) per run, alone")
    if Path(args.out).suffix.lower() not in CUBE_SUFFIXES[:2]:
        raise ValueError(f"--out {args.out}: the results of a cube go to an HDF5 file; "
                         "give --out RESULTS.h5")
    given = [f"--{name}" for name in ("json", "plot", "wavelength") if getattr(args, name)]
    if given:
        raise ValueError(f"{', '.join(given)}: not for a cube; its results file holds "
                         "every sample")
    if Path(args.inputs[0]).resolve() == Path(args.out).resolve():
        raise ValueError(f"--out {args.out}: is the cube itself; give another file")
    with Cube(args.inputs[0]) as cube:
        devices = _local_devices() if args.scheduler is None else None
        if args.model == "auto":
            first = list(range(min(cube.count, AUTO_SAMPLES)))
            samples = dict(zip(first, cube.read(first)))
            chosen = choose_model(first, args, read=samples.__getitem__)
        model = get(chosen if args.model == "auto" else args.model)
        # The cube's path and size too: results are by sample index, so another cube (or
        # the same grown) must not take over this one's rows.
        settings = {**result_options(args, model), "cube": str(cube.path.resolve()),
                    "samples": cube.count}
        results = CubeResults(args.out, cube.count, model.names, settings)
        stored = results.stored_settings()
        if stored is not None and json.loads(stored) != json.loads(results.settings):
            old = json.loads(stored)
            changed = [f"{k}: {_shown(old.get(k))} there, {_shown(v)} here"
                       for k, v in settings.items() if old.get(k) != v]
            raise ValueError(f"{args.out}: was fitted with other options "
                             f"({'; '.join(changed)}); give another --out, or delete it "
                             f"(and {results.parts}) to refit")
        done = results.done()
        pending = np.flatnonzero(~done)
        if done.any():
            print(f"{args.out}: {int(done.sum())} of {cube.count} samples already done; "
                  + (f"fitting the other {pending.size}" if pending.size
                     else "nothing left to fit"), file=sys.stderr)
        results.start()
        options = fit_options(args, model)
        blocks = [pending[i:i + args.chunk_size]
                  for i in range(0, pending.size, args.chunk_size)]
        if devices and blocks:
            print(f"fitting {cube.count} samples of {cube.points} points on {len(devices)} "
                  f"{devices[0].platform} device(s)", file=sys.stderr)
        lost = []
        with tqdm(total=int(pending.size), unit="sample", desc="brdfjax batch",
                  file=sys.stderr, disable=not blocks) as progress:
            chunks = ([(int(i), data) for i, data in zip(block, cube.read(block))]
                      for block in blocks)

            def record(indices, numbers: dict) -> None:
                results.record(indices, numbers)
                progress.update(len(indices))

            lost = _fit_chunks(chunks, args.scheduler, options, record, cube=True)
        counts = results.assemble(cube.path, cube.names, uncertainty=bool(args.uncertainty)) \
            if not lost else None
    if lost:
        raise ValueError(f"{len(lost)} chunk(s) failed on the cluster and were not recorded "
                         f"(rerun to fit them): {'; '.join(lost)}")
    print(f"{counts['converged'] + counts['max_steps']} of {cube.count} fitted"
          + (f" ({counts['max_steps']} stopped at the LM step cap)" if counts["max_steps"]
             else "") + underdetermined_text(counts["underdetermined"], model, args.out)
          + (f"; {counts['failed']} failed (see message in {args.out})"
             if counts["failed"] else ""), file=sys.stderr)
    return 1 if counts["failed"] else 0


def underdetermined_text(count: int, model, out) -> str:
    """The summary's words on ``count`` underdetermined samples ("" for none)."""
    if not count:
        return ""
    return (f"; {count} underdetermined (no more distinct geometries than the "
            f"{model.size} parameters of {model.name}: their parameters are not determined; "
            f"status and message in {out})")


def spectral_request(text):
    """``--wavelength`` of batch: None (one sample per file), ``"all"`` or a list of nm.

    A single number keeps the old meaning (read that wavelength, one sample per file).
    """
    if text is None:
        return None
    if text.strip().lower() == "all":
        return "all"
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        raise ValueError(f"--wavelength {text!r}: give all, a wavelength in nm, or a list "
                         "such as 532,633") from None
    return values if len(values) > 1 else None


def spectral_samples(files, request) -> list[str]:
    """One `sample_key` per wavelength of every file (a file that cannot be read stays one
    key, and fails when it is loaded)."""
    from brdfjax.data.formats import load_spectral
    from brdfjax.data.measurements import DataError

    keys = []
    for file in files:
        try:
            found = load_spectral(file, None if request == "all" else request)
        except (DataError, ValueError, OSError):
            keys.append(file)
            continue
        keys += [sample_key(file, wavelength) for wavelength in found]
    return keys


def json_name(key: str) -> str:
    """The --json file name of a sample: its file's stem, with its wavelength if any."""
    file, wavelength = split_key(key)
    return Path(file).stem + ("" if wavelength is None else f"_{wavelength:g}nm")


def _plot_spectral(path, rows, model) -> None:
    from brdfjax.data.formats import replace_atomically
    from brdfjax.plot import plot_spectral

    names = model.names
    samples = sorted({Path(r["file"]).stem for r in rows})

    def number(text):
        return float(text) if text not in ("", None) else None

    records = [{"wavelength_nm": float(r["wavelength_nm"]),
                "params": {k: float(r[k]) for k in names},
                "std": {k: number(r.get(f"std_{k}")) for k in names}}
               for r in rows if r["status"] != "failed" and r["wavelength_nm"] != ""]
    if records:
        replace_atomically(path, lambda out: plot_spectral(
            records, out, names, sample=", ".join(samples[:3]), model=model.name))


def _local_devices() -> list:
    """The JAX devices of a local batch, one per core on a CPU; caches on."""
    from brdfjax.cache import enable
    from brdfjax.fitting.batch import use_every_core

    devices = use_every_core()
    enable()
    return devices


def _chunks(pending, args, unread: dict, names):
    """Read the pending files; yield ``(files, measurements)`` chunks of readable ones.

    A file that cannot be read goes into ``unread`` as a failed result with the reason.
    """
    from brdfjax.data.measurements import DataError

    chunk = []
    for key in pending:
        try:
            chunk.append((key, read_sample(key, args)))
        except (DataError, ValueError, OSError) as error:
            unread[key] = {"params": dict.fromkeys(names, float("nan")),
                            "error": float("nan"), "status": "failed", "message": str(error)}
        if len(chunk) == args.chunk_size:
            yield chunk
            chunk = []
    if chunk:
        yield chunk


def read_sample(key: str, args):
    """The measurements of one sample key: a file, or one wavelength of a spectral file."""
    from brdfjax.data.formats import load, load_spectral

    file, wavelength = split_key(key)
    if wavelength is None:
        return load(file, **reader_options(args))
    return load_spectral(file, [wavelength])[wavelength]


def choose_model(keys, args, read=None) -> str:
    """``--model auto`` of a batch: one model for every sample (one model keeps the CSV's
    columns, and the samples' parameters, comparable). It is the model ``brdfjax models``
    recommends (the one-standard-error rule, `Comparison.best`) more often than any other
    over the first `AUTO_SAMPLES` samples that can be compared; a tie goes to fewer
    parameters, then to the lower median cv_error. The lowest median cv_error alone, the
    rule before, could take a sum lower by less than the noise of the held-out points,
    which ``models`` does not recommend. Said on stderr, after a progress bar of the samples
    cross-validated (a few seconds each, the first with the models' compilation: half a
    minute with empty caches)."""
    import numpy as np
    from tqdm import tqdm

    from brdfjax.data.measurements import DataError
    from brdfjax.models import get
    from brdfjax.prediction.selection import compare_models, ranked

    errors, votes, used, reasons = {}, {}, 0, []
    with tqdm(total=min(AUTO_SAMPLES, len(keys)), unit="sample", file=sys.stderr,
              desc="--model auto: every model cross-validated on") as bar:
        for key in keys:
            try:
                data = read(key) if read is not None else read_sample(key, args)
                comparison = compare_models(data, seed=args.seed, discrepancy="none")
            except (DataError, ValueError, OSError) as error:
                reasons.append(f"{key}: {error}")
                bar.set_postfix_str(f"{len(reasons)} unreadable, skipped")
                continue
            for score in comparison.scores:
                errors.setdefault(score.name, []).append(score.cv_error)
            votes[comparison.best.name] = votes.get(comparison.best.name, 0) + 1
            used += 1
            bar.update()
            if used == AUTO_SAMPLES:
                break
    if not used:
        raise ValueError("--model auto: no sample could be cross-validated to choose a model "
                         f"({reasons[0] if reasons else 'no inputs'}); give --model NAME")
    median = {name: float(np.median(values)) for name, values in errors.items()}
    order = sorted(votes, key=lambda name: (-votes[name], get(name).size, median[name]))
    chosen, lowest = order[0], ranked(median)[0]  # within 0.1 %: a tie, fewer parameters
    print(f"--model auto: {chosen}, recommended by brdfjax models (the one-standard-error "
          f"rule) on {votes[chosen]} of {used} samples compared ({len(keys)} in all); "
          f"median cv_error {100 * median[chosen]:.3g} %"
          + (f", the lowest {lowest} ({100 * median[lowest]:.3g} %)" if lowest != chosen
             else ", the lowest")
          + (f"; next {order[1]} ({votes[order[1]]} of {used})" if len(order) > 1 else ""),
          file=sys.stderr)
    return chosen


def _fit_chunks(chunks, scheduler, options, record, cube: bool = False) -> list:
    """Fit every chunk of ``(key, measurements)`` pairs here or on the cluster, calling
    ``record(keys, results)`` for each as it finishes: results of `fit_chunk`, or for a
    ``cube`` of `fit_cube_chunk`.

    Returns:
        The errors of chunks the cluster could not fit (nothing is recorded for them, so
        a rerun fits them again).
    """
    from brdfjax.cluster import fit_chunk, fit_cube_chunk, fit_on_cluster

    task = fit_cube_chunk if cube else fit_chunk
    if scheduler is None:
        for chunk in chunks:
            keys, samples = zip(*chunk)
            record(list(keys), task(list(samples), options))
        return []
    sent, lost = [], []

    def remember(chunks):
        for chunk in chunks:
            sent.append([key for key, _ in chunk])
            yield [data for _, data in chunk]

    for number, results in fit_on_cluster(remember(chunks), scheduler, options, task):
        if isinstance(results, BaseException):
            lost.append(f"{len(sent[number])} samples from {sent[number][0]}: {results}")
        else:
            record(sent[number], results)
    return lost


def _write_json(directory, batch: dict) -> None:
    from brdfjax.data.formats import json_text, write_atomically

    for key, result in batch.items():
        file, wavelength = split_key(key)
        record = {"file": file, **({} if wavelength is None else {"wavelength_nm": wavelength})}
        write_atomically(Path(directory) / f"{json_name(key)}.json",
                         json_text({**record, **result}))


def _summary(rows: dict, files, lost, model, out) -> int:
    """Print what failed and why, and how many fits are underdetermined; 1 if anything
    failed, else 0."""
    done = [f for f in files if f in rows]
    failed = [(f, rows[f]["message"]) for f in done if rows[f]["status"] == "failed"]
    capped = sum(rows[f]["status"] == "max_steps" for f in done)
    short = sum(rows[f]["status"] == "underdetermined" for f in done)
    print(f"{len(done) - len(failed) - short} of {len(files)} fitted"
          + (f" ({capped} stopped at the LM step cap: see their message)" if capped else "")
          + underdetermined_text(short, model, out), file=sys.stderr)
    if failed:
        print(f"{len(failed)} failed:", file=sys.stderr)
        for file, message in failed:
            print(f"  {message if message.startswith(file) else f'{file}: {message}'}",
                  file=sys.stderr)
    if lost:
        raise ValueError(f"{len(lost)} chunk(s) failed on the cluster and were not recorded "
                         f"(rerun to fit them): {'; '.join(lost)}")
    return 1 if failed else 0
