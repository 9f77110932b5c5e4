"""Sub-commands of the ``brdfjax`` CLI, and the option parsers they share."""

from __future__ import annotations

import argparse
import os
import shlex
from pathlib import Path

import numpy as np


def parameters(text: str, model: str = "five") -> np.ndarray:
    """Comma-separated parameters of ``model`` in its order, or a paper sample's name.

    The paper's samples (``white_paint``, ...) are parameters of the five-parameter model.
    """
    from brdfjax.models import get
    from brdfjax.models.paper import PAPER_SAMPLES

    names = get(model).names
    if text in PAPER_SAMPLES:
        if model != "five":
            raise ValueError(f"--params {text}: the paper's samples are parameters of the "
                             f"five model, not of {model}")
        return np.array(PAPER_SAMPLES[text], dtype=float)
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        values = []
    if len(values) != len(names):
        raise ValueError(
            f"--params {text!r}: give {len(names)} numbers {','.join(names)} for the {model} "
            f"model" + (f", or a paper sample ({', '.join(PAPER_SAMPLES)})"
                        if model == "five" else ""))
    return np.array(values)


def edited_command(argv, command: str, edits: dict, append=()) -> str:
    """A command line to suggest, made from the user's own (``argv``: the sub-command and
    its arguments, as `brdfjax.cli.main` keeps them in ``args.argv``).

    ``command`` replaces the sub-command. Each option named in ``edits`` (in full, as the
    parser takes them, ``--opt value`` or ``--opt=value``) has its value passed through
    ``edits[option]``, which gives the value to keep or None to leave the option out;
    every other argument is kept as given. ``append`` follows, before a ``--`` if there is
    one. Quoted for a POSIX shell."""
    tokens, kept = list(argv[1:]), [command]
    while tokens:
        token = tokens.pop(0)
        if token == "--":  # what follows is positional
            kept += list(append) + [token] + tokens
            break
        name, equals, value = token.partition("=")
        if name not in edits or not (equals or tokens):
            kept.append(token)
            continue
        value = edits[name](value if equals else tokens.pop(0))
        if value is not None:
            kept += [f"{name}={value}"] if equals else [name, value]
    else:
        kept += list(append)
    return "brdfjax " + shlex.join(kept)


def add_model_option(parser, help_text: str = "the model") -> None:
    """``--model NAME`` (the five-parameter model by default; names checked when used, so
    that ``--help`` needs no JAX)."""
    parser.add_argument("--model", default="five", metavar="NAME",
                        help=f"{help_text}: five (default), {OTHER_MODELS}")


# The models besides the paper's, for --help (which imports no JAX, so not from
# brdfjax.models; tests/test_cli.py checks the list against brdfjax.models.available()).
OTHER_MODELS = ("torrance-sparrow, ggx, beckmann, lambert, rpv, backscatter, abg, ross-li, or "
                "a sum A+B such as ggx+backscatter")


def angles(text: str) -> np.ndarray:
    """Degrees as ``10,30,60`` or an inclusive range ``START:STOP:STEP`` (STEP > 0,
    START <= STOP)."""
    try:
        values = [float(x) for x in text.split(":" if ":" in text else ",")]
        if ":" in text:
            start, stop, step = values
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r}: give degrees as 10,30,60 or START:STOP:STEP") from None
    if not np.all(np.isfinite(values)):
        raise argparse.ArgumentTypeError(f"{text!r}: give finite numbers of degrees")
    if ":" not in text:
        return np.array(values)
    if not step > 0 or not start <= stop:
        raise argparse.ArgumentTypeError(
            f"{text!r}: a range START:STOP:STEP runs upwards with a positive step, "
            f"e.g. {min(start, stop):g}:{max(start, stop):g}:{abs(step) or 1:g}")
    return np.arange(start, stop + step / 2, step)


def zeniths(text: str) -> np.ndarray:
    """`angles` that are zenith angles: in [0, 90] degrees (an argparse type)."""
    from brdfjax.angles import check_degrees

    values = angles(text)
    try:
        check_degrees(zenith=values)
    except ValueError:
        outside = values[(values < 0) | (values > 90)]
        raise argparse.ArgumentTypeError(
            f"{outside[0]:g} deg: zenith angles lie in [0, 90] deg (a signed in-plane angle "
            "t is theta_r = |t|, with phi_r 180 on the specular side, else 0)") from None
    return values


