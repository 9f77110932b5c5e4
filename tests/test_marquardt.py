"""Levenberg-Marquardt with Marquardt's scaling: bounds reached, scale invariance, no
underflow, zero columns, and the white-paint GGX fit that used to crawl."""

import jax.numpy as jnp
import lineax as lx
import numpy as np
import optimistix as optx
import pytest

from brdfjax.fitting.marquardt import (
    ONE_FUNCTION_SIZE,
    MarquardtDescent,
    ScaledLevenbergMarquardt,
    one_function,
)
from brdfjax.models.bounds import SATURATED, Bounds, from_free

UNIT_SQUARE = Bounds(np.zeros(2), np.ones(2), np.zeros(2, dtype=int))


def _solve(solver, residuals, u0, max_steps=2000):
    solution = optx.least_squares(residuals, solver, jnp.asarray(u0), max_steps=max_steps,
                                  throw=False)
    return solution, int(solution.stats["num_steps"])


def test_a_parameter_whose_optimum_lies_beyond_its_bound_reaches_the_bound_quickly():
    # x is stiff (weight 100) with its optimum 0.3 inside; y wants 2, beyond its bound 1.
    def residuals(u, args):
        x, y = from_free(u, UNIT_SQUARE)
        return jnp.array([100 * (x - 0.3), y - 2])

    scaled, scaled_steps = _solve(ScaledLevenbergMarquardt(rtol=1e-10, atol=1e-10),
                                  residuals, [0.0, 0.0])
    plain, plain_steps = _solve(optx.LevenbergMarquardt(rtol=1e-10, atol=1e-10),
                                residuals, [0.0, 0.0])
    assert scaled.result == optx.RESULTS.successful
    x, y = from_free(scaled.value, UNIT_SQUARE)
    assert abs(x - 0.3) < 1e-12
    assert 1 - y < 1e-15  # sigmoid(SATURATED) = 1 - 2.3e-16
    assert scaled_steps <= 30
    # optimistix's own LM damps both coordinates alike and crawls to the same point: the
    # reason for this one (749 steps against 12 when written)
    assert plain.result == optx.RESULTS.successful
    np.testing.assert_allclose(from_free(plain.value, UNIT_SQUARE), [x, y], atol=1e-9)
    assert plain_steps >= 5 * scaled_steps


@pytest.mark.parametrize("tiny", [1.0, 1e-170])
def test_a_column_whose_square_underflows_is_still_solved(tiny):
    # A linear least-squares problem in (v0, tiny * v1): (1e-170)^2 underflows to 0, so
    # damping by lambda J^T J computed naively would make the step singular.
    a = jnp.array([[1.0, 2.0], [3.0, -1.0], [0.5, 0.5]])
    b = jnp.array([1.0, 2.0, 3.0])

    def residuals(v, args):
        return a @ jnp.array([v[0], tiny * v[1]]) - b

    solution, _ = _solve(ScaledLevenbergMarquardt(rtol=1e-12, atol=1e-12), residuals,
                         [0.0, 0.0])
    expected, *_ = np.linalg.lstsq(np.asarray(a), np.asarray(b), rcond=None)
    assert solution.result == optx.RESULTS.successful
    found = np.array([solution.value[0], tiny * solution.value[1]])
    np.testing.assert_allclose(found, expected, rtol=1e-10)


def test_a_parameter_that_changes_nothing_takes_no_step():
    def residuals(u, args):
        return jnp.array([u[0] - 1.0, 2 * (u[0] + 1.0)])  # u[1] does not enter

    solution, _ = _solve(ScaledLevenbergMarquardt(rtol=1e-12, atol=1e-12), residuals,
                         [0.0, 5.0])
    assert solution.result == optx.RESULTS.successful
    assert float(solution.value[1]) == 5.0
    np.testing.assert_allclose(float(solution.value[0]), -0.6, rtol=1e-12)


def exponentials(points=12):
    """A two-exponential curve fit on ``points`` times, nonlinear in both rates (a dozen LM
    steps)."""
    t = jnp.linspace(0.0, 3.0, points)
    observed = 2.0 * jnp.exp(-1.3 * t) + 0.5 * jnp.exp(-0.2 * t)

    def residuals(u, args):
        return u[0] * jnp.exp(-u[1] * t) + u[2] * jnp.exp(-u[3] * t) - observed

    return residuals


