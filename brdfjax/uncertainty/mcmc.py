"""Sampling the posterior (`brdfjax.uncertainty.likelihood`) with emcee.

emcee 3.1.6's ``DESnookerMove`` samples the wrong distribution: it projects on
``delta / sqrt(|delta|)`` instead of the unit vector and weights the acceptance by
``(|q - z| / |x - z|)^((d - 1) / 2)`` instead of ``^(d - 1)`` (the snooker update of ter
Braak and Vrugt, Statistics and Computing 18, 435, 2008). On a 5-D Gaussian it gives
variances 25 % too small alone and 3-5 % too small in the 0.8 DE / 0.2 snooker mix, where the
corrected move gives them to 1 % (``benchmarks/bench_uncertainty.py`` repeats the check).
`sample_posterior` uses that mix with the corrected move, `snooker_move`. emcee's main branch
fixed the move in January 2025 (PR #531), in no release yet: `snooker_move` hands over to
emcee's own once the installed emcee is a final release after 3.1.6.

emcee (and h5py) are imported only inside `sample_posterior`, so importing this module
stays light.
"""

from __future__ import annotations

import time
import warnings

import jax
import numpy as np

from brdfjax.data.measurements import Measurements
from brdfjax.models import Model
from brdfjax.models.bounds import Bounds
from brdfjax.optional import require
from brdfjax.uncertainty.laplace import laplace_approximation
from brdfjax.uncertainty.likelihood import (
    Posterior,
    draw_inside,
    log_posterior_batch,
    physical,
    training_setup,
)
from brdfjax.uncertainty.result import (
    UncertaintyResult,
    UncertaintyWarning,
    chi2_warning,
    fitted_of,
    noise_summary,
    summarize,
)

# emcee's convergence rule: trust the chain once it is longer than 50 integrated
# autocorrelation times (emcee's ``integrated_time(tol=50)``); burn-in 2 tau, thinning tau/2
# (the emcee documentation's "Autocorrelation analysis" tutorial).
AUTOCORRELATION_LENGTHS = 50


def emcee_snooker_is_fixed(version: str) -> bool:
    """Whether emcee ``version`` carries the snooker fix: a final release after 3.1.6.

    Development and pre-release versions count as unfixed (the corrected move is right
    either way; emcee's own is used only where it is known to be).
    """
    import re

    release = re.fullmatch(r"(\d+)\.(\d+)(?:\.(\d+))?(?:\.post\d+)?", version)
    return release is not None and tuple(int(p or 0) for p in release.groups()) > (3, 1, 6)


def snooker_move(gamma: float = 1.7):
    """ter Braak and Vrugt's (2008) snooker update, as emcee's ``DESnookerMove`` should be.

    The ensemble is split in two halves, as for emcee's DE move. For each walker ``x`` of one
    half: pick three distinct walkers ``z, z1, z2`` of the other half (a uniformly random
    ordered triple, so the roles are symmetric), move along the unit vector
    ``u = (x - z) / |x - z|`` by ``gamma u.(z1 - z2)``, and accept with the extra factor
    ``(|q - z| / |x - z|)^(d - 1)``. emcee's move draws the three from three quarters of the
    ensemble instead, which costs two more log-probability calls per step. Vectorised over
    the walkers; ``gamma`` 1.7 as ter Braak and Vrugt recommend. See the module docstring for
    what emcee 3.1.6 does wrong. With an emcee release that carries the fix
    (`emcee_snooker_is_fixed`), emcee's own ``DESnookerMove``.
    """
    import emcee
    from emcee.moves.red_blue import RedBlueMove

    if emcee_snooker_is_fixed(emcee.__version__):
        return emcee.moves.DESnookerMove(gammas=gamma)

    class SnookerMove(RedBlueMove):
        def get_proposal(self, s, c, random):
            others = np.concatenate(c, axis=0)
            count, ndim = s.shape
            triple = np.argsort(random.random_sample((count, len(others))), axis=1)[:, :3]
            z, z1, z2 = (others[triple[:, k]] for k in range(3))
            delta = s - z
            norm = np.sqrt(np.einsum("ij,ij->i", delta, delta))
            unit = delta / norm[:, None]
            step = gamma * np.einsum("ij,ij->i", unit, z1 - z2)
            # q - z = (norm + step) u, so |q - z| / |x - z| = |1 + step / norm|.
            return s + unit * step[:, None], (ndim - 1.0) * np.log(np.abs(1.0 + step / norm))

    return SnookerMove()


