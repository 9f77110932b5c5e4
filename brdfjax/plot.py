"""Figures people look at: fitted curves over the data, and the model over the hemisphere.

matplotlib (Agg backend) is imported here only, when a figure is asked for. Curves show
the projected BRDF ``f_r cos(theta_r)`` against the signed reflection angle (positive on
the specular side), as the paper's Fig. 5/6 do; the 3-D view shows the fitted model over
the whole hemisphere, as its Fig. 9-15 do. Out-of-plane data are drawn as polar maps of
data, model and residual (`plot_polar_maps`), spectral fits as parameters against
wavelength (`plot_spectral`). For uncertainty: bands on the curves
(`plot_fit`'s ``bands``, `plot_band_widths`), on the reflectance (`plot_reflectance_bands`),
and the posterior's corner plot (`plot_corner`, with the ``corner`` package).
"""

from __future__ import annotations

import functools
import textwrap

import numpy as np

# Opacity of the shaded bands: the curve's 68 % band darkest, its 95 % band lighter, the
# predictive band (much wider, drawn under them) lightest; strong enough to see on a
# projector or in print (issue 26: the old 0.3 / 0.15 / 0.08 were faint).
BAND_ALPHA = {"68": 0.45, "95": 0.25}
PREDICTIVE_ALPHA = 0.14
# Line width of the posterior's median curve in `plot_fit`, thinner than the fit's 1.5.
MEDIAN_WIDTH = 0.7


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def signed_angle_deg(data) -> np.ndarray:
    """Signed reflection angle in degrees: positive on the specular side (phi_r = 180)."""
    return np.where(np.cos(data.phi_r) < 0, 1.0, -1.0) * np.degrees(data.theta_r)


def curve_angles(incidence_deg: float, count: int = 361):
    """In-plane angles (radians) for a smooth curve at one incidence, and the signed degrees.

    ``count`` points from -89.9 to 89.9 deg, the two nearest the back-scatter (``-theta_i``)
    and specular (``+theta_i``) directions moved onto them: a narrow peak there is drawn at
    its height, not up to half a step beside it (the white paint's peaks were drawn up to
    5 % low).
    """
    signed = np.linspace(-89.9, 89.9, count)
    for direction in (-incidence_deg, incidence_deg):
        direction = float(np.clip(direction, -89.9, 89.9))
        signed[np.argmin(np.abs(signed - direction))] = direction
    theta_i = np.full(count, np.radians(incidence_deg))
    return (theta_i, np.radians(np.abs(signed)), np.where(signed > 0, np.pi, 0.0)), signed


