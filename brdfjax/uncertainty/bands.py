"""Posterior bands: how well the curves and the reflectance are determined.

Every parameter draw of an `~brdfjax.uncertainty.result.UncertaintyResult` (posterior samples, or
draws from the Laplace Gaussian) gives a model curve; pointwise quantiles over the draws
give the central 68.27 % and 95 % credible bands. They are bands on the noise-free model,
i.e. on where the true curve lies, which is what a user extrapolating the fit needs; a new
measurement scatters further by the measurement noise. The same works at incidences that
were held out of the fit, and for the directional-hemispherical reflectance of Eq. (9).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from brdfjax.angles import check_degrees
from brdfjax.cache import stage
from brdfjax.models import Model, model_for
from brdfjax.models.hemispherical import reflectance
from brdfjax.models.paper import evaluate_projected
from brdfjax.plot import curve_angles
from brdfjax.uncertainty.result import INTERVALS

# Draws used per band. 2000 give the 2.5 % and 97.5 % quantiles to a few per cent of the
# band width; a fixed count also keeps the compiled evaluation from being rebuilt for every
# chain length. The reflectance quadrature costs about 15 000 model evaluations per angle, so
# it takes fewer: a few hundred give its quantiles to about 5 % of the band width.
CURVE_DRAWS = 2000
REFLECTANCE_DRAWS = 300


class CurveBand(NamedTuple):
    """Bands of ``f_r cos(theta_r)`` along one in-plane scan (arrays of the same length).

    The field order is what `brdfjax.plot.plot_fit` unpacks from its ``bands`` argument.

    Attributes:
        signed_deg: signed reflection angle (> 0: specular side), degrees.
        lo68, hi68: the central 68.27 % band.
        lo95, hi95: the central 95 % band.
        median: the pointwise median: the curve the bands are about (None where not
            computed).
    """

    signed_deg: np.ndarray
    lo68: np.ndarray
    hi68: np.ndarray
    lo95: np.ndarray
    hi95: np.ndarray
    median: np.ndarray | None = None


class ReflectanceBands(NamedTuple):
    """Posterior summaries of rho(theta_i), Eq. (9), at several incidences (arrays (M,)).

    Attributes:
        theta_i_deg: incidence angles, degrees.
        median, std: posterior median and standard deviation of rho.
        lo68, hi68, lo95, hi95: central 68.27 % and 95 % intervals.
    """

    theta_i_deg: np.ndarray
    median: np.ndarray
    std: np.ndarray
    lo68: np.ndarray
    hi68: np.ndarray
    lo95: np.ndarray
    hi95: np.ndarray

    def to_dict(self) -> dict:
        """``{"0": {"median", "std", "ci68": [lo, hi], "ci95": [lo, hi]}, ...}`` by degrees."""
        return {f"{deg:g}": {"median": float(self.median[k]), "std": float(self.std[k]),
                             "ci68": [float(self.lo68[k]), float(self.hi68[k])],
                             "ci95": [float(self.lo95[k]), float(self.hi95[k])]}
                for k, deg in enumerate(self.theta_i_deg)}


def subsample(samples, draws: int, seed: int = 0) -> np.ndarray:
    """``draws`` rows of ``samples`` picked at random without replacement (all if fewer)."""
    samples = np.asarray(samples, dtype=float)
    if samples.shape[0] <= draws:
        return samples
    pick = np.random.default_rng(seed).choice(samples.shape[0], draws, replace=False)
    return samples[np.sort(pick)]


def quantile_bands(values) -> tuple[np.ndarray, ...]:
    """Pointwise (lo68, hi68, lo95, hi95) over the first axis of ``values`` (draws, ...)."""
    levels = [*INTERVALS["ci68"], *INTERVALS["ci95"]]
    return tuple(np.quantile(np.asarray(values), levels, axis=0))


@stage
def _curves(samples, geometry, model) -> jax.Array:
    """``f_r cos(theta_r)`` of every draw (S, P) on the model's geometry: (S, points)."""
    return jax.vmap(evaluate_projected, in_axes=(0, None, None))(samples, geometry, model)


