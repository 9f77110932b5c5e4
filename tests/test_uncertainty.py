"""Uncertainty: likelihood, Laplace, emcee and bands against independent computations.

One fit, one Laplace approximation and one converged chain of the bundled white-paint data
are shared by the whole module, so the compiled functions are built once.
"""

import dataclasses
import json
import subprocess
import sys
import warnings

import jax
import numpy as np
import pytest
from conftest import DATA, REPO
from scipy.optimize import minimize
from scipy.stats import norm

import brdfjax.fitting.fit
from brdfjax.cli import main
from brdfjax.data.measurements import Measurements
from brdfjax.data.synthetic import paper_sample
from brdfjax.fitting.fit import fit, split
from brdfjax.models.bounds import make_bounds, to_unit
from brdfjax.models.hemispherical import reflectance
from brdfjax.models.paper import PAPER_SAMPLES, PARAMETER_NAMES, projected_brdf
from brdfjax.uncertainty.bands import curve_bands, reflectance_bands
from brdfjax.uncertainty.laplace import estimate_noise, laplace_approximation
from brdfjax.uncertainty.likelihood import (
    build_posterior,
    log_likelihood,
    log_posterior,
    log_posterior_batch,
)
from brdfjax.uncertainty.mcmc import emcee_snooker_is_fixed, sample_posterior, snooker_move
from brdfjax.uncertainty.result import UncertaintyWarning

TRUTH = np.array(PAPER_SAMPLES["white_paint"], dtype=float)
HELD_OUT = [21, 52]
LOG_SCALE = np.array([True, True, True, False, True])  # and asinh for b


def prior_coordinates(params):
    """log10 of kb, kr, a, kd and asinh b: where the prior is uniform (up to scale)."""
    return np.where(LOG_SCALE, np.log10(np.abs(params)), np.arcsinh(params))


def std_in_prior_coordinates(result):
    """A result's linearised physical std carried to `prior_coordinates` (d/dp of each)."""
    mode = result.median
    return np.where(LOG_SCALE, result.std / (mode * np.log(10)),
                    result.std / np.sqrt(1 + mode**2))


@pytest.fixture(scope="module")
def white_fit(white_paint):
    """LM from the truth on the training incidences (the fit itself is tested elsewhere)."""
    return fit(white_paint, "lm", start=TRUTH, validate_incidences_deg=HELD_OUT)


@pytest.fixture(scope="module")
def white_laplace(white_paint, white_fit):
    return laplace_approximation(white_paint, white_fit)


@pytest.fixture(scope="module")
def white_mcmc(white_paint, white_fit, white_laplace):
    return sample_posterior(white_paint, white_fit, start=white_laplace, seed=1,
                            progress=False)


@pytest.fixture(scope="module")
def training(white_paint):
    return split(white_paint, HELD_OUT)[0]


def test_log_likelihood_is_the_gaussian_density(training):
    post = build_posterior(training)
    x = np.asarray(to_unit(TRUTH * 1.01, post.bounds))
    cos_r = np.cos(training.theta_r)
    model = np.asarray(projected_brdf(TRUTH * 1.01, training.theta_i, training.theta_r,
                                      training.phi_r))
    expected = norm.logpdf(training.brdf * cos_r, model, training.sigma * cos_r).sum()
    assert float(log_likelihood(x, post)) == pytest.approx(expected, rel=1e-12)
    assert float(log_posterior(x, post)) == pytest.approx(expected, rel=1e-12)

    # Without sigma: two more coordinates, the log10 noise scales, and the variance model.
    noisy = build_posterior(dataclasses.replace(training, sigma=None))
    x = np.concatenate([x, [np.log10(0.03), np.log10(1e-3)]])
    expected = norm.logpdf(training.brdf * cos_r, model,
                           np.sqrt((0.03 * model) ** 2 + 1e-3**2)).sum()
    assert noisy.ndim == 7
    assert float(log_likelihood(x, noisy)) == pytest.approx(expected, rel=1e-12)

    # The prior box: -inf just outside, in the batch form emcee calls too.
    outside = np.array([x, x, x])
    outside[0, 3], outside[1, 5] = 1.0 + 1e-9, noisy.upper[5] + 1e-9
    values = np.asarray(log_posterior_batch(outside, noisy))
    assert values[0] == values[1] == -np.inf and values[2] == pytest.approx(expected)


