"""``numba.njit`` that imports numba when a kernel is first called, not when its module is imported.

Importing numba costs 0.2 - 0.4 s, and compiled kernels are needed by the simulations only: a
command that reads a run file and analyses it (``daq analyze``), lists scenes or prints help never
calls one and should not pay for it. ``@njit(cache=True, ...)`` here takes numba's options and
returns a :class:`LazyKernel`; the first call of any lazy kernel imports numba, turns *every*
registered kernel into its numba dispatcher (the same options, the same on-disk cache) and
replaces the lazy objects by the dispatchers in the namespaces of the project's modules, so that
kernels calling kernels see dispatchers when numba compiles them. Calls through a reference taken
before that (``from rig.x import kernel``) are forwarded (about 0.3 us each).
"""

from __future__ import annotations

import sys
import threading

#: packages whose module namespaces are patched (their kernels call each other by global name)
PACKAGES = ("rig", "daq", "processing")

_registry: list["LazyKernel"] = []
_lock = threading.RLock()


class LazyKernel:
    """A Python function and the options of its future numba dispatcher."""

    def __init__(self, func, options: dict):
        self.py_func = func
        self.options = dict(options)
        self._dispatcher = None
        self.__name__ = func.__name__
        self.__qualname__ = func.__qualname__
        self.__module__ = func.__module__
        self.__doc__ = func.__doc__
        self.__wrapped__ = func

    @property
    def dispatcher(self):
        """The numba dispatcher (imports numba and materialises all kernels on first use)."""
        if self._dispatcher is None:
            materialise()
        return self._dispatcher

    def __call__(self, *args, **kwargs):
        d = self._dispatcher
        if d is None:
            d = self.dispatcher
        return d(*args, **kwargs)

    def __getattr__(self, name):  # e.g. .signatures, .inspect_types of the dispatcher
        if name.startswith("__") or name in ("_dispatcher", "py_func", "options"):
            raise AttributeError(name)
        return getattr(self.dispatcher, name)

    def __repr__(self):
        state = "compiled on demand" if self._dispatcher is None else "materialised"
        return f"<LazyKernel {self.__module__}.{self.__qualname__} ({state})>"


def njit(**options):
    """``numba.njit(**options)`` deferred to the first call (module docstring)."""
    def wrap(func):
        kernel = LazyKernel(func, options)
        with _lock:
            _registry.append(kernel)
        return kernel
    return wrap


def materialise() -> None:
    """Import numba, make every registered kernel's dispatcher and patch the namespaces."""
    with _lock:
        import numba

        for k in _registry:
            if k._dispatcher is None:
                k._dispatcher = numba.njit(**k.options)(k.py_func)
        for name, mod in list(sys.modules.items()):
            if name.split(".")[0] not in PACKAGES or mod is None:
                continue
            space = getattr(mod, "__dict__", None)
            if not space:
                continue
            for key, value in list(space.items()):
                if isinstance(value, LazyKernel) and value._dispatcher is not None:
                    space[key] = value._dispatcher
