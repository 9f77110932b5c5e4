"""GPU timings, on a lent GPU machine (never required): batches and dense scans.

    python benchmarks/bench_gpu.py [--only batch dense | --only devices] [--quick]

Section ``gpu``: `brdfjax.fit_batch` of 256 and 1024 of bench_batch's synthetic 716-point
samples in chunks of 1024. Section ``gpu-devices``: the same 256 samples on the GPU and on
the same machine's CPU cores (one single-threaded JAX device per core, as `brdfjax batch`
does), same JAX, same seeds: speed, and whether the two agree. Section ``gpu-dense``:
bench_dense's synthetic scans (five and ggx, 101 250 and 300 600 points) fitted the default
way (searched on representative points) and on all points (`brdfjax.fitting.fit.DENSE_POINTS`
above the point count). ``first`` is the first call (tracing and compilation included),
``warm`` a second call of the same size, on the machine's default JAX device. The CPU rows
of the batch and dense sections were measured on another machine (2 cores): compare
throughput, not the machines; section gpu-devices compares on one machine.

Measured on an H100 (2026-11-26): 14 samples per second warm, against 186 on the same
machine's 16 CPU cores: the fits are many small sequential steps (the GA's generations,
each LM step of each start), so kernel launches, not arithmetic, set the time. 10 000
samples would take about 12 minutes there, more than a device call allows, and are not run.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from benchmarks import report
from benchmarks.bench_batch import samples
from benchmarks.bench_dense import SIZES, scan
from benchmarks.report import write_section

CHUNK = 1024


def timed(call):
    """(seconds of the first call, compilation included; of a second, warm call; its result)"""
    tic = time.perf_counter()
    call()
    first = time.perf_counter() - tic
    tic = time.perf_counter()
    result = call()
    return first, time.perf_counter() - tic, result


def bench_batch(sizes):
    from brdfjax.fitting.batch import fit_batch

    rows, made = [], samples(max(sizes))
    for size in sizes:
        batch = made[:size]
        first, warm, results = timed(lambda batch=batch: fit_batch(batch, chunk_size=CHUNK))
        converged = sum(r.status == "converged" for r in results)
        rows.append(f"| {size} | {first:.1f} | {warm:.2f} | {size / warm:.0f} | "
                    f"{converged}/{size} |")
        print(rows[-1], flush=True)
    return rows


def bench_devices(count):
    import jax
    import numpy as np

    from brdfjax.fitting.batch import fit_batch

    made, rows, fitted = samples(count), [], {}
    for name, devices in (("GPU", jax.devices()), ("CPU", jax.devices("cpu"))):  # GPU first
        first, warm, fitted[name] = timed(lambda devices=devices: fit_batch(
            made, chunk_size=CHUNK, devices=devices))
        converged = sum(r.status == "converged" for r in fitted[name])
        steps = np.median([np.max(r.lm_steps) for r in fitted[name]])
        rows.append(f"| {name} ({len(devices)} device{'s' * (len(devices) > 1)}) | "
                    f"{first:.1f} | {warm:.2f} | {count / warm:.0f} | {converged}/{count} | "
                    f"{steps:.0f} |")
        print(rows[-1], flush=True)
    gpu, cpu = (np.array([r.error for r in fitted[k]]) for k in ("GPU", "CPU"))
    gap = np.abs(gpu - cpu) / cpu
    status = sum(a.status != b.status for a, b in zip(fitted["GPU"], fitted["CPU"]))
    summary = (f"GPU against CPU, sample by sample: largest relative difference in E "
               f"{np.max(gap):.1e}, {np.sum(gap > 1e-6)} of {count} differ by more than "
               f"1e-6, {status} differ in status.")
    print(summary, flush=True)
    return rows, summary


def bench_dense(models, sizes):
    import brdfjax
    import brdfjax.fitting.fit

    rows, default = [], brdfjax.fitting.fit.DENSE_POINTS
    try:
        for model in models:
            for points in sizes:
                data = scan(model, *SIZES[points])
                for mode, threshold in (("representative", default),
                                        ("all points", len(data))):
                    brdfjax.fitting.fit.DENSE_POINTS = threshold
                    first, warm, result = timed(lambda data=data, model=model: brdfjax.fit(
                        data, model=model))
                    rows.append(f"| {model} | {len(data)} | {mode} | {first:.1f} | "
                                f"{warm:.2f} | {result.error:.10g} | {result.status} |")
                    print(rows[-1], flush=True)
    finally:
        brdfjax.fitting.fit.DENSE_POINTS = default
    return rows


def main() -> None:
    import jax

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", choices=("batch", "devices", "dense"),
                        default=["batch", "dense"], help="sections to run (devices alone)")
    parser.add_argument("--quick", action="store_true", help="small sizes; write nothing")
    args = parser.parse_args()
    if "devices" in args.only and len(args.only) > 1:
        parser.error("run --only devices on its own: it makes one CPU device per core, "
                     "single-threaded, before JAX starts, which would change the others")
    report.DRY_RUN = args.quick
    if "devices" in args.only:
        from brdfjax.fitting.batch import use_every_core

        use_every_core()  # one CPU device per core beside the GPU, before JAX starts
    device = jax.devices()[0]
    print(f"device: {device.platform} {device.device_kind}", flush=True)
    if "batch" in args.only:
        batch = bench_batch([16, 64] if args.quick else [256, 1024])
        write_section("gpu", "\n".join([
            f"## GPU: batches ({device.device_kind})", "",
            ("`brdfjax.fit_batch` of bench_batch's synthetic 716-point samples (the "
             f"five-parameter model, default search), chunks of {CHUNK}; first call "
             "(compilation included) and a second, warm call of the same samples."), "",
            "| samples | first call (s) | warm (s) | samples per second (warm) | converged |",
            "|---|---|---|---|---|", *batch]))
    if "devices" in args.only:
        rows, summary = bench_devices(16 if args.quick else 256)
        write_section("gpu-devices", "\n".join([
            f"## GPU against the same machine's CPU cores ({device.device_kind})", "",
            ("`brdfjax.fit_batch` of bench_batch's synthetic 716-point samples (the "
             "five-parameter model, default search, same seeds) on the GPU and on the "
             "machine's CPU cores, one single-threaded JAX device per core "
             "(`brdfjax.fitting.batch.use_every_core`, as `brdfjax batch` does); same process, same "
             "JAX. Steps: the median over samples of the most LM steps of a start. A "
             "sample whose status differs between the devices but whose E does not differs "
             "in LM's convergence test at its 1e-10 tolerance, not in the fit."), "",
            ("| devices | first call (s) | warm (s) | samples per second (warm) | converged "
             "| LM steps |"), "|---|---|---|---|---|---|", *rows, "", summary]))
    if "dense" in args.only:
        dense = bench_dense(["five"] if args.quick else ["five", "ggx"],
                            [1_000] if args.quick else [100_000, 300_000])
        write_section("gpu-dense", "\n".join([
            f"## GPU: dense scans ({device.device_kind})", "",
            ("bench_dense's synthetic out-of-plane scans (five incidences, 2.5 % noise), the "
             "default fit (searched and screened on 4096 representative points, the winner "
             "polished on all) and the fit on all points; first call (compilation included) "
             "and a second, warm call. The CPU's numbers for the same scans are in sections "
             "dense and dense-scaling (2 cores), where the representative points are what "
             "makes a dense scan fast."), "",
            "| model | points | fit | first call (s) | warm (s) | E | status |",
            "|---|---|---|---|---|---|---|", *dense]))


if __name__ == "__main__":
    main()
