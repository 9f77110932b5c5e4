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
from pathlib import Path

BENCHMARKS = Path(__file__).resolve().parents[1] / "BENCHMARKS.md"
PREAMBLE = """# Benchmarks

Measured, not claimed: every number below comes from a script in `benchmarks/`, run as
shown, on the machine named in its section. Rerun one with the command given; rerun all
with `make bench`.
"""


def machine() -> str:
    """A one-line description of this machine and the library versions that matter."""
    import jax
    import numpy

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return (f"{os.cpu_count()} cores ({cpu}), Python {platform.python_version()}, "
            f"jax {jax.__version__} on {jax.default_backend()}, numpy {numpy.__version__}")


def write_section(name: str, body: str) -> None:
    """Replace (or append) the section ``name`` of BENCHMARKS.md with ``body``."""
    command = "python " + " ".join([os.path.relpath(sys.argv[0])] + sys.argv[1:])
    stamp = datetime.date.today().isoformat()
    section = (f"<!-- begin {name} -->\n{body.rstrip()}\n\n"
               f"*Machine: {machine()}. Command: `{command}`. Date: {stamp}.*\n"
               f"<!-- end {name} -->")
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
