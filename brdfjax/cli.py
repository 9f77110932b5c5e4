"""The ``brdfjax`` command line: one sub-command per task, each in `brdfjax.commands`.

User errors (bad data, bad options, missing files, instrument faults) become one line on
stderr and exit code 1; usage errors exit 2 (argparse). Warnings raised while a command runs
(NumPy's overflow ``RuntimeWarning``, JAX's ``UserWarning``) never reach the user raw: each
distinct one becomes a line ``brdfjax CMD: warning: ...`` after a command that succeeded,
and is dropped after one that failed, whose error says why. Nothing heavy is imported until
a command runs, so ``--help`` is instant.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import threading
import time
import warnings

from brdfjax.commands import OTHER_MODELS

# Each module defines ``register(subparsers)``, adding its commands with a ``run`` default.
COMMAND_MODULES = (
    "brdfjax.commands.fitting",
    "brdfjax.commands.models",
    "brdfjax.commands.data",
    "brdfjax.commands.datasets",
    "brdfjax.commands.batch",
    "brdfjax.commands.instrument",
    "brdfjax.commands.plan",
)


class _Parser(argparse.ArgumentParser):
    """Long options are taken in full only (argparse's ``allow_abbrev=False``; its sub-command
    parsers are of this class too): an abbreviation that works today would stop when a
    longer option shares its start, and the commands brdfjax suggests to run next
    (`brdfjax.commands.edited_command`) rename options by their full names."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, allow_abbrev=False, **kwargs)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="brdfjax",
        description="Fit BRDF models (the five-parameter model of Zhang, Wu, Cao and Zhang "
                    f"by default; {OTHER_MODELS}) to measured BRDF data, cross-validate "
                    "them and predict new geometry.")
    parser.add_argument("--version", action="version", version="brdfjax 0.1.0")
    verbose = "say how long each compiled stage took to trace, lower and compile (stderr)"
    parser.add_argument("-v", "--verbose", "--profile", action="store_true", help=verbose)
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(subparsers)
    for command in subparsers.choices.values():  # also after the command: brdfjax fit -v
        command.add_argument("-v", "--verbose", "--profile", action="store_true",
                             default=argparse.SUPPRESS, help=verbose)
    return parser


# Warnings for developers, not for someone running a command.
SILENT_WARNINGS = (DeprecationWarning, PendingDeprecationWarning, ImportWarning,
                   ResourceWarning, FutureWarning)


def main(argv=None) -> int:
    """Run one command; its exit code (0, 1 for user errors, 130 when interrupted).

    Run as a program (``argv`` None, in the main thread), the command works in a second
    thread while the main thread only waits, so Ctrl-C is seen at once even while XLA
    compiles or runs for a minute without returning to Python. The process then leaves
    through ``os._exit(130)`` after saying so: a normal exit would finalise the interpreter
    while the command's thread is still inside the JAX runtime, which ended in a
    segmentation fault (2 of 5 interrupted ``brdfjax batch`` runs). Nothing is lost by
    leaving at once: ``batch`` replaces its CSV whole after every chunk
    (`brdfjax.data.formats.write_atomically`), and no other command has written anything by
    then that a rerun would not write again. Called with ``argv`` (tests, scripts), the
    command runs in the calling thread and an interrupt returns 130.
    """
    args = build_parser().parse_args(argv)
    # The sub-command and its arguments, for commands that suggest another (the options
    # before it, -v alone, take no value: the first token that names it is it).
    given = list(sys.argv[1:] if argv is None else argv)
    args.argv = given[given.index(args.command):]
    if argv is not None or threading.current_thread() is not threading.main_thread():
        return _run(args)
    outcome = {}

    def work():
        try:
            outcome["code"] = _run(args)
        except BaseException as error:  # noqa: BLE001  (re-raised in the main thread)
            outcome["error"] = error

    worker = threading.Thread(target=work, name=f"brdfjax {args.command}", daemon=True)
    try:
        worker.start()
        while worker.is_alive():
            worker.join(0.1)
    except KeyboardInterrupt:
        print(f"\nbrdfjax {args.command}: interrupted", file=sys.stderr)
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(130)
    if "error" in outcome:
        raise outcome["error"]
    return outcome["code"]


def _run(args) -> int:
    """The command of ``args``, user errors turned into a line and exit code 1; at ``-v``
    with each compilation's time (`brdfjax.cache.report_compiles`) and their sum."""
    if not args.verbose:
        return _run_quietly(args)
    from brdfjax.cache import compile_seconds, report_compiles

    report_compiles()
    tic = time.perf_counter()
    try:
        return _run_quietly(args)
    finally:
        report_compiles(on=False)
        spent = ", ".join(f"{step} {seconds:.2f} s" for step, seconds in compile_seconds.items())
        print(f"compile: in all {spent or 'nothing compiled'}; the command took "
              f"{time.perf_counter() - tic:.2f} s", file=sys.stderr)


def _run_quietly(args) -> int:
    from brdfjax.data.measurements import DataError
    from brdfjax.optional import MissingDependency

    caught = {}

    def keep(message, category, filename, lineno, file=None, line=None):
        if not issubclass(category, SILENT_WARNINGS):  # one line per distinct text
            caught.setdefault(str(message).splitlines()[0], category)

    with warnings.catch_warnings():
        # "always": the filters the caller had (pytest's "error", say) must not turn a
        # numerical warning deep in a fit into an exception.
        warnings.simplefilter("always")
        warnings.showwarning = keep
        try:
            code = args.run(args) or 0
        except (DataError, ValueError, OSError, MissingDependency) as problem:
            print(f"brdfjax {args.command}: error: {problem}", file=sys.stderr)
            return 1
        except KeyboardInterrupt:
            print(f"brdfjax {args.command}: interrupted", file=sys.stderr)
            return 130
    if code == 0:
        for text, category in caught.items():
            print(f"brdfjax {args.command}: warning: {text} ({category.__name__})",
                  file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
