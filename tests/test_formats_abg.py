"""ABg per incidence: each incidence's own fit recovers its (A, B, g), and the Zemax catalog
entry and the checks say what the rows are."""

import numpy as np
import pytest

from brdfjax.data.formats.abg import AbgRow, abg_rows, catalog_entry, report
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
