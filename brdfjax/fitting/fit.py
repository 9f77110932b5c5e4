"""Fitting a measurement set: genetic search, Levenberg-Marquardt polish, and the result.

`fit` is the one entry point, for every model of `brdfjax.models` (the five-parameter
model by default). The default ``hybrid`` method runs `brdfjax.fitting.evolve.evolve` to find the
basin, then `brdfjax.fitting.polish.polish` from ``starts`` distinct good members (and the model's
own extra starts: the five-parameter model's Fresnel-free one) at once, and keeps the best.
Dense scans (more than `DENSE_POINTS` points) are searched and screened on representative
points, and only the winner is polished on all of them. ``ga`` stops after the
genetic search; ``lm`` polishes from given parameters, or from random points of the box.
Incidence angles can be held out for validation, as the paper does (fit 10/30/45/60 deg,
validate 21/52 deg).
"""

from __future__ import annotations

import threading
import time
import warnings
from dataclasses import dataclass, field

import jax
import numpy as np

from brdfjax.cache import stage
from brdfjax.data.measurements import DataError, Measurements, checked, incidence_groups
from brdfjax.fitting.evolve import EvolveConfig, EvolveResult, check_population, evolve
from brdfjax.fitting.objective import (
    Problem,
    prepare,
    problem,
    projected,
    relative_error,
    targets,
    with_loss,
)
from brdfjax.fitting.polish import STARTS, PolishResult, polish, polish_population
from brdfjax.models import Model, get
from brdfjax.models.bounds import Bounds, default_bounds, from_unit, to_free, to_unit
from brdfjax.models.paper import FIVE

METHODS = ("hybrid", "ga", "lm")
# Dense scans: above DENSE_POINTS training points the hybrid fit searches and screens on
# SEARCH_POINTS representative points (`representative`) and polishes only the winner on
# every point. The basin is found long before all points are needed: a 1 deg x 2 deg scan
# of 100 000 points repeats the same shape hundreds of times.
DENSE_POINTS = 16384
SEARCH_POINTS = 4096
# Every status a fit can end with (`FitResult.status`).
STATUSES = ("converged", "max_steps", "search_only", "underdetermined", "failed")
# Angles (deg) that agree to this many decimals are one geometry (`distinct_geometries`).
GEOMETRY_DECIMALS = 3


class UnderdeterminedWarning(UserWarning):
    """A fit of no more distinct geometries than free parameters (`underdetermined`)."""