_exponentials = exponentials()


EXPONENTIALS_START = [1.0, 2.0, 1.0, 0.1]  # rates 2 and 0.1 against the data's 1.3 and 0.2


@pytest.mark.parametrize("points", [12, ONE_FUNCTION_SIZE // 10 + 1])  # 4 unknowns: 10 entries
def test_without_scaling_the_steps_are_optimistix_levenberg_marquardts(points):
    # The screening round's solver takes the same damped steps as optimistix's own LM (with
    # the normal equations by Cholesky, as before it replaced it): the same path, to
    # rounding, step by step, whether the step is written as one function (unrolled
    # Cholesky) or with LAPACK's solve. (Where the path ends depends on rounding: the
    # tolerance test passes a few steps apart on this ill-conditioned fit.)
    assert one_function(points, 4) == (points == 12)
    residuals = exponentials(points)
    unscaled = ScaledLevenbergMarquardt(rtol=1e-12, atol=1e-12,
                                        descent=MarquardtDescent(scaled=False))
    theirs = optx.LevenbergMarquardt(rtol=1e-12, atol=1e-12,
                                     linear_solver=lx.Normal(lx.Cholesky()))
    for steps in (2, 5, 12, 20):
        ours, _ = _solve(unscaled, residuals, EXPONENTIALS_START, max_steps=steps)
        reference, _ = _solve(theirs, residuals, EXPONENTIALS_START, max_steps=steps)
        np.testing.assert_allclose(ours.value, reference.value, rtol=1e-13, atol=1e-13)
    ours, _ = _solve(unscaled, residuals, EXPONENTIALS_START)
    np.testing.assert_allclose(ours.value, [2.0, 1.3, 0.5, 0.2], rtol=1e-8)


@pytest.mark.parametrize("cap", [0, 1, 3])
def test_a_step_cap_stops_where_optimistix_max_steps_stops(cap):
    capped, capped_steps = _solve(ScaledLevenbergMarquardt(rtol=1e-12, atol=1e-12,
                                                           cap=jnp.asarray(cap)),
                                  _exponentials, EXPONENTIALS_START)
    limited, limited_steps = _solve(ScaledLevenbergMarquardt(rtol=1e-12, atol=1e-12),
                                    _exponentials, EXPONENTIALS_START, max_steps=cap)
    assert capped_steps == limited_steps == cap
    assert capped.result == limited.result == optx.RESULTS.nonlinear_max_steps_reached
    np.testing.assert_array_equal(capped.value, limited.value)


def test_a_cap_beyond_convergence_changes_nothing():
    capped, capped_steps = _solve(ScaledLevenbergMarquardt(rtol=1e-12, atol=1e-12, cap=500),
                                  _exponentials, EXPONENTIALS_START)
    free, free_steps = _solve(ScaledLevenbergMarquardt(rtol=1e-12, atol=1e-12),
                              _exponentials, EXPONENTIALS_START)
    assert capped.result == free.result == optx.RESULTS.successful
    assert capped_steps == free_steps < 500
    np.testing.assert_array_equal(capped.value, free.value)


def test_free_coordinates_beyond_saturation_sit_exactly_on_the_bound():
    at_edges = from_free(np.array([-1e9, 1e9]), UNIT_SQUARE)
    just_inside = from_free(np.array([-SATURATED, SATURATED]), UNIT_SQUARE)
    np.testing.assert_array_equal(at_edges, just_inside)
    assert 0 < at_edges[0] < 1e-15 and 1 - at_edges[1] < 1e-15


def test_the_white_paint_ggx_fit_reaches_its_bounds_without_crawling(white_paint):
    # The paper's white paint back-scatters as no GGX can: its best GGX lies on the box's
    # corner alpha = 2, f0 = 1, which unscaled LM took 655 steps to approach.
    from brdfjax.compare import scipy_vp
    from brdfjax.fitting.fit import fit

    result = fit(white_paint, model="ggx", seed=0)
    assert result.status == "converged"
    assert {"alpha", "f0"} <= set(result.at_bounds)
    assert int(np.max(result.lm_steps)) < 150
    assert result.error <= scipy_vp(white_paint, "ggx", seed=0)[1] * (1 + 1e-9)
