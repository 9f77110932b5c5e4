"""What every BRDF model provides to the engine: names, search box, geometry, formula.

A model is a small frozen dataclass (hashable, so it is a static part of every compiled
function: jit, vmap and grad see it as a pytree without leaves) that declares:

- `Model.parameters`: each parameter's name, default search range, the scale it is
  searched on (``linear``, ``log10`` or ``asinh``) and the reason for that range;
- `Model.geometry`: the parameter-free terms it needs at each measurement point
  (precomputed once per data set, so a model pays only for what it uses);
- `Model.evaluate`: f_r in 1/sr from a parameter vector and that geometry;
- `Model.columns`, `Model.coefficient_bounds` and `Model.assemble`: the split into
  coefficients that enter f_r linearly and the other parameters, so that the genetic
  search solves the linear ones exactly and searches only the others (variable
  projection, Golub and Pereyra 1973);
- optionally `Model.extra_starts` (polish starts of its own) and `Model.peak` (where the
  reflectance quadrature should put its densest nodes);
- for sums of models (`brdfjax.models.sum`): `Model.constant` (an additive constant term,
  kept once in a sum), `Model.scales` (the parameters that switch the model off when all
  sit at their lower bounds) and `Model.order_by` (which orders two lobes of one kind).

Nothing in the engine (objective, search, polish, uncertainty, batch) knows which model
it runs. Adding a model is one new module in `brdfjax.models` with a `Model` subclass.
"""

from __future__ import annotations

import collections
import dataclasses
from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np


@dataclass(frozen=True)
class Parameter:
    """One model parameter: its name, default search range and scale, and why.

    Attributes:
        name: the name used in files, arrays, JSON and tables.
        low, high: the default search range.
        scale: ``linear``, ``log10`` (positive parameters spanning decades) or ``asinh``
            (either sign, linear near zero and logarithmic beyond 1).
        reason: why this range (shown in the docs and ``brdfjax models --help``).
        limits: the range the parameter can physically take, where it has one (a
            reflectance: 0 to 1), or None: no ``--bound`` may pass it
            (`brdfjax.models.bounds.make_bounds`), and a fit at it is not told to widen.
    """

    name: str
    low: float
    high: float
    scale: str
    reason: str
    limits: tuple[float, float] | None = None


# The physical range of a weight, an albedo, a width or a roughness (`Parameter.limits`):
# no negative values (a positive one searched in log10 keeps a positive lower bound).
NON_NEGATIVE = (0.0, float("inf"))


def limits_text(limits: tuple[float, float]) -> str:
    """A physical range in words: ``0 to 1``, ``0 and above``, ``2 and below``."""
    low, high = (float(x) for x in limits)
    if np.isfinite(low) and np.isfinite(high):
        return f"{low:g} to {high:g}"
    if np.isfinite(low):
        return f"{low:g} and above"
    return f"{high:g} and below" if np.isfinite(high) else "any value"


def array_module(*values):
    """``jax.numpy`` if any value holds a JAX array (or tracer), else ``numpy``.

    Host-side bookkeeping (a parameter vector, a bounds transform) then runs in NumPy: in a
    new process every JAX operation outside a compiled stage costs a compilation.
    """
    return jnp if any(isinstance(v, jax.Array) for v in jax.tree.leaves(values)) else np


def as_vector(params):
    """A parameter vector (first axis: the model's parameters, as every model reads it) from
    a named tuple or array; a named tuple of arrays (N,) gives (P, N), N parameter sets."""
    if isinstance(params, tuple):  # a model's Params named tuple
        xp = array_module(*params)
        return xp.stack([xp.asarray(x) for x in params], axis=0)
    return array_module(params).asarray(params)


