"""Every benchmark, one after another, each in its own process: ``make bench``.

    .venv/bin/python benchmarks/run_all.py [--quick]

Timings share the machine's cores, so the scripts run in turn, never side by side. Each
writes its sections of BENCHMARKS.md itself (``--quick`` runs write nothing where the
script says so). About three hours on a 2-core machine.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
SCRIPTS = ("bench_fit.py", "bench_profile.py", "bench_uncertainty.py", "bench_batch.py",
           "bench_models.py", "bench_dense.py", "bench_predictive.py", "bench_plan.py",
           "bench_adaptive.py", "bench_contention.py")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="pass --quick where supported")
    args = parser.parse_args()
    for script in SCRIPTS:
        command = [sys.executable, str(HERE / script)]
        if args.quick and script != "bench_uncertainty.py":
            command.append("--quick")
        tic = time.perf_counter()
        print(f"== {script}", flush=True)
        done = subprocess.run(command, check=False)
        print(f"== {script}: exit {done.returncode} after {time.perf_counter() - tic:.0f} s",
              flush=True)
        if done.returncode:
            return done.returncode
    return 0


if __name__ == "__main__":
    sys.exit(main())
