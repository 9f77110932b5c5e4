"""What to measure next: `plan` chooses a batch of geometries among candidates and orders
them into a short route for the goniometer's motors.

**With measurements**, the choice is the greedy integrated-variance design (active learning
Cohn, ALC, or I-optimal/IMSE design: Cohn 1996; Gramacy, *Surrogates*, 2020, ch. 6) of the
learned discrepancy's Gaussian process (`brdfjax.prediction.discrepancy`):

1. the model is fitted (`brdfjax.fit`, no uncertainty) and the process of its log residual
   is fitted on at most `~brdfjax.prediction.discrepancy.MAX_POINTS` of the readings, as
   ``brdfjax fit --predict`` fits it; its hyperparameters and noise are then fixed;
2. the process is conditioned on the readings' inputs (at most `CONDITION_POINTS` of them,
   spread by `~brdfjax.prediction.discrepancy.subsample`; more than the 256 the
   hyperparameters are learned on, so that a reading outside those 256 still counts as
   known); the observed values play no part: with fixed hyperparameters a Gaussian
   process's covariance does not depend on them;
3. for every candidate ``c`` the drop of the posterior variance summed over the region ``R``
   if ``c`` were read is, in closed form,
   ``sum_r k_n(r, c)^2 / (k_n(c, c) + noise^2)``, with ``k_n`` the posterior covariance
   given the points so far; the candidate of the largest drop is taken, the process is
   conditioned on it (a rank-one term of ``k_n``), and so on ``budget`` times. The matrix
   algebra is NumPy's, vectorised over the candidates; it costs ``O(n^3 + n |R| |C| +
   budget |R| |C|)`` for ``n`` readings.

The region is where the prediction is wanted: by default the candidates themselves (all of
them, measured or not). It is reduced to at most `REGION_POINTS` points and the candidates
to at most `CANDIDATE_POINTS`, each by the discrepancy's `subsample` rule (evenly spaced
along each incidence's Z-order curve, every incidence keeping its share).

**Without measurements**, the design is space-filling: greedy maximin (farthest-point
sampling) over the candidates in the process's feature space
(`~brdfjax.prediction.discrepancy.features`: half and difference angles, the half vector
signed where the candidates leave the plane of incidence, and the incidence; in radians).
The first point is a candidate drawn with ``seed``; each next one is the candidate farthest
from every point chosen. It was preferred to a scrambled Sobol set snapped to the nearest
unused candidate because candidates are a finite set, often a regular grid: two Sobol
points near one node snap to neighbouring nodes, so the snapped design's minimum distance
can fall to the grid's step, no better than a random subset's, whereas greedy maximin makes
that minimum as large as it can (at least half the best possible). It also spreads in the
space the process learns in. Its known weakness: it takes the edges of the domain (grazing
angles, the extreme incidences) first and fills the inside after.

**The model.** ``model="auto"`` chooses it as ``brdfjax fit --model auto --predict`` does
(`auto_model`: `brdfjax.prediction.selection.compare_models` with the learned discrepancy,
then `~brdfjax.prediction.selection.Comparison.predictor`, the one-standard-error rule on
each model's cross-validation corrected by its discrepancy); it needs readings at three
incidences or more.

**Threads.** The planning runs with one BLAS thread (`one_blas_thread`): the process's
Cholesky factorisations (JAX's CPU LAPACK calls, SciPy's OpenBLAS) and the design's matrix
products (NumPy's OpenBLAS) are small enough that a second thread gains little, and on a
loaded machine OpenBLAS's waiting threads took the cores from the work: planning 20 readings
from 300 among 5000 candidates took 3.8-10.8 s warm with OpenBLAS's default two threads
and 0.7-0.9 s with one, on two cores shared with other jobs (load average 4-5).

Candidates the instrument cannot reach (`brdfjax.instrument.plan.unreachable`: a motor past
its range, the detector in the source beam) are left out, and so are geometries already
measured and a candidate's repeats: a plan never proposes a reading twice.

**The route.** The chosen geometries are grouped by incidence (motor B), the incidences
taken in increasing order from the home position; within one, by the detector-arm azimuth
(motor A), the azimuths taken from the end nearer to the arm, each swept in signed zenith
(motor C) from the end nearer to the detector, so that consecutive sweeps run back and forth
(serpentine). The motor time counts the travel of each motor at the simulator's speed
(`brdfjax.instrument.simulator.MOTOR_SPEED`), one motor after another as
`brdfjax.instrument.acquire` moves them, from the home position. The sweep order (the
geometries sorted by incidence, then ``phi_r``, then ``theta_r``) is timed too, and is kept
if it is shorter, so the route is never slower. The sample changer swaps once per reading
(`~brdfjax.instrument.simulator.CHANGER_SECONDS` each) in any order.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import glob
import os
from dataclasses import dataclass, field

import numpy as np

from brdfjax.data.measurements import Measurements, geometry_keys

REGION_POINTS = 1024
CANDIDATE_POINTS = 8192
CONDITION_POINTS = 1024


@dataclass
class Plan:
    """A batch of readings to take, in the order to take them.

    Attributes:
        theta_i, theta_r, phi_r: the geometries in degrees (``phi_r`` in [0, 360)), in the
            route's order.
        method: ``alc`` (integrated variance, from measurements) or ``maximin``
            (space-filling, from none).
        model: the model fitted (``alc``), or None.
        candidates: the candidates chosen among: reachable, distinct and not yet measured
            (before `CANDIDATE_POINTS` reduces them).
        unreachable: candidates left out because the instrument cannot reach them.
        measured: readings the plan started from.
        region_points: the region's points the variance is summed over (``alc``).
        variance_before, variance_after: the process's posterior variance of the log
            residual (latent, without the noise), averaged over the region, given the
            readings and given the readings and the plan (``alc``; NaN for ``maximin``).
            Its square root is roughly a relative standard deviation of the correction.
        motor_seconds: the route's motor travel time at the simulator's motor speed.
        sweep_motor_seconds: the same geometries' in sweep order (incidence, ``phi_r``,
            ``theta_r``).
        changer_seconds: the sample changer's time, one swap per reading (any order).
        discrepancy: the fitted process (``alc``), or None.
        auto: whether ``model`` was chosen by ``model="auto"`` (`auto_model`).
    """

    theta_i: np.ndarray
    theta_r: np.ndarray
    phi_r: np.ndarray
    method: str
    model: str | None
    candidates: int
    unreachable: int
    measured: int
    region_points: int
    variance_before: float
    variance_after: float
    motor_seconds: float
    sweep_motor_seconds: float
    changer_seconds: float
    discrepancy: object = field(default=None, repr=False)
    auto: bool = False

    def __len__(self) -> int:
        return self.theta_i.size

    def geometry(self) -> Measurements:
        """The plan as geometry-only `Measurements` (brdf NaN), in order."""
        return Measurements.from_degrees(self.theta_i, self.theta_r, self.phi_r,
                                         np.full(len(self), np.nan),
                                         metadata={"source": "brdfjax plan"})

    def to_csv(self) -> str:
        """A geometry-only brdfjax CSV (``theta_i,theta_r,phi_r``, degrees, in order) that
        `brdfjax.data.formats.load_geometry` reads."""
        lines = [f"# source: brdfjax plan ({self.method}"
                 + (f", {self.model}" if self.model else "") + ")", "theta_i,theta_r,phi_r"]
        lines += [",".join(f"{x:.10g}" for x in row)
                  for row in zip(self.theta_i, self.theta_r, self.phi_r)]
        return "\n".join(lines) + "\n"

    def instrument_plan(self, **settings):
        """The `brdfjax.instrument.plan.Plan` that measures these geometries in this order
        (``settings``: its ``average``, ``integration_ms``, ``beam_margin``)."""
        from brdfjax.instrument.plan import Plan as InstrumentPlan

        return InstrumentPlan(geometries=tuple(zip(self.theta_i, self.theta_r, self.phi_r)),
                              **settings)

    def summary(self) -> list[str]:
        """What the plan is, in a few lines."""
        if self.method == "alc":
            chosen = " (chosen by --model auto)" if self.auto else ""
            how = (f"chosen by integrated variance (ALC) of {self.model}{chosen} x its "
                   "discrepancy "
                   f"over {self.region_points} region points, from {self.measured} readings: "
                   f"the process's mean variance over the region {self.variance_before:.3g} "
                   f"-> {self.variance_after:.3g} (sd {np.sqrt(self.variance_before):.3g} -> "
                   f"{np.sqrt(self.variance_after):.3g} in log units)")
        else:
            how = "chosen space-filling (greedy maximin in the discrepancy's inputs), no data"
        left = f", {self.unreachable} out of the instrument's reach left out" \
            if self.unreachable else ""
        return [f"plan: {len(self)} readings of {self.candidates} candidates{left}; {how}",
                (f"route: {self.motor_seconds:.0f} s of motor travel "
                 f"({self.sweep_motor_seconds:.0f} s in sweep order), plus "
                 f"{self.changer_seconds:.0f} s of sample changer")]


@dataclass(frozen=True)
class Candidates:
    """The candidates a plan chooses among (`check_inputs`).

    Attributes:
        index: positions in the candidates given of the reachable, distinct, unmeasured ones.
        unreachable: how many were out of the instrument's reach.
        repeated: how many repeated an earlier candidate.
        measured: how many were measured already.
    """

    index: np.ndarray
    unreachable: int
    repeated: int
    measured: int


def plan(measured: Measurements | None, candidates: Measurements, budget: int, *,
         region: Measurements | None = None, model: str = "ggx", seed: int = 0) -> Plan:
    """The ``budget`` readings, among ``candidates``, that most reduce the prediction's
    integrated uncertainty over ``region``, in the order to measure them (see the module
    docstring).

    Args:
        measured: readings already taken (their BRDF is used), or None to start from
            nothing (a space-filling design).
        candidates: the geometries that may be chosen (any `Measurements`; its BRDF is
            ignored): a replay's file, a lab's fixed positions, or `instrument_grid`. New
            incidences are candidates like any other.
        budget: how many readings to choose (at least 1).
        region: where the prediction is wanted (default: the candidates); every point must
            be within the instrument's reach.
        model: the model whose discrepancy is learned: a name of
            `brdfjax.models.available`, or ``auto`` to choose it as ``brdfjax fit --model
            auto --predict`` does (`auto_model`; readings at three incidences or more).
        seed: seeds the fit and the space-filling design's first point.

    Returns:
        A `Plan`.

    Raises:
        ValueError: bad input (checked before any work; `check_inputs`).
    """
    found = check_inputs(candidates, budget, region=region, measured=measured, model=model)
    with one_blas_thread():
        return _plan(measured, candidates, found, budget, region=region, model=model,
                     seed=seed)


def _plan(measured, candidates, found: Candidates, budget, *, region, model, seed) -> Plan:
    """`plan` of checked inputs."""
    # Degrees as the candidates gave them: 30, not the 29.999999999999996 of a round trip
    # through radians, in the plan file a user reads.
    chosen_angles = np.round(np.degrees([candidates.theta_i, candidates.theta_r,
                                         candidates.phi_r]), 9) + 0.0
    index = found.index
    if measured is None:
        picks = _maximin(_features_of(candidates, index), budget, seed)
        before = after = float("nan")
        region_points, process, fitted_model = 0, None, None
    else:
        picks, before, after, region_points, process, fitted_model = _alc_plan(
            measured, candidates, index, budget, region=region, model=model, seed=seed)
    ti, tr, pr = chosen_angles[:, index[picks]]
    pr = np.mod(pr, 360.0)
    order, seconds, sweep = route(ti, tr, pr)
    from brdfjax.instrument.simulator import CHANGER_SECONDS

    return Plan(ti[order], tr[order], pr[order], "maximin" if measured is None else "alc",
                fitted_model, index.size, found.unreachable,
                0 if measured is None else len(measured), region_points, before, after,
                seconds, sweep, CHANGER_SECONDS * len(order), process,
                measured is not None and model == "auto")


def auto_model(measured: Measurements, seed: int = 0) -> str:
    """The model ``brdfjax fit --model auto --predict`` chooses for ``measured``: every
    model of `brdfjax.prediction.selection.DEFAULT_CANDIDATES` fitted and cross-validated
    with its learned discrepancy (`~brdfjax.prediction.selection.compare_models`), then
    `~brdfjax.prediction.selection.Comparison.predictor`. ``measured`` needs readings at
    three incidences or more. ``plan(model="auto")`` calls it; so may a loop that plans
    batch after batch."""
    from brdfjax.prediction.selection import compare_models

    with one_blas_thread():
        return compare_models(measured, seed=seed, discrepancy="gp").predictor.name


def check_inputs(candidates: Measurements, budget, *, region: Measurements | None = None,
                 measured: Measurements | None = None, model: str = "ggx",
                 names: dict | None = None) -> Candidates:
    """Check a plan's inputs before any work; `ValueError` says what is wrong in one line.

    ``names`` gives the words that name each input in messages (``{"budget": "--budget",
    "candidates": "--candidates GEOM.csv", "region": ..., "measured": ...}``).

    Returns:
        The usable `Candidates`.
    """
    from brdfjax.instrument.plan import unreachable

    names = {"budget": "budget", "candidates": "candidates", "region": "region",
             "measured": "measured", "model": "model", **(names or {})}
    if isinstance(budget, bool) or not isinstance(budget, (int, np.integer)) or budget < 1:
        raise ValueError(f"{names['budget']} {budget}: give the number of readings to plan, "
                         "a whole number of at least 1")
    if len(candidates) == 0:
        raise ValueError(f"{names['candidates']}: no geometries to choose from")
    if measured is not None:
        if not measured.has_brdf or np.isnan(measured.brdf).any():
            raise ValueError(f"{names['measured']}: the readings have no BRDF values; give "
                             "measurements, or none to start from nothing")
        if len(measured) < 3:
            raise ValueError(f"{names['measured']}: {len(measured)} readings; a plan from "
                             "measurements needs at least 3 (give none for a space-filling "
                             "start)")
        if model == "auto":
            incidences = np.unique(np.round(np.degrees(measured.theta_i), 6)).size
            if incidences < 3:
                raise ValueError(f"{names['model']} auto: chooses by cross-validation over "
                                 f"incidences and needs readings at 3 or more; "
                                 f"{names['measured']} has {incidences}: name a model (ggx, "
                                 "the default, predicts best on most real data)")
        else:
            from brdfjax.models import get

            get(model)  # an unknown name fails here, before the fit
    if region is not None:
        if len(region) == 0:
            raise ValueError(f"{names['region']}: no geometries")
        angles = np.degrees([region.theta_i, region.theta_r, region.phi_r]).T
        reasons = [unreachable(*g) for g in angles]
        bad = [k for k, why in enumerate(reasons) if why is not None]
        if bad:
            k = bad[0]
            raise ValueError(
                f"{names['region']}: {len(bad)} of {len(region)} geometries are out of the "
                f"instrument's reach; the first, point {k + 1} (theta_i {angles[k][0]:g}, "
                f"theta_r {angles[k][1]:g}, phi_r {angles[k][2]:g} deg): {reasons[k]}")
    angles = np.degrees([candidates.theta_i, candidates.theta_r, candidates.phi_r]).T
    reachable = np.array([unreachable(*g) is None for g in angles])
    keys = _keys(candidates)
    _, first = np.unique(keys, axis=0, return_index=True)
    distinct = np.zeros(len(candidates), bool)
    distinct[first] = True
    done = np.zeros(len(candidates), bool)
    if measured is not None:
        known = {tuple(row) for row in _keys(measured)}
        done = np.array([tuple(row) in known for row in keys])
    usable = reachable & distinct & ~done
    found = Candidates(np.flatnonzero(usable), int((~reachable).sum()),
                       int((reachable & ~distinct).sum()), int((reachable & distinct & done).sum()))
    if budget > found.index.size:
        raise ValueError(
            f"{names['budget']} {budget}: more than the {found.index.size} candidate "
            f"geometries left to measure ({names['candidates']}: {len(candidates)} geometries, "
            f"{found.unreachable} out of the instrument's reach, {found.repeated} repeated, "
            f"{found.measured} already measured)")
    return found


def instrument_grid(out_of_plane: bool = False) -> Measurements:
    """The instrument's reachable geometries on a grid (geometry only): incidences 0-80 deg
    in steps of 10, ``theta_r`` 0-85 in steps of 5, ``phi_r`` 0 and 180 (in plane) or 0-180
    in steps of 15 (``out_of_plane``), the normal once per incidence, without the geometries
    `brdfjax.instrument.plan.unreachable` refuses (the detector in the source beam)."""
    from brdfjax.instrument.plan import unreachable

    azimuths = np.arange(0.0, 181.0, 15.0) if out_of_plane else np.array([0.0, 180.0])
    rows = [(ti, tr, pr) for ti in np.arange(0.0, 81.0, 10.0)
            for tr in np.arange(0.0, 86.0, 5.0) for pr in azimuths]
    rows = [row for row in rows if unreachable(*row) is None]
    ti, tr, pr = np.array(rows).T
    _, first = np.unique(geometry_keys(ti, tr, pr), axis=0, return_index=True)
    keep = np.sort(first)
    return Measurements.from_degrees(ti[keep], tr[keep], pr[keep], np.full(keep.size, np.nan),
                                     metadata={"source": "brdfjax plan: the instrument's grid"})


def route(theta_i, theta_r, phi_r) -> tuple[np.ndarray, float, float]:
    """The order to measure geometries in (degrees, arrays (N,)) and its motor seconds,
    and the sweep order's (see the module docstring): ``(order, seconds, sweep seconds)``."""
    from brdfjax.instrument.plan import motor_angles

    theta_i, theta_r, phi_r = (np.asarray(x, float) for x in (theta_i, theta_r, phi_r))
    motors = np.array([motor_angles(*g, normal_azimuth=np.nan)
                       for g in zip(theta_i, theta_r, phi_r)]).reshape(-1, 3)
    a, b, c = np.round(motors.T, 6)
    normal = np.isnan(a)
    order, arm, detector = [], 0.0, 0.0
    for incidence in np.unique(b):
        here = np.flatnonzero(b == incidence)
        azimuths = np.unique(a[here[~normal[here]]])
        if azimuths.size and abs(arm - azimuths[-1]) < abs(arm - azimuths[0]):
            azimuths = azimuths[::-1]
        groups = [here[a[here] == value] for value in azimuths] or [np.zeros(0, int)]
        groups[0] = np.concatenate([groups[0], here[normal[here]]])  # the normal: any arm
        for group in groups:
            group = group[np.argsort(c[group], kind="stable")]
            if abs(detector - c[group[-1]]) < abs(detector - c[group[0]]):
                group = group[::-1]
            order += list(group)
            arm = a[group[-1]] if not normal[group[-1]] else arm
            detector = c[group[-1]]
    order = np.array(order, int)
    sweep = np.lexsort((theta_r, np.mod(phi_r, 360.0), theta_i))
    seconds = motor_seconds(theta_i[order], theta_r[order], phi_r[order])
    sweep_seconds = motor_seconds(theta_i[sweep], theta_r[sweep], phi_r[sweep])
    if sweep_seconds < seconds:
        order, seconds = sweep, sweep_seconds
    return order, seconds, sweep_seconds


