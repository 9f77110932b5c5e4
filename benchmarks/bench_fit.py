"""Fitting benchmarks: accuracy targets and speed against SciPy (run time against error:
`bench_profile.py`).

    .venv/bin/python benchmarks/bench_fit.py [--quick]

Sections written to BENCHMARKS.md:
- ``population``: cost per point-evaluation of the population evaluation (512 x 716).
- ``recovery``: noise-free synthetic data of the five paper samples, 20 seeds each.
- ``noisy``: 2.5 % noise, E against the best of a long multi-start search, 20 seeds each.
- ``real``: every real RT-300S run, brdfjax hybrid against generous scipy DE + LS.
- ``speed``: warm hybrid on the 716-point white-paint set against scipy DE + LS.
- ``cold``: `brdfjax fit` as a new process, first run ever and with a warm cache.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import jax
import jax.numpy as jnp
import numpy as np

import brdfjax
from benchmarks import report
from benchmarks.report import write_section
from brdfjax.compare import (
    TOLERANCES,
    scipy_de_ls,
    scipy_vp,
    unit_objectives,
)
from brdfjax.data.formats import load
from brdfjax.data.synthetic import paper_sample
from brdfjax.fitting.evolve import score_population
from brdfjax.fitting.fit import fit
from brdfjax.fitting.objective import error as objective_error
from brdfjax.fitting.objective import problem
from brdfjax.models.bounds import default_bounds
from brdfjax.models.paper import PAPER_SAMPLES

TRAIN = [10, 30, 45, 60]
RT300S = report.real_data("uaz-loft-rt300s")
REAL = sorted([*RT300S.glob("raw/*.xls"), *RT300S.glob("raw_legacy_1deg/*.xls")])
REAL = [p for p in REAL if not p.name.startswith("blank")]


def white_paint_train(noise=0.025, seed=1):
    return paper_sample("white_paint", noise=noise, seed=seed).at_incidences(TRAIN)


def median_time(run, repeats):
    run()
    times = []
    for _ in range(repeats):
        tic = time.perf_counter()
        jax.block_until_ready(run())
        times.append(time.perf_counter() - tic)
    return float(np.median(times))


def population_row(data, dtype, repeats):
    """A table row: time of one E evaluation for 512 members, and per point-evaluation."""
    prob = problem(data, dtype=dtype)
    bounds = jax.tree.map(lambda x: x.astype(dtype) if x.dtype.kind == "f" else x,
                          default_bounds())
    z = jax.random.uniform(jax.random.key(0), (512, 5), dtype=dtype)
    run = jax.jit(score_population)
    seconds = median_time(lambda: run(z, prob, bounds), repeats)
    return (f"| {jnp.dtype(dtype).name} | 512 x {len(data)} | {1e3 * seconds:.2f} | "
            f"{1e9 * seconds / (512 * len(data)):.2f} |")


def bench_population(repeats):
    data = white_paint_train()
    rows = [population_row(data, dtype, repeats) for dtype in (jnp.float64, jnp.float32)]
    write_section("population", "## Population evaluation (the genetic search's scoring)\n\n"
                  "`brdfjax.fitting.evolve.score_population`: for every member, kb and kd solved "
                  "exactly for its (kr, a, b), then E of Eq. (6). Geometry terms "
                  "precomputed once per data set (`brdfjax.models.geometry.Scene`); each "
                  "point-evaluation is the parameter-dependent part of Eq. (5) plus its "
                  "share of the six weighted sums.\n\n"
                  "| dtype | members x points | time (ms) | ns per point-evaluation |\n"
                  "|---|---|---|---|\n" + "\n".join(rows))


def bench_recovery(seeds):
    rows = []
    for name, truth in PAPER_SAMPLES.items():
        data = paper_sample(name, noise=0.0).at_incidences(
            TRAIN if name == "white_paint" else [10, 30, 45, 60])
        ok, worst_e, worst_p, times = 0, 0.0, 0.0, []
        for seed in range(seeds):
            result = fit(data, seed=seed)
            rel = float(np.max(np.abs(result.vector / np.array(truth) - 1)))
            ok += result.error < 1e-12 and rel < 1e-6
            worst_e, worst_p = max(worst_e, result.error), max(worst_p, rel)
            times.append(result.timings["total"])
        rows.append(f"| {name} | {ok}/{seeds} | {worst_e:.2e} | {worst_p:.2e} | "
                    f"{1e3 * np.median(times[1:]):.0f} |")
    write_section("recovery", "## Recovery from noise-free synthetic data\n\n"
                  "Target: parameters to 1e-6 relative and E < 1e-12 for 20 of 20 seeds "
                  "(fit seeds 0-19, hybrid method, default settings; 716 points each).\n\n"
                  "| sample | recovered | worst E | worst max relative parameter error | "
                  "median warm fit (ms) |\n|---|---|---|---|---|\n" + "\n".join(rows))


def long_search(data, truth):
    """The best E of a long multi-start search: 3 big hybrid fits and LM from the truth."""
    big = [fit(data, seed=100 + k, population_size=2048, max_generations=200, starts=64).error
           for k in range(3)]
    return min(*big, fit(data, "lm", start=np.array(truth)).error)


def scipy_reference(data, seeds=6):
    """The lowest E of the careful SciPy peer from ``seeds`` DE seeds, with a larger
    population and a tighter tolerance: a reference that is not brdfjax's own search."""
    objectives = unit_objectives(data, shared=True)
    return min(scipy_vp(data, seed=seed, objectives=objectives, popsize=30, tol=1e-4)[1]
               for seed in range(seeds))


