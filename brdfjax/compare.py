"""Run time against error: brdfjax's methods beside the tools a user would pick instead.

Every method fits the same model (by default Eq. 5; any model of `brdfjax.models`),
evaluated by the same compiled function, to the same data, minimising the same E of
Eq. (6) over the same box (the model's `brdfjax.models.bounds.default_bounds`), in one process:

- ``brdfjax hybrid``: genetic search, then Levenberg-Marquardt (the default);
- ``brdfjax ga``: the genetic search alone;
- ``brdfjax lm``: Levenberg-Marquardt alone from random points of the box;
- ``scipy vp``: what a careful SciPy user writes (`scipy_vp`):
  ``differential_evolution`` over the model's nonlinear parameters only, the linear
  ones solved exactly for each candidate (variable projection), then ``least_squares``
  on every parameter with the exact Jacobian (``jax.jacfwd``). The headline peer.
- ``scipy de+ls (naive)``: ``differential_evolution`` over every parameter, then
  ``least_squares`` with a finite-difference Jacobian (`scipy_de_ls`);
- ``pygad + ls``: pygad's genetic algorithm, then the same finite-difference
  ``least_squares`` (`pygad_fit`), if pygad is installed;
- ``lmfit de+ls``: what a physicist writes with lmfit (`lmfit_fit`): ``lmfit.minimize``
  with ``method="differential_evolution"`` over every parameter, then
  ``method="least_squares"`` from its result, if lmfit is installed.

Stopping rules (`TOLERANCES`): brdfjax's genetic search stops after ``max_generations``
(40) or when no island's best E has improved by a relative 1e-6 for 15 generations (a model
with one searched parameter, GGX or Beckmann, is scored once on a 128-point grid); its LM
polish (optimistix Levenberg-Marquardt, float64) stops at rtol = atol = 1e-10 or after
1000 steps (`brdfjax.fitting.polish`). SciPy's ``differential_evolution`` runs with its defaults
(popsize 15 per dimension, maxiter 1000, tol 0.01, atol 0: it stops when the population's
standard deviation of E is below 0.01 of its mean), ``polish=False``; ``least_squares``
(``trf``, box (0, 1)) with xtol = ftol = gtol = 1e-12. pygad runs 200 generations of 64.
lmfit's differential evolution keeps lmfit's defaults (SciPy's settings with
``polish=True``, at most 2000 (P + 1) evaluations), its ``least_squares`` the same
tolerances as SciPy's.

The SciPy objectives are built and compiled apart from the optimisers
(`unit_objectives`), so a SciPy time is its optimiser's: `compare` and the benchmarks
build them once per data set and call each method once before timing (until issue 16
they were rebuilt, and recompiled, inside every timed call).
Timings are warm (each method runs once before it is timed). scipy and pygad are imported
only here.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from brdfjax.fitting.fit import fit
from brdfjax.fitting.objective import error, problem, residuals, solve_linear
from brdfjax.models import Model, get
from brdfjax.models.bounds import default_bounds, from_unit, to_unit

# Every method's stopping rule, as stated in the benchmark tables.
TOLERANCES = {
    "brdfjax hybrid": "GA: 40 generations, or 15 with no 1e-6 relative gain (one searched "
                      "parameter: a 128-point grid instead); LM: rtol = atol = 1e-10, "
                      "at most 1000 steps",
    "scipy vp": "DE defaults (popsize 15/dim, maxiter 1000, tol 0.01); least_squares trf, "
                "xtol = ftol = gtol = 1e-12, exact Jacobian",
    "scipy de+ls (naive)": "DE defaults (popsize 15/dim, maxiter 1000, tol 0.01); "
                           "least_squares trf, xtol = ftol = gtol = 1e-12, 2-point Jacobian",
    "pygad + ls": "200 generations x 64; least_squares as the naive peer",
    "lmfit de+ls": "lmfit's DE defaults (SciPy's, polish=True, at most 2000 (P + 1) "
                   "evaluations); lmfit least_squares trf, xtol = ftol = gtol = 1e-12, "
                   "2-point Jacobian",
}
LEAST_SQUARES_TOLERANCE = 1e-12


@dataclass
class MethodRun:
    """One method's outcome: best E, median warm wall time, and its model evaluations."""

    method: str
    error: float
    seconds: float
    evaluations: int
    note: str = ""