def motor_seconds(theta_i, theta_r, phi_r) -> float:
    """The motors' travel time (s) to visit geometries (degrees) in order from the home
    position (every motor at 0), one motor after another, at
    `brdfjax.instrument.simulator.MOTOR_SPEED`, with the motor angles the plan file gives
    them (`brdfjax.instrument.plan.motor_angles`)."""
    from brdfjax.instrument.plan import motor_angles
    from brdfjax.instrument.simulator import MOTOR_SPEED

    position, travel = np.zeros(3), 0.0
    for geometry in zip(theta_i, theta_r, phi_r):
        new = np.array(motor_angles(*geometry, normal_azimuth=position[0]))
        travel += float(np.abs(new - position).sum())
        position = new
    return travel / MOTOR_SPEED


def integrated_variance_design(kernel, prior_variance: float, noise: float, known, candidates,
                               region, budget: int, available=None) -> dict:
    """The greedy integrated-variance (ALC) design of a Gaussian process with fixed
    hyperparameters (see the module docstring).

    The posterior cross-covariance ``k_n(R, C)`` is formed once, given ``known``; each pick
    adds a rank-one term, kept as its two factors, so that a step costs one matrix-vector
    product with it and the column sums of squares (the drops' numerators) are updated in
    closed form, instead of rewriting the matrix.

    Args:
        kernel: ``kernel(x1 (N, D), x2 (M, D)) -> (N, M)`` covariances, without noise.
        prior_variance: ``kernel(x, x)`` (a stationary kernel's amplitude squared).
        noise: the white noise's standard deviation.
        known: inputs already read (n, D); n may be 0.
        candidates: inputs that may be chosen (m, D).
        region: inputs whose variance is summed (q, D).
        budget: how many to choose.
        available: mask (m,) of the candidates that may be chosen (default: all).

    Returns:
        ``{"picks": indices into candidates in the order chosen, "drops": the variance drop
        over the region of every candidate at each step (budget, m), "before", "after": the
        posterior variance (latent) summed over the region given ``known``, and given
        ``known`` and the picks}``.
    """
    known, candidates, region = (np.asarray(x, float).reshape(len(x), -1)
                                 for x in (known, candidates, region))
    noise2 = float(noise) ** 2
    cross = kernel(region, candidates)  # k_n(R, C) given the readings alone
    variance_c = np.full(len(candidates), float(prior_variance))
    variance_r = np.full(len(region), float(prior_variance))
    if len(known):
        from scipy.linalg import cho_factor, solve_triangular

        factor = cho_factor(kernel(known, known) + noise2 * np.eye(len(known)), lower=True)[0]
        whitened_c = solve_triangular(factor, kernel(known, candidates), lower=True)
        whitened_r = solve_triangular(factor, kernel(known, region), lower=True)
        cross -= whitened_r.T @ whitened_c
        variance_c -= np.sum(whitened_c**2, axis=0)
        variance_r -= np.sum(whitened_r**2, axis=0)
    else:
        whitened_c = np.zeros((0, len(candidates)))
    free = np.ones(len(candidates), bool) if available is None else np.array(available, bool)
    before = float(variance_r.sum())
    squares = np.einsum("rc,rc->c", cross, cross)  # sum_r k(r, c)^2 of the posterior
    updates_r, updates_c, picks, drops = [], [], [], []
    for _ in range(budget):
        drop = np.maximum(squares, 0.0) / (np.maximum(variance_c, 0.0) + noise2)
        drops.append(drop)
        # The first of the candidates within 1e-9 of the largest drop: geometries the
        # process cannot tell apart (the same inputs) tie to rounding, and the choice
        # among them must not follow the last bits of the input.
        drop = np.where(free, drop, -np.inf)
        pick = int(np.argmax(drop >= drop.max() * (1 - 1e-9)))
        picks.append(pick)
        free[pick] = False
        # k(R, pick) and k(C, pick) of the current posterior: given the readings, less the
        # earlier picks' rank-one terms.
        done_r, done_c = np.array(updates_r).reshape(-1, len(region)), \
            np.array(updates_c).reshape(-1, len(candidates))
        column_r = cross[:, pick] - done_r.T @ done_c[:, pick]
        column_c = kernel(candidates[pick:pick + 1], candidates)[0]  # symmetric
        column_c -= whitened_c.T @ whitened_c[:, pick] + done_c.T @ done_c[:, pick]
        scale = np.sqrt(max(variance_c[pick], 0.0) + noise2)
        update_r, update_c = column_r / scale, column_c / scale
        # sum_r (k(r, c) - u_r v_c)^2 = squares - 2 v_c (k(R, c) . u) + v_c^2 |u|^2
        projected = cross.T @ update_r - done_c.T @ (done_r @ update_r)
        squares = squares - 2 * update_c * projected + update_c**2 * (update_r @ update_r)
        variance_c -= update_c**2
        variance_r -= update_r**2
        updates_r.append(update_r)
        updates_c.append(update_c)
    return {"picks": np.array(picks, int), "drops": np.array(drops), "before": before,
            "after": float(variance_r.sum())}


