"""Fitting: recovery of known parameters, reproducibility, status, and no recompilation."""

import os
from functools import partial

import jax
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import lsq_linear
from transcription import brdf as transcribed

from brdfjax.data.synthetic import paper_sample
from brdfjax.fitting.evolve import COUNTED, ascending, evolve
from brdfjax.fitting.fit import fit
from brdfjax.fitting.objective import _geometry, problem, projected, solve_linear
from brdfjax.fitting.polish import polish, polish_population, population_starts
from brdfjax.models import get
from brdfjax.models.bounds import (
    default_bounds,
    from_free,
    from_unit,
    make_bounds,
    to_free,
    to_unit,
)
from brdfjax.models.five import FRESNEL_FREE_A
from brdfjax.models.paper import FIVE, PAPER_SAMPLES, evaluate


@pytest.fixture(scope="module")
def clean_white_paint():
    return paper_sample("white_paint", noise=0.0)


@pytest.mark.parametrize("name", ["white_paint", "cement", "forged_steel"])
def test_noise_free_data_recover_the_parameters(name):
    data = paper_sample(name, noise=0.0)
    result = fit(data, seed=3)
    assert result.status == "converged"
    assert result.error < 1e-12
    np.testing.assert_allclose(result.vector, np.array(PAPER_SAMPLES[name]), rtol=1e-6)


def test_errors_match_an_independent_transcription_of_eq6(white_paint):
    result = fit(white_paint, validate_incidences_deg=[21, 52])
    d = white_paint
    with np.errstate(invalid="ignore", divide="ignore"):
        model = transcribed(*result.vector, d.theta_i, d.theta_r, d.phi_r)
    # At the exact specular points the paper's formula is 0/0: take its limit from both sides.
    singular = ~np.isfinite(model)
    sides = [transcribed(*result.vector, d.theta_i[singular], d.theta_r[singular] + e,
                         d.phi_r[singular]) for e in (1e-6, -1e-6)]
    model[singular] = np.mean(sides, axis=0)
    model *= np.cos(d.theta_r)
    measured = d.brdf * np.cos(d.theta_r)
    theta = np.round(np.degrees(d.theta_i))

    def e(mask):
        return np.sum((model[mask] - measured[mask]) ** 2) / np.sum(measured[mask] ** 2)

    held = np.isin(theta, [21, 52])
    assert result.error == pytest.approx(e(~held), rel=1e-9)
    assert result.validation_error == pytest.approx(e(held), rel=1e-9)
    for deg, value in result.validation_by_incidence.items():
        assert value == pytest.approx(e(theta == deg), rel=1e-9)
    assert set(result.error_by_incidence) == {10.0, 30.0, 45.0, 60.0}
    assert np.sum(result.residuals**2) == pytest.approx(result.error, rel=1e-12)
    # 2.5 % noise: E is about 0.025^2, and the fit is close to the truth
    assert 2e-4 < result.error < 1e-3
    np.testing.assert_allclose(result.vector[[1, 4]], [2.24, 0.22], rtol=0.02)


def test_same_seed_same_result_other_seed_other_path(white_paint):
    first = fit(white_paint, seed=11)
    again = fit(white_paint, seed=11)
    other = fit(white_paint, seed=12)
    np.testing.assert_array_equal(first.vector, again.vector)
    np.testing.assert_array_equal(first.history, again.history)
    assert not np.array_equal(first.history, other.history)


def test_a_fit_that_cannot_converge_says_so(clean_white_paint):
    result = fit(clean_white_paint, "lm", starts=2, max_steps=2)
    assert result.status == "max_steps"
    assert not result.lm_success.any()
    assert result.error > 1e-6
    # print(result) reads as a summary: no residuals (hundreds of them) or per-start arrays
    text = repr(result)
    assert "kb=" in text and "status='max_steps'" in text and len(text) < 1500
    assert not any(f"{name}=" in text for name in ("residuals", "lm_steps", "history"))


