"""The package surface: lazy imports, and public names that no submodule shadows."""

import importlib
import pkgutil
import subprocess
import sys

import brdfjax


def test_public_names_stay_functions_after_every_submodule_is_imported():
    for module in pkgutil.walk_packages(brdfjax.__path__, "brdfjax."):
        if not module.name.endswith("__main__"):
            importlib.import_module(module.name)
    for name in brdfjax.__all__:
        value = getattr(brdfjax, name)
        assert not isinstance(value, type(brdfjax)), f"brdfjax.{name} is a module"
    assert callable(brdfjax.fit) and callable(brdfjax.reflectance)


def test_submodules_come_on_first_use_like_the_names():
    """The README's ``brdfjax.cache.enable()`` and ``brdfjax.models.available()`` after a
    plain ``import brdfjax`` (they raised AttributeError)."""
    code = ("import brdfjax; print(callable(brdfjax.cache.enable), brdfjax.models.available()[0],"
            " callable(brdfjax.fit_per_incidence)); brdfjax.nothing")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=False)
    assert done.stdout.split() == ["True", "five", "True"]
    assert "AttributeError: module 'brdfjax' has no attribute 'nothing'" in done.stderr


def test_import_brdfjax_loads_no_jax():
    code = "import sys, brdfjax; print('jax' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "False"


def test_import_sets_the_xla_flags_unless_given():
    """LLVM at -O2, and on the jaxlib they were measured with, XLA:CPU's elemental emitters
    and while loops of any size compiled as one function; a setting given in XLA_FLAGS is
    kept. A jit then runs: XLA took the flags (it aborts on one it does not know)."""
    import os
    from importlib import metadata

    from brdfjax import _MEASURED_FLAGS, _MEASURED_JAXLIB

    code = ("import os, brdfjax, jax; jax.jit(lambda x: x + 1)(1.0).block_until_ready(); "
            "print(os.environ['XLA_FLAGS'])")

    def flags(given):
        env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
        env.update({"XLA_FLAGS": given} if given is not None else {})
        return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              check=True, env=env).stdout.split()

    level = "--xla_backend_optimization_level=2"
    emitters = "--xla_cpu_use_fusion_emitters=false"
    loops = "--xla_backend_extra_options=xla_cpu_small_while_loop_byte_threshold=1000000000"
    measured = metadata.version("jaxlib").startswith(_MEASURED_JAXLIB)
    assert [f"--{k}={v}" for k, v in _MEASURED_FLAGS.items()] == [emitters, loops]
    ours = [level] + ([emitters, loops] if measured else [])
    assert flags(None) == ours
    assert flags("--xla_force_host_platform_device_count=2") == [
        "--xla_force_host_platform_device_count=2", *ours]
    assert flags("--xla_backend_optimization_level=3") == [
        "--xla_backend_optimization_level=3", *ours[1:]]
    assert flags("--xla_cpu_use_fusion_emitters=true") == [
        "--xla_cpu_use_fusion_emitters=true", level] + ([loops] if measured else [])


# The stages in the README's Layout order: each imports only the stages above it.
STAGES = ("data", "models", "fitting", "uncertainty", "prediction")
# The data modules that evaluate a model, and so import brdfjax.models (which imports no
# data module): the writers of a fitted model's values and the synthetic sets.
EVALUATE_MODELS = ("brdfjax.data.formats.abg", "brdfjax.data.formats.astm",
                   "brdfjax.data.formats.zemax", "brdfjax.data.synthetic")


def _module_imports() -> tuple[dict, dict]:
    """Every brdfjax module's imports of other brdfjax modules, read statically (``ast``)
    from brdfjax/**/*.py: ``(every import, wherever it is), (those run when the module
    loads: not inside a function, nor under ``if TYPE_CHECKING``)``, each ``{module: set of
    modules}``. ``from a.b import c`` counts as an import of ``a.b.c`` where that is a
    module, else of ``a.b``; a package's ``__init__`` is the package's own name."""
    import ast
    from pathlib import Path

    root = Path(brdfjax.__file__).parent
    files = {}
    for path in root.rglob("*.py"):
        parts = ("brdfjax", *path.relative_to(root).with_suffix("").parts)
        files[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path

    def resolve(name: str) -> str | None:
        while name and name not in files:
            name = name.rpartition(".")[0]
        return name or None

    every, loaded = {}, {}
    for module, path in files.items():
        package = module if path.name == "__init__.py" else module.rpartition(".")[0]
        every[module], loaded[module] = set(), set()

        def visit(node, at_load: bool, module=module, package=package):
            deferred = isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda)
            if deferred or isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
                at_load = False
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parent = package.split(".")[:len(package.split(".")) - node.level + 1]
                    base = ".".join(parent + ([base] if base else []))
                names = [f"{base}.{alias.name}" for alias in node.names]
            else:
                names = []
            for name in names:
                target = resolve(name) if name.startswith("brdfjax") else None
                if target and target != module:
                    every[module].add(target)
                    if at_load:
                        loaded[module].add(target)
            for child in ast.iter_child_nodes(node):
                visit(child, at_load)

        visit(ast.parse(path.read_text(encoding="utf-8")), True)
    return every, loaded


def _cycles(graph: dict) -> list[list]:
    """The strongly connected components of more than one node (Tarjan): each a cycle."""
    index, low, stack, found = {}, {}, [], []

    def strong(node):
        index[node] = low[node] = len(index)
        stack.append(node)
        for other in sorted(graph.get(node, ())):
            if other not in index:
                strong(other)
                low[node] = min(low[node], low[other])
            elif other in stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            component = []
            while not component or component[-1] != node:
                component.append(stack.pop())
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            strong(node)
    return found


def _group(module: str) -> str:
    """A module's package below brdfjax (``fitting``), or the module itself where it sits
    at the top (``brdfjax.plot``)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 2 or module.endswith(tuple(f".{s}" for s in STAGES)) \
        else module


def test_no_import_cycle_between_stages_or_modules():
    """No stage package imports one that imports it back, by any import, even one deferred
    into a function (models/five.py and models/sum.py took ``to_unit`` from
    fitting.bounds, which imports models: issue 47, defect 10; fitting/cluster.py took
    the Laplace approximation from uncertainty, which imports fitting); every import
    between the stages goes down the README's order (but the data modules that evaluate a
    model, `EVALUATE_MODELS`); and no module imports, as it loads, one that imports it
    back as it loads."""
    every, loaded = _module_imports()
    assert len(every) > 50 and "brdfjax.models.five" in every  # it read the package
    packages: dict = {}
    edges = []
    for module, targets in every.items():
        for target in targets:
            if _group(module) != _group(target):
                packages.setdefault(_group(module), set()).add(_group(target))
                edges.append((module, target))
    cycles = _cycles(packages)
    assert not cycles, "import cycles between packages: " + "; ".join(
        " <-> ".join(cycle) + " (" + ", ".join(f"{a} -> {b}" for a, b in sorted(edges)
                                                if _group(a) in cycle and _group(b) in cycle)
        + ")" for cycle in cycles)
    upward = sorted((a, b) for a, b in edges if _group(a) in STAGES and _group(b) in STAGES
                    and STAGES.index(_group(b)) > STAGES.index(_group(a))
                    and a not in EVALUATE_MODELS)
    assert upward == [], f"a stage imports a stage below it: {upward}"
    assert not _cycles(loaded), f"modules that import each other as they load: {_cycles(loaded)}"
