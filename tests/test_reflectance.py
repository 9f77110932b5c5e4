"""Eq. (9): against an independent integration of the transcription, the quadrature's
nodes, its convergence, and the energy flag."""

import warnings

import jax.numpy as jnp
import numpy as np
import pytest
import transcription

from brdfjax.models.hemispherical import (
    AZIMUTH_NODES,
    RADIAL_NODES,
    EnergyWarning,
    energy_warning,
    hemisphere_nodes,
    reflectance,
)
from brdfjax.models.paper import PAPER_SAMPLES

# The quadrature is tested on parameters that create energy on purpose (the paper's
# polyimide); test_energy_warning_flags_polyimide_only checks the warning.
pytestmark = pytest.mark.filterwarnings("ignore::brdfjax.models.hemispherical.EnergyWarning")

INCIDENCES = np.radians([0.0, 30.0, 60.0, 80.0, 90.0])
CHECKED_DEG = [0.0, 30.0, 60.0, 80.0]  # where the independent integral is taken


@pytest.mark.parametrize("name", list(PAPER_SAMPLES))
def test_paper_samples_equal_an_independent_integration(name):
    """scipy's nested adaptive quad of the transcription (breaks at the back-scatter peak)
    gives the quadrature's rho to the 1e-6 the module claims, at 0 to 80 deg."""
    params = tuple(PAPER_SAMPLES[name])
    ours = np.asarray(reflectance(params, np.radians(CHECKED_DEG)))
    for deg, rho in zip(CHECKED_DEG, ours):
        expected = transcription.reflectance("five", params, np.radians(deg))
        assert rho == pytest.approx(expected, rel=1e-6), deg


def test_white_paint_at_normal_incidence_is_the_papers_73_4_percent():
    """The paper's number, 73.4 % (its Eq. 9 with its Table 1 parameters)."""
    rho = float(reflectance(PAPER_SAMPLES["white_paint"], 0.0))
    assert round(rho, 3) == 0.734
    assert round(transcription.reflectance("five", tuple(PAPER_SAMPLES["white_paint"]), 0.0),
                 3) == 0.734


@pytest.mark.parametrize("mirrored", [False, True])
def test_nodes_integrate_polynomials_in_cos_exactly(mirrored):
    """sum(weight g) over the nodes against closed forms of integral g cos(tr) d(omega):
    g = 1 gives pi, cos(tr) 2 pi / 3, cos^2(tr) pi / 2, sin^2(tr) cos^2(phi_r) pi / 4.
    The hemisphere's edge cuts the polar cap around the peak for incidences above 0, so the
    nodes alone are exact to rounding up to 60 deg and within 1e-4 up to 85 deg (the module
    docstring's claim); the control variate makes the constant part exact anyway."""
    for deg, tolerance in ((0, 1e-12), (30, 1e-12), (60, 1e-12), (80, 1e-8), (85, 1e-4)):
        theta_r, phi_r, weight = (np.asarray(x) for x in hemisphere_nodes(
            np.radians(deg), RADIAL_NODES, AZIMUTH_NODES, mirrored))
        cos_r = np.cos(theta_r)
        for g, exact in ((1.0, np.pi), (cos_r, 2 * np.pi / 3), (cos_r**2, np.pi / 2),
                         ((1 - cos_r**2) * np.cos(phi_r) ** 2, np.pi / 4)):
            assert np.sum(weight * g) == pytest.approx(exact, rel=tolerance, abs=0), deg
        assert np.all(weight >= 0) and np.all((theta_r >= 0) & (theta_r <= np.pi / 2))


def test_the_constant_part_is_integrated_exactly_and_the_lobe_by_the_nodes():
    """The control variate of the module docstring: rho = pi min f + sum(weight (f - min f)).
    At 89 deg the nodes alone are 1.5e-4 off pi, yet a constant BRDF (a Lambertian kd, here
    the five-parameter model with kb = 0) gives pi kd to rounding; and for the white paint
    the result is pi min f plus the nodes' sum of the rest, not the nodes' sum of f."""
    from brdfjax.models.paper import brdf

    theta_i = np.radians(89.0)
    theta_r, phi_r, weight = (np.asarray(x) for x in hemisphere_nodes(
        theta_i, RADIAL_NODES, AZIMUTH_NODES, False))
    assert abs(np.sum(weight) - np.pi) > 1e-4  # so the exactness below is the control variate
    kd = 0.123
    assert float(reflectance([0.0, 2.0, 0.5, -10.0, kd], theta_i)) == pytest.approx(
        np.pi * kd, rel=1e-14)
    params = PAPER_SAMPLES["white_paint"]
    f = np.asarray(brdf(params, jnp.full_like(theta_r, theta_i), theta_r, phi_r))
    floor = f.min()
    assert float(reflectance(params, theta_i)) == pytest.approx(
        np.pi * floor + np.sum(weight * (f - floor)), rel=1e-12)


def test_the_lobe_vanishes_at_grazing_incidence():
    """At 90 deg incidence G -> 0 (tan ti -> inf in Eq. 3), so only kd remains: rho = pi kd;
    and rho tends to it continuously (the independent integral at 89.9 deg is within 1 %)."""
    params = PAPER_SAMPLES["white_paint"]
    assert float(reflectance(params, np.pi / 2)) == pytest.approx(np.pi * 0.220, rel=1e-9)
    near = transcription.reflectance("five", tuple(params), np.radians(89.9), tol=1e-6)
    assert near == pytest.approx(np.pi * 0.220, rel=0.01)


@pytest.mark.parametrize("name", list(PAPER_SAMPLES))
def test_quadrature_converged_to_1e6(name):
    """Doubling both node counts changes nothing at the 1e-6 level, at any incidence."""
    params = PAPER_SAMPLES[name]
    default = np.asarray(reflectance(params, INCIDENCES))
    doubled = np.asarray(reflectance(params, INCIDENCES, radial_nodes=320, azimuth_nodes=192))
    np.testing.assert_allclose(default, doubled, atol=1e-6)


def test_coarse_grid_would_be_wrong():
    """A 45 x 90 midpoint grid in (tr, pr) misses the narrow back-scatter peak."""
    from brdfjax.models.paper import brdf

    tr = (np.arange(45) + 0.5) * np.radians(2)
    pr = (np.arange(90) + 0.5) * np.radians(4)
    TR, PR = np.meshgrid(tr, pr)
    f = np.asarray(brdf(PAPER_SAMPLES["white_paint"], 0.0, TR, PR))
    coarse = np.sum(f * np.cos(TR) * np.sin(TR)) * np.radians(2) * np.radians(4)
    assert abs(coarse - float(reflectance(PAPER_SAMPLES["white_paint"], 0.0))) > 1e-3


def test_energy_warning_flags_polyimide_only():
    with pytest.warns(EnergyWarning, match=r"reflectance up to 7\.6\d* > 1"):
        rho = reflectance(PAPER_SAMPLES["polyimide"], INCIDENCES)  # said in Python too
    assert energy_warning(rho) is not None
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert energy_warning(reflectance(PAPER_SAMPLES["white_paint"], INCIDENCES)) is None
