"""Shared test setup: float64 on, and paths to the bundled and the shared data."""

from pathlib import Path

import jax
import pytest

jax.config.update("jax_enable_x64", True)

REPO = Path(__file__).resolve().parents[1]
DATA = REPO / "data"
SHARED = REPO.parent / "shared"


@pytest.fixture(scope="session")
def white_paint():
    """The bundled synthetic white-paint measurements."""
    from brdfjax.formats import load

    return load(DATA / "synthetic" / "white_paint.csv")