class Objectives(NamedTuple):
    """One data set's objectives as NumPy functions of unit-cube coordinates.

    Attributes:
        error: E of every parameter, z (P,) -> float (inf where not finite).
        errors: E of a population, (N, P) -> (N,).
        residuals: the residual vector, z (P,) -> (N,) (zero on padding points).
        jacobian: its exact Jacobian, z (P,) -> (N, P).
        projected_error: E with the linear parameters solved, of the nonlinear
            coordinates only, (Q,) -> float.
        solved: the full unit vector (P,) from the nonlinear coordinates (Q,), linear
            parameters solved.
        nonlinear: the positions of the nonlinear parameters in a parameter vector.
    """

    error: Callable
    errors: Callable
    residuals: Callable
    jacobian: Callable
    projected_error: Callable
    solved: Callable
    nonlinear: tuple


def _unit_error(z, prob, bounds):
    return error(from_unit(z, bounds), prob)


def _unit_errors(zs, prob, bounds):
    return jax.vmap(lambda z: _unit_error(z, prob, bounds))(zs)


def _unit_residuals(z, prob, bounds):
    return residuals(from_unit(z, bounds), prob)


def _fill(z_nonlinear, prob, bounds, nonlinear):
    """The full parameter vector from nonlinear unit coordinates, linear ones solved."""
    z = jnp.full(bounds.lower.shape, 0.5, dtype=prob.target.dtype).at[nonlinear].set(
        z_nonlinear)
    return solve_linear(from_unit(z, bounds), prob, bounds)


def _projected_error(z_nonlinear, prob, bounds, nonlinear):
    return _fill(z_nonlinear, prob, bounds, nonlinear)[1]


def _solved(z_nonlinear, prob, bounds, nonlinear):
    return to_unit(_fill(z_nonlinear, prob, bounds, nonlinear)[0], bounds)


_KERNELS = {"error": _unit_error, "errors": _unit_errors,
            "residuals": _unit_residuals, "jacobian": jax.jacfwd(_unit_residuals),
            "projected_error": _projected_error, "solved": _solved}
# Shared compiled code: the problem and bounds are arguments (traced), so every data set of
# one model and point count reuses it.
_SHARED = {name: jax.jit(kernel) for name, kernel in _KERNELS.items()}


def nonlinear_parameters(model: Model, bounds) -> tuple[int, ...]:
    """Positions of the parameters that `Model.assemble` leaves alone (the ones searched).

    Derived, not declared: two different coefficient vectors are assembled into the same
    parameter vector, and the entries that differ are set by the linear solve (kb and kd
    of the five-parameter model; ks, f0 and kd of GGX; rho0 and rhoc of RPV).
    """
    bounds = jax.tree.map(jnp.asarray, bounds)
    params = from_unit(jnp.full(model.size, 0.5), bounds)
    low, high = (jnp.asarray(x, dtype=float) for x in model.coefficient_bounds(bounds))
    # Unequal fractions: coefficients scaled together would keep a ratio such as GGX's f0.
    fractions = np.random.default_rng(0).uniform(0.1, 0.9, size=(2, low.size))
    first, second = (model.assemble(low + f * (high - low), params, bounds) for f in fractions)
    return tuple(int(k) for k in np.flatnonzero(np.asarray(first) == np.asarray(second)))


