"""Shared test setup: float64 on, caches kept out of the home directory, data paths."""

import os
import tempfile
from pathlib import Path

import jax
import pytest

jax.config.update("jax_enable_x64", True)
# CLI commands enable the on-disk caches (`brdfjax.cache.enable`): keep those of a test run
# apart from the user's, and shared by the subprocesses the tests start.
os.environ.setdefault("BRDFJAX_CACHE", tempfile.mkdtemp(prefix="brdfjax-test-cache-"))

REPO = Path(__file__).resolve().parents[1]
DATA = REPO / "data"
SHARED = REPO.parent / "shared"


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
