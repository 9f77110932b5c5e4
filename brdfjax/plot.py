"""Figures people look at: fitted curves over the data, and the model over the hemisphere.

matplotlib (Agg backend) is imported here only, when a figure is asked for. Curves show
the projected BRDF ``f_r cos(theta_r)`` against the signed reflection angle (positive on
the specular side), as the paper's Fig. 5/6 do; the 3-D view shows the fitted model over
the whole hemisphere, as its Fig. 9-15 do.
"""

from __future__ import annotations

import numpy as np


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def signed_angle_deg(data) -> np.ndarray:
    """Signed reflection angle in degrees: positive on the specular side (phi_r = 180)."""
    return np.where(np.cos(data.phi_r) < 0, 1.0, -1.0) * np.degrees(data.theta_r)


def curve_angles(incidence_deg: float, count: int = 361):
    """In-plane angles (radians) for a smooth curve at one incidence, and the signed degrees."""
    signed = np.linspace(-89.9, 89.9, count)
    theta_i = np.full(count, np.radians(incidence_deg))
    return (theta_i, np.radians(np.abs(signed)), np.where(signed > 0, np.pi, 0.0)), signed


def plot_fit(data, params, path, title: str = "", held_out=(), bands=None, log: bool = False):
    """Data points and fitted curves of f_r cos(theta_r), one colour per incidence.

    Args:
        data: the measurements (every incidence is drawn).
        params: fitted parameters (5,).
        path: output image file (PNG, PDF or SVG by suffix).
        title: figure title.
        held_out: incidences (deg) not used in the fit, drawn hollow and dashed.
        bands: optional ``{incidence: (signed_deg, lo68, hi68, lo95, hi95)}`` to shade.
        log: log-scale the vertical axis (for dark samples with a strong peak).
    """
    from brdfjax.model import projected_brdf

    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 5))
    colours = plt.get_cmap("viridis")(np.linspace(0, 0.9, max(1, len(data.incidences_deg))))
    held = {round(float(x), 6) for x in held_out}
    for colour, incidence in zip(colours, data.incidences_deg):
        subset = data.at_incidences([incidence])
        is_held = round(float(incidence), 6) in held
        ax.plot(signed_angle_deg(subset), subset.brdf * np.cos(subset.theta_r),
                "o", ms=3, mfc="none" if is_held else colour, mec=colour,
                label=f"{incidence:g} deg data" + (" (held out)" if is_held else ""))
        angles, signed = curve_angles(incidence)
        model = np.asarray(projected_brdf(np.asarray(params, float), *angles))
        ax.plot(signed, model, "--" if is_held else "-", color=colour, lw=1.5)
        if bands and incidence in bands:
            x, lo68, hi68, lo95, hi95 = bands[incidence]
            ax.fill_between(x, lo95, hi95, color=colour, alpha=0.15, lw=0)
            ax.fill_between(x, lo68, hi68, color=colour, alpha=0.3, lw=0)
    ax.set_xlabel("reflection angle theta_r (deg; > 0: specular side, < 0: source side)")
    ax.set_ylabel("f_r cos(theta_r)  (1/sr)")
    if log:
        ax.set_yscale("log")
    ax.set_title(title or data.name)
    ax.legend(fontsize=7, ncol=2)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_hemisphere(params, incidences_deg, path, title: str = "", resolution: int = 121):
    """3-D surfaces of the model's f_r cos(theta_r) over the hemisphere, one per incidence.

    The horizontal coordinates are ``sin(tr) cos(pr)``, ``sin(tr) sin(pr)`` (the projected
    hemisphere, source at +x), the height is f_r cos(tr).
    """
    from brdfjax.model import projected_brdf

    plt = _pyplot()
    count = len(incidences_deg)
    fig = plt.figure(figsize=(4.5 * count, 4.5))
    theta_r, phi_r = np.meshgrid(np.radians(np.linspace(0, 89.5, resolution)),
                                 np.radians(np.linspace(0, 360, 2 * resolution)))
    for k, incidence in enumerate(incidences_deg):
        values = np.asarray(projected_brdf(np.asarray(params, float), np.radians(incidence),
                                           theta_r, phi_r))
        ax = fig.add_subplot(1, count, k + 1, projection="3d")
        ax.plot_surface(np.sin(theta_r) * np.cos(phi_r), np.sin(theta_r) * np.sin(phi_r),
                        values, cmap="viridis", linewidth=0, rcount=80, ccount=80)
        ax.set_title(f"incidence {incidence:g} deg", fontsize=9)
        ax.set_xlabel("sin tr cos pr")
        ax.set_ylabel("sin tr sin pr")
        ax.set_zlabel("f_r cos tr")
    fig.suptitle(title or "fitted model over the hemisphere")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
