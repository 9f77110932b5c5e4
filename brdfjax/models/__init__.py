"""The family of BRDF models that brdfjax fits, one module each.

| name | parameters | module |
|---|---|---|
| ``five`` (default) | kb, kr, a, b, kd | `brdfjax.models.five` (the paper's Eq. 5) |
| ``torrance-sparrow`` | g, c, n, rho0 | `brdfjax.models.torrance_sparrow` (Eq. 2) |
| ``ggx`` | ks, alpha, f0, kd | `brdfjax.models.ggx` |
| ``beckmann`` | ks, alpha, f0, kd | `brdfjax.models.beckmann` |
| ``lambert`` | kd | `brdfjax.models.lambert` |
| ``rpv`` | rho0, k, asymmetry, rhoc | `brdfjax.models.rpv` |
| ``backscatter`` | kb, beta | `brdfjax.models.backscatter` |
| ``abg`` | A, B, g | `brdfjax.models.abg` |
| ``ross-li`` | f_iso, f_vol, f_geo | `brdfjax.models.ross_li` |
| ``A+B`` | the parts', repeats ``_2`` | `brdfjax.models.sum` (any sum: ``ggx+backscatter``) |

A model is found by its module: every module of this package whose name does not start
with ``_`` is imported on the first lookup, and each `Model` subclass defined in it with a
``name`` is registered. The package also holds what every model shares: `base` (the
`Model` interface), `geometry` (the angle terms), `paper` (evaluating a model on angles)
and `hemispherical` (reflectance, Eq. 9); they define no model. Adding a model is therefore one new
file (see the README, "Adding a model"), and it then takes part in sums with no change elsewhere. A
name with ``+`` is a `Sum` of the named models (`brdfjax.models.sum`); sums are not listed by
`available`.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil

import numpy as np

from brdfjax.models.base import Model, Parameter

DEFAULT = "five"
_registry: dict[str, type[Model]] = {}

__all__ = ["DEFAULT", "Model", "Parameter", "available", "get", "model_for"]


def _discover() -> dict[str, type[Model]]:
    if not _registry:
        for module in pkgutil.iter_modules(__path__):
            if module.name.startswith("_") or module.name == "base":
                continue
            name = f"{__name__}.{module.name}"
            for _, cls in inspect.getmembers(importlib.import_module(name), inspect.isclass):
                if (issubclass(cls, Model) and cls.__module__ == name
                        and isinstance(cls.__dict__.get("name"), str)):
                    _registry[cls.name] = cls
        order = [DEFAULT] + sorted(set(_registry) - {DEFAULT})
        _registry.update({name: _registry.pop(name) for name in order})
    return _registry


def available() -> tuple[str, ...]:
    """The names of every model, the default first."""
    return tuple(_discover())


def get(model: str | Model | None = None, constants=None) -> Model:
    """A model instance from its name (or the instance itself); None is the default.

    Args:
        model: a name of `available`, a `Model`, or None for ``five``.
        constants: shadowing constants of Eq. (3) for models with a G term (None keeps
            the paper's).
    """
    if model is None:
        model = DEFAULT
    if isinstance(model, str) and "+" in model:
        from brdfjax.models.sum import Sum

        model = Sum(tuple(get(part.strip()) for part in model.split("+")))
    if model == "auto":
        raise ValueError("model 'auto' is chosen by cross-validation on data: brdfjax fit and "
                         "batch take it; in Python, brdfjax.compare_models(data).best.name is "
                         "the compact model, .predictor.name the one to predict with")
    if isinstance(model, str):
        registry = _discover()
        if model not in registry:
            raise ValueError(f"unknown model {model!r}; choose one of {', '.join(registry)}, "
                             "or a sum of them such as ggx+backscatter")
        model = registry[model]()
    if not isinstance(model, Model):
        raise TypeError(f"expected a model name or a brdfjax.models.Model, got {model!r}")
    return model if constants is None else model.with_constants(constants)


def model_for(params, model: str | Model | None = None, constants=None) -> Model:
    """The model to evaluate ``params`` with, checked against them.

    Args:
        params: a model's named tuple (a fit's ``result.params``), or an array whose first
            axis is the parameters.
        model: as for `get`; None takes the single model whose named tuple ``params`` is
            (a sum's parameters need ``model=``, e.g. ``result.model``), and the default
            for an array.
        constants: as for `get`.

    Raises:
        ValueError: ``params`` are another model's named tuple, or their count is not the
            model's (under JAX, an index past the end is clamped, not refused: ggx's four
            parameters read as the paper's five gave a reflectance of 3.5 instead of 0.07).
    """
    named = isinstance(params, tuple) and hasattr(params, "_fields")
    if model is None and named:
        model = next((name for name, cls in _discover().items() if cls.Params is type(params)),
                     None)
        if model is None:
            raise ValueError(f"{type(params).__name__}({', '.join(params._fields)}) belong to "
                             "no single model (a sum's): pass model=, e.g. result.model")
    model = get(model, constants)
    hint = "pass model= the model they were fitted with (result.model)"
    if named and (type(params).__name__, tuple(params._fields)) != (model.Params.__name__,
                                                                      model.names):
        raise ValueError(f"{type(params).__name__}({', '.join(params._fields)}) are not the "
                         f"parameters of {model.name} ({', '.join(model.names)}): {hint}")
    if named:
        return model
    if isinstance(params, list | tuple):  # it may hold tracers (jit, grad): no np.shape
        count = len(params)
    else:
        shape = np.shape(params)  # an array's, traced or not
        count = shape[0] if shape else None
    if count != model.size:
        raise ValueError(f"{model.name} takes {model.size} parameters "
                         f"({', '.join(model.names)}) along the first axis, got "
                         f"{'a scalar' if count is None else count}: {hint}")
    return model