def test_methods_ga_and_lm(clean_white_paint):
    ga = fit(clean_white_paint, "ga")
    assert ga.status == "search_only" and ga.lm_steps.size == 0 and ga.history.size > 0
    assert np.all(np.diff(ga.history) <= 0)  # elitism: the best never gets worse
    # The search alone must land in the truth's basin, below the E that 2.5 % noise gives
    # (0.025^2), where LM takes over: seeds 0-5 ended at 3.6e-6 to 3.6e-4 (this one, seed
    # 0, at 3.5e-5). kr and kd are pinned by the data; a and b trade off along a valley.
    assert ga.error < 0.025**2
    np.testing.assert_allclose(ga.vector[[1, 4]], np.array(PAPER_SAMPLES["white_paint"])[[1, 4]],
                               rtol=0.05)
    lm = fit(clean_white_paint, "lm", start=np.array(PAPER_SAMPLES["white_paint"]) * 1.05)
    assert lm.status == "converged" and lm.error < 1e-20


def test_parameter_at_a_bound_is_reported(clean_white_paint):
    narrow = make_bounds({"kd": (0.3, 1.0)})  # the truth 0.22 lies outside
    result = fit(clean_white_paint, bounds=narrow)
    assert "kd" in result.at_bounds
    assert result.params.kd == pytest.approx(0.3, rel=1e-6)


def test_second_fit_of_same_shaped_data_does_not_recompile(clean_white_paint):
    fit(clean_white_paint, seed=1)
    compiled = [f._cache_size() for f in (evolve, population_starts, polish, _geometry)]
    other = paper_sample("white_paint", noise=0.01, seed=5)
    fit(other, seed=2, bounds=make_bounds({"b": (-90.0, 20.0)}))  # new data, new bounds
    assert [f._cache_size() for f in (evolve, population_starts, polish, _geometry)] == compiled


def test_a_population_that_breeds_nothing_is_a_clear_error(clean_white_paint):
    prob, bounds = problem(clean_white_paint), default_bounds()
    with pytest.raises(ValueError, match="not a multiple of islands 8"):
        evolve(0, prob, bounds, population_size=36)
    with pytest.raises(ValueError, match="nothing would be bred; give at least 40"):
        evolve(0, prob, bounds, population_size=32)


def test_repeated_starts_are_skipped_and_change_nothing(clean_white_paint):
    prob, bounds = problem(clean_white_paint), default_bounds()
    u = to_free(np.array([PAPER_SAMPLES[name] for name in ("white_paint", "cement",
                                                              "khaki_paint")]), bounds)
    steps = {"max_steps": 50, "screen_steps": 5, "keep": 2}
    alone = polish(u, prob, bounds, **steps)
    repeated = polish(u[[0, 1, 0, 2, 1]], prob, bounds, **steps)
    np.testing.assert_array_equal(repeated.errors, alone.errors)
    np.testing.assert_array_equal(repeated.steps, alone.steps)
    assert repeated.evaluations == alone.evaluations
    # Fewer distinct starts than survive screening: the repeat that survives is not rerun.
    few = polish(u[[0, 0, 0, 1]], prob, bounds, **{**steps, "keep": 3})
    assert np.isinf(few.errors[2]) and few.steps[2] == 0 and np.all(few.steps[:2] > 0)
    # each real start: a residual and a 5-column Jacobian at its start and per step, twice
    assert few.evaluations == 6 * np.sum(few.steps[:2] + 2)


def _children(z, elite, crossover_rate, mutation_rate, rounds=4000, seed=0):
    """`breed` of island ``z`` on ``rounds`` independent uniform draws: (rounds, children, P)."""
    from brdfjax.fitting.evolve import EvolveConfig, breed, draw_count

    tournament = 3
    config = EvolveConfig(mutation_rate=mutation_rate, mutation_scale=0.05,
                          crossover_rate=crossover_rate)
    bits = np.random.default_rng(seed).integers(
        0, 2**16, (rounds, len(z) - elite, draw_count(tournament, z.shape[1])), np.uint16)
    one = jax.jit(jax.vmap(breed, in_axes=(0, None, None, None)), static_argnums=2)
    return np.asarray(one(bits, jax.numpy.asarray(z, np.float32), tournament, config))


