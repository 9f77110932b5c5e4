"""The model of Eq. (5): against a transcription of the paper, at every edge of its domain."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from transcription import brdf as transcribed
from transcription import generic_points
from transcription import shadowing as transcribed_shadowing

from brdfjax.models.geometry import ShadowingConstants, scene
from brdfjax.models.paper import PAPER_SAMPLES, Params, brdf, evaluate, projected_brdf

HALF_PI = np.pi / 2
SAMPLES = list(PAPER_SAMPLES.values())


@pytest.mark.parametrize("in_plane", [False, True])
@pytest.mark.parametrize("params", SAMPLES, ids=list(PAPER_SAMPLES))
def test_float64_matches_transcription_to_1e12(params, in_plane):
    ti, tr, pr = generic_points(2000, 1, in_plane)
    exact = transcribed(*(np.longdouble(p) for p in params),
                        *(x.astype(np.longdouble) for x in (ti, tr, pr)))
    got = np.asarray(brdf(params, ti, tr, pr))
    assert got.dtype == np.float64
    np.testing.assert_allclose(got, exact.astype(float), rtol=1e-12, atol=0)


@pytest.mark.parametrize("params", SAMPLES, ids=list(PAPER_SAMPLES))
def test_float32_matches_transcription_to_1e5(params):
    ti, tr, pr = generic_points(2000, 2, in_plane=False)
    exact = transcribed(*params, ti, tr, pr)
    got = np.asarray(brdf(jnp.asarray(np.array(params), jnp.float32),
                          *(x.astype(np.float32) for x in (ti, tr, pr))))
    assert got.dtype == np.float32
    np.testing.assert_allclose(got, exact, rtol=1e-5, atol=0)


def test_in_plane_fast_path_equals_general_path():
    ti, tr, pr = generic_points(500, 3, in_plane=True)
    for params in SAMPLES:
        fast = evaluate(params, scene(ti, tr, pr, in_plane=True))
        general = evaluate(params, scene(ti, tr, pr, in_plane=False))
        np.testing.assert_allclose(fast, general, rtol=1e-11)


def test_named_and_vector_parameters_agree():
    p = PAPER_SAMPLES["khaki_paint"]
    assert float(brdf(p, 0.3, 0.5, 2.0)) == float(brdf(np.array(p), 0.3, 0.5, 2.0))
    assert Params.from_vector(p.vector()) == Params(*map(jnp.asarray, p))


@pytest.mark.parametrize("changed", [{"sigma_sph": 0.05}, {"sigma_r": 0.2}, {"u_sph": 3.0},
                                     {"v_sph": 2.5}, {"sigma_sph": 0.002, "sigma_r": 0.0}],
                         ids=lambda c: ",".join(c))
def test_overridden_constants_match_the_transcription(changed):
    """Each shadowing constant of Eq. (3)-(4) reaches G: values equal the transcription
    evaluated with the same constants, and differ from the paper's (by more than 0.1 % where the
    lobe is visible)."""
    constants = ShadowingConstants(**changed)
    ti, tr, pr = generic_points(300, 4, in_plane=False)
    p = PAPER_SAMPLES["white_paint"]
    exact = transcribed(*(np.longdouble(x) for x in p),
                        *(x.astype(np.longdouble) for x in (ti, tr, pr)), constants=constants)
    got = np.asarray(brdf(p, ti, tr, pr, constants))
    np.testing.assert_allclose(got, exact.astype(float), rtol=1e-12, atol=0)
    assert np.max(np.abs(got / np.asarray(brdf(p, ti, tr, pr)) - 1)) > 1e-3


# ---- limits where the formulas break: values and gradients finite, and the right value

def _value_and_grads(in_plane):
    def f(params, angles):
        return evaluate(params, scene(*angles, in_plane=in_plane))

    return jax.jit(lambda p, a: (f(p, a), *jax.grad(f, argnums=(0, 1))(p, a)))


VALUE_AND_GRADS = {flag: _value_and_grads(flag) for flag in (False, True)}


def all_finite(*trees):
    return all(bool(jnp.all(jnp.isfinite(x))) for x in jax.tree.leaves(trees))


EDGE_POINTS = {
    "specular": (0.6, 0.6, np.pi),
    "back-scatter": (0.6, 0.6, 0.0),
    "normal both": (0.0, 0.0, 0.0),
    "normal incidence grazing view": (0.0, HALF_PI, 1.0),
    "grazing both, specular (w_r = -w_i)": (HALF_PI, HALF_PI, np.pi),
    "grazing both, back-scatter": (HALF_PI, HALF_PI, 0.0),
    "grazing incidence": (HALF_PI, 0.4, np.pi),
    "grazing view": (0.4, HALF_PI, np.pi),
    "grazing view, source side": (0.4, HALF_PI, 0.0),
}
STEP = 1e-7
# Where the transcription (0/0 at most edges) is evaluated instead: points STEP inside the
# domain, along a path that avoids its other singular points; their mean is the limit.
# Back-scatter needs none: the printed formulas are finite there.
APPROACH = {
    "specular": [(0.6, 0.6 + STEP, np.pi), (0.6, 0.6 - STEP, np.pi)],
    "back-scatter": [(0.6, 0.6, 0.0)],
    "normal both": [(STEP, STEP, 0.0)],  # along the back-scatter line (a cusp if a < 1/2)
    "normal incidence grazing view": [(STEP, HALF_PI - STEP, 1.0)],
    "grazing both, specular (w_r = -w_i)": [(HALF_PI - 2 * STEP, HALF_PI - STEP, np.pi)],
    "grazing both, back-scatter": [(HALF_PI - STEP, HALF_PI - STEP, 0.0)],
    "grazing incidence": [(HALF_PI - STEP, 0.4, np.pi)],
    "grazing view": [(0.4, HALF_PI - STEP, np.pi)],
    "grazing view, source side": [(0.4, HALF_PI - STEP, 0.0)],
}


@pytest.mark.parametrize("point", EDGE_POINTS.values(), ids=list(EDGE_POINTS))
@pytest.mark.parametrize("params", SAMPLES, ids=list(PAPER_SAMPLES))
def test_edges_are_finite_on_both_paths(point, params):
    in_plane = np.sin(point[2]) == 0
    for flag in {False, in_plane}:
        values = VALUE_AND_GRADS[flag](jnp.asarray(params), tuple(map(jnp.asarray, point)))
        assert all_finite(values)


@pytest.mark.parametrize("edge", list(EDGE_POINTS))
@pytest.mark.parametrize("params", SAMPLES, ids=list(PAPER_SAMPLES))
def test_edges_are_the_transcriptions_limits(edge, params):
    """At every edge point the value is the printed formula's limit (to 2e-6: the formula is
    taken 1e-7 away, and its slope there reaches ~5 per radian, relative)."""
    p = np.array(params)
    with np.errstate(invalid="ignore", divide="ignore"):
        near = np.mean([transcribed(*(np.longdouble(x) for x in p),
                                    *(np.longdouble(x) for x in point))
                        for point in APPROACH[edge]])
    assert np.isfinite(near)
    assert float(brdf(p, *EDGE_POINTS[edge])) == pytest.approx(float(near), rel=2e-6)


def test_specular_value_is_the_in_plane_limit():
    """At the specular point the model equals its limit along the plane of incidence."""
    p = jnp.asarray(PAPER_SAMPLES["khaki_paint"])
    at = float(brdf(p, 0.6, 0.6, np.pi, ))
    near = [float(transcribed(*np.array(p), 0.6, 0.6 + e, np.pi)) for e in (1e-4, -1e-4)]
    assert at == pytest.approx(np.mean(near), rel=1e-6)
    assert float(evaluate(p, scene(0.6, 0.6, np.pi, in_plane=False))) == pytest.approx(at, 1e-12)


def test_grazing_value_is_the_limit():
    """G / cos(tr) at tr = 90 deg is the limit of the paper's formula as tr -> 90 deg."""
    p = np.array(PAPER_SAMPLES["forged_steel"])
    for phi in (0.0, 1.0, np.pi):
        at = float(brdf(p, 0.5, HALF_PI, phi))
        near = float(transcribed(*p, 0.5, HALF_PI - 1e-7, phi))
        assert at == pytest.approx(near, rel=1e-6)


