"""Fitting many measurement sets at once: the hybrid fit of `brdfjax.fit` over a batch.

`fit_batch` runs, for every sample of a catalogue, exactly the fit that `brdfjax.fitting.fit.fit`
runs with the ``hybrid`` method (genetic search, then screened Levenberg-Marquardt from
distinct good members), but as one compiled call per chunk of samples:

1. Each sample is checked (`brdfjax.data.measurements.failures`: the checks of ``validate``,
   a chunk's samples of one length together); one that fails becomes a ``failed`` result
   carrying the reason and never reaches the compiled fit, so it cannot spoil the others.
   Inside the fit every sample is its own lane with its own status.
2. Samples with identical angle arrays share one precomputed geometry of the model (a
   chunk of many distinct geometries, per-pixel angles, computes them in one vmapped
   call: `_scenes`). Samples are ordered by geometry and cut into chunks of at most
   ``chunk_size``; a chunk whose samples all share one geometry passes that scene once
   (``vmap`` with ``in_axes=None``), any other chunk passes one scene per sample.
3. Ragged data are padded, not looped over: point counts are padded to the next multiple of
   `brdfjax.fitting.objective.POINT_BUCKET` with zero-weight copies of the sample's first point
   (as a single fit pads them), then to the chunk's largest sample, and a chunk's
   sample count to a power of two (at most ``chunk_size``) and a multiple of the device
   count, with copies of its first sample whose results are dropped (``map`` lanes with
   ``search_batch`` and ``polish_batch`` 1, the defaults, skip them: they cost nothing
   there). Compilations are so
   bounded to one per (sample bucket, point bucket, shared geometry or not) and device
   (XLA compiles for each device it runs on, all devices at once; a chunk uses one device
   per `SAMPLES_PER_DEVICE` samples at most, so a small chunk compiles once, and a linear
   model's chunk one device).
4. Every sample is keyed by ``jax.random.key(seed)`` as `brdfjax.fitting.fit.fit` keys it, so a
   batched fit follows the same search as the single fit of the same sample and ends at the
   same E (to 1e-9 relative, tested): both pad points to the same bucket, so they run the
   same arithmetic, except for a sample padded further to a larger sample of its chunk.
5. Lanes: how a chunk's samples share a device (``lanes``, chosen by backend).
   - ``map`` (the default on a CPU): each step runs its samples ``search_batch`` (genetic
     search) or ``polish_batch`` (Levenberg-Marquardt) at a time side by side under
     ``vmap``, such groups one after another under ``lax.map`` (`across_samples`); ``None``
     vmaps the whole chunk. A vmapped loop runs as long as its slowest lane (an LM that
     needs 700 steps holds up every sample beside it; 64 starts: 613 ms vmapped, 242 ms
     looped), and on a CPU, where a lane costs as much as a sample, even the GA was slower
     vmapped over many samples than mapped; the defaults are the fastest measured on a
     2-core CPU (``BENCHMARKS.md``, section batch).
   - ``vmap`` (the default on an accelerator, where lanes run at once and each loop step
     is a kernel launch): every sample of the chunk side by side in both stages, and each
     sample's LM starts side by side too (`brdfjax.fitting.polish.polish`'s
     ``side_by_side``); a finished lane is masked (``vmap`` of a ``while_loop`` keeps its
     state) until the slowest is done. So that a few slow lanes do not hold all the others,
     LM's convergence round stops at `LANE_STEPS` steps (the longest start of a 64-point
     cube sample took a median of 47 LM steps, up to 20 of screening included, 100 at the
     90th percentile: ``BENCHMARKS.md``, section lanes-cpu), and the starts still
     running then continue in a second, small batch of their own from where they
     stopped, for the rest of ``max_steps`` (`_resume_slow`, on the first device: it is
     small). A start so resumed restarts LM's damping and reaches its minimum by a
     slightly different path. Converged fits ended at the ``map`` path's E to 1e-9 in the
     tests and to 7.8e-12 on 256 cube samples (``BENCHMARKS.md``, lanes-cpu), but not bit
     for bit: the vmapped genetic search computes in another order, and a search that
     branches on the last bits can end in another basin (once seen on another cube,
     3.5e-4 in E).
6. The sample axis is split over the local devices: each device gets a contiguous block
   of the chunk's samples, placed on it (``jax.device_put``) and fitted by the same
   compiled function, dispatched to all devices before waiting on any, so the devices run
   independently. (A sample axis sharded with ``NamedSharding`` under one ``jit`` was
   tried first: XLA then runs every loop in lock-step across devices, the search's and each
   LM's ``while_loop`` waiting for the slowest device at every step, and 2 devices were
   barely faster than 1.) On a CPU, `use_every_core` makes one single-threaded device per
   core.
"""