_ascending = jax.jit(ascending)


@settings(deadline=None, max_examples=60)
@given(st.sampled_from([12, 16, COUNTED, COUNTED + 1]), st.integers(1, 8), st.data())
def test_the_search_orders_its_islands_as_a_stable_sort(members, islands, data):
    """`ascending` against NumPy's stable argsort, ties, -0.0 and +-inf (+inf: a NaN score)
    included, on islands it counts (up to `COUNTED` members) and on islands it sorts."""
    pool = st.sampled_from([0.0, -0.0, 1e-7, 0.5, 2.0, -3.0, np.inf, -np.inf])
    values = np.asarray(data.draw(st.lists(pool, min_size=members * islands,
                                           max_size=members * islands)),
                        dtype=np.float32).reshape(islands, members)
    np.testing.assert_array_equal(_ascending(values), np.argsort(values, axis=-1, kind="stable"))
    sorted_ = "sort" in str(jax.make_jaxpr(ascending)(values))
    assert sorted_ == (members > COUNTED)


def test_the_genetic_search_breeds_as_its_draws_say():
    """`breed` from uniform 16-bit draws, against closed forms, on an island of 12 members
    (not a power of two): tournament winners (the best of 3 uniform entrants), the
    mutation's rate, mean and spread, and the BLX-0.5 blend's share and uniform spread."""
    from scipy import stats

    members, elite = 12, 4
    # Without crossover or mutation a child is its first parent: member k holds k / 16.
    ranks = _children(np.arange(members)[:, None].repeat(5, 1) / 16, elite, 0.0, 0.0)
    winners = np.round(ranks[..., 0] * 16).astype(int).ravel()
    k = np.arange(members)
    expected = ((members - k) ** 3 - (members - k - 1) ** 3) / members**3
    counts = np.bincount(winners, minlength=members)
    assert stats.chisquare(counts, expected * counts.sum()).pvalue > 1e-4
    # Mutation alone, on equal members: a gene moves with the rate, by N(0, 0.05).
    moved = _children(np.full((members, 5), 0.5), elite, 0.0, 0.2, seed=1) - 0.5
    share = np.mean(moved != 0)
    assert abs(share - 0.2) < 5 * np.sqrt(0.2 * 0.8 / moved.size)
    one_gene = np.mean(np.sum(moved != 0, axis=-1) == 1)  # each gene on its own draw
    assert abs(one_gene - 5 * 0.2 * 0.8**4) < 5 * np.sqrt(0.41 * 0.59 / moved[..., 0].size)
    steps = moved[moved != 0]
    assert abs(steps.mean()) < 5 * 0.05 / np.sqrt(steps.size)
    assert steps.std() == pytest.approx(0.05, rel=0.02)
    # The blend: members alternate 0.25 / 0.75; parents that differ give
    # first + beta (second - first) with beta ~ U(-0.5, 1.5): a child uniform on (0, 1).
    z = np.where(k % 2 == 0, 0.25, 0.75)[:, None].repeat(5, 1)
    blended = _children(z, elite, 0.9, 0.0, seed=2)
    genes = np.sum((blended != 0.25) & (blended != 0.75), axis=-1)
    assert set(np.unique(genes)) == {0, 5}  # a child is crossed whole, or not at all
    blended = blended.ravel()
    mixed = blended[(blended != 0.25) & (blended != 0.75)]
    even = expected[::2].sum()
    assert abs(mixed.size / blended.size - 0.9 * 2 * even * (1 - even)) < 0.01
    assert stats.kstest(mixed, "uniform").pvalue > 1e-4