def process_kernel(process):
    """The covariance function (without noise) of a fitted
    `brdfjax.prediction.discrepancy.Discrepancy`, as `integrated_variance_design` takes
    it: ``kernel(x1 (N, D), x2 (M, D)) -> (N, M)``, NumPy arrays. It is the process's own
    kernel (`brdfjax.prediction.discrepancy._kernel`: ``amplitude^2 SE(angles) (share + (1 -
    share) SE(theta_i))``) written in NumPy, the squared distances by matrix products:
    planning 20 readings from 300 among 5000 candidates spent 0.8 s in it, against 3.3 s
    with tinygp's kernel compiled (2 loaded cores)."""
    from brdfjax.prediction.discrepancy import _physical

    _, amplitude, lengths, share, _ = (np.asarray(v) for v in _physical(
        np.asarray(process._u), process._x.shape[1]))

    def kernel(x1, x2):
        x1, x2 = (np.asarray(x, float) / lengths for x in (x1, x2))
        out = _squared_distances(x1[:, :-1], x2[:, :-1])
        out *= -0.5
        np.exp(out, out=out)
        out *= _incidence_factor(x1[:, -1], x2[:, -1], float(share))
        out *= amplitude**2
        return out

    return kernel


def _squared_distances(x1, x2) -> np.ndarray:
    """``|x1_i - x2_j|^2`` (N, M) by a matrix product, in place (no temporaries of the
    output's size), at least 0."""
    out = x1 @ x2.T
    out *= -2.0
    out += np.sum(x1**2, axis=1)[:, None]
    out += np.sum(x2**2, axis=1)[None, :]
    return np.maximum(out, 0.0, out=out)


