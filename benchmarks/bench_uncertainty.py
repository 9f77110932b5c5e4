"""Uncertainty benchmarks: calibration over synthetic replicates, speed, and the snooker move.

    .venv/bin/python benchmarks/bench_uncertainty.py [--replicates 200] [--noise-replicates 50]
        [--only calibration speed snooker]

Calibration: white-paint replicates (the paper's parameters and geometry, 2.5 % relative
noise with its sigma given, a new noise draw per replicate; fit on 10/30/45/60 deg = 716
points, 21/52 deg held out). Each is fitted (hybrid), then Laplace and emcee (run until 50
autocorrelation times) give 68 % and 95 % intervals; the table counts how often they
contain the true parameter, and how many points of the true curves (all six incidences,
held-out ones included) lie inside the 95 % bands. A second, smaller set drops sigma, so
that the noise scales are inferred. Speed: Laplace warm, and emcee 32 walkers x 5000 steps
warm, on the bundled 716-point set. Last, the check behind the corrected snooker move
(`brdfjax.uncertainty.mcmc`): emcee's ``DESnookerMove`` against the corrected one on a 5-D
Gaussian. Sections of BENCHMARKS.md: ``uncertainty`` (calibration), ``uncertainty-speed``,
``uncertainty-snooker``; ``--only`` runs some of them.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time
import warnings
from functools import partial
from pathlib import Path
from statistics import NormalDist

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import numpy as np

from benchmarks.report import worker_json, write_section
from brdfjax.data.formats import load
from brdfjax.data.synthetic import paper_sample
from brdfjax.fitting.fit import fit
from brdfjax.models.paper import PAPER_SAMPLES, PARAMETER_NAMES, projected_brdf
from brdfjax.plot import curve_angles
from brdfjax.uncertainty.bands import curve_bands
from brdfjax.uncertainty.laplace import laplace_approximation
from brdfjax.uncertainty.mcmc import inline_dispatch, sample_posterior
from brdfjax.uncertainty.result import UncertaintyWarning

TRUTH = np.array(PAPER_SAMPLES["white_paint"], dtype=float)
HELD_OUT = [21, 52]
INCIDENCES = [10.0, 21.0, 30.0, 45.0, 52.0, 60.0]
CURVE_POINTS = 181


def true_curves() -> np.ndarray:
    """The true f_r cos(theta_r) on the band scans of every incidence, (incidences, points)."""
    return np.array([np.asarray(projected_brdf(TRUTH, *curve_angles(deg, CURVE_POINTS)[0]))
                     for deg in INCIDENCES])


def inside(interval, value) -> np.ndarray:
    """Whether value lies in each [lo, hi] row of interval (5, 2)."""
    return (interval[:, 0] <= value) & (value <= interval[:, 1])


def band_hits(result, truth) -> np.ndarray:
    """Fraction of the true curve's points inside the 95 % band, per incidence."""
    bands = curve_bands(result.samples, INCIDENCES, count=CURVE_POINTS)
    return np.array([np.mean((bands[deg].lo95 <= truth[k]) & (truth[k] <= bands[deg].hi95))
                     for k, deg in enumerate(INCIDENCES)])


def calibrate(replicates: int, given_sigma: bool, offset: int) -> dict:
    """Coverage counts of both methods over noise replicates (see the module docstring)."""
    truth = true_curves()
    counts = {m: {"ci68": np.zeros(5), "ci95": np.zeros(5), "bands": []}
              for m in ("laplace", "mcmc")}
    statuses, steps, tau, seconds = [], [], [], []
    for k in range(replicates):
        data = paper_sample("white_paint", seed=offset + k)
        if not given_sigma:
            data = dataclasses.replace(data, sigma=None)
        result = fit(data, validate_incidences_deg=HELD_OUT, seed=k)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UncertaintyWarning)
            laplace = laplace_approximation(data, result, seed=k)
            tic = time.perf_counter()
            mcmc = sample_posterior(data, result, start=laplace, seed=k, progress=False)
        seconds.append(time.perf_counter() - tic)
        statuses.append(mcmc.status)
        steps.append(mcmc.diagnostics["steps"])
        tau.append(max(mcmc.diagnostics["tau"].values()))
        for name, estimate in (("laplace", laplace), ("mcmc", mcmc)):
            for level in ("ci68", "ci95"):
                counts[name][level] += inside(getattr(estimate, level), TRUTH)
            counts[name]["bands"].append(band_hits(estimate, truth))
        if (k + 1) % 10 == 0:
            print(f"  {k + 1}/{replicates}: emcee 95 % coverage so far "
                  f"{np.round(counts['mcmc']['ci95'] / (k + 1), 3)}", flush=True)
    return {"counts": counts, "replicates": replicates, "statuses": statuses,
            "steps": np.array(steps), "tau": np.array(tau), "seconds": np.array(seconds)}