def _first(data, points):
    return data.select(np.arange(len(data)) < points)


@pytest.mark.parametrize("points", [64, 716])
def test_the_residuals_jvp_is_plain_autodiff_in_the_parameters_and_the_data(white_paint,
                                                                            points):
    """LM's residuals form their Jacobian in a custom JVP rule (`_free_residuals`): its
    tangents equal those of the plain function, in the free coordinates and, where someone
    differentiates in them, in the measured values (a straightforward derivative); on a
    problem small enough for LM's loop to run as one function (its products written as
    sums of columns) and on a larger one."""
    from brdfjax.fitting.objective import residuals
    from brdfjax.fitting.polish import _free_residuals

    prob, bounds = problem(_first(white_paint, points)), default_bounds()
    u = to_free(np.asarray(PAPER_SAMPLES["white_paint"]), bounds)
    du = np.linspace(-1.0, 1.0, 5)
    dt = np.cos(np.arange(prob.target.size))

    def custom(u, target):
        return _free_residuals(u, (prob._replace(target=target), bounds))

    def plain(u, target):
        return residuals(from_free(u, bounds), prob._replace(target=target))

    for tangents in ((du, np.zeros_like(dt)), (du, dt)):
        value, tangent = jax.jvp(custom, (u, prob.target), tangents)
        expected, expected_tangent = jax.jvp(plain, (u, prob.target), tangents)
        np.testing.assert_allclose(value, expected, rtol=1e-14, atol=1e-16)
        np.testing.assert_allclose(tangent, expected_tangent, rtol=1e-12, atol=1e-14)
    # in the data alone (the parameters' tangent a symbolic zero), and linearised in u and
    # transposed, as LM uses it
    _, tangent = jax.jvp(lambda t: custom(u, t), (prob.target,), (dt,))
    _, expected_tangent = jax.jvp(lambda t: plain(u, t), (prob.target,), (dt,))
    np.testing.assert_allclose(tangent, expected_tangent, rtol=1e-12, atol=1e-14)
    _, linear = jax.linearize(lambda u: custom(u, prob.target), u)
    _, expected_linear = jax.linearize(lambda u: plain(u, prob.target), u)
    np.testing.assert_allclose(linear(du), expected_linear(du), rtol=1e-12, atol=1e-14)
    (back,) = jax.linear_transpose(linear, u)(dt)
    (expected_back,) = jax.linear_transpose(expected_linear, u)(dt)
    np.testing.assert_allclose(back, expected_back, rtol=1e-12, atol=1e-14)
    # in u alone, as LM linearises it: the Jacobian against central differences
    # (each difference rounds to a few eps |sqrt(w) f| / step: the absolute tolerance)
    jacobian = jax.jacfwd(lambda u: _free_residuals(u, (prob, bounds)))(u)
    step = 1e-6
    rounding = 1e-8 * np.abs(np.sqrt(prob.weight) * prob.target).max()
    for k in range(5):
        e = np.eye(5)[k] * step
        difference = (plain(u + e, prob.target) - plain(u - e, prob.target)) / (2 * step)
        np.testing.assert_allclose(jacobian[:, k], difference, rtol=1e-5,
                                   atol=max(rounding, 1e-8 * np.abs(difference).max()))


@pytest.mark.skipif("xla_cpu_small_while_loop_byte_threshold" not in os.environ["XLA_FLAGS"],
                    reason="brdfjax sets XLA's small-loop threshold only on the jaxlib it measured")
