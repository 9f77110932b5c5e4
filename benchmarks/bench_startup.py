"""A new user's first commands: each from an empty compilation cache, as a new process.

    python benchmarks/bench_startup.py                     # section startup of BENCHMARKS.md
    python benchmarks/bench_startup.py --before ../old     # also an older tree, same runs
    python benchmarks/bench_startup.py --repeats 1 --quick # one run each, nothing written
    python benchmarks/bench_startup.py --only fit          # section startup-fit

Targets (issue 25, a quiet 2-core machine, median of 3): the first ``brdfjax fit`` of the
716-point white-paint set (four incidences) at most 8 s, the first ``brdfjax models`` of a
120-point RT-300S run at most 30 s, the first ``brdfjax batch --model auto`` over the 8
RT-300S runs at most 60 s. Each run gets its own empty ``BRDFJAX_CACHE``; the tree measured
is put first on ``PYTHONPATH``. The load average after each run is reported: above the core
count, other work shared the cores and the wall times are longer than on a quiet machine.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from benchmarks.report import child_env, commit_of, real_data, write_section

RAW = real_data("uaz-loft-rt300s") / "raw"
TARGETS = {"fit": 8.0, "models": 30.0, "batch auto": 60.0}


def commands(folder: Path) -> dict:
    from brdfjax import save
    from brdfjax.data.formats import load

    train = folder / "white_paint_train.csv"
    save(load(REPO / "data" / "synthetic" / "white_paint.csv").at_incidences([10, 30, 45, 60]),
         train)
    brdfjax = [sys.executable, "-m", "brdfjax.cli"]
    return {"fit": [*brdfjax, "fit", str(train)],
            "models": [*brdfjax, "models", str(RAW / "NiTE_on_steel_v1o0A_20250915.xls"),
                       "--in-plane"],
            "batch auto": [*brdfjax, "batch", str(RAW), "--model", "auto", "--in-plane",
                           "--out", str(folder / "auto.csv")]}


def first_run(command, tree: Path, folder: Path) -> tuple[float, float]:
    """Wall seconds of one run from an empty cache, and the load average after it."""
    cache = Path(tempfile.mkdtemp(dir=folder))
    (folder / "auto.csv").unlink(missing_ok=True)
    Path(f"{folder / 'auto.csv'}.options.json").unlink(missing_ok=True)
    env = child_env(BRDFJAX_CACHE=str(cache), PYTHONPATH=str(tree))
    tic = time.perf_counter()
    # Run outside the checkout: ``python -m`` puts the working directory first on the path,
    # where a brdfjax there would shadow the tree on PYTHONPATH (every --before measured
    # this checkout when run from it).
    subprocess.run(command, env=env, capture_output=True, check=True, cwd=folder)
    return time.perf_counter() - tic, os.getloadavg()[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--before", type=Path, help="an older tree to measure the same way")
    parser.add_argument("--quick", action="store_true", help="print, write nothing")
    parser.add_argument("--only", nargs="+", choices=list(TARGETS),
                        help="these commands only, written to section startup-NAME")
    args = parser.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="brdfjax-startup-"))
    runs = {name: command for name, command in commands(folder).items()
            if not args.only or name in args.only}
    trees = {"now": REPO, **({"before": args.before.resolve()} if args.before else {})}
    rows = []
    for name, command in runs.items():
        # The trees alternate run by run: this machine's speed drifts by more than most
        # changes within an hour, and one tree's runs all in a row would measure the drift.
        measured = {label: [] for label in trees}
        for _ in range(args.repeats):
            for label, tree in trees.items():
                measured[label].append(first_run(command, tree, folder))
        for label, results in measured.items():
            walls = [wall for wall, _ in results]
            rows.append(f"| `brdfjax {name}` | {label} | {np.median(walls):.1f} | "
                        f"{min(walls):.1f}-{max(walls):.1f} | "
                        f"{max(load for _, load in results):.1f} | {TARGETS[name]:.0f} |")
    named = ", ".join(f"`brdfjax {name}`" for name in runs)
    text = (f"## Start-up: a new user's first {named if args.only else 'commands'} "
            "(empty cache)\n\n"
            f"Median of {args.repeats} runs, each from its own empty compilation cache.\n\n"
            "| command | tree | median (s) | range (s) | load after (max) | target (s) |\n"
            "|---|---|---|---|---|---|\n" + "\n".join(rows) + "\n"
            + (f"\n*before*: `{commit_of(args.before)}`; *now*: `{commit_of(REPO)}`.\n"
               if args.before else ""))
    if args.quick:
        print(text)
    else:
        write_section("-".join(["startup", *(args.only or [])]).replace(" ", "-"), text)


if __name__ == "__main__":
    main()