def _incidence_factor(t1, t2, share: float) -> np.ndarray:
    """``share + (1 - share) exp(-(t1_i - t2_j)^2 / 2)`` (N, M) for scaled incidences: the
    exponential taken once per pair of distinct incidences (a goniometer has few), then
    spread by index."""
    u1, i1 = np.unique(t1, return_inverse=True)
    u2, i2 = np.unique(t2, return_inverse=True)
    table = share + (1 - share) * np.exp(-0.5 * (u1[:, None] - u2[None, :]) ** 2)
    return table[i1[:, None], i2[None, :]]


def _alc_plan(measured, candidates, index, budget, *, region, model, seed):
    """(picks into ``index``, mean variance before and after, region points, process,
    model name) of the integrated-variance design from ``measured``."""
    from brdfjax.fitting.fit import fit
    from brdfjax.fitting.objective import brdf_values, prepare
    from brdfjax.prediction.discrepancy import (
        MAX_POINTS,
        features,
        fit_discrepancies,
        log_residual,
        residual_floor,
        subsample,
    )

    if model == "auto":
        model = auto_model(measured, seed=seed)
    result = fit(measured, model=model, seed=seed)
    values = np.asarray(brdf_values(result.vector, prepare(measured, result.model),
                                    result.model))
    floor, azimuth = residual_floor(measured.brdf), not measured.in_plane
    x = features(measured.theta_i, measured.theta_r, measured.phi_r, azimuth)
    residual = log_residual(measured.brdf, values, floor)
    keep = subsample(measured.theta_i, measured.theta_r, measured.phi_r, MAX_POINTS)
    (process,) = fit_discrepancies([(x[keep], residual[keep])], floor, azimuth)
    known = x[subsample(measured.theta_i, measured.theta_r, measured.phi_r, CONDITION_POINTS)]
    region = candidates if region is None else region
    where = subsample(region.theta_i, region.theta_r, region.phi_r, REGION_POINTS)
    x_region = features(region.theta_i[where], region.theta_r[where], region.phi_r[where],
                        azimuth)
    pool = index[subsample(candidates.theta_i[index], candidates.theta_r[index],
                           candidates.phi_r[index], CANDIDATE_POINTS)]
    x_pool = features(candidates.theta_i[pool], candidates.theta_r[pool],
                      candidates.phi_r[pool], azimuth)
    design = integrated_variance_design(process_kernel(process), process.amplitude**2,
                                        process.noise, known, x_pool, x_region, budget)
    picks = np.searchsorted(index, pool[design["picks"]])
    return (picks, design["before"] / where.size, design["after"] / where.size, where.size,
            process, result.model.name)