from __future__ import annotations

import hashlib
import inspect
import os
import time
import warnings
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from brdfjax.cache import stage
from brdfjax.data.measurements import Measurements, failures
from brdfjax.fitting.evolve import EvolveConfig, EvolveResult, evolve
from brdfjax.fitting.fit import (
    STATUSES,
    FitResult,
    UnderdeterminedWarning,
    check_bounds,
    distinct_geometries,
    fit,
    fit_result,
    polish_summary,
    search_summary,
    settled,
    solved_fit,
    status_message,
)
from brdfjax.fitting.objective import (
    NOTHING_TO_FIT,
    Problem,
    bucket,
    normalised,
    pad,
    padded_scene,
    prepare,
)
from brdfjax.fitting.polish import PolishResult, polish_population, resume
from brdfjax.models import Model, get
from brdfjax.models.bounds import Bounds, default_bounds, to_unit
from brdfjax.models.paper import evaluate_projected

# The single fit's own defaults, read from its signature: a batched fit is the fit that
# `brdfjax.fitting.fit.fit` gives each sample, whatever those defaults become.
FIT_DEFAULTS = {name: inspect.signature(fit).parameters[name].default
                for name in ("starts", "population_size", "max_generations", "max_steps",
                             "config", "constants")}
# Samples side by side in the genetic search and in the LM polish (`across_samples`): the
# fastest on a 2-core CPU among 1, 4, 16 and the whole chunk (BENCHMARKS.md, section batch).
SEARCH_BATCH = 1
POLISH_BATCH = 1
# LM convergence-round steps of the first batch on the ``vmap`` lanes; starts still running
# then continue in a second batch (`_resume_slow`).
LANE_STEPS = 64
LANES = ("auto", "map", "vmap")
# Samples per device below which a chunk uses fewer devices (`_run_chunk`): 8 warm fits of
# 120-716 points take 0.1-0.2 s on one CPU device, about what loading one compiled shape for
# a second device from the caches takes, while compiling it takes 10-30 s.
SAMPLES_PER_DEVICE = 8
# Distinct geometries in a chunk from which they are computed in one vmapped call
# (`_scenes`): per-pixel angles, not a cross-validation's folds (at most 24) or a few files.
VECTOR_GEOMETRIES = 64


