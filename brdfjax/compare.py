"""Run time against error: brdfjax's methods beside the tools a user would pick instead.

Every method fits the same model (Eq. 5, evaluated by the same compiled function) to the
same data, minimising the same E of Eq. (6) over the same box (`brdfjax.bounds`: log10 for
kb, kr, a, kd; asinh for b), in one process:

- ``brdfjax hybrid``: genetic search, then Levenberg-Marquardt (the default);
- ``brdfjax ga``: the genetic search alone;
- ``brdfjax lm``: Levenberg-Marquardt alone from random points of the box;
- ``scipy de+ls``: ``scipy.optimize.differential_evolution`` then ``least_squares``
  (finite-difference Jacobian), the usual SciPy recipe;
- ``pygad``: pygad's genetic algorithm, if installed.

Timings are warm (compilation excluded: each method runs once before it is timed). scipy
and pygad are imported only here.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from brdfjax.bounds import default_bounds, from_unit
from brdfjax.fitting import fit
from brdfjax.objective import error, problem, residuals


@dataclass
class MethodRun:
    """One method's outcome: best E, median warm wall time, and its model evaluations."""

    method: str
    error: float
    seconds: float
    evaluations: int
    note: str = ""


def _unit_objectives(data, bounds):
    """E and the residual vector as NumPy functions of unit-cube coordinates."""
    prob = problem(data)
    # Bounds as JAX arrays: captured as NumPy constants they cost 30 % more per call here.
    bounds = jax.tree.map(jnp.asarray, bounds)
    error_jit = jax.jit(lambda z: error(from_unit(z, bounds), prob))
    errors_jit = jax.jit(jax.vmap(lambda z: error(from_unit(z, bounds), prob)))
    residual_jit = jax.jit(lambda z: residuals(from_unit(z, bounds), prob))
    return (lambda z: float(error_jit(z)), lambda zs: np.asarray(errors_jit(zs)),
            lambda z: np.asarray(residual_jit(z)))


def scipy_de_ls(data, seed: int = 0, generous: bool = False, bounds=None):
    """differential_evolution then least_squares, as a SciPy user would write it.

    Args:
        data: the measurements.
        seed: DE's seed.
        generous: larger population and more generations (for a reference optimum).
        bounds: the box (default bounds if None).

    Returns:
        (best unit-cube point, E, model evaluations).
    """
    from scipy.optimize import differential_evolution, least_squares

    bounds = default_bounds() if bounds is None else bounds
    objective, _, residual = _unit_objectives(data, bounds)
    settings = {"popsize": 40, "maxiter": 3000, "tol": 1e-10} if generous else {}
    de = differential_evolution(objective, [(0.0, 1.0)] * 5, seed=seed, polish=False,
                                **settings)
    ls = least_squares(residual, de.x, bounds=(0.0, 1.0), xtol=1e-12, ftol=1e-12, gtol=1e-12)
    return ls.x, float(objective(ls.x)), int(de.nfev + ls.nfev * 6)


def pygad_fit(data, seed: int = 0, bounds=None):
    """pygad's GA on the unit cube with batched fitness (returns point, E, evaluations)."""
    import pygad

    bounds = default_bounds() if bounds is None else bounds
    _, batch_errors, _ = _unit_objectives(data, bounds)
    generations, population = 200, 64

    def fitness(_, solutions, __):
        return -batch_errors(np.atleast_2d(solutions))

    ga = pygad.GA(num_generations=generations, num_parents_mating=16, fitness_func=fitness,
                  fitness_batch_size=population, sol_per_pop=population, num_genes=5,
                  gene_space={"low": 0.0, "high": 1.0}, random_seed=seed,
                  parent_selection_type="tournament", crossover_type="uniform",
                  mutation_type="random", mutation_percent_genes=40, suppress_warnings=True)
    ga.run()
    z, score, _ = ga.best_solution()
    return z, float(-score), generations * population


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
            include=("hybrid", "ga", "lm", "scipy", "pygad"), model="five") -> list[MethodRun]:
    """Fit ``data`` with each method; return one `MethodRun` per method.

    brdfjax's methods fit ``model``; the SciPy and pygad rows fit the five-parameter model.
    """
    from functools import partial

    fit_model = partial(fit, model=model)
    runs = []
    if "hybrid" in include:
        result, seconds = _timed(lambda: fit_model(data, seed=seed), repeats)
        runs.append(MethodRun("brdfjax hybrid", result.error, seconds, result.evaluations,
                              f"status {result.status}"))
    if "ga" in include:
        result, seconds = _timed(lambda: fit_model(data, "ga", seed=seed), repeats)
        runs.append(MethodRun("brdfjax ga", result.error, seconds, result.evaluations))
    if "lm" in include:
        best = min(r.error for r in runs) if runs else None
        result, seconds = _timed(lambda: fit_model(data, "lm", seed=seed, starts=lm_starts), repeats)
        note = f"{lm_starts} random starts"
        if best is not None:
            single = [fit_model(data, "lm", seed=seed + k, starts=1).error for k in range(lm_starts)]
            hits = sum(e <= best * (1 + 1e-6) for e in single)
            note += f"; one start reaches the hybrid's E in {hits}/{lm_starts}"
        runs.append(MethodRun("brdfjax lm", result.error, seconds, result.evaluations, note))
    if "scipy" in include:
        (_, e, evaluations), seconds = _timed(lambda: scipy_de_ls(data, seed), repeats)
        runs.append(MethodRun("scipy de+ls", e, seconds, evaluations))
    if "pygad" in include:
        try:
            (_, e, evaluations), seconds = _timed(lambda: pygad_fit(data, seed), repeats)
            runs.append(MethodRun("pygad", e, seconds, evaluations))
        except ImportError:
            runs.append(MethodRun("pygad", float("nan"), float("nan"), 0, "not installed"))
    return runs


def format_table(runs) -> str:
    """A Markdown table of `MethodRun` rows, E in percent."""
    lines = ["| method | E (%) | warm time (ms) | evaluations | note |",
             "|---|---|---|---|---|"]
    lines += [f"| {r.method} | {100 * r.error:.6g} | {1e3 * r.seconds:.1f} | {r.evaluations} "
              f"| {r.note} |" for r in runs]
    return "\n".join(lines)
