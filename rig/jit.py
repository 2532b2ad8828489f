"""``numba.njit`` that imports numba when a kernel is first called, not when its module is imported.

Importing numba costs 0.2 - 0.4 s, and compiled kernels are needed by the simulations only: a
command that reads a run file and analyses it (``daq analyze``), lists scenes or prints help never
calls one and should not pay for it. ``@njit(cache=True, ...)`` here takes numba's options and
returns a :class:`LazyKernel`; the first call of any lazy kernel imports numba, turns *every*
registered kernel into its numba dispatcher (the same options, the same on-disk cache) and
replaces the lazy objects by the dispatchers in the namespaces of the modules of the packages
that define kernels (the packages of the registered functions, found at run time: this module
names none), so that kernels calling kernels see dispatchers when numba compiles them. Calls
through a reference held elsewhere are forwarded (about 0.3 us each).

numba's on-disk cache (``cache=True``) checks a function's own source file only (numba/numba#1833):
a kernel that calls one in another file would keep its stale compiled code when only the callee
changes. So before importing numba, :func:`materialise` points ``NUMBA_CACHE_DIR`` at a directory
named after a hash of the source of every kernel file (:func:`cache_dir`): any change to any
kernel starts a fresh cache, and kernels may call kernels across files. A ``NUMBA_CACHE_DIR``
set by the caller is kept (the caller owns it, e.g. a cold-start benchmark), and so is numba's
default if numba was imported before (it reads the variable at import). A new directory's older
siblings are pruned (:func:`prune_cache_dirs`: the newest few are kept, and any used within a day),
so edits do not pile up compiled code.
"""

from __future__ import annotations

import hashlib
import os
import sys
import threading
from pathlib import Path

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
        if "numba" not in sys.modules and "NUMBA_CACHE_DIR" not in os.environ:
            path = cache_dir()
            if not path.exists():
                prune_cache_dirs(path)
            os.environ["NUMBA_CACHE_DIR"] = str(path)
        import numba

        for k in _registry:
            if k._dispatcher is None:
                k._dispatcher = numba.njit(**k.options)(k.py_func)
        packages = kernel_packages()
        for name, mod in list(sys.modules.items()):
            if name.split(".")[0] not in packages or mod is None:
                continue
            space = getattr(mod, "__dict__", None)
            if not space:
                continue
            for key, value in list(space.items()):
                if isinstance(value, LazyKernel) and value._dispatcher is not None:
                    space[key] = value._dispatcher


def kernel_packages() -> set[str]:
    """The top-level packages of the modules that define registered kernels."""
    return {k.__module__.split(".")[0] for k in _registry}


def kernel_sources() -> list[Path]:
    """Every ``.py`` file that defines lazy kernels, in the packages of the registered ones
    (found by the decorator's name in the source, so files not yet imported count too)."""
    files = set()
    for top in sorted(kernel_packages()):
        for root in getattr(sys.modules.get(top), "__path__", []):
            files.update(p for p in Path(root).rglob("*.py")
                         if "__pycache__" not in p.parts and "@njit(" in p.read_text("utf-8"))
    return sorted(files)


def cache_dir() -> Path:
    """``<this package>/__pycache__/numba-<hash>`` (``$XDG_CACHE_HOME/pendulum-daq/numba-<hash>``
    where the package is read-only): the hash (SHA-256, 16 hex digits) of the kernel files'
    names and contents and of the Python version."""
    h = hashlib.sha256(sys.version.encode())
    for p in kernel_sources():
        h.update(str(p).encode())
        h.update(p.read_bytes())
    name = f"numba-{h.hexdigest()[:16]}"
    local = Path(__file__).resolve().parent / "__pycache__"
    if os.access(local if local.exists() else local.parent, os.W_OK):
        return local / name
    # an installed, read-only package: the user's cache directory instead
    user = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return user / "pendulum-daq" / name


#: :func:`prune_cache_dirs` keeps this many of the newest sibling cache directories...
KEEP_CACHE_DIRS = 3
#: ... and every one modified less than this long ago [s] (another checkout may be using it)
KEEP_CACHE_AGE_S = 86400.0


def prune_cache_dirs(current: Path, *, keep: int = KEEP_CACHE_DIRS,
                     min_age_s: float = KEEP_CACHE_AGE_S) -> list[Path]:
    """Remove the ``numba-*`` siblings of ``current`` (kernel caches of earlier sources) except
    the ``keep`` most recently modified and those modified within ``min_age_s`` seconds;
    ``current`` itself is never removed. Best effort (a directory that cannot be removed stays).
    Returns the directories removed."""
    import shutil
    import time

    parent = current.parent
    if not parent.is_dir():
        return []
    found = []
    for p in parent.glob("numba-*"):
        if p.is_dir() and p.name != current.name:
            try:
                found.append((p.stat().st_mtime, p))
            except OSError:
                continue
    found.sort(reverse=True)
    now = time.time()
    removed = []
    for i, (mtime, p) in enumerate(found):
        if i < keep or now - mtime < min_age_s:
            continue
        shutil.rmtree(p, ignore_errors=True)
        if not p.exists():
            removed.append(p)
    return removed