def fit_batch(samples: Sequence[Measurements], *, model: str | Model | None = None,
              seed: int | Sequence[int] = 0, bounds: Bounds | None = None,
              chunk_size: int = 256,
              lanes: str = "auto",
              search_batch: int | None = SEARCH_BATCH, polish_batch: int | None = POLISH_BATCH,
              devices=None, table: bool = False,
              **options) -> list[FitResult] | BatchTable:
    """Fit a model to every sample of a batch, one compiled call per chunk.

    Each sample gets the fit that ``brdfjax.fit(sample, model=model, seed=seed)`` gives it (hybrid
    method, no held-out incidences) and its own status: ``converged``, ``max_steps``,
    ``underdetermined`` (no more distinct geometries than parameters: the rule of
    `brdfjax.fitting.fit.settled`, with one `UnderdeterminedWarning` whatever their number)
    or ``failed``, with `FitResult.message` saying why where there is more to say. Bad data
    (NaN, no measurements, ...) make that sample ``failed`` with the `DataError` text; the
    other samples are fitted as if it were not there.

    Args:
        samples: the measurement sets, any lengths and geometries.
        model: a name of `brdfjax.models.available` or a `brdfjax.models.Model` (the
            five-parameter model if None).
        seed: one seed for every sample, or one per sample.
        bounds: the search box (the model's `brdfjax.models.bounds.default_bounds` if None).
        chunk_size: at most this many samples per compiled call; bounds the memory,
            which grows with it where samples run side by side (``search_batch`` or
            ``polish_batch`` None or large).
        lanes: ``map`` (samples one after another, in groups of ``search_batch`` and
            ``polish_batch``), ``vmap`` (a chunk's samples and their LM starts side by
            side, slow starts resumed in a second batch), or ``auto``: ``map`` on a CPU,
            ``vmap`` on an accelerator (the module docstring, item 5).
        search_batch, polish_batch: with ``lanes`` ``map``, samples side by side under
            ``vmap`` in the genetic search and in the LM polish (`across_samples`); None
            for the whole chunk.
        devices: the devices to split each chunk over (default: ``jax.devices()``).
        table: return a `BatchTable` (every sample's parameters, E, status and message as
            arrays, formed for a whole chunk at once) instead of a `FitResult` per sample:
            the same numbers without the per-sample Python, which costs more than the fit
            of a small linear sample (Ross-Li pixels).
        **options: ``starts``, ``population_size``, ``max_generations``, ``max_steps``,
            ``config``, ``constants``: as in `brdfjax.fitting.fit.fit`, with its defaults
            (`FIT_DEFAULTS`).

    Returns:
        One `FitResult` per sample, in the order given (``timings["total"]`` is the
        sample's share of its chunk's wall time); or with ``table``, one `BatchTable`.
    """
    unknown = set(options) - set(FIT_DEFAULTS)
    if unknown:
        raise TypeError(f"fit_batch got unknown option(s) {sorted(unknown)}; "
                        f"it takes {sorted(FIT_DEFAULTS)}")
    options = {**FIT_DEFAULTS, **options}
    model = get(model, options.pop("constants"))
    config = options.pop("config")
    if np.ndim(seed) and np.size(seed) != len(samples):
        raise ValueError(f"{np.size(seed)} seeds for {len(samples)} samples: give one seed, "
                         "or one per sample")
    seeds = np.broadcast_to(np.asarray(seed, dtype=np.int64), (len(samples),))
    bounds = default_bounds(model) if bounds is None else bounds
    check_bounds(bounds, model)
    devices = list(devices or jax.devices())
    side_by_side = lane_choice(lanes, devices) == "vmap"
    settings = {**options, "search_batch": None if side_by_side else search_batch,
                "polish_batch": None if side_by_side else polish_batch,
                "side_by_side": side_by_side}
    resumed_steps = 0  # the convergence round's steps left to the slow lanes' second batch
    if side_by_side and options["max_steps"] > LANE_STEPS:
        settings["max_steps"], resumed_steps = LANE_STEPS, options["max_steps"] - LANE_STEPS
    chunks = _warned(_chunk_fits(samples, model, seeds, bounds, config, devices, chunk_size,
                                 settings, resumed_steps), model)
    if table:
        return _table(chunks, len(samples), model)
    results: list[FitResult | None] = [None] * len(samples)
    for chunk in chunks:
        for index, message in chunk.failed.items():
            results[index] = _failed(samples[index], message, bounds, model)
        searched, polished = _lanes(chunk.searched), _lanes(chunk.polished)
        for lane, index in enumerate(chunk.indices):
            results[index] = _sample_result(
                samples[index], searched[lane], polished[lane], chunk.params[lane],
                chunk.status[lane], chunk.evaluations[lane], chunk.fitted[lane],
                chunk.units[lane], options["population_size"],
                chunk.seconds / len(chunk.indices), chunk.messages[lane], bounds, model)
    return results


def _warned(chunks, model: Model):
    """The chunks of `_chunk_fits`, passed on; one `UnderdeterminedWarning` after them
    where any sample was ``underdetermined`` (one, not one per sample: a cube of 1e5
    samples would print thousands)."""
    count = 0
    for chunk in chunks:
        if chunk.status is not None:
            count += int(np.sum(chunk.status == "underdetermined"))
        yield chunk
    if count:
        warnings.warn(f"samples with no more distinct geometries (theta_i, theta_r, phi_r) "
                      f"than the {model.size} parameters of {model.name} are underdetermined: "
                      "their parameters are one of many sets that fit as well (their status "
                      "and message say so)", UnderdeterminedWarning, stacklevel=3)


class BatchTable(NamedTuple):
    """The numbers of a batch, one row per sample in the order given (``fit_batch(...,
    table=True)``): what `FitResult` reports as ``params``, ``error``, ``status`` and
    ``message``.

    Attributes:
        params: (N, P) fitted parameters (NaN where the data failed their checks).
        error: (N,) E of Eq. (6), a fraction.
        status: (N,) ``converged``, ``max_steps``, ``underdetermined`` or ``failed``.
        message: (N,) why the status, where there is more to say ("" elsewhere).
    """

    params: np.ndarray
    error: np.ndarray
    status: np.ndarray
    message: np.ndarray


class _ChunkFit(NamedTuple):
    """One chunk of `_chunk_fits`. The samples fitted (``indices``, in lane order), the
    samples that failed their checks (``failed``, index: the reason), the fitted ones'
    batched search and polish (host arrays, leading axis the samples), the polish's
    `polish_summary` (``params``, ``status``, ``evaluations``; ``params`` as reported,
    `brdfjax.models.Model.canonical`; ``status`` `settled`: ``underdetermined`` where a sample
    has too few geometries), the fitted projected BRDF and unit-cube coordinates
    (`_fitted`), the padded chunk (`_run_chunk`), its wall seconds and each fitted sample's
    `FitResult.message`."""

    indices: list
    failed: dict
    searched: EvolveResult | None = None
    polished: PolishResult | None = None
    params: np.ndarray | None = None
    status: np.ndarray | None = None
    evaluations: np.ndarray | None = None
    fitted: np.ndarray | None = None
    units: np.ndarray | None = None
    padded: Problem | None = None
    seconds: float = 0.0
    messages: list | None = None


