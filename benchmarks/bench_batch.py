"""Batch fits: 256 samples against a loop of SciPy fits, LM strategies, scaling, equality.

    python benchmarks/bench_batch.py            # everything, into BENCHMARKS.md (section batch)
    python benchmarks/bench_batch.py --quick    # smaller sizes, nothing written

Samples are synthetic: the paper's five samples in turn, each parameter scaled by
``exp(0.1 N(0, 1))``, on the paper's 716-point geometry (incidence 10/30/45/60 deg, 179
points each), 2.5 % relative noise with its own seed (`brdfjax.data.synthetic.synthesize`).

Every batch runs in a fresh subprocess (``--worker``): the CPU device count must be set
before JAX starts, and the peak resident memory it reports (``ru_maxrss``) is then that
batch's alone, JAX runtime and compiled code included. Times are wall seconds: ``cold``
is the first call (tracing and compilation included), ``warm`` the best of the later ones.
The SciPy baseline is `brdfjax.compare.scipy_de_ls` (``differential_evolution`` with
SciPy's defaults on the same unit cube, then ``least_squares``; the same compiled model),
timed per sample on a few samples with its compilation excluded, and extrapolated.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from benchmarks.report import worker_json, write_section
from brdfjax.fitting.batch import POLISH_BATCH, SEARCH_BATCH

# (search_batch, polish_batch) pairs timed against each other, and brdfjax's defaults.
STRATEGIES = ((None, None), (None, 1), (16, 16), (4, 4), (1, 1))
DEFAULT_BATCHES = (SEARCH_BATCH, POLISH_BATCH)
# Smaller search for the "lighter settings" row (sizes valid for 8 islands).
LIGHT = {"population_size": 128, "max_generations": 30, "starts": 8, "max_steps": 100}


def _settings(options: dict) -> str:
    """``population_size 256, ...`` for the search sizes among ``options``."""
    return ", ".join(f"`{k}` {options[k]}" for k in LIGHT)


def samples(count: int, first: int = 0) -> list:
    """``count`` synthetic 716-point samples (see the module docstring)."""
    from brdfjax.data.synthetic import paper_geometry, synthesize
    from brdfjax.models.paper import PAPER_SAMPLES

    geometry = paper_geometry("cement")  # the four-incidence, 716-point scan
    names = list(PAPER_SAMPLES)
    made = []
    for index in range(first, first + count):
        rng = np.random.default_rng(index)
        params = np.array(PAPER_SAMPLES[names[index % len(names)]])
        made.append(synthesize(params * np.exp(0.1 * rng.standard_normal(5)), *geometry,
                               seed=index, metadata={"sample": f"synthetic {index}"}))
    return made


def worker(count: int, batches: dict, repeats: int, compare_single: bool,
           settings: dict) -> dict:
    """Time `fit_batch` on ``count`` samples in this process; optionally single fits too."""
    import jax

    from brdfjax.fitting.batch import fit_batch, use_every_core
    from brdfjax.fitting.fit import fit

    use_every_core()  # single-threaded devices, as `brdfjax batch` runs (device count kept)
    data = samples(count)
    tic = time.perf_counter()
    results = fit_batch(data, **batches, **settings)
    cold = time.perf_counter() - tic
    warm, cpu = [], []
    for _ in range(repeats):
        tic, cpu_tic = time.perf_counter(), _cpu_seconds()
        results = fit_batch(data, **batches, **settings)
        warm.append(time.perf_counter() - tic)
        cpu.append(_cpu_seconds() - cpu_tic)
    report = {"count": count, "devices": len(jax.devices()), **batches,
              "cold": cold, "warm": min(warm), "cpu": cpu[warm.index(min(warm))],
              "maxrss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
              "load": os.getloadavg()[0],
              "errors": [r.error for r in results],
              "statuses": [r.status for r in results]}
    if compare_single:
        single = [fit(d, **settings) for d in data]
        batched = np.array(report["errors"])
        alone = np.array([r.error for r in single])
        report["max_relative_difference"] = float(np.max(np.abs(batched / alone - 1)))
        report["same_status"] = all(r.status == s.status for r, s in zip(results, single))
    return report


def _cpu_seconds() -> float:
    """CPU time (user + system) of this process so far, all threads."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def _verdict(met: bool, quick: bool) -> str:
    """``met`` / ``not met``, or no verdict for a --quick run (not the target's size)."""
    return "not judged (--quick)" if quick else "met" if met else "not met"