@pytest.mark.parametrize("name, one, beyond", [("five", 256, 320), ("ggx+ggx", 128, 192)])
def test_levenberg_marquardt_on_a_small_problem_compiles_as_one_function(white_paint, name,
                                                                         one, beyond):
    """On a small problem (`one_function`) LM's loop holds nothing that keeps XLA:CPU from
    compiling it as one function (no LAPACK call, no operation handed to YNNPACK); on a
    larger one, and with the starts side by side, it keeps LAPACK's solve and its kernels
    (`brdfjax.fitting.marquardt`). A sum of two lobes (7 unknowns) is small on fewer points:
    on 192, XLA would hand its Gram reduction to YNNPACK."""
    from brdfjax.fitting.marquardt import one_function

    model = get(name)
    bounds = default_bounds(model)
    starts = np.zeros((3, model.size))
    for points, side_by_side, compact in ((one, False, True), (beyond, False, False),
                                          (one, True, False)):
        assert one_function(points, model.size) == (points == one)
        prob = problem(_first(white_paint, points), model)
        text = jax.jit(partial(polish, bounds=bounds, side_by_side=side_by_side)).lower(
            starts, prob).compile().as_text()
        assert ("xla_cpu_small_call" in text) == compact
        assert ("lapack" in text) != compact
        assert "ynn" not in text or not compact


def test_fresnel_free_start(clean_white_paint):
    prob, bounds = problem(clean_white_paint), default_bounds()
    free = from_unit(FIVE.extra_starts(jax.numpy.full((1, 5), 0.7), bounds)[0], bounds)
    assert free[3] == 0.0 and free[2] == pytest.approx(FRESNEL_FREE_A, rel=1e-12)
    other_a = free.at[2].set(30.0)  # with b = 0, R0 = 1 whatever a is
    np.testing.assert_array_equal(evaluate(free, prob.scene), evaluate(other_a, prob.scene))
    # polish_population adds it as a 17th start; where b cannot be 0 it is a skipped repeat
    population = evolve(0, prob, bounds).population
    for b_range, runs in (((-150.0, 80.0), True), ((-150.0, -10.0), False)):
        polished = polish_population(population, prob, make_bounds({"b": b_range}),
                                     max_steps=2, keep=17)
        assert polished.steps.shape == (17,) and (polished.steps[16] > 0) == runs


def transcribed_residuals(data):
    """Residuals of Eq. (6) by the transcription (E = their squared norm), for SciPy."""
    cos_r = np.cos(data.theta_r)
    measured = data.brdf * cos_r
    norm = np.sqrt(np.sum(measured**2))

    def residuals(p):
        with np.errstate(invalid="ignore", divide="ignore"):
            model = transcribed(*p, data.theta_i, data.theta_r, data.phi_r)
            singular = ~np.isfinite(model)  # the exact specular points: the 0/0 limit
            model[singular] = np.mean([transcribed(*p, data.theta_i[singular],
                                                   data.theta_r[singular] + e,
                                                   data.phi_r[singular]) for e in (1e-6, -1e-6)],
                                      axis=0)
        return (model * cos_r - measured) / norm

    return residuals


NOISY_CEMENT_START = np.array([2.3806e-3, 3.2013, 0.0100000001, 0.20696, 0.067036])


def noisy_cement():
    """The cement with noise seed 1003, and E at its best fit by SciPy's least_squares on the
    transcription from `NOISY_CEMENT_START`, in the same box (5.8967110e-4)."""
    from scipy.optimize import least_squares

    data = paper_sample("cement", noise=0.025, seed=1003).at_incidences([10, 30, 45, 60])
    bounds = default_bounds()
    low, high = np.asarray(bounds.lower), np.asarray(bounds.upper)
    reference = least_squares(transcribed_residuals(data), NOISY_CEMENT_START,
                              bounds=(low, high), x_scale=np.abs(NOISY_CEMENT_START) + 1e-3,
                              ftol=1e-15, xtol=1e-15, gtol=1e-15)
    return data, reference