def _chunk_fits(samples, model, seeds, bounds, config, devices, chunk_size, settings,
                resumed_steps):
    """Check, prepare and fit the samples a chunk at a time; yield a `_ChunkFit` each.

    A chunk's samples are checked and prepared together, as arrays (`failures`,
    `_chunk_targets`, `_scenes`): per-sample Python cost more than the fit of a small linear
    sample (a Ross-Li pixel)."""
    # Stable sort by geometry, so that samples sharing one land in the same chunks.
    keys = [_geometry_key(data) for data in samples]
    rank = {key: number for number, key in enumerate(dict.fromkeys(keys))}
    order = sorted(range(len(samples)), key=lambda i: rank[keys[i]])
    for begin in range(0, len(order), chunk_size):
        # Problems are prepared chunk by chunk, so host and device memory stay bounded.
        # Host arrays throughout: the chunk goes to the devices in one transfer.
        block = order[begin:begin + chunk_size]
        failed = {block[position]: message for position, message
                  in failures([samples[i] for i in block]).items()}
        checked = [i for i in block if i not in failed]
        points = max((bucket(len(samples[i])) for i in checked), default=0)
        targets, weights, usable = _chunk_targets([samples[i] for i in checked], points)
        failed.update({i: f"{samples[i].name}: {NOTHING_TO_FIT}"
                       for i, ok in zip(checked, usable) if not ok})
        indices = [i for i, ok in zip(checked, usable) if ok]
        if not indices:
            yield _ChunkFit([], failed)
            continue
        # Padded as far as the fitted samples need (not those left out just above).
        points = max(bucket(len(samples[i])) for i in indices)
        targets, weights = targets[usable, :points], weights[usable, :points]
        # After the checks: each geometry is made from angles that passed them.
        distinct: dict[bytes, int] = {}  # each geometry's first sample
        for i in indices:
            distinct.setdefault(keys[i], i)
        row_of = {key: row for row, key in enumerate(distinct)}
        scene = _scenes([samples[i] for i in distinct.values()], model, points)
        tic = time.perf_counter()
        (searched, polished), padded = _run_chunk(
            scene, np.array([row_of[keys[i]] for i in indices]), targets, weights, model,
            seeds[indices], bounds, config, devices, chunk_size, settings)
        if resumed_steps and model.searched_size:
            polished = _resume_slow(polished, padded, bounds, devices[0], resumed_steps)
        best, status, evaluations = polish_summary(polished)
        # Counted once per geometry, as the scenes are: a cube's samples share one.
        geometries = {key: distinct_geometries(samples[i]) for key, i in distinct.items()}
        counts = np.array([geometries[keys[i]] for i in indices])
        status = settled(status, counts, model)
        messages = [status_message(s, settings["max_steps"] + resumed_steps, n, model)
                    for s, n in zip(status, counts)]
        params, fitted, units = _fitted(best, padded, bounds)
        yield _ChunkFit(indices, failed, searched, polished, params, status, evaluations,
                        fitted, units, padded, time.perf_counter() - tic, messages)


def _chunk_targets(samples: list, points: int) -> tuple[np.ndarray, ...]:
    """`brdfjax.fitting.objective.normalised` of each sample: targets and weights (samples,
    points) and whether each sample is usable (samples,); samples of one length are stacked
    and done together."""
    count = len(samples)
    targets, weights = np.zeros((count, points)), np.zeros((count, points))
    usable = np.zeros(count, dtype=bool)
    groups: dict[tuple, list[int]] = {}
    for position, data in enumerate(samples):
        groups.setdefault((len(data), data.weights is None), []).append(position)
    for (_, unweighted), positions in groups.items():
        rows = [samples[p] for p in positions]
        stacked = [np.stack([getattr(data, name) for data in rows])
                   for name in ("brdf", "theta_r")]
        given = None if unweighted else np.stack([data.weights for data in rows])
        targets[positions], weights[positions], usable[positions] = normalised(
            *stacked, given, points)
    return targets, weights, usable