class Model:
    """The interface every BRDF model implements (subclass it as a frozen dataclass).

    Class attributes:
        name: the model's name on the command line and in files (``ggx``).
        summary: one line on when to use it.
        parameters: the `Parameter` s, in the order of every parameter vector.
        linear: names of the coefficients that enter f_r linearly (see `columns`).
        peak: ``backscatter`` or ``specular``: where f_r may be sharply peaked, for the
            reflectance quadrature of Eq. (9); ``none`` for smooth models.
        Params: a named tuple of the parameters (made from `parameters` if not given).
        constant: the name of a parameter that is an additive constant of f_r (``kd``), or
            None; it must also be a name of `linear`. A sum keeps one such term only.
        scales: the parameters that scale the model: all at their lower bounds, the model
            contributes (almost) nothing, and in a sum its shape is then unidentified.
        order_by: the parameter that orders two parts of this kind in a sum (the narrower
            lobe first), or None.
    """

    name: ClassVar[str]
    summary: ClassVar[str]
    parameters: ClassVar[tuple[Parameter, ...]]
    linear: ClassVar[tuple[str, ...]]
    peak: ClassVar[str] = "none"
    Params: ClassVar[type]
    constant: ClassVar[str | None] = None
    scales: ClassVar[tuple[str, ...]] = ()
    order_by: ClassVar[str | None] = None

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if "Params" not in cls.__dict__ and isinstance(cls.__dict__.get("parameters"), tuple):
            cls.Params = collections.namedtuple(
                f"{cls.__name__}Params", [p.name for p in cls.parameters])
        jax.tree_util.register_static(cls)  # a static pytree: hashable, no leaves

    @property
    def names(self) -> tuple[str, ...]:
        """The parameter names, in order."""
        return tuple(p.name for p in self.parameters)

    @property
    def size(self) -> int:
        """The number of parameters."""
        return len(self.parameters)

    @property
    def searched_size(self) -> int:
        """How many parameters the search explores; the linear solve sets the others (one
        per linear coefficient)."""
        return self.size - len(self.linear)

    def index(self, name: str) -> int:
        """The position of parameter ``name`` in a parameter vector."""
        return self.names.index(name)

    def geometry(self, theta_i, theta_r, phi_r, in_plane: bool) -> NamedTuple:
        """The parameter-free terms at broadcast angle arrays (radians).

        Returns a named tuple of arrays of one shape with at least a ``cos_theta_r`` field
        (the projection of Eq. 6), each value computed from its own point's angles alone
        (`brdfjax.fitting.objective.prepare` pads the points and cuts the copies off).
        ``in_plane`` is True when every ``phi_r`` is 0 or pi, where a model may use exact
        closed forms.
        """
        raise NotImplementedError

    def evaluate(self, params, geometry) -> jax.Array:
        """f_r (1/sr) from a parameter vector (P,) on this model's geometry."""
        raise NotImplementedError

    def columns(self, params, geometry, bounds) -> tuple[list, list]:
        """The linear split: ``f_r = sum_k c_k unit_k column_k`` at fixed other parameters.

        The coefficients' box (`coefficient_bounds`) should map into the parameters' box
        through `assemble` (a column may depend on ``bounds`` for that: RPV's), so that E
        of the solved coefficients is E of the assembled parameters. Where a scale is the
        sum of two coefficients (`mixture`), `scale_sum` bounds that sum.

        Returns:
            ``(columns, units)``: K arrays with the geometry's shape, and K scalars. The
            coefficients ``c_k`` are those of `coefficient_bounds` and `assemble`;
            ``units`` lets a model return a rescaled column (one that would overflow
            otherwise), 1 elsewhere. The genetic search solves in float32 and multiplies
            each column by the points' weights before scaling it: where a column matters,
            its peak should stay well within float32's range, about 1e-20 to 1e20
            (`brdfjax.fitting.objective.solve_linear`).
        """
        raise NotImplementedError

    def coefficient_bounds(self, bounds) -> tuple:
        """Bounds (K,), (K,) of the linear coefficients from the parameters' `Bounds`."""
        raise NotImplementedError

    def assemble(self, coefficients, params, bounds):
        """The parameter vector (P,) with its linear part set from ``coefficients`` (K,)."""
        raise NotImplementedError

    def scale_sum(self, bounds):
        """Bounds (low, high) of the sum of the first two coefficients, where they are the
        weights of a `mixture` whose sum is a bounded scale (RPV's rho0, GGX's ks); None
        where no coefficients sum to a parameter."""

    def scale_sums(self, bounds) -> list:
        """Every constrained pair of coefficients: ``[(i, j, low, high)]``, the weights
        ``i`` and ``j`` of a `mixture` whose sum lies in [low, high]; from `scale_sum` (the
        first two coefficients) unless a model has several (a sum of models)."""
        pair = self.scale_sum(bounds)
        return [] if pair is None else [(0, 1, *pair)]

    def components(self, params) -> list:
        """``[(model, params)]`` whose f_r add up to this model's: the model itself, or the
        parts of a sum (the reflectance integrates each around its own peak)."""
        return [(self, params)]

    def canonical(self, params, bounds):
        """The one parameter vector (P,) of the equivalent ones that the fit reports (a sum
        orders its lobes of one kind); ``params`` itself by default."""
        return params

    def idle_parts(self, params, bounds) -> list[str]:
        """Sentences on parts of the model whose weight is zero (none but in a sum)."""
        return []

    def extra_starts(self, z, bounds):
        """More polish starts (E, P) in unit-cube coordinates, made from the best member
        ``z`` (1, P); none by default."""
        return z[:0]

    def with_constants(self, constants) -> Model:
        """This model with other shadowing constants (a model with a G term keeps them in a
        ``constants`` field; the others take none)."""
        if not hasattr(self, "constants"):
            raise ValueError(f"the {self.name} model has no shadowing constants to set")
        return dataclasses.replace(self, constants=type(self.constants)(*constants))