def at_least(minimum: int):
    """An argparse type: a whole number of at least ``minimum``."""
    def whole_number(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r}: give a whole number") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{value}: give at least {minimum}")
        return value

    return whole_number


positive_int = at_least(1)


def reader_options(args) -> dict:
    """Keyword options for `brdfjax.data.formats.load` from the common file options."""
    options = {}
    if getattr(args, "blank", None):
        options["blank"] = args.blank
    if getattr(args, "in_plane", False):
        options["in_plane"] = True
    wavelength = getattr(args, "wavelength", None)
    if wavelength is not None:
        try:  # batch's --wavelength may also be "all" or a list (one sample each)
            options["wavelength_nm"] = float(wavelength)
        except ValueError:
            pass
    return options


def _check_figure_format(label: str, given: str) -> None:
    from matplotlib.backend_bases import FigureCanvasBase

    formats = FigureCanvasBase.get_supported_filetypes()
    if Path(given).suffix.lower().lstrip(".") not in formats:
        raise ValueError(f"{label} {given}: name the figure with the extension of a format "
                         f"matplotlib writes, e.g. .png, .pdf or .svg (all: "
                         f"{', '.join(sorted(formats))})")


def add_reader_options(parser, spectral: bool = False) -> None:
    parser.add_argument("--blank", help="RT-300S blank .xls to subtract (default: the "
                                        "blank_*.xls beside the file)")
    parser.add_argument("--in-plane", action="store_true",
                        help="RT-300S .xls: read the plane of incidence only (Azimuth -90, "
                             "as brdfjax read these files before 3-D reading), not every "
                             "azimuth of the scan")
    if spectral:
        parser.add_argument("--wavelength", metavar="NM|all|NM,NM",
                            help="multi-wavelength files (NIST, ASTM, Zemax): read one "
                                 "wavelength, or fit every wavelength (all) or those listed "
                                 "as samples of their own, with a wavelength_nm column")
    else:
        parser.add_argument("--wavelength", type=float, metavar="NM",
                            help="wavelength to read from multi-wavelength files (NIST, "
                                 "Zemax, ASTM)")


def check_writable(files: dict | None = None, folders: dict | None = None,
                   figures: dict | None = None) -> None:
    """Fail now, before any work, if an output cannot be written where the user asked.

    Each file's folder must exist and take a new file (tried for real: permission bits
    alone say nothing to root or on a read-only mount); a folder must be a folder or be
    creatable under the nearest existing one; a figure's name must end in a format
    matplotlib writes (it takes the format from the name). Errors name the option and the
    path as the user gave them.

    Args:
        files: ``{"--json": "fit.json", "output": ...}``; None values (options not given)
            are skipped.
        folders: the same for output folders (created later if missing).
        figures: the same for figures (``{"--plot": "fit.png"}``).
    """
    for label, given in (figures or {}).items():
        if given is not None:
            _check_figure_format(label, given)
    for label, given in {**(files or {}), **(figures or {})}.items():
        if given is None:
            continue
        path = Path(given)
        if path.is_dir():
            raise ValueError(f"{label} {given}: is a folder; give a file name")
        _check_folder(label, given, path.parent)
        if path.exists() and not os.access(path, os.W_OK):
            raise ValueError(f"{label} {given}: the file exists and is not writable")
    for label, given in (folders or {}).items():
        if given is None:
            continue
        path = Path(given)
        if path.exists() and not path.is_dir():
            raise ValueError(f"{label} {given}: exists and is not a folder")
        existing = path
        while not existing.exists() and existing != existing.parent:
            existing = existing.parent
        _check_folder(label, given, existing)


def _check_folder(label: str, given, folder: Path) -> None:
    """Raise if ``folder`` is missing, not a folder, or refuses a new file."""
    if not folder.exists():
        raise ValueError(f"{label} {given}: the folder {folder} does not exist")
    if not folder.is_dir():
        raise ValueError(f"{label} {given}: {folder} is not a folder")
    probe = folder / f".brdfjax-write-test-{os.getpid()}"
    try:
        os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
        os.unlink(probe)
    except FileExistsError:
        pass  # another run's probe: the folder takes files
    except OSError as error:
        raise ValueError(f"{label} {given}: cannot write in {folder} "
                         f"({error.strerror})") from None