def coverage_table(run: dict) -> str:
    """Markdown: coverage per parameter, both methods, both levels."""
    n = run["replicates"]
    lines = ["| interval | " + " | ".join(PARAMETER_NAMES) + " |",
             "|---|" + "---|" * 5]
    for method, label in (("mcmc", "emcee"), ("laplace", "Laplace")):
        for level, nominal in (("ci95", "95 %"), ("ci68", "68 %")):
            share = run["counts"][method][level] / n
            lines.append(f"| {label} {nominal} | " + " | ".join(f"{100 * s:.1f} %"
                                                               for s in share) + " |")
    held = np.isin(INCIDENCES, HELD_OUT)
    band_lines = ["| bands (95 %) | fitted incidences | held-out incidences (21, 52 deg) |",
                  "|---|---|---|"]
    for method, label in (("mcmc", "emcee"), ("laplace", "Laplace")):
        hits = np.array(run["counts"][method]["bands"])
        band_lines.append(f"| {label} | {100 * hits[:, ~held].mean():.1f} % | "
                          f"{100 * hits[:, held].mean():.1f} % |")
    converged = sum(s == "converged" for s in run["statuses"])
    return "\n".join(lines) + "\n\n" + "\n".join(band_lines) + (
        f"\n\nemcee: {converged}/{n} chains converged (longer than 50 tau); steps median "
        f"{np.median(run['steps']):.0f} (max {run['steps'].max()}), max tau median "
        f"{np.median(run['tau']):.1f}, {np.median(run['seconds']):.2f} s per chain (median). "
        f"Binomial standard error of a 95 % coverage over {n} replicates: "
        f"{100 * np.sqrt(0.95 * 0.05 / n):.1f} %. " + _outliers(run))


def _outliers(run: dict) -> str:
    """A sentence on every coverage two binomial standard errors or more from nominal."""
    n, found = run["replicates"], []
    for method, label in (("mcmc", "emcee"), ("laplace", "Laplace")):
        for level, nominal in (("ci95", 0.95), ("ci68", 0.68)):
            se = np.sqrt(nominal * (1 - nominal) / n)
            for name, share in zip(PARAMETER_NAMES, run["counts"][method][level] / n):
                if abs(share - nominal) >= 1.95 * se:  # 2 SE, as printed to 1 decimal
                    side = "low" if share < nominal else "high"
                    found.append(f"{label}'s {100 * nominal:.0f} % coverage of {name}, "
                                 f"{100 * share:.1f} %, is {abs(share - nominal) / se:.1f} "
                                 f"binomial SE {side} (SE {100 * se:.1f} %)")
    if not found:
        return "Every coverage lies within 2 binomial SE of its nominal level."
    return ("Outside 2 binomial SE: " + "; ".join(found) + ". Such an interval covers the truth less (low) "
            "or more (high) often than its level claims; with 20 coverages in the table, "
            "roughly one lies 2 SE out by chance alone (a 2-sided 5 % event each, the entries not independent), so one "
            "such entry alone is weak evidence of a miscalibrated interval, and the 95 % "
            "rows, which matter most, are the ones to watch.")



