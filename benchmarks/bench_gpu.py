"""GPU timings, on a lent GPU machine (never required): batches and dense scans.

    python benchmarks/bench_gpu.py [--quick]

Section ``gpu``: `brdfjax.fit_batch` of 256 and 1024 of bench_batch's synthetic 716-point
samples in chunks of 1024, and the 101 250-point dense scans of bench_dense (five
and ggx), on the machine's default JAX device. ``first`` is the first call (tracing and
compilation included), ``warm`` a second call of the same size. The CPU rows of the batch
and dense sections were measured on another machine (2 cores): compare throughput, not
the machines. On the GPU the model evaluation and the linear solves run on the device;
JAX's CPU-only tricks (several CPU devices) do not apply.

Measured on an H100 (2026-11-26): 14 samples per second warm, slower than the 2-core CPU
(46-62 per second): the fits are many small sequential steps (the GA's generations, each LM
step of each start), so kernel launches, not arithmetic, set the time. 10 000 samples
would take about 12 minutes there, more than a device call allows, and are not run.
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
from benchmarks.bench_dense import scan
from benchmarks.report import write_section

CHUNK = 1024


def timed(call):
    tic = time.perf_counter()
    result = call()
    return time.perf_counter() - tic, result


def bench_batch(sizes):
    from brdfjax.batch import fit_batch

    rows, made = [], samples(max(sizes))
    for size in sizes:
        batch = made[:size]
        first, _ = timed(lambda batch=batch: fit_batch(batch, chunk_size=CHUNK))
        warm, results = timed(lambda batch=batch: fit_batch(batch, chunk_size=CHUNK))
        converged = sum(r.status == "converged" for r in results)
        rows.append(f"| {size} | {first:.1f} | {warm:.2f} | {size / warm:.0f} | "
                    f"{converged}/{size} |")
        print(rows[-1], flush=True)
    return rows


def bench_dense(models):
    import brdfjax

    rows = []
    for model in models:
        data = scan(model, 1.0, 1.6)
        first, _ = timed(lambda data=data, model=model: brdfjax.fit(data, model=model))
        warm, result = timed(lambda data=data, model=model: brdfjax.fit(data, model=model))
        rows.append(f"| {model} | {len(data)} | {first:.1f} | {warm:.2f} | "
                    f"{result.error:.10g} | {result.status} |")
        print(rows[-1], flush=True)
    return rows


def main() -> None:
    import jax

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes; write nothing")
    args = parser.parse_args()
    report.DRY_RUN = args.quick
    device = jax.devices()[0]
    print(f"device: {device.platform} {device.device_kind}", flush=True)
    batch = bench_batch([16, 64] if args.quick else [256, 1024])
    dense = bench_dense(["five"] if args.quick else ["five", "ggx"])
    write_section("gpu", "\n".join([
        f"## GPU: batches and dense scans ({device.device_kind})", "",
        ("`brdfjax.fit_batch` of bench_batch's synthetic 716-point samples (the five-parameter "
         f"model, default search), chunks of {CHUNK}; first call (compilation included) and "
         "a second, warm call of the same samples."), "",
        "| samples | first call (s) | warm (s) | samples per second (warm) | converged |",
        "|---|---|---|---|---|", *batch, "",
        "Dense scans of bench_dense (1 deg x 1.6 deg, 5 incidences, 2.5 % noise), default fit.",
        "", "| model | points | first fit (s) | warm fit (s) | E | status |",
        "|---|---|---|---|---|---|", *dense]))


if __name__ == "__main__":
    main()
