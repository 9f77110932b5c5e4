"""brdfjax: fit BRDF models to measured data, the five-parameter model of Zhang, Wu, Cao and
Zhang by default, cross-validate them and predict new geometry.

    import brdfjax
    data = brdfjax.load("data/synthetic/white_paint.csv")
    result = brdfjax.fit(data, validate_incidences_deg=[21, 52])
    brdfjax.reflectance(result.params, 0.0)
    brdfjax.compare_models(data).table()          # every model, ranked by cv_error

Fitting needs float64, so brdfjax turns on JAX's 64-bit mode (unless ``JAX_ENABLE_X64=0``
is set); float32 inputs are still evaluated in float32. Names are imported on first use,
so ``import brdfjax`` (and the CLI's ``--help``) stays fast.
"""

import importlib
import os
import sys

if "jax" in sys.modules:
    if os.environ.get("JAX_ENABLE_X64", "1") != "0":
        sys.modules["jax"].config.update("jax_enable_x64", True)
else:
    os.environ.setdefault("JAX_ENABLE_X64", "1")

__version__ = "0.1.0"

_EXPORTS = {
    "brdf": "brdfjax.model",
    "projected_brdf": "brdfjax.model",
    "evaluate": "brdfjax.model",
    "Params": "brdfjax.model",
    "PAPER_SAMPLES": "brdfjax.model",
    "PARAMETER_NAMES": "brdfjax.model",
    "scene": "brdfjax.geometry",
    "ShadowingConstants": "brdfjax.geometry",
    "reflectance": "brdfjax.hemispherical",
    "Measurements": "brdfjax.measurements",
    "DataError": "brdfjax.measurements",
    "load": "brdfjax.formats",
    "save": "brdfjax.formats",
    "fit": "brdfjax.fitting",
    "FitResult": "brdfjax.fitting",
    "fit_batch": "brdfjax.batch",
    "cross_validate": "brdfjax.validation",
    "CrossValidation": "brdfjax.validation",
    "predict": "brdfjax.prediction",
    "Prediction": "brdfjax.prediction",
    "compare_models": "brdfjax.selection",
    "Comparison": "brdfjax.selection",
    "Model": "brdfjax.models",
    "Bounds": "brdfjax.bounds",
    "make_bounds": "brdfjax.bounds",
    "default_bounds": "brdfjax.bounds",
    "laplace_approximation": "brdfjax.laplace",
    "sample_posterior": "brdfjax.posterior",
    "inline_dispatch": "brdfjax.posterior",
    "UncertaintyResult": "brdfjax.posterior",
    "UncertaintyWarning": "brdfjax.posterior",
    "curve_bands": "brdfjax.bands",
    "reflectance_bands": "brdfjax.bands",
}

__all__ = [
    "PAPER_SAMPLES",
    "PARAMETER_NAMES",
    "Bounds",
    "Comparison",
    "CrossValidation",
    "DataError",
    "FitResult",
    "Measurements",
    "Model",
    "Params",
    "Prediction",
    "ShadowingConstants",
    "UncertaintyResult",
    "UncertaintyWarning",
    "brdf",
    "compare_models",
    "cross_validate",
    "curve_bands",
    "default_bounds",
    "evaluate",
    "fit",
    "fit_batch",
    "inline_dispatch",
    "laplace_approximation",
    "load",
    "make_bounds",
    "predict",
    "projected_brdf",
    "reflectance",
    "reflectance_bands",
    "sample_posterior",
    "save",
    "scene",
]


def __getattr__(name):
    if name not in _EXPORTS:
        raise AttributeError(f"module 'brdfjax' has no attribute {name!r}")
    value = getattr(importlib.import_module(_EXPORTS[name]), name)
    globals()[name] = value
    return value


def __dir__():
    return __all__
