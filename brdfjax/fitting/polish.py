"""Local refinement: optimistix Levenberg-Marquardt from several good starting points.

LM has no bounds, so it runs in the unconstrained coordinates ``u`` of `brdfjax.models.bounds`
(``z = sigmoid(u)`` in the unit cube). It runs in two rounds:

1. **Screening**: up to `SCREEN_STEPS` (20) steps of LM whose damping is the same in every
   coordinate (the steps of optimistix's own LM). Its first steps are short in all of them,
   so each start settles into its own basin (the five-parameter model's Fresnel-free start
   stays in the thin valley where the paper's cement has its best fit). Twenty steps rank
   the starts as forty did: every model on every bundled real run ended at the same E (1e-6;
   180 fits), and so did 256 cube samples, while 43 % of a cube sample's starts used to run
   all 40 (`BENCHMARKS.md`, section cube).
2. **Convergence**: the best 3 continue with Marquardt's scaling of the damping
   (`brdfjax.fitting.marquardt`), under which a parameter whose best value lies on a bound gets
   there in a few steps instead of crawling for hundreds. Scaled from the first step, LM
   jumps too far along a coordinate whose Jacobian column is nearly zero: from the
   Fresnel-free start (b = 0, where a does not enter), a jumped to its upper bound and the
   cement fit ended in a worse basin.

Both rounds run through one compiled LM loop (`brdfjax.fitting.marquardt`'s solver with its
scaling and its step cap as data, ``lax.scan`` over the two rounds; the starts leave the
screening sorted, and the second round runs the first ``keep`` and branches past the
rest, a branch that stays one under a vmap over samples). Two loops, one per round, made
the polish twice as long to compile (the five-parameter model and ggx+backscatter on 120
points: 1.26-1.76 s against 0.62-0.92 s); with one, every model on every bundled real run
ended where it had, bit for bit (`BENCHMARKS.md`, section startup-fit-models-batch-auto).

Several distinct starts run in one compiled call with ``throw=False``, each reporting
its own status; the caller keeps the best. A start identical to an earlier one is
skipped (a converged island offers the same member more than once), which saves about
a third of the screening where the starts run one after another (under ``vmap``, as
with `brdfjax.fit_batch`'s ``polish_batch`` above 1, the skip becomes a select and every
start runs; the results are the same).

The starts run one after another (``lax.map``), not side by side (``vmap``): a vmapped
``while_loop`` runs every lane as long as the slowest, and under ``vmap`` each of
optimistix's branches (``lax.cond``) becomes a select that computes both sides. On a CPU
16 starts of 40 screening steps (the screening's length then) took 12-23 ms mapped
against 40 ms vmapped (exploratory timing, 716 points). On an accelerator, where lanes
run at once and each loop step is a kernel launch, ``side_by_side`` runs them under
``vmap`` (`brdfjax.fitting.batch`'s ``lanes``).

Each step solves its P x P normal equations by Cholesky: with at most 5 parameters they
are tiny, it is the fastest here, and unlike lineax's default QR it was not seen to
deadlock on several simulated CPU devices (QR and SVD sat at 0 % CPU for 19 minutes). On
a small problem (`brdfjax.fitting.marquardt.one_function`: the five-parameter model on up
to 256 points) the factorisation is unrolled and LM's whole loop compiles as one function
(`brdfjax.fitting.marquardt`).
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
from jax.custom_derivatives import SymbolicZero

from brdfjax.cache import stage
from brdfjax.fitting.objective import Problem, error, residuals
from brdfjax.models.bounds import Bounds, from_free, from_unit, to_free

# Relative and absolute step tolerances: float64 meets 1e-10 (noise-free data reach
# E ~ 1e-20); float32 cannot meet tighter than about 1e-6 (at 1e-8 LM runs to its cap).
TOLERANCE = {jnp.dtype("float64"): 1e-10, jnp.dtype("float32"): 1e-6}
# Distinct GA members the hybrid fit polishes by default (`polish_population`).
STARTS = 16
# Steps of the screening round (module docstring).
SCREEN_STEPS = 20


class PolishResult(NamedTuple):
    """One LM run per start (leading axis: starts).

    Attributes:
        free: final unconstrained coordinates, (starts, P).
        params: final physical parameters, (starts, P).
        errors: E at the end, (starts,).
        success: True where optimistix reports ``successful``.
        steps: LM steps taken, (starts,); 0 for a skipped repeat.
        evaluations: model evaluations over all starts and rounds (a residual and a
            P-column Jacobian per step; a skipped repeat costs none).
    """

    free: jax.Array
    params: jax.Array
    errors: jax.Array
    success: jax.Array
    steps: jax.Array
    evaluations: jax.Array


@jax.custom_jvp
def _free_residuals(u, args):
    """The residuals at free coordinates ``u`` (``args = (prob, bounds)``), whose
    linearisation in ``u`` is the Jacobian alone.

    optimistix linearises the residuals at every LM step (``jax.linearize``) and carries the
    linearisation in its loop state; a plain function's linearisation holds every
    intermediate array of the model, which XLA copies at each step's accept-or-reject
    branch (about 60 copies for the five-parameter model). With the Jacobian formed in
    this custom JVP rule (P products with the basis, as linearising did), the state holds
    one matrix, the Jacobian transposed (P x N: `brdfjax.fitting.marquardt.jacobian_product`).
    """
    prob, bounds = args
    return residuals(from_free(u, bounds), prob)


def _free_residuals_jvp(primals, tangents):
    (u, args), (tangent, args_tangent) = primals, tangents
    if _is_zero(tangent):  # differentiated in the data or the box alone
        value = _free_residuals.fun(u, args)
        out = jnp.zeros_like(value)
    else:
        from brdfjax.fitting.marquardt import jacobian_product  # traced only, as below

        basis = jnp.eye(u.shape[0], dtype=u.dtype)
        value, jacobian = jax.vmap(lambda e: jax.jvp(lambda v: _free_residuals.fun(v, args),
                                                     (u,), (e,)), out_axes=(None, 0))(basis)
        out = jacobian_product(jacobian, tangent)
    leaves, structure = jax.tree.flatten(args)
    moved = jax.tree.leaves(args_tangent, is_leaf=_is_zero)
    moving = [k for k, t in enumerate(moved) if not _is_zero(t)]
    if moving:  # differentiated in the data or the box too (LM never is): as usual

        def of_moving(*values):
            changed = list(leaves)
            for k, v in zip(moving, values):
                changed[k] = v
            return _free_residuals.fun(u, structure.unflatten(changed))

        out = out + jax.jvp(of_moving, [leaves[k] for k in moving],
                            [moved[k] for k in moving])[1]
    return value, out


_free_residuals.defjvp(_free_residuals_jvp, symbolic_zeros=True)


def _is_zero(tangent) -> bool:
    return isinstance(tangent, SymbolicZero)


def _levenberg_marquardt(starts, skipped, prob, bounds, max_steps, scaled=True, cap=None,
                         side_by_side=False, rows=None):
    """LM from each row of ``starts`` (one after another, or ``side_by_side`` under ``vmap``),
    each with its own status.

    Rows where ``skipped`` is True are not run: they keep their start, E = inf and 0 steps
    (side by side they run and are then discarded: ``vmap`` makes the branch a select).
    ``scaled``: Marquardt's scaling (`brdfjax.fitting.marquardt`), else the same damping in
    every coordinate; ``cap``: a lower step limit than ``max_steps``, which may be traced.
    ``rows``: run only the first ``rows`` rows (a number that may be traced but is the same
    for every sample of an outer ``vmap``, so that skipping the others stays a branch).
    """
    import optimistix as optx  # imported only when traced: a cached stage runs without it

    from brdfjax.fitting.marquardt import MarquardtDescent, ScaledLevenbergMarquardt

    tol = TOLERANCE[jnp.dtype(starts.dtype)]
    descent = MarquardtDescent(scaled, compact=not side_by_side)
    solver = ScaledLevenbergMarquardt(rtol=tol, atol=tol, descent=descent,
                                      cap=cap)

    def run(u0):
        solution = optx.least_squares(_free_residuals, solver, u0, args=(prob, bounds),
                                      max_steps=max_steps, throw=False)
        u = solution.value
        params = from_free(u, bounds)
        value = error(params, prob)
        return (u, params, jnp.where(jnp.isnan(value), jnp.inf, value),
                solution.result == optx.RESULTS.successful, solution.stats["num_steps"])

    def skip(u0):
        return (u0, from_free(u0, bounds), jnp.asarray(jnp.inf, u0.dtype), jnp.asarray(False),
                jnp.asarray(0, jnp.result_type(int)))

    def one(args):
        index, u0, repeat = args
        if rows is None:
            return jax.lax.cond(repeat, skip, run, u0)
        return jax.lax.cond(index < rows, lambda: jax.lax.cond(repeat, skip, run, u0),
                            lambda: skip(u0))

    index = jnp.arange(starts.shape[0])
    u, params, errors, success, steps = (jax.vmap(one) if side_by_side else
                                         partial(jax.lax.map, one))((index, starts, skipped))
    if rows is not None:
        skipped = skipped | (index >= rows)
    evaluations = (1 + prob.model.size) * jnp.sum(jnp.where(skipped, 0, steps + 1))
    return PolishResult(u, params, errors, success, steps, evaluations)


def repeats(starts) -> jax.Array:
    """True for each row of ``starts`` (S, P) equal to an earlier row."""
    same = jnp.all(starts[:, None] == starts[None], axis=-1)
    return jnp.any(jnp.tril(same, -1), axis=1)


@stage(static_argnames=("max_steps", "screen_steps", "keep", "side_by_side"))
def polish(starts, prob: Problem, bounds: Bounds, *, max_steps: int = 1000,
           screen_steps: int = SCREEN_STEPS, keep: int = 3,
           side_by_side: bool = False) -> PolishResult:
    """Levenberg-Marquardt from many starts, screened, then run to convergence.

    Every start first takes up to ``screen_steps`` steps of unscaled LM; only the
    ``keep`` best then continue, with Marquardt's scaling (`brdfjax.fitting.marquardt`), for up
    to ``max_steps`` more, so that a start along a flat valley is run long only where it
    may win. With ``keep`` at least the number of starts, every start continues, in order.

    Args:
        starts: unconstrained starting coordinates, (S, P).
        prob: the measurement set.
        bounds: the search box.
        max_steps, screen_steps, keep: step caps and how many starts survive screening.
        side_by_side: run the starts under ``vmap`` instead of one after another (the
            accelerator path of `brdfjax.fitting.batch`).

    Returns:
        A `PolishResult` for the surviving starts (steps counted over both rounds).
    """
    count = starts.shape[0]
    skipped = repeats(starts)
    loop_steps, kept = max(max_steps, screen_steps), min(keep, count)

    def lm(free, skip, cap, scaled, rows=None):
        return _levenberg_marquardt(free, skip, prob, bounds, loop_steps, scaled, cap,
                                    side_by_side, rows)

    def ranked(errors):  # best first; skipped repeats (E = inf) sort last
        return jnp.argsort(errors) if keep < count else jnp.arange(count)

    if side_by_side:  # two loops: under vmap a skipped start would still run
        screened = lm(starts, skipped, screen_steps, False)
        best = ranked(screened.errors)[:kept]
        final = lm(screened.free[best], skipped[best], max_steps, True)
        return final._replace(steps=final.steps + screened.steps[best],
                              evaluations=final.evaluations + screened.evaluations)

    def one_round(carry, setting):  # the starts leave sorted: the second round runs the first
        free, skip = carry
        rows, cap, scaled = setting
        out = lm(free, skip, cap, scaled, rows)
        order = ranked(out.errors)
        return (out.free[order], skip[order]), (out, order)

    settings = (jnp.array([count, kept]), jnp.array([screen_steps, max_steps]),
                jnp.array([False, True]))
    _, (rounds, order) = jax.lax.scan(one_round, (starts, skipped), settings)
    final = jax.tree.map(lambda x: x[1, :kept], rounds._replace(evaluations=None))
    return final._replace(steps=final.steps + rounds.steps[0, order[0, :kept]],
                          evaluations=jnp.sum(rounds.evaluations))


def polish_population(population, prob: Problem, bounds: Bounds, *, starts: int = STARTS,
                      islands: int = 8, separation: float = 0.1, max_steps: int = 1000,
                      screen_steps: int = SCREEN_STEPS, keep: int = 3,
                      side_by_side: bool = False) -> PolishResult:
    """`polish` from distinct good members of each island of a `brdfjax.fitting.evolve` population.

    Each of the ``islands`` blocks of ``population`` (sorted best first within the block)
    gives ``starts // islands`` members that lie ``separation`` apart, so every basin the
    islands found gets its own starts. The model may add starts of its own made from the
    best member (`brdfjax.models.Model.extra_starts`: the five-parameter model's
    Fresnel-free start): `start_count` in all. The starts are chosen and polished in two
    compiled calls, so that other polishes of as many starts (the Laplace approximation's
    polish to the mode, `brdfjax.uncertainty.laplace.find_mode`) run the same compiled LM.
    """
    u0 = population_starts(population, prob.model, bounds, starts=starts, islands=islands,
                           separation=separation)
    return polish(u0, prob, bounds, max_steps=max_steps, screen_steps=screen_steps, keep=keep,
                  side_by_side=side_by_side)


@stage(static_argnames=("starts", "islands"))
def population_starts(population, model, bounds: Bounds, *, starts: int = STARTS,
                      islands: int = 8, separation: float = 0.1) -> jax.Array:
    """The unconstrained LM starts (`start_count`, P) that `polish_population` polishes."""
    if starts % islands:
        raise ValueError(f"starts {starts} is not a multiple of islands {islands}")
    blocks = population.reshape(islands, -1, model.size)
    chosen = jax.vmap(lambda z: z[distinct_members(z, starts // islands, separation)])(blocks)
    chosen = jnp.concatenate([chosen.reshape(-1, model.size),
                              model.extra_starts(population[:1], bounds)])
    return to_free(from_unit(chosen, bounds), bounds)


def start_count(model, bounds: Bounds, starts: int = STARTS) -> int:
    """The LM starts of `polish_population`: ``starts`` members and the model's own (a
    shape, traced once per model)."""
    if model not in _own_starts:
        unit = jax.ShapeDtypeStruct((1, model.size), jnp.float64)
        _own_starts[model] = jax.eval_shape(model.extra_starts, unit, bounds).shape[0]
    return starts + _own_starts[model]


_own_starts: dict = {}  # model: the count of its `brdfjax.models.Model.extra_starts`


def resume(free, prob: Problem, bounds: Bounds, max_steps: int) -> PolishResult:
    """LM's convergence round (Marquardt's scaling) from one start ``free`` (P,) for up to
    ``max_steps`` steps: a start `polish` stopped at a lower cap, run on (the accelerator
    path's slow lanes, `brdfjax.fitting.batch`). Leading axis 1."""
    return _levenberg_marquardt(free[None], jnp.zeros(1, bool), prob, bounds, max_steps)


def distinct_members(z, count: int, separation: float = 0.02) -> jax.Array:
    """Indices of ``count`` good, mutually distinct members of a sorted population.

    Walks the population best first and takes a member when it lies farther than
    ``separation`` (max-norm, unit cube) from every member already taken; if too few are
    distinct, the remaining slots repeat the best.
    """

    def visit(k, state):
        chosen, taken = state
        gap = jnp.max(jnp.abs(z[chosen] - z[k]), axis=-1)
        far = jnp.all((gap > separation) | (jnp.arange(count) >= taken))
        take = far & (taken < count)
        chosen = jnp.where(take, chosen.at[taken].set(k), chosen)
        return chosen, taken + take

    chosen, _ = jax.lax.fori_loop(0, z.shape[0], visit,
                                  (jnp.zeros(count, dtype=int), jnp.asarray(0)))
    return chosen