@dataclass
class FitResult:
    """The outcome of `fit`.

    Attributes:
        params: the fitted parameters by name (the model's ``Params`` named tuple).
        error: E of Eq. (6) on the training points, as a fraction.
        error_by_incidence: E on each training incidence alone, keyed by degrees.
        validation_error: E on the held-out incidences together (None if none held out).
        validation_by_incidence: E on each held-out incidence alone.
        residuals: the training residual vector (its squared norm is ``error``).
        status: ``converged``, ``max_steps`` (LM hit its step cap), ``failed`` (no finite
            result), ``search_only`` (the ``ga`` method does not polish), or
            ``underdetermined``: the training points hold no more distinct geometries than
            the model has parameters (`distinct_geometries`, `settled`), so the parameters
            are one of many sets that fit them as well, whatever E says.
        at_bounds: names of parameters within 1e-6 of a bound (in unit-cube terms).
        evaluations: model evaluations of the whole data set (a Jacobian counts one per
            parameter).
        lm_steps: LM steps of each start; lm_success: each start's optimistix status.
        timings: wall seconds per stage (``evolve``, ``polish``, ``total``).
        history: the genetic search's best E after each generation.
        method: the method used; train_incidences, validation_incidences: in degrees.
        message: why the status, where there is more to say (a batch sample's data error).
        model: the `brdfjax.models.Model` fitted.
        training: the measurements fitted (for cross-validation and predictions), with the
            weights of the loss.
        loss: what the fit minimised (`brdfjax.fitting.objective.with_loss`).
        calibrations: the conformal calibrations `brdfjax.predict` computed for this fit,
            by (discrepancy, seed): a later prediction from the same fit reuses them.
    """

    params: tuple
    error: float
    error_by_incidence: dict
    validation_error: float | None
    validation_by_incidence: dict
    residuals: np.ndarray = field(repr=False)
    status: str
    at_bounds: list
    evaluations: int
    lm_steps: np.ndarray = field(repr=False)
    lm_success: np.ndarray = field(repr=False)
    timings: dict
    history: np.ndarray = field(repr=False)
    method: str
    train_incidences: list
    validation_incidences: list
    bounds: Bounds = field(repr=False)
    model: Model = field(default=FIVE)
    message: str = ""
    training: Measurements | None = field(default=None, repr=False)
    loss: str = "eq6"
    # not an argument: `dataclasses.replace` (another training set, say) starts a new one
    calibrations: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    @property
    def vector(self) -> np.ndarray:
        """The parameters as an array, in the model's order (kb, kr, a, b, kd by default)."""
        return np.array(self.params, dtype=float)

    def to_dict(self) -> dict:
        """A JSON-ready summary (E as a fraction, incidences as string keys)."""
        return {
            "model": self.model.name,
            "loss": self.loss,
            "params": dict(zip(self.model.names, map(float, self.params))),
            "error": self.error,
            "error_by_incidence": {f"{k:g}": v for k, v in self.error_by_incidence.items()},
            "validation_error": self.validation_error,
            "validation_by_incidence": {f"{k:g}": v
                                        for k, v in self.validation_by_incidence.items()},
            "status": self.status,
            "at_bounds": self.at_bounds,
            "method": self.method,
            "evaluations": self.evaluations,
            "lm_steps": [int(s) for s in self.lm_steps],
            "timings": self.timings,
            "message": self.message,
        }


def split(data: Measurements, validate_incidences_deg=None) -> tuple[Measurements, Measurements]:
    """Training and held-out subsets by incidence angle (degrees)."""
    if validate_incidences_deg is None or np.size(validate_incidences_deg) == 0:
        return data, data.select(np.zeros(len(data), dtype=bool))
    validate_incidences_deg = np.atleast_1d(np.asarray(validate_incidences_deg, dtype=float))
    mask = data.incidence_mask(validate_incidences_deg)
    train, held = data.select(~mask), data.select(mask)
    missing = set(np.round(validate_incidences_deg, 6)) - set(held.incidences_deg)
    if missing:
        raise DataError(f"held-out incidence(s) {_degrees(sorted(missing))} deg not in the data",
                        data.path,
                        hint=f"the data have {_degrees(data.incidences_deg)} deg")
    if len(train.incidences_deg) == 0:
        raise DataError("nothing left to fit after holding out "
                        f"{_degrees(validate_incidences_deg)} deg", data.path,
                        hint="held-out validation needs at least two incidence angles")
    return train, held


def _degrees(values) -> str:
    return ", ".join(f"{float(x):g}" for x in values)


