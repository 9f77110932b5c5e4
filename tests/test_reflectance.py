"""Eq. (9): the paper's 73.4 %, convergence of the quadrature, and the energy flag."""

import numpy as np
import pytest

from brdfjax.hemispherical import energy_warning, reflectance
from brdfjax.model import PAPER_SAMPLES

INCIDENCES = np.radians([0.0, 30.0, 60.0, 80.0, 90.0])


def test_white_paint_at_normal_incidence_is_the_papers_73_4_percent():
    rho = float(reflectance(PAPER_SAMPLES["white_paint"], 0.0))
    assert round(rho, 3) == 0.734
    assert rho == pytest.approx(0.73411, abs=1e-5)  # an independent transcription's value


@pytest.mark.parametrize("name", list(PAPER_SAMPLES))
def test_quadrature_converged_to_1e4(name):
    """Doubling both node counts changes nothing at the 1e-4 level, at any incidence."""
    params = PAPER_SAMPLES[name]
    default = np.asarray(reflectance(params, INCIDENCES))
    doubled = np.asarray(reflectance(params, INCIDENCES, radial_nodes=320, azimuth_nodes=192))
    np.testing.assert_allclose(default, doubled, atol=1e-6)


def test_lambertian_part_is_pi_kd():
    """With kb = 0 the integral is pi kd exactly; at 90 deg incidence the lobe vanishes."""
    kd = 0.123
    np.testing.assert_allclose(reflectance([0.0, 2.0, 0.5, -10.0, kd], INCIDENCES),
                               np.pi * kd, rtol=1e-12)
    assert float(reflectance(PAPER_SAMPLES["white_paint"], np.pi / 2)) == pytest.approx(
        np.pi * 0.220, rel=1e-9)


def test_coarse_grid_would_be_wrong():
    """A 45 x 90 midpoint grid in (tr, pr) misses the narrow back-scatter peak."""
    from brdfjax.model import brdf

    tr = (np.arange(45) + 0.5) * np.radians(2)
    pr = (np.arange(90) + 0.5) * np.radians(4)
    TR, PR = np.meshgrid(tr, pr)
    f = np.asarray(brdf(PAPER_SAMPLES["white_paint"], 0.0, TR, PR))
    coarse = np.sum(f * np.cos(TR) * np.sin(TR)) * np.radians(2) * np.radians(4)
    assert abs(coarse - float(reflectance(PAPER_SAMPLES["white_paint"], 0.0))) > 1e-3


def test_energy_warning_flags_polyimide_only():
    assert energy_warning(reflectance(PAPER_SAMPLES["polyimide"], INCIDENCES)) is not None
    assert energy_warning(reflectance(PAPER_SAMPLES["white_paint"], INCIDENCES)) is None
