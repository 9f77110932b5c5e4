"""Global search: a real-coded genetic algorithm in JAX, the whole run one compiled loop.

The paper fits its five parameters with a genetic algorithm; this one searches the unit
cube of `brdfjax.models.bounds` (log10 for the positive parameters, asinh for b) so that the
degenerate basins of real data are reachable. Only the parameters that enter f_r
nonlinearly matter to the search ((kr, a, b) of the five-parameter model, alpha of GGX):
every member gets the best linear ones (kb and kd) exactly (variable projection,
`brdfjax.fitting.objective.solve_linear`), and the search space shrinks from five dimensions to
three (to one for GGX). Each generation:

1. the population is scored with one ``vmap`` of Eq. (6), the linear parameters solved
   (NaN counts as +inf);
2. the ``elite_count`` best members pass unchanged (elitism);
3. parents are drawn by tournament (the best of ``tournament_size`` random members);
4. children are blends ``p1 + beta (p2 - p1)`` with ``beta ~ U(-0.5, 1.5)`` per gene
   (BLX-0.5 crossover), then each gene mutates with probability ``mutation_rate`` by a
   normal step of ``mutation_scale``, and is clipped to the box.

Every draw of every generation comes from one call of JAX's generator before the loop,
16-bit words that `breed` reads as uniforms and tournament entrants: inside the loop on
XLA:CPU each generator call cost more than all its bits, and drawn so the search of a
64-point sample runs in two thirds of the time (BENCHMARKS.md, section cube). Their memory,
``max_generations`` x the children of a generation x `draw_count` x 2 bytes, is 165 kB
per search with the default sizes. With JAX's default (threefry) keys the draws are the
same under ``vmap``, so the accelerator's lanes draw what the single fit draws; an ``rbg``
key (faster still on a CPU) would not keep that.

The islands evolve side by side in one loop (``lax.while_loop``), their members scored
together; it stops after ``max_generations`` or when no island's best error has improved
by a relative ``tolerance`` for ``patience`` generations. Sizes are static; rates, bounds
and data are traced, so sweeping them never recompiles.

A model that leaves at most one parameter to search (GGX and Beckmann search alpha only,
Lambert nothing) needs no genetic algorithm: `scan` scores ``population_size`` evenly
spaced values of that parameter once, and its best local minima become the polish starts.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from brdfjax.cache import stage
from brdfjax.fitting.objective import Problem, solve_linear
from brdfjax.models.bounds import Bounds, from_unit, to_unit

BLEND_EXTENT = 0.5  # BLX-alpha with alpha = 0.5: children may land beyond either parent
# Islands up to this size are ordered by counting (`ascending`): a chosen bound, not a
# measured crossover (only the default islands of 16 were profiled).
COUNTED = 64


class EvolveConfig(NamedTuple):
    """Rates of the genetic algorithm (traced: changing them does not recompile)."""

    mutation_rate: float = 0.2
    mutation_scale: float = 0.05
    crossover_rate: float = 0.9
    tolerance: float = 1e-6


class EvolveResult(NamedTuple):
    """The final population and how the run went.

    Attributes:
        population: unit-cube coordinates, (population_size, P) (see `evolve` for order).
        errors: E of each member, (population_size,).
        history: best E after each generation, (max_generations,), NaN after the stop.
        generations: generations run.
    """

    population: jax.Array
    errors: jax.Array
    history: jax.Array
    generations: jax.Array


def score_population(z, prob: Problem, bounds: Bounds) -> tuple[jax.Array, jax.Array]:
    """Score a unit-cube population (N, P), solving each member's linear parameters exactly.

    `brdfjax.fitting.objective.solve_linear` gives the best linear parameters within the bounds
    (kb and kd of the five-parameter model). They replace the members' genes, so the
    returned population is consistent with its errors.

    Returns:
        The updated population and the E of each member (NaN becomes +inf).
    """

    def one(member):
        params, value = solve_linear(from_unit(member, bounds), prob, bounds)
        solved = to_unit(params, bounds)
        return jnp.where(jnp.isfinite(solved), solved, member), value

    z, values = jax.vmap(one)(z)
    return z, jnp.where(jnp.isnan(values), jnp.inf, values)


def check_population(population_size: int, islands: int = 8, elite_count: int = 4) -> None:
    """Refuse a population `evolve` cannot split into islands that breed."""
    if population_size % islands:
        raise ValueError(f"population_size {population_size} is not a multiple of "
                         f"islands {islands}")
    if population_size // islands <= elite_count:
        raise ValueError(f"population_size {population_size} leaves {population_size // islands}"
                         f" members to each of {islands} islands, all kept as elite "
                         f"(elite_count {elite_count}): nothing would be bred; give at least "
                         f"{islands * (elite_count + 1)}")


@stage(static_argnames=("population_size", "islands", "max_generations", "elite_count",
                        "tournament_size", "patience", "precision"))
def evolve(key, prob: Problem, bounds: Bounds, config: EvolveConfig | None = None, *,
           population_size: int = 128, islands: int = 8, max_generations: int = 40,
           elite_count: int = 4, tournament_size: int = 3, patience: int = 15,
           precision: str = "float32") -> EvolveResult:
    """Run the genetic algorithm on one problem, as ``islands`` independent populations.

    Real data have several basins (the RT-300S black coatings: the kb-b valley and others): one
    population converges into whichever it finds first, independent islands into several,
    and `brdfjax.fitting.polish.polish_population` polishes the best of each. The search runs in
    ``precision`` (float32 evaluates a population about twice as fast; it only has to find
    the basin, Levenberg-Marquardt polishes in the problem's float64).

    Args:
        key: a JAX PRNG key (new or legacy), or an integer seed; the same key gives the
            same run.
        prob: the measurement set (`brdfjax.fitting.objective.problem`).
        bounds: the search box.
        config: the rates (`EvolveConfig` defaults if None).
        population_size: members in all islands together (a multiple of ``islands``).
        islands, max_generations, elite_count (per island), tournament_size, patience: sizes.
        precision: dtype name of the search arithmetic.

    Returns:
        An `EvolveResult` whose population is in island blocks of
        ``population_size // islands`` rows, each block sorted best first and the blocks
        ordered by their best (row 0 is the best member), returned in the problem's dtype.
    """
    check_population(population_size, islands, elite_count)
    config = EvolveConfig() if config is None else config
    if key is None:
        raise TypeError("the seed must be an integer or a JAX PRNG key, got None")
    kind, scalar = jnp.result_type(key), jnp.ndim(key) == 0
    typed = jax.dtypes.issubdtype(kind, jax.dtypes.prng_key)
    if scalar and jnp.issubdtype(kind, jnp.integer):
        key = jax.random.key(key)
    elif scalar and not typed:
        raise TypeError(f"the seed must be an integer or a JAX PRNG key, got a {kind}")
    elif not typed:
        key = jax.random.wrap_key_data(key)  # a legacy uint32 key of jax.random.PRNGKey
    out, dtype = prob.target.dtype, jnp.dtype(precision)
    prob, bounds = in_precision((prob, bounds), dtype)
    if prob.model.searched_size <= 1:
        return scan(prob, bounds, population_size, islands, max_generations, out)
    config = jax.tree.map(lambda x: jnp.asarray(x, dtype), config)
    size = population_size // islands
    dimensions = prob.model.size

    def score(z):
        """Score every member of every island: one flat vmap, the fastest layout on CPU."""
        scored, errors = score_population(z.reshape(-1, dimensions), prob, bounds)
        return scored.reshape(z.shape), errors.reshape(z.shape[:-1])

    def sort(z, errors):
        order = ascending(errors)
        return (jnp.take_along_axis(z, order[..., None], axis=1),
                jnp.take_along_axis(errors, order, axis=-1))

    # The first population is scored through the generations' own scoring call, in
    # `warm` rounds of `children` members per island (the last window ends at the
    # island's end, overlapping the one before): XLA inlines every call site, and the
    # model, its linear solve included, compiled once instead of twice makes the search
    # compile about a third faster (BENCHMARKS.md, startup-fit).
    children = size - elite_count
    draws = draw_count(tournament_size, dimensions)
    windows = jnp.asarray([min(k * children, size - children)
                           for k in range(-(-size // children))])
    warm = windows.shape[0]
    init_key, loop_key = jax.random.split(key)
    founders = jax.random.uniform(init_key, (islands, size, dimensions), dtype=dtype)
    # Every generation's draws in one call before the loop (module docstring); with the
    # default sizes 165 kB per search.
    bits = jax.random.bits(loop_key, (max_generations, islands, children, draws), jnp.uint16)

    def condition(state):
        round_, _, _, _, stalled, _ = state
        return (round_ < warm) | ((round_ - warm < max_generations)
                                  & jnp.any(stalled < patience))

    def candidates(round_, z):
        """A window of the first population, or the next generation's children."""
        def window():
            return jax.lax.dynamic_slice_in_dim(founders, windows[round_], children, axis=1)

        def bred():
            return jax.vmap(breed, in_axes=(0, 0, None, None))(
                bits[jnp.maximum(round_ - warm, 0)], z, tournament_size, config)

        return jax.lax.cond(round_ < warm, window, bred)

    def settle_first(round_, z, errors, scored, scored_errors):
        """Put a scored window in place; after the last, sort the islands."""
        start = windows[round_]
        z = jax.lax.dynamic_update_slice_in_dim(z, scored, start, axis=1)
        errors = jax.lax.dynamic_update_slice_in_dim(errors, scored_errors, start, axis=1)
        return jax.lax.cond(round_ == warm - 1, sort, lambda z, e: (z, e), z, errors)

    def settle_children(z, errors, scored, scored_errors):
        return sort(jnp.concatenate([z[:, :elite_count], scored], axis=1),
                    jnp.concatenate([errors[:, :elite_count], scored_errors], axis=1))

    def step(state):
        round_, z, errors, history, stalled, best = state
        breeding = round_ >= warm
        scored, scored_errors = score(candidates(round_, z))
        z, errors = jax.lax.cond(breeding,
                                 lambda: settle_children(z, errors, scored, scored_errors),
                                 lambda: settle_first(round_, z, errors, scored, scored_errors))
        generation = round_ - warm
        improved = errors[:, 0] < best * (1 - config.tolerance)
        stalled = jnp.where(breeding, jnp.where(improved, 0, stalled + 1), stalled)
        history = jnp.where(breeding, history.at[generation].set(errors[:, 0].min()), history)
        best = jnp.where(breeding, jnp.minimum(best, errors[:, 0]),
                         jnp.where(round_ == warm - 1, errors[:, 0], best))
        return round_ + 1, z, errors, history, stalled, best

    state = (jnp.asarray(0), founders, jnp.full((islands, size), jnp.inf, dtype),
             jnp.full(max_generations, jnp.nan, dtype), jnp.zeros(islands, dtype=int),
             jnp.full(islands, jnp.inf, dtype))
    rounds, z, errors, history, _, _ = jax.lax.while_loop(condition, step, state)
    generations = rounds - warm
    order = jnp.argsort(errors[:, 0])  # islands best first: member 0 is the best of all
    z, errors = z[order], errors[order]
    return EvolveResult(population=z.reshape(-1, dimensions).astype(out),
                        errors=errors.reshape(-1).astype(out), history=history.astype(out),
                        generations=generations)


def in_precision(tree, dtype):
    """``tree`` with every floating-point leaf in ``dtype`` (the search's arithmetic) and the
    others (a model's flags, integer arrays) as they are."""
    return jax.tree.map(
        lambda x: x.astype(dtype) if jnp.issubdtype(x.dtype, jnp.floating) else x, tree)


def ascending(values) -> jax.Array:
    """The order that sorts ``values`` ascending along the last axis, ties kept in index
    order: ``jnp.argsort``'s stable order, for values without NaN (the search scores NaN
    as +inf; a NaN would give indices that are no permutation).

    Each value's place is the count of values before it, so that one comparison of every
    pair replaces a sort: XLA:CPU sorts through a comparator call per comparison, and the
    two sorts of a generation's 8 islands of 16 took 12 us each, longer than the rest of
    its bookkeeping (`jax.profiler`). The pairs grow as the square of the island, so an
    island of more than `COUNTED` members is sorted after all.
    """
    count = values.shape[-1]
    if count > COUNTED:
        return jnp.argsort(values, axis=-1, stable=True)
    index = jnp.arange(count)
    earlier = index[None, :] < index[:, None]
    ahead = values[..., None, :] < values[..., :, None]
    tied = values[..., None, :] == values[..., :, None]
    place = jnp.sum(ahead | (tied & earlier), axis=-1)
    return jnp.sum(jnp.where(place[..., None, :] == index[:, None], index, 0), axis=-1)


def draw_count(tournament_size: int, dimensions: int) -> int:
    """The 16-bit draws `breed` takes per child: two tournaments, then a blend factor per
    gene, a crossover draw, a mutation draw per gene and a mutation step per gene."""
    return 2 * tournament_size + 3 * dimensions + 1


def breed(bits, z, tournament_size: int, config: EvolveConfig):
    """The children of one island from its draws: tournament, BLX blend, mutation.

    Args:
        bits: uint16 draws, (children, `draw_count`): one row per child.
        z: the island's members, sorted best first, (members, P), in the search's dtype.
        tournament_size, config: as `evolve` takes them.

    Each draw k is read as the uniform ``(k + 1/2) / 2^16`` (in (0, 1), never either end;
    rates are so resolved to 2^-16), computed in at least float32 so that a half-precision
    search never rounds it to 1. A tournament entrant is the high half of ``k x members``
    (multiply-shift: uniform over the members for a power-of-two island, within 2^-16 of
    uniform otherwise); the mutation step is ``mutation_scale sqrt(2) erfinv(2u - 1)``, a
    normal step cut at 4.4 sigma.

    Returns:
        The children, clipped to the unit cube, (children, P).
    """
    size, dimensions = z.shape
    children = bits.shape[0]
    wide = jnp.promote_types(z.dtype, jnp.float32)
    uniform = (bits[:, 2 * tournament_size:].astype(wide) + 0.5) / 65536
    entrants = (bits[:, :2 * tournament_size].astype(jnp.uint32) * size) >> 16
    winners = jnp.min(entrants.reshape(children, 2, tournament_size), axis=-1)
    first, second = z[winners[:, 0]], z[winners[:, 1]]
    beta, crossed, mutate, step = jnp.split(uniform, [dimensions, dimensions + 1,
                                                      2 * dimensions + 1], axis=-1)
    beta = (-BLEND_EXTENT + (1 + 2 * BLEND_EXTENT) * beta).astype(z.dtype)
    child = jnp.where(crossed < config.crossover_rate, first + beta * (second - first), first)
    step = (config.mutation_scale * jnp.sqrt(2.0) * jax.scipy.special.erfinv(2 * step - 1)
            ).astype(z.dtype)
    return jnp.clip(jnp.where(mutate < config.mutation_rate, child + step, child), 0.0, 1.0)


def scan(prob: Problem, bounds: Bounds, points: int, islands: int, max_generations: int,
         out) -> EvolveResult:
    """The search of a model with at most one parameter to search: a grid, scored once.

    Every gene of member k is ``(k + 1/2) / points``: the linear solve overwrites all genes
    but the searched one, which thus takes ``points`` evenly spaced values across its range
    (a 3-decade log10 range in steps of 5.5 % for 128 points). The grid's local minima,
    best first, give one island each (the best ``islands``; where there are fewer, the
    remaining islands repeat the best member), so that `brdfjax.fitting.polish.polish_population`
    starts once from each minimum: it skips repeated starts.

    Returns:
        An `EvolveResult` laid out as `evolve`'s (island blocks, each one member repeated)
        with ``generations`` 0 and an all-NaN history: no generation was bred.
    """
    grid = (jnp.arange(points, dtype=prob.target.dtype) + 0.5) / points
    z, errors = score_population(jnp.broadcast_to(grid[:, None], (points, prob.model.size)),
                                 prob, bounds)
    padded = jnp.pad(errors, 1, constant_values=jnp.inf)
    minimum = (errors <= padded[:-2]) & (errors <= padded[2:]) & jnp.isfinite(errors)
    order = jnp.argsort(jnp.where(minimum, errors, jnp.inf))[:islands]
    order = jnp.where(minimum[order], order, order[0])  # too few minima: repeat the best
    block = points // islands
    return EvolveResult(population=jnp.repeat(z[order], block, axis=0).astype(out),
                        errors=jnp.repeat(errors[order], block).astype(out),
                        history=jnp.full(max_generations, jnp.nan, out),
                        generations=jnp.asarray(0))