def eq6_intervals(result, level: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """Intervals about the Eq. (6) fit itself, two ways, in the fit's unit coordinates.

    Eq. (6) is unweighted least squares on the projected BRDF (weights g aside), so its
    estimate has the usual linearised covariance ``(J^T J)^-1 J^T Omega J (J^T J)^-1``:
    ``classic`` takes the noise as alike at every point (``Omega = s^2 I``, ``s^2`` the
    residual variance), ``sandwich`` takes each point's squared residual (White's HC0, times
    N / (N - P)), which holds whatever the noise's shape. The interval ends are Gaussian
    quantiles in the unit coordinates mapped through the bounds, as Laplace's are.

    Returns:
        ``(classic, sandwich)``, each (P, 2) in physical units.
    """
    import jax
    import jax.numpy as jnp

    from brdfjax.fitting.objective import prepare, targets
    from brdfjax.models.bounds import from_unit, to_unit
    from brdfjax.models.paper import evaluate_projected

    train, model, bounds = result.training, result.model, result.bounds
    scene = prepare(train, model)
    target, weight = targets(train)
    root = np.sqrt(weight)
    unit = np.asarray(to_unit(np.asarray(result.vector), bounds))

    def weighted(z):
        return jnp.sqrt(jnp.asarray(weight)) * evaluate_projected(from_unit(z, bounds), scene,
                                                                  model)

    jacobian = np.asarray(jax.jacfwd(weighted)(jnp.asarray(unit)))
    residual = root * target - np.asarray(weighted(jnp.asarray(unit)))
    n, p = jacobian.shape
    bread = np.linalg.inv(jacobian.T @ jacobian)
    classic = bread * (residual @ residual) / (n - p)
    meat = (jacobian * residual[:, None] ** 2).T @ jacobian
    sandwich = bread @ meat @ bread * n / (n - p)
    quantile = NormalDist().inv_cdf(0.5 + level / 2)
    out = []
    for covariance in (classic, sandwich):
        half = quantile * np.sqrt(np.diag(covariance))
        ends = np.clip(np.stack([unit - half, unit + half]), 0.0, 1.0)
        out.append(np.asarray(from_unit(jnp.asarray(ends), bounds)).T)
    return out[0], out[1]


def consistency(replicates: int, sample: str = "white_paint", offset: int = 7000) -> str:
    """Which interval to report beside which estimate (issue 26): coverage of the truth by
    the posterior's intervals and by intervals about the Eq. (6) fit, and how often the fit
    lies outside the posterior's interval, with sigma given and with it dropped."""
    truth = np.array(PAPER_SAMPLES[sample], dtype=float)
    lines = ["| sigma | interval (95 %) | centred on | " + " | ".join(PARAMETER_NAMES)
             + " | width (median, relative to truth) |", "|---|---|---|" + "---|" * 6]
    notes = []
    for given in (True, False):
        hits = {k: np.zeros(5) for k in ("posterior", "classic", "sandwich")}
        widths = {k: [] for k in hits}
        fit_outside, error_fit, error_median = np.zeros(5), [], []
        for k in range(replicates):
            data = paper_sample(sample, seed=offset + k)
            if not given:
                data = dataclasses.replace(data, sigma=None)
            result = fit(data, validate_incidences_deg=HELD_OUT, seed=k)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UncertaintyWarning)
                laplace = laplace_approximation(data, result, seed=k)
            classic, sandwich = eq6_intervals(result)
            for name, interval in (("posterior", laplace.ci95), ("classic", classic),
                                   ("sandwich", sandwich)):
                hits[name] += inside(interval, truth)
                widths[name].append((interval[:, 1] - interval[:, 0]) / np.abs(truth))
            fit_outside += ~inside(laplace.ci95, result.vector)
            error_fit.append(np.abs(result.vector - truth) / np.abs(truth))
            error_median.append(np.abs(laplace.median - truth) / np.abs(truth))
        label = "given" if given else "inferred"
        for name, centre in (("posterior", "posterior median"), ("classic", "Eq. (6) fit"),
                             ("sandwich", "Eq. (6) fit")):
            kind = {"posterior": "posterior (Laplace)", "classic": "Eq. (6), noise alike",
                    "sandwich": "Eq. (6), sandwich"}[name]
            width = np.median(np.array(widths[name]), axis=0)
            lines.append(f"| {label} | {kind} | {centre} | "
                         + " | ".join(f"{100 * h / replicates:.0f} %" for h in hits[name])
                         + " | " + ", ".join(f"{100 * w:.2g} %" for w in width) + " |")
        notes.append(
            f"sigma {label}: the Eq. (6) fit lies outside the posterior's 95 % interval in "
            + ", ".join(f"{name} {100 * c / replicates:.0f} %"
                        for name, c in zip(PARAMETER_NAMES, fit_outside))
            + " of replicates; median relative error of the fit "
            + ", ".join(f"{100 * v:.2g} %" for v in np.median(error_fit, axis=0))
            + ", of the posterior median "
            + ", ".join(f"{100 * v:.2g} %" for v in np.median(error_median, axis=0)) + ".")
    se = 100 * np.sqrt(0.95 * 0.05 / replicates)
    return ("\n".join(lines) + "\n\n" + "\n\n".join(notes)
            + f"\n\n{replicates} replicates each; binomial standard error of a 95 % "
              f"coverage: {se:.1f} %.")