def bench_noisy(seeds):
    rows = []
    for name in PAPER_SAMPLES:
        ok, worst, scipy_lower = 0, 0.0, 0
        for seed in range(seeds):
            data = paper_sample(name, noise=0.025, seed=1000 + seed).at_incidences(
                [10, 30, 45, 60])
            independent = scipy_reference(data)
            reference = min(long_search(data, PAPER_SAMPLES[name]), independent)
            e = fit(data, seed=seed).error
            gap = (e - reference) / reference
            ok += gap <= 1e-6
            worst = max(worst, gap)
            scipy_lower += independent < e * (1 - 1e-6)
        rows.append(f"| {name} | {ok}/{seeds} | {worst:.1e} | {scipy_lower} |")
    write_section("noisy", "## Synthetic data with 2.5 % relative noise\n\n"
                  "Target: E within 1e-6 relative of the reference, the lower of two "
                  "searches: a long brdfjax multi-start search (3 hybrid fits with 2048 "
                  "members x 200 generations and 64 LM starts, and LM started from the true "
                  "parameters) and an independent one, the careful SciPy peer (`scipy_vp`) "
                  "from 6 DE seeds with popsize 30 per dimension and tol 1e-4; for 20 of 20 "
                  "noise seeds (1000-1019; the Fresnel-free start was chosen on the cement "
                  "ones, see the models-synthetic section for seeds never used in "
                  "choosing settings). \"SciPy lower\": seeds where the SciPy search found a "
                  "lower E than brdfjax's default fit.\n\n"
                  "| sample | within 1e-6 | worst (E - E_best) / E_best | SciPy lower |\n"
                  "|---|---|---|---|\n" + "\n".join(rows))


def bench_real():
    rows = []
    for path in REAL:
        data = load(path, in_plane=True)
        result = fit(data)
        _, e_scipy, _ = scipy_de_ls(data, seed=0, generous=True,
                                    objectives=unit_objectives(data, shared=True))
        verdict = "yes" if result.error <= e_scipy * (1 + 1e-6) else "NO"
        rows.append(f"| {path.parent.name}/{path.name} | {len(data)} | {100 * result.error:.5f} "
                    f"| {100 * e_scipy:.5f} | {verdict} | {result.status} |")
    write_section("real", "## Real RT-300S runs (all incidences)\n\n"
                  "brdfjax hybrid (defaults) against scipy `differential_evolution` "
                  "(popsize 40, maxiter 3000, tol 1e-10) + `least_squares`, same model, "
                  "same box.\n\n"
                  "| run | points | E brdfjax (%) | E scipy (%) | brdfjax no worse | status |\n"
                  "|---|---|---|---|---|---|\n" + "\n".join(rows))


