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


def test_import_brdfjax_loads_no_jax():
    code = "import sys, brdfjax; print('jax' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "False"
