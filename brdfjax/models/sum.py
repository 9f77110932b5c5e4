"""Sums of models: ``A+B`` is the model ``f_r = f_A + f_B``, built from the parts' interfaces.

``brdfjax.models.get("ggx+backscatter")`` (or ``--model ggx+backscatter``) gives a `Sum`: a
model like any other, whose parameter vector is the parts' vectors concatenated; nothing in
the engine knows it is a sum (the idea of ALTA's compound functions). brdfjax's rules, as
the docs' Models page (``docs/models.md``, "Sums of models") shows them:

- A part's parameters keep their names; where a name repeats, the later part's gets
  ``_2``, ``_3`` (the name's second, third occurrence): ``ggx+ggx`` is ks, alpha, f0, kd,
  ks_2, alpha_2, f0_2.
- A constant term that two parts carry (`Model.constant`: ``kd``) is kept once, in the
  first part that has one; the later parts' constants are 0 (two would make the linear
  solve degenerate). A part left with no parameters (``ggx+lambert``'s lambert) is refused.
- Every part's linear coefficients are the sum's (their columns side by side), solved
  together and exactly inside the search (`brdfjax.fitting.objective.solve_linear`, including each
  part's bounded-sum constraints, `Model.scale_sums`); the parts' nonlinear parameters are
  searched together.

Two lobes of one kind (two equal parts: ``ggx+ggx``) can swap roles without changing f_r.
The search does not care; the result is made unique after the fit (`Sum.canonical`): the
equal parts are ordered by their `Model.order_by` parameter, ascending (``alpha <=
alpha_2``: the narrower GGX lobe first), with the shared constant left where it is. The swap
is made only where the two parts' boxes are the same (the defaults), so that the reported
vector stays inside its box. When a part's weight is zero (every parameter of its
`Model.scales` at its lower bound), its shape parameters are not determined by the data:
`Sum.idle_parts` says so, and the Laplace and emcee outputs carry it as a warning.

The reflectance of Eq. (9) integrates each part around its own peak (`Sum.components`):
a specular lobe plus a back-scatter lobe has two.
"""

from __future__ import annotations

import collections
import dataclasses
import functools
from dataclasses import dataclass
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from brdfjax.models.base import Model, array_module
from brdfjax.models.bounds import to_unit


class SumGeometry(NamedTuple):
    """The geometry of a sum: each distinct part's own geometry, and the projection.

    Attributes:
        parts: one geometry per distinct part (equal parts share one), in part order.
        cos_theta_r: the projection of Eq. (6).
    """

    parts: tuple
    cos_theta_r: jnp.ndarray


class _Layout(NamedTuple):
    """Where each part's parameters and coefficients sit in the sum's (host constants)."""

    parameters: tuple        # the sum's `Parameter` s
    index: tuple             # per part: the sum's position of each part parameter, or None
    columns: tuple           # per part: the part's coefficient positions the sum keeps
    offsets: tuple           # per part: the sum's position of its first kept coefficient
    dropped: tuple           # per part: the coefficient position of its dropped constant, or None
    geometry: tuple          # per part: which `SumGeometry.parts` entry it reads


@functools.cache
def _params_type(sum_name: str, names: tuple) -> type:
    """The named tuple of one sum's parameters, named after the sum (``ggx+backscatter``:
    ``GgxPlusBackscatterParams``), so that another sum's of the same names is told apart."""
    title = "Plus".join(part.title().replace("-", "") for part in sum_name.split("+"))
    return collections.namedtuple(f"{title}Params", names, rename=True)