def curve_bands(samples, incidences_deg, *, count: int = 361, draws: int = CURVE_DRAWS,
                seed: int = 0, model: str | Model | None = None, constants=None) -> dict:
    """68.27 % and 95 % bands of the in-plane curves at any incidences, held-out ones too.

    Each scan runs from -89.9 to 89.9 deg signed reflection angle (< 0: source side), as the
    curves of `brdfjax.plot.plot_fit`.

    Args:
        samples: parameter draws (S, P), e.g. `UncertaintyResult.samples`.
        incidences_deg: incidence angles in degrees.
        count: points per scan.
        draws, seed: how many of the samples to use, picked at random (`subsample`).
        model: the model of the samples (the five-parameter model if None).
        constants: the shadowing constants of Eq. (3), for models with a G term.

    Returns:
        ``{incidence: CurveBand}``, keyed by the incidences as floats (the form
        `brdfjax.plot.plot_fit` takes as ``bands``).
    """
    check_degrees(incidences_deg=incidences_deg)
    incidences = [float(x) for x in np.atleast_1d(incidences_deg)]
    scans = [curve_angles(deg, count) for deg in incidences]
    angles = [np.concatenate([scan[0][k] for scan in scans]) for k in range(3)]
    model = model_for(np.asarray(samples)[0], model, constants)
    geometry = model.geometry(*angles, in_plane=True)
    values = np.asarray(_curves(jnp.asarray(subsample(samples, draws, seed)), geometry, model))
    values = values.reshape(values.shape[0], len(incidences), count)
    bands = (*quantile_bands(values), np.median(values, axis=0))
    return {deg: CurveBand(scans[k][1], *(band[k] for band in bands))
            for k, deg in enumerate(incidences)}


# The share of the fitted curve outside the posterior's 95 % band (`share_outside`) above
# which `band_note` says so: the 95 % band itself leaves out 5 % of the posterior's curves.
NOTED_SHARE = 0.05


def band_note(uncertainty, bands: dict) -> str:
    """A sentence when the fit an `~brdfjax.uncertainty.result.UncertaintyResult` came from
    leaves the posterior's 95 % ``bands`` along more than `NOTED_SHARE` of its curves, with
    why (`~brdfjax.uncertainty.result.UncertaintyResult.fit_note`); else ""."""
    if uncertainty.fitted is None or not bands:
        return ""
    share = share_outside(bands, uncertainty.fitted, uncertainty.model)
    if share <= NOTED_SHARE:
        return ""
    note = uncertainty.fit_note(uncertainty.fitted, uncertainty.fitted_loss)
    return (f"The fitted curve leaves the posterior's 95 % band along {100 * share:.0f} % of "
            f"its length: {note[0].lower()}{note[1:]}.")


def share_outside(bands: dict, params, model: str | Model | None = None,
                  constants=None) -> float:
    """The share of a curve's points, over every scan of ``bands`` (`curve_bands`), that lie
    outside the 95 % band: how far the curve of ``params`` (the fit) and the posterior's
    bands disagree (0 where the curve runs inside them everywhere).

    Args:
        bands: ``{incidence: CurveBand}``.
        params: the parameters (P,) of the curve.
        model, constants: as for `curve_bands`.
    """
    model = model_for(np.asarray(params, dtype=float), model, constants)
    outside, total = 0, 0
    for incidence, band in bands.items():
        angles, _ = curve_angles(incidence, len(band.signed_deg))
        curve = np.asarray(_curves(jnp.asarray(params, dtype=float)[None],
                                   model.geometry(*angles, in_plane=True), model))[0]
        outside += int(np.sum((curve < band.lo95) | (curve > band.hi95)))
        total += curve.size
    return outside / max(total, 1)


@stage
def _reflectances(samples, theta_i, model) -> jax.Array:
    """rho of Eq. (9) for every draw (S, P) at every incidence (M,): (S, M)."""
    return jax.vmap(lambda params: reflectance(params, theta_i, model=model))(samples)


def reflectance_bands(samples, theta_i_deg, *, draws: int = REFLECTANCE_DRAWS, seed: int = 0,
                      model: str | Model | None = None, constants=None) -> ReflectanceBands:
    """Posterior median, spread and intervals of the reflectance rho(theta_i) of Eq. (9).

    Args:
        samples: parameter draws (S, P).
        theta_i_deg: incidence angles in degrees.
        draws, seed: how many of the samples to integrate, picked at random (`subsample`).
        model: the model of the samples (the five-parameter model if None).
        constants: the shadowing constants of Eq. (3), for models with a G term.

    Returns:
        `ReflectanceBands`.
    """
    check_degrees(theta_i_deg=theta_i_deg)
    samples = subsample(samples, draws, seed)
    theta = np.atleast_1d(np.asarray(theta_i_deg, dtype=float))
    values = np.asarray(_reflectances(jnp.asarray(samples), jnp.radians(theta),
                                      model_for(samples[0], model, constants)))
    return ReflectanceBands(theta, np.median(values, axis=0), np.std(values, axis=0, ddof=1),
                            *quantile_bands(values))
