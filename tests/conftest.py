"""Shared test setup: float64 on, caches kept out of the home directory, data paths."""

import os
import signal
import subprocess
import tempfile
from pathlib import Path

import jax
import pytest

# The tests check results, not speed: in-process they compile with LLVM's lowest level (a
# level given in XLA_FLAGS is kept, and brdfjax keeps it too), which took the suite's CPU
# time from 25.0 to 21.8 min (all 905 tests passed either way, 2026-12-08). The commands the
# tests run as new processes with `environment` compile as a user's do, at brdfjax's level;
# other child processes (the notebooks' kernels) inherit this level.
# XLA reads the flags when its backend starts, at the first computation: after this.
if "xla_backend_optimization_level" not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "")
                               + " --xla_backend_optimization_level=0").strip()

jax.config.update("jax_enable_x64", True)
# CLI commands enable the on-disk caches (`brdfjax.cache.enable`): keep those of a test run
# apart from the user's, and shared by the subprocesses the tests start.
os.environ.setdefault("BRDFJAX_CACHE", tempfile.mkdtemp(prefix="brdfjax-test-cache-"))

REPO = Path(__file__).resolve().parents[1]
DATA = REPO / "data"
SHARED = REPO.parent / "shared"


def _real_data() -> Path:
    """The folder of the real data sets (`brdfjax.datasets`): ``BRDFJAX_DATA`` where it is
    set, else the project's shared copy where it exists (as in CI), else the sets downloaded
    into the user's cache. Every file of every set is checked to be there, so that a missing
    one fails the run here instead of a test skipping."""
    from brdfjax import datasets

    shared = SHARED / "data" / "real"
    if not os.environ.get(datasets.ENVIRONMENT) and shared.is_dir():
        os.environ[datasets.ENVIRONMENT] = str(shared)
    return {datasets.fetch(name, progress=True).parent for name in datasets.names()}.pop()


# The real measurements, laid out as <set>/<folder>/<file>.
REAL = _real_data()
# The in-plane CSVs made outside this project from the raw files, to check the readers
# against: the project's shared data folder has them, its sources do not.
DERIVED = SHARED / "data" / "real"


@pytest.fixture(scope="session")
def white_paint():
    """The bundled synthetic white-paint measurements."""
    from brdfjax.data.formats import load

    return load(DATA / "synthetic" / "white_paint.csv")


@pytest.fixture(autouse=True)
def _stages_off_after_each_test(monkeypatch):
    """A CLI test run in-process turns stages on; the next test starts with plain jit again."""
    from brdfjax import cache

    monkeypatch.setattr(cache, "_directory", cache._directory)


@pytest.fixture(scope="module")
def environment(tmp_path_factory):
    """Environment of command-line runs in subprocesses: one CPU device, this checkout, and
    one compilation cache per test module."""
    return {**os.environ, "BRDFJAX_CACHE": str(tmp_path_factory.mktemp("jax-cache")),
            "PYTHONPATH": str(REPO), "XLA_FLAGS": "--xla_force_host_platform_device_count=1"}


@pytest.fixture
def dask_scheduler(environment, monkeypatch):
    """The address of a real local Dask cluster (2 worker processes, one thread each) whose
    workers inherit `environment`."""
    distributed = pytest.importorskip("distributed")
    for name, value in environment.items():  # the workers inherit it when spawned
        monkeypatch.setenv(name, value)
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        yield cluster.scheduler_address


def interruptible(command, **options) -> subprocess.Popen:
    """``subprocess.Popen(command, **options)`` with SIGINT reaching the child's Python: a
    shell that runs the suite in the background (``make test &``) ignores SIGINT, and an
    ignored signal stays ignored across exec, so the child would install no
    KeyboardInterrupt handler and run on untouched; a handler set here is reset to the
    default at exec instead."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        return subprocess.Popen(command, **options)
    finally:
        signal.signal(signal.SIGINT, previous)
