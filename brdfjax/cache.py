"""Work that outlives the process: compiled code and traced stages kept on disk.

A new process pays twice before it computes anything: JAX traces the Python of each
jitted function (seconds for optimistix's Levenberg-Marquardt under ``vmap``), then XLA
compiles it. JAX's persistent compilation cache saves the second; `stage` saves the
first. A stage is a jitted function whose traced and lowered form is serialised with
``jax.export`` the first time it runs on arguments of a given shape; a later process
loads that form (milliseconds) and compiles it, which the compilation cache turns into a
lookup. Loading a stage imports neither optimistix nor equinox.

Both caches are off until `enable` is called (the CLI calls it); library calls then use
plain ``jax.jit``. A stage's file name hashes the function's module and name, the static
arguments, the argument shapes and dtypes, the platform, the versions of JAX and its
libraries, and the source of the whole ``brdfjax`` package, so editing a brdfjax module
never reuses a stale stage (stages are for brdfjax's own functions). An unreadable file is
traced again and replaced; a stage that cannot be exported or written runs as plain jit.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import os
import pickle
import tempfile
import threading
import time
from importlib import metadata
from pathlib import Path

import jax

_directory: Path | None = None


def enable(directory: str | os.PathLike | None = None) -> Path:
    """Keep compiled code (``xla/``) and traced stages (``stages/``) under ``directory``.

    The default is ``$BRDFJAX_CACHE``, else ``~/.cache/brdfjax``. Every compilation is
    kept (JAX's default keeps only those over 1 s, and ours are shorter).

    Returns:
        The directory used.
    """
    global _directory
    directory = Path(directory or os.environ.get("BRDFJAX_CACHE")
                     or Path.home() / ".cache" / "brdfjax")
    jax.config.update("jax_compilation_cache_dir", str(directory / "xla"))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    _directory = directory
    return directory


# JAX's own timing events (jax/_src/dispatch.py), each recorded with the function's name.
_COMPILE_EVENTS = {"/jax/core/compile/jaxpr_trace_duration": "traced",
                   "/jax/core/compile/jaxpr_to_mlir_module_duration": "lowered",
                   "/jax/core/compile/backend_compile_duration": "compiled"}
_reporting = {"on": False, "listening": False}
compile_seconds: dict[str, float] = {}  # by step ("traced", ...), since reporting began


def report_compiles(on: bool = True) -> None:
    """Say on stderr how long each stage takes to trace, lower and compile (or stop).

    One line per step of every compilation, e.g. ``compile: _fit_chunk compiled by XLA in
    3.21 s`` (a persistent-cache hit shows as a short compile), and for a `stage`, whether
    its traced form was loaded from disk or traced and exported. Sums by step are kept in
    `compile_seconds`. The CLI calls this at ``-v``.
    """
    _reporting["on"] = on
    if on:
        compile_seconds.clear()
    if _reporting["listening"]:
        return
    _reporting["listening"] = True

    def listen(event: str, seconds: float, **metadata) -> None:
        step = _COMPILE_EVENTS.get(event)
        if step is None or not _reporting["on"]:
            return
        compile_seconds[step] = compile_seconds.get(step, 0.0) + seconds
        if seconds >= 0.01:  # the many tiny jits of host-side helpers are not worth a line
            name = str(metadata.get("fun_name", "?")).removeprefix("jit_")
            if name.startswith("jit(") and name.endswith(")"):
                name = name[4:-1]
            _say(f"{name} {step}{' by XLA' if step == 'compiled' else ''} in {seconds:.2f} s")

    jax.monitoring.register_event_duration_secs_listener(listen)


def _say(text: str) -> None:
    if _reporting["on"]:
        import sys

        print(f"compile: {text}", file=sys.stderr, flush=True)


def stage(function=None, *, static_argnames: tuple[str, ...] = ()):
    """Decorator: ``jax.jit`` whose tracing is kept on disk once `enable` was called.

    Called with tracers (inside another jit or vmap) or with the caches off, a stage is
    ``jax.jit(function, static_argnames=...)`` called with its defaults filled in.
    ``stage_function.compile(*args, **kwargs)`` compiles it for such arguments without
    running it, so that a later call in any thread runs at once (compiling ahead where
    running would not be safe: XLA's LAPACK calls can deadlock beside another thread's).
    """
    if function is None:
        return functools.partial(stage, static_argnames=static_argnames)
    jitted = jax.jit(function, static_argnames=static_argnames)
    signature = inspect.signature(function)

    def dispatch(args, kwargs, run: bool):
        # Defaults filled in: jit keys its compilations on how arguments are spelled, and
        # two calls of one shape (one passing a default, one leaving it out) would compile
        # twice (the fit's polish and the Laplace approximation's).
        bound = signature.bind(*args, **kwargs)
        bound.apply_defaults()
        leaves = jax.tree.leaves(bound.arguments)
        if _directory is None or any(isinstance(x, jax.core.Tracer) for x in leaves):
            return _run_or_compile(jitted, run, *bound.args, **bound.kwargs)
        static = {name: bound.arguments.pop(name) for name in static_argnames}
        return _exported(function, jitted, static, bound.args, bound.kwargs, run)

    @functools.wraps(function)
    def call(*args, **kwargs):
        return dispatch(args, kwargs, run=True)

    call.compile = lambda *args, **kwargs: dispatch(args, kwargs, run=False)
    call._cache_size = jitted._cache_size  # compilations so far, as jax.jit reports
    return call


# stage file -> (compiled call, output structure), or None where it could not be made
_loaded: dict[Path, tuple | None] = {}


_building: dict[Path, threading.Lock] = {}  # one per stage file being loaded or built
_building_lock = threading.Lock()


def _load(path: Path, build, name: str) -> tuple | None:
    """`_load_once` of ``path``, one thread at a time (threads that need the same stage at
    once, one per device or per model, trace it once and share it)."""
    with _building_lock:
        lock = _building.setdefault(path, threading.Lock())
    with lock:
        return _load_once(path, build, name)


def _load_once(path: Path, build, name: str) -> tuple | None:
    """The compiled call of one stage file and its output structure, built if missing.

    None when the stage cannot be exported or written (the caller then runs plain jit).
    """
    if path not in _loaded:
        tic = time.perf_counter()
        try:
            exported, out_tree = pickle.loads(path.read_bytes())
            exported = jax.export.deserialize(exported)
            _say(f"{name} stage loaded from disk in {time.perf_counter() - tic:.2f} s")
        except Exception:  # noqa: BLE001  (missing, truncated, other jaxlib): trace again
            exported = None
        if exported is None:
            try:
                exported, out_tree = build()
                _write(path, pickle.dumps((exported.serialize(), out_tree)))
                _say(f"{name} stage traced and exported in {time.perf_counter() - tic:.2f} s")
            except Exception:  # noqa: BLE001  (not exportable, cache not writable)
                _loaded[path] = None
                return None

        def call(*args):
            return exported.call(*args)

        call.__name__ = call.__qualname__ = name  # named in JAX's compile events
        _loaded[path] = jax.jit(call), out_tree
    return _loaded[path]


def _exported(function, jitted, static: dict, args: tuple, kwargs: dict, run: bool):
    leaves, in_tree = jax.tree.flatten((args, kwargs))
    # Typed PRNG keys cannot cross the export boundary: pass their raw data and rewrap.
    impls = [jax.random.key_impl(x) if _is_key(x) else None for x in leaves]
    raw = [jax.random.key_data(x) if impl else x for x, impl in zip(leaves, impls)]
    avals = [x if isinstance(x, jax.ShapeDtypeStruct) else
             jax.ShapeDtypeStruct(jax.numpy.shape(x), jax.numpy.result_type(x),
                                  weak_type=getattr(x, "weak_type", type(x) in (int, float)))
             for x in raw]
    signature = repr((function.__module__, function.__qualname__, sorted(static.items()),
                      in_tree, [(a.shape, str(a.dtype), a.weak_type) for a in avals],
                      [str(i) for i in impls], _fingerprint()))
    path = _directory / "stages" / f"{hashlib.sha256(signature.encode()).hexdigest()}.stage"
    out_tree = []

    def flat(*raw):  # renamed below, so compile timings name the stage
        leaves = [jax.random.wrap_key_data(x, impl=i) if i else x for x, i in zip(raw, impls)]
        args, kwargs = jax.tree.unflatten(in_tree, leaves)
        out, tree = jax.tree.flatten(function(*args, **kwargs, **static))
        out_tree.append(tree)
        return out

    flat.__name__ = flat.__qualname__ = function.__name__

    def build():
        exported = jax.export.export(jax.jit(flat))(*avals)
        return exported, out_tree[0]

    loaded = _load(path, build, function.__name__)
    if loaded is None:
        return _run_or_compile(jitted, run, *args, **kwargs, **static)
    compiled, tree = loaded
    return jax.tree.unflatten(tree, compiled(*raw)) if run else compiled.lower(*raw).compile()


def _run_or_compile(jitted, run: bool, *args, **kwargs):
    """``jitted(*args, **kwargs)``, or where ``run`` is False its compilation for them."""
    return jitted(*args, **kwargs) if run else jitted.lower(*args, **kwargs).compile()


def _is_key(x) -> bool:
    return hasattr(x, "dtype") and jax.dtypes.issubdtype(x.dtype, jax.dtypes.prng_key)


@functools.cache
def _fingerprint() -> str:
    """The platform, the x64 switch, the libraries' versions, and this package's source."""
    digest = hashlib.sha256()
    device = jax.devices()[0]
    digest.update(f"{device.platform} {device.device_kind} "
                  f"x64={jax.config.jax_enable_x64}\n".encode())
    for name in ("jax", "jaxlib", "optimistix", "equinox", "lineax"):
        digest.update(f"{name} {metadata.version(name)}\n".encode())
    package = Path(__file__).parent
    for path in sorted(package.rglob("*.py")):
        digest.update(path.relative_to(package).as_posix().encode() + path.read_bytes())
    return digest.hexdigest()


def _write(path: Path, payload: bytes) -> None:
    """Write whole or not at all: parallel processes may write the same stage."""
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    with os.fdopen(handle, "wb") as stream:
        stream.write(payload)
    os.replace(temporary, path)