@contextlib.contextmanager
def one_blas_thread():
    """Run the body with one thread in NumPy's and SciPy's OpenBLAS (the number each had is
    put back after), where their libraries can be found; else as they are (see the module
    docstring, 'Threads')."""
    controls = _openblas_controls()
    before = [get() for get, _ in controls]
    for _, set_threads in controls:
        set_threads(1)
    try:
        yield
    finally:
        for (_, set_threads), count in zip(controls, before):
            set_threads(count)


_OPENBLAS_THREADS = [("scipy_openblas_get_num_threads64_", "scipy_openblas_set_num_threads64_"),
                     ("scipy_openblas_get_num_threads", "scipy_openblas_set_num_threads"),
                     ("openblas_get_num_threads", "openblas_set_num_threads")]


@functools.cache
def _openblas_controls() -> tuple:
    """``(get, set)`` thread-count functions of the OpenBLAS libraries that the NumPy and
    SciPy wheels bundle (``numpy.libs``, ``scipy.libs``; ``.dylibs`` on macOS), found once."""
    import scipy

    found = []
    for module in (np, scipy):
        package = os.path.dirname(module.__file__)
        folders = [f"{package}.libs", os.path.join(package, ".dylibs")]
        for path in sorted(p for folder in folders for p in glob.glob(f"{folder}/*openblas*")):
            found += _thread_functions(path)
    return tuple(found)