class ScaledShape(Model):
    """A model that is one weight times a shape, ``f_r = w shape(other parameters)``, its
    weight the first parameter and its only linear coefficient (Lambert, ABg, the
    back-scatter lobe). A subclass gives `shape`; the linear split follows from it."""

    def shape(self, params, geometry) -> jax.Array:
        """f_r of unit weight at the other parameters of ``params`` (P,)."""
        raise NotImplementedError

    def evaluate(self, params, geometry):
        return params[0] * self.shape(params, geometry)

    def columns(self, params, geometry, bounds):
        return [self.shape(params, geometry)], [1.0]

    def coefficient_bounds(self, bounds):
        return bounds.lower[:1], bounds.upper[:1]

    def assemble(self, coefficients, params, bounds):
        return params.at[0].set(coefficients[0])


def broadcast_angles(theta_i, theta_r, phi_r):
    """The three angle arrays broadcast to one shape, in one floating dtype (float64 unless
    all are float32)."""
    dtype = jnp.result_type(float, theta_i, theta_r, phi_r)
    return jnp.broadcast_arrays(*(jnp.asarray(x, dtype=dtype) for x in (theta_i, theta_r, phi_r)))


def safe_divide(numerator, denominator, where, fallback):
    """numerator / denominator where ``where``, else ``fallback``, with finite gradients."""
    safe = jnp.where(where, denominator, 1.0)
    return jnp.where(where, numerator / safe, fallback)


def mixture(at_low, at_high, low, high, fallback):
    """A scale and a parameter from the weights of a model at the two ends of that
    parameter's range.

    Where the parameter enters as ``scale (A + parameter B)`` (GGX's ``ks`` and ``f0``,
    RPV's ``rho0`` and ``rhoc``), the model is ``at_low`` times its value at the parameter's
    lower bound plus ``at_high`` times its value at the upper. Both weights non-negative is
    exactly the parameter within its bounds, so the linear solve's box keeps it there; the
    solve keeps the scale in its bounds through `Model.scale_sum` (the caller clips it
    against rounding only).

    Returns:
        (scale = at_low + at_high, the parameter: the weights' mean of its bounds, clipped;
        ``fallback`` where both weights are 0).
    """
    scale = at_low + at_high
    value = safe_divide(at_low * low + at_high * high, scale, scale > 0, fallback)
    return scale, jnp.clip(value, low, high)


def safe_sqrt(x):
    """sqrt(x) with a zero (not infinite) derivative at x = 0."""
    positive = x > 0
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, x, 1.0)), 0.0)


class PhaseTerms(NamedTuple):
    """The trigonometry of two directions ``w_i = (sin ti, 0, cos ti)`` and
    ``w_r = (sin tr cos pr, sin tr sin pr, cos tr)`` and of the phase angle g between them.

    Attributes:
        cos_i, sin_i, cos_r, sin_r, cos_p, sin_p: of ti, tr and pr.
        cos_phase: ``cos g = w_i . w_r``.
        cross2: ``|w_i x w_r|^2 = sin^2 g``, a sum of squares: exact near g = 0, where
            ``1 - cos^2 g`` cancels.
    """

    cos_i: jax.Array
    sin_i: jax.Array
    cos_r: jax.Array
    sin_r: jax.Array
    cos_p: jax.Array
    sin_p: jax.Array
    cos_phase: jax.Array
    cross2: jax.Array


def phase_terms(theta_i, theta_r, phi_r) -> PhaseTerms:
    """`PhaseTerms` at broadcastable angles in radians (models peaked at the source: the
    back-scatter lobe, Ross-Li's kernels)."""
    theta_i, theta_r, phi_r = broadcast_angles(theta_i, theta_r, phi_r)
    cos_i, sin_i = jnp.cos(theta_i), jnp.sin(theta_i)
    cos_r, sin_r = jnp.cos(theta_r), jnp.sin(theta_r)
    cos_p, sin_p = jnp.cos(phi_r), jnp.sin(phi_r)
    cos_phase = cos_i * cos_r + sin_i * sin_r * cos_p
    cross2 = ((cos_i * sin_r * sin_p) ** 2 + (cos_i * sin_r * cos_p - sin_i * cos_r) ** 2
              + (sin_i * sin_r * sin_p) ** 2)
    return PhaseTerms(cos_i, sin_i, cos_r, sin_r, cos_p, sin_p, cos_phase, cross2)
