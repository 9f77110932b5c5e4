"""Levenberg-Marquardt with Marquardt's scaling, assembled from optimistix's parts.

`optimistix.LevenbergMarquardt` damps every coordinate alike, solving
``(J^T J + lambda I) step = -J^T r``. `brdfjax.fitting.polish` runs LM in the unconstrained
coordinates ``u`` of `brdfjax.models.bounds` (``z = sigmoid(u)``), where a parameter whose best
value lies on a bound has a Jacobian column that shrinks like ``exp(-|u|)`` as it nears
that bound. Next to the other columns that column's curvature is negligible against
``lambda``, so each step moves it by ``g / lambda`` only, and LM crawls towards the bound
for hundreds of steps (GGX on the bundled white paint, best at alpha = 2 and f0 = 1: 655
steps).

Marquardt's original damping scales ``lambda`` by each column's own size,
``(J^T J + lambda D^2) step = -J^T r`` with ``D`` diagonal, which makes the step
independent of how each coordinate is scaled: the saturating column takes the
Gauss-Newton step it asks for, and reaches the bound in a few steps (that GGX fit: 42-52
steps for each surviving start, the first 20 of them the unscaled screening of
`brdfjax.fitting.polish`, which says why the screening stays unscaled). Optimistix
composes a least-squares solver from a descent and a search; this module supplies the
descent, `MarquardtDescent`, and uses optimistix's `ClassicalTrustRegion` as
`optimistix.LevenbergMarquardt` does. (MINPACK's variant keeps the largest ``D`` seen so
far, which brings the crawl back.)

A column that is exactly zero (a parameter that does not change the residuals) takes
no step: its gradient is zero too. `brdfjax.models.bounds.from_free` clips ``u`` to
±`brdfjax.models.bounds.SATURATED`, so a coordinate on a bound has an exactly zero column, not
one so small that its scaled step would be enormous and never settle (without the clip,
Torrance-Sparrow on a 02aeroglaze run ran to its 1000-step cap).

On a small problem every step is written so that XLA:CPU compiles LM's whole loop as one
function (its small-while-loop pass, which `brdfjax` opens to loops of any size): the
products with the Jacobian as sums of its rows (it is held transposed), the Gram matrix's
upper triangle as one reduction and the normal equations solved by an unrolled Cholesky
factorisation, because a LAPACK call or an operation handed to XLA's YNNPACK library keeps
the loop as it is, one dispatched kernel per operation, about 140 per step. An LM step of
the five-parameter model on 64 points then takes about half the time. "Small" is a Gram
reduction of at most `ONE_FUNCTION_SIZE` elements (points x P (P + 1) / 2): beyond it
jaxlib 0.10's XLA hands that reduction to YNNPACK (measured: at 256 points for 6
parameters, 192 for 7, 128 for 8, none up to 256 for the five-parameter model), and the
loop would stay kernels with the slower unrolled step (ggx+ggx on 192 padded points: 65
against 39 ms per polish). On more points the kernels win anyway: the one function's code
is slower per point (the five-parameter model's polish on 512 and 716 points took 10-16 ms
as one function against 7-13 ms as kernels). There, and for starts side by side
(``compact``), the step keeps its matrix products and LAPACK's solve (`BENCHMARKS.md`,
section cube).
"""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import numpy as np
import optimistix as optx

from brdfjax.fitting.objective import cholesky_solve

# The largest Gram reduction (points x the P (P + 1) / 2 entries of the upper triangle) with
# which LM's loop runs as one function (module docstring).
ONE_FUNCTION_SIZE = 4096


def one_function(points: int, parameters: int) -> bool:
    """Whether LM on ``points`` residuals in ``parameters`` unknowns is written to compile as
    one function."""
    return points * parameters * (parameters + 1) // 2 <= ONE_FUNCTION_SIZE


def jacobian_product(jacobian, tangent):
    """``J @ tangent`` from the transposed Jacobian ``jacobian`` (P, N); on a small problem as
    a sum of rows (module docstring), which leaves XLA no matrix product to hand to a
    library."""
    if not one_function(jacobian.shape[1], jacobian.shape[0]):
        return tangent @ jacobian
    return sum(jacobian[k] * tangent[k] for k in range(jacobian.shape[0]))


class _Linearised(eqx.Module):
    """The residuals, the Jacobian with each column divided by its scale, transposed
    (P, N), and the scales."""

    residual: jax.Array
    transposed: jax.Array
    scale: jax.Array