def plot_fit(data, params, path, title: str = "", held_out=(), bands=None, log: bool = False,
             model=None, predictive=None, errors=None, bands_method: str = "", note: str = "",
             readings=None):
    """Data points and fitted curves of f_r cos(theta_r), one colour per incidence.

    Args:
        data: the measurements (every incidence is drawn).
        params: fitted parameters of ``model`` (kb, kr, a, b, kd by default).
        path: output image file (PNG, PDF or SVG by suffix).
        title: figure title.
        held_out: incidences (deg) not used in the fit, drawn hollow and dashed.
        bands: optional ``{incidence: (signed_deg, lo68, hi68, lo95, hi95[, median])}`` to
            shade: the posterior's bands of the curve (`brdfjax.uncertainty.bands.CurveBand`),
            named in the legend; their median, the curve they are about, is drawn thin.
        bands_method: the method the bands come from (laplace, mcmc), named in the legend.
        note: a sentence shown under the title (why the fit leaves its bands, say).
        predictive: predictive bands (drawn under the others, lightest, named in the
            legend), ``{incidence: (signed_deg, prediction, lo68, hi68, lo95, hi95)}``; the
            prediction is drawn dotted where it differs from the model curve (a learned
            discrepancy corrects it). An incidence here that the data lack (one asked for
            with ``--predict``) is drawn too, its model curve dash-dotted.
        errors: ``{incidence: E}`` shown in the legend (a fraction; printed in %).
        readings: readings the data lack (those of a ``--predict`` file), in the plane of
            incidence: ``{incidence: (Measurements, label)}``, drawn as crosses in their
            incidence's colour and named in the legend by ``label``; an incidence the data
            lack is then drawn as measured, not as "predicted (not measured)".
        log: log-scale the vertical axis (for dark samples with a strong peak).
        model: a model name or `brdfjax.models.Model` (the five-parameter model if None).

    Returns:
        The matplotlib figure (already saved and closed), for inspection.
    """
    from brdfjax.models.paper import projected_brdf

    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 6))
    measured = [float(t) for t in data.incidences_deg]
    extra = {float(t): value for t, value in (readings or {}).items()}
    asked = sorted(float(t) for t in {*(predictive or {}), *extra}
                   if not np.any(np.isclose(float(t), measured)))
    incidences = sorted(measured + asked)
    colours = plt.get_cmap("viridis")(np.linspace(0, 0.9, max(1, len(incidences))))
    held = {round(float(x), 6) for x in held_out}
    corrected = False
    for colour, incidence in zip(colours, incidences):
        is_held = round(float(incidence), 6) in held
        if incidence in asked and incidence not in extra:
            ax.plot([], [], ":", color=colour, lw=1.5,
                    label=f"{incidence:g} deg predicted (not measured)")
        elif incidence not in asked:
            subset = data.at_incidences([incidence])
            error = (errors or {}).get(float(incidence))
            ax.plot(signed_angle_deg(subset), subset.brdf * np.cos(subset.theta_r),
                    "o", ms=3, mfc="none" if is_held else colour, mec=colour,
                    label=f"{incidence:g} deg data" + (" (held out)" if is_held else "")
                    + ("" if error is None else f", E {100 * error:.3g} %"))
        if incidence in extra:
            points, label = extra[incidence]
            ax.plot(signed_angle_deg(points), points.brdf * np.cos(points.theta_r),
                    "x", ms=4.5, mew=1.2, color=colour, label=label)
        angles, signed = curve_angles(incidence)
        curve = np.asarray(projected_brdf(np.asarray(params, float), *angles, model=model))
        style = "-." if incidence in asked else "--" if is_held else "-"
        ax.plot(signed, curve, style, color=colour, lw=1.5)
        if predictive and incidence in predictive:
            x, centre, _, _, lo95, hi95 = predictive[incidence]
            if log:  # a band reaching zero or below ends at the bottom of the data's decades
                lo95 = np.maximum(lo95, 0.1 * np.min(curve[curve > 0], initial=np.inf))
            ax.fill_between(x, lo95, hi95, color=colour, alpha=PREDICTIVE_ALPHA, lw=0)
            if not np.allclose(centre, curve, rtol=1e-9, atol=0):
                corrected = True
                ax.plot(x, centre, ":", color=colour, lw=1.5)
        if bands and incidence in bands:
            x, lo68, hi68, lo95, hi95, *median = bands[incidence]
            ax.fill_between(x, lo95, hi95, color=colour, alpha=BAND_ALPHA["95"], lw=0)
            ax.fill_between(x, lo68, hi68, color=colour, alpha=BAND_ALPHA["68"], lw=0)
            if median and median[0] is not None:
                ax.plot(x, median[0], "-", color=colour, lw=MEDIAN_WIDTH)
    ax.set_xlabel("reflection angle theta_r (deg; > 0: specular side, < 0: source side)")
    ax.set_ylabel("f_r cos(theta_r)  (1/sr)")
    if log:
        ax.set_yscale("log")
    if note:
        fig.suptitle(textwrap.fill(title or data.name, 80), fontsize=10)
        ax.set_title(textwrap.fill(note, 110), fontsize=8, color="0.25")
    else:
        ax.set_title(textwrap.fill(title or data.name, 80), fontsize=10)
    handles, _ = ax.get_legend_handles_labels()
    # The shades are named in the legend, so no title has to say "lighter" or "darker".
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    from brdfjax.models import get

    shade = "0.35"
    name = get(model).name
    handles.append(Line2D([], [], ls="-", color=shade, lw=1.5, label=f"fitted {name} model"))
    if held:
        handles.append(Line2D([], [], ls="--", color=shade, lw=1.5,
                              label=f"fitted {name} model at a held-out incidence"))
    if asked:
        handles.append(Line2D([], [], ls="-.", color=shade, lw=1.5,
                              label=f"fitted {name} model at an incidence the data lack"))
    if bands:
        method = f" ({bands_method})" if bands_method else ""
        handles += [Patch(color=shade, alpha=BAND_ALPHA[level], lw=0,
                          label=f"{level} % band of the posterior's curves{method}")
                    for level in ("68", "95")]
        if any(len(band) > 5 and band[5] is not None for band in bands.values()):
            handles.append(Line2D([], [], ls="-", color=shade, lw=MEDIAN_WIDTH,
                                  label="posterior median curve (the bands' centre)"))
    if predictive:
        handles.append(Patch(color=shade, alpha=PREDICTIVE_ALPHA, lw=0,
                             label="95 % predictive band (a new measurement)"))
    if corrected:
        handles.append(Line2D([], [], ls=":", color=shade, lw=1.5,
                              label="prediction: model x learned discrepancy"))
    # Below the axes: inside them, it covered the peaks of the first incidences.
    ax.legend(handles=handles, fontsize=7, ncol=3, loc="upper center",
              bbox_to_anchor=(0.5, -0.14), frameon=False)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    # "tight": the legend below the axes grows with the incidences and is never cut off.
    fig.savefig(path, dpi=120, bbox_inches="tight", pad_inches=0.15)
    plt.close(fig)
    return fig


