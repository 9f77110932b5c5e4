"""What the fit minimises: the relative squared error of Eq. (6) and its residual vector.

    E(x) = sum g (f_r cos tr - f_r0 cos tr)^2 / sum g (f_r0 cos tr)^2

over the measurement points, with ``g = g1(ti) g2(tr)`` the paper's weights (1 in the paper;
here the data's per-point ``weights`` when given). A `Problem` holds the scene and the
measured projected BRDF with the weights already normalised by the denominator, so that
``E = sum(weight * (model - target)^2)`` and the least-squares residual is
``sqrt(weight) * (model - target)``. All arrays are traced: refitting same-shaped data with
other values never recompiles.
"""

from __future__ import annotations

import functools
import itertools
import operator
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from brdfjax.cache import stage
from brdfjax.data.measurements import Measurements
from brdfjax.models import Model
from brdfjax.models.bounds import Bounds
from brdfjax.models.paper import FIVE, evaluate, evaluate_projected


class Problem(NamedTuple):
    """A measurement set ready for the objective (a pytree of arrays of shape (N,)).

    Attributes:
        scene: the model's parameter-free geometry terms (`brdfjax.models.Model.geometry`).
        target: the measured projected BRDF f_r0 cos(tr).
        weight: g / sum(g target^2); zero for padding points.
        model: the `brdfjax.models.Model` fitted (static: no leaves).
    """

    scene: NamedTuple
    target: jax.Array
    weight: jax.Array
    model: Model = FIVE


def _model_geometry(model, theta_i, theta_r, phi_r, in_plane):
    return model.geometry(theta_i, theta_r, phi_r, in_plane)


_geometry = stage(_model_geometry, static_argnames=("in_plane",))

# Fitted point counts are padded up to a multiple of this with zero-weight copies of the
# first point (a valid geometry, so every value stays finite; zero weight, so E is
# unchanged). Data of nearby sizes then share compiled code, and a sample fitted alone
# runs exactly the arithmetic it runs in a batch (`brdfjax.fitting.batch`).
POINT_BUCKET = 64