def test_noise_scales_match_a_direct_maximisation(training):
    # Relative and absolute noise together, so both scales are identifiable.
    rng = np.random.default_rng(5)
    model = np.asarray(projected_brdf(TRUTH, training.theta_i, training.theta_r,
                                      training.phi_r))
    cos_r = np.cos(training.theta_r)
    scatter = np.sqrt((0.03 * model) ** 2 + 0.004**2) * rng.standard_normal(model.size)
    data = dataclasses.replace(training, brdf=(model + scatter) / cos_r, sigma=None)
    post = build_posterior(data)
    found = np.asarray(estimate_noise(to_unit(TRUTH, post.bounds), post))

    def negative_log_likelihood(log_scales):
        s_rel, s_abs = 10.0**log_scales
        return -norm.logpdf(data.brdf * cos_r, model,
                            np.sqrt((s_rel * model) ** 2 + s_abs**2)).sum()

    best = minimize(negative_log_likelihood, [-1.0, -2.0], method="Nelder-Mead",
                    options={"xatol": 1e-10, "fatol": 1e-12, "maxiter": 4000}).x
    np.testing.assert_allclose(found, best, atol=1e-6)
    np.testing.assert_allclose(10.0**found, [0.03, 0.004], rtol=0.1)


def test_laplace_matches_finite_differences(training, white_laplace):
    assert white_laplace.method == "laplace" and white_laplace.status == "ok"
    mode = white_laplace.median
    t0 = prior_coordinates(mode)
    cos_r = np.cos(training.theta_r)
    # compiled once for the 111 evaluations below (eagerly, 0.3 s each on a loaded machine)
    model_at = jax.jit(lambda params: projected_brdf(params, training.theta_i,
                                                     training.theta_r, training.phi_r))

    def weighted_residuals(t):
        params = np.where(LOG_SCALE, 10.0**t, np.sinh(t))
        model = np.asarray(model_at(params))
        return (model - training.brdf * cos_r) / (training.sigma * cos_r)

    laplace_std = std_in_prior_coordinates(white_laplace)
    # The same quantity, (J^T J)^-1 with J by central differences: to rounding.
    jacobian = np.stack([(weighted_residuals(t0 + h) - weighted_residuals(t0 - h)) / (2 * h[k])
                         for k, h in enumerate(np.diag(1e-6 * np.maximum(np.abs(t0), 1)))],
                        axis=1)
    np.testing.assert_allclose(laplace_std, np.sqrt(np.diag(np.linalg.inv(jacobian.T @ jacobian))),
                               rtol=1e-5)
    # The mode: there the chi-square gradient J^T r vanishes (relative to its scale).
    information = jacobian.T @ jacobian
    scale = np.sqrt(np.diag(information))
    assert np.all(np.abs(jacobian.T @ weighted_residuals(t0)) < 1e-4 * scale)
    # The condition number of the correlation form does not depend on each axis's scaling.
    assert white_laplace.diagnostics["condition_number"] == pytest.approx(
        np.linalg.cond(information / np.outer(scale, scale)), rel=1e-4)

    # The observed curvature (finite-difference Hessian of chi^2 / 2, residual term
    # included) differs from the expected (Fisher) one by a few per cent here.
    def half_chi2(t):
        return 0.5 * np.sum(weighted_residuals(t) ** 2)

    step = 0.5 * laplace_std  # chi-square is near quadratic over a standard deviation
    hessian = np.empty((5, 5))
    for i in range(5):
        for j in range(5):
            ei, ej = np.eye(5)[i] * step[i], np.eye(5)[j] * step[j]
            hessian[i, j] = (half_chi2(t0 + ei + ej) - half_chi2(t0 + ei - ej)
                             - half_chi2(t0 - ei + ej) + half_chi2(t0 - ei - ej)) / (
                                 4 * step[i] * step[j])
    np.testing.assert_allclose(laplace_std, np.sqrt(np.diag(np.linalg.inv(hessian))), rtol=0.1)
    # Intervals: the 95 % one is 1.96 / 1.00 times the 68 % one in the prior's coordinates.
    width68 = np.diff(prior_coordinates(white_laplace.ci68.T), axis=0)[0]
    width95 = np.diff(prior_coordinates(white_laplace.ci95.T), axis=0)[0]
    np.testing.assert_allclose(width95 / width68, 1.959964, rtol=1e-5)
    np.testing.assert_allclose(width68, 2 * laplace_std, rtol=1e-5)


def test_laplace_std_matches_the_spread_of_refits(training, white_laplace):
    # Refit 40 noise replicates by chi-square (Eq. 6 with weights 1 / sigma_proj^2).
    fits = []
    for seed in range(40):
        data = split(paper_sample("white_paint", seed=100 + seed), HELD_OUT)[0]
        weighted = dataclasses.replace(data, weights=1 / (data.sigma * np.cos(data.theta_r)) ** 2)
        fits.append(fit(weighted, "lm", start=TRUTH).vector)
    spread = np.std(prior_coordinates(np.array(fits)), axis=0, ddof=1)
    laplace_std = std_in_prior_coordinates(white_laplace)
    # 40 replicates estimate a standard deviation to about 11 %: allow three times that.
    np.testing.assert_allclose(spread, laplace_std, rtol=0.35)