def test_noisy_cement_reaches_the_best_fit_of_a_long_search():
    """Noise seed 1003: the basin of the best fit lies at a's lower bound, reached before the
    Fresnel-free start only by a long search (3 fits of 2048 members x 200 generations and
    64 starts). NOISY_CEMENT_START, that search's best parameters, is a regression pin of
    where the basin is; the E there is not: SciPy's least_squares on the transcription, from
    the same start in the same box, gives it independently. The default fit reaches it from
    the seeds 0, 1 and 2; one may miss (a search's seed picks its path, so one seed pins
    nothing). How often, over the seeds 0-29, is the slow test below (28 of 30 at least)."""
    data, reference = noisy_cement()
    e_scipy = 2 * reference.cost
    best = fit(data, "lm", start=NOISY_CEMENT_START)
    assert best.error == pytest.approx(e_scipy, rel=1e-6)
    np.testing.assert_allclose(best.vector, reference.x, rtol=1e-5)
    reached = [fit(data, seed=seed).error <= e_scipy * (1 + 1e-6) for seed in range(3)]
    assert sum(reached) >= 2, reached


# Runs with `pytest -m slow tests/test_fit.py` (pyproject's addopts leave it out of the
# default suite): 30 fits, about 1 min alone on the 2-core machine, 2 min loaded.
@pytest.mark.slow
def test_noisy_cement_is_reached_from_nearly_every_seed():
    """The default fit reaches the best fit of the noisy cement from at least 28 of the
    seeds 0-29 (29 since the search's scoring changed, seed 3 not; 29 before, seed 19 not).
    benchmarks/bench_fit.py's section noisy checks the same over 20 noise seeds of each
    paper sample (cement's 1000-1019, 1003 among them)."""
    data, reference = noisy_cement()
    e_scipy = 2 * reference.cost
    reached = [fit(data, seed=seed).error <= e_scipy * (1 + 1e-6) for seed in range(30)]
    assert sum(reached) >= 28, reached


def test_bound_transforms_round_trip():
    bounds = default_bounds()
    p = np.array(PAPER_SAMPLES["cement"])
    np.testing.assert_allclose(from_free(to_free(p, bounds), bounds), p, rtol=1e-12)
    z = np.asarray(to_unit(p, bounds))
    assert np.all((z > 0) & (z < 1))
    # b on the asinh scale: b = 0 sits where asinh(0) = 0 falls between asinh of the bounds
    low, high = np.arcsinh(-150.0), np.arcsinh(80.0)
    assert to_unit(np.array([1.0, 1.0, 1.0, 0.0, 1.0]), bounds)[3] == pytest.approx(
        -low / (high - low), rel=1e-14)
    linear = make_bounds({"b": (-4.0, 6.0)}, scales={"b": "linear"})
    assert from_unit(np.full(5, 0.25), linear)[3] == pytest.approx(-1.5, rel=1e-14)
    with pytest.raises(ValueError, match="lower bound must be positive"):
        make_bounds({"kb": (0.0, 1.0)})
    with pytest.raises(ValueError, match="unknown parameter"):
        make_bounds({"kx": (0.0, 1.0)})
    with pytest.raises(ValueError, match="unknown scale"):
        make_bounds({}, scales={"b": "log"})


LINEAR_SOLVE = jax.jit(solve_linear)


@settings(max_examples=60, deadline=None)
@given(kr=st.floats(1e-2, 1e2), a=st.floats(1e-2, 1e2), b=st.floats(-150.0, 80.0),
       kd_range=st.sampled_from([(1e-8, 1e2), (0.3, 1.0), (1e-8, 0.05)]),
       kb_range=st.sampled_from([(1e-14, 1e3), (0.5, 2.0)]))