def unit_objectives(data, model: str | Model | None = None, bounds=None, *,
                    shared: bool = False) -> Objectives:
    """`Objectives` of ``data`` for ``model`` over ``bounds`` (the model's default box).

    Args:
        data, model, bounds: as `scipy_vp`.
        shared: False (the default, for timings) compiles each function for this data set
            (the data are constants of the compiled code: the fastest calls, about a
            second of compilation per data set, on a function's first call); True reuses
            code compiled once per model and point count, the data passed as arguments
            (about 25 us more per call: for accuracy tables over many data sets).
    """
    model = get(model)
    bounds = default_bounds(model) if bounds is None else bounds
    prob = problem(data, model)
    # Bounds as JAX arrays: captured as NumPy constants they cost 30 % more per call.
    bounds = jax.tree.map(jnp.asarray, bounds)
    nonlinear = nonlinear_parameters(model, bounds)
    index = jnp.asarray(nonlinear, dtype=int)
    if shared:
        compiled = {name: functools.partial(function, prob=prob, bounds=bounds)
                    for name, function in _SHARED.items()}
    else:
        compiled = {name: jax.jit(functools.partial(kernel, prob=prob, bounds=bounds))
                    for name, kernel in _KERNELS.items()}

    def finite(value):
        value = float(value)
        return value if np.isfinite(value) else np.inf

    return Objectives(
        error=lambda z: finite(compiled["error"](z)),
        errors=lambda zs: np.asarray(compiled["errors"](zs)),
        residuals=lambda z: np.asarray(compiled["residuals"](z)),
        jacobian=lambda z: np.asarray(compiled["jacobian"](z)),
        projected_error=lambda z: finite(compiled["projected_error"](z, nonlinear=index)),
        solved=lambda z: np.clip(np.asarray(compiled["solved"](z, nonlinear=index)), 0.0,
                                 1.0),
        nonlinear=nonlinear)


def _polish(objectives: Objectives, start, exact: bool):
    """``least_squares`` on the unit cube from ``start``; the better of it and the start."""
    from scipy.optimize import least_squares

    tol = LEAST_SQUARES_TOLERANCE
    ls = least_squares(objectives.residuals, start, jac=objectives.jacobian if exact else "2-point",
                       bounds=(0.0, 1.0), xtol=tol, ftol=tol, gtol=tol)
    e_start, e_end = objectives.error(start), objectives.error(ls.x)
    return (ls.x, e_end, ls) if e_end <= e_start else (np.asarray(start), e_start, ls)


def scipy_vp(data, model: str | Model | None = None, seed: int = 0, *, bounds=None,
             objectives: Objectives | None = None, popsize: int = 15, maxiter: int = 1000,
             tol: float = 0.01):
    """The careful SciPy peer: variable projection in differential evolution, then an
    exact-Jacobian ``least_squares`` on every parameter.

    DE searches the unit cube of the model's nonlinear parameters only
    (`nonlinear_parameters`: (kr, a, b) of the five-parameter model, alpha of GGX); each
    candidate's linear parameters are solved exactly by `brdfjax.fitting.objective.solve_linear`
    (jitted; the same bounded linear least squares the genetic search uses), the others
    held at the centre of their box (they do not enter E). ``least_squares`` (trf, box
    (0, 1), xtol = ftol = gtol = 1e-12) then polishes all parameters from the best
    candidate with the Jacobian of ``jax.jacfwd``. A model with no nonlinear parameter
    (Lambert) skips DE.

    Args:
        data: the measurements.
        model: a model name or `brdfjax.models.Model` (the five-parameter model if None).
        seed: DE's seed.
        bounds: the box (the model's default if None).
        objectives: `unit_objectives` of ``data`` built beforehand (built here if None).
        popsize, maxiter, tol: DE's settings (SciPy's defaults).

    Returns:
        (best unit-cube point (P,), E, model evaluations: DE's candidates, then one per
        residual call and P per Jacobian).
    """
    from scipy.optimize import differential_evolution

    model = get(model)
    objectives = unit_objectives(data, model, bounds) if objectives is None else objectives
    count = len(objectives.nonlinear)
    evaluations = 1
    if count:
        de = differential_evolution(objectives.projected_error, [(0.0, 1.0)] * count,
                                    seed=seed, polish=False, popsize=popsize,
                                    maxiter=maxiter, tol=tol)
        start, evaluations = objectives.solved(de.x), de.nfev
    else:
        start = objectives.solved(np.zeros(0))
    z, e, ls = _polish(objectives, start, exact=True)
    return z, e, int(evaluations + ls.nfev + ls.njev * model.size)