def test_laplace_repeats_exactly_without_recompiling(white_paint, white_fit, white_laplace):
    """Warm calls reuse the compiled stages and give the same answer (how fast a warm call
    is belongs to benchmarks/bench_uncertainty.py, not to a unit test)."""
    from brdfjax.uncertainty import laplace

    stages = (laplace._weighted_start, laplace._keep_finite, laplace._curvature)
    compiled = [f._cache_size() for f in stages]
    again = laplace_approximation(white_paint, white_fit)
    assert [f._cache_size() for f in stages] == compiled
    np.testing.assert_array_equal(again.std, white_laplace.std)
    np.testing.assert_array_equal(again.samples, white_laplace.samples)


def test_laplace_polishes_with_the_hybrid_fits_compiled_lm():
    """After a hybrid fit, the polish to the mode adds no compiled LM: it polishes as many
    starts as the fit (one start and its skipped repeats) on points padded alike. A
    first ``brdfjax fit`` so compiles one LM, not two (BENCHMARKS.md, section startup)."""
    from brdfjax.fitting.polish import polish

    data = paper_sample("khaki_paint", seed=3)
    data = data.select(np.isin(np.round(np.degrees(data.theta_i)), [10, 45])
                       & (np.round(np.degrees(data.theta_r)) % 5 == 0))
    result = fit(data, population_size=48, max_generations=3)  # 16 starts and its own
    compiled = polish._cache_size()
    laplace = laplace_approximation(data, result)
    assert polish._cache_size() == compiled
    assert np.all(np.isfinite(laplace.std))


# Runs with `pytest -m slow tests/test_uncertainty.py` (pyproject's addopts leave it out of
# the default suite); 20-25 s on the shared 2-core development machine. Measured there:
# coverage 38, 39, 36, 36, 38 of 40; Laplace std / spread 0.80-1.04; bands 0.81-1.23.
@pytest.mark.slow
def test_laplace_coverage_and_band_width_over_40_replicates():
    """40 noise replicates of the synthetic white paint (seeds 500-539, never used to choose
    settings): the Laplace 95 % intervals hold the truth as often as they claim, and the
    widths of the intervals and of the curve bands match the spread between replicates."""
    from scipy.stats import binom

    from brdfjax.plot import curve_angles

    replicates, incidences = 40, [10.0, 21.0, 52.0]  # a fitted and the two held-out
    inside, modes, stds, band_halfwidths, curves = [], [], [], [], []
    for seed in range(500, 500 + replicates):
        data = paper_sample("white_paint", seed=seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UncertaintyWarning)
            result = laplace_approximation(
                data, fit(data, "lm", start=TRUTH, validate_incidences_deg=HELD_OUT))
        inside.append((result.ci95[:, 0] <= TRUTH) & (TRUTH <= result.ci95[:, 1]))
        modes.append(prior_coordinates(result.median))
        stds.append(std_in_prior_coordinates(result))
        bands = curve_bands(result.samples, incidences, count=46)
        band_halfwidths.append(np.concatenate([(b.hi95 - b.lo95) / 2 for b in bands.values()]))
        curves.append(np.concatenate([np.asarray(projected_brdf(result.median,
                                                                *curve_angles(d, 46)[0]))
                                      for d in incidences]))
    # Coverage, per parameter: a count out of 40 that is Binomial(40, 0.95) when the intervals
    # are right; the central 99.8 % of that distribution (33 to 40), so five parameters
    # together fail by chance less than 1 % of the time.
    low, high = binom.interval(0.998, replicates, 0.95)
    counts = np.sum(inside, axis=0)
    assert np.all((counts >= low) & (counts <= high)), (counts, low, high)
    # Widths: the Laplace std against the spread of the modes between replicates, in the
    # prior's coordinates; 40 replicates estimate a std to about 11 %, so within a factor
    # 1.35 (3 standard errors).
    spread = np.std(modes, axis=0, ddof=1)
    ratio = np.median(stds, axis=0) / spread
    assert np.all((ratio > 1 / 1.35) & (ratio < 1.35)), ratio
    # The curve bands: the median 95 % half-width over replicates against 1.96 times the
    # spread of the fitted curves, at each angle; the median over angles within 1.35, and
    # no angle off by more than a factor 2.
    band_ratio = np.median(band_halfwidths, axis=0) / (1.96 * np.std(curves, axis=0, ddof=1))
    assert 1 / 1.35 < np.median(band_ratio) < 1.35, np.median(band_ratio)
    assert np.all((band_ratio > 0.5) & (band_ratio < 2)), band_ratio