def plot_prediction_bands(held, predictions: dict, path, title: str = ""):
    """Held-out measurements against predictions and their 68 / 95 % bands, one panel per
    prediction (``{label: brdfjax.prediction.intervals.Prediction}``, in-plane geometry), on one
    log scale of ``f_r cos(theta_r)`` so that the wings read as well as the peak."""
    plt = _pyplot()
    panels = list(predictions.items())
    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 4.4), sharey=True,
                             squeeze=False)
    x = signed_angle_deg(held)
    order = np.argsort(x)
    cos_r = np.cos(held.theta_r)

    def curve(values):
        return (np.asarray(values) * cos_r)[order]

    def lowest(names) -> float:
        values = np.concatenate([curve(held.brdf)] + [curve(getattr(p, k)) for _, p in panels
                                                      for k in names])
        values = values[np.isfinite(values) & (values > 0)]
        return float(values.min()) if values.size else 1e-6

    # One floor for the shared axis, below every drawn value but no more than three decades
    # below the data and predictions: a band whose lower edge is lower (or negative, with
    # relative scores) runs down to it, the axis' edge.
    bottom = max(0.5 * lowest(("brdf", "lo68", "lo95")), 1e-3 * lowest(("brdf",)))
    for ax, (label, prediction) in zip(axes[0], panels):
        ax.fill_between(x[order], np.maximum(curve(prediction.lo95), bottom),
                        curve(prediction.hi95), color="C0", alpha=0.2, lw=0, label="95 %")
        ax.fill_between(x[order], np.maximum(curve(prediction.lo68), bottom),
                        curve(prediction.hi68), color="C0", alpha=0.45, lw=0, label="68 %")
        ax.plot(x[order], curve(prediction.brdf), "-", color="C0", lw=1.5, label="prediction")
        ax.plot(x, held.brdf * cos_r, "o", ms=3.5, mfc="none", mec="k", label="held-out data")
        ax.set_yscale("log")
        ax.set_ylim(bottom=bottom)
        ax.set_title(f"{label}\n95 % half-width {100 * np.median(prediction.half_width()):.0f}"
                     f" % (median), coverage {100 * prediction.coverage('95'):.0f} %",
                     fontsize=9)
        ax.set_xlabel("theta_r (deg; > 0: specular side)")
        ax.grid(alpha=0.3, which="both")
    axes[0][0].set_ylabel("f_r cos(theta_r)  (1/sr)")
    axes[0][0].legend(fontsize=8, loc="lower center")
    fig.suptitle(textwrap.fill(title, 100), fontsize=10)
    fig.tight_layout()
    # "tight": a marker at the figure's edge (the legend's, a point at the last angle) is
    # never cut off
    fig.savefig(path, dpi=120, bbox_inches="tight", pad_inches=0.1)
    plt.close(fig)
    return fig