def test_back_scatter_value_and_a_derivative():
    """R0 = 1 exactly at back-scatter, and dE/da is finite there (0 log 0 avoided)."""
    p = jnp.asarray(PAPER_SAMPLES["white_paint"])
    value, grad_p, _ = VALUE_AND_GRADS[True](p, (jnp.asarray(0.6), jnp.asarray(0.6),
                                                 jnp.asarray(0.0)))
    kb, kr, _, _, kd = np.array(p)
    shadowing, alpha, cos_g = transcribed_shadowing(0.6, 0.6, 0.0)  # the printed Eq. (3)-(4)
    assert alpha == pytest.approx(0.6, rel=1e-12) and cos_g == 1.0
    facets = kr**2 * np.cos(0.6) / (np.sin(0.6) ** 2 + kr**2 * np.cos(0.6) ** 2)  # alpha = ti
    expected = kb * facets * 1.0 * shadowing / np.cos(0.6) + kd  # R0(0) = 1
    assert float(value) == pytest.approx(expected, rel=1e-14)
    assert float(grad_p[2]) == 0.0


angle = st.floats(0.0, HALF_PI)
azimuth = st.floats(-2 * np.pi, 4 * np.pi) | st.sampled_from([0.0, np.pi, -np.pi, 2 * np.pi])
edge_angle = angle | st.sampled_from([0.0, HALF_PI])
parameters = st.tuples(
    st.floats(1e-14, 1e3), st.floats(1e-2, 1e2), st.floats(1e-2, 1e2),
    st.floats(-150.0, 80.0), st.floats(1e-8, 1e2))


