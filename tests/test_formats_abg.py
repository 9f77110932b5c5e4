"""ABg per incidence: each incidence's own fit recovers its (A, B, g), and the Zemax catalog
entry and the checks say what the rows are."""

import numpy as np
import pytest

from brdfjax.data.formats.abg import POOR_ROW_ERROR, AbgRow, abg_rows, catalog_entry, report
from brdfjax.data.measurements import Measurements
from brdfjax.models.paper import brdf
from brdfjax.prediction.cross_validation import fit_per_incidence

TRUTH = {10.0: (2e-3, 1e-2, 1.5), 40.0: (1e-3, 3e-3, 2.0), 60.0: (5e-4, 1e-3, 2.5)}


def per_incidence_data():
    """Noise-free in-plane ABg data, each incidence with its own (A, B, g)."""
    parts = []
    for degrees, params in TRUTH.items():
        tr, side = np.meshgrid(np.radians(np.arange(1.0, 86.0, 1.5)), [0.0, np.pi])
        ti = np.full(tr.size, np.radians(degrees))
        parts.append((ti, tr.ravel(), side.ravel(),
                      np.asarray(brdf(np.array(params), ti, tr.ravel(), side.ravel(),
                                      model="abg"))))
    return Measurements(*(np.concatenate(x) for x in zip(*parts)),
                        metadata={"sample": "abg per incidence", "wavelength_nm": 633.0})


def test_each_incidence_recovers_its_own_parameters_and_exports():
    fits = fit_per_incidence(per_incidence_data(), "abg")
    assert [d for d, _ in fits] == list(TRUTH)
    for degrees, result in fits:
        assert result.error < 1e-16
        np.testing.assert_allclose(result.vector, TRUTH[degrees], rtol=1e-6)
    rows = abg_rows(fits)
    assert all(0 < row.tis < 1 and row.zemax_ok for row in rows)
    for row in rows:
        assert row.fred_check == pytest.approx(np.pi * row.A / row.B)
    lines = catalog_entry("coat-1", rows, 0.633).splitlines()
    assert lines[0] == "COAT-1 0.633"
    parsed = np.array([[float(x) for x in line.split()] for line in lines[1:]])
    np.testing.assert_allclose(parsed[:, 0], list(TRUTH))
    np.testing.assert_allclose(parsed[:, 1:], [TRUTH[d] for d in TRUTH], rtol=1e-6)
    assert "FRED" in report(rows) and "at 40 deg" in report(rows)


@pytest.mark.parametrize(("name", "rows", "message"), [
    ("has space", [AbgRow(10, 1e-3, 1e-2, 2, 0, 0.1, 0.3, True)], "no spaces"),
    ("ok", [], "no ABg rows"),
    ("ok", [AbgRow(d, 1e-3, 1e-2, 2, 0, 0.1, 0.3, True) for d in range(11)], "at most 10"),
    ("ok", [AbgRow(10, 1e-3, 1e-13, 2, 0, 0.1, 1.0, False)], "refuses"),
])
def test_bad_entries_are_refused_with_a_reason(name, rows, message):
    with pytest.raises(ValueError, match=message):
        catalog_entry(name, rows)


def test_rows_say_how_well_they_fit_and_flag_poor_ones():
    """Issue 47, defect 7: rows with E of 11.7 and 14.9 % were written with "checks ok".
    Here the 40 deg incidence is two lobes (ABg and a mirror-side lobe three times wider),
    which one ABg lobe cannot follow: its row is flagged, the others are not, and every
    row's E equals Eq. (6) recomputed in NumPy from its own parameters."""
    data = per_incidence_data()
    at_40 = np.isclose(np.degrees(data.theta_i), 40.0)
    wide = np.asarray(brdf(np.array([1e-2, 1e-1, 3.0]), data.theta_i, data.theta_r,
                           data.phi_r + np.pi, model="abg"))
    brdf_values = np.where(at_40, data.brdf + wide, data.brdf)
    two_lobes = Measurements(data.theta_i, data.theta_r, data.phi_r, brdf_values,
                             metadata=data.metadata)
    rows = abg_rows(fit_per_incidence(two_lobes, "abg"))
    for row in rows:
        mine = np.isclose(np.degrees(two_lobes.theta_i), row.incidence_deg)
        ti, tr, pr = (x[mine] for x in (two_lobes.theta_i, two_lobes.theta_r,
                                        two_lobes.phi_r))
        measured = two_lobes.brdf[mine] * np.cos(tr)
        fitted = np.asarray(brdf(np.array([row.A, row.B, row.g]), ti, tr, pr,
                                 model="abg")) * np.cos(tr)
        independent = np.sum((fitted - measured) ** 2) / np.sum(measured**2)
        assert row.error == pytest.approx(independent, rel=1e-6, abs=1e-15)
    assert [row.poor_fit for row in rows] == [False, True, False]
    assert rows[1].error > POOR_ROW_ERROR > max(rows[0].error, rows[2].error)
    lines = report(rows).splitlines()
    assert ["poor fit" in line for line in lines[1:4]] == [False, True, False]
    assert "1 of 3 rows fit poorly" in report(rows) and "at 40 deg" in report(rows)
    assert [row.to_dict()["poor_fit"] for row in rows] == [False, True, False]
    # a threshold of the caller's: above every row's E, none is poor
    assert not any(row.poor_fit for row in abg_rows(fit_per_incidence(two_lobes, "abg"),
                                                    poor_error=1.0))