def _scenes(rows: list, model: Model, points: int) -> NamedTuple:
    """The model's geometry of each of ``rows`` (one sample per distinct geometry of a
    chunk), padded to ``points`` with copies of its first point and stacked: (G, points).

    From `VECTOR_GEOMETRIES` rows on (per-pixel angles), the rows in the plane of incidence
    and those out of it are each computed in one vmapped call, padded to a power of two
    with copies: a call per geometry costs about 0.3 ms of dispatch, more than the fit of a
    small linear sample. Fewer (a cross-validation's folds, a few files) keep a call each,
    with no compiled shape of their own.
    """
    if len(rows) < VECTOR_GEOMETRIES:
        return _stack([padded_scene(prepare(data, model), points) for data in rows])
    in_plane = np.array([data.in_plane for data in rows])
    parts, positions = [], []
    for plane in dict.fromkeys(in_plane.tolist()):  # in order of appearance
        chosen = np.flatnonzero(in_plane == plane)
        filled = chosen[_filled(chosen.size, _power_of_two(chosen.size))]
        angles = [np.stack([pad(getattr(rows[k], name), points) for k in filled])
                  for name in ("theta_i", "theta_r", "phi_r")]
        computed = _geometries(model, *angles, in_plane=plane)
        parts.append(jax.tree.map(lambda x, n=chosen.size: np.asarray(x)[:n], computed))
        positions.append(chosen)
    back = np.argsort(np.concatenate(positions))
    return jax.tree.map(lambda *arrays: np.concatenate(arrays)[back], *parts)


def _stack(scenes: list) -> NamedTuple:
    """Scenes of equal shape stacked along a new leading axis."""
    return jax.tree.map(lambda *arrays: np.stack([np.asarray(a) for a in arrays]), *scenes)


@stage(static_argnames=("in_plane",))
def _geometries(model: Model, theta_i, theta_r, phi_r, *, in_plane: bool):
    """The model's geometry of each row of angle arrays (G, N) (`brdfjax.fitting.objective.prepare`
    of each)."""
    return jax.vmap(lambda *angles: model.geometry(*angles, in_plane))(theta_i, theta_r, phi_r)


def _table(chunks, count: int, model: Model) -> BatchTable:
    """The `BatchTable` of `_chunk_fits`, each chunk's numbers formed at once: the E of
    `fit_result` (to rounding: there the weights are not normalised)."""
    table = BatchTable(np.full((count, model.size), np.nan), np.full(count, np.nan),
                       np.full(count, "failed", dtype=f"U{max(map(len, STATUSES))}"),
                       np.full(count, "", dtype=object))
    for chunk in chunks:
        table.message[list(chunk.failed)] = list(chunk.failed.values())
        if not chunk.indices:
            continue
        lanes = len(chunk.indices)
        target, weight = chunk.padded.target[:lanes], chunk.padded.weight[:lanes]
        difference = chunk.fitted - target
        table.params[chunk.indices] = chunk.params
        table.error[chunk.indices] = (np.sum(weight * difference * difference, axis=1)
                                      / np.sum(weight * target * target, axis=1))
        table.status[chunk.indices] = chunk.status
        table.message[chunk.indices] = chunk.messages
    return table


def lane_choice(lanes: str, devices) -> str:
    """``map`` or ``vmap``: ``lanes`` itself, or for ``auto`` ``map`` on a CPU and ``vmap``
    on an accelerator."""
    if lanes not in LANES:
        raise ValueError(f"lanes {lanes!r}: give one of {', '.join(LANES)}")
    if lanes == "auto":
        return "map" if devices[0].platform == "cpu" else "vmap"
    return lanes


def _resume_slow(polished: PolishResult, chunk: Problem, bounds: Bounds, device,
                 steps: int) -> PolishResult:
    """The ``vmap`` lanes' second batch: every start of ``polished`` (host arrays,
    (samples, starts, ...)) that ended unconverged with a finite E (stopped at `LANE_STEPS`,
    or rarely for another reason), run on for up to ``steps`` more LM steps side by side,
    its results put in its place (steps and evaluations added; the resumed run evaluates
    its start once more). ``chunk``: the padded chunk of `_run_chunk`."""
    samples, starts = np.nonzero(~polished.success & np.isfinite(polished.errors))
    if not samples.size:
        return polished
    filled = _filled(samples.size, _power_of_two(samples.size))  # few compiled sizes
    pick, start = samples[filled], starts[filled]
    shared = chunk.scene.cos_theta_r.ndim == 1
    scene = chunk.scene if shared else jax.tree.map(lambda x: x[pick], chunk.scene)
    arrays = jax.device_put((polished.free[pick, start], scene, chunk.target[pick],
                             chunk.weight[pick], bounds), device)
    resumed = jax.tree.map(lambda x: np.asarray(x)[:samples.size],
                           _resumed_lanes(*arrays, chunk.model, max_steps=steps))
    merged = {name: np.array(getattr(polished, name)) for name in polished._fields}
    for name in ("free", "params", "errors", "success"):  # one start per lane
        merged[name][samples, starts] = getattr(resumed, name)[:, 0]
    merged["steps"][samples, starts] += resumed.steps[:, 0]
    np.add.at(merged["evaluations"], samples, resumed.evaluations)
    return PolishResult(**merged)