def bench_speed(repeats):
    data = white_paint_train()
    objectives = unit_objectives(data)  # compiled here, outside every timed region
    peers = {"brdfjax hybrid": lambda seed: fit(data, seed=seed).error,
             "scipy vp (careful)": lambda seed: scipy_vp(data, seed=seed,
                                                         objectives=objectives)[1],
             "scipy DE + LS (naive)": lambda seed: scipy_de_ls(data, seed=seed,
                                                               objectives=objectives)[1]}
    for run in peers.values():
        run(99)  # warm-up: compilation and first-call costs
    times = {name: [] for name in peers}
    errors = {name: [] for name in peers}
    for seed in range(3):  # interleaved, so that other jobs on the machine bias no method
        for name, run in peers.items():
            tic = time.perf_counter()
            errors[name].append(run(seed))
            times[name].append(time.perf_counter() - tic)
    median = {name: float(np.median(t)) for name, t in times.items()}
    best = min(min(e) for e in errors.values())
    rows = [f"| {name} | {100 * np.median(errors[name]):.6f} | {median[name]:.4f} | "
            f"{sum(e <= best * (1 + 1e-6) for e in errors[name])}/3 | {TOLERANCES[key]} |"
            for name, key in zip(peers, ("brdfjax hybrid", "scipy vp", "scipy de+ls (naive)"))]
    hybrid = median["brdfjax hybrid"]
    write_section("speed", "## Speed: warm fit of the 716-point white-paint set\n\n"
                  "Targets: hybrid at most 0.1 s warm and at least 15x faster than the "
                  "careful SciPy peer (`brdfjax.compare.scipy_vp`) reaching the same E. "
                  "Seeds 0-2 of each method, interleaved; median wall time. The SciPy "
                  "objectives are compiled before any timing, so SciPy's time is its "
                  "optimiser's.\n\n"
                  "| method | E (%) | time (s) | seeds reaching the best E (1e-6) | "
                  "stopping rule |\n|---|---|---|---|---|\n" + "\n".join(rows) + "\n\n"
                  f"Speed-up: **{median['scipy vp (careful)'] / hybrid:.1f}x** against the "
                  f"careful peer, {median['scipy DE + LS (naive)'] / hybrid:.1f}x against "
                  "the naive one.")


SCIPY_SCRIPT = """
import sys, numpy as np
from scipy.optimize import differential_evolution, least_squares
sys.path.insert(0, {tests!r})
from transcription import brdf
lines = [line for line in open(sys.argv[1]) if not line.startswith("#")]
t = np.loadtxt(lines[1:], delimiter=",")
ti, tr, pr, f0 = np.radians(t[:, 0]), np.radians(t[:, 1]), np.radians(t[:, 2]), t[:, 3]
tr = np.where(tr == ti, tr + 1e-6, tr)  # the paper's form is 0/0 at specular, NaN at back-scatter
# brdfjax's default box and scales: log10 for kb, kr, a, kd; asinh for b
lo = np.array([-14, -2, -2, np.arcsinh(-150), -8.0]); hi = np.array([3, 2, 2, np.arcsinh(80), 2.0])
log = np.array([1, 1, 1, 0, 1], bool)
def params(z):
    t = lo + (hi - lo) * z
    return np.where(log, 10.0 ** t, np.sinh(t))
y = f0 * np.cos(tr)
def residual(z):
    return (brdf(*params(z), ti, tr, pr) * np.cos(tr) - y) / np.sqrt(np.sum(y * y))
def error(z):
    r = residual(z)
    return r @ r if np.all(np.isfinite(r)) else np.inf
de = differential_evolution(error, [(0, 1)] * 5, seed=0, polish=False)
ls = least_squares(residual, de.x, bounds=(0, 1))
print(*params(ls.x), error(ls.x))
"""