def _versus(errors, references, rtol: float = 1e-6) -> str:
    """``equal to (1e-6) on 5, lower on 1, higher on 0 of 6 samples`` for E against E."""
    pairs = list(zip(errors, references))
    equal = sum(abs(e / r - 1) <= rtol for e, r in pairs)
    lower = sum(e < r * (1 - rtol) for e, r in pairs)
    return (f"equal (to {rtol:g}) on {equal}, lower on {lower}, higher on "
            f"{len(pairs) - equal - lower} of {len(pairs)} samples than")


def run_worker(count: int, devices: int, batches: tuple = DEFAULT_BATCHES, repeats: int = 2,
               compare_single: bool = False, settings: dict | None = None) -> dict:
    """`worker` in a fresh process with ``devices`` CPU devices.

    ``batches`` is (``search_batch``, ``polish_batch``) of `brdfjax.fit_batch`.
    """
    env = {**os.environ, "XLA_FLAGS": f"--xla_force_host_platform_device_count={devices}"}
    named = dict(zip(("search_batch", "polish_batch"), batches))
    command = [sys.executable, __file__, "--worker", str(count), "--batches", json.dumps(named),
               "--repeats", str(repeats), "--settings", json.dumps(settings or {})]
    command += ["--compare-single"] if compare_single else []
    report = worker_json(command, env)
    print(f"  {count} samples, {devices} device(s), batches {batches}: cold "
          f"{report['cold']:.1f} s, warm {report['warm']:.2f} s ({report['cpu']:.2f} s CPU), "
          f"{report['maxrss_mb']:.0f} MB", file=sys.stderr)
    return report


