"""The figures of out-of-plane, scattered and spectral data: drawn, and refusing misuse."""

from pathlib import Path

import numpy as np
import pytest
from conftest import REAL

from brdfjax.data.formats import load
from brdfjax.plot import plot_hemisphere, plot_polar_maps, plot_spectral

REPO = Path(__file__).resolve().parents[1]
PTFE = REAL / "nist-germer-ptfe"


def is_png(path) -> bool:
    return path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 20000


@pytest.mark.parametrize("name,options", [("PTFE.data.csv", {"wavelength_nm": 532}),
                                          ("PTFE.data.random.csv", {})])
def test_polar_maps_of_grid_and_scattered_data(tmp_path, name, options):
    data = load(PTFE / name, **options)
    predicted = np.full(len(data), np.median(data.brdf))
    plot_polar_maps(data, predicted, tmp_path / "maps.png", title=name)
    assert is_png(tmp_path / "maps.png")


def test_polar_maps_need_one_prediction_per_point(tmp_path):
    data = load(PTFE / "PTFE.data.random.csv")
    with pytest.raises(ValueError, match="predicted has 3 values, the data 1760"):
        plot_polar_maps(data, [1.0, 2.0, 3.0], tmp_path / "maps.png")


def test_hemisphere_and_spectral_figures(tmp_path):
    from brdfjax.models.paper import PAPER_SAMPLES

    plot_hemisphere(PAPER_SAMPLES["white_paint"], [10, 60], tmp_path / "h.png",
                    resolution=31)
    records = [{"wavelength_nm": w, "params": {"kb": 0.1 * k + 0.1, "b": -20.0 + k},
                "std": {"kb": 0.01, "b": None}} for k, w in enumerate((351, 532, 633))]
    records.append({"wavelength_nm": 1064, "params": {"kb": 0.5, "b": -15.0}})
    plot_spectral(records, tmp_path / "s.png", ["kb", "b"])
    assert is_png(tmp_path / "h.png") and is_png(tmp_path / "s.png")


def test_the_hemisphere_draws_the_peak_at_its_height(tmp_path):
    """demo_hemisphere.png drew white paint's 10 deg back-scatter peak at about 4.5 against
    5.97 (brdfjax eval): its grid missed the peak's direction and the surface skipped rows.
    The drawn surface now holds the peak exactly."""
    import brdfjax
    from brdfjax.models.paper import PAPER_SAMPLES

    params = PAPER_SAMPLES["white_paint"]
    peaks = plot_hemisphere(params, [10, 30, 60], tmp_path / "h.png")
    for incidence, drawn in peaks.items():
        exact = float(brdfjax.projected_brdf(params, np.radians(incidence),
                                             np.radians(incidence), 0.0))
        assert drawn == pytest.approx(exact, rel=1e-12)
    assert peaks[10.0] == pytest.approx(5.9713, rel=1e-4)
    assert is_png(tmp_path / "h.png")