def speed_worker(inline: bool) -> dict:
    """Laplace warm and emcee 32 x 5000 warm, in this (fresh) process: times in seconds.

    ``inline``: JAX's CPU computations run on the calling thread
    (`brdfjax.uncertainty.mcmc.inline_dispatch`, as ``brdfjax fit`` sets), else JAX's default
    asynchronous dispatch. Wall time, and the process's CPU time beside it: on a shared
    machine the wall time includes waiting for a core.
    """
    if inline:
        inline_dispatch()  # before the first JAX computation of this process
    data = load(REPO / "data" / "synthetic" / "white_paint.csv")
    result = fit(data, validate_incidences_deg=HELD_OUT)
    laplace = laplace_approximation(data, result)

    def timed(run):
        wall, cpu = time.perf_counter(), time.process_time()
        run()
        return time.perf_counter() - wall, time.process_time() - cpu

    laplace_times = [timed(lambda: laplace_approximation(data, result)) for _ in range(50)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UncertaintyWarning)
        sample_posterior(data, result, start=laplace, max_steps=500,
                         stop_when_converged=False, progress=False)
        sampled = [timed(partial(sample_posterior, data, result, start=laplace,
                                 max_steps=5000, seed=seed, progress=False,
                                 stop_when_converged=False)) for seed in range(3)]
    return {"laplace": laplace_times, "emcee": sampled, "load": os.getloadavg()[0]}


def speed() -> str:
    """Laplace and emcee timings, each dispatch mode in a fresh process (alternated, twice)."""
    runs = {True: [], False: []}
    for _ in range(2):
        for inline, done_runs in runs.items():
            command = [sys.executable, __file__, "--speed-worker",
                       "inline" if inline else "default"]
            done_runs.append(worker_json(command))

    def cells(key, inline, unit=1.0, digits=2):
        times = unit * np.concatenate([np.array(run[key]) for run in runs[inline]])
        return (f"{np.median(times[:, 0]):.{digits}f}, {times[:, 0].min():.{digits}f} | "
                f"{np.median(times[:, 1]):.{digits}f}")

    loads = [run["load"] for both in runs.values() for run in both]
    return ("| what | target | wall (median, min) | CPU (median) |\n|---|---|---|---|\n"
            "| Laplace, warm (100 calls), ms | at most 20 ms | "
            f"{cells('laplace', True, 1e3, 1)} |\n"
            "| emcee 32 walkers x 5000 steps, 716 points, warm (6 runs), s | at most 5 s | "
            f"{cells('emcee', True)} |\n"
            "| the same emcee runs with JAX's default asynchronous dispatch, s | | "
            f"{cells('emcee', False)} |\n\n"
            "Each row runs in two fresh processes, alternated with the other mode. The first "
            "two rows run as `brdfjax fit` does, with JAX's CPU computations inline on the "
            "calling thread (`brdfjax.inline_dispatch`). Load average after the "
            f"runs: {min(loads):.1f}-{max(loads):.1f} on {os.cpu_count()} cores.")


