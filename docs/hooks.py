"""MkDocs hooks: pages generated from the code at build time, so they cannot go stale.

- ``api.md``: one section per name in ``brdfjax.__all__`` (mkdocstrings renders each
  docstring from the module that defines it, found through ``brdfjax._EXPORTS``).
- ``cli.md``: the ``--help`` of every command and sub-command of ``brdfjax``.
- ``models.md``: every model of `brdfjax.models`: its module's docstring (the formula, and
  what the code does where the formula breaks down) and its parameters' default ranges
  (a ``|`` in a reason is escaped, so it stays inside its table cell).
- The notebooks in ``notebooks/`` and the figures of ``BENCHMARKS.md`` are added as pages and
  files from where they live, so nothing is copied into ``docs/``.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from mkdocs.plugins import event_priority
from mkdocs.structure.files import File

REPO = Path(__file__).resolve().parents[1]
# The figures BENCHMARKS.md shows, copied beside its page.
EXTRA_FILES = ("benchmarks/profile.png", "benchmarks/anytime.png",
               "benchmarks/predictive_bands.png", "benchmarks/plan.png",
               "benchmarks/adaptive.png")
ESCAPED_BAR = "\\|"  # a "|" inside a Markdown table cell


@event_priority(100)  # before mkdocs-jupyter, which turns the .ipynb files into pages
def on_files(files, config):
    sources = sorted(p.relative_to(REPO).as_posix() for p in (REPO / "notebooks").glob("*.ipynb"))
    for path in [*sources, *EXTRA_FILES]:
        files.append(File(path, src_dir=str(REPO), dest_dir=config["site_dir"],
                          use_directory_urls=config["use_directory_urls"]))
    return files


def on_page_markdown(markdown, page, config, files):
    for marker, generate in (("<!-- brdfjax-api -->", api_markdown),
                             ("<!-- brdfjax-cli -->", cli_markdown),
                             ("<!-- brdfjax-models -->", models_markdown)):
        if marker in markdown:
            return markdown.replace(marker, generate())
    return markdown


def api_markdown() -> str:
    import brdfjax

    sections = []
    for name in brdfjax.__all__:
        module = brdfjax._EXPORTS[name]
        sections.append(f"## `brdfjax.{name}`\n\n*Defined in `{module}`.*\n\n"
                        f"::: {module}.{name}\n")
    return "\n".join(sections)


def models_markdown() -> str:
    import inspect

    from brdfjax.models import available, get

    sections = []
    for name in available():
        model = get(name)
        module = inspect.getmodule(type(model))
        rows = [f"| `{p.name}` | {p.low:g} | {p.high:g} | {p.scale} | "
                f"{p.reason.replace('|', ESCAPED_BAR)} |" for p in model.parameters]
        sections.append("\n".join([
            f"## `{name}`", "", (f"{model.summary[0].upper()}{model.summary[1:]}. *Defined in "
            f"`{module.__name__}`.*"), "",
            inspect.cleandoc(module.__doc__), "",  # Markdown: formulas are indented blocks
            "| parameter | low | high | searched on | why this range |", "|---|---|---|---|---|",
            *rows, ""]))
    import brdfjax.models.sum as sums

    sections.append("## Sums of models: `A+B`\n\n" + inspect.cleandoc(sums.__doc__) + "\n")
    return "\n".join(sections)


def cli_markdown() -> str:
    from brdfjax.cli import build_parser

    # argparse wraps help text to the terminal's width: 80 columns fit the page's code
    # block at 1280 px (100 ran past its right edge); narrower screens wrap (extra.css).
    os.environ["COLUMNS"] = "80"
    sections = []
    for path, parser in commands(build_parser(), ["brdfjax"]):
        sections.append(f"## `{' '.join(path)}`\n\n```text\n{parser.format_help()}```\n")
    return "\n".join(sections)


def commands(parser, path):
    """(path, parser) of the parser and every sub-command under it, depth first."""
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from commands(sub, [*path, name])
