"""Lazy re-exports for a package's ``__init__.py`` (PEP 562): a public name is imported from its
module on first use and kept in the package's namespace, so importing the package costs no more
than its directory. A public submodule is an attribute too, imported on first use, so
``import daq; daq.hdf5.read_run`` works as written."""

from __future__ import annotations

import importlib
import importlib.util


def lazy_exports(package: str, exports: dict[str, tuple[str, str]], namespace: dict):
    """``(__getattr__, __dir__)`` for the package ``package`` whose public names map to
    ``(module, attribute)`` in ``exports``; ``namespace`` is the package's ``globals()``."""

    def __getattr__(name: str):
        try:
            module, attr = exports[name]
        except KeyError:
            if name.startswith("_") or importlib.util.find_spec(f"{package}.{name}") is None:
                raise AttributeError(f"module {package!r} has no attribute {name!r}") from None
            return importlib.import_module(f"{package}.{name}")  # sets namespace[name] itself
        value = getattr(importlib.import_module(module), attr)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(exports))

    return __getattr__, __dir__