def plot_hemisphere(params, incidences_deg, path, title: str = "", resolution: int = 121,
                    model=None):
    """3-D surfaces of the model's f_r cos(theta_r) over the hemisphere, one per incidence.

    The horizontal coordinates are ``sin(tr) cos(pr)``, ``sin(tr) sin(pr)`` (the projected
    hemisphere, source at +x), the height is f_r cos(tr), coloured by height with a colour
    bar per panel. The grid holds the back-scatter and specular directions of each incidence
    exactly and is drawn at full resolution (no facet is skipped), so a narrow peak is drawn
    at its true height; each panel's title states that height and where it is. Facets are
    drawn without antialiasing, whose seams between thousands of small facets showed as
    moire rings. Each axis carries three or four ticks in small type.

    Returns:
        ``{incidence: the highest f_r cos(theta_r) drawn}`` (1/sr).
    """
    from matplotlib.ticker import MaxNLocator

    from brdfjax.models.paper import projected_brdf

    plt = _pyplot()
    count = len(incidences_deg)
    fig = plt.figure(figsize=(4.6 * count, 4.4))
    # phi_r: an odd count puts 0 and 180 deg (back-scatter and specular) on the grid.
    phi = np.radians(np.linspace(0, 360, 2 * resolution + 1))
    peaks = {}
    for k, incidence in enumerate(incidences_deg):
        zenith = np.union1d(np.linspace(0, 89.5, resolution), [min(float(incidence), 89.5)])
        theta_r, phi_r = np.meshgrid(np.radians(zenith), phi)
        values = np.asarray(projected_brdf(np.asarray(params, float), np.radians(incidence),
                                           theta_r, phi_r, model=model))
        peak = np.unravel_index(np.nanargmax(values), values.shape)
        ax = fig.add_subplot(1, count, k + 1, projection="3d")
        # A facet is coloured by the mean of its corners: the colour scale is set to the
        # peak itself, so the colour bar reaches the height the surface is drawn to.
        surface = ax.plot_surface(np.sin(theta_r) * np.cos(phi_r),
                                  np.sin(theta_r) * np.sin(phi_r), values, cmap="viridis",
                                  vmin=min(0.0, np.nanmin(values)), vmax=values[peak],
                                  linewidth=0, antialiased=False, rstride=1, cstride=1)
        ax.set_zlim(min(0.0, np.nanmin(values)), values[peak])
        where = (f"theta_r {np.degrees(theta_r[peak]):.3g} deg, "
                 + ("source side" if np.cos(phi_r[peak]) > 0 else "specular side")
                 if np.degrees(theta_r[peak]) >= 0.5 else "the normal")
        ax.set_title(f"incidence {incidence:g} deg\npeak {values[peak]:.3g} 1/sr at {where}",
                     fontsize=9)
        peaks[float(incidence)] = float(values[peak])
        for axis, ticks in ((ax.xaxis, 3), (ax.yaxis, 3), (ax.zaxis, 4)):
            axis.set_major_locator(MaxNLocator(ticks))
        ax.tick_params(labelsize=7, pad=0)
        ax.set_xlabel("sin(theta_r) cos(phi_r)\n(+1: source side)", fontsize=7, labelpad=4)
        ax.set_ylabel("sin(theta_r) sin(phi_r)", fontsize=7, labelpad=2)
        ax.set_zlabel("")  # the colour bar carries the quantity and its unit
        ax.set_box_aspect(None, zoom=1.05)
        bar = fig.colorbar(surface, ax=ax, shrink=0.55, pad=0.1, aspect=18)
        bar.set_label("f_r cos(theta_r)  (1/sr)", fontsize=8)
        bar.ax.tick_params(labelsize=7)
    fig.suptitle(title or "fitted model over the hemisphere", fontsize=11)
    fig.subplots_adjust(left=0.0, right=0.96, bottom=0.04, top=0.84, wspace=0.08)
    fig.savefig(path, dpi=110, bbox_inches="tight", pad_inches=0.1)
    plt.close(fig)
    return peaks