def scipy_de_ls(data, seed: int = 0, generous: bool = False, bounds=None, *,
                model: str | Model | None = None, objectives: Objectives | None = None):
    """The naive SciPy peer: differential_evolution on every parameter, then
    least_squares with a finite-difference Jacobian.

    Args:
        data: the measurements.
        seed: DE's seed.
        generous: larger population and more generations (popsize 40, maxiter 3000,
            tol 1e-10) instead of SciPy's defaults.
        bounds: the box (the model's default if None).
        model: a model name or `brdfjax.models.Model` (the five-parameter model if None).
        objectives: `unit_objectives` of ``data`` built beforehand (built here if None).

    Returns:
        (best unit-cube point, E, model evaluations).
    """
    from scipy.optimize import differential_evolution

    model = get(model)
    objectives = unit_objectives(data, model, bounds) if objectives is None else objectives
    settings = {"popsize": 40, "maxiter": 3000, "tol": 1e-10} if generous else {}
    de = differential_evolution(objectives.error, [(0.0, 1.0)] * model.size, seed=seed,
                                polish=False, **settings)
    z, e, ls = _polish(objectives, de.x, exact=False)
    return z, e, int(de.nfev + ls.nfev * (model.size + 1))


def pygad_fit(data, seed: int = 0, bounds=None, *, model: str | Model | None = None,
              objectives: Objectives | None = None, polish: bool = True):
    """pygad's GA on the unit cube (batched fitness), then the naive peer's
    finite-difference ``least_squares`` from its best member unless ``polish`` is False.

    Returns:
        (point, E, evaluations, E of the GA alone).
    """
    import pygad

    model = get(model)
    objectives = unit_objectives(data, model, bounds) if objectives is None else objectives
    generations, population = 200, 64

    def fitness(_, solutions, __):
        return -objectives.errors(np.atleast_2d(solutions))

    ga = pygad.GA(num_generations=generations, num_parents_mating=16, fitness_func=fitness,
                  fitness_batch_size=population, sol_per_pop=population,
                  num_genes=model.size, gene_space={"low": 0.0, "high": 1.0},
                  random_seed=seed, parent_selection_type="tournament",
                  crossover_type="uniform", mutation_type="random",
                  mutation_percent_genes=40, suppress_warnings=True)
    ga.run()
    z, score, _ = ga.best_solution()
    evaluations, e_ga = generations * population, float(-score)
    if not polish:
        return z, e_ga, evaluations, e_ga
    z, e, ls = _polish(objectives, np.clip(z, 0.0, 1.0), exact=False)
    return z, e, int(evaluations + ls.nfev * (model.size + 1)), e_ga


def lmfit_fit(data, seed: int = 0, bounds=None, *, model: str | Model | None = None,
              objectives: Objectives | None = None, polish: bool = True):
    """lmfit, as a physicist fits a curve: ``lmfit.minimize(method="differential_evolution")``
    over every parameter of the unit cube, then ``lmfit.minimize(method="least_squares")``
    (finite-difference Jacobian) from its result unless ``polish`` is False.

    The parameters are the unit-cube coordinates ``z0 .. z{P-1}`` (min 0, max 1): the same
    box and scales as the other peers, through lmfit's `~lmfit.Parameters`. lmfit's
    differential evolution keeps lmfit's defaults (SciPy's settings with ``polish=True``,
    and at most 2000 (P + 1) evaluations, after which lmfit returns the last point
    evaluated); its residual is the same `Objectives.residuals`, with a non-finite one
    replaced by a large finite one (lmfit refuses NaN). No covariance is computed.

    Returns:
        (point, E, evaluations, E after differential evolution alone).
    """
    import lmfit

    model = get(model)
    objectives = unit_objectives(data, model, bounds) if objectives is None else objectives
    names = [f"z{k}" for k in range(model.size)]

    def vector(params):
        return np.array([params[name].value for name in names])

    def residual(params):
        r = objectives.residuals(vector(params))
        return r if np.all(np.isfinite(r)) else np.full(r.shape, 1e3)

    params = lmfit.Parameters()
    for name in names:
        params.add(name, value=0.5, min=0.0, max=1.0)
    de = lmfit.minimize(residual, params, method="differential_evolution", seed=seed,
                        calc_covar=False)
    z_de = np.clip(vector(de.params), 0.0, 1.0)
    e_de, evaluations = objectives.error(z_de), de.nfev
    if not polish:
        return z_de, e_de, evaluations, e_de
    tol = LEAST_SQUARES_TOLERANCE
    ls = lmfit.minimize(residual, de.params, method="least_squares", calc_covar=False,
                        xtol=tol, ftol=tol, gtol=tol)
    z = np.clip(vector(ls.params), 0.0, 1.0)
    e = objectives.error(z)
    z, e = (z, e) if e <= e_de else (z_de, e_de)
    return z, e, int(evaluations + ls.nfev), e_de