def test_fit_curves_pass_through_the_peaks_and_bands_are_named_not_faint(tmp_path):
    """The in-plane curves hold the back-scatter and specular directions (the white paint's
    peaks were drawn up to 5 % low between grid points), and the shaded bands are named in
    the legend, strongest first, instead of "(lighter)" in one title and "(darker)" in
    another."""
    import brdfjax
    from brdfjax.models.paper import PAPER_SAMPLES
    from brdfjax.plot import curve_angles, plot_fit

    params = PAPER_SAMPLES["white_paint"]
    for incidence in (10.0, 21.0, 52.0, 60.0):
        angles, signed = curve_angles(incidence)
        assert signed.size == 361 and np.all(np.diff(signed) > 0)
        assert {-incidence, incidence} <= set(signed)
        curve = np.asarray(brdfjax.projected_brdf(params, *angles))
        peak = float(brdfjax.projected_brdf(params, np.radians(incidence),
                                            np.radians(incidence), 0.0))
        assert curve.max() == pytest.approx(peak, rel=1e-12)

    data = load(REPO / "data" / "synthetic" / "white_paint.csv").at_incidences([10, 60])
    bands, predictive = {}, {}
    for incidence in (10.0, 60.0):
        angles, signed = curve_angles(incidence)
        curve = np.asarray(brdfjax.projected_brdf(params, *angles))
        bands[incidence] = (signed, 0.98 * curve, 1.02 * curve, 0.96 * curve, 1.04 * curve)
        predictive[incidence] = (signed, curve, 0.9 * curve, 1.1 * curve, 0.8 * curve,
                                 1.2 * curve)
    figure = plot_fit(data, params, tmp_path / "fit.png", bands=bands, predictive=predictive)
    (ax,) = figure.axes
    legend = {t.get_text(): h for t, h in zip(ax.get_legend().get_texts(),
                                               ax.get_legend().legend_handles)}
    alpha = [legend[k].get_alpha() for k in ("68 % band of the posterior's curves",
                                             "95 % band of the posterior's curves",
                                             "95 % predictive band (a new measurement)")]
    assert alpha == sorted(alpha, reverse=True) and alpha[1] >= 0.2  # visible, not faint
    # the legend stands below the axes: inside, it covered the first incidences' peaks
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(figure)  # the figure was closed: lay it out again to measure
    canvas.draw()
    renderer = canvas.get_renderer()
    assert not ax.get_legend().get_window_extent(renderer).overlaps(
        ax.get_window_extent(renderer))
    assert not any(word in ax.get_title() for word in ("lighter", "darker"))
    assert is_png(tmp_path / "fit.png")
    # every line style is named: the fitted curve, and dashed where an incidence is held out
    assert legend["fitted five model"].get_linestyle() == "-"
    assert "fitted five model at a held-out incidence" not in legend
    figure = plot_fit(data, params, tmp_path / "held.png", held_out=[60.0])
    legend = {t.get_text(): h for t, h in zip(figure.axes[0].get_legend().get_texts(),
                                               figure.axes[0].get_legend().legend_handles)}
    assert legend["fitted five model at a held-out incidence"].get_linestyle() == "--"
    # an incidence predicted but not measured (--predict) gets its curve, band and name
    angles, signed = curve_angles(35.0)
    curve = np.asarray(brdfjax.projected_brdf(params, *angles))
    predictive[35.0] = (signed, 1.05 * curve, curve, curve, 0.8 * curve, 1.3 * curve)
    figure = plot_fit(data, params, tmp_path / "asked.png", predictive=predictive)
    (ax,) = figure.axes
    legend = {t.get_text(): h for t, h in zip(ax.get_legend().get_texts(),
                                               ax.get_legend().legend_handles)}
    assert legend["35 deg predicted (not measured)"].get_linestyle() == ":"
    assert legend["fitted five model at an incidence the data lack"].get_linestyle() == "-."
    drawn = [line.get_ydata() for line in ax.get_lines() if len(line.get_ydata()) == 361]
    assert any(np.array_equal(y, 1.05 * curve) for y in drawn)  # the prediction, dotted
    assert any(np.allclose(y, curve, rtol=1e-12) for y in drawn)  # the model, dash-dotted


