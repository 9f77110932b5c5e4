"""Angles outside their domain are refused on host inputs, with the degrees/radians hint."""

import jax
import numpy as np
import pytest

import brdfjax
from brdfjax.angles import check_degrees, check_radians

PAINT = brdfjax.PAPER_SAMPLES["white_paint"]
RADIANS_HINT = r"radians \(files and the command line take degrees\); did you mean np.radians"


@pytest.mark.parametrize("call", [
    lambda: brdfjax.brdf(PAINT, 30.0, 0.2, np.pi),
    lambda: brdfjax.brdf(PAINT, 0.5, np.array([0.1, 80.0]), np.pi),
    lambda: brdfjax.projected_brdf(PAINT, 0.5, 45, 0.0),
    lambda: brdfjax.brdf(PAINT, 0.5, 0.2, 180.0),
    lambda: brdfjax.reflectance(PAINT, 30.0),
    lambda: brdfjax.reflectance(PAINT, [0.0, 60.0]),
    lambda: brdfjax.scene(0.5, 45.0, np.pi),
], ids=["brdf theta_i", "brdf theta_r", "projected_brdf", "brdf phi_r", "reflectance",
        "reflectance list", "scene"])
def test_degrees_given_as_radians_are_refused(call):
    with pytest.raises(ValueError, match=RADIANS_HINT):
        call()


def test_radians_past_the_horizon_are_not_taken_for_degrees():
    """1.7 rad is 97 deg: below the horizon, and np.radians(1.7) would be no help."""
    with pytest.raises(ValueError, match=r"^theta_i = 1.7 rad is below the horizon: zenith "
                                         r"angles lie in \[0, pi/2\] = \[0, 1.5708\] rad$"):
        brdfjax.reflectance(PAINT, 1.7)
    with pytest.raises(ValueError, match=r"theta_i = 30 is outside .*np.radians\(30\)"):
        brdfjax.reflectance(PAINT, [0, 2, 30, 60])  # degrees, whatever comes first


def test_a_signed_in_plane_angle_is_explained():
    with pytest.raises(ValueError, match=r"theta_r = -0.3 is negative.*phi_r = pi"):
        brdfjax.brdf(PAINT, 0.5, -0.3, 0.0)


@pytest.mark.parametrize("call", [
    lambda: brdfjax.curve_bands(np.array([list(PAINT)]), [30, 100], draws=1),
    lambda: brdfjax.reflectance_bands(np.array([list(PAINT)]), [-10], draws=1),
], ids=["curve_bands", "reflectance_bands"])
def test_the_bands_refuse_incidences_outside_0_to_90_degrees(call):
    with pytest.raises(ValueError, match=r"outside \[0, 90\] deg"):
        call()


def test_the_domain_edges_and_nan_pass():
    check_radians(("phi_r",), theta_i=np.radians([0.0, 90.0]), theta_r=np.pi / 2 + 1e-9,
                  phi_r=np.array([-np.pi, 2 * np.pi, np.nan]))
    check_degrees(theta_i_deg=[0, 90])
    assert np.isfinite(brdfjax.reflectance(PAINT, np.radians(90.0)))


def test_jax_arrays_and_tracers_are_not_checked():
    """Compiled code pays nothing: inside jit the values are unknown and go unchecked."""
    value = jax.jit(lambda t: brdfjax.brdf(PAINT, t, 0.3, np.pi))(40.0)
    assert np.isfinite(value)
    assert np.isfinite(brdfjax.brdf(PAINT, jax.numpy.asarray(40.0), 0.3, np.pi))
    grad = jax.grad(lambda t: brdfjax.projected_brdf(PAINT, t, 0.3, np.pi))(0.4)
    assert np.isfinite(grad)