def plot_polar_maps(data, predicted, path, title: str = "", max_rows: int = 6):
    """Polar maps of the data, the model and their relative residual, per incidence.

    theta_r is the radius (degrees, 0 at the centre) and phi_r the angle around it (0: the
    source side, 180: the specular side). One row per incidence, or per incidence bin
    (`~brdfjax.data.measurements.Measurements.incidence_bins`) when there are more than
    ``max_rows``. The data and model columns share one colour scale (logarithmic when the
    values span more than two decades), the residual column a symmetric one; every row
    uses the same scales, so rows can be compared.

    Args:
        data: the measurements (any geometry).
        predicted: the model's BRDF at the data's points, shape (N,), so any model works.
        path: output image file.
        title: figure title.
        max_rows: the most rows (incidence bins) to draw.
    """
    from matplotlib.colors import LogNorm, Normalize

    plt = _pyplot()
    predicted = np.asarray(predicted, dtype=float).reshape(-1)
    if predicted.shape != data.brdf.shape:
        raise ValueError(f"predicted has {predicted.size} values, the data {len(data)}")
    bins = data.incidence_bins(max_bins=max_rows)
    with np.errstate(divide="ignore", invalid="ignore"):
        residual = 100 * (predicted - data.brdf) / np.abs(data.brdf)
    both = np.concatenate([data.brdf, predicted])
    positive = both[np.isfinite(both) & (both > 0)]
    if positive.size and positive.max() > 100 * positive.min():
        value_norm = LogNorm(positive.min(), positive.max())
    else:
        value_norm = Normalize(np.nanmin(both), np.nanmax(both))
    limit = float(np.nanpercentile(np.abs(residual[np.isfinite(residual)]), 98)) \
        if np.isfinite(residual).any() else 1.0
    residual_norm = Normalize(-max(limit, 1e-9), max(limit, 1e-9))
    columns = (("measured", "measured f_r (1/sr)", data.brdf, value_norm, "viridis"),
               ("model", "model f_r (1/sr)", predicted, value_norm, "viridis"),
               ("residual", "(model - measured) / measured (%)", residual, residual_norm,
                "RdBu_r"))
    rows = len(bins.labels)
    fig, axes = plt.subplots(rows, 3, figsize=(10.5, 3.4 * rows + 1.4), layout="constrained",
                             subplot_kw={"projection": "polar"}, squeeze=False)
    size = float(np.clip(4000 / max(1, len(data) / rows), 4, 60))
    for row, label in enumerate(bins.labels):
        mask = bins.index == row
        for column, (short, name, values, norm, cmap) in enumerate(columns):
            ax = axes[row, column]
            image = ax.scatter(data.phi_r[mask], np.degrees(data.theta_r[mask]),
                               c=values[mask], norm=norm, cmap=cmap, s=size, linewidths=0)
            ax.set_rlim(0, 90)
            ax.set_rticks([30, 60, 90], ["30", "60", ""])
            ax.set_rlabel_position(135)
            ax.set_thetagrids([0, 90, 180, 270], ["0\nsource", "90", "180\nspecular", "270"])
            ax.tick_params(labelsize=7, pad=1)
            ax.set_title(f"{short}, incidence {label} ({int(mask.sum())} points)",
                         fontsize=9, pad=8)
            if row == rows - 1:
                # fraction: the bar's share of the whole column's height.
                bar = fig.colorbar(image, ax=axes[:, column], location="bottom",
                                   shrink=0.85, aspect=25, fraction=0.12 / rows, pad=0.01)
                bar.set_label(name, fontsize=9)
                bar.ax.tick_params(labelsize=7)
    fig.suptitle(f"{title or data.name}: polar maps, radius theta_r (deg), angle phi_r "
                 "(deg)", fontsize=11)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)


# Units of the parameters whose unit is known, for axis labels: the paper's model's weights
# scale f_r (1/sr); its a and b are exponents.
PARAMETER_UNITS = {"kb": "1/sr", "kr": "1/sr", "kd": "1/sr", "a": "dimensionless",
                   "b": "dimensionless"}


def figure_title(sample: str, model: str = "", what: str = "") -> str:
    """Every figure's title, one convention: ``SAMPLE: MODEL fit, WHAT`` (parts left out
    where not given), e.g. ``white_paint: five fit, E = 0.026 %``."""
    head = f"{sample}: {model} fit" if model else sample
    return f"{head}, {what}" if what else head


