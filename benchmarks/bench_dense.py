"""Dense scans: search on representative points, polish on all (issue 14, item 5).

    .venv/bin/python benchmarks/bench_dense.py [--quick]

Synthetic out-of-plane scans of the five-parameter model (the white paint's parameters)
and of GGX (a NiTE-like fit), 2.5 % relative noise, incidences 10/25/40/55/70 deg,
theta_r every 1 deg from 0 to 89, phi_r every 1.6 deg all round (101 250 points; smaller
scans thin phi_r and theta_r). Every fit runs in a fresh process, twice (the second,
warm run is timed); peak memory is that process's ``ru_maxrss`` (JAX and compiled code
included). "all points" is the fit with the dense path switched off
(`brdfjax.fitting.fit.DENSE_POINTS` above the point count): what brdfjax did before.

Sections: ``dense`` (the 101 250-point scan, both ways) and ``dense-scaling`` (fit time
and memory against the number of points, 1000 to 300 600, with SciPy's careful peer on the
same scans; its DE scores every candidate on every point, which stays well under 10 minutes
here because the linear parameters are solved, not searched).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from benchmarks import report
from benchmarks.report import worker_json, write_section

PARAMS = {"five": "5.708,2.24,0.452,-58.722,0.22", "ggx": "1.94,0.348,0.045,0.003"}
SIZES = {1_000: (4.5, 36.0), 10_000: (2.0, 8.0), 100_000: (1.0, 1.6),
         300_000: (0.5, 1.08)}  # points: (theta_r step, phi_r step) in deg: 1000, 10 125,
# 101 250 and 300 600 points


def scan(model: str, theta_step: float, phi_step: float):
    import numpy as np

    import brdfjax
    from brdfjax.data.measurements import Measurements

    ti, tr, pr = np.meshgrid(np.radians([10.0, 25.0, 40.0, 55.0, 70.0]),
                             np.radians(np.arange(0.0, 89.9, theta_step)),
                             np.radians(np.arange(0.0, 359.9, phi_step)))
    ti, tr, pr = ti.ravel(), tr.ravel(), pr.ravel()
    params = np.array([float(x) for x in PARAMS[model].split(",")])
    clean = np.asarray(brdfjax.brdf(params, ti, tr, pr, model=model))
    noise = 1 + 0.025 * np.random.default_rng(1).standard_normal(clean.size)
    return Measurements(ti, tr, pr, clean * noise, metadata={"sample": f"dense {model}"})


def worker(spec: str) -> dict:
    """One fit, cold then warm, in this process: ``model,theta_step,phi_step,mode``."""
    import resource

    import brdfjax
    import brdfjax.fitting.fit

    model, theta_step, phi_step, mode = spec.split(",")
    data = scan(model, float(theta_step), float(phi_step))
    if mode == "all":
        brdfjax.fitting.fit.DENSE_POINTS = 10**12
    times, result = [], None
    for _ in range(2):
        tic = time.perf_counter()
        if mode == "scipy":
            from brdfjax.compare import scipy_vp

            error = scipy_vp(data, model, seed=0)[1]
        else:
            result = brdfjax.fit(data, model=model)
            error = result.error
        times.append(time.perf_counter() - tic)
    return {"points": len(data), "cold": times[0], "warm": times[1], "error": error,
            "status": None if result is None else result.status,
            "memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def run(model, sizes, mode):
    theta_step, phi_step = sizes
    return worker_json([sys.executable, __file__, "--worker",
                        f"{model},{theta_step},{phi_step},{mode}"])


def bench_dense(models):
    lines = ["## Dense scans: searched on representative points, polished on all",
             "", "| model | points | fit | warm (s) | E | peak memory (MB) |",
             "|---|---|---|---|---|---|"]
    notes = []
    for model in models:
        runs = {mode: run(model, SIZES[100_000], mode) for mode in ("all", "dense")}
        for mode, label in (("all", "all points (before)"), ("dense", "representative")):
            r = runs[mode]
            lines.append(f"| {model} | {r['points']} | {label} | {r['warm']:.2f} | "
                         f"{r['error']:.10g} | {r['memory_mb']:.0f} |")
        gap = (runs["dense"]["error"] - runs["all"]["error"]) / runs["all"]["error"]
        notes.append(f"- {model}: **{runs['all']['warm'] / runs['dense']['warm']:.1f}x** "
                     f"faster warm; E differs by {gap:+.2e} relative (target: within 1e-6 "
                     "of the full-data fit, at least 3x faster, under 2 GB).")
    write_section("dense", "\n".join(lines + [""] + notes))


def bench_scaling(models, sizes):
    lines = ["## Dense scans: fit time and memory against points", "",
             ("Synthetic out-of-plane scans (five incidences, 2.5 % noise; see the script's "
              "docstring), 1000 to 300 600 points. brdfjax's default fit (searched on "
              "representative points above 16 384) and the careful SciPy peer (`scipy_vp`), "
              "each in a fresh process, timed on its second (warm) call; memory is the "
              "brdfjax process's peak resident set, JAX and compiled code included."), "",
             ("| model | points | brdfjax warm (s) | brdfjax cold (s) | memory (MB) | "
             "SciPy VP warm (s) | E brdfjax | E SciPy |"), "|---|---|---|---|---|---|---|---|"]
    for model in models:
        for points in sizes:
            mine = run(model, SIZES[points], "dense")
            peer = run(model, SIZES[points], "scipy")
            lines.append(f"| {model} | {mine['points']} | {mine['warm']:.2f} | "
                         f"{mine['cold']:.1f} | {mine['memory_mb']:.0f} | {peer['warm']:.2f} | "
                         f"{mine['error']:.8g} | {peer['error']:.8g} |")
    write_section("dense-scaling", "\n".join(lines))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="five only, nothing written")
    parser.add_argument("--only", nargs="+", choices=("dense", "scaling"))
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        print(json.dumps(worker(args.worker)))
        return
    report.DRY_RUN = args.quick
    models = ["five"] if args.quick else ["five", "ggx"]
    if "dense" in (args.only or ["dense"]):
        bench_dense(models)
    if "scaling" in (args.only or ["scaling"]):
        bench_scaling(models, [1_000, 10_000] if args.quick else list(SIZES))


if __name__ == "__main__":
    main()