class MarquardtDescent(optx.AbstractDescent):
    """The damped Gauss-Newton step ``-(J^T J + lambda D^2)^-1 J^T r``.

    ``D`` holds each Jacobian column's largest magnitude (Marquardt used the column's
    2-norm; any per-column measure gives the same invariance, and this one can neither
    underflow nor overflow when squared, since the scaled columns are at most 1).
    ``lambda`` is the reciprocal of the trust region's step size, as in
    `optimistix.DampedNewtonDescent`. The Jacobian is read once per accepted point, by P
    products of the linearisation with the basis under ``vmap`` (lineax's ``as_matrix``
    of the same operator made each LM step of the five-parameter model on 716 points a
    fifth slower); each trial step is then a P x P Cholesky solve. The residuals of
    `brdfjax.fitting.polish` linearise to their Jacobian itself (a custom JVP rule that
    forms it at every linearised point, rejected steps' included), so those products
    only read it back. It is held transposed, (P, N), as the P products give it row by
    row: held (N, P), XLA:CPU copied it into the other layout at every accepted step, and
    the polish of 716 points took 8.8 ms instead of 7.3 (BENCHMARKS.md, section batch).

    Attributes:
        scaled: Marquardt's scaling; False (or a traced False) takes ``D = I``: the
            steps of `optimistix.LevenbergMarquardt` with its normal equations solved by
            Cholesky, to rounding (the screening round of `brdfjax.fitting.polish`, which
            runs both rounds through one compiled loop).
        compact: on a small problem (`one_function`), the step written for one compiled
            function (module docstring); False keeps the matrix form at any size, for LM's
            starts side by side under ``vmap``, where XLA hands the batched reduction to
            YNNPACK anyway.
    """

    scaled: bool | jax.Array = True
    compact: bool = True

    def init(self, y, f_info_struct) -> _Linearised:
        points, size = f_info_struct.residual.shape[0], y.shape[0]
        return _Linearised(jnp.zeros(points, y.dtype), jnp.zeros((size, points), y.dtype),
                           jnp.ones(size, y.dtype))

    def query(self, y, f_info, state) -> _Linearised:
        del state
        basis = jnp.eye(y.shape[0], dtype=y.dtype)
        transposed = jax.vmap(f_info.jac.mv)(basis)  # (P, N): J^T
        largest = jnp.max(jnp.abs(transposed), axis=1)
        # a zero column takes no step anyway
        scale = jnp.where(self.scaled & (largest > 0), largest, 1.0)
        return _Linearised(f_info.residual, transposed / scale[:, None], scale)

    def step(self, step_size, state: _Linearised):
        """Solves ``(K^T K + lambda I) w = K^T r`` with ``K = J D^-1``; the step is
        ``-D^-1 w``."""
        eps = jnp.finfo(step_size.dtype).eps
        damping = jnp.where(step_size > eps, 1 / jnp.maximum(step_size, eps),
                            jnp.finfo(step_size.dtype).max)
        k_t = state.transposed  # K^T, (P, N)
        size = k_t.shape[0]
        if not (self.compact and one_function(k_t.shape[1], size)):
            normal = k_t @ k_t.T + damping * jnp.eye(size, dtype=k_t.dtype)
            solution = lx.linear_solve(
                lx.MatrixLinearOperator(normal, lx.positive_semidefinite_tag),
                k_t @ state.residual, lx.Cholesky(), throw=False)
            return -solution.value / state.scale, optx.RESULTS.promote(solution.result)
        # the Gram matrix's upper triangle in one reduction, and the solve unrolled
        rows, cols = np.triu_indices(size)
        entries = dict(zip(zip(rows.tolist(), cols.tolist()),
                           jnp.sum(k_t[rows] * k_t[cols], axis=1)))
        normal = [[entries[min(i, j), max(i, j)] + (damping if i == j else 0.0)
                   for j in range(size)] for i in range(size)]
        solution, _ = cholesky_solve(normal, list(jnp.sum(k_t * state.residual, axis=1)))
        return -jnp.stack(solution) / state.scale, optx.RESULTS.successful


def _silent(**_):
    """optimistix's verbose hook, printing nothing."""


class ScaledLevenbergMarquardt(optx.AbstractGaussNewton):
    """`optimistix.LevenbergMarquardt` with `MarquardtDescent` in place of its descent.

    Attributes:
        rtol, atol: relative and absolute tolerances of optimistix's Cauchy termination
            (on the step and on the change of the loss).
        cap: stop after this many steps (None: only at ``max_steps``).
    """

    rtol: float
    atol: float
    norm: Callable = optx.max_norm
    descent: MarquardtDescent = MarquardtDescent()
    search: optx.ClassicalTrustRegion = optx.ClassicalTrustRegion()
    verbose: Callable = _silent
    cap: int | jax.Array | None = None

    def terminate(self, fn, y, args, options, state, tags):
        """optimistix's test, and a stop at ``cap`` steps (reported as optimistix reports
        its own ``max_steps``; an earlier failure keeps its own code): a cap that may be
        traced, so that LM runs of different lengths share one compiled loop."""
        done, result = super().terminate(fn, y, args, options, state, tags)
        if self.cap is None:
            return done, result
        capped = ~done & (result == optx.RESULTS.successful) & (state.num_steps >= self.cap)
        return done | capped, optx.RESULTS.where(capped, optx.RESULTS.nonlinear_max_steps_reached,
                                                 result)