def plot_spectral(records, path, names, title: str = "", sample: str = "", model: str = ""):
    """Each fitted parameter against wavelength, with its standard error as bars.

    Args:
        records: one dict per wavelength: ``{"wavelength_nm": float, "params": {name:
            value}, "std": {name: value or None}}`` (``std`` may be missing or None).
        path: output image file.
        names: the parameters to draw, one panel each (e.g. ``("kb", "kr", "a", "b",
            "kd")``).
        title: figure title (default: the sample and model, `figure_title`).
        sample, model: the sample's and the model's names, for the default title.
    """
    plt = _pyplot()
    records = sorted(records, key=lambda r: r["wavelength_nm"])
    wavelengths = np.array([r["wavelength_nm"] for r in records], dtype=float)
    columns = min(3, len(names))
    rows = -(-len(names) // columns)
    fig, axes = plt.subplots(rows, columns, figsize=(4.2 * columns, 3.2 * rows),
                             squeeze=False)
    for ax, name in zip(axes.flat, names):
        values = np.array([r["params"][name] for r in records], dtype=float)
        errors = np.array([np.nan if (r.get("std") or {}).get(name) is None
                           else r["std"][name] for r in records], dtype=float)
        known = np.isfinite(errors)
        ax.plot(wavelengths, values, "-", color="C0", lw=1)
        ax.errorbar(wavelengths[known], values[known], yerr=errors[known], fmt="o",
                    color="C0", capsize=4, ms=5)
        if not known.all():
            ax.plot(wavelengths[~known], values[~known], "o", mfc="white", mec="C0", ms=6,
                    label="no uncertainty")
            ax.legend(fontsize=7)
        if np.all(values > 0) and values.max() > 100 * values.min():
            ax.set_yscale("log")
        ax.set_xlabel("wavelength (nm)")
        ax.set_ylabel(f"{name} ({PARAMETER_UNITS[name]})" if name in PARAMETER_UNITS
                      else name)
        ax.grid(alpha=0.3)
    for ax in axes.flat[len(names):]:
        ax.set_visible(False)
    fig.suptitle(title or figure_title(sample or "parameters", model,
                                       "against wavelength (bars: 1 standard error)"))
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _corner_coordinates(result) -> tuple[np.ndarray, list]:
    """A result's draws in the prior's coordinates (log10 kb, asinh b, ...), labelled."""
    from brdfjax.models.bounds import scale_label, scaled

    with np.errstate(divide="ignore"):
        values = np.asarray(scaled(np.asarray(result.samples, dtype=float), result.bounds))
    values = values[np.all(np.isfinite(values), axis=1)]
    labels = [scale_label(n, k) for n, k in zip(result.model.names, result.bounds.scale)]
    return values, labels


# Ticks on each axis of the corner plot.
CORNER_TICKS = 3


def _small_corner_ticks(fig) -> None:
    """Tick labels of the corner plot in small type, so that even long ones keep apart."""
    for ax in fig.axes:
        ax.tick_params(labelsize=8)


def plot_corner(results, path, title: str = "", truths=None, names=None):
    """Corner plot of the posterior of (kb, kr, a, b, kd), one or more results overlaid.

    Each parameter is drawn on its search scale (log10 kb, asinh b, ...), the coordinates
    the prior is uniform in, where the posterior is closest to Gaussian; contours enclose
    39 % and 86 % (one and two standard deviations of a 2-D Gaussian).

    Args:
        results: an `~brdfjax.uncertainty.result.UncertaintyResult` or a list of them (e.g. Laplace
            and MCMC of the same data, to compare).
        path: output image file.
        title: figure title.
        truths: optional true parameters (5,) to mark (synthetic data).
        names: legend labels (default: each result's method).
    """
    import corner

    plt = _pyplot()
    results = results if isinstance(results, (list, tuple)) else [results]
    names = names or [r.method for r in results]
    coordinates = [_corner_coordinates(r) for r in results]
    labels = coordinates[0][1]
    stacked = np.concatenate([values for values, _ in coordinates])
    span = [tuple(np.quantile(stacked[:, k], [0.0005, 0.9995])) for k in range(len(labels))]
    colours = plt.get_cmap("tab10").colors
    fig = None
    for k, (values, _) in enumerate(coordinates):
        # Three ticks an axis: with corner's five, long labels ran into each other
        # ("-0.336-4.825", issue 47); matplotlib's formatter keeps them short.
        fig = corner.corner(values, fig=fig, labels=labels, range=span, color=colours[k],
                            levels=(0.393, 0.865), plot_datapoints=False,
                            plot_density=False, fill_contours=False, smooth=1.0,
                            hist_kwargs={"density": True}, max_n_ticks=CORNER_TICKS,
                            labelpad=0.1)
    _small_corner_ticks(fig)
    if truths is not None:
        from brdfjax.models.bounds import scaled

        corner.overplot_lines(fig, scaled(np.asarray(truths, dtype=float), results[0].bounds),
                              color="black", lw=1)
    fig.legend(handles=[plt.Line2D([], [], color=colours[k], label=name)
                        for k, name in enumerate(names)]
               + ([plt.Line2D([], [], color="black", label="truth")] if truths is not None
                  else []), loc="upper right", bbox_to_anchor=(0.95, 0.9))
    fig.suptitle(title or f"posterior of {', '.join(results[0].model.names)}")
    fig.savefig(path, dpi=100, bbox_inches="tight")
    plt.close(fig)


def plot_reflectance_bands(bands, path, title: str = "", truth=None):
    """rho(theta_i) of Eq. (9): posterior median with 68 % and 95 % bands.

    Args:
        bands: `~brdfjax.uncertainty.bands.ReflectanceBands`.
        path: output image file.
        title: figure title.
        truth: optional true rho at the same incidences (synthetic data).
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4))
    x = bands.theta_i_deg
    ax.fill_between(x, bands.lo95, bands.hi95, color="C0", alpha=0.2, lw=0, label="95 %")
    ax.fill_between(x, bands.lo68, bands.hi68, color="C0", alpha=0.4, lw=0, label="68 %")
    ax.plot(x, bands.median, "C0-", label="posterior median")
    if truth is not None:
        ax.plot(x, truth, "k--", lw=1, label="truth")
    ax.set_xlabel("incidence angle theta_i (deg)")
    ax.set_ylabel("directional-hemispherical reflectance rho")
    ax.set_title(title or "reflectance, Eq. (9)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_band_widths(bands, path, title: str = "", held_out=()):
    """Half-width of the 95 % band relative to its middle, in percent, along each scan.

    Where `plot_fit`'s bands are too thin to see, this shows how well each part of each
    curve is determined (held-out incidences dashed).

    Args:
        bands: ``{incidence: CurveBand}`` from `brdfjax.uncertainty.bands.curve_bands`.
        path: output image file.
        title: figure title.
        held_out: incidences (deg) not used in the fit.
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    colours = plt.get_cmap("viridis")(np.linspace(0, 0.9, max(1, len(bands))))
    held = {round(float(x), 6) for x in held_out}
    for colour, (incidence, band) in zip(colours, sorted(bands.items())):
        middle = (band.hi95 + band.lo95) / 2
        width = 100 * (band.hi95 - band.lo95) / 2 / np.where(middle > 0, middle, np.nan)
        is_held = round(float(incidence), 6) in held
        ax.plot(band.signed_deg, width, "--" if is_held else "-", color=colour,
                label=f"{incidence:g} deg" + (" (held out)" if is_held else ""))
    ax.set_xlabel("reflection angle theta_r (deg; > 0: specular side, < 0: source side)")
    ax.set_ylabel("95 % band half-width (% of the curve)")
    ax.set_yscale("log")
    ax.set_title(title or "how well the curves are determined")
    ax.legend(fontsize=7, ncol=2)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def same_curves(names, curves, count: int, rtol: float = 1e-3) -> dict:
    """The first ``count`` distinct curves among ``names`` (in rank order): ``{drawn name:
    [it, then the names whose curves lie within rtol of its own in every panel, relative to
    the panel's peak]}``, drawn as one, by the model of the fewest parameters among them.
    Two models can fit alike (ggx+backscatter with its lobe switched off is ggx): drawn
    apart, the later curve hides the earlier. ``curves(name)`` gives a model's values, a
    list of one array per panel."""
    from brdfjax.models import get

    def alike(a, b):
        return all(np.max(np.abs(x - y)) <= rtol * np.max(np.abs(y)) for x, y in zip(a, b))

    groups, values = {}, {}
    for name in names:
        values[name] = curves(name)
        twin = next((g for g in groups if alike(values[name], values[g])), None)
        if twin is not None:
            groups[twin].append(name)
        elif len(groups) < count:
            groups[name] = [name]
    simplest = (sorted(group, key=lambda name: get(name).size) for group in groups.values())
    return {group[0]: group for group in simplest}


def panel_columns(count: int) -> int:
    """Columns of a grid of ``count`` panels: at most 3, and no more empty cells than
    needed (4 panels in 2 x 2, not 2 x 3 with two empty)."""
    return 2 if count == 4 else min(3, count)


def plot_models(data, comparison, path, title: str = "", max_panels: int = 6,
                max_models: int = 4):
    """The best models' fits over the data, one panel per incidence (up to ``max_panels``).

    Drawn: the ``max_models`` lowest cv_error, and the paper's model where it was compared
    (ten models' curves hid the data and each other; the table has them all); models whose
    fits draw the same curve (`same_curves`) count once. Solid: the
    fit on all incidences; dashed: the fit of the fold that held this incidence out, i.e.
    the model's prediction of an incidence it did not see. The legend gives each model's
    held-out E at that incidence; it stands below its panel, never over the curves. The
    curves are in the plane of incidence, and so are the readings drawn: of data that leave
    it, those in it (drawn all, a 3-D scan's readings at every azimuth filled the area under
    the curves, and a good fit looked poor).

    Returns:
        The matplotlib figure (already saved and closed), for inspection.
    """
    from brdfjax.models.paper import projected_brdf

    plt = _pyplot()
    folds = comparison.best.validation.folds
    panels = folds[:max_panels]
    columns = panel_columns(len(panels))
    rows = -(-len(panels) // columns)
    fig, axes = plt.subplots(rows, columns, figsize=(4.6 * columns, 4.2 * rows + 0.8),
                             squeeze=False)
    colours = plt.get_cmap("tab10")
    scores = {s.name: s for s in comparison.scores}
    panel_angles = [curve_angles((fold.low + fold.high) / 2) for fold in panels]

    @functools.cache
    def curves(name):  # the fit on all incidences, in every panel
        fit = scores[name].fit
        return [np.asarray(projected_brdf(fit.vector, *angles, model=fit.model))
                for angles, _ in panel_angles]

    shown = same_curves(comparison.ranking, curves, max_models)
    if "five" in scores and not any("five" in group for group in shown.values()):
        shown |= same_curves(["five"], curves, 1)
    # The plane of incidence, the normal (in every plane) included.
    drawn_data = data.select((np.abs(np.sin(data.phi_r)) < 1e-9) | (data.theta_r < 1e-9))
    incidence = np.degrees(drawn_data.theta_i)
    for panel, (ax, fold, (angles, signed)) in enumerate(zip(axes.ravel(), panels,
                                                             panel_angles)):
        subset = drawn_data.select((incidence >= fold.low - 1e-6)
                                   & (incidence <= fold.high + 1e-6))
        ax.plot(signed_angle_deg(subset), subset.brdf * np.cos(subset.theta_r), "o", ms=2.5,
                color="0.2", zorder=3)
        held_errors = []
        for k, name in enumerate(shown):
            score = scores[name]
            held = next(f for f in score.validation.folds if f.label == fold.label)
            colour = colours(k % 10)
            ax.plot(signed, curves(name)[panel], "-", color=colour, lw=1.2)
            ax.plot(signed, np.asarray(projected_brdf(held.params, *angles,
                                                      model=score.fit.model)),
                    "--", color=colour, lw=1.0)
            held_errors.append(f"{name} {100 * held.held_error:.3g}")
        kind = "" if fold.interior else ", extrapolation"
        ax.set_title(f"incidence {fold.label} deg{kind}\n"
                     + textwrap.fill("held-out E (%): " + ", ".join(held_errors), 60),
                     fontsize=8)
        ax.set_xlabel("theta_r (deg; > 0 specular side)", fontsize=8)
        ax.set_ylabel("f_r cos(theta_r) (1/sr)", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    for ax in axes.ravel()[len(panels):]:
        ax.axis("off")
    # One legend for every panel, below them (inside a panel it covered the curves, issue
    # 26; under each panel it repeated itself in tiny type, issue 47); each panel's title
    # gives the models' held-out E there.
    handles = [plt.Line2D([], [], ls="", marker="o", ms=4, color="0.2", label=(
        "data" if data.in_plane else f"data in the plane of incidence ({len(drawn_data)} of "
        f"{len(data)} readings)"))]
    handles += [plt.Line2D([], [], color=colours(k % 10), lw=1.5,
                           label=name + (f" ({', '.join(twins[1:])} the same)"
                                         if len(twins) > 1 else ""))
                for k, (name, twins) in enumerate(shown.items())]
    handles += [plt.Line2D([], [], color="0.35", lw=1.2, label="fit on all incidences"),
                plt.Line2D([], [], color="0.35", lw=1.0, ls="--",
                           label="fit without this incidence (its prediction)")]
    fig.legend(handles=handles, loc="lower center", fontsize=9, frameon=False,
               ncol=min(4 if data.in_plane else 3, len(handles)))  # its longer label
    drawn = (f"the {len(comparison.ranking)} models drawn"
             if sum(map(len, shown.values())) == len(comparison.ranking) else
             f"the {min(max_models, len(shown))} lowest cv_error"
             + (" and the paper's model" if len(shown) > max_models else "")
             + f" of {len(comparison.ranking)}")
    fig.suptitle(title or f"{data.name}: {drawn}, ranked by cv_error", fontsize=10)
    fig.tight_layout(rect=(0, 0.7 / (4.2 * rows + 0.8), 1, 1))  # room for the legend
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return fig
