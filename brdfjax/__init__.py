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
import importlib.util
import os
import sys

if "jax" in sys.modules:
    if os.environ.get("JAX_ENABLE_X64", "1") != "0":
        sys.modules["jax"].config.update("jax_enable_x64", True)
else:
    os.environ.setdefault("JAX_ENABLE_X64", "1")

# XLA compiles brdfjax's code with LLVM at -O2 instead of its default -O3: a new process
# spends most of its first fit compiling, and at -O2 the genetic search compiles in 2.3 s
# instead of 3.8 s and the first `brdfjax fit` takes 11.1 s instead of 13.1 s, while the
# compiled code runs as fast (BENCHMARKS.md, section startup). E is unchanged; parameters
# in flat directions move at the 1e-8 level (another order of summation). A level given
# in XLA_FLAGS is kept; like 64-bit mode, this acts only before JAX starts its backend.
_flags = os.environ.get("XLA_FLAGS", "")
if "xla_backend_optimization_level" not in _flags:
    _flags = f"{_flags} --xla_backend_optimization_level=2".strip()
# XLA:CPU's elemental emitters compile brdfjax's loops far faster than its MLIR fusion
# emitters, and the code runs as fast with the same results: the first `brdfjax models` took
# 28.0 s instead of 39.9 s, its compilations 29 s of CPU instead of 52 s (BENCHMARKS.md,
# section startup-fit-models-batch-auto).
# XLA:CPU compiles a while loop whose body accesses less than a threshold of bytes (1 kB by
# default) as one function, instead of one dispatched kernel per operation. brdfjax opens
# the threshold to loops of any size and writes the loops that gain so that nothing else
# blocks the pass (`brdfjax.fitting.marquardt`: Levenberg-Marquardt on small problems);
# a loop with a library call (LAPACK, or a matrix product handed to YNNPACK) stays as it
# was, and loops of JAX's own without one (threefry's rounds, rolled on CPU) become one
# function too. The cube of `brdfjax batch` (64 points a sample) fits about 1.4x faster,
# the 716-point batch as fast (BENCHMARKS.md, section cube).
# XLA aborts the process on a flag it does not know, and newer XLA retires such flags, so
# both are set only on the jaxlib they were measured with. Reading that version costs
# `import brdfjax` about 30 ms (importlib.metadata, which JAX imports anyway).
_MEASURED_JAXLIB = ("0.10.",)
_MEASURED_FLAGS = {"xla_cpu_use_fusion_emitters": "false",
                   "xla_backend_extra_options": "xla_cpu_small_while_loop_byte_threshold=1000000000"}
if any(name not in _flags for name in _MEASURED_FLAGS):
    from importlib import metadata as _metadata

    try:
        if _metadata.version("jaxlib").startswith(_MEASURED_JAXLIB):
            for _name, _value in _MEASURED_FLAGS.items():
                if _name not in _flags:
                    _flags = f"{_flags} --{_name}={_value}"
    except _metadata.PackageNotFoundError:
        pass
os.environ["XLA_FLAGS"] = _flags

# OpenBLAS runs one thread per core by default, and its idle threads spin, waiting for the
# next call, instead of sleeping. jaxlib solves with SciPy's OpenBLAS (LAPACK's Cholesky and
# triangular solves of the learned discrepancy, `brdfjax.prediction.discrepancy`), matrices
# of at most 256 rows, a few thousand calls a fit: a perf profile of warm `fit --cv` found
# three quarters of the process's CPU in OpenBLAS's spinning (blas_thread_server,
# exec_blas_async_wait). Alone on 2 cores that costs little, but where another job holds
# the cores the spinning threads take its time slices from the one that works: the same
# warm `fit --cv` took 38-65 s beside two busy processes, against 2-5 s with one OpenBLAS
# thread (BENCHMARKS.md, section contention). One thread is the default here; a count given
# in OPENBLAS_NUM_THREADS is kept. Like XLA's flags it acts on a library loaded after
# `import brdfjax`: SciPy's OpenBLAS loads at the first LAPACK call, NumPy's with NumPy.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

__version__ = "0.1.0"

_EXPORTS = {
    "brdf": "brdfjax.models.paper",
    "projected_brdf": "brdfjax.models.paper",
    "evaluate": "brdfjax.models.paper",
    "Params": "brdfjax.models.paper",
    "PAPER_SAMPLES": "brdfjax.models.paper",
    "PARAMETER_NAMES": "brdfjax.models.paper",
    "scene": "brdfjax.models.geometry",
    "ShadowingConstants": "brdfjax.models.geometry",
    "reflectance": "brdfjax.models.hemispherical",
    "EnergyWarning": "brdfjax.models.hemispherical",
    "Measurements": "brdfjax.data.measurements",
    "DataError": "brdfjax.data.measurements",
    "load": "brdfjax.data.formats",
    "save": "brdfjax.data.formats",
    "fit": "brdfjax.fitting.fit",
    "FitResult": "brdfjax.fitting.fit",
    "UnderdeterminedWarning": "brdfjax.fitting.fit",
    "fit_batch": "brdfjax.fitting.batch",
    "cross_validate": "brdfjax.prediction.cross_validation",
    "fit_per_incidence": "brdfjax.prediction.cross_validation",
    "CrossValidation": "brdfjax.prediction.cross_validation",
    "predict": "brdfjax.prediction.intervals",
    "Prediction": "brdfjax.prediction.intervals",
    "compare_models": "brdfjax.prediction.selection",
    "plan": "brdfjax.instrument.design",
    "Comparison": "brdfjax.prediction.selection",
    "Model": "brdfjax.models",
    "Bounds": "brdfjax.models.bounds",
    "make_bounds": "brdfjax.models.bounds",
    "default_bounds": "brdfjax.models.bounds",
    "laplace_approximation": "brdfjax.uncertainty.laplace",
    "sample_posterior": "brdfjax.uncertainty.mcmc",
    "inline_dispatch": "brdfjax.uncertainty.mcmc",
    "UncertaintyResult": "brdfjax.uncertainty.result",
    "UncertaintyWarning": "brdfjax.uncertainty.result",
    "curve_bands": "brdfjax.uncertainty.bands",
    "reflectance_bands": "brdfjax.uncertainty.bands",
}

__all__ = [
    "PAPER_SAMPLES",
    "PARAMETER_NAMES",
    "Bounds",
    "Comparison",
    "CrossValidation",
    "DataError",
    "EnergyWarning",
    "FitResult",
    "Measurements",
    "Model",
    "Params",
    "Prediction",
    "ShadowingConstants",
    "UncertaintyResult",
    "UncertaintyWarning",
    "UnderdeterminedWarning",
    "brdf",
    "compare_models",
    "cross_validate",
    "curve_bands",
    "default_bounds",
    "evaluate",
    "fit",
    "fit_batch",
    "fit_per_incidence",
    "inline_dispatch",
    "laplace_approximation",
    "load",
    "make_bounds",
    "plan",
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
        # A subpackage or module (brdfjax.cache.enable(), brdfjax.models.available()),
        # imported on first use like the names.
        if name.startswith("_") or importlib.util.find_spec(f"{__name__}.{name}") is None:
            raise AttributeError(f"module 'brdfjax' has no attribute {name!r}")
        return importlib.import_module(f"{__name__}.{name}")
    value = getattr(importlib.import_module(_EXPORTS[name]), name)
    globals()[name] = value
    return value


def __dir__():
    return __all__
