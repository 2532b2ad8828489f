"""Lazy re-exports for a package's ``__init__.py`` (PEP 562): a public name is imported from its
module on first use and kept in the package's namespace, so importing the package costs no more
than its directory. A public submodule is an attribute too, imported on first use, so
``import daq; daq.hdf5.read_run`` works as written."""

from __future__ import annotations

import importlib
import importlib.util


def submodule_getattr(package: str):
    """A ``__getattr__`` for the package ``package`` that imports a public submodule when it is
    first used as an attribute (``rig.bench.modes`` after ``import rig``), and raises
    AttributeError for any other name."""

    def __getattr__(name: str):
        if name.startswith("_") or importlib.util.find_spec(f"{package}.{name}") is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return importlib.import_module(f"{package}.{name}")  # binds it in the package

    return __getattr__


def lazy_exports(package: str, exports: dict[str, tuple[str, str]], namespace: dict):
    """``(__getattr__, __dir__)`` for the package ``package`` whose public names map to
    ``(module, attribute)`` in ``exports``; ``namespace`` is the package's ``globals()``."""

    submodule = submodule_getattr(package)

    def __getattr__(name: str):
        if name not in exports:
            return submodule(name)
        module, attr = exports[name]
        value = getattr(importlib.import_module(module), attr)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(exports))

    return __getattr__, __dir__