def bench_cold():
    data_file = REPO / "data" / "synthetic" / "white_paint.csv"
    train = Path(tempfile.mkdtemp()) / "white_paint_train.csv"
    brdfjax.save(load(data_file).at_incidences(TRAIN), train)
    cache = tempfile.mkdtemp(prefix="brdfjax-cache-")
    env = {**os.environ, "BRDFJAX_CACHE": cache}
    cli = [str(Path(sys.executable).parent / "brdfjax"), "fit", str(train)]

    def wall(command, **kwargs):
        tic = time.perf_counter()
        subprocess.run(command, check=True, capture_output=True, **kwargs)
        return time.perf_counter() - tic


    first = wall(cli, env=env)
    later = float(np.median([wall(cli, env=env) for _ in range(3)]))
    fit_only = float(np.median([wall([*cli, "--uncertainty", "none"], env=env)
                                for _ in range(3)]))
    script = Path(tempfile.mkdtemp()) / "scipy_fit.py"
    script.write_text(SCIPY_SCRIPT.format(tests=str(REPO / "tests")))
    scipy = float(np.median([wall([sys.executable, str(script), str(train)])
                             for _ in range(3)]))
    # E of both fits, each computed by brdfjax on the same data: the script moves exact
    # specular points by 1e-6 rad (its transcription is 0/0 there), so its own E is of a
    # slightly different problem.
    out = Path(tempfile.mkdtemp()) / "fit.json"
    subprocess.run([*cli, "--uncertainty", "none", "--json", str(out)], check=True,
                   capture_output=True, env=env)
    e_brdfjax = json.loads(out.read_text())["error"]
    printed = subprocess.run([sys.executable, str(script), str(train)], check=True,
                             capture_output=True, text=True).stdout.split()
    e_scipy = float(objective_error(np.array(printed[:5], dtype=float), problem(load(train))))
    write_section("cold", "## Cold start: `brdfjax fit` as a new process (716 points)\n\n"
                  "Targets: first run ever at most 15 s; later runs (persistent compilation "
                  "cache) no slower than the equivalent NumPy + scipy DE + LS script as a "
                  "whole process. `brdfjax fit` computes the Laplace uncertainty by default; "
                  "the script fits only, on the same data, box and scales (log10, b by asinh) "
                  "with the transcription of `tests/transcription.py`.\n\n"
                  "| run | wall time (s) |\n|---|---|\n"
                  f"| `brdfjax fit`, empty compilation cache | {first:.2f} |\n"
                  f"| `brdfjax fit`, warm cache (median of 3) | {later:.2f} |\n"
                  f"| `brdfjax fit --uncertainty none`, warm cache (median of 3) | "
                  f"{fit_only:.2f} |\n"
                  f"| NumPy model + scipy DE + LS script (median of 3) | {scipy:.2f} |\n\n"
                  f"E of Eq. (6) on the training data, both computed by brdfjax: brdfjax's fit "
                  f"{100 * e_brdfjax:.6g} %, the script's parameters {100 * e_scipy:.6g} % "
                  f"(the script's own E, {100 * float(printed[5]):.6g} %, is of its "
                  "transcription, which moves exact specular points by 1e-6 rad).")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="fewer seeds and repeats; print, write nothing")
    parser.add_argument("--only", nargs="*", help="sections to run")
    args = parser.parse_args()
    seeds, repeats = (3, 3) if args.quick else (20, 20)
    report.DRY_RUN = args.quick  # a 3-seed run must not replace the 20-seed tables
    sections = {"population": lambda: bench_population(repeats),
                "recovery": lambda: bench_recovery(seeds),
                "speed": lambda: bench_speed(repeats),
                "cold": bench_cold,
                "real": bench_real,
                "noisy": lambda: bench_noisy(seeds)}
    for name in args.only or sections:
        tic = time.perf_counter()
        sections[name]()
        print(f"{name}: {time.perf_counter() - tic:.0f} s", flush=True)