def test_prediction_bands_are_drawn_down_to_their_lower_edge(tmp_path):
    """Each panel's 95 % band is drawn down to its own lower edge, below the faintest
    held-out point it holds (it was cut at 0.3 x the lowest prediction, and held-out points
    inside the band were drawn outside it), and a negative edge runs to the axis' bottom."""
    from matplotlib.collections import PolyCollection

    from brdfjax.data.measurements import Measurements
    from brdfjax.plot import plot_prediction_bands
    from brdfjax.prediction.intervals import Prediction

    theta_r = np.arange(5.0, 86.0, 5.0)
    held = Measurements.from_degrees(np.full(theta_r.size, 30.0), theta_r,
                                     np.full(theta_r.size, 180.0), 10.0 ** -(theta_r / 20))
    centre = 4 * held.brdf  # predictions four times too high: the band's edge is far below

    def prediction(low95):
        return Prediction(*np.degrees([held.theta_i, held.theta_r, held.phi_r]), centre,
                          centre, 0.5 * centre, 2 * centre, low95, 8 * centre, held.brdf,
                          "ggx")

    figure = plot_prediction_bands(held, {"positive": prediction(0.2 * centre),
                                          "negative": prediction(centre - 10)},
                                   tmp_path / "bands.png")
    cos_r = np.cos(held.theta_r)
    for ax in figure.axes:
        bottom = ax.get_ylim()[0]
        assert bottom < np.min(0.2 * centre * cos_r) and bottom < np.min(held.brdf * cos_r)
        band = next(c for c in ax.collections if isinstance(c, PolyCollection))
        lowest = band.get_paths()[0].vertices[:, 1].min()
        assert lowest == pytest.approx(bottom if ax.get_title().startswith("negative")
                                       else np.min(0.2 * centre * cos_r), rel=1e-9)


def test_fit_bands_name_the_posterior_and_draw_its_median(tmp_path):
    """The bands are the posterior's, not the fitted curve's (issue 47, defect 2: "68 % band
    of the fitted curve" around a curve that left them): the legend says so and which
    method, the curve they are about is drawn, and a note under the title says why the fit
    leaves them."""
    import brdfjax
    from brdfjax.models.paper import PAPER_SAMPLES
    from brdfjax.plot import curve_angles, plot_fit
    from brdfjax.uncertainty.bands import CurveBand

    params = PAPER_SAMPLES["white_paint"]
    data = load(REPO / "data" / "synthetic" / "white_paint.csv").at_incidences([10])
    angles, signed = curve_angles(10.0)
    median = 1.2 * np.asarray(brdfjax.projected_brdf(params, *angles))
    bands = {10.0: CurveBand(signed, 0.98 * median, 1.02 * median, 0.96 * median,
                             1.04 * median, median)}
    note = "The fitted curve leaves the posterior's 95 % band along 100 % of its length."
    figure = plot_fit(data, params, tmp_path / "fit.png", bands=bands, bands_method="mcmc",
                      note=note)
    (ax,) = figure.axes
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "68 % band of the posterior's curves (mcmc)" in labels
    assert "posterior median curve (the bands' centre)" in labels
    assert not any("fitted curve" in label for label in labels)
    assert any(np.array_equal(line.get_ydata(), median) for line in ax.get_lines())
    assert ax.get_title().replace("\n", " ") == note
    assert is_png(tmp_path / "fit.png")


def test_spectral_figure_names_sample_model_and_units(monkeypatch, tmp_path):
    """spectral.png named neither the sample nor the model and gave no units (issue 47,
    defect 9); its title follows every figure's convention (`figure_title`)."""
    import matplotlib.figure

    from brdfjax.plot import figure_title

    assert figure_title("PTFE", "five", "x") == "PTFE: five fit, x"

    seen = {}
    real = matplotlib.figure.Figure.savefig

    def spy(self, *args, **kwargs):
        seen["title"] = self._suptitle.get_text()
        seen["labels"] = [ax.get_ylabel() for ax in self.axes if ax.get_visible()]
        return real(self, *args, **kwargs)

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", spy)
    records = [{"wavelength_nm": w, "params": {"kb": 0.1 * k + 0.1, "b": -20.0 + k}}
               for k, w in enumerate((351, 532, 633))]
    plot_spectral(records, tmp_path / "s.png", ["kb", "b"], sample="PTFE", model="five")
    assert seen["title"].startswith("PTFE: five fit, against wavelength")
    assert seen["labels"] == ["kb (1/sr)", "b (dimensionless)"]
