"""Batch fits: 256 samples against a loop of SciPy fits, LM strategies, scaling, equality.

    python benchmarks/bench_batch.py            # everything, into BENCHMARKS.md (section batch)
    python benchmarks/bench_batch.py --quick    # smaller sizes, nothing written

Samples are synthetic: the paper's five samples in turn, each parameter scaled by
``exp(0.1 N(0, 1))``, on the paper's 716-point geometry (incidence 10/30/45/60 deg, 179
points each), 2.5 % relative noise with its own seed (`brdfjax.synthetic.synthesize`).

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
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


# Smaller search for the "lighter settings" row (sizes valid for 8 islands).
LIGHT = {"population_size": 128, "max_generations": 30, "starts": 8, "max_steps": 100}


def _settings(options: dict) -> str:
    """``population_size 256, ...`` for the search sizes among ``options``."""
    return ", ".join(f"`{k}` {options[k]}" for k in LIGHT)


def samples(count: int, first: int = 0) -> list:
    """``count`` synthetic 716-point samples (see the module docstring)."""
    import numpy as np

    from brdfjax.model import PAPER_SAMPLES
    from brdfjax.synthetic import paper_geometry, synthesize

    geometry = paper_geometry("cement")  # the four-incidence, 716-point scan
    names = list(PAPER_SAMPLES)
    made = []
    for index in range(first, first + count):
        rng = np.random.default_rng(index)
        params = np.array(PAPER_SAMPLES[names[index % len(names)]])
        made.append(synthesize(params * np.exp(0.1 * rng.standard_normal(5)), *geometry,
                               seed=index, metadata={"sample": f"synthetic {index}"}))
    return made


def worker(count: int, lm_batch, repeats: int, compare_single: bool, settings: dict) -> dict:
    """Time `fit_batch` on ``count`` samples in this process; optionally single fits too."""
    import jax
    import numpy as np

    from brdfjax.batch import fit_batch
    from brdfjax.fit import fit

    data = samples(count)
    tic = time.perf_counter()
    results = fit_batch(data, lm_batch=lm_batch, **settings)
    cold = time.perf_counter() - tic
    warm, cpu = [], []
    for _ in range(repeats):
        tic, cpu_tic = time.perf_counter(), _cpu_seconds()
        results = fit_batch(data, lm_batch=lm_batch, **settings)
        warm.append(time.perf_counter() - tic)
        cpu.append(_cpu_seconds() - cpu_tic)
    report = {"count": count, "devices": len(jax.devices()), "lm_batch": lm_batch,
              "cold": cold, "warm": min(warm), "cpu": cpu[warm.index(min(warm))],
              "maxrss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
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


def run_worker(count: int, devices: int, lm_batch, repeats: int = 2,
               compare_single: bool = False, settings: dict | None = None) -> dict:
    """`worker` in a fresh process with ``devices`` CPU devices."""
    env = {**os.environ, "XLA_FLAGS": f"--xla_force_host_platform_device_count={devices}"}
    command = [sys.executable, __file__, "--worker", str(count), "--lm-batch", str(lm_batch),
               "--repeats", str(repeats), "--settings", json.dumps(settings or {})]
    command += ["--compare-single"] if compare_single else []
    done = subprocess.run(command, env=env, capture_output=True, text=True, check=True)
    report = json.loads(done.stdout.strip().splitlines()[-1])
    print(f"  {count} samples, {devices} device(s), lm_batch {lm_batch}: cold "
          f"{report['cold']:.1f} s, warm {report['warm']:.2f} s ({report['cpu']:.2f} s CPU), "
          f"{report['maxrss_mb']:.0f} MB", 
          file=sys.stderr)
    return report


def scipy_seconds(count: int) -> tuple[float, list]:
    """Median SciPy DE + least_squares seconds per sample (compilation excluded), and E."""
    import numpy as np

    from brdfjax.bounds import default_bounds
    from brdfjax.compare import _unit_objectives, scipy_de_ls

    times, errors = [], []
    for data in samples(count):
        # scipy_de_ls compiles its objective for every sample: time that apart.
        tic = time.perf_counter()
        objective, _, residual = _unit_objectives(data, default_bounds())
        objective(np.full(5, 0.5))
        residual(np.full(5, 0.5))
        compile_seconds = time.perf_counter() - tic
        tic = time.perf_counter()
        _, error, _ = scipy_de_ls(data, seed=0)
        times.append(time.perf_counter() - tic - compile_seconds)
        errors.append(error)
    return float(np.median(times)), errors


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="smaller sizes; write nothing")
    parser.add_argument("--worker", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--lm-batch", default="1", help=argparse.SUPPRESS)
    parser.add_argument("--repeats", type=int, default=2, help=argparse.SUPPRESS)
    parser.add_argument("--compare-single", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--settings", default="{}", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker is not None:
        lm_batch = None if args.lm_batch == "None" else int(args.lm_batch)
        print(json.dumps(worker(args.worker, lm_batch, args.repeats, args.compare_single,
                                json.loads(args.settings))))
        return

    from brdfjax.batch import FIT_DEFAULTS, LM_BATCH

    count = 32 if args.quick else 256
    cores = os.cpu_count()
    print(f"LM strategies on {count} samples", file=sys.stderr)
    strategies = [(devices, lm_batch) for devices in sorted({1, cores})
                  for lm_batch in (1, 4, 16, None)]
    timed = {key: run_worker(count, *key) for key in strategies}
    print(f"{count} samples against single fits", file=sys.stderr)
    main_run = run_worker(count, cores, LM_BATCH, repeats=2, compare_single=True)
    print("scaling", file=sys.stderr)
    sizes = (1, 4, 32) if args.quick else (1, 16, 256, 1024)
    scaling = {size: main_run if size == count else
               run_worker(size, cores, LM_BATCH, repeats=1 if size > 256 else 2)
               for size in sizes}
    print("lighter settings", file=sys.stderr)
    light = run_worker(count, cores, LM_BATCH, settings=LIGHT)
    print("scipy", file=sys.stderr)
    scipy_count = 2 if args.quick else 6
    per_sample, scipy_errors = scipy_seconds(scipy_count)

    warm = main_run["warm"]
    ratio = per_sample * count / warm
    errors = main_run["errors"][:scipy_count]
    lines = [
        "## Batch fits (`brdfjax.fit_batch`)",
        "",
        (f"Targets: {count} samples of 716 points in at most 10 s warm, and at least 50x the "
         "throughput of looping SciPy DE + least_squares. Synthetic samples (the paper's five "
         "in turn, parameters scaled by exp(0.1 N(0,1)), 2.5 % noise, own seed each); the "
         f"default fit ({_settings(FIT_DEFAULTS)}), on "
         f"{cores} CPU devices (`XLA_FLAGS=--xla_force_host_platform_device_count={cores}`, "
         "which `brdfjax batch` sets by itself) unless said otherwise. Each batch size runs "
         "in a fresh process; peak memory is that process's `ru_maxrss` (JAX runtime and "
         "compiled code included; the 1-sample row is the floor)."),
        "",
        (f"- **{count} samples: {warm:.2f} s warm** ({1e3 * warm / count:.1f} ms per sample; "
         f"first call {main_run['cold']:.1f} s with compilation)."),
        f"- SciPy DE + least_squares: {per_sample:.3f} s per sample (median of "
        f"{scipy_count} samples, its per-sample JIT compilation excluded), so "
        f"{per_sample * count:.0f} s for {count} samples extrapolated: **{ratio:.1f}x** the "
        "throughput. Same E as the batch on those samples: "
        + ("yes" if all(abs(b / s - 1) < 1e-6 for b, s in zip(errors, scipy_errors))
           else "no (" + ", ".join(f"{100 * b:.5g} vs {100 * s:.5g} %"
                                   for b, s in zip(errors, scipy_errors)) + ")") + ".",
        f"- Batched against `brdfjax.fit` of each of the {count} samples (same seed): largest "
        f"relative difference in E **{main_run['max_relative_difference']:.1e}**; same "
        f"status for every sample: {'yes' if main_run['same_status'] else 'no'}. Statuses: "
        + ", ".join(f"{s} {main_run['statuses'].count(s)}"
                    for s in sorted(set(main_run["statuses"]))) + ".",
        "",
        f"### LM stage: vmap over samples or a map ({count} samples, warm seconds)",
        "",
        ("`lm_batch` samples run their LMs together under `vmap` (`None`: the whole chunk), "
         "one such group after another (`lax.map`). A vmapped LM runs as long as its "
         "slowest lane."),
        "",
        "| devices | lm_batch 1 | 4 | 16 | None (vmap) |",
        "|---|---|---|---|---|",
    ]
    for devices in sorted({1, cores}):
        lines.append(f"| {devices} | " + " | ".join(
            f"{timed[(devices, b)]['warm']:.2f}" for b in (1, 4, 16, None)) + " |")
    reached = sum(abs(e / d - 1) < 1e-6 for e, d in zip(light["errors"], main_run["errors"]))
    lines += [
        "",
        f"Default: `lm_batch={LM_BATCH}` (`brdfjax.batch.LM_BATCH`).",
        "",
        "### Lighter settings",
        "",
        (f"{_settings(LIGHT)} instead of the defaults: "
         f"{light['warm']:.2f} s warm for {count} samples, "
         f"**{per_sample * count / light['warm']:.1f}x** SciPy's throughput; E equal to the "
         f"default fit's (1e-6 relative) on {reached} of {count} samples."),
        "",
        "### Scaling",
        "",
        "| samples | cold (s) | warm (s) | ms per sample (warm) | peak memory (MB) |",
        "|---|---|---|---|---|",
    ]
    lines += [f"| {size} | {r['cold']:.1f} | {r['warm']:.2f} | {1e3 * r['warm'] / size:.1f} | "
              f"{r['maxrss_mb']:.0f} |" for size, r in scaling.items()]
    lines += ["", ("Chunks hold at most 256 samples (`chunk_size`), so memory stops growing "
                   "past one chunk."),
              "", "No GPU was available: the 10,000-sample GPU time is not measured."]
    text = "\n".join(lines)
    print(text)
    if not args.quick:
        from benchmarks.report import write_section

        write_section("batch", text)


if __name__ == "__main__":
    main()
