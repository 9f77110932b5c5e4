"""Uncertainty benchmarks: calibration over synthetic replicates, speed, and the snooker move.

    .venv/bin/python benchmarks/bench_uncertainty.py [--replicates 200] [--noise-replicates 50]
        [--lmfit-replicates 20] [--only calibration speed snooker consistency lmfit]

Calibration: white-paint replicates (the paper's parameters and geometry, 2.5 % relative
noise with its sigma given, a new noise draw per replicate; fit on 10/30/45/60 deg = 716
points, 21/52 deg held out). Each is fitted (hybrid), then Laplace and emcee (run until 50
autocorrelation times) give 68 % and 95 % intervals; the table counts how often they
contain the true parameter, and how many points of the true curves (all six incidences,
held-out ones included) lie inside the 95 % bands. A second, smaller set drops sigma, so
that the noise scales are inferred. Speed: Laplace warm, and emcee 32 walkers x 5000 steps
warm, on the bundled 716-point set. Last, the check behind the corrected snooker move
(`brdfjax.uncertainty.mcmc`): emcee's ``DESnookerMove`` against the corrected one on a 5-D
Gaussian. Then lmfit's ``Minimizer.emcee`` beside brdfjax's Laplace and emcee, from the same
fit with the same walkers and steps (`lmfit_section`). Sections of BENCHMARKS.md:
``uncertainty`` (calibration), ``uncertainty-speed``, ``uncertainty-snooker``,
``uncertainty-consistency``, ``uncertainty-lmfit``; ``--only`` runs some of them.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time
import timeit
import warnings
from functools import partial
from pathlib import Path
from statistics import NormalDist

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import numpy as np

from benchmarks.report import real_data, worker_json, write_section
from brdfjax.data.formats import load
from brdfjax.data.synthetic import paper_sample
from brdfjax.fitting.fit import fit
from brdfjax.models.paper import PAPER_SAMPLES, PARAMETER_NAMES, projected_brdf
from brdfjax.plot import curve_angles
from brdfjax.uncertainty.bands import curve_bands
from brdfjax.uncertainty.laplace import laplace_approximation
from brdfjax.uncertainty.likelihood import ABSOLUTE_NOISE_RANGE, physical, training_setup
from brdfjax.uncertainty.mcmc import autocorrelation_time, inline_dispatch, sample_posterior
from brdfjax.uncertainty.result import UncertaintyWarning, summarize

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

# lmfit's emcee beside brdfjax's (section uncertainty-lmfit). Both samplers run 32 walkers
# (brdfjax's default) x 2000 steps, more than brdfjax's white-paint chains need to converge
# (1000-1750 steps, section uncertainty). lmfit's burn and thin are its user's to choose:
# 500 and 10, a quarter of the chain and about a quarter of its autocorrelation time (about
# 45 steps with emcee's stretch move on the white paint, exploratory); brdfjax's sampler
# takes 2 tau and tau / 2 itself.
WALKERS, STEPS = 32, 2000
LMFIT_BURN, LMFIT_THIN = 500, 10
METHODS = ("Laplace", "brdfjax emcee", "lmfit emcee")
REAL_RUNS = (("RT-300S NiTE on steel A", "uaz-loft-rt300s",
              "raw/NiTE_on_steel_v1o0A_20250915.xls", {"in_plane": True}),
             ("NIST PTFE, 633 nm", "nist-germer-ptfe", "PTFE.data.csv", {"wavelength_nm": 633}))


def lmfit_emcee(post, start, seed: int) -> dict:
    """lmfit's ``Minimizer.emcee`` on the posterior ``post`` (`training_setup`), its walkers
    started as lmfit starts them: a ball of relative radius 1e-4 about the fit ``start`` (P,).

    The lmfit parameters are the fit's unit-cube coordinates ``z0 .. z{P-1}`` (min 0, max 1),
    so lmfit's uniform prior within the bounds is brdfjax's prior. The residual is brdfjax's
    projected model on the training points, jitted with them as constants and compiled
    before the timing, called from NumPy one walker at a time: ``(y - m) / sigma`` with
    ``is_weighted=True`` where the data give sigma (the likelihood is then brdfjax's), else
    ``y - m`` with ``is_weighted=False``, where lmfit samples one absolute noise scale
    ``__lnsigma``, added by hand as lmfit's documentation does: started at the fit's RMS
    residual and bounded as brdfjax's prior on its absolute scale.

    Returns:
        `method_summary`'s fields, and ``call``: seconds per residual call.
    """
    import jax
    import lmfit

    from brdfjax.models.bounds import from_unit, to_unit
    from brdfjax.models.paper import evaluate_projected

    model = jax.jit(lambda z: evaluate_projected(from_unit(z, post.bounds), post.scene,
                                                 post.model))
    target = np.asarray(post.target)
    scale = 1.0 if post.sigma is None else np.asarray(post.sigma)
    names = [f"z{k}" for k in range(post.size)]

    def residual(params):
        return (target - np.asarray(model(np.array([params[n].value for n in names])))) / scale

    params = lmfit.Parameters()
    for name, value in zip(names, np.asarray(to_unit(np.asarray(start), post.bounds))):
        params.add(name, value=float(value), min=0.0, max=1.0)
    residual(params)  # compiles the model, outside the timing
    call = min(timeit.repeat(partial(residual, params), number=100, repeat=3)) / 100
    if post.sigma is None:
        peak = float(np.max(np.abs(target)))
        params.add("__lnsigma", value=np.log(np.sqrt(np.mean(residual(params) ** 2))),
                   min=np.log(ABSOLUTE_NOISE_RANGE[0] * peak),
                   max=np.log(ABSOLUTE_NOISE_RANGE[1] * peak))
    tic = time.perf_counter()
    minimizer = lmfit.Minimizer(residual, params)
    out = minimizer.emcee(steps=STEPS, nwalkers=WALKERS, burn=LMFIT_BURN, thin=LMFIT_THIN,
                          is_weighted=post.sigma is not None, seed=seed, progress=False)
    seconds = time.perf_counter() - tic
    tau = float(np.max(autocorrelation_time(minimizer.sampler.get_chain())))
    flat = out.chain.reshape(-1, out.chain.shape[-1])
    stats = summarize(physical(flat, post))
    noise = ("given sigma" if post.sigma is not None else
             f"one absolute scale {np.exp(np.median(flat[:, -1])):.3g}")
    return {"median": stats["median"], "ci95": stats["ci95"], "seconds": seconds, "tau": tau,
            "effective": WALKERS * (STEPS - LMFIT_BURN) / tau, "noise": noise, "call": call,
            "status": "converged" if STEPS > 50 * tau else "not_converged"}


def method_summary(estimate, seconds: float) -> dict:
    """Median, 95 % interval, wall seconds, autocorrelation time, effective samples
    (walkers x (steps - burn-in) / max tau), noise and status of a brdfjax estimate."""
    noise = estimate.noise
    if "sigma_rel" in noise:
        noise = (f"relative {noise['sigma_rel']['median']:.3g}, "
                 f"absolute {noise['sigma_abs']['median']:.3g}")
    else:
        noise = noise["model"]
    summary = {"median": estimate.median, "ci95": estimate.ci95, "seconds": seconds,
               "tau": float("nan"), "effective": float("nan"), "noise": noise,
               "status": estimate.status}
    if estimate.method == "mcmc":
        summary["tau"] = max(estimate.diagnostics["tau"].values())
        summary["effective"] = min(estimate.diagnostics["effective_samples"].values())
    return summary


def three_posteriors(data, held_out, seed: int) -> dict:
    """Fit ``data`` (hybrid, ``held_out`` incidences left out), then from that one fit:
    Laplace, brdfjax's emcee and lmfit's emcee, each timed alone and warm; ``{method:
    summary}``. brdfjax's emcee runs exactly `STEPS`, starting from its own Laplace (inside
    its time)."""
    result = fit(data, validate_incidences_deg=held_out, seed=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UncertaintyWarning)
        # Compiles brdfjax's functions for these shapes (once per size), outside the timing.
        sample_posterior(data, result, walkers=WALKERS, max_steps=10, progress=False)
        tic = time.perf_counter()
        laplace = laplace_approximation(data, result, seed=seed)
        laplace_seconds = time.perf_counter() - tic
        tic = time.perf_counter()
        mcmc = sample_posterior(data, result, walkers=WALKERS, max_steps=STEPS,
                                stop_when_converged=False, seed=seed, progress=False)
        mcmc_seconds = time.perf_counter() - tic
    post, start = training_setup(data, result)
    return {"Laplace": method_summary(laplace, laplace_seconds),
            "brdfjax emcee": method_summary(mcmc, mcmc_seconds),
            "lmfit emcee": lmfit_emcee(post, start, seed)}


def lmfit_coverage(replicates: int, offset: int = 9000) -> str:
    """The three methods on white-paint replicates (sigma given): 95 % coverage of the truth
    and warm speed."""
    hits = {method: np.zeros(5) for method in METHODS}
    runs = []
    for k in range(replicates):
        run = three_posteriors(paper_sample("white_paint", seed=offset + k), HELD_OUT, seed=k)
        for method in METHODS:
            hits[method] += inside(run[method]["ci95"], TRUTH)
        runs.append(run)
        print(f"  {k + 1}/{replicates}: " + ", ".join(
            f"{m} {run[m]['seconds']:.2f} s" for m in METHODS), flush=True)
    lines = ["| method | 95 % coverage: " + " | ".join(PARAMETER_NAMES)
             + " | wall, s (median) | max tau, steps (median) | chains longer than 50 tau "
             "| effective samples per s (median) |", "|---|" + "---|" * 9]
    for method in METHODS:
        seconds = np.median([run[method]["seconds"] for run in runs])
        tau = np.median([run[method]["tau"] for run in runs])
        rate = np.median([run[method]["effective"] / run[method]["seconds"] for run in runs])
        converged = sum(run[method]["status"] == "converged" for run in runs)
        lines.append(f"| {method} | " + " | ".join(f"{100 * h / replicates:.0f} %"
                                                   for h in hits[method])
                     + (f" | {1e3 * seconds:.1f} ms | - | - | - |" if method == "Laplace" else
                        f" | {seconds:.2f} | {tau:.0f} | {converged}/{replicates} "
                        f"| {rate:.0f} |"))
    ours, theirs = (np.median([run[m]["seconds"] for run in runs])
                    for m in ("brdfjax emcee", "lmfit emcee"))
    call = np.median([run["lmfit emcee"]["call"] for run in runs])
    se = 100 * np.sqrt(0.95 * 0.05 / replicates)
    return ("\n".join(lines) + f"\n\n{replicates} replicates (seeds {offset}-"
            f"{offset + replicates - 1}); binomial standard error of a 95 % coverage: "
            f"{se:.1f} %. lmfit's emcee took {theirs / ours:.1f}x brdfjax's for the "
            f"same walkers and steps; its residual costs {1e6 * call:.0f} us a call "
            f"(brdfjax's jitted model called from NumPy), {WALKERS * STEPS} calls: "
            f"{WALKERS * STEPS * call:.1f} s of its {theirs:.1f} s.")


def lmfit_real() -> str:
    """The three methods on real runs (every incidence, noise inferred): medians and 95 %
    interval widths side by side, and where lmfit's emcee disagrees with brdfjax's."""
    lines = ["| run | parameter | " + " | ".join(f"{m}: median (95 % width)" for m in METHODS)
             + " |", "|---|---|" + "---|" * 3]
    notes = []
    for label, dataset, name, options in REAL_RUNS:
        data = load(real_data(dataset) / name, **options)
        run = three_posteriors(data, None, seed=0)
        widths = {m: np.diff(run[m]["ci95"], axis=1)[:, 0] for m in METHODS}
        for k, parameter in enumerate(PARAMETER_NAMES):
            lines.append(f"| {label} | {parameter} | " + " | ".join(
                f"{run[m]['median'][k]:.4g} ({widths[m][k]:.3g})" for m in METHODS) + " |")
        for key, text in (("noise", "noise"), ("status", "status"),
                          ("seconds", "wall, s"), ("tau", "max tau, steps")):
            lines.append(f"| {label} | {text} | " + " | ".join(
                f"{run[m][key]:.3g}" if isinstance(run[m][key], float) else str(run[m][key])
                for m in METHODS) + " |")
        ours, theirs = run["brdfjax emcee"], run["lmfit emcee"]
        found = []
        for k, parameter in enumerate(PARAMETER_NAMES):
            ratio = widths["lmfit emcee"][k] / widths["brdfjax emcee"][k]
            if not ours["ci95"][k, 0] <= theirs["median"][k] <= ours["ci95"][k, 1]:
                found.append(f"{parameter}'s lmfit median outside brdfjax emcee's 95 % interval")
            if not 0.5 <= ratio <= 2.0:
                found.append(f"{parameter}'s lmfit interval {ratio:.2g}x as wide")
        notes.append(f"{label} ({len(data)} points): "
                     + ("; ".join(found) if found else "lmfit's medians lie inside brdfjax "
                        "emcee's 95 % intervals, and its widths within a factor 2") + ".")
    return "\n".join(lines) + "\n\n" + "\n\n".join(notes)


def lmfit_section(replicates: int) -> str:
    """Section uncertainty-lmfit: the synthetic coverage table and the real runs' table."""
    from importlib.metadata import version

    print(f"lmfit: {replicates} white-paint replicates", flush=True)
    coverage = lmfit_coverage(replicates)
    print(coverage, flush=True)
    real = lmfit_real()
    print(real, flush=True)
    return f"""## Uncertainty against lmfit's emcee

brdfjax's Laplace approximation (`brdfjax.laplace_approximation`) and emcee
(`brdfjax.sample_posterior`: differential-evolution and corrected snooker moves, the
log-posterior of all walkers in one jitted call, started from Laplace) beside lmfit
{version("lmfit")}'s `Minimizer.emcee` (emcee's default stretch move, one residual call per
walker, `workers=1`, its default), all three from the same hybrid fit, in one process.
Both samplers run {WALKERS} walkers x {STEPS} steps; lmfit's walkers start as lmfit starts
them, in a ball of relative radius 1e-4 about the fit, with `burn={LMFIT_BURN}`,
`thin={LMFIT_THIN}`; brdfjax's sampler discards 2 tau and thins by tau / 2. lmfit's
parameters are the fit's unit-cube coordinates (log10 of kb, kr, a, kd, asinh b, bounded
0..1), so its uniform prior is brdfjax's. Its objective is brdfjax's float64 projected
model, jitted with the data as constants and compiled before any timing, called from NumPy:
the numbers then differ by the sampler and the likelihood, not by a transcription of the
model. Wall times are warm and exclude the fit.

### Synthetic white paint, sigma given

The paper's parameters and geometry, 2.5 % relative noise, sigma given, a new draw per
replicate; fit on 10/30/45/60 deg (716 points), 21/52 deg held out. lmfit's residual is
`(y - m) / sigma` with `is_weighted=True`: its likelihood is brdfjax's, and the three
estimate the same posterior. Target: 95 % intervals hold the truth in 90-99 % of replicates.

{coverage}

### Real runs, noise inferred

Every incidence fitted (model five). The files carry no sigma: brdfjax infers a relative and
an absolute noise scale, `v = (s_rel m)^2 + s_abs^2`; lmfit's residual is `y - m` with
`is_weighted=False`, so lmfit samples one absolute scale `__lnsigma` (every point alike).
The two likelihoods differ where the relative part of the noise dominates: lmfit's weights
the brightest points (the specular peak) most, brdfjax's each point by its own scale.
"noise" gives the posterior medians of the scales on the projected BRDF.

{real}
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--replicates", type=int, default=200)
    parser.add_argument("--noise-replicates", type=int, default=50)
    parser.add_argument("--only", nargs="+",
                        choices=("calibration", "speed", "snooker", "consistency", "lmfit"),
                        default=("calibration", "speed", "snooker", "consistency", "lmfit"))
    parser.add_argument("--consistency-replicates", type=int, default=100)
    parser.add_argument("--lmfit-replicates", type=int, default=20)
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
    if "lmfit" in args.only:
        write_section("uncertainty-lmfit", lmfit_section(args.lmfit_replicates))
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
