"""Optional packages: a missing one is a clear error that says what to install.

The core (fitting, reflectance, files) needs none of them; Dask (``--scheduler``), emcee
(``--uncertainty mcmc``) and pyserial (the instrument driver) come with brdfjax's extras.
The command line prints a `MissingDependency` as one line and exits 1; any other
ImportError is a bug and keeps its traceback.
"""

from __future__ import annotations

import importlib
from types import ModuleType


class MissingDependency(ImportError):
    """An optional package that the requested work needs is not installed."""


def require(module: str, extra: str, purpose: str, package: str | None = None) -> ModuleType:
    """Import ``module``, or raise `MissingDependency` naming the extra that installs it.

    Args:
        module: the module to import (``dask.distributed``).
        extra: brdfjax's extra that installs it (``batch``).
        purpose: what needs it, as the user asked for it (``--scheduler``).
        package: the package's name where it is not the module's (``pyserial``).
    """
    try:
        return importlib.import_module(module)
    except ImportError as missing:
        raise MissingDependency(f"{purpose} needs {package or module.split('.')[0]}, which is "
                                f"not installed here: pip install 'brdfjax[{extra}]' (in a "
                                f"checkout of brdfjax: pip install -e '.[{extra}]')") from missing
