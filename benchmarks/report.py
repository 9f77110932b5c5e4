"""Write one benchmark's results into its own section of BENCHMARKS.md.

Each benchmark owns the text between ``<!-- begin NAME -->`` and ``<!-- end NAME -->``, so
benchmarks can be rerun one at a time without touching each other's numbers. Every section
records the machine, the command and the date.
"""

from __future__ import annotations

import datetime
import json
import os
import platform
import re
import subprocess
import sys
import time
from pathlib import Path

BENCHMARKS = Path(__file__).resolve().parents[1] / "BENCHMARKS.md"
PREAMBLE = """# Benchmarks

Measured, not claimed: every number below comes from a script in `benchmarks/`, run as
shown, on the machine named in its section. Rerun one with the command given; rerun all
with `make bench`.
"""


def real_data(name: str) -> Path:
    """The folder of real data set ``name`` (`brdfjax.datasets`): from ``BRDFJAX_DATA``,
    else from the project's shared copy where it exists (as in CI), else downloaded."""
    from brdfjax import datasets

    shared = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"
    if not os.environ.get(datasets.ENVIRONMENT) and shared.is_dir():
        os.environ[datasets.ENVIRONMENT] = str(shared)
    return datasets.fetch(name, progress=True)


# XLA_FLAGS as the benchmark was started with: `import brdfjax` adds its own flags to this
# process's environment, and a child process running another checkout (``--before``,
# ``--baseline``) must get that checkout's own, not these. Right only where this module is
# imported before brdfjax (the scripts that use `child_env` import it first).
_GIVEN_XLA_FLAGS = os.environ.get("XLA_FLAGS")


def child_env(**extra: str) -> dict:
    """This process's environment with XLA_FLAGS as the benchmark was started with, then
    ``extra``: for a child process that imports a brdfjax of its own."""
    env = dict(os.environ)
    env.pop("XLA_FLAGS", None)
    if _GIVEN_XLA_FLAGS is not None:
        env["XLA_FLAGS"] = _GIVEN_XLA_FLAGS
    return {**env, **extra}


# Only the footer of a run that writes: ``--quick`` runs set this and print instead.
DRY_RUN = False
VERSIONED = ("jax", "jaxlib", "optimistix", "numpy", "scipy", "emcee", "pygad")


def versions() -> str:
    """``jax 0.10.2, jaxlib 0.10.2, ...`` for every library a benchmark's numbers depend on."""
    from importlib.metadata import PackageNotFoundError, version

    def one(name):
        try:
            return f"{name} {version(name)}"
        except PackageNotFoundError:
            return f"{name} not installed"

    return ", ".join(one(name) for name in VERSIONED)


def load_average() -> str:
    """The 1-minute load average now, and the core count (above it, timings are inflated)."""
    try:
        return f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores"
    except OSError:
        return "unknown"


def machine() -> str:
    """A one-line description of this machine and the library versions that matter."""
    import jax

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return (f"{os.cpu_count()} cores ({cpu}), Python {platform.python_version()}, "
            f"JAX on {jax.default_backend()}; {versions()}")


def write_section(name: str, body: str) -> None:
    """Replace (or append) the section ``name`` of BENCHMARKS.md with ``body``.

    With `DRY_RUN` set (``--quick``), print the section and leave BENCHMARKS.md alone.
    """
    command = "python " + " ".join([os.path.relpath(sys.argv[0])] + sys.argv[1:])
    stamp = datetime.date.today().isoformat()
    section = (f"<!-- begin {name} -->\n{body.rstrip()}\n\n"
               f"*Machine: {machine()}. Command: `{command}`. Date: {stamp}. "
               f"Load average (1 min) when written: {load_average()}.*\n"
               f"<!-- end {name} -->")
    if DRY_RUN:
        print(f"--quick: not written to BENCHMARKS.md:\n{section}")
        return
    text = BENCHMARKS.read_text() if BENCHMARKS.exists() else PREAMBLE
    pattern = re.compile(rf"<!-- begin {re.escape(name)} -->.*?<!-- end {re.escape(name)} -->",
                         re.DOTALL)
    text = pattern.sub(lambda _: section, text) if pattern.search(text) else (
        text.rstrip() + "\n\n" + section + "\n")
    BENCHMARKS.write_text(text)


def worker_json(command: list, env: dict | None = None) -> dict:
    """Run a benchmark worker in a fresh process; its last line of output, read as JSON.

    A failing worker raises with its stderr, so that the reason is not lost.
    """
    done = subprocess.run(command, env=env, capture_output=True, text=True, check=False)
    if done.returncode:
        raise RuntimeError(f"worker {command[1:]} failed:\n{done.stderr}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def time_commands(commands: dict, repeats: int) -> dict:
    """Wall seconds of whole commands, ``{label: [repeats times]}``: each run once to warm
    the caches, then the commands in turn, ``repeats`` rounds (so that a drift of the
    machine's speed falls on all of them alike). A failing command raises with its stderr."""
    def run(command):
        tic = time.perf_counter()
        done = subprocess.run(command, capture_output=True, text=True, check=False)
        if done.returncode:
            raise RuntimeError(f"{' '.join(map(str, command))} failed:\n{done.stderr}")
        return time.perf_counter() - tic

    for command in commands.values():
        run(command)
    times = {label: [] for label in commands}
    for _ in range(repeats):
        for label, command in commands.items():
            times[label].append(run(command))
    return times


def commit_of(tree) -> str:
    """The short commit hash a checkout is at ("?" where git cannot say)."""
    done = subprocess.run(["git", "-C", str(tree), "rev-parse", "--short", "HEAD"],
                          capture_output=True, text=True, check=False)
    return done.stdout.strip() or "?"
