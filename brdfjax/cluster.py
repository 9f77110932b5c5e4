"""Batch fits beyond one machine: chunks of samples sent to a Dask distributed cluster.

Dask (``pip install 'brdfjax[batch]'``) does the scheduling; brdfjax only cuts the
catalogue into chunks and hands each to `fit_chunk` on a worker. A worker runs
`brdfjax.fitting.batch.fit_batch` on its chunk (compiling once per chunk shape, then reusing the
compiled fit for every later chunk) and sends back plain data (dictionaries, or a cube
block's NumPy arrays: `fit_cube_chunk`), so a worker needs
brdfjax installed but not the data files: the client reads them and ships the arrays.
`fit_chunk` is also what the local path of ``brdfjax batch`` calls, so a cluster run and a
local run compute the same thing.

To use a real cluster, start a scheduler on one machine and workers on the others (each
with brdfjax installed, one worker process per core, one thread each: a worker's JAX runs
single-threaded, as a local batch's devices do, `brdfjax.fitting.batch.single_threaded`)::

    dask-scheduler                                  # prints tcp://HOST:8786
    dask-worker tcp://HOST:8786 --nworkers 4 --nthreads 1   # on a 4-core machine
    brdfjax batch data/*.xls --out results.csv --scheduler tcp://HOST:8786

Dask is imported only here, and only when a cluster is used.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator

from brdfjax.optional import require

IN_FLIGHT_PER_WORKER = 2  # chunks queued per worker: one running, one ready to start


def fit_chunk(samples: list, options: dict) -> list[dict]:
    """Fit one chunk of samples wherever this runs, returning JSON-ready results.

    Args:
        samples: `brdfjax.data.measurements.Measurements`, one per sample.
        options: keyword arguments of `brdfjax.fitting.batch.fit_batch`, except that bounds come
            as ``ranges``, a ``{name: (low, high)}`` dict for `brdfjax.models.bounds.make_bounds`
            (plain data travel to workers; JAX arrays need not). ``uncertainty``:
            ``"laplace"`` adds `brdfjax.uncertainty.laplace.laplace_approximation` to each result.

    Returns:
        One `brdfjax.fitting.fit.FitResult.to_dict` per sample, in order; with ``uncertainty``, a
        ``"std"`` entry of standard deviations by parameter name and the approximation's
        ``"uncertainty_status"``.
    """
    from brdfjax.fitting.batch import fit_batch, single_threaded

    single_threaded()  # on a worker, as the local batch runs
    uncertainty, bounds, options = _batch_options(options)
    results = fit_batch(samples, bounds=bounds, **options)
    summaries = [result.to_dict() for result in results]
    if uncertainty == "laplace":
        _add_laplace(samples, results, summaries, bounds)
    return summaries


def fit_cube_chunk(samples: list, options: dict) -> dict:
    """`fit_chunk` for a block of a cube: the numbers its results file holds
    (`brdfjax.data.formats.cube.CubeResults.record`), as arrays: ``params`` and ``std``
    (n, P), ``error``, ``status`` and ``message`` (n,). Without ``uncertainty`` they come
    from `brdfjax.fitting.batch.fit_batch`'s table, formed for the whole block at once."""
    import numpy as np

    from brdfjax.fitting.batch import fit_batch, single_threaded
    from brdfjax.models import get

    single_threaded()  # on a worker, as the local batch runs
    if options.get("uncertainty") is None:
        _, bounds, plain = _batch_options(options)
        table = fit_batch(samples, bounds=bounds, table=True, **plain)
        return {**table._asdict(), "std": np.full_like(table.params, np.nan)}
    summaries = fit_chunk(samples, options)
    names = get(options.get("model")).names
    return {"params": np.array([[s["params"][n] for n in names] for s in summaries], float),
            "std": np.array([[s.get("std", {}).get(n, np.nan) for n in names]
                             for s in summaries], float),
            "error": np.array([s["error"] for s in summaries], float),
            "status": np.array([s["status"] for s in summaries]),
            "message": np.array([s["message"] for s in summaries], dtype=object)}


def _batch_options(options: dict) -> tuple:
    """A chunk's ``options`` (`fit_chunk`) as ``(uncertainty, bounds, the keyword arguments
    of fit_batch)``: the box made from ``ranges``."""
    from brdfjax.models.bounds import make_bounds

    options = dict(options)
    uncertainty = options.pop("uncertainty", None)
    return uncertainty, make_bounds(options.pop("ranges", {}), model=options.get("model")), options


def _add_laplace(samples, results, summaries, bounds) -> None:
    """Put the Laplace standard deviations and status into each fitted sample's summary."""
    import warnings

    from brdfjax.uncertainty.laplace import laplace_approximation

    for data, result, summary in zip(samples, results, summaries):
        if result.status == "failed":
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # its reasons are kept in the status
            approximation = laplace_approximation(data, result, bounds=bounds)
        summary["std"] = dict(zip(result.model.names, map(float, approximation.std)))
        summary["uncertainty_status"] = approximation.status


def require_dask() -> None:
    """Raise `brdfjax.optional.MissingDependency` when dask.distributed is missing (the
    machine running ``brdfjax batch`` needs it as well as the workers)."""
    require("dask.distributed", "batch", "--scheduler")


def fit_on_cluster(chunks: Iterable[list], scheduler: str, options: dict,
                   task=fit_chunk) -> Iterator[tuple[int, list[dict] | dict | BaseException]]:
    """Send every chunk to a Dask cluster; yield each chunk's results as soon as it is done.

    Args:
        chunks: lists of `~brdfjax.data.measurements.Measurements`; each becomes one task.
        scheduler: the scheduler's address, e.g. ``tcp://10.0.0.5:8786``.
        options: as for `fit_chunk`.
        task: what each chunk runs: `fit_chunk`, or `fit_cube_chunk` for a cube's blocks.

    Yields:
        ``(chunk number, results)`` in order of completion; ``results`` is the exception
        instead when the chunk failed on the cluster (a worker died, ...).

    Raises:
        brdfjax.optional.MissingDependency: dask.distributed is not installed.
        OSError: the scheduler cannot be reached.
    """
    require_dask()
    from dask.distributed import Client, as_completed

    from brdfjax.cache import enable

    with Client(scheduler, timeout="30s") as client:
        # Workers keep compiled fits on disk, so a restarted worker skips XLA compilation.
        client.run(enable)
        # At most a few chunks per worker in flight: the rest are read (and shipped) only
        # as earlier ones finish, so a cube of millions of samples never sits in memory.
        in_flight = IN_FLIGHT_PER_WORKER * max(1, len(client.scheduler_info()["workers"]))
        chunks = enumerate(chunks)
        numbers, running = {}, as_completed()

        def submit() -> bool:
            number, chunk = next(chunks, (None, None))
            if chunk is None:
                return False
            future = client.submit(task, chunk, options, pure=False)
            numbers[future] = number
            running.add(future)
            return True

        while len(numbers) < in_flight and submit():
            pass
        for future in running:
            number = numbers.pop(future)
            try:
                result = future.result()
            # Whatever a worker raised (or KilledWorker), the chunk, not the run, has failed.
            except Exception as error:  # noqa: BLE001
                result = error
            future.release()
            submit()
            yield number, result