def test_linear_coefficients_match_bounded_least_squares(white_paint, kr, a, b, kd_range,
                                                         kb_range):
    """kb, kd and E of the exact 2-D solve equal SciPy's bounded linear least squares."""
    prob = problem(white_paint.at_incidences([10, 30]))
    bounds = make_bounds({"kb": kb_range, "kd": kd_range})
    solved, e = LINEAR_SOLVE(np.array([1.0, kr, a, b, 1.0]), prob, bounds)
    kb, kd, e = float(solved[0]), float(solved[4]), float(e)
    # SciPy on the same columns: the projected lobe (kb = 1, kd = 0) and cos(tr)
    lobe = np.asarray(projected(np.array([1.0, kr, a, b, 0.0]), prob.scene))
    root = np.sqrt(np.asarray(prob.weight))
    scale = max(np.max(np.abs(lobe)), 1e-300)  # SciPy needs columns of comparable size
    columns = root[:, None] * np.stack([lobe / scale, np.asarray(prob.scene.cos_theta_r)], 1)
    reference = lsq_linear(columns, root * np.asarray(prob.target), method="bvls", tol=1e-14,
                           bounds=([kb_range[0] * scale, kd_range[0]],
                                   [kb_range[1] * scale, kd_range[1]]))
    e_scipy = float(np.sum(reference.fun**2))
    e_direct = float(np.sum(np.asarray(prob.weight) * (
        np.asarray(projected(np.array([kb, kr, a, b, kd]), prob.scene)) - prob.target) ** 2))
    assert kb_range[0] <= kb <= kb_range[1] and kd_range[0] <= kd <= kd_range[1]
    assert e == pytest.approx(e_direct, rel=1e-9, abs=1e-14)
    assert e_direct <= e_scipy * (1 + 1e-9) + 1e-14


def test_evolve_takes_a_seed_a_typed_key_or_a_legacy_key():
    import jax

    from brdfjax.fitting.objective import problem

    prob = problem(paper_sample("khaki_paint", noise=0.0).at_incidences([10]))
    runs = [evolve(key, prob, default_bounds(), max_generations=2).errors
            for key in (5, jax.random.key(5), jax.random.PRNGKey(5))]
    np.testing.assert_array_equal(runs[0], runs[1])
    np.testing.assert_array_equal(runs[0], runs[2])


def test_library_calls_check_measurements_built_in_python(white_paint):
    """Measurements built in Python have not been through load()'s checks: fit, predict
    and compare_models check them, as fit_batch did (degrees read as radians converged)."""
    from types import SimpleNamespace

    from brdfjax.data.measurements import DataError, Measurements
    from brdfjax.prediction.intervals import predict
    from brdfjax.prediction.selection import compare_models

    degrees = Measurements(*(np.degrees(x) for x in (white_paint.theta_i, white_paint.theta_r,
                                                     white_paint.phi_r)), white_paint.brdf)
    with pytest.raises(DataError, match=r"did you mean np.radians\(10\)\? \(Measurements"
                                        r"\.from_degrees takes degrees\)"):
        fit(degrees, model="ggx")
    broken = Measurements(white_paint.theta_i, white_paint.theta_r, white_paint.phi_r,
                          np.where(np.arange(len(white_paint)) == 3, np.nan, white_paint.brdf))
    with pytest.raises(DataError, match="brdf is nan"):
        fit(broken)
    with pytest.raises(TypeError, match=r"fit takes Measurements, got str: read a file with "
                                        r"brdfjax.load\(path\)"):
        fit("white_paint.csv")
    with pytest.raises(TypeError, match="predict takes a fit's result"):
        predict(get("ggx").Params(1.0, 0.3, 0.04, 0.01), white_paint)
    with pytest.raises(DataError, match="did you mean np.radians"):
        predict(SimpleNamespace(training=white_paint), degrees)
    with pytest.raises(ValueError, match="unknown discrepancy 'GP'"):  # before any work
        predict(SimpleNamespace(training=white_paint), white_paint, discrepancy="GP")
    with pytest.raises(ValueError, match="unknown discrepancy 'GP'"):
        compare_models(white_paint, "ggx,five", discrepancy="GP")
    with pytest.raises(ValueError, match="unknown model 'nope'"):  # a string of names
        compare_models(white_paint, "ggx, nope")


