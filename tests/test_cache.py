"""On-disk stages (`brdfjax.cache`): same numbers as plain jit, no tracing in a later process."""

import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
from conftest import REPO

from brdfjax import cache
from brdfjax.data.synthetic import paper_sample
from brdfjax.fitting.fit import fit

# A later process loads the fit's stages from disk: neither optimistix nor equinox is
# imported (they are only needed to trace the Levenberg-Marquardt stage).
SCRIPT = """
import sys
from brdfjax.cache import enable
from brdfjax.fitting.fit import fit
from brdfjax.data.synthetic import paper_sample
enable(sys.argv[1])
result = fit(paper_sample("khaki_paint", noise=0.01, seed=3).at_incidences([10, 30]), seed=2)
print(repr(result.error), "optimistix" in sys.modules)
"""


def run_script(directory):
    done = subprocess.run([sys.executable, "-c", SCRIPT, str(directory)], cwd=REPO,
                          capture_output=True, text=True, timeout=300, check=True)
    error, traced = done.stdout.split()
    return float(error), traced == "True"


def test_a_later_process_loads_the_stages_without_tracing(tmp_path):
    plain = fit(paper_sample("khaki_paint", noise=0.01, seed=3).at_incidences([10, 30]), seed=2)
    first, traced_first = run_script(tmp_path)
    later, traced_later = run_script(tmp_path)
    assert traced_first and not traced_later
    assert later == first == plain.error  # the same numbers as plain jax.jit
    for stage_file in (tmp_path / "stages").glob("*.stage"):
        stage_file.write_bytes(stage_file.read_bytes()[:100])  # truncated: traced again
    again, traced_again = run_script(tmp_path)
    assert traced_again and again == first


def square_plus(x, power=2):
    return x**power + 1.0


def test_a_stage_is_written_once_and_falls_back_to_jit_where_it_cannot_be(tmp_path,
                                                                          monkeypatch):
    staged = cache.stage(square_plus, static_argnames=("power",))
    monkeypatch.setattr(cache, "_directory", tmp_path)
    assert float(staged(3.0, 3)) == 28.0  # a positional static argument
    assert float(staged(2.0, power=3)) == 9.0
    assert len(list((tmp_path / "stages").glob("*.stage"))) == 1
    blocked = tmp_path / "a-file"
    blocked.write_text("not a directory: no stage can be written under it")
    monkeypatch.setattr(cache, "_directory", blocked)
    assert float(staged(3.0, power=2)) == 10.0


def test_a_stage_compiled_ahead_runs_without_compiling_again(tmp_path, monkeypatch, caplog):
    def compiled():  # JAX's own log of its XLA compilations of square_plus, then cleared
        lines = [r.getMessage() for r in caplog.records if "XLA compilation" in r.getMessage()]
        caplog.clear()
        return [line for line in lines if "square_plus" in line]

    for directory in (tmp_path, None):  # through a stage file, and as plain jit
        monkeypatch.setattr(cache, "_directory", directory)
        staged = cache.stage(square_plus, static_argnames=("power",))
        values = jnp.arange(5.0)
        with jax.log_compiles(True), caplog.at_level("WARNING"):
            staged.compile(values, power=3)
            assert compiled()
            assert np.array_equal(staged(values, power=3), np.arange(5.0)**3 + 1.0)
            assert not compiled()