@dataclass(frozen=True)
class Sum(Model):
    """The sum of two or more models (see the module docstring)."""

    parts: tuple

    def __post_init__(self):
        if len(self.parts) < 2:
            raise ValueError("a sum of models needs at least two parts, e.g. ggx+backscatter")
        for part in self.parts:
            if not isinstance(part, Model):
                raise TypeError(f"a part of a sum must be a brdfjax.models.Model, got {part!r}")
        self._layout  # noqa: B018  (refuses a part left with nothing, at construction)

    # ---- what the engine reads from any model

    @property
    def name(self) -> str:
        return "+".join(part.name for part in self.parts)

    @property
    def summary(self) -> str:
        return "the sum of " + " and ".join(part.name for part in self.parts)

    @property
    def parameters(self) -> tuple:
        return self._layout.parameters

    @property
    def linear(self) -> tuple:
        return tuple(f"{part.linear[c]} ({part.name}, part {k + 1})"
                     for k, part in enumerate(self.parts) for c in self._layout.columns[k])

    @property
    def peak(self) -> str:
        peaks = {part.peak for part in self.parts} - {"none"}
        return peaks.pop() if len(peaks) == 1 else "none" if not peaks else "mixed"

    @property
    def Params(self) -> type:
        return _params_type(self.name, self.names)

    @property
    def constant(self):
        for k, part in enumerate(self.parts):
            if part.constant is not None and self._layout.dropped[k] is None:
                return self.names[self._layout.index[k][part.index(part.constant)]]
        return None

    @functools.cached_property
    def _layout(self) -> _Layout:
        counts = collections.Counter()
        parameters, index, columns, offsets, dropped, geometry = [], [], [], [], [], []
        has_constant, offset = False, 0
        for k, part in enumerate(self.parts):
            drop = part.constant if part.constant is not None and has_constant else None
            has_constant = has_constant or part.constant is not None
            positions = []
            for parameter in part.parameters:
                if parameter.name == drop:
                    positions.append(None)
                    continue
                counts[parameter.name] += 1
                count = counts[parameter.name]
                name = parameter.name if count == 1 else f"{parameter.name}_{count}"
                positions.append(len(parameters))
                parameters.append(dataclasses.replace(parameter, name=name))
            if all(p is None for p in positions):
                raise ValueError(f"{self.name}: the part {part.name} adds nothing (its "
                                 f"constant {drop} is already an earlier part's)")
            dropped_column = None if drop is None else part.linear.index(drop)
            kept = tuple(c for c in range(len(part.linear)) if c != dropped_column)
            index.append(tuple(positions))
            columns.append(kept)
            offsets.append(offset)
            dropped.append(dropped_column)
            offset += len(kept)
            geometry.append(next(j for j in range(k + 1) if self.parts[j] == part))
        distinct = sorted(set(geometry))
        geometry = [distinct.index(g) for g in geometry]
        return _Layout(tuple(parameters), tuple(index), tuple(columns), tuple(offsets),
                       tuple(dropped), tuple(geometry))

    # ---- the parts' views of the sum's vectors

    def part_vector(self, k: int, vector, fill=0.0):
        """Part ``k``'s parameter vector (last axis) from the sum's: its dropped constant
        is ``fill``."""
        xp = array_module(vector)
        vector = xp.asarray(vector)
        positions = self._layout.index[k]
        take = np.array([0 if p is None else p for p in positions])
        gathered = vector[..., take]
        if all(p is not None for p in positions):
            return gathered
        missing = np.array([p is None for p in positions])
        return xp.where(missing, xp.asarray(fill, dtype=gathered.dtype), gathered)

    def part_bounds(self, k: int, bounds):
        """Part ``k``'s `Bounds` (its dropped constant boxed to [0, 0] on a linear scale)."""
        return type(bounds)(self.part_vector(k, bounds.lower), self.part_vector(k, bounds.upper),
                            self.part_vector(k, bounds.scale, fill=0))

    def _scatter(self, k: int, vector, part_vector):
        """``vector`` with part ``k``'s entries set from ``part_vector``."""
        positions = self._layout.index[k]
        keep = [j for j, p in enumerate(positions) if p is not None]
        target = np.array([positions[j] for j in keep])
        return vector.at[..., target].set(part_vector[..., np.array(keep)])

    # ---- the Model interface

    def geometry(self, theta_i, theta_r, phi_r, in_plane):
        owners = sorted({self.parts.index(part) for part in self.parts})
        parts = tuple(self.parts[j].geometry(theta_i, theta_r, phi_r, in_plane) for j in owners)
        return SumGeometry(parts, parts[0].cos_theta_r)

    def evaluate(self, params, geometry):
        params = jnp.asarray(params)
        return sum(part.evaluate(self.part_vector(k, params),
                                 geometry.parts[self._layout.geometry[k]])
                   for k, part in enumerate(self.parts))

    def columns(self, params, geometry, bounds):
        params = jnp.asarray(params)
        columns, units = [], []
        for k, part in enumerate(self.parts):
            c, u = part.columns(self.part_vector(k, params),
                                geometry.parts[self._layout.geometry[k]],
                                self.part_bounds(k, bounds))
            columns += [c[j] for j in self._layout.columns[k]]
            units += [u[j] for j in self._layout.columns[k]]
        return columns, units

    def coefficient_bounds(self, bounds):
        lows, highs = [], []
        for k, part in enumerate(self.parts):
            low, high = part.coefficient_bounds(self.part_bounds(k, bounds))
            kept = np.array(self._layout.columns[k])
            lows.append(jnp.asarray(low)[kept])
            highs.append(jnp.asarray(high)[kept])
        return jnp.concatenate(lows), jnp.concatenate(highs)

    def scale_sums(self, bounds) -> list:
        pairs = []
        for k, part in enumerate(self.parts):
            kept = self._layout.columns[k]
            for i, j, low, high in part.scale_sums(self.part_bounds(k, bounds)):
                pairs.append((self._layout.offsets[k] + kept.index(i),
                              self._layout.offsets[k] + kept.index(j), low, high))
        return pairs

    def scale_sum(self, bounds):
        pairs = self.scale_sums(bounds)
        if len(pairs) == 1 and pairs[0][:2] == (0, 1):
            return pairs[0][2:]
        return None

    def assemble(self, coefficients, params, bounds):
        params = jnp.asarray(params)
        result = params
        for k, part in enumerate(self.parts):
            layout = self._layout
            size = len(layout.columns[k])
            mine = coefficients[layout.offsets[k]:layout.offsets[k] + size]
            if layout.dropped[k] is not None:  # the dropped constant's coefficient is 0
                mine = jnp.insert(mine, layout.dropped[k], 0.0)
            assembled = part.assemble(mine, self.part_vector(k, params),
                                      self.part_bounds(k, bounds))
            result = self._scatter(k, result, jnp.asarray(assembled))
        return result

    def extra_starts(self, z, bounds):
        """Each part's own extra starts, the other parts' coordinates kept."""
        starts = [z[:0]]
        for k, part in enumerate(self.parts):
            extra = part.extra_starts(self.part_vector(k, z, fill=0.5), self.part_bounds(k, bounds))
            if extra.shape[0]:
                starts.append(self._scatter(k, jnp.broadcast_to(z[:1], (extra.shape[0],)
                                                                + z.shape[1:]), extra))
        return jnp.concatenate(starts)

    def with_constants(self, constants) -> Model:
        if not any(hasattr(part, "constants") for part in self.parts):
            raise ValueError(f"no part of {self.name} has shadowing constants to set")
        return Sum(tuple(part.with_constants(constants) if hasattr(part, "constants") else part
                         for part in self.parts))

    def components(self, params) -> list:
        params = array_module(params).asarray(params)
        return [(part, self.part_vector(k, params)) for k, part in enumerate(self.parts)]

    def _groups(self) -> list[list[int]]:
        """Equal parts with an `Model.order_by` parameter, by part index."""
        groups = collections.defaultdict(list)
        for k, part in enumerate(self.parts):
            if part.order_by is not None:
                groups[part].append(k)
        return [g for g in groups.values() if len(g) > 1]

    def canonical(self, params, bounds):
        """Equal parts ordered by their `Model.order_by` parameter (ascending; see the
        module docstring); host arrays."""
        vector = np.array(params, dtype=float)
        lower, upper = np.asarray(bounds.lower), np.asarray(bounds.upper)
        for group in self._groups():
            # the positions each part of the group owns, its shared constant excluded
            part = self.parts[group[0]]
            movable = [j for j, p in enumerate(part.parameters) if p.name != part.constant]
            owned = [[self._layout.index[k][j] for j in movable] for k in group]
            if any(p is None for row in owned for p in row):
                continue
            same_box = all(np.array_equal(lower[row], lower[owned[0]])
                           and np.array_equal(upper[row], upper[owned[0]]) for row in owned)
            if not same_box:
                continue
            key = part.index(part.order_by)
            keys = [vector[self._layout.index[k][key]] for k in group]
            order = np.argsort(keys, kind="stable")
            values = [vector[row].copy() for row in owned]
            for row, source in zip(owned, order):
                vector[row] = values[source]
        return vector

    def idle_parts(self, params, bounds) -> list[str]:
        """A sentence for each part whose weight is zero: its shape is then unidentified."""
        unit = np.asarray(to_unit(np.asarray(params, dtype=float), bounds))
        sentences = []
        for k, part in enumerate(self.parts):
            positions = self._layout.index[k]
            scales = [positions[part.index(name)] for name in part.scales]
            scales = [p for p in scales if p is not None]
            if not scales or not all(unit[p] < 1e-6 for p in scales):
                continue
            weights = ", ".join(self.names[p] for p in scales)
            shape = [self.names[p] for j, p in enumerate(positions)
                     if p is not None and p not in scales
                     and part.parameters[j].name != part.constant]
            sentences.append(
                f"part {k + 1} ({part.name}) of {self.name} has its weight {weights} at its "
                f"lower bound (zero in effect): its shape ({', '.join(shape) or 'none'}) is not "
                "determined by the data and its intervals mean nothing; the other part alone "
                "describes the data")
        return sentences