def snooker_check(steps: int = 20000) -> str:
    """Variance of a 5-D Gaussian's samples over its true variance, per move mix."""
    import emcee

    from brdfjax.uncertainty.mcmc import snooker_move

    rng = np.random.default_rng(1)
    factor = rng.standard_normal((5, 5))
    covariance = factor @ factor.T + 0.5 * np.eye(5)
    precision = np.linalg.inv(covariance)

    def log_probability(x):
        return -0.5 * np.einsum("ij,jk,ik->i", x, precision, x)

    mixes = {"emcee DESnookerMove alone": [(emcee.moves.DESnookerMove(), 1.0)],
             "corrected snooker alone": [(snooker_move(), 1.0)],
             "0.8 DE + 0.2 emcee snooker": [(emcee.moves.DEMove(), 0.8),
                                            (emcee.moves.DESnookerMove(), 0.2)],
             "0.8 DE + 0.2 corrected snooker (used)": [(emcee.moves.DEMove(), 0.8),
                                                       (snooker_move(), 0.2)]}
    lines = ["| moves | sampled / true variance, per coordinate |", "|---|---|"]
    for name, moves in mixes.items():
        sampler = emcee.EnsembleSampler(32, 5, log_probability, vectorize=True, moves=moves)
        sampler.random_state = np.random.RandomState(3).get_state()
        sampler.run_mcmc(rng.multivariate_normal(np.zeros(5), covariance, 32), steps)
        chain = sampler.get_chain(discard=2000, flat=True)
        ratio = np.diag(np.cov(chain.T)) / np.diag(covariance)
        lines.append(f"| {name} | " + ", ".join(f"{r:.3f}" for r in ratio) + " |")
    return "\n".join(lines) + (f"\n\n32 walkers x {steps} steps each, 2000 discarded; the "
                               "variance ratio of a correct sampler is 1 to about 1 %.")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--replicates", type=int, default=200)
    parser.add_argument("--noise-replicates", type=int, default=50)
    parser.add_argument("--only", nargs="+",
                        choices=("calibration", "speed", "snooker", "consistency"),
                        default=("calibration", "speed", "snooker", "consistency"))
    parser.add_argument("--consistency-replicates", type=int, default=100)
    parser.add_argument("--speed-worker", choices=("inline", "default"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.speed_worker:
        print(json.dumps(speed_worker(args.speed_worker == "inline")))
        return
    inline_dispatch()  # as `brdfjax fit` runs

    if "speed" in args.only:
        timing = speed()
        print(timing, flush=True)
        write_section("uncertainty-speed", f"""## Uncertainty: speed

On the bundled 716-point white-paint set (fit on 10/30/45/60 deg).

{timing}
""")
    if "snooker" in args.only:
        snooker = snooker_check()
        print(snooker, flush=True)
        write_section("uncertainty-snooker", f"""## Uncertainty: emcee's snooker move

`DESnookerMove` of emcee 3.1.6 against the corrected move `brdfjax.uncertainty.mcmc` uses, on a
5-D Gaussian with known covariance (see `brdfjax/uncertainty/mcmc.py` for what differs).

{snooker}
""")
    if "consistency" in args.only:
        print(f"consistency: {args.consistency_replicates} replicates", flush=True)
        table = consistency(args.consistency_replicates)
        print(table, flush=True)
        write_section("uncertainty-consistency", f"""## Uncertainty: which interval, about which estimate

The fit minimises Eq. (6), which weights every point alike; the posterior's likelihood
weights each point by 1 / its variance (the file's sigma, or the inferred relative +
absolute noise). The two estimates differ, and the fit can lie outside the posterior's
interval. Which interval is calibrated, about which estimate? Synthetic white paint (the
paper's parameters and geometry, 2.5 % relative noise, a new draw per replicate, seeds
7000 on), fit on 10/30/45/60 deg, 21/52 deg held out; the share of replicates whose 95 %
interval holds the true parameter. "Eq. (6), noise alike": the textbook least-squares
interval about the fit, ``s^2 (J^T J)^-1``; "Eq. (6), sandwich": the same about the fit
with each point's own squared residual (White's estimator), valid whatever the noise's
shape.

{table}
""")
    if "calibration" in args.only:
        print(f"calibration, given sigma: {args.replicates} replicates", flush=True)
        given = coverage_table(calibrate(args.replicates, True, offset=1000))
        print(given, flush=True)
        inferred = ""
        if args.noise_replicates:
            print(f"calibration, inferred noise: {args.noise_replicates} replicates", flush=True)
            inferred = ("\n\n### With the noise inferred (sigma column dropped, "
                        f"{args.noise_replicates} replicates)\n\n"
                        + coverage_table(calibrate(args.noise_replicates, False, offset=5000)))
            print(inferred, flush=True)
        write_section("uncertainty", f"""## Uncertainty: calibration

Synthetic white paint (the paper's parameters and geometry; 2.5 % relative noise, sigma
given), a new noise draw per replicate; fit (hybrid) on 10/30/45/60 deg (716 points),
21/52 deg held out. Laplace (`brdfjax.laplace_approximation`) and emcee
(`brdfjax.sample_posterior`, run until the chain is longer than 50 autocorrelation times);
the share of replicates whose interval contains the true parameter. Target: emcee's 95 %
intervals contain the truth in 90-99 % of replicates for every parameter; the true curves
lie inside the 95 % bands at 90-99 % of their points (181 points per incidence, pointwise
bands, averaged over replicates).

### With sigma given ({args.replicates} replicates)

{given}{inferred}
""")


if __name__ == "__main__":
    main()