def _thread_functions(path: str) -> list:
    """The first ``(get, set)`` pair of `_OPENBLAS_THREADS` that the library at ``path``
    exports, as a one-item list, or an empty one."""
    try:
        library = ctypes.CDLL(path)
    except OSError:
        return []
    for get_name, set_name in _OPENBLAS_THREADS:
        get, set_threads = (getattr(library, name, None) for name in (get_name, set_name))
        if get is not None and set_threads is not None:
            get.restype = ctypes.c_int
            set_threads.argtypes = [ctypes.c_int]
            return [(get, set_threads)]
    return []


def _keys(data: Measurements) -> np.ndarray:
    """`geometry_keys` of ``data`` with ``phi_r`` taken modulo 360 before it rounds, so that
    -81.8699 and 278.1301 deg give one key (rounded first, the first becomes
    278.13009999999997)."""
    return geometry_keys(np.degrees(data.theta_i), np.degrees(data.theta_r),
                         np.mod(np.degrees(data.phi_r), 360.0))


def _features_of(candidates: Measurements, index) -> np.ndarray:
    from brdfjax.prediction.discrepancy import features

    return features(candidates.theta_i[index], candidates.theta_r[index],
                    candidates.phi_r[index], not candidates.in_plane)


def _maximin(x: np.ndarray, budget: int, seed: int) -> np.ndarray:
    """Greedy maximin (farthest-point) indices of ``budget`` rows of ``x``, the first drawn
    with ``seed``."""
    picks = [int(np.random.default_rng(seed).integers(len(x)))]
    nearest = np.linalg.norm(x - x[picks[0]], axis=1)
    nearest[picks[0]] = -np.inf
    for _ in range(budget - 1):
        pick = int(np.argmax(nearest))
        picks.append(pick)
        nearest = np.minimum(nearest, np.linalg.norm(x - x[pick], axis=1))
        nearest[picks] = -np.inf  # a point the same as a chosen one is 0 away, not chosen
    return np.array(picks, int)