def fit(data: Measurements, method: str = "hybrid", *, model: str | Model | None = None,
        seed: int = 0, validate_incidences_deg=None, bounds: Bounds | None = None, start=None,
        starts: int = STARTS, population_size: int = 128, max_generations: int = 40,
        max_steps: int = 1000, config: EvolveConfig | None = None,
        constants=None, loss: str = "eq6") -> FitResult:
    """Fit a model (the five-parameter model by default) by minimising E of Eq. (6).

    Args:
        data: the measurements (checked as `brdfjax.load` checks a file's: angles in
            radians, finite values, no outliers or negative values beyond noise).
        method: ``hybrid`` (genetic search then LM), ``ga`` or ``lm``.
        model: a name of `brdfjax.models.available` or a `brdfjax.models.Model`.
        seed: seeds every random choice; the same seed gives the same result.
        validate_incidences_deg: incidence angles (deg) held out of the fit and scored after.
        bounds: the search box (the model's `brdfjax.models.bounds.default_bounds` if None).
        start: for ``lm``, starting parameters (P,) or (S, P); random starts if None.
        starts: how many distinct GA members LM polishes (a multiple of the genetic
            search's 8 islands; besides the model's extra starts), or how many random starts
            for ``lm``.
        population_size, max_generations: genetic-search sizes.
        max_steps: LM step cap per start.
        config: genetic-search rates (defaults if None).
        constants: the shadowing constants of Eq. (3), for models with a G term (the
            paper's if None).
        loss: ``eq6`` (E of Eq. 6, the default), ``relative`` or ``balanced``
            (`brdfjax.fitting.objective.with_loss`); E is then reported under that loss.

    Returns:
        A `FitResult`.

    Warns:
        UnderdeterminedWarning: the training points hold no more distinct geometries than
            the model has parameters; the status is then ``underdetermined``.
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; choose one of {METHODS}")
    checked(data, "fit")
    model = get(model, constants)
    bounds = default_bounds(model) if bounds is None else bounds
    check_bounds(bounds, model)
    train, held = split(with_loss(data, loss), validate_incidences_deg)
    prob = problem(train, model)
    timings, history, evaluations = {}, np.zeros(0), 0
    method_ran = method
    begin = time.perf_counter()
    search = prob
    if method == "hybrid" and len(train) > DENSE_POINTS:
        search = problem(representative(train, SEARCH_POINTS), model)

    if method != "lm" and model.searched_size == 0:
        # Nothing to search (Ross-Li, Lambert): E is a convex quadratic of the linear
        # coefficients over their box, and the exact solve is the fit; LM adds nothing.
        tic = time.perf_counter()
        searched, polished = _solved_fit(prob, bounds, max_generations=max_generations)
        polished.errors.block_until_ready()
        timings["solve"] = time.perf_counter() - tic
        best, status, evaluations = polish_summary(polished)
        steps, success = np.asarray(polished.steps), np.asarray(polished.success)
        method_ran = "solve"
    elif method != "lm":
        check_population(population_size)  # before the polish is compiled ahead for it
        ahead = (_polish_ahead(search, bounds, population_size, starts, max_steps)
                 if method == "hybrid" else None)
        tic = time.perf_counter()
        try:
            searched = evolve(seed, search, bounds, config, population_size=population_size,
                              max_generations=max_generations)
            searched.errors.block_until_ready()
        except Exception:  # not Ctrl-C: that would wait for the whole compile-ahead
            if ahead is not None:  # left compiling behind the error, it crashed at exit
                ahead.join()
            raise
        timings["evolve"] = time.perf_counter() - tic
        history, evaluations = search_summary(searched, population_size)

    if method_ran == "solve":
        pass
    elif method == "ga":
        best = from_unit(np.asarray(searched.population)[np.argmin(searched.errors)], bounds)
        status, steps, success = "search_only", np.zeros(0, int), np.zeros(0, bool)
    else:
        tic = time.perf_counter()
        if method == "hybrid":
            if ahead is not None:
                ahead.join()  # never two LMs at once: XLA's LAPACK calls can deadlock
            polished = polish_population(placed(searched.population), search, bounds,
                                         starts=starts, max_steps=max_steps)
            if search is not prob:  # the winner of the representative points, on every point
                winner, _, screened = polish_summary(polished)
                evaluations += screened * search.target.size // prob.target.size
                polished = polish(to_free(winner[None], bounds), prob, bounds,
                                  max_steps=max_steps)
        else:
            polished = polish(_lm_starts(start, starts, seed, bounds, model), prob, bounds,
                              max_steps=max_steps)
        polished.errors.block_until_ready()
        timings["polish"] = time.perf_counter() - tic
        best, status, lm_evaluations = polish_summary(polished)
        steps, success = np.asarray(polished.steps), np.asarray(polished.success)
        evaluations += lm_evaluations
    timings["total"] = time.perf_counter() - begin
    geometries = distinct_geometries(train)
    status = str(settled(status, geometries, model))
    message = status_message(status, max_steps, geometries, model)
    if status == "underdetermined":
        warnings.warn(message, UnderdeterminedWarning, stacklevel=2)
    return fit_result(with_loss(data, loss), train, held, np.asarray(best, dtype=float),
                      bounds, model, loss=loss,
                      geometry=None if len(held) else prob.scene, method=method,
                      status=status, evaluations=evaluations, lm_steps=steps,
                      lm_success=success, timings=timings, history=history, message=message)


def distinct_geometries(data: Measurements) -> int:
    """How many distinct geometries the points of ``data`` hold: the distinct
    (theta_i, theta_r, phi_r) in degrees rounded to `GEOMETRY_DECIMALS` decimals, with
    phi_r folded into 0..180 deg (every model is isotropic: f_r depends on phi_r through
    its cosine alone) and taken as 0 where theta_i or theta_r is 0 (the azimuth of a
    normal direction means nothing). Repeated readings of one geometry count once: they
    average noise but determine nothing more.
    """
    theta_i, theta_r, phi_r = (np.round(np.degrees(np.asarray(x, dtype=float)),
                                        GEOMETRY_DECIMALS)
                               for x in (data.theta_i, data.theta_r, data.phi_r))
    phi_r = np.round(np.abs((phi_r + 180.0) % 360.0 - 180.0), GEOMETRY_DECIMALS)
    phi_r = np.where((theta_i == 0) | (theta_r == 0), 0.0, phi_r)
    return len(np.unique(np.stack([theta_i, theta_r, phi_r], axis=-1), axis=0))


def settled(status, geometries, model: Model):
    """The status a fit reports: ``underdetermined`` in place of any other but ``failed``
    where ``geometries`` (`distinct_geometries` of the training points) are no more than
    the model's free parameters (``model.size``: through P geometries a model of P
    parameters can pass exactly, E = 0, with parameters the data do not choose). The one
    rule for `fit` and every sample of `brdfjax.fitting.batch.fit_batch`; arrays of
    statuses and counts give an array.
    """
    status = np.asarray(status).astype(object)
    short = (np.asarray(geometries) <= model.size) & (status != "failed")
    settled = np.where(short, "underdetermined", status)
    return str(settled) if settled.ndim == 0 else settled.astype(f"U{max(map(len, STATUSES))}")


def status_message(status: str, max_steps: int, geometries: int, model: Model) -> str:
    """`FitResult.message`: why the status, where there is more to say ("" elsewhere)."""
    if status == "underdetermined":
        return (f"underdetermined: {geometries} distinct geometr"
                f"{'y' if geometries == 1 else 'ies'} (theta_i, theta_r, phi_r) for the "
                f"{model.size} parameters of {model.name} ({', '.join(model.names)}): a fit "
                "needs more geometries than parameters, so these parameters are one of many "
                "sets that fit the points as well, and a small E proves nothing; measure "
                "more geometries, or fit a model of fewer parameters")
    return {"max_steps": f"Levenberg-Marquardt stopped at its cap of {max_steps} steps "
                         "before meeting its tolerance",
            "failed": "no start reached a finite E"}.get(str(status), "")


# The polish shapes compiled ahead in this process (`_polish_ahead`).
_polished_ahead: set = set()


def _polish_ahead(search: Problem, bounds: Bounds, population_size: int, starts: int,
                  max_steps: int) -> threading.Thread | None:
    """Compile the hybrid fit's polish in a second thread while this one compiles and runs
    the genetic search: XLA compiles each on its own core (a first ``brdfjax fit`` of 716
    points: BENCHMARKS.md, section startup). The thread runs the polish once, to the end,
    on a population of identical members placed on the device (`placed`), so only a start
    or two take a few LM steps; its result, or its error (the real call raises it again),
    is dropped. None where these shapes were compiled ahead before in this process.
    """
    import jax.numpy as jnp

    key = (search.model, search.target.shape, search.target.dtype, population_size, starts,
           max_steps)
    if key in _polished_ahead:
        return None
    _polished_ahead.add(key)
    population = placed(jnp.full((population_size, search.model.size), 0.5,
                                 search.target.dtype))

    def compile_and_run():
        try:  # waited for: the caller's join() must mean that no LM is running
            polish_population(population, search, bounds, starts=starts,
                              max_steps=max_steps).errors.block_until_ready()
        except Exception:  # noqa: BLE001, S110  (the real call raises it)
            pass

    thread = threading.Thread(target=compile_and_run, daemon=True,
                              name="brdfjax polish compiled ahead")
    thread.start()
    return thread


def placed(array):
    """``array`` committed to the default device. jit compiles a function once per kind of
    input placement: an array left uncommitted (the output of a plain ``jax.jit``) and one
    placed on a device (the output of a disk-cached stage, `brdfjax.cache`) are two inputs,
    compiled twice. The polish and its compile-ahead both take placed populations."""
    return jax.device_put(array, jax.devices()[0])


def solved_fit(prob: Problem, bounds: Bounds, max_generations: int = 40):
    """The fit of a model with nothing to search: one exact linear solve
    (`brdfjax.fitting.objective.solve_linear`), laid out as a search and a one-start polish.

    Returns:
        (`brdfjax.fitting.evolve.EvolveResult` of the one solved member, no generation bred;
        `brdfjax.fitting.polish.PolishResult` of it, 0 LM steps, successful where E is finite).
    """
    import jax.numpy as jnp

    from brdfjax.fitting.evolve import EvolveResult
    from brdfjax.fitting.objective import solve_linear
    from brdfjax.models.bounds import to_free as free_of

    dtype = prob.target.dtype
    bounds = Bounds(*(jnp.asarray(b, dtype) if k < 2 else jnp.asarray(b)
                      for k, b in enumerate(bounds)))
    params, value = solve_linear(from_unit(jnp.full(prob.model.size, 0.5, dtype), bounds),
                                 prob, bounds)
    value = jnp.where(jnp.isnan(value), jnp.inf, value)
    unit = to_unit(params, bounds)
    searched = EvolveResult(unit[None], value[None],
                            jnp.full(max_generations, jnp.nan, dtype), jnp.asarray(0))
    polished = PolishResult(free_of(params, bounds)[None], params[None], value[None],
                            jnp.isfinite(value)[None], jnp.zeros(1, jnp.result_type(int)),
                            jnp.asarray(1, jnp.result_type(int)))
    return searched, polished


_solved_fit = stage(solved_fit, static_argnames=("max_generations",))


def representative(data: Measurements, count: int) -> Measurements:
    """About ``count`` points of ``data`` that keep its shape, for searching dense scans.

    Every incidence (or incidence bin, `brdfjax.prediction.cross_validation.incidence_groups`) keeps
    its share of the points. Within one, a tenth of its share goes to its brightest points, so
    that narrow peaks stay represented, and the rest are spread evenly over its points
    ordered by (theta_r, phi_r), so that every angle is.
    """
    keep = np.zeros(len(data), dtype=bool)
    for *_, mask in incidence_groups(data):
        index = np.flatnonzero(mask)
        share = max(1, round(count * index.size / len(data)))
        brightest = index[np.argsort(-np.abs(data.brdf[index]))[:max(1, share // 10)]]
        ordered = index[np.lexsort((data.phi_r[index], data.theta_r[index]))]
        spread = ordered[np.linspace(0, index.size - 1, share - brightest.size).astype(int)]
        keep[brightest] = keep[spread] = True
    return data.select(keep)


def search_summary(searched: EvolveResult, population_size: int) -> tuple[np.ndarray, int]:
    """The genetic search's best-E history and its count of model evaluations.

    Args:
        searched: one run of `brdfjax.fitting.evolve.evolve` (host or device arrays).
        population_size: its population size.

    Returns:
        The history up to the last generation run, and the evaluations it took.
    """
    generations = int(searched.generations)
    return np.asarray(searched.history)[:generations], population_size * (generations + 1)


def polish_summary(polished: PolishResult) -> tuple[np.ndarray, str, int]:
    """The best polished start, the fit's status, and LM's count of model evaluations.

    Args:
        polished: the surviving starts of one `brdfjax.fitting.polish.polish` (host or
            device), or of many fits along leading axes (`brdfjax.fit_batch`'s samples).

    Returns:
        The parameters (P,) of the start with the lowest E; ``converged``, ``max_steps``
        or ``failed`` (no start reached a finite E); and the evaluations taken. Over
        leading axes, arrays of them.
    """
    errors = np.asarray(polished.errors)
    pick = np.argmin(errors, axis=-1)[..., None]
    lowest = np.take_along_axis(errors, pick, axis=-1)[..., 0]
    success = np.take_along_axis(np.asarray(polished.success), pick, axis=-1)[..., 0]
    status = np.where(~np.isfinite(lowest), "failed",
                      np.where(success, "converged", "max_steps"))
    best = np.take_along_axis(np.asarray(polished.params, dtype=float), pick[..., None],
                              axis=-2)[..., 0, :]
    if errors.ndim == 1:
        return best, str(status), int(polished.evaluations)
    return best, status, np.asarray(polished.evaluations)


def _lm_starts(start, count, seed, bounds, model):
    """Unconstrained LM starts: the given parameters, or ``count`` random points of the box."""
    if start is None:
        unit = np.random.default_rng(seed).uniform(size=(count, bounds.lower.size))
        return to_free(from_unit(unit, bounds), bounds)
    starts = np.atleast_2d(np.asarray(start, dtype=float))
    if starts.ndim != 2 or starts.shape[1] != model.size:
        raise ValueError(f"start: give {model.size} parameters of the {model.name} model "
                         f"({', '.join(model.names)}), or (S, {model.size}) for S starts; got "
                         f"shape {np.shape(start)}")
    return to_free(starts, bounds)


def check_bounds(bounds: Bounds, model: Model) -> None:
    """A clear error when ``bounds`` were made for another model (another parameter count)."""
    if np.shape(bounds.lower) != (model.size,):
        raise ValueError(f"the bounds have {np.size(bounds.lower)} parameters, the {model.name} "
                         f"model {model.size} ({', '.join(model.names)}); make them with "
                         f"brdfjax.make_bounds(..., model={model.name!r})")


def fit_result(data, train, held, vector, bounds, model, geometry=None, fitted=None,
               unit=None, **details) -> FitResult:
    """A `FitResult` for ``vector``: E overall, per incidence and held out, from one model
    evaluation of ``data`` (split into ``train`` and ``held``, None where nothing is held
    out; ``geometry`` is the model's geometry of ``data``, padded or not, where already
    computed); ``details`` fill the rest (status, timings, ...).

    ``fitted`` (the projected BRDF on the points of ``data``, padded or not) and ``unit``
    (the unit-cube coordinates) of the reported parameters, ``model.canonical(vector)``,
    may be given where already computed: `brdfjax.fitting.batch` computes both for a whole
    chunk of samples at once.
    """
    vector = np.asarray(model.canonical(vector, bounds), dtype=float)  # a sum's lobes ordered
    if fitted is None:
        geometry = prepare(data, model) if geometry is None else geometry
        fitted = projected(vector, geometry, model)
    fitted = np.asarray(fitted)[:len(data)]  # padded geometry
    unit = np.asarray(to_unit(vector, bounds)) if unit is None else unit
    target, weight = targets(data)
    theta = np.round(np.degrees(data.theta_i), 6)
    held_out = [] if held is None else held.incidences_deg
    is_held = np.zeros(len(data), bool) if held is None else data.incidence_mask(held_out)
    trained = np.unique(theta[~is_held])  # train's incidences: the points not held out

    def error_on(mask):
        return relative_error(fitted[mask], target[mask], weight[mask])

    normalised = weight[~is_held] / np.sum(weight[~is_held] * target[~is_held] ** 2)
    return FitResult(
        params=model.Params(*map(float, vector)),
        error=error_on(~is_held),
        error_by_incidence={float(d): error_on(theta == d) for d in trained},
        validation_error=error_on(is_held) if is_held.any() else None,
        validation_by_incidence={float(d): error_on(theta == d) for d in held_out},
        residuals=np.sqrt(normalised) * (fitted[~is_held] - target[~is_held]),
        at_bounds=[n for n, z in zip(model.names, np.asarray(unit).tolist())
                   if z < 1e-6 or z > 1 - 1e-6],
        train_incidences=[float(x) for x in trained],
        validation_incidences=[float(x) for x in held_out],
        bounds=bounds, model=model, training=train, **details)