def bucket(count: int) -> int:
    """``count`` rounded up to a multiple of `POINT_BUCKET`."""
    return POINT_BUCKET * -(-count // POINT_BUCKET)


def pad(values, length: int, fill=None) -> np.ndarray:
    """``values`` (N,) extended to ``length`` with ``fill``, or with its first value."""
    values = np.asarray(values)
    if values.size == length:
        return values
    extra = np.full(length - values.size, values[0] if fill is None else fill,
                    dtype=values.dtype)
    return np.concatenate([values, extra])


def padded_scene(geometry: NamedTuple, length: int) -> NamedTuple:
    """A geometry extended to ``length`` points with copies of its first point (every
    array of it: a sum's geometry nests its parts')."""
    return jax.tree.map(lambda x: pad(x, length), geometry)


def prepare(data: Measurements, model: Model = FIVE, dtype=jnp.float64) -> NamedTuple:
    """The model's geometry of a measurement set (host arrays; one compiled call, and
    in-plane data take the fast path where the model has one).

    The call runs on the angles padded to `bucket` points with copies of the first, so that
    sets of nearby sizes share its compiled shape (a cross-validation's folds and all of
    its data: one compilation per model instead of two); the geometry is pointwise, so the
    copies are cut off again exactly.
    """
    count = len(data.theta_i)
    angles = (pad(np.asarray(x, dtype=dtype), bucket(count))
              for x in (data.theta_i, data.theta_r, data.phi_r))
    geometry = _geometry(model, *angles, in_plane=data.in_plane)
    return jax.tree.map(lambda x: np.asarray(x)[:count], geometry)


def _projected(params, geometry, model):
    return evaluate_projected(params, geometry, model)


_projected_stage = stage(_projected)


def projected(params, geometry, model: Model = FIVE) -> jax.Array:
    """`brdfjax.models.paper.evaluate_projected` as one compiled stage (host calls)."""
    return _projected_stage(params, geometry, model)


def _brdf(params, geometry, model):
    return evaluate(params, geometry, model)


_brdf_stage = stage(_brdf)


def brdf_values(params, geometry, model: Model = FIVE) -> jax.Array:
    """`brdfjax.models.paper.evaluate` (f_r, 1/sr) as one compiled stage (host calls)."""
    return _brdf_stage(params, geometry, model)


def targets(data: Measurements) -> tuple[np.ndarray, np.ndarray]:
    """The measured projected BRDF f_r0 cos(tr) and the weights g of Eq. (6) (host arrays)."""
    target = data.brdf * np.cos(data.theta_r)
    weight = np.ones_like(target) if data.weights is None else data.weights
    return target, weight


LOSSES = ("eq6", "relative", "balanced")
# The relative loss's floor, as a fraction of the largest |f_r0 cos tr|: points near zero
# are not weighted beyond 1 / floor^2.
RELATIVE_FLOOR = 0.01


def with_loss(data: Measurements, loss: str) -> Measurements:
    """``data`` with the weights of Eq. (6) that make it minimise ``loss``.

    ``eq6`` leaves the data as they are (the paper's weights 1, or the file's); ``relative``
    weights each point by ``1 / (y^2 + floor^2)`` (y the projected measurement, floor
    `RELATIVE_FLOOR` of the largest), so that E is the mean squared relative error;
    ``balanced`` weights each incidence by ``1 / sum y^2`` over its points, so that every
    incidence counts alike. Any weights of the file multiply these.
    """
    import dataclasses

    if loss not in LOSSES:
        raise ValueError(f"unknown loss {loss!r}; choose one of {', '.join(LOSSES)}")
    if loss == "eq6":
        return data
    target = data.brdf * np.cos(data.theta_r)
    if loss == "relative":
        floor = RELATIVE_FLOOR * np.max(np.abs(target))
        weight = 1.0 / (target**2 + floor**2)
    else:
        degrees = np.round(np.degrees(data.theta_i), 6)
        totals = {d: np.sum(target[degrees == d] ** 2) for d in np.unique(degrees)}
        weight = np.array([1.0 / totals[d] if totals[d] > 0 else 0.0 for d in degrees])
    if data.weights is not None:
        weight = weight * data.weights
    return dataclasses.replace(data, weights=weight)


def relative_error(model_projected, target, weight) -> float:
    """E of Eq. (6) on host arrays (for reporting on any subset of points)."""
    difference = model_projected - target  # array methods: cheaper than np.sum on few points
    return float((weight * difference * difference).sum() / (weight * target * target).sum())


def problem(data: Measurements, model: Model = FIVE, dtype=jnp.float64,
            geometry: NamedTuple | None = None) -> Problem:
    """The objective's view of a measurement set: geometry, target, normalised weights.

    The arrays are padded to ``bucket(len(data))`` points of zero weight.

    Args:
        data: the measurements.
        model: the `brdfjax.models.Model` to fit.
        dtype: float64 for fitting; float32 halves the cost of a population evaluation.
        geometry: the model's geometry of ``data`` if already computed, padded or not.
    """
    points = bucket(len(data))
    geometry = prepare(data, model, dtype) if geometry is None else geometry
    if geometry.cos_theta_r.shape[-1] != points:
        geometry = padded_scene(geometry, points)
    target, weight = normalised_targets(data, points)
    return Problem(geometry, jnp.asarray(target, dtype), jnp.asarray(weight, dtype), model)


NOTHING_TO_FIT = "every weighted measurement is zero; nothing to fit"


def normalised_targets(data: Measurements, points: int) -> tuple[np.ndarray, np.ndarray]:
    """`Problem.target` and `Problem.weight` as host arrays, padded to ``points``.

    Raises:
        ValueError: every weighted measurement is zero (E of Eq. 6 is undefined).
    """
    target, weight, usable = normalised(data.brdf, data.theta_r, data.weights, points)
    if not usable:
        raise ValueError(f"{data.name}: {NOTHING_TO_FIT}")
    return target, weight


def normalised(brdf, theta_r, weights, points: int) -> tuple[np.ndarray, ...]:
    """`normalised_targets` of measurement arrays (..., N) with any leading axes (the samples
    of a batch, stacked), and whether each set is usable: a set whose every weighted
    measurement is zero has no E of Eq. 6 (its weights are left unnormalised).

    Returns:
        target and weight (..., points), zero beyond N; usable (...).
    """
    target = brdf * np.cos(theta_r)
    weight = np.ones_like(target) if weights is None else weights
    denominator = np.sum(weight * target**2, axis=-1, keepdims=True)
    usable = denominator[..., 0] > 0
    weight = weight / np.where(denominator > 0, denominator, 1.0)
    padding = [(0, 0)] * (target.ndim - 1) + [(0, points - target.shape[-1])]
    return np.pad(target, padding), np.pad(weight, padding), usable


def residuals(params, prob: Problem) -> jax.Array:
    """Residual vector whose squared norm is E of Eq. (6)."""
    return jnp.sqrt(prob.weight) * (evaluate_projected(params, prob.scene, prob.model)
                                    - prob.target)


def error(params, prob: Problem) -> jax.Array:
    """E of Eq. (6) as a fraction (the paper prints it in percent)."""
    return jnp.sum(prob.weight * (evaluate_projected(params, prob.scene, prob.model)
                                  - prob.target) ** 2)


def solve_linear(params, prob: Problem, bounds: Bounds):
    """The parameters that enter f_r linearly, at their best within the bounds, and E.

    At fixed nonlinear parameters ``f_r cos(tr) = sum_k c_k s_k`` (the model's
    `~brdfjax.models.Model.columns` times ``cos tr``), so E of Eq. (6) is a convex quadratic
    in the coefficients c, minimised over their box exactly, without iterating
    (`box_least_squares`: variable projection, Golub and Pereyra 1973). E follows from the
    weighted sums of the column products, without a second pass over the points.

    Each column is measured in units of its largest magnitude (the model is
    ``sum x_k s_k`` with ``x_k = c_k unit_k peak_k``), so that a huge ``exp(b ...)``
    balanced by a tiny kb (the five-parameter model on real black coatings) neither
    overflows nor loses precision in float32. Every sum takes one factor of each product
    already scaled (with the weight) and is scaled once more after, so that two tiny
    columns never multiply unscaled: unscaled squares underflowed for 16 % of random
    five-parameter members on a real black coating (EC1; ``b`` near its upper bound),
    scored infinite where float64 gives about 0.7 of E at zero (`tests/test_models.py`).
    The other factor is the column itself, so a model's columns (with their `units`) must
    keep the weight times their peak above float32's smallest normal number (1.2e-38;
    XLA:CPU flushes smaller products to zero): the five-parameter model's lobe is taken
    per unit ``exp(max(b - 40, 0))`` for that (`brdfjax.models.five.column_offset`). A
    scaled copy of each column made the genetic search of 716 points a fifth slower
    (BENCHMARKS.md, section batch), and so did forming each product from two scaled
    factors (12.0-13.1 against 9.6-10.4 ms, the best of six on one thread, when the column
    contract was set).
    The largest magnitude among every 8th point only, tried as a cheaper scale, failed on
    narrow lobes: Beckmann's at alpha 0.002 is 1e-167 there against 5.8e3 at its peak, and
    its scaled products overflowed even float64.

    Args:
        params: a parameter vector (P,) whose nonlinear entries are used.
        prob: the measurement set.
        bounds: the search box.

    Returns:
        (the parameter vector with its linear entries solved, E).
    """
    model = prob.model
    columns, units = model.columns(params, prob.scene, bounds)
    c, t, w = prob.scene.cos_theta_r, prob.target, prob.weight
    raw = [column * c for column in columns]
    inverse, to_x = [], []
    for s, unit in zip(raw, units):
        peak = jnp.max(jnp.abs(s))
        peak = jnp.where(peak > 0, peak, 1.0)
        inverse.append(1 / peak)
        to_x.append(unit * peak)
    count = len(raw)
    gram = [[None] * count for _ in range(count)]
    for i in range(count):
        for j in range(i, count):  # entry by entry: a column without parameters stays one,
            # and a product with it is a matrix product under vmap
            gram[i][j] = gram[j][i] = ((w * raw[j] * inverse[j]) @ raw[i]) * inverse[i]
    projections = [((w * t) @ s) * scale for s, scale in zip(raw, inverse)]
    to_x = jnp.stack([jnp.asarray(x, dtype=c.dtype) for x in to_x])
    low, high = model.coefficient_bounds(bounds)
    pairs = model.scale_sums(bounds)
    total = jnp.sum(w * t * t)
    # Up to two coefficients (the five-parameter model, Torrance-Sparrow, RPV) the 9 faces
    # are unrolled; beyond (GGX and Beckmann have three: 27 faces) the faces are arrays,
    # which traces and compiles in far less time with the same fits: GGX's and Beckmann's
    # cross-validation took 3.5-4.6 s of CPU from an empty cache instead of 5.1-7.2 s, and
    # their fits of the 15 real runs ended at the same E (3.6e-15).
    if count <= 2 and all(p[:2] == (0, 1) for p in pairs):
        pair = pairs[0] if pairs else None
        if pair is not None:  # x_0 / to_x_0 + x_1 / to_x_1 within the scale's bounds
            pair = ((1.0 / to_x[0], 1.0 / to_x[1]), *pair[2:])
        x, value = box_least_squares(gram, projections, total, low * to_x, high * to_x, pair)
    else:  # three coefficients or more, or several bounded sums (sums of models)
        pairs = [(i, j, 1.0 / to_x[i], 1.0 / to_x[j], s_low, s_high)
                 for i, j, s_low, s_high in pairs]
        x, value = polytope_least_squares(jnp.stack([jnp.stack(row) for row in gram]),
                                          jnp.stack(projections), total, low * to_x,
                                          high * to_x, pairs)
    coefficients = jnp.clip(x / to_x, low, high)
    return model.assemble(coefficients, params, bounds), value


# A free coordinate's pivot in the Cholesky factor below this fraction of its diagonal
# counts as singular (the columns are collinear within float32's precision).
PIVOT_TOLERANCE = 1e-6


def box_least_squares(gram, projections, total, low, high, pair=None):
    """Exact minimum of ``q(x) = total - 2 p.x + x.G.x`` over the box ``low <= x <= high``.

    q is a convex quadratic, so its minimum over a polytope is the unconstrained minimum of
    some face. In the box each coordinate is free, at its lower or at its upper bound: all
    ``3^K`` faces are tried (K, the number of linear coefficients, is at most 2 here: 9
    tiny solves, unrolled Cholesky factorisations), and the best face whose free solution
    lies inside the box wins. The faces with every coordinate at a bound always qualify.

    With ``pair = ((w0, w1), s_low, s_high)`` the first two coordinates are instead
    non-negative with ``s_low <= w0 x0 + w1 x1 <= s_high`` (the weights of a `mixture`,
    whose sum is a bounded scale). Their faces are the 9 of that trapezoid: its inside,
    its 4 edges (a weight 0, or the sum on a bound, with the other free) and its 4 corners.

    Args:
        gram: G as a K x K nested list of scalars; projections: p, K scalars; total: q(0).
        low, high: the box (K,).
        pair: the first two coordinates' constraint, or None.

    Returns:
        (x (K,), q(x) clipped at 0).
    """
    count = len(projections)
    candidates, values = [], []
    for coords, inside_of in _faces(count, low, high, pair):
        free = sorted({j for _, terms in coords for j in terms})
        anchor = [a for a, _ in coords]
        # x = a + B y over the free variables y: (B'GB) y = B'(p - G a)
        residual = [projections[k] - sum(gram[k][m] * anchor[m] for m in range(count)
                                          if not _is_zero(anchor[m])) for k in range(count)]
        reduced = [[sum(_times(coords[k][1][i] * coords[m][1][j], gram[k][m])
                        for k in range(count) if i in coords[k][1]
                        for m in range(count) if j in coords[m][1]) for j in free]
                   for i in free]
        rhs = [sum(_times(coords[k][1][i], residual[k]) for k in range(count)
                   if i in coords[k][1]) for i in free]
        solved, regular = cholesky_solve(reduced, rhs)
        y = dict(zip(free, solved))
        x = [a + sum(_times(b, y[j]) for j, b in terms.items()) for a, terms in coords]
        value = total - 2 * sum(projections[k] * x[k] for k in range(count)) + sum(
            gram[i][j] * x[i] * x[j] for i in range(count) for j in range(count))
        candidates.append(jnp.stack([jnp.asarray(v, dtype=jnp.result_type(total)) for v in x]))
        values.append(jnp.where(regular & inside_of(x) & ~jnp.isnan(value), value, jnp.inf))
    values = jnp.stack(values)
    best = jnp.argmin(values)
    return jnp.stack(candidates)[best], jnp.maximum(values[best], 0.0)


def polytope_least_squares(gram, projections, total, low, high, pairs=()):
    """`box_least_squares` for more coefficients and several bounded pairs, vectorised.

    The same exact method (a convex quadratic's minimum over a polytope is the free minimum
    of one of its faces; every face is tried and the best one whose solution is feasible
    wins), with the faces as arrays rather than unrolled code, so that a sum of models
    (``ggx+ggx``: 5 coefficients, two bounded pairs, 243 faces) compiles in about the time
    of one face. Each coordinate outside a pair is free, at its lower or at its upper bound;
    each pair ``(i, j, w_i, w_j, s_low, s_high)`` (``x_i, x_j >= 0``, ``s_low <= w_i x_i +
    w_j x_j <= s_high``) takes one of its 9 faces (`_pair_faces`).

    Args:
        gram: G (K, K); projections: p (K,); total: q(0).
        low, high: the box (K,) of the coordinates outside the pairs.
        pairs: the bounded pairs.

    Returns:
        (x (K,), q(x) clipped at 0).
    """
    count = projections.shape[0]
    dtype = jnp.result_type(total)
    paired = {k for i, j, *_ in pairs for k in (i, j)}
    # The faces' structure is static (NumPy); their numbers come from two short traced
    # vectors: ``values`` (anchors: 0, the bounds, each pair's corners) and ``ratios`` (the
    # slope -w_i / w_j of each pair's sum edge), so that the traced graph stays small.
    values = [jnp.asarray(0.0, dtype)] + [low[k] for k in range(count)] + [
        high[k] for k in range(count)]
    ratios = [jnp.asarray(1.0, dtype)]
    # Each coordinate's options: (coordinate, anchor's index in values, {free variable:
    # index in ratios}, checks), a check being (kind, coordinate or pair number): kind 0
    # low <= x_k <= high, 1 x_k >= 0, 2 the pair's sum within its bounds.
    choices = []
    for k in range(count):
        if k not in paired:
            choices.append([[(k, 0, {k: 0}, [(0, k)])], [(k, 1 + k, {}, [])],
                            [(k, 1 + count + k, {}, [])]])
    for number, (i, j, w_i, w_j, s_low, s_high) in enumerate(pairs):
        ratios.append(-w_i / w_j)
        slope = len(ratios) - 1
        faces = [[(i, 0, {i: 0}, [(1, i)]), (j, 0, {j: 0}, [(1, j), (2, number)])],
                 [(i, 0, {}, []), (j, 0, {j: 0}, [(1, j), (2, number)])],
                 [(i, 0, {i: 0}, [(1, i), (2, number)]), (j, 0, {}, [])]]
        for s in (s_low, s_high):
            values += [s / w_j, s / w_i]
            on_j, on_i = len(values) - 2, len(values) - 1
            faces.append([(i, 0, {i: 0}, [(1, i)]), (j, on_j, {i: slope}, [(1, j)])])
            faces.append([(i, 0, {}, []), (j, on_j, {}, [])])
            faces.append([(i, on_i, {}, []), (j, 0, {}, [])])
        choices.append(faces)
    kinds = [(0, k) for k in range(count)] + [(1, k) for k in range(count)] + [
        (2, n) for n in range(len(pairs))]
    faces = list(itertools.product(*choices))
    # Every coordinate has one anchor, and every free variable v enters x through
    # coordinate v (ratio 1) and at most one other, its ``partner`` (a pair's sum edge:
    # x_j = s / w_j + slope y_i): B's column v is ``e_v + slope e_partner``. So B'GB and
    # B'r are picks of G's entries, not products with a dense B (F x K^3 work for the
    # population's every member: most of a sum's search time before).
    anchor_of = np.zeros((len(faces), count), dtype=int)
    free = np.zeros((len(faces), count), dtype=bool)
    partner = np.tile(np.arange(count), (len(faces), 1))
    slope_of = np.full((len(faces), count), len(ratios))  # the index of 0 in `ratios` below
    checks = np.zeros((len(faces), len(kinds)), dtype=bool)
    for f, face in enumerate(faces):
        for k, anchor, terms, wanted in (e for group in face for e in group):
            anchor_of[f, k] = anchor
            for variable, ratio in terms.items():
                free[f, variable] = True
                if variable != k:  # (on its own coordinate a variable's ratio is 1)
                    assert partner[f, variable] == variable, "a variable has one partner"
                    partner[f, variable], slope_of[f, variable] = k, ratio
            for check in wanted:
                checks[f, kinds.index(check)] = True
    # Every face-dependent quantity below is one (F,) vector per coordinate (or per entry
    # of a K x K matrix), and each face's choice among a few traced numbers is a chain of
    # selects on the static structure (`_pick`): XLA:CPU fuses the face algebra into a few
    # elementwise loops, where gathers, (F, K, K) tensors and short reductions under the
    # population's vmap took 4.8x as long for ggx+ggx and 2.9x for ggx+backscatter
    # (scoring 128 members on 120 points: 9.2 -> 1.9 ms and 2.6 -> 0.9 ms).
    values = [jnp.asarray(v, dtype) for v in values]
    ratios = [jnp.asarray(r, dtype) for r in ratios] + [jnp.asarray(0.0, dtype)]
    columns = range(count)
    anchors = [_pick(values, anchor_of[:, k]) for k in columns]
    slopes = [_pick(ratios, slope_of[:, v]) for v in columns]
    pinned = ~free
    # x = a + B y; (B'GB) y = B'(p - G a) over the free y (the others pinned to 0).
    gram_bases = [[gram[k, v] + slopes[v] * _pick(gram[k], partner[:, v]) for v in columns]
                  for k in columns]                                          # G B
    reduced = [[gram_bases[i][j] + slopes[i] * _pick([row[j] for row in gram_bases],
                                                     partner[:, i]) for j in columns]
               for i in columns]
    reduced = [[jnp.where(pinned[:, i] | pinned[:, j], 0.0, reduced[i][j]) for j in columns]
               for i in columns]
    diagonal = [reduced[i][i] for i in columns]
    for i in columns:
        reduced[i][i] = reduced[i][i] + jnp.asarray(pinned[:, i], dtype)
    residual = [projections[j] - _total(anchors[k] * gram[k, j] for k in columns)
                for j in columns]
    rhs = [jnp.where(free[:, i], residual[i] + slopes[i] * _pick(residual, partner[:, i]), 0.0)
           for i in columns]
    # Cholesky unrolled over the K coordinates, vectorised over the faces: no LAPACK call
    # (LAPACK's custom calls were seen to hang XLA on CPU with several threads or devices,
    # see `brdfjax.fitting.polish`; this is as fast for K <= 7).
    y, pivots = cholesky_solve(reduced, rhs, with_pivots=True)
    y = [jnp.where(free[:, v], y[v], 0.0) for v in columns]
    regular = functools.reduce(operator.and_, (
        pinned[:, i] | (pivots[i] > PIVOT_TOLERANCE * diagonal[i]) for i in columns))
    x = [_total([anchors[k] + y[k]] + [jnp.where(partner[:, v] == k, slopes[v] * y[v], 0.0)
                                       for v in columns if v != k and np.any(partner[:, v] == k)])
         for k in columns]  # a pair's sum edge also moves the free variable's partner
    # Formed once: without the barrier XLA fused x's whole chain (the Cholesky included)
    # into each of its consumers below and computed it again in each (twice the time).
    x, regular = jax.lax.optimization_barrier((x, regular))
    satisfied = [(x[k] >= low[k]) & (x[k] <= high[k]) for k in columns]  # kind 0
    satisfied += [x[k] >= 0 for k in columns]  # kind 1
    sums = [w_i * x[i] + w_j * x[j] for i, j, w_i, w_j, *_ in pairs]
    satisfied += [(total_ >= p[4]) & (total_ <= p[5]) for total_, p in zip(sums, pairs)]  # kind 2
    inside = functools.reduce(operator.and_, (
        ~checks[:, c] | satisfied[c] for c in range(len(kinds)) if np.any(checks[:, c])))
    value = total - 2 * _total(x[k] * projections[k] for k in columns) + _total(
        x[i] * _total(x[j] * gram[i, j] for j in columns) for i in columns)
    value = jnp.where(regular & inside & ~jnp.isnan(value), value, jnp.inf)
    best = jnp.argmin(value)
    return jnp.stack([x_k[best] for x_k in x]), jnp.maximum(value[best], 0.0)


def _pick(options, index):
    """``options[index]`` for a static integer array ``index`` (F,): a chain of selects
    among the few options it names (each a number or an (F,) array), not a gather."""
    chosen = np.unique(index)
    picked = options[chosen[0]]
    for d in chosen[1:]:
        picked = jnp.where(index == d, options[d], picked)
    return jnp.broadcast_to(picked, index.shape)


def _total(terms):
    """The sum of a few arrays, term by term: elementwise additions, which XLA:CPU fuses,
    where its reduction over a short axis of a large array (K <= 7 here) ran several
    times slower."""
    return functools.reduce(operator.add, terms)


def _is_zero(value) -> bool:
    return isinstance(value, float) and value == 0.0


def _times(coefficient, value):
    """``coefficient * value``, without an operation where the coefficient is the number 1."""
    return value if isinstance(coefficient, float) and coefficient == 1.0 else coefficient * value


def _faces(count, low, high, pair):
    """The faces of `box_least_squares`' polytope: for each, every coordinate as
    ``(constant, {free variable: coefficient})`` and a function of the solved x that says
    whether the free solution lies inside the polytope."""
    boxed = range(2 if pair is not None else 0, count)
    box_states = []
    for k in boxed:  # free, at the lower bound, at the upper bound
        box_states.append([((0.0, {k: 1.0}), lambda x, k=k: (x[k] >= low[k]) & (x[k] <= high[k])),
                           ((low[k], {}), None), ((high[k], {}), None)])
    pair_states = [[]] if pair is None else _pair_faces(*pair)
    for first in pair_states:
        for rest in itertools.product(*box_states):
            states = list(first) + list(rest)
            coords = [coord for coord, _ in states]
            checks = [check for _, check in states if check is not None]

            def inside_of(x, checks=checks):
                inside = jnp.asarray(True)
                for check in checks:
                    inside = inside & check(x)
                return inside

            yield coords, inside_of


def _pair_faces(weights, s_low, s_high):
    """The 9 faces of ``x0, x1 >= 0, s_low <= w0 x0 + w1 x1 <= s_high`` (variables 0, 1)."""
    w0, w1 = weights

    def sum_inside(x):
        total = w0 * x[0] + w1 * x[1]
        return (total >= s_low) & (total <= s_high)

    inside = [(((0.0, {0: 1.0}), None), ((0.0, {1: 1.0}),
               lambda x: (x[0] >= 0) & (x[1] >= 0) & sum_inside(x)))]
    edges = [(((0.0, {}), None), ((0.0, {1: 1.0}), sum_inside)),
             (((0.0, {0: 1.0}), sum_inside), ((0.0, {}), None))]
    for s in (s_low, s_high):  # the sum on a bound: x1 = (s - w0 x0) / w1, both >= 0
        edges.append((((0.0, {0: 1.0}), lambda x: (x[0] >= 0) & (x[1] >= 0)),
                      ((s / w1, {0: -w0 / w1}), None)))
    corners = [(((0.0, {}), None), ((s / w1, {}), None)) for s in (s_low, s_high)]
    corners += [(((s / w0, {}), None), ((0.0, {}), None)) for s in (s_low, s_high)]
    return inside + edges + corners


def cholesky_solve(matrix, rhs, with_pivots=False):
    """Solve a small SPD system given as nested lists (unrolled); also whether it is regular
    (or, ``with_pivots``, each pivot, for the caller to judge)."""
    size = len(rhs)
    factor = [[None] * size for _ in range(size)]
    regular = jnp.asarray(True)
    pivots = []
    for j in range(size):
        pivot = matrix[j][j] - sum(factor[j][k] ** 2 for k in range(j))
        pivots.append(pivot)
        regular = regular & (pivot > PIVOT_TOLERANCE * matrix[j][j])
        root = jnp.sqrt(jnp.where(pivot > 0, pivot, 1.0))
        factor[j][j] = root
        for i in range(j + 1, size):
            factor[i][j] = (matrix[i][j] - sum(factor[i][k] * factor[j][k]
                                               for k in range(j))) / root
    forward = []
    for i in range(size):
        forward.append((rhs[i] - sum(factor[i][k] * forward[k] for k in range(i)))
                       / factor[i][i])
    solution = [None] * size
    for i in reversed(range(size)):
        solution[i] = (forward[i] - sum(factor[k][i] * solution[k]
                                        for k in range(i + 1, size))) / factor[i][i]
    return (solution, pivots) if with_pivots else (solution, regular)
