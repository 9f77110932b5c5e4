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


def test_models_tied_below_the_top_are_listed_fewest_parameters_first():
    """Issue 47, defect 9: the README's rule (cv_errors within 0.1 % tie, and the model
    with fewer parameters wins) held for the lowest only; ggx+backscatter with its lobe
    off and ggx, tied under ggx+ggx, were listed by their last digits. The expected orders
    are written out by hand from the rule."""
    from types import SimpleNamespace

    from brdfjax.prediction.selection import Comparison, ModelScore, ranked

    errors = {"five": 0.116, "ggx+backscatter": 0.0018999, "ggx+ggx": 0.00155,
              "ggx": 0.0019001, "lambert": float("nan"), "rpv": 0.116001, "beckmann": 0.05}
    expected = ["ggx+ggx", "ggx", "ggx+backscatter", "beckmann", "rpv", "five", "lambert"]
    assert ranked(errors) == expected
    scores = [ModelScore(name, SimpleNamespace(), SimpleNamespace(cv_error=value), 0.0, 0.0,
                         {}) for name, value in errors.items()]
    assert Comparison(scores).ranking == expected
    # a chain of small steps is not one tie: each group is measured from its own lowest
    assert ranked({"ggx+ggx": 1.0, "ggx": 1.0008, "lambert": 1.0016}) == [
        "ggx", "ggx+ggx", "lambert"]


def test_lmfit_reaches_scipy_s_error_on_a_small_synthetic_problem():
    """The lmfit peer (its differential evolution, then its least_squares) minimises the
    same E over the same box as SciPy's: on noisy synthetic white paint at two incidences,
    GGX, both end at the same E (1e-6 relative). lmfit is in the bench extra, not the test
    one, so the test is skipped where it is missing (as in CI)."""
    pytest.importorskip("lmfit")
    from brdfjax.compare import lmfit_fit, scipy_vp, unit_objectives
    from brdfjax.data.synthetic import paper_sample

    data = paper_sample("white_paint", noise=0.025, seed=3).at_incidences([30, 60])
    objectives = unit_objectives(data, "ggx", shared=True)
    _, e_scipy, _ = scipy_vp(data, "ggx", seed=0, objectives=objectives)
    z, e_lmfit, evaluations, e_de = lmfit_fit(data, seed=0, model="ggx", objectives=objectives)
    assert e_lmfit == pytest.approx(e_scipy, rel=1e-6)
    assert e_lmfit <= e_de and evaluations > 0 and z.shape == (4,)
