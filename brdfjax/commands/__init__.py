"""Sub-commands of the ``brdfjax`` CLI, and the option parsers they share."""

from __future__ import annotations

import argparse

import numpy as np


def parameters(text: str) -> np.ndarray:
    """``kb,kr,a,b,kd`` or the name of a paper sample (``white_paint``, ...)."""
    from brdfjax.model import PAPER_SAMPLES

    if text in PAPER_SAMPLES:
        return np.array(PAPER_SAMPLES[text], dtype=float)
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 5:
        raise argparse.ArgumentTypeError(
            f"{text!r}: give five numbers kb,kr,a,b,kd or a paper sample "
            f"({', '.join(PAPER_SAMPLES)})")
    return np.array(values)


def angles(text: str) -> np.ndarray:
    """Degrees as ``10,30,60`` or an inclusive range ``START:STOP:STEP``."""
    try:
        if ":" in text:
            start, stop, step = (float(x) for x in text.split(":"))
            return np.arange(start, stop + step / 2, step)
        return np.array([float(x) for x in text.split(",")])
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r}: give degrees as 10,30,60 or START:STOP:STEP") from None


def reader_options(args) -> dict:
    """Keyword options for `brdfjax.formats.load` from the common file options."""
    options = {}
    if getattr(args, "blank", None):
        options["blank"] = args.blank
    if getattr(args, "wavelength", None) is not None:
        options["wavelength_nm"] = args.wavelength
    return options


def add_reader_options(parser) -> None:
    parser.add_argument("--blank", help="RT-300S blank .xls to subtract (default: the "
                                        "blank_*.xls beside the file)")
    parser.add_argument("--wavelength", type=float, metavar="NM",
                        help="wavelength to read from multi-wavelength files (NIST, Zemax)")
