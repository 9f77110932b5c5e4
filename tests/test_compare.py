"""The careful SciPy peer of the benchmarks: the same problem, an independent optimiser."""

import pytest
from conftest import REAL

from brdfjax.compare import compare, format_table, nonlinear_parameters
from brdfjax.data.formats import load
from brdfjax.models import get
from brdfjax.models.bounds import default_bounds


@pytest.mark.parametrize(("name", "searched"), [("five", (1, 2, 3)), ("ggx", (1,)),
                                                ("rpv", (1, 2)), ("lambert", ())])
def test_the_searched_parameters_are_those_the_linear_solve_leaves_alone(name, searched):
    model = get(name)
    assert nonlinear_parameters(model, default_bounds(model)) == searched


def test_scipy_reaches_brdfjax_s_error_on_a_real_run():
    """SciPy's DE over the nonlinear parameters plus least_squares, from its own seed,
    ends at brdfjax's E (to 1e-6 relative) for the GGX fit of a real NiTE run."""
    data = load(REAL / "uaz-loft-rt300s" / "raw" / "NiTE_on_invar_v1o0A_20250915.xls",
                in_plane=True)
    runs = {run.method: run for run in compare(data, repeats=1, include=("hybrid", "scipy-vp"),
                                               model="ggx")}
    assert runs["scipy vp"].error == pytest.approx(runs["brdfjax hybrid"].error, rel=1e-6)
    assert "| scipy vp |" in format_table(list(runs.values()))