def _timed(run, repeats):
    """Run once to warm up, then ``repeats`` times; the last result and the median time."""
    result = run()
    times = []
    for _ in range(repeats):
        tic = time.perf_counter()
        result = run()
        times.append(time.perf_counter() - tic)
    return result, float(np.median(times))


def compare(data, seed: int = 0, repeats: int = 3, lm_starts: int = 32,
            include=("hybrid", "ga", "lm", "scipy-vp", "scipy", "pygad"),
            model: str | Model | None = None) -> list[MethodRun]:
    """Fit ``data`` with each method; return one `MethodRun` per method.

    The SciPy objectives are built (and compiled) once, before any timing.
    """
    model = get(model)
    runs = []
    if "hybrid" in include:
        result, seconds = _timed(lambda: fit(data, seed=seed, model=model), repeats)
        runs.append(MethodRun("brdfjax hybrid", result.error, seconds, result.evaluations,
                              f"status {result.status}"))
    if "ga" in include:
        result, seconds = _timed(lambda: fit(data, "ga", seed=seed, model=model), repeats)
        runs.append(MethodRun("brdfjax ga", result.error, seconds, result.evaluations))
    if "lm" in include:
        best = min(r.error for r in runs) if runs else None
        result, seconds = _timed(lambda: fit(data, "lm", seed=seed, starts=lm_starts,
                                             model=model), repeats)
        note = f"{lm_starts} random starts"
        if best is not None:
            single = [fit(data, "lm", seed=seed + k, starts=1, model=model).error
                      for k in range(lm_starts)]
            hits = sum(e <= best * (1 + 1e-6) for e in single)
            note += f"; one start reaches the hybrid's E in {hits}/{lm_starts}"
        runs.append(MethodRun("brdfjax lm", result.error, seconds, result.evaluations, note))
    objectives = unit_objectives(data, model) if {"scipy-vp", "scipy", "pygad", "lmfit"} & set(
        include) else None
    if "scipy-vp" in include:
        (_, e, evaluations), seconds = _timed(
            lambda: scipy_vp(data, model, seed, objectives=objectives), repeats)
        runs.append(MethodRun("scipy vp", e, seconds, evaluations,
                              "careful peer: VP in DE, exact-Jacobian least_squares"))
    if "scipy" in include:
        (_, e, evaluations), seconds = _timed(
            lambda: scipy_de_ls(data, seed, model=model, objectives=objectives), repeats)
        runs.append(MethodRun("scipy de+ls (naive)", e, seconds, evaluations,
                              "every parameter in DE, finite-difference least_squares"))
    if "pygad" in include:
        runs.append(_optional_peer("pygad + ls", "GA", lambda: pygad_fit(
            data, seed, model=model, objectives=objectives), repeats))
    if "lmfit" in include:  # not by default: `brdfjax compare` shows the tools it was built on
        runs.append(_optional_peer("lmfit de+ls", "DE", lambda: lmfit_fit(
            data, seed, model=model, objectives=objectives), repeats))
    return runs


def _optional_peer(method: str, search: str, run, repeats: int) -> MethodRun:
    """The `MethodRun` of a peer whose library may be missing (pygad, lmfit): ``run()``
    returns ``(params, E, evaluations, E of its global search alone)``."""
    try:
        (_, e, evaluations, e_search), seconds = _timed(run, repeats)
    except ImportError:
        return MethodRun(method, float("nan"), float("nan"), 0, "not installed")
    return MethodRun(method, e, seconds, evaluations,
                     f"{search} alone ends at E = {100 * e_search:.4g} %")


def format_table(runs) -> str:
    """A Markdown table of `MethodRun` rows, E in percent."""
    lines = ["| method | E (%) | warm time (ms) | evaluations | note |",
             "|---|---|---|---|---|"]
    lines += [f"| {r.method} | {100 * r.error:.6g} | {1e3 * r.seconds:.1f} | {r.evaluations} "
              f"| {r.note} |" for r in runs]
    return "\n".join(lines)