@stage(static_argnames=("max_steps",))
def _resumed_lanes(free, scene, target, weight, bounds: Bounds, model: Model, *,
                   max_steps: int) -> PolishResult:
    """`brdfjax.fitting.polish.resume` of every lane (free (B, P), targets (B, N)) side by
    side, on a shared scene (N,) or one per lane (B, N)."""

    def one(scene, free, target, weight):
        return resume(free, Problem(scene, target, weight, model), bounds, max_steps)

    return across_samples(one, scene, (free, target, weight), None)


def _geometry_key(data: Measurements) -> bytes:
    """A digest equal for measurement sets with identical angle arrays."""
    digest = hashlib.sha256()
    for angles in (data.theta_i, data.theta_r, data.phi_r):
        digest.update(np.ascontiguousarray(angles, dtype=float).tobytes() + b"|")
    return digest.digest()


def _lanes(batched) -> list:
    """Each sample's slice of a batched result (a pytree with leading sample axis)."""
    leaves, tree = jax.tree.flatten(batched)
    return [jax.tree.unflatten(tree, lane) for lane in zip(*leaves)]


def _failed(data: Measurements, message: str, bounds: Bounds, model: Model) -> FitResult:
    """The result of a sample that could not be fitted: NaN parameters and the reason."""
    nothing = np.zeros(0)
    return FitResult(params=model.Params(*[np.nan] * model.size), error=np.nan,
                     error_by_incidence={},
                     validation_error=None, validation_by_incidence={}, residuals=nothing,
                     status="failed", at_bounds=[], evaluations=0,
                     lm_steps=nothing.astype(int), lm_success=nothing.astype(bool),
                     timings={}, history=nothing, method="hybrid", train_incidences=[],
                     validation_incidences=[], bounds=bounds, model=model, message=message)


def _sample_result(data, searched, polished, best, status, lm_evaluations, fitted, unit,
                   population_size, seconds, message, bounds, model) -> FitResult:
    """One sample's `FitResult` from its lanes of the batched search and polish, the
    polish's `polish_summary` (``best``, ``status``, ``lm_evaluations``; the status
    `settled`, with its ``message``), and its fitted projected BRDF and unit-cube
    coordinates (`_fitted`)."""
    history, evaluations = search_summary(searched, population_size)
    return fit_result(data, data, None, best, bounds, model, fitted=fitted, unit=unit,
                      method="hybrid", status=str(status),
                      evaluations=evaluations + int(lm_evaluations),
                      lm_steps=polished.steps, lm_success=polished.success,
                      timings={"total": seconds}, history=history, message=message)