def ensemble_sampler(walkers: int, ndim: int, log_probability, **options):
    """emcee's ``EnsembleSampler(vectorize=True)``, taking the log-probability array as it is.

    For a vectorised log-probability emcee looks for blobs and converts the result walker by
    walker in Python, about 50 us per call with 16 walkers, 10 % of a run here. This
    subclass checks the coordinates and the result as emcee does (no infinite or NaN
    coordinate, no NaN log-probability) and returns the array; it supports no blobs.
    """
    import emcee

    class VectorizedSampler(emcee.EnsembleSampler):
        def compute_log_prob(self, coords):
            if not np.all(np.isfinite(coords)):
                raise ValueError("a walker has an infinite or NaN coordinate")
            log_prob = np.array(self.log_prob_fn(coords), dtype=float)  # emcee writes to it
            if np.any(np.isnan(log_prob)):
                raise ValueError("the log-probability is NaN")
            return log_prob, None

    return VectorizedSampler(walkers, ndim, log_probability, vectorize=True, **options)

def _starting_walkers(start: UncertaintyResult, post: Posterior, walkers: int,
                      rng: np.random.Generator) -> np.ndarray:
    """Walkers drawn from the Laplace Gaussian, each spread capped at a quarter of the box.

    The cap keeps a flat or unidentified direction (an absolute noise scale of zero, a
    singular curvature) from throwing walkers across the whole prior.
    """
    lower, upper = np.asarray(post.lower), np.asarray(post.upper)
    covariance = np.asarray(start.center_covariance, dtype=float)
    scale = np.sqrt(np.clip(np.diag(covariance), 0, None))
    cap = np.minimum(1.0, (upper - lower) / 4 / np.where(scale > 0, scale, np.inf))
    return draw_inside(rng, np.clip(start.center, lower, upper),
                       covariance * np.outer(cap, cap), lower, upper, walkers)


def inline_dispatch() -> None:
    """Run JAX's CPU computations on the calling thread instead of handing them to a worker.

    emcee calls the log-posterior twice per step, each call about 0.1 ms of work. With JAX's
    default asynchronous dispatch every call also waits for a worker thread and back; on
    this 2-core machine that doubled the time per call inside an emcee run (325 against
    164 us, exploratory) and made 32 walkers x 5000 steps take 6-7 s instead of about 4 s
    (``BENCHMARKS.md``, section uncertainty-speed). The setting is process-wide and takes
    effect only before JAX starts its backend (later it changes nothing); ``brdfjax fit``
    makes it. Not for `brdfjax.fit_batch` on several devices, which needs to dispatch to
    every device before it waits for any.
    """
    jax.config.update("jax_cpu_enable_async_dispatch", False)


def autocorrelation_time(chain) -> np.ndarray:
    """emcee's integrated autocorrelation time of each coordinate of a chain (steps, walkers, D).

    Computed with ``tol=0``, so that it never raises or logs: callers judge the length.
    """
    from emcee.autocorr import integrated_time

    return integrated_time(np.asarray(chain), tol=0)


def require_emcee():
    """emcee, or `brdfjax.optional.MissingDependency` saying how to install it."""
    return require("emcee", "mcmc", "MCMC sampling (--uncertainty mcmc)")


def check_walkers(walkers: int, coordinates: int) -> None:
    """Refuse fewer walkers than emcee's stretch move needs: twice the sampled
    ``coordinates`` (the model's parameters, plus the two noise scales of
    `brdfjax.uncertainty.likelihood.NOISE_NAMES` where the data give no sigma)."""
    if walkers < 2 * coordinates:
        raise ValueError(f"emcee needs at least {2 * coordinates} walkers for {coordinates} "
                         f"sampled coordinates, got {walkers}")


