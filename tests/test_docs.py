"""The documentation site builds in strict mode and documents every public name."""

import html
import inspect
import os
import re
import subprocess
import sys
from pathlib import Path

import griffe
import pytest
from conftest import REPO

import brdfjax
from brdfjax.cli import build_parser
from brdfjax.models import available, get


def test_every_public_name_has_a_docstring():
    package = griffe.load("brdfjax", search_paths=[str(REPO)])
    missing = []
    for name in brdfjax.__all__:
        module = brdfjax._EXPORTS[name].removeprefix("brdfjax.")
        docstring = package[f"{module}.{name}"].docstring
        if docstring is None or not docstring.value.strip():
            missing.append(name)
    assert missing == []


@pytest.mark.timeout(300)
def test_the_site_builds_strictly_with_every_name_command_and_notebook(tmp_path):
    """A broken reference, a missing include or an unknown page fails the strict build.

    The notebooks are rendered without running them (``make docs`` runs them), which keeps
    this test to seconds.
    """
    site = tmp_path / "site"
    done = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site)],
        cwd=REPO, capture_output=True, text=True, timeout=290, check=False,
        env={**os.environ, "BRDFJAX_DOCS_EXECUTE": "false", "NO_MKDOCS_2_WARNING": "1"})
    assert done.returncode == 0, done.stderr[-3000:]
    api = (site / "api" / "index.html").read_text()
    assert all(f"brdfjax.{name}</code>" in api for name in brdfjax.__all__)
    cli = (site / "cli" / "index.html").read_text()
    for action in build_parser()._subparsers._group_actions:
        assert all(f"usage: brdfjax {name}" in cli for name in action.choices)
    assert "usage: brdfjax instrument simulate" in cli
    assert "brdfjax fit data/synthetic/white_paint.csv" in (site / "index.html").read_text()
    assert "Where the formulas break" in (site / "model" / "index.html").read_text()
    models = html.unescape(re.sub(r"<[^>]+>", "", (site / "models" / "index.html").read_text()))
    for name in available():  # each model's section, formula (its docstring) and whole box
        model = get(name)
        module = inspect.getmodule(type(model))
        docstring = inspect.getdoc(module)
        assert f"Defined in {module.__name__}." in models, name
        assert docstring.splitlines()[0].replace("``", "") in models, name
        assert all(p.reason in models for p in model.parameters), name  # '|' kept in its cell
    for figure in ("profile", "anytime", "plan", "adaptive"):  # BENCHMARKS.md's figures
        assert (site / "benchmarks" / f"{figure}.png").is_file(), figure
    for notebook in (REPO / "notebooks").glob("*.ipynb"):
        assert (site / "notebooks" / notebook.stem / "index.html").is_file(), notebook.name


def test_the_readme_states_parameter_order_per_model_and_no_missing_file():
    """The README's model table gives each model's parameters in the code's order; it claims
    no single order for every model, points to no file a clone lacks (MODELS.md) and has
    no option jargon (throw=False) where a user reads what a fit does."""
    readme = (REPO / "README.md").read_text()
    rows = dict(re.findall(r"^\| `([\w-]+)`(?: \(default\))? \| ([\w ,]+) \|", readme, re.MULTILINE))
    assert set(rows) == set(available())
    for name, parameters in rows.items():
        assert tuple(p.strip() for p in parameters.split(",")) == get(name).names, name
    assert "always ordered" not in readme
    assert "MODELS.md" not in readme and "throw=False" not in readme
    for path in re.findall(r"`((?:brdfjax|docs|data|notebooks|benchmarks)/[\w./-]+)`", readme):
        assert (REPO / path.rstrip(".")).exists() or "*" in path, path


def test_cli_help_and_code_blocks_are_not_cut_on_the_right():
    """The Command line page's --help fits its code block (80 columns; it was written at
    100 and ran past the right edge), and the site's stylesheet wraps code blocks and lets
    a wide table scroll in its own box instead of cutting either off."""
    sys.path.insert(0, str(REPO / "docs"))
    try:
        import hooks
    finally:
        sys.path.remove(str(REPO / "docs"))
    previous = os.environ.get("COLUMNS")
    try:
        page = hooks.cli_markdown()
    finally:
        if previous is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = previous
    longest = max(page.splitlines(), key=len)
    assert len(longest) <= 80, longest
    config = (REPO / "mkdocs.yml").read_text()
    assert re.search(r"^extra_css:\n  - stylesheets/extra.css$", config, re.MULTILINE)
    css = (REPO / "docs" / "stylesheets" / "extra.css").read_text()
    assert re.search(r"pre > code[^{]*\{[^}]*white-space: pre-wrap", css)
    assert re.search(r"jupyter-wrapper\) \.md-sidebar--secondary \{\s*display: none", css)


def test_no_page_or_docstring_cites_a_file_the_project_does_not_have():
    """Eight docstrings, six of them on the Models page, cited "MODELS.md", a file no clone
    has (issue 47, defect 5): they cite the papers and the docs' own pages instead."""
    sys.path.insert(0, str(REPO / "docs"))
    try:
        import hooks
    finally:
        sys.path.remove(str(REPO / "docs"))
    missing = "MODELS" + ".md"
    assert missing not in hooks.models_markdown()
    files = [REPO / "README.md", *(REPO / "docs").glob("*.md"),
             *(REPO / "brdfjax").rglob("*.py"), *(REPO / "tests").glob("*.py"),
             *(REPO / "benchmarks").glob("*.py")]
    citing = [str(path.relative_to(REPO)) for path in files
              if missing in path.read_text(encoding="utf-8") and path != Path(__file__)]
    assert citing == []
    assert not (REPO / missing).exists()