def _run_chunk(scenes, rows, targets, weights, model: Model, seeds, bounds, config, devices,
               chunk_size, settings):
    """Pad one chunk, fit a block of it on every device at once.

    Args:
        scenes: the chunk's distinct geometries, stacked (G, N) (`_scenes`).
        rows: the geometry of each sample, (B,).
        targets, weights: each sample's `Problem` arrays, (B, N).
        model, seeds, bounds, config, devices, chunk_size, settings: as `fit_batch` passes.

    Returns:
        The searches and polishes of the samples (host arrays), and the padded chunk fitted:
        a `Problem` of host arrays with a leading lane axis (the scene's only where the
        samples have more than one geometry).
    """
    count = len(rows)
    # A device per SAMPLES_PER_DEVICE samples at most: XLA compiles a shape once per device,
    # and a small chunk (a cross-validation's folds, a few files) gains less from a second
    # device than that compilation (or its load from the cache) costs. So does any chunk of
    # a linear model: one exact solve per sample, 1024 Ross-Li pixels in milliseconds.
    linear = model.searched_size == 0
    devices = devices[:1 if linear else max(1, count // SAMPLES_PER_DEVICE)]
    lanes = min(chunk_size, _power_of_two(count))
    lanes = -(-max(lanes, count) // len(devices)) * len(devices)
    chosen = _filled(count, lanes)
    targets, weights = targets[chosen], weights[chosen]
    shared = scenes.cos_theta_r.shape[0] == 1
    scene = jax.tree.map(lambda x: x[0] if shared else x[rows[chosen]], scenes)
    config = EvolveConfig() if config is None else config
    block = lanes // len(devices)
    real = np.arange(lanes) < count  # the copies padding the chunk are skipped (map lanes)
    per_sample = (np.asarray(seeds)[chosen], real, targets, weights, None if shared else scene)

    def dispatch(number: int):
        device = devices[number]
        part = jax.tree.map(partial(_block, number=number, size=block), per_sample)
        seeds_, real_, target, weight, scene_ = jax.device_put(part, device)
        return _fit_chunk(seeds_, real_, jax.device_put(scene, device) if shared else scene_,
                          target, weight, *jax.device_put((bounds, config), device),
                          model, **settings)

    # Dispatched to every device before any result is awaited. From threads: XLA compiles
    # a new shape once per device, and so compiles for all devices at once (2 devices:
    # 29 s + 23 s one after the other on a loaded 2-core machine).
    if len(devices) == 1:
        running = [dispatch(0)]
    else:
        with ThreadPoolExecutor(len(devices)) as pool:
            running = list(pool.map(dispatch, range(len(devices))))
    results = jax.tree.map(lambda *blocks: np.concatenate(blocks)[:count], *running)
    return results, Problem(scene, targets, weights, model)


def _power_of_two(count: int) -> int:
    """The smallest power of two at least ``count`` (at least 1): lane counts so rounded
    keep the compiled shapes few."""
    return 1 << (count - 1).bit_length()


def _filled(count: int, lanes: int) -> list[int]:
    """The sample of each of ``lanes`` lanes: every one of ``count`` samples, then copies of
    the first (their results are dropped)."""
    return list(range(count)) + [0] * (lanes - count)


def _fitted(best, chunk: Problem, bounds: Bounds) -> tuple[np.ndarray, ...]:
    """Each sample's best parameters (samples, P) as `fit_result` reports them
    (`brdfjax.models.Model.canonical`), with their projected BRDF on its points (samples,
    N) and unit-cube coordinates (samples, P), for the whole padded ``chunk`` (`_run_chunk`)
    at once: the model in one compiled call.

    A shared scene is broadcast to every lane: vmapped over a scene of its own, each lane
    computes exactly what `brdfjax.fitting.objective.projected` computes for it alone (over
    a shared one, XLA orders the arithmetic otherwise, and the last bits differ).
    """
    model, lanes = chunk.model, len(chunk.target)
    vectors = on_bounds(np.stack([model.canonical(vector, bounds) for vector in best]), bounds)
    scene = jax.tree.map(lambda x: np.broadcast_to(x, (lanes, x.shape[-1])), chunk.scene)
    values = _projected_lanes(vectors[_filled(len(best), lanes)], scene, model)
    return vectors, np.asarray(values)[:len(best)], to_unit(vectors, bounds)


# A parameter this close to a bound (relative to the bound, or to the box's width where the
# bound is 0) is the bound: the search's way back from its scaled coordinates (log10, asinh)
# leaves float noise there (kd = 1.0000000000000061e-08 for the bound 1e-8), 6e-15 relative,
# while no fit determines a parameter to 1e-12.
BOUND_SNAP = 1e-12


def on_bounds(vectors, bounds: Bounds) -> np.ndarray:
    """``vectors`` (..., P) with every value within `BOUND_SNAP` of a bound set to it."""
    vectors = np.array(vectors, dtype=float)
    lower, upper = np.asarray(bounds.lower, float), np.asarray(bounds.upper, float)
    for edge in (lower, upper):
        scale = np.where(edge != 0, np.abs(edge), upper - lower)
        vectors = np.where(np.abs(vectors - edge) <= BOUND_SNAP * scale, edge, vectors)
    return vectors


@stage
def _projected_lanes(vectors, scene, model: Model):
    """`brdfjax.models.paper.evaluate_projected` of every lane's parameters (B, P) on its
    scene (B, N)."""
    return jax.vmap(evaluate_projected, in_axes=(0, 0, None))(vectors, scene, model)


def _block(values, number: int, size: int):
    """The ``number``-th block of ``size`` samples of an array with a leading sample axis."""
    return values[number * size:(number + 1) * size]


@stage(static_argnames=("population_size", "max_generations", "starts", "max_steps",
                        "search_batch", "polish_batch", "side_by_side"))
def _fit_chunk(seeds, real, scene, target, weight, bounds: Bounds, config: EvolveConfig,
               model: Model, *, population_size: int, max_generations: int, starts: int,
               max_steps: int, search_batch: int | None, polish_batch: int | None,
               side_by_side: bool) -> tuple[EvolveResult, PolishResult]:
    """The hybrid fit of a padded chunk in one compiled call.

    Args:
        seeds: one integer seed per sample, (B,).
        real: whether each lane holds a sample (B,); the others pad the chunk and are
            skipped where samples run one at a time (`across_samples`).
        scene: one geometry (N,) shared by every sample, or one per sample (B, N).
        target, weight: the `Problem` arrays of each sample, (B, N); weight 0 on padding.
        bounds, config: the search box and the genetic-search rates.
        model: the `brdfjax.models.Model` fitted (static).
        population_size, max_generations, starts, max_steps: as in `fit`.
        search_batch, polish_batch: samples run side by side in each stage (see
            `across_samples`).
        side_by_side: each sample's LM starts side by side (the ``vmap`` lanes).

    Returns:
        The batched `EvolveResult` and `PolishResult`, leading axis B.
    """

    if model.searched_size == 0:  # a linear model (Ross-Li, Lambert): one exact solve
        return across_samples(lambda scene, target, weight: solved_fit(
            Problem(scene, target, weight, model), bounds, max_generations), scene,
            (target, weight), None)

    def search(scene, seed, target, weight):
        return evolve(jax.random.key(seed), Problem(scene, target, weight, model), bounds, config,
                      population_size=population_size, max_generations=max_generations)

    def refine(scene, population, target, weight):
        return polish_population(population, Problem(scene, target, weight, model), bounds,
                                 starts=starts, max_steps=max_steps, side_by_side=side_by_side)

    searched = across_samples(search, scene, (seeds, target, weight), search_batch, real)
    polished = across_samples(refine, scene, (searched.population, target, weight),
                              polish_batch, real)
    return searched, polished


def across_samples(function, scene, arrays: tuple, batch: int | None, real=None):
    """``function(scene, *arrays[i])`` for every sample i, ``batch`` samples side by side.

    ``batch`` samples run together under ``vmap``, such groups one after another under
    ``lax.map``; ``None`` vmaps them all at once. Under ``vmap`` a loop runs as long as its
    slowest lane, so on a CPU small groups can be faster (``BENCHMARKS.md``). With
    ``batch`` 1, the samples whose ``real`` flag is False are skipped (their outputs are
    zeros): a chunk's padding costs nothing (a cross-validation's 5 fits padded to 8 lanes
    ran 1.6 times as long). Side by side, a skipped lane would still run.

    Args:
        function: ``(scene, *per-sample arrays) -> pytree`` for one sample.
        scene: a geometry shared by all samples (arrays (N,)) or one per sample ((B, N)).
        arrays: per-sample arrays, leading axis B.
        batch: samples per vmapped group, or None for all.
        real: whether each sample is one (B,), or None; with ``batch`` 1 the others (a
            chunk's padding) are skipped.

    Returns:
        The stacked outputs, leading axis B (zeros for a skipped sample).
    """
    shared = scene.cos_theta_r.ndim == 1
    if batch is None:
        return jax.vmap(function, in_axes=(None if shared else 0,) + (0,) * len(arrays))(
            scene, *arrays)
    mapped = arrays if shared else (scene, *arrays)

    def one(item):
        return function(scene, *item) if shared else function(*item)

    def unless_skipped(item):  # the sample's flag first: zeros where it is False
        flag, item = item[0], item[1:]
        zeros = jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), jax.eval_shape(one, item))
        return jax.lax.cond(flag, lambda: one(item), lambda: zeros)

    step = one
    if batch == 1 and real is not None:
        step, mapped = unless_skipped, (real, *mapped)
    # batch_size=1 would still vmap each sample (over an axis of one), which costs more
    return jax.lax.map(step, mapped, batch_size=None if batch == 1 else batch)


def use_every_core() -> list:
    """The devices to fit on: on a CPU, one single-threaded device per core.

    XLA alone keeps about one core busy on this work (its small operations gain little from
    threads), while one device per core, each running its own block of samples on one
    thread, keeps every core busy without the threads contending (``BENCHMARKS.md``,
    section batch). Must run before JAX starts its backend to take effect; a device count
    given in ``XLA_FLAGS`` (``--xla_force_host_platform_device_count``) is kept, and so are
    the devices of a JAX that has already started.
    """
    single_threaded()
    if "xla_force_host_platform_device_count" not in os.environ["XLA_FLAGS"]:
        try:
            jax.config.update("jax_num_cpu_devices", len(os.sched_getaffinity(0)))
        except RuntimeError:  # JAX already running in this process: keep its devices
            pass
    return jax.devices()


def single_threaded() -> None:
    """XLA:CPU without Eigen's threads, as every batch runs (`use_every_core`; a setting
    given in ``XLA_FLAGS`` is kept). A Dask worker's chunk (`brdfjax.cluster`) so
    computes what the local batch computes: with Eigen's threads a matrix product's last
    bits differ, and a fit that branches on them can end at another step count. Acts only
    before JAX starts its backend (on a worker: before its first chunk)."""
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_cpu_multi_thread_eigen" not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} --xla_cpu_multi_thread_eigen=false".strip()