def test_laplace_flags_a_parameter_at_its_bound(white_paint):
    # The true kd is 0.22; with kd at most 0.2 the best fit presses against that bound.
    bounds = make_bounds({"kd": (1e-8, 0.2)})
    with pytest.warns(UncertaintyWarning) as caught:
        approximation = laplace_approximation(white_paint, TRUTH * [1, 1, 1, 1, 0.2 / 0.22],
                                              bounds=bounds, validate_incidences_deg=HELD_OUT)
    assert approximation.status == "untrustworthy"
    assert approximation.warnings == [str(w.message) for w in caught]
    assert approximation.warnings[0].startswith("the posterior's mode puts kd at a bound")
    assert "mcmc" in approximation.warnings[0]
    # The table marks that row: its linearised std and its intervals contradicted each
    # other (NiTE on invar A, ggx: kd's std 6e-4 beside a 68 % interval of [1e-8, 100]).
    assert approximation.diagnostics["at_bounds"] == ["kd"]
    rows = {line.split()[0]: line for line in approximation.table().splitlines()
            if line.split() and line.split()[0] in approximation.model.names}
    assert [name for name, line in rows.items() if line.endswith("(cut)")] == ["kd"]
    assert "(cut) kd: the mode lies on a bound of the box" in approximation.table()
    # The misfit is large enough that the data's sigma no longer describe the scatter.
    assert "chi-square per degree of freedom" in approximation.warnings[1]


def test_table_names_the_loss_the_fit_minimised(white_fit, white_laplace):
    """The fit column says which optimum it holds, and stays aligned however long that is."""
    eq6 = white_laplace.table(fitted=white_fit.vector)
    balanced = white_laplace.table(fitted=white_fit.vector, loss="balanced")
    assert "fit (Eq. 6)" in eq6 and "Eq. (6) optimum" in eq6 and "balanced" not in eq6
    assert "fit (balanced)" in balanced and "optimum of the balanced loss" in balanced
    assert "Eq. 6" not in balanced and "Eq. (6)" not in balanced
    lines = balanced.splitlines()
    header = next(line for line in lines if "fit (balanced)" in line)
    end = header.index("fit (balanced)") + len("fit (balanced)")
    for name, value in zip(white_fit.model.names, white_fit.vector):
        row = next(line for line in lines if line.split()[:1] == [name])
        assert row[:end].split()[-1] == f"{value:.6g}" and row[end] in " *", row


def test_laplace_flags_unidentified_parameters():
    # kb = 1e-9: the specular lobe is invisible, so kr, a and b are not determined.
    params = TRUTH * [1e-9 / TRUTH[0], 1, 1, 1, 1]
    data = paper_sample("white_paint")
    clean = np.asarray(projected_brdf(params, data.theta_i, data.theta_r, data.phi_r))
    data = dataclasses.replace(
        data, brdf=clean / np.cos(data.theta_r) * (1 + 0.025 * np.random.default_rng(2)
                                                    .standard_normal(clean.size)),
        sigma=0.025 * clean / np.cos(data.theta_r))
    with pytest.warns(UncertaintyWarning):
        approximation = laplace_approximation(data, params, validate_incidences_deg=HELD_OUT)
    assert approximation.status == "untrustworthy"
    # LM drifts along the flat directions (which flags fire depends on where it stops):
    # the four specular parameters end at a bound or with intervals over much of the box,
    # while kd stays determined.
    bounds = approximation.bounds
    mode = np.asarray(to_unit(approximation.median, bounds))
    width = np.diff(np.asarray(to_unit(approximation.ci95.T, bounds)), axis=0)[0]
    loose = (mode < 1e-6) | (mode > 1 - 1e-6) | (width > 0.1)
    assert list(loose) == [True, True, True, True, False]


def test_laplace_flags_ill_conditioned_curvature(white_paint, white_fit, white_laplace):
    condition = white_laplace.diagnostics["condition_number"]  # about 800: a-b correlated
    with pytest.warns(UncertaintyWarning, match="ill-conditioned"):
        approximation = laplace_approximation(white_paint, white_fit,
                                              condition_limit=condition / 2)
    assert approximation.status == "untrustworthy"


def test_mcmc_converges_and_agrees_with_laplace(white_mcmc, white_laplace):
    assert white_mcmc.method == "mcmc" and white_mcmc.status == "converged"
    d = white_mcmc.diagnostics
    assert d["steps"] > 50 * max(d["tau"].values())
    assert 0.15 < d["acceptance_fraction"] < 0.6
    assert min(d["effective_samples"].values()) > 1000
    assert white_mcmc.chain.shape == (d["steps"], 32, 5)
    # A near-Gaussian posterior: the two methods agree.
    np.testing.assert_allclose(white_mcmc.std, white_laplace.std, rtol=0.15)
    assert np.all(np.abs(white_mcmc.median - white_laplace.median) < 0.3 * white_laplace.std)
    assert white_mcmc.correlation[2, 3] == pytest.approx(white_laplace.correlation[2, 3],
                                                         abs=0.02)


def test_sampler_is_reproducible_and_warns_when_not_converged(white_paint, white_fit,
                                                               white_laplace):
    def run(seed):
        with pytest.warns(UncertaintyWarning, match="did not converge"):
            return sample_posterior(white_paint, white_fit, start=white_laplace, seed=seed,
                                    max_steps=120, progress=False)

    first = run(7)
    compiled = log_posterior_batch._cache_size()
    again, other = run(7), run(8)
    assert log_posterior_batch._cache_size() == compiled  # no recompilation per run
    assert first.status == "not_converged"
    assert "intervals are unreliable" in first.warnings[0]
    np.testing.assert_array_equal(first.chain, again.chain)
    assert not np.array_equal(first.chain, other.chain)


