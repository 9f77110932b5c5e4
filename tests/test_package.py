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


def test_import_sets_the_llvm_level_unless_given():
    import os

    code = "import os, brdfjax; print(os.environ['XLA_FLAGS'])"

    def flags(given):
        env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
        env.update({"XLA_FLAGS": given} if given is not None else {})
        return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              check=True, env=env).stdout.split()

    assert flags(None) == ["--xla_backend_optimization_level=2"]
    assert flags("--xla_force_host_platform_device_count=2") == [
        "--xla_force_host_platform_device_count=2", "--xla_backend_optimization_level=2"]
    assert flags("--xla_backend_optimization_level=3") == ["--xla_backend_optimization_level=3"]
