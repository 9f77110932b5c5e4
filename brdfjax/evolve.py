"""Global search: a real-coded genetic algorithm in JAX, the whole run one compiled loop.

The paper fits its five parameters with a genetic algorithm; this one searches the unit
cube of `brdfjax.bounds` (log10 for the positive parameters) so that the degenerate basins
of real data are reachable. Each generation:

1. the population is scored with one ``vmap`` of Eq. (6) (NaN counts as +inf);
2. the ``elite_count`` best members pass unchanged (elitism);
3. parents are drawn by tournament (the best of ``tournament_size`` random members);
4. children are blends ``p1 + beta (p2 - p1)`` with ``beta ~ U(-0.5, 1.5)`` per gene
   (BLX-0.5 crossover), then each gene mutates with probability ``mutation_rate`` by a
   normal step of ``mutation_scale``, and is clipped to the box.

The loop (``lax.while_loop``) stops after ``max_generations`` or when the best error has
not improved by a relative ``tolerance`` for ``patience`` generations. Sizes are static;
rates, bounds and data are traced, so sweeping them never recompiles.
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp

from brdfjax.bounds import Bounds, from_unit
from brdfjax.objective import Problem, error

BLEND_EXTENT = 0.5  # BLX-alpha with alpha = 0.5: children may land beyond either parent


class EvolveConfig(NamedTuple):
    """Rates of the genetic algorithm (traced: changing them does not recompile)."""

    mutation_rate: float = 0.2
    mutation_scale: float = 0.05
    crossover_rate: float = 0.9
    tolerance: float = 1e-6


class EvolveResult(NamedTuple):
    """The final population and how the run went.

    Attributes:
        population: unit-cube coordinates, (population_size, 5) (see `evolve` for order).
        errors: E of each member, (population_size,).
        history: best E after each generation, (max_generations,), NaN after the stop.
        generations: generations run.
    """

    population: jax.Array
    errors: jax.Array
    history: jax.Array
    generations: jax.Array


def population_errors(z, prob: Problem, bounds: Bounds) -> jax.Array:
    """E of every member of a unit-cube population (N, 5); NaN becomes +inf."""
    values = jax.vmap(lambda member: error(from_unit(member, bounds), prob))(z)
    return jnp.where(jnp.isnan(values), jnp.inf, values)


@partial(jax.jit, static_argnames=("population_size", "islands", "max_generations",
                                   "elite_count", "tournament_size", "patience", "precision"))
def evolve(key, prob: Problem, bounds: Bounds, config: EvolveConfig | None = None, *,
           population_size: int = 256, islands: int = 8, max_generations: int = 60,
           elite_count: int = 4, tournament_size: int = 3, patience: int = 15,
           precision: str = "float32") -> EvolveResult:
    """Run the genetic algorithm on one problem, as ``islands`` independent populations.

    Real data have several basins (FIELD-NOTES.md; the RT-300S "singularity" runs): one
    population converges into whichever it finds first, independent islands into several,
    and `brdfjax.polish.polish_population` polishes the best of each. The search runs in
    ``precision`` (float32 evaluates a population about twice as fast; it only has to find
    the basin, Levenberg-Marquardt polishes in the problem's float64).

    Args:
        key: a JAX PRNG key; the same key gives the same run.
        prob: the measurement set (`brdfjax.objective.problem`).
        bounds: the search box.
        config: the rates (`EvolveConfig` defaults if None).
        population_size: members in all islands together (a multiple of ``islands``).
        islands, max_generations, elite_count (per island), tournament_size, patience: sizes.
        precision: dtype name of the search arithmetic.

    Returns:
        An `EvolveResult` whose population is in island blocks of
        ``population_size // islands`` rows, each block sorted best first, returned in the
        problem's dtype.
    """
    if population_size % islands:
        raise ValueError(f"population_size {population_size} is not a multiple of "
                         f"islands {islands}")
    config = EvolveConfig() if config is None else config
    dtype = jnp.dtype(precision)
    low_prob, low_bounds = jax.tree.map(
        lambda x: x.astype(dtype) if jnp.issubdtype(x.dtype, jnp.floating) else x,
        (prob, bounds))
    runs = jax.vmap(lambda k: _island(k, low_prob, low_bounds, config,
                                      population_size // islands, max_generations,
                                      elite_count, tournament_size, patience))(
        jax.random.split(key, islands))
    out = prob.target.dtype
    return EvolveResult(population=runs.population.reshape(-1, 5).astype(out),
                        errors=runs.errors.reshape(-1).astype(out),
                        history=jnp.nanmin(runs.history, axis=0).astype(out),
                        generations=runs.generations.max())


def _island(key, prob, bounds, config, population_size, max_generations, elite_count,
            tournament_size, patience) -> EvolveResult:
    """One population evolved to the stop; sorted best first."""
    init_key, loop_key = jax.random.split(key)
    z = jax.random.uniform(init_key, (population_size, 5), dtype=prob.target.dtype)
    errors = population_errors(z, prob, bounds)
    order = jnp.argsort(errors)
    history = jnp.full(max_generations, jnp.nan, dtype=errors.dtype)

    def breed(key, z, errors):
        k_tour, k_blend, k_cross, k_mut, k_step = jax.random.split(key, 5)
        children = population_size - elite_count
        entrants = jax.random.randint(k_tour, (2, children, tournament_size), 0,
                                      population_size)
        winners = jnp.take_along_axis(
            entrants, jnp.argmin(errors[entrants], axis=-1)[..., None], axis=-1)[..., 0]
        first, second = z[winners[0]], z[winners[1]]
        beta = jax.random.uniform(k_blend, first.shape, minval=-BLEND_EXTENT,
                                  maxval=1 + BLEND_EXTENT, dtype=z.dtype)
        crossed = jax.random.uniform(k_cross, (children, 1)) < config.crossover_rate
        child = jnp.where(crossed, first + beta * (second - first), first)
        mutate = jax.random.uniform(k_mut, child.shape) < config.mutation_rate
        step = config.mutation_scale * jax.random.normal(k_step, child.shape, dtype=z.dtype)
        return jnp.clip(jnp.where(mutate, child + step, child), 0.0, 1.0)

    def condition(state):
        generation, _, _, _, _, stalled, _ = state
        return (generation < max_generations) & (stalled < patience)

    def step(state):
        generation, key, z, errors, history, stalled, best = state
        key, sub = jax.random.split(key)
        elite = jnp.argsort(errors)[:elite_count]
        children = breed(sub, z, errors)
        z = jnp.concatenate([z[elite], children])
        errors = jnp.concatenate([errors[elite], population_errors(children, prob, bounds)])
        new_best = errors.min()
        improved = new_best < best * (1 - config.tolerance)
        stalled = jnp.where(improved, 0, stalled + 1)
        history = history.at[generation].set(new_best)
        return generation + 1, key, z, errors, history, stalled, jnp.minimum(best, new_best)

    state = (jnp.asarray(0), loop_key, z[order], errors[order], history, jnp.asarray(0),
             errors.min())
    generations, _, z, errors, history, _, _ = jax.lax.while_loop(condition, step, state)
    order = jnp.argsort(errors)
    return EvolveResult(z[order], errors[order], history, generations)