@settings(max_examples=300, deadline=None)
@given(params=parameters, ti=edge_angle, tr=edge_angle, pr=azimuth)
def test_finite_everywhere(params, ti, tr, pr):
    """No NaN or inf in values or gradients, anywhere, for parameters across the box."""
    values = VALUE_AND_GRADS[False](jnp.asarray(params), (jnp.asarray(ti), jnp.asarray(tr),
                                                          jnp.asarray(pr)))
    assert all_finite(values)


@settings(max_examples=100, deadline=None)
@given(params=st.sampled_from(SAMPLES), ti=st.floats(0.05, 1.4), tr=st.floats(0.05, 1.4),
       pr=st.floats(0.1, 2 * np.pi - 0.1))
def test_gradients_match_finite_differences(params, ti, tr, pr):
    if abs(ti - tr) < 0.05 and abs(np.cos(pr)) > 0.99:
        return  # next to the specular and back-scatter cusps
    point = np.array([ti, tr, pr])
    p = np.array(params, dtype=float)
    _, grad_p, grad_angles = VALUE_AND_GRADS[False](jnp.asarray(p), tuple(map(jnp.asarray,
                                                                              point)))

    def f(q, x):
        return float(brdf(q, *x))

    for k in range(5):
        h = 1e-6 * max(abs(p[k]), 1e-3)
        up, down = p.copy(), p.copy()
        up[k] += h
        down[k] -= h
        fd = (f(up, point) - f(down, point)) / (2 * h)
        assert float(grad_p[k]) == pytest.approx(fd, rel=1e-5, abs=1e-9)
    for k in range(3):
        h = 1e-6
        up, down = point.copy(), point.copy()
        up[k] += h
        down[k] -= h
        fd = (f(p, up) - f(p, down)) / (2 * h)
        assert float(grad_angles[k]) == pytest.approx(fd, rel=1e-4, abs=1e-7)


def test_projected_brdf_is_brdf_times_cos():
    p = PAPER_SAMPLES["polyimide"]
    assert float(projected_brdf(p, 0.3, 1.1, 2.0)) == pytest.approx(
        float(brdf(p, 0.3, 1.1, 2.0)) * np.cos(1.1), rel=1e-15)