def test_chain_resumes_from_its_file(white_paint, white_fit, white_laplace, tmp_path):
    path = tmp_path / "chain.h5"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UncertaintyWarning)
        short = sample_posterior(white_paint, white_fit, start=white_laplace, seed=3,
                                 max_steps=60, chain_path=path, progress=False)
        longer = sample_posterior(white_paint, white_fit, seed=99, max_steps=100,
                                  chain_path=path, progress=False)
        with pytest.raises(ValueError, match="walkers"):
            sample_posterior(white_paint, white_fit, walkers=40, max_steps=120,
                             chain_path=path, progress=False)
    assert longer.chain.shape == (100, 32, 5)
    np.testing.assert_array_equal(longer.chain[:60], short.chain)
    assert json.loads(json.dumps(longer.to_dict()))["diagnostics"]["steps"] == 100


def test_noise_model_is_inferred_by_both_methods(white_paint, white_fit):
    data = dataclasses.replace(white_paint, sigma=None)
    with pytest.warns(UncertaintyWarning, match="sigma_abs sits at the lower edge of its prior"):
        approximation = laplace_approximation(data, white_fit)
    assert any("sigma_abs sits at the lower edge" in text for text in approximation.warnings)
    assert "warning: the noise scale sigma_abs" in approximation.table()
    assert approximation.noise["sigma_rel"]["median"] == pytest.approx(0.025, rel=0.1)
    low, high = approximation.noise["sigma_rel"]["ci95"]
    assert low < 0.025 < high
    assert approximation.noise["sigma_abs"]["ci95"] is None  # none in the data: prior edge
    with pytest.warns(UncertaintyWarning, match="did not converge"):
        sampled = sample_posterior(data, white_fit, start=approximation, max_steps=300,
                                   progress=False)
    assert sampled.chain.shape[2] == 7
    assert sampled.noise["sigma_rel"]["ci95"][0] < 0.025 < sampled.noise["sigma_rel"]["ci95"][1]


def test_curve_bands_match_the_linearised_spread(white_laplace):
    import jax

    incidences = [21.0, 30.0]  # one held out, one fitted
    bands = curve_bands(white_laplace.samples, incidences, count=91)
    for incidence, band in bands.items():
        assert np.all((band.lo95 <= band.lo68) & (band.lo68 <= band.hi68)
                      & (band.hi68 <= band.hi95))
        # Delta method: var f = g^T C g, g the gradient of f in the physical parameters.
        theta_r = np.radians(np.abs(band.signed_deg))
        phi_r = np.where(band.signed_deg > 0, np.pi, 0.0)
        gradient = np.asarray(jax.jacfwd(projected_brdf)(
            white_laplace.median, np.radians(incidence), theta_r, phi_r))
        linear = np.sqrt(np.einsum("ni,ij,nj->n", gradient, white_laplace.covariance,
                                   gradient))
        np.testing.assert_allclose((band.hi68 - band.lo68) / 2, linear, rtol=0.12)


def test_reflectance_bands_contain_the_truth(white_mcmc):
    bands = reflectance_bands(white_mcmc.samples, [0.0, 45.0], draws=200)
    truth = np.asarray(reflectance(TRUTH, np.radians([0.0, 45.0])))
    assert np.all((bands.lo95 < truth) & (truth < bands.hi95))
    assert np.all((bands.lo95 < bands.lo68) & (bands.lo68 < bands.median)
                  & (bands.median < bands.hi68) & (bands.hi68 < bands.hi95))
    assert set(bands.to_dict()) == {"0", "45"}


@pytest.fixture
def fit_once(monkeypatch, white_fit):
    """The CLI's fit replaced by the module's, so CLI tests do not refit."""
    monkeypatch.setattr(brdfjax.fitting.fit, "fit", lambda *args, **kwargs: white_fit)


def test_cli_uncertainty_none_does_no_uncertainty_work(fit_once, monkeypatch, tmp_path, capsys):
    def forbidden(*args, **kwargs):
        raise AssertionError("--uncertainty none must not compute uncertainty")

    for module, name in [("brdfjax.uncertainty.laplace", "laplace_approximation"),
                         ("brdfjax.uncertainty.mcmc", "sample_posterior"),
                         ("brdfjax.uncertainty.bands", "curve_bands"), ("brdfjax.uncertainty.bands", "reflectance_bands")]:
        monkeypatch.setattr(sys.modules[module], name, forbidden)
    out = tmp_path / "fit.json"
    assert main(["fit", str(DATA / "synthetic" / "white_paint.csv"), "--uncertainty", "none",
                 "--validate-incidence", "21,52", "--json", str(out)]) == 0
    assert "uncertainty" not in json.loads(out.read_text())
    assert "uncertainty (" not in capsys.readouterr().out  # no table (the tmp path has the word)