def test_a_single_held_out_incidence_needs_no_list(white_paint):
    from brdfjax.fitting.fit import split

    train, held = split(white_paint, 21)
    assert list(held.incidences_deg) == [21.0] and 21.0 not in train.incidences_deg


def test_a_fit_that_raises_leaves_no_compilation_running(white_paint):
    """The polish compiled ahead in a thread was left running after the search refused its
    arguments: at the end of a script, the process crashed at exit (1 run in 8). A size is
    refused before the thread starts; an error inside the search waits for it."""
    import threading

    with pytest.raises(ValueError, match="population_size 12 is not a multiple of islands 8"):
        fit(white_paint, population_size=12)
    assert "brdfjax polish compiled ahead" not in [t.name for t in threading.enumerate()]
    with pytest.raises(TypeError, match="the seed must be an integer or a JAX PRNG key, "
                                        "got a float64"):
        fit(white_paint, seed=1.5, population_size=48)  # sizes not compiled ahead before
    assert "brdfjax polish compiled ahead" not in [t.name for t in threading.enumerate()]


def test_arguments_of_the_wrong_shape_or_order_are_said(white_paint):
    """Each ended in a NumPy broadcast error or a bare TypeError (a newcomer's review)."""
    from brdfjax.fitting.batch import fit_batch
    from brdfjax.uncertainty.laplace import laplace_approximation

    with pytest.raises(ValueError, match=r"start: give 5 parameters of the five model \(kb, "
                                         r"kr, a, b, kd\), or \(S, 5\) for S starts; got "
                                         r"shape \(3,\)"):
        fit(white_paint, method="lm", start=[1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="3 seeds for 2 samples: give one seed, or one per"):
        fit_batch([white_paint, white_paint], seed=[1, 2, 3])
    result = fit(white_paint, method="lm", start=np.array(PAPER_SAMPLES["white_paint"]),
                 max_steps=5)
    with pytest.raises(TypeError, match=r"the measurements come first, then the fit"):
        laplace_approximation(result, white_paint)


def test_no_more_geometries_than_parameters_is_underdetermined_not_converged():
    """Two readings fitted by GGX's four parameters were reported ``converged`` (E of
    4.6e-27 %, ks = 363; issue 47, defect 1). Geometries are counted once however often
    they are read, with phi_r folded into 0..180 deg and no azimuth at theta_r = 0; a fit
    of no more of them than free parameters is ``underdetermined``, says why and warns."""
    from brdfjax.data.measurements import Measurements
    from brdfjax.fitting.fit import UnderdeterminedWarning, distinct_geometries, settled

    five = get("five")
    points = Measurements.from_degrees(
        np.full(8, 30.0), [20, 20, 20, 20, 20, 20, 0, 0], [0, 0, 360, 30, -30, 330, 0, 90],
        np.full(8, 0.1))
    assert distinct_geometries(points) == 3  # (20, 0), (20, 30) and the normal
    assert settled("converged", 5, five) == "underdetermined"
    assert settled("max_steps", 5, five) == "underdetermined"
    assert settled("converged", 6, five) == "converged" and settled("failed", 1, five) == "failed"
    assert list(settled(np.array(["converged", "failed", "max_steps"]), np.array([2, 2, 9]),
                        five)) == ["underdetermined", "failed", "max_steps"]
    # Lambert's one parameter: one geometry read twice fits exactly and says nothing
    twice = Measurements.from_degrees([30.0, 30.0], [20.0, 20.0], [0.0, 0.0], [0.1, 0.1])
    with pytest.warns(UnderdeterminedWarning, match="1 distinct geometry .* for the 1 "
                                                     "parameters of lambert"):
        alone = fit(twice, model="lambert")
    assert alone.status == "underdetermined" and "a small E proves nothing" in alone.message
    assert alone.to_dict()["status"] == "underdetermined"
    two = Measurements.from_degrees([30.0, 30.0], [20.0, 40.0], [0.0, 0.0], [0.1, 0.12])
    assert fit(two, model="lambert").status == "converged"