def sample_posterior(data: Measurements, fit, *, walkers: int = 32, max_steps: int = 20000,
                     check_every: int = 250, stop_when_converged: bool = True, seed: int = 0,
                     chain_path=None, progress: bool = True,
                     start: UncertaintyResult | None = None, bounds: Bounds | None = None,
                     model: str | Model | None = None,
                     validate_incidences_deg=None) -> UncertaintyResult:
    """Sample the posterior with emcee until the chain is longer than 50 autocorrelation times.

    Walkers start from the Laplace approximation at the fit's optimum (`start`, computed if
    not given). The sampler (``vectorize=True``, moves 0.8 differential evolution and 0.2
    corrected snooker) runs ``check_every`` steps at a time; after each chunk the integrated
    autocorrelation time tau is estimated, and sampling stops once the chain is longer than
    50 max(tau), or at ``max_steps`` with status ``not_converged`` and an
    `UncertaintyWarning`. Burn-in is 2 max(tau), thinning tau/2 (min over coordinates).

    Args:
        data: all measurements.
        fit: a `brdfjax.fitting.fit.FitResult`, or parameters (P,) (see `training_setup`).
        walkers: ensemble size (at least twice the number of sampled coordinates).
        max_steps: cap on the chain length (a resumed chain counts its stored steps).
        check_every: steps between convergence checks.
        stop_when_converged: False runs exactly ``max_steps`` steps (benchmarks).
        seed: seeds the starting walkers and emcee's random state; the same seed gives the
            same chain. A resumed chain continues the random state saved in its file.
        chain_path: an HDF5 file (emcee's ``HDFBackend``) that keeps the chain; if it
            already holds a chain of the same shape, sampling resumes from its last step.
        progress: show a tqdm progress bar.
        start: a Laplace `UncertaintyResult` of the same data to start the walkers from.
        bounds, model, validate_incidences_deg: see `training_setup`.

    Returns:
        An `UncertaintyResult` with method ``mcmc``.
    """
    from tqdm import tqdm

    emcee = require_emcee()
    post, vector = training_setup(data, fit, bounds, model, validate_incidences_deg)
    check_walkers(walkers, post.ndim)
    if max_steps < 1 or check_every < 1:
        raise ValueError("max_steps and check_every must be positive")
    tic = time.perf_counter()
    backend = None if chain_path is None else emcee.backends.HDFBackend(str(chain_path))
    resume = backend is not None and backend.initialized and backend.iteration > 0
    if resume and backend.shape != (walkers, post.ndim):
        raise ValueError(f"{chain_path} holds a chain of {backend.shape[0]} walkers x "
                         f"{backend.shape[1]} coordinates, not {walkers} x {post.ndim}; "
                         "use another file or the same settings")
    if backend is not None and not resume:
        backend.reset(walkers, post.ndim)

    on_device = jax.device_put(post)  # once, not at every one of emcee's calls

    def log_probability(x):
        return np.asarray(log_posterior_batch(x, on_device))

    sampler = ensemble_sampler(walkers, post.ndim, log_probability, backend=backend,
                               moves=[(emcee.moves.DEMove(), 0.8), (snooker_move(), 0.2)])
    if resume:
        state = sampler.get_last_sample()
    else:
        if start is None:
            start = laplace_approximation(data, fit, bounds=post.bounds, model=post.model,
                                          validate_incidences_deg=validate_incidences_deg, draws=0)
        rng = np.random.default_rng(seed)
        state = _starting_walkers(start, post, walkers, rng)
        sampler.random_state = np.random.RandomState(rng.integers(2**32)).get_state()

    # A resumed chain may be long enough already.
    tau = autocorrelation_time(sampler.get_chain()) if resume else np.full(post.ndim, np.nan)
    with tqdm(total=max_steps, initial=sampler.iteration, disable=not progress,
              desc="emcee", unit="step") as bar:
        while sampler.iteration < max_steps and not (
                stop_when_converged and _converged(tau, sampler.iteration)):
            chunk = min(check_every if stop_when_converged else max_steps,
                        max_steps - sampler.iteration)
            for step in sampler.sample(state, iterations=chunk):
                bar.update(1)
            state = step
            tau = autocorrelation_time(sampler.get_chain())
            bar.set_postfix(tau=f"{np.max(tau):.1f}")
    timings = {"sampling": time.perf_counter() - tic}
    return _mcmc_result(sampler, post, tau, chain_path, timings, fitted_of(fit), vector)


