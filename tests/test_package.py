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