def scipy_seconds(count: int) -> dict:
    """Wall and CPU seconds of each of ``count`` samples, and E, for both SciPy peers.

    ``careful``: `brdfjax.compare.scipy_vp` (variable projection in DE, exact-Jacobian
    least_squares); ``naive``: `brdfjax.compare.scipy_de_ls` (DE over all five parameters,
    finite-difference least_squares). Each sample's objectives are built and compiled before
    the timers start (`brdfjax.compare.unit_objectives`), so the times are the optimisers'.
    """
    from brdfjax.compare import scipy_de_ls, scipy_vp, unit_objectives

    peers = {"careful": scipy_vp, "naive": scipy_de_ls}
    found = {name: ([], [], []) for name in peers}
    for data in samples(count):
        objectives = unit_objectives(data)
        objectives.error(np.full(5, 0.5))
        objectives.residuals(np.full(5, 0.5))
        for name, peer in peers.items():
            times, cpu, errors = found[name]
            tic, cpu_tic = time.perf_counter(), _cpu_seconds()
            _, error, _ = peer(data, seed=0, objectives=objectives)
            times.append(time.perf_counter() - tic)
            cpu.append(_cpu_seconds() - cpu_tic)
            errors.append(error)
    return {name: (np.array(t), np.array(c), e) for name, (t, c, e) in found.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="smaller sizes; write nothing")
    parser.add_argument("--worker", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--batches", default="{}", help=argparse.SUPPRESS)
    parser.add_argument("--repeats", type=int, default=2, help=argparse.SUPPRESS)
    parser.add_argument("--compare-single", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--settings", default="{}", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker is not None:
        print(json.dumps(worker(args.worker, json.loads(args.batches), args.repeats,
                                args.compare_single, json.loads(args.settings))))
        return

    from brdfjax.fitting.batch import FIT_DEFAULTS

    count = 32 if args.quick else 256
    cores = os.cpu_count()
    print(f"LM strategies on {count} samples", file=sys.stderr)
    strategy_count = count // 4  # the whole-chunk vmap is slow: time on fewer samples
    # SciPy's time per sample varied from 0.87 to 1.7 s between runs on this machine: it is
    # timed before and after the batch runs, and each sample's faster pass counts.
    scipy_count = 2 if args.quick else 6
    print("scipy (first pass)", file=sys.stderr)
    scipy_first = scipy_seconds(scipy_count)
    timed = {batches: run_worker(strategy_count, cores, batches) for batches in STRATEGIES}
    # One device against one per core, alternated so that other jobs on the machine bias
    # neither side: the best of two runs each.
    devices = {n: [] for n in (1, cores)}
    for _ in range(2):
        for n, runs in devices.items():
            runs.append(run_worker(strategy_count, n, repeats=3))
    best = {n: min(runs, key=lambda r: r["warm"]) for n, runs in devices.items()}
    print(f"{count} samples against single fits", file=sys.stderr)
    main_run = run_worker(count, cores, repeats=3, compare_single=True)
    print("scaling", file=sys.stderr)
    sizes = (1, 4, 32) if args.quick else (1, 16, 256, 1024)
    scaling = {size: main_run if size == count else
               run_worker(size, cores, repeats=1 if size > 256 else 2)
               for size in sizes}
    print("lighter settings", file=sys.stderr)
    light = run_worker(count, cores, settings=LIGHT)
    print("scipy (second pass)", file=sys.stderr)
    scipy_second = scipy_seconds(scipy_count)
    peers = {}  # name: (wall s per sample, CPU s per sample, E of each sample)
    for name in scipy_first:
        wall, cpu = (float(np.median(np.minimum(a, b)))
                     for a, b in zip(scipy_first[name][:2], scipy_second[name][:2]))
        peers[name] = (wall, cpu, scipy_first[name][2])

    warm = main_run["warm"]
    ratio = {name: wall * count / warm for name, (wall, _, _) in peers.items()}
    light_ratio = peers["careful"][0] * count / light["warm"]

    def peer_line(name, label, function, target):
        wall, cpu, errors = peers[name]
        return (f"- {label} (`brdfjax.compare.{function}`): {wall:.3f} s per sample (median "
                f"of {scipy_count} samples, timed one by one, each the faster of two passes, "
                "one before and one after the batch runs; its objectives compiled before its "
                f"timer starts), so {wall * count:.0f} s for {count} samples extrapolated: "
                f"the batch has **{ratio[name]:.1f}x** the throughput{target}. In CPU time "
                f"(user + system, all threads; less sensitive to other jobs): {cpu:.3f} s per "
                f"sample against the batch's {main_run['cpu'] / count:.3f} s, "
                f"{cpu * count / main_run['cpu']:.1f}x. On those samples the batch's E is "
                f"{_versus(main_run['errors'][:scipy_count], errors)} SciPy's.")
    lines = [
        "## Batch fits (`brdfjax.fit_batch`)",
        "",
        (f"Targets: {count} samples of 716 points in at most 10 s warm, and at least 50x the "
         "throughput of looping SciPy DE + least_squares (the naive peer; the careful one "
         "is the headline since issue 16). Synthetic samples (the paper's five "
         "in turn, parameters scaled by exp(0.1 N(0,1)), 2.5 % noise, own seed each); the "
         f"default fit ({_settings(FIT_DEFAULTS)}), on "
         f"{cores} single-threaded CPU devices (`XLA_FLAGS=--xla_force_host_platform_device_"
         f"count={cores} --xla_cpu_multi_thread_eigen=false`, which `brdfjax batch` sets by "
         "itself: `brdfjax.fitting.batch.use_every_core`) unless said otherwise. Each batch runs "
         "in a fresh process; peak memory is that process's `ru_maxrss` (JAX runtime and "
         "compiled code included; the 1-sample row is the floor). CPU is the process's "
         "user + system time; load is the machine's 1-minute load average after the run: "
         "above the core count, other jobs shared the cores and the wall times are longer "
         "than on an idle machine."),
        "",
        (f"- **{count} samples: {warm:.2f} s warm** ({1e3 * warm / count:.1f} ms per sample, "
         f"{main_run['cpu']:.1f} s CPU, load {main_run['load']:.1f}; first call "
         f"{main_run['cold']:.1f} s with compilation): target of 10 s "
         f"**{_verdict(warm <= 10, args.quick)}**."),
        peer_line("careful", "The careful SciPy peer, the headline", "scipy_vp", ""),
        peer_line("naive", "The naive SciPy peer", "scipy_de_ls",
                  f"; target of 50x (set against this peer) "
                  f"**{_verdict(ratio['naive'] >= 50, args.quick)}**"),
        (f"- Batched against `brdfjax.fit` of each of the {count} samples (same seed): largest "
         f"relative difference in E **{main_run['max_relative_difference']:.1e}**; same "
         f"status for every sample: {'yes' if main_run['same_status'] else 'no'} ("
         + ", ".join(f"{s} {main_run['statuses'].count(s)}"
                     for s in sorted(set(main_run["statuses"]))) + ")."),
        (f"- Lighter settings, {_settings(LIGHT)}: {light['warm']:.2f} s warm "
         f"({light['cpu']:.1f} s CPU, load {light['load']:.1f}), **{light_ratio:.1f}x** "
         f"the careful peer's throughput; E {_versus(light['errors'], main_run['errors'])} "
         "the default "
         "fit's."),
        "",
        f"### vmap over samples, or a map ({strategy_count} samples, {cores} devices)",
        "",
        ("`search_batch` (genetic search) and `polish_batch` (LM) samples run side by side "
         "under `vmap`, such groups one after another (`lax.map`); `None`: the whole chunk "
         "at once. A vmapped loop runs as long as its slowest lane."),
        "",
        "| search_batch | polish_batch | warm (s) | CPU (s) | load |",
        "|---|---|---|---|---|",
    ]
    lines += [f"| {b[0]} | {b[1]} | {r['warm']:.2f} | {r['cpu']:.2f} | {r['load']:.1f} |"
              for b, r in timed.items()]
    lines += [
        "",
        (f"Defaults: `search_batch={DEFAULT_BATCHES[0]}`, `polish_batch={DEFAULT_BATCHES[1]}`. "
         f"{strategy_count} samples, best of two alternated runs: "
         + " against ".join(f"{best[n]['warm']:.2f} s warm ({best[n]['cpu']:.1f} s CPU, load "
                            f"{best[n]['load']:.1f}) on {n} device{'s' * (n > 1)}"
                            for n in best) + "."),
        "",
        "### Scaling",
        "",
        ("| samples | cold (s) | warm (s) | CPU (s) | ms per sample (warm) | peak memory (MB) "
        "| load |"),
        "|---|---|---|---|---|---|---|",
    ]
    lines += [f"| {size} | {r['cold']:.1f} | {r['warm']:.2f} | {r['cpu']:.2f} | "
              f"{1e3 * r['warm'] / size:.1f} | {r['maxrss_mb']:.0f} | {r['load']:.1f} |"
              for size, r in scaling.items()]
    lines += ["", ("Chunks hold at most 256 samples (`chunk_size`), so memory stops growing "
                   "past one chunk."),
              "", ("GPU: see the gpu section (an H100 ran these batches 3-4x slower than "
                   "these 2 CPU cores).")]
    text = "\n".join(lines)
    print(text)
    if not args.quick:
        write_section("batch", text)


if __name__ == "__main__":
    main()
