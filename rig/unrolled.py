"""Kernels generated for one set of sizes and one exact-zero pattern: written, cached, loaded.

A loop over a small dense matrix (the coupled bench's ``Phi`` is 12 x 12 on the paper's rig) runs
through memory: numba's loops over runtime sizes keep the accumulators in arrays and do not
vectorise. The same arithmetic written out as straight-line code on scalars (one local per matrix
entry and per state) stays in registers, and the products by the matrices' exact zeros can be
left out. A method that generates such code (etdab: :func:`rig.solvers.etdab.etdab_kernel`)
compiles it with :func:`load`.

Generated modules are written once under ``<numba cache dir>/unrolled/<name>_<hash>.py`` (the
hash of their text: any change of the generator or of the pattern is a new file), imported from
there and compiled with ``cache=True``, so a second process loads the compiled code from numba's
on-disk cache instead of compiling again. Writes are atomic (a temporary file, then
``os.replace``) and an existing file is never rewritten, so concurrent workers agree. Where no
cache directory is writable the module goes to a fresh temporary directory (compiled per
process, the same code).

Public API: :func:`load`.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import sys
import tempfile
import threading
from pathlib import Path



_lock = threading.RLock()
_loaded: dict[str, object] = {}
_by_pattern: dict[tuple, object] = {}




def load(source: str, name: str, options: dict):
    """``numba.njit(**options)`` of function ``name`` defined by ``source`` (a module's text),
    written to and imported from the cache directory (module docstring)."""
    digest = hashlib.sha256(source.encode()).hexdigest()[:16]
    key = f"{name}_{digest}"
    with _lock:
        got = _loaded.get(key)
        if got is not None:
            return got
        from rig.jit import materialise

        materialise()  # numba imported with the kernels' cache directory; rig's kernels compiled
        import numba

        path = _write_once(_module_dir() / f"{key}.py", source)
        spec = importlib.util.spec_from_file_location(f"rig._unrolled_{key}", path)
        mod = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = mod
        spec.loader.exec_module(mod)
        got = numba.njit(**options)(getattr(mod, name))
        _loaded[key] = got
        return got


def _module_dir() -> Path:
    """``unrolled/`` in numba's cache directory (the kernels' one, :func:`rig.jit.cache_dir`),
    or a fresh temporary directory where that is not writable."""
    from rig.jit import cache_dir

    base = Path(os.environ.get("NUMBA_CACHE_DIR") or cache_dir())
    path = base / "unrolled"
    try:
        path.mkdir(parents=True, exist_ok=True)
        if os.access(path, os.W_OK):
            return path
    except OSError:
        pass
    return Path(tempfile.mkdtemp(prefix="pendulum-daq-unrolled-"))


def _write_once(path: Path, text: str) -> Path:
    """``path`` holding ``text``: written atomically if absent (or different), else left as it is
    (its modification time is numba's cache key for the functions it defines)."""
    try:
        if path.read_text("utf-8") == text:
            return path
    except OSError:
        pass
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.stem, suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path
