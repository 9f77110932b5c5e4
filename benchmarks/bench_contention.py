"""Run time of warm commands while other processes hold the cores (issue 47, defect 8).

Warm ``brdfjax fit RUN --model ggx --cv`` and ``--predict`` took 2.3-53 s on 2 cores while
another job ran: OpenBLAS's idle threads spin, waiting for the next call, and took the time
slices of the thread doing the learned discrepancy's LAPACK calls. ``import brdfjax`` now
makes one OpenBLAS thread the default and keeps a count given in OPENBLAS_NUM_THREADS, so
the code before is this checkout with ``OPENBLAS_NUM_THREADS`` set to the core count
(OpenBLAS's own default): both are timed in one run, interleaved, on the same machine.

Each command runs as a whole process (warmed once per setting first), alone and beside
``--competitors`` busy Python processes (a loop each, no I/O). The machine may be shared:
its load average is in the section's footer, and other jobs inflate every time alike.

    python benchmarks/bench_contention.py [--repeats 3] [--competitors 2] [--predict] [--quick]
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from benchmarks import report  # first: it records XLA_FLAGS before brdfjax adds its own

RUN = "raw/NiTE_on_steel_v1o0A_20250915.xls"


def busy(seconds: float) -> None:
    """A competing job: one core's worth of pure Python work for ``seconds``."""
    end = time.monotonic() + seconds
    count = 0
    while time.monotonic() < end:
        for _ in range(10000):
            count += 1


def timed(command: list, env: dict) -> float:
    tic = time.perf_counter()
    done = subprocess.run(command, env=env, capture_output=True, text=True, check=False)
    if done.returncode:
        raise RuntimeError(f"{' '.join(command)} failed:\n{done.stderr}")
    return time.perf_counter() - tic


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--competitors", type=int, default=len(os.sched_getaffinity(0)))
    parser.add_argument("--predict", action="store_true",
                        help="also time fit --predict (the run's own geometry)")
    parser.add_argument("--quick", action="store_true",
                        help="one repeat, print instead of writing")
    args = parser.parse_args()
    report.DRY_RUN = args.quick
    repeats = 1 if args.quick else args.repeats
    data = report.real_data("uaz-loft-rt300s") / RUN
    cores = len(os.sched_getaffinity(0))  # what OpenBLAS counts by default
    out = Path(tempfile.mkdtemp(prefix="bench-contention-"))
    cli = [sys.executable, "-m", "brdfjax.cli", "fit", str(data), "--model", "ggx"]
    commands = {"fit --cv": cli + ["--cv"]}
    if args.predict:
        commands["fit --predict"] = cli + ["--predict", str(data),
                                           "--predict-out", str(out / "pred.csv")]
    base = report.child_env(BRDFJAX_CACHE=str(out / "cache"))
    base.pop("OPENBLAS_NUM_THREADS", None)  # as a user starts it
    settings = {"1 (brdfjax's default now)": base,
                f"{cores} (OpenBLAS's default: the code before)":
                    {**base, "OPENBLAS_NUM_THREADS": str(cores)}}
    for command in commands.values():  # warm the caches, once per setting
        for env in settings.values():
            timed(command, env)
    times = {(c, load, s): [] for c in commands for load in ("alone", "busy")
             for s in settings}
    started = report.load_average()
    for _ in range(repeats):
        for load in ("alone", "busy"):
            rivals = []
            if load == "busy":
                rivals = [multiprocessing.Process(target=busy, args=(3600,), daemon=True)
                          for _ in range(args.competitors)]
                for rival in rivals:
                    rival.start()
            try:
                for label, command in commands.items():
                    for setting, env in settings.items():
                        times[label, load, setting].append(timed(command, env))
                        print(label, load, setting, f"{times[label, load, setting][-1]:.2f} s",
                              flush=True)
            finally:
                for rival in rivals:
                    rival.terminate()
                    rival.join()
    rows = []
    for (label, load, setting), values in times.items():
        where = "alone" if load == "alone" else f"beside {args.competitors} busy processes"
        rows.append(f"| `{label}` | {where} | {setting} | {statistics.median(values):.2f} | "
                    f"{', '.join(f'{v:.1f}' for v in values)} |")
    now, before = settings
    ratio = {label: statistics.median(times[label, "busy", before])
             / statistics.median(times[label, "busy", now]) for label in commands}
    body = f"""<a id="contention"></a>
## Contention: warm commands beside busy processes

Warm `brdfjax fit RUN --model ggx`, RUN NiTE on steel A (`{RUN}` of uaz-loft-rt300s), with
{' and with '.join(f"`{c.split()[-1]}`" for c in commands)}, each a whole process, alone and beside {args.competitors} busy Python
processes on {cores} cores; OpenBLAS threads 1 (the default `import brdfjax` sets now, a
given OPENBLAS_NUM_THREADS kept) against {cores} (OpenBLAS's default: the code before), in
one run, interleaved, {repeats} repeats. The cause, measured with perf: OpenBLAS's idle
threads spin between calls (`blas_thread_server`, `exec_blas_async_wait`: about three
quarters of the process's CPU), and beside busy processes they take the time slices of
the thread making jaxlib's LAPACK calls (the learned discrepancy's Cholesky and triangular
solves). "alone" is without a competing process of this script's own: other jobs on a shared
machine load both conditions alike (1-minute load average {started} when the timings began;
the footer has it when written).

| command | load | OpenBLAS threads | median (s) | each run (s) |
|---|---|---|---|---|
{chr(10).join(rows)}

Beside busy processes, {cores} OpenBLAS threads took
{', '.join(f"{r:.1f}x" for r in ratio.values())} the time of one
({', '.join(ratio)}).
"""
    report.write_section("contention", body)


if __name__ == "__main__":
    main()