def test_importing_uncertainty_does_not_import_emcee():
    code = ("import sys, brdfjax.commands.fitting, brdfjax.uncertainty.laplace, brdfjax.uncertainty.bands, "
            "brdfjax.uncertainty.mcmc; assert 'emcee' not in sys.modules, 'emcee imported'; "
            "assert 'h5py' not in sys.modules and 'corner' not in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=REPO)


def test_cli_json_schema_and_plots(fit_once, tmp_path, capsys):
    out = tmp_path / "fit.json"
    assert main(["fit", str(DATA / "synthetic" / "white_paint.csv"), "--validate-incidence",
                 "21,52", "--json", str(out), "--plot", str(tmp_path / "fit.png"),
                 "--plot-corner", str(tmp_path / "corner.png")]) == 0
    table = capsys.readouterr().out
    assert "uncertainty (laplace, ok)" in table and "95 % interval" in table
    uncertainty = json.loads(out.read_text())["uncertainty"]
    assert uncertainty["method"] == "laplace" and uncertainty["status"] == "ok"
    assert set(uncertainty["params"]) == set(PARAMETER_NAMES)
    for entry in uncertainty["params"].values():
        assert set(entry) == {"median", "std", "ci68", "ci95"}
        assert entry["ci95"][0] < entry["ci68"][0] < entry["median"] < entry["ci68"][1] \
            < entry["ci95"][1]
    assert set(uncertainty["reflectance"]) == {f"{d}" for d in range(0, 90, 10)}
    assert set(uncertainty["reflectance"]["0"]) == {"median", "std", "ci68", "ci95"}
    assert (tmp_path / "fit.png").stat().st_size > 0
    assert (tmp_path / "corner.png").stat().st_size > 0


def test_cli_says_which_loss_the_fit_minimised(monkeypatch, white_fit, capsys):
    """The fit's header and the table's fit column name a loss other than Eq. (6)."""
    import dataclasses

    balanced = dataclasses.replace(white_fit, loss="balanced")
    monkeypatch.setattr(brdfjax.fitting.fit, "fit", lambda *args, **kwargs: balanced)
    assert main(["fit", str(DATA / "synthetic" / "white_paint.csv"), "--validate-incidence",
                 "21,52", "--loss", "balanced"]) == 0
    out = capsys.readouterr().out
    assert "model minimising the balanced loss, status" in out
    assert "the fit of the balanced loss lies" in out and "Eq. (6) fit" not in out


def test_cli_mcmc_reports_an_unconverged_chain(fit_once, tmp_path, capsys):
    out = tmp_path / "fit.json"
    assert main(["fit", str(DATA / "synthetic" / "white_paint.csv"), "--validate-incidence",
                 "21,52", "--uncertainty", "mcmc", "--walkers", "16", "--mcmc-steps", "80",
                 "--json", str(out)]) == 0
    table = capsys.readouterr().out
    assert "uncertainty (mcmc, not_converged: " in table and "autocorrelation times" in table
    assert "its 1 warning" in table and "--uncertainty-table" in table
    uncertainty = json.loads(out.read_text())["uncertainty"]
    assert uncertainty["method"] == "mcmc" and uncertainty["status"] == "not_converged"
    assert uncertainty["diagnostics"]["walkers"] == 16
    assert main(["fit", str(DATA / "synthetic" / "white_paint.csv"), "--uncertainty", "none",
                 "--plot-corner", str(tmp_path / "c.png")]) == 1


@pytest.mark.parametrize(("version", "fixed"), [
    ("3.1.6", False), ("3.1.5", False), ("3.0.2", False), ("3.1.6.post1", False),
    ("3.1.7", True), ("3.2", True), ("3.2.0.post1", True), ("4.0.0", True),
    ("3.1.7.dev12+g1a2b3c", False), ("3.1.7rc1", False), ("unknown", False)])
def test_snooker_move_follows_the_installed_emcee(monkeypatch, version, fixed):
    """emcee <= 3.1.6 has the snooker bug (fixed on emcee's main branch, PR #531, January
    2025): the corrected move until a final release after 3.1.6, then emcee's own."""
    import emcee

    assert emcee_snooker_is_fixed(version) is fixed
    monkeypatch.setattr(emcee, "__version__", version)
    move = snooker_move(gamma=1.5)
    assert isinstance(move, emcee.moves.DESnookerMove) is fixed
    assert isinstance(move, emcee.moves.red_blue.RedBlueMove)
    if fixed:
        assert move.gammas == 1.5


def test_the_installed_emcee_gets_the_move_it_needs():
    import emcee

    move = snooker_move()
    assert isinstance(move, emcee.moves.DESnookerMove) == emcee_snooker_is_fixed(
        emcee.__version__)


def test_measurements_without_information_are_refused():
    grazing = Measurements.from_degrees([30.0], [90.0], [0.0], [0.1])
    with pytest.raises(ValueError, match="no measurement"):
        build_posterior(grazing)


def test_the_table_and_json_say_which_estimate_the_intervals_are_about(white_fit,
                                                                     white_laplace):
    """In Python too (table() with no arguments), the fit stands beside the posterior median,
    a fitted value outside its interval is marked, and the table and the JSON say which of
    the two the intervals are about and which to report (issue 26: b's interval
    [-61.3, -57.3] beside a fitted b of -64.9, unexplained)."""
    np.testing.assert_array_equal(white_laplace.fitted, white_fit.vector)
    table = white_laplace.table()
    assert table == white_laplace.table(fitted=white_fit.vector, loss=white_fit.loss)
    assert "fit (Eq. 6)" in table
    assert "report: the posterior median with its intervals" in table
    record = white_laplace.to_dict()
    assert "intervals are about the posterior median" in record["about"]
    outside = [name for k, name in enumerate(white_fit.model.names)
               if not white_laplace.ci95[k][0] <= white_fit.vector[k]
               <= white_laplace.ci95[k][1]]
    assert record["fit_outside_ci95"] == outside
    for name in outside:
        row = next(line for line in table.splitlines() if line.split()[:1] == [name])
        assert "*" in row


def test_mcmc_keeps_the_fit_it_started_from(white_fit, white_mcmc):
    """emcee's result, like Laplace's, carries the fit, so its table shows the fit column."""
    np.testing.assert_array_equal(white_mcmc.fitted, white_fit.vector)
    assert "fit (Eq. 6)" in white_mcmc.table()
    assert white_mcmc.to_dict()["fit_outside_ci95"] == white_mcmc.fit_outside()


# The in-plane AnoBlack EC1 coating with ggx+backscatter, at the hybrid fit's optimum (seed
# 0; beta at its upper bound, 2): issue 47, defect 2.
ANOBLACK = "uaz-loft-rt300s/raw/ANOPLATE_AnoBlack_EC1_Alum6061_v1o0_20251115.xls"
ANOBLACK_FIT = [0.621009, 0.225358, 0.0407846, 0.00439618, 0.00705694, 2.0]


def test_axis_falls_against_closed_forms():
    """`axis_falls` is 1 on every axis of a Gaussian, and what a quartic term adds where the
    density is not one: -log p = x^T A x / 2 + c (u.x)^4 falls, 2 standard deviations along
    an axis v of A with eigenvalue mu, by 2 + c (2 u.v / sqrt(mu))^4; relative to the
    Gaussian's 2, 1 + c (2 u.v)^4 / (2 mu^2)."""
    from brdfjax.uncertainty.laplace import axis_falls

    rng = np.random.default_rng(0)
    root = rng.standard_normal((4, 4))
    information = root @ root.T + 4 * np.eye(4)
    center = rng.standard_normal(4)

    def gaussian(x):
        d = x - center
        return -0.5 * np.einsum("ni,ij,nj->n", d, information, d)

    falls, axes = axis_falls(gaussian, center, information)
    np.testing.assert_allclose(falls, 1.0, rtol=1e-9)
    mu, vectors = np.linalg.eigh(information)
    np.testing.assert_allclose(np.abs(axes), np.abs(vectors), atol=1e-12)

    u, c = np.array([1.0, -2.0, 0.5, 0.0]), 0.7

    def quartic(x):
        return gaussian(x) - c * ((x - center) @ u) ** 4

    falls, axes = axis_falls(quartic, center, information)
    expected = 1 + c * (2 * (axes.T @ u)) ** 4 / (2 * mu**2)
    np.testing.assert_allclose(falls, np.stack([expected, expected], axis=1), rtol=1e-9)

    # A box that cuts an axis within 2 standard deviations: an infinite fall that way.
    def boxed(x):
        return np.where(x[:, 0] > center[0] + 1e-3, -np.inf, gaussian(x))

    falls, axes = axis_falls(boxed, center, information)
    assert np.all(np.isinf(falls[np.arange(4), (axes[0] > 0).astype(int)]))


def test_laplace_ok_means_the_gaussian_holds(white_laplace):
    """Laplace said "ok" on the AnoBlack coating with a kd-kb correlation of -0.994, where
    its kd interval [8.4e-5, 0.024] misses emcee's median 2.1e-5 (emcee's 95 %:
    [1.4e-8, 3.1e-3]). There the log-posterior, computed here without the module, falls
    hundreds of times faster than the Gaussian's along the kd-kb-beta axis: untrustworthy,
    and why. The white paint's falls are within 5 % of the Gaussian's: ok."""
    from conftest import REAL

    from brdfjax.data.formats import load

    data = load(REAL / ANOBLACK, in_plane=True)
    with pytest.warns(UncertaintyWarning, match="not Gaussian"):
        approximation = laplace_approximation(data, np.array(ANOBLACK_FIT),
                                              model="ggx+backscatter")
    assert approximation.status == "untrustworthy"
    assert approximation.diagnostics["reasons"][0].startswith("not Gaussian along kd-kb")
    assert abs(approximation.correlation[3, 4]) > 0.99

    # The fall along the worst axis, from norm.logpdf and the model alone (the posterior
    # leaves out the points at theta_r = 90 deg, whose projected BRDF is 0).
    from brdfjax.models.bounds import from_unit

    size, center, model = 6, approximation.center, approximation.model
    information = np.linalg.inv(approximation.center_covariance)[:size, :size]
    mu, axes = np.linalg.eigh(information)
    s_rel, s_abs = 10.0 ** center[size:]
    kept = data.select(np.cos(data.theta_r) > 1e-12)
    target = kept.brdf * np.cos(kept.theta_r)

    def log_density(unit):
        m = np.asarray(projected_brdf(np.asarray(from_unit(unit, approximation.bounds)),
                                      kept.theta_i, kept.theta_r, kept.phi_r, model=model))
        return norm.logpdf(target, m, np.sqrt((s_rel * m) ** 2 + s_abs**2)).sum()

    worst = 0  # the widest axis, eigh's first
    step = 2 / np.sqrt(mu[worst]) * axes[:, worst]
    base = log_density(center[:size])
    falls = [(base - log_density(center[:size] + sign * step)) / 2 for sign in (-1, 1)]
    assert min(falls) > 100
    np.testing.assert_allclose(falls, approximation.diagnostics["axis_falls"][worst],
                               rtol=1e-3)
    assert white_laplace.status == "ok" and white_laplace.diagnostics["reasons"] == []
    np.testing.assert_allclose(white_laplace.diagnostics["axis_falls"], 1.0, atol=0.05)


def test_share_outside_counts_the_points_outside_the_95_band():
    """The share of the fitted curve outside its band, against a band built by hand: above
    the curve on the source side of the first scan only (the points of negative signed
    angle), around it elsewhere."""
    from brdfjax.plot import curve_angles
    from brdfjax.uncertainty.bands import CurveBand, share_outside

    bands, outside = {}, 0
    for k, incidence in enumerate((10.0, 45.0)):
        angles, signed = curve_angles(incidence, 91)
        curve = np.asarray(projected_brdf(TRUTH, *angles))
        base = np.where((signed < 0) & (k == 0), 1.5 * curve, curve)
        bands[incidence] = CurveBand(signed, 0.95 * base, 1.05 * base, 0.9 * base, 1.1 * base)
        outside += int(np.sum((signed < 0) & (k == 0)))
    assert share_outside(bands, TRUTH) == pytest.approx(outside / (2 * 91), abs=1e-12)


def test_brief_is_short_and_says_why_the_fit_differs(white_fit, white_laplace):
    """The default block: a few lines, each parameter's median and 95 % interval as
    computed, and the fitted parameters outside those intervals named, checked here
    against the intervals themselves."""
    brief = white_laplace.brief(hint="more: --uncertainty-table")
    lines = brief.splitlines()
    assert len(lines) <= 7 and lines[0].startswith("uncertainty (laplace, ok)")
    assert lines[-1] == "  more: --uncertainty-table"
    flat = " ".join(line.strip() for line in lines)
    for k, name in enumerate(white_fit.model.names):
        low, high = white_laplace.ci95[k]
        assert f"{name} {white_laplace.median[k]:.3g} [{low:.3g}, {high:.3g}]" in flat
    outside = [name for k, name in enumerate(white_fit.model.names)
               if not white_laplace.ci95[k][0] <= white_fit.vector[k] <= white_laplace.ci95[k][1]]
    assert outside  # the white paint's fit is another estimate than the posterior's
    assert f"outside the 95 % intervals of {', '.join(outside)}:" in flat
    assert "a and b are determined together" in flat
    # A fitted value at its bound is named, beside the posterior's value.
    pressed = white_fit.vector.copy()
    pressed[3] = white_laplace.bounds.upper[3]
    note = white_laplace.fit_note(pressed)
    assert f"b = {pressed[3]:.3g} sits at a bound, the posterior's at " in note
    assert "lies inside every 95 % interval" in white_laplace.fit_note(white_laplace.median)


def test_cli_prints_a_short_block_and_the_full_table_on_request(fit_once, capsys):
    """``brdfjax fit`` prints the few lines of `UncertaintyResult.brief` (the block was
    about 20 lines); ``--uncertainty-table`` the whole table."""
    path = str(DATA / "synthetic" / "white_paint.csv")
    assert main(["fit", path, "--validate-incidence", "21,52"]) == 0
    out = capsys.readouterr().out
    block = out[out.index("uncertainty (laplace"):].splitlines()
    assert len(block) <= 7 and "--uncertainty-table" in block[-1]
    assert "strongest correlations" not in out
    assert main(["fit", path, "--validate-incidence", "21,52", "--uncertainty-table"]) == 0
    out = capsys.readouterr().out
    assert "strongest correlations" in out and "68 % interval" in out