def _converged(tau, steps: int) -> bool:
    return bool(np.all(np.isfinite(tau)) and steps > AUTOCORRELATION_LENGTHS * np.max(tau))


def _mcmc_result(sampler, post: Posterior, tau, chain_path, timings,
                 fitted: dict, vector=None) -> UncertaintyResult:
    """Summaries, diagnostics and warnings of a finished emcee run (``vector``: the fit it
    started from, whose parts of zero weight a sum of models names)."""
    steps, walkers = int(sampler.iteration), int(sampler.nwalkers)  # numpy ints from HDF5
    finite = np.all(np.isfinite(tau))
    burn_in = min(int(2 * np.max(tau)), steps // 2) if finite else steps // 2
    thin = max(1, int(0.5 * np.min(tau))) if finite else 1
    flat = sampler.get_chain(discard=burn_in, thin=thin, flat=True)
    samples = physical(flat, post)
    stats = summarize(samples)
    messages = []
    status = "converged"
    reasons = []
    if not _converged(tau, steps):
        status = "not_converged"
        reasons.append(f"{steps / np.max(tau):.3g} autocorrelation times, fewer than "
                       f"{AUTOCORRELATION_LENGTHS}")
        messages.append(
            f"the chain did not converge: {steps} steps is "
            f"{steps / np.max(tau):.3g} autocorrelation times (max tau {np.max(tau):.3g}), "
            f"fewer than {AUTOCORRELATION_LENGTHS}; the intervals are unreliable. Run longer "
            "(raise max_steps, the CLI's --mcmc-steps"
            + (f"; the chain in {chain_path} resumes)" if chain_path else ")"))
    warning = chi2_warning(np.median(flat, axis=0), post)
    if warning:
        messages.append(warning)
    if vector is not None:  # a sum of models with a part switched off
        messages += post.model.idle_parts(vector, post.bounds)
    for text in messages:
        warnings.warn(text, UncertaintyWarning, stacklevel=3)
    noise = noise_summary(post)
    if post.ndim > post.size:
        scales = summarize(flat[:, post.size:])
        noise = noise_summary(post, scales["median"], scales["ci95"])
    ess = walkers * (steps - burn_in) / tau
    acceptance = np.asarray(sampler.acceptance_fraction)
    diagnostics = {
        "walkers": walkers, "steps": steps, "burn_in": burn_in, "thin": thin,
        "samples": int(samples.shape[0]),
        "tau": dict(zip(post.names, map(float, tau))),
        "effective_samples": dict(zip(post.names, map(float, ess))),
        "acceptance_fraction": float(np.mean(acceptance)),
        "acceptance_fraction_min": float(np.min(acceptance)),
        "steps_per_tau": float(steps / np.max(tau)),
        "chain_path": None if chain_path is None else str(chain_path),
        "reasons": reasons,
    }
    return UncertaintyResult(
        method="mcmc", status=status, warnings=messages, median=stats["median"],
        std=stats["std"], ci68=stats["ci68"], ci95=stats["ci95"],
        covariance=np.atleast_2d(np.cov(samples.T)),
        correlation=np.atleast_2d(np.corrcoef(flat[:, :post.size].T)), samples=samples, noise=noise,
        center=np.mean(flat, axis=0), center_covariance=np.cov(flat.T),
        diagnostics=diagnostics, timings=timings, chain=sampler.get_chain(),
        bounds=post.bounds, model=post.model, **fitted)

