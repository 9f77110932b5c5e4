"""`brdfjax plan` (`brdfjax.instrument.design`): the integrated-variance criterion against
a brute-force Gaussian-process update, the space-filling start, determinism, the motor
route, and the command's files and bad input."""

import re
import types

import numpy as np
import pytest
from conftest import DATA

from brdfjax.cli import main
from brdfjax.data.formats import load, load_geometry
from brdfjax.data.measurements import Measurements
from brdfjax.instrument.design import (
    instrument_grid,
    integrated_variance_design,
    motor_seconds,
    plan,
    process_kernel,
    route,
)
from brdfjax.instrument.plan import load_plan
from brdfjax.instrument.simulator import MOTOR_SPEED
from brdfjax.prediction.discrepancy import _kernel, _physical, _unconstrained, features


@pytest.fixture(scope="module")
def measured():
    """40 readings of the synthetic white paint, spread over its incidences."""
    data = load(DATA / "synthetic" / "white_paint.csv")
    return data.select(np.arange(len(data)) % (len(data) // 40) == 0)


def _process(dims=3):
    """A stand-in for a fitted discrepancy: fixed hyperparameters, the real kernel."""
    u = np.concatenate([[0.0, _unconstrained(0.3, "amplitude")],
                        [_unconstrained(v, "length") for v in (0.3, 0.5)][:dims - 1],
                        [_unconstrained(0.8, "incidence"), 0.5, _unconstrained(0.05, "noise")]])
    _, amplitude, _, _, noise = (np.asarray(v) for v in _physical(u, dims))
    return types.SimpleNamespace(_u=u, _x=np.zeros((1, dims))), float(amplitude), float(noise)


def _region_variance(kernel, prior, noise, known, region):
    """The posterior variance summed over ``region``, by np.linalg."""
    if not len(known):
        return prior * len(region)
    cross = kernel(known, region)
    gram = kernel(known, known) + noise**2 * np.eye(len(known))
    return float(np.sum(prior - np.sum(cross * np.linalg.solve(gram, cross), axis=0)))


def test_alc_reduction_equals_the_brute_force_update():
    rng = np.random.default_rng(3)
    process, amplitude, noise = _process()
    kernel = process_kernel(process)
    known, candidates, region = (rng.uniform(0, 1.2, (n, 3)) for n in (12, 25, 40))
    # The NumPy kernel is the discrepancy's own (tinygp's).
    assert np.allclose(kernel(known, region), np.asarray(_kernel(process._u, 3)(known, region)),
                       rtol=1e-12, atol=1e-14)
    design = integrated_variance_design(kernel, amplitude**2, noise, known, candidates,
                                        region, budget=4)
    before = _region_variance(kernel, amplitude**2, noise, known, region)
    assert design["before"] == pytest.approx(before, abs=1e-9)
    for c in (0, 7, 13, 24):
        after = _region_variance(kernel, amplitude**2, noise,
                                 np.vstack([known, candidates[c:c + 1]]), region)
        assert design["drops"][0, c] == pytest.approx(before - after, abs=1e-9)
    assert design["picks"][0] == np.argmax(design["drops"][0])
    # The second step's drops, given the readings and the first pick.
    given = np.vstack([known, candidates[design["picks"][:1]]])
    before = _region_variance(kernel, amplitude**2, noise, given, region)
    for c in (2, 11, 19):
        after = _region_variance(kernel, amplitude**2, noise,
                                 np.vstack([given, candidates[c:c + 1]]), region)
        assert design["drops"][1, c] == pytest.approx(before - after, abs=1e-9)
    # The rank-one updates after each pick: the variance given all picks, by np.linalg.
    after = _region_variance(kernel, amplitude**2, noise,
                             np.vstack([known, candidates[design["picks"]]]), region)
    assert design["after"] == pytest.approx(after, abs=1e-9)
    assert len(set(design["picks"].tolist())) == 4


def test_the_space_filling_start_spreads():
    grid = instrument_grid()
    x_all = features(grid.theta_i, grid.theta_r, grid.phi_r, False)

    def closest(x):
        d = np.linalg.norm(x[:, None] - x[None], axis=-1)
        return d[np.triu_indices(len(x), 1)].min()

    for seed in (0, 1, 2):
        design = plan(None, grid, 20, seed=seed)
        assert design.method == "maximin" and len(design) == 20
        chosen = features(*np.radians([design.theta_i, design.theta_r, design.phi_r]), False)
        random = x_all[np.random.default_rng(seed).choice(len(grid), 20, replace=False)]
        assert closest(chosen) > closest(random)


def test_the_plan_is_deterministic_for_a_seed(measured):
    grid = instrument_grid()
    first, again = plan(None, grid, 15, seed=4), plan(None, grid, 15, seed=4)
    assert np.array_equal(np.c_[first.theta_i, first.theta_r, first.phi_r],
                          np.c_[again.theta_i, again.theta_r, again.phi_r])
    a, b = (plan(measured, grid, 10, seed=1) for _ in range(2))
    assert a.method == "alc" and a.model == "ggx" and a.measured == len(measured)
    assert np.array_equal(np.c_[a.theta_i, a.theta_r, a.phi_r],
                          np.c_[b.theta_i, b.theta_r, b.phi_r])
    assert a.variance_after < a.variance_before
    # Nothing already measured is proposed again.
    known = {tuple(row) for row in measured.geometries()}
    assert not known & {tuple(row) for row in a.geometry().geometries()}


def test_the_route_counts_motor_time_and_beats_the_sweep_order():
    # From home: B to 10, C to +20 (phi_r 180: the specular side), then C to -30.
    assert motor_seconds([10, 10], [20, 30], [180, 0]) == pytest.approx(80 / MOTOR_SPEED)
    rng = np.random.default_rng(0)
    incidence = rng.choice([10.0, 30.0, 50.0, 70.0], 40)
    zenith = rng.choice(np.arange(5.0, 86.0, 5.0), 40)
    side = rng.choice([0.0, 180.0], 40)
    order, seconds, sweep = route(incidence, zenith, side)
    assert sorted(order) == list(range(40))
    assert np.all(np.diff(incidence[order]) >= 0)  # grouped by incidence
    assert seconds == pytest.approx(motor_seconds(incidence[order], zenith[order], side[order]))
    assert seconds < sweep
    design = plan(None, instrument_grid(out_of_plane=True), 30, seed=0)
    assert design.motor_seconds <= design.sweep_motor_seconds


def _csv(path, text):
    path.write_text(text)
    return str(path)


def test_the_command_writes_a_geometry_file_and_a_plan(measured, tmp_path, capsys):
    out = tmp_path / "next"
    assert main(["plan", "--budget", "8", "--out", str(out)]) == 0
    written = load_geometry(tmp_path / "next.csv")
    listed = load_plan(tmp_path / "next.toml")
    assert len(written) == len(listed.points) == 8
    assert np.allclose(np.degrees([written.theta_i, written.theta_r, written.phi_r]).T,
                       listed.geometries)
    # Degrees as a user wrote them: 30, not the 29.999999999999996 of a round trip through
    # radians (3 of these 8 geometries before).
    assert not re.search(r"\d\.\d{9}", (tmp_path / "next.toml").read_text())
    assert "route:" in capsys.readouterr().out
    # From measurements, among a candidates file; the plan starts from the readings.
    candidates = Measurements.from_degrees(*np.array(
        [(ti, tr, pr) for ti in (15, 35, 55) for tr in (10, 30, 50, 70) for pr in (0, 180)]).T,
        np.full(24, np.nan))
    lines = ["theta_i,theta_r,phi_r"] + [f"{a:g},{b:g},{c:g}" for a, b, c in
                                          np.degrees([candidates.theta_i, candidates.theta_r,
                                                      candidates.phi_r]).T]
    geometry = _csv(tmp_path / "geometry.csv", "\n".join(lines) + "\n")
    source = tmp_path / "measured.csv"
    from brdfjax.data.formats import save

    save(measured, source)
    assert main(["plan", str(source), "--budget", "5", "--candidates", geometry,
                 "--out", str(tmp_path / "more.toml"), "--seed", "1"]) == 0
    assert "integrated variance (ALC) of ggx" in capsys.readouterr().out
    more = load_geometry(tmp_path / "more.csv")
    chosen = {tuple(row) for row in more.geometries()}
    assert len(chosen) == 5 and chosen <= {tuple(row) for row in candidates.geometries()}


def test_bad_input_is_one_line_before_any_work(tmp_path, capsys):
    out = str(tmp_path / "next")
    no_angles = _csv(tmp_path / "values.csv", "brdf\n0.1\n0.2\n")
    three = _csv(tmp_path / "three.csv", "theta_i,theta_r,phi_r\n10,20,0\n10,30,0\n10,40,0\n")
    beyond = _csv(tmp_path / "beyond.csv", "theta_i,theta_r,phi_r\n30,20,0\n85,20,180\n")
    for argv, message in [
        (["--budget", "0"], "--budget 0: give the number of readings"),
        (["--budget", "-2"], "--budget -2: give the number of readings"),
        (["--budget", "2", "--candidates", no_angles], "--candidates: .*missing column"),
        (["--budget", "5", "--candidates", three], "--budget 5: more than the 3 candidate"),
        (["--budget", "2", "--region", beyond],
         (r"--region .*: 1 of 2 geometries are out of the instrument's reach; the first, "
          r"point 2 \(theta_i 85.*motor B")),
    ]:
        assert main(["plan", *argv, "--out", out]) == 1
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1, err
        assert err.startswith("brdfjax plan: error: ")
        assert re.search(message, err), err
    assert not list(tmp_path.glob("next*"))


def test_a_measured_geometry_is_left_out_whatever_its_azimuth_is_written_as():
    from brdfjax.instrument.design import check_inputs

    candidates = Measurements.from_degrees([30, 30, 30], [40, 40, 0], [278.1301, 100, 45],
                                           np.full(3, np.nan))
    measured = Measurements.from_degrees([30, 30, 30], [40, 0, 20], [-81.8699, 0, 180],
                                         [0.3, 0.3, 0.3])
    found = check_inputs(candidates, 1, measured=measured)
    assert found.measured == 2 and found.index.tolist() == [1]


def test_auto_plans_with_the_predictor_of_the_comparison(measured, monkeypatch):
    # auto is compare_models' predictor with the learned discrepancy, at the plan's seed
    # (as fit --model auto --predict), and the plan is the one of that model named.
    from brdfjax.prediction import selection

    asked = []

    def comparison(data, models=None, *, seed=0, discrepancy="gp", **_):
        asked.append((len(data), models, seed, discrepancy))
        return types.SimpleNamespace(predictor=types.SimpleNamespace(name="lambert"))

    monkeypatch.setattr(selection, "compare_models", comparison)
    grid = instrument_grid()
    chosen, named = plan(measured, grid, 4, model="auto", seed=1), \
        plan(measured, grid, 4, model="lambert", seed=1)
    assert asked == [(len(measured), None, 1, "gp")]
    assert chosen.model == "lambert" and chosen.auto and not named.auto
    assert "lambert (chosen by --model auto)" in chosen.summary()[0]
    assert np.array_equal(np.c_[chosen.theta_i, chosen.theta_r, chosen.phi_r],
                          np.c_[named.theta_i, named.theta_r, named.phi_r])


@pytest.mark.slow
def test_auto_chooses_the_model_the_data_were_made_with(measured, monkeypatch):
    # The white paint is the paper's model with 2.5 % noise: of it and a constant, auto
    # chooses the paper's model (not the default ggx). 30 s cold, hence slow.
    from brdfjax.instrument.design import auto_model
    from brdfjax.prediction import selection

    monkeypatch.setattr(selection, "DEFAULT_CANDIDATES", ("lambert", "five"))
    assert auto_model(measured, seed=1) == "five"
    assert plan(measured, instrument_grid(), 2, model="auto", seed=1).model == "five"


def test_auto_needs_three_incidences(measured, tmp_path, capsys):
    two = measured.at_incidences(measured.incidences_deg[:2])
    with pytest.raises(ValueError, match="auto: chooses by cross-validation .* has 2"):
        plan(two, instrument_grid(), 3, model="auto")
    from brdfjax.data.formats import save

    save(two, tmp_path / "two.csv")
    assert main(["plan", str(tmp_path / "two.csv"), "--budget", "3", "--model", "auto",
                 "--out", str(tmp_path / "next")]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--model auto: chooses by cross-validation" in err
    assert not list(tmp_path.glob("next*"))


def test_planning_runs_with_one_blas_thread_and_puts_the_count_back():
    from brdfjax.instrument.design import _openblas_controls, one_blas_thread

    controls = _openblas_controls()
    if not controls:
        pytest.skip("no OpenBLAS found beside NumPy and SciPy (another BLAS)")
    (get, set_threads), saved = controls[0], controls[0][0]()
    try:
        set_threads(2)
        with pytest.raises(RuntimeError), one_blas_thread():
            assert [g() for g, _ in controls] == [1] * len(controls)
            raise RuntimeError
        assert get() == 2
    finally:
        set_threads(saved)


def test_the_kernel_on_few_incidences_equals_the_process_kernel():
    # The incidence factor is taken once per pair of distinct incidences, then spread.
    rng = np.random.default_rng(5)
    process, _, _ = _process()
    x1, x2 = rng.uniform(0, 1.2, (30, 3)), rng.uniform(0, 1.2, (45, 3))
    x1[:, -1] = rng.choice([0.2, 0.5, 0.9], 30)
    x2[:, -1] = rng.choice([0.2, 0.7, 0.9, 1.2], 45)
    assert np.allclose(process_kernel(process)(x1, x2),
                       np.asarray(_kernel(process._u, 3)(x1, x2)), rtol=1e-12, atol=1e-14)
