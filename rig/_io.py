"""Safe output files: nothing existing is overwritten without ``force``; a file appears complete or
not at all (written under a temporary name in the same directory, then renamed), with the mode
the user's umask gives a new file. Also the version every written file records
(:func:`software_version`). Private infrastructure of the packages above."""

from __future__ import annotations

import contextlib
import functools
import importlib.metadata
import os
import tempfile
from pathlib import Path

from rig.errors import ConfigError, ForceRequired


def check_writable(path: Path, *, force: bool) -> Path:
    """Validate an output path before any work is done; returns it as a :class:`Path`."""
    path = Path(path)
    if path.is_symlink() and not path.exists():
        if not force:
            raise ForceRequired(f"output {str(path)!r} is a symbolic link to "
                                f"{os.readlink(path)!r}, which does not exist",
                                "replace the link by the file")
        return path
    if path.exists() and not force:
        raise ForceRequired(f"output {str(path)!r} exists")
    if path.exists() and path.is_dir():
        raise ConfigError(f"output {str(path)!r} is a directory; expected a file path")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise ConfigError(f"output {str(path)!r}: directory {str(parent)!r} does not exist")
    if not os.access(parent, os.W_OK):
        raise ConfigError(f"output {str(path)!r}: directory {str(parent)!r} is not writable")
    return path


def umask_mode(mode: int = 0o666) -> int:
    """``mode`` less the process's umask: what ``open()`` would give a new file (a temporary
    file from :func:`tempfile.mkstemp` is 0600 whatever the umask)."""
    mask = os.umask(0)
    os.umask(mask)
    return mode & ~mask


@contextlib.contextmanager
def atomic_output(path: Path, *, force: bool, suffix: str = ""):
    """Yield a temporary path beside ``path``; on success rename it to ``path``, on error remove it.

    The existing file (if any, and only with ``force``) is replaced only once the new one is
    complete.
    """
    path = check_writable(path, force=force)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix or path.suffix,
                               dir=path.parent if str(path.parent) else ".")
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        if path.exists() and not force:  # appeared meanwhile
            raise ForceRequired(f"output {str(path)!r} exists")
        os.chmod(tmp_path, umask_mode())  # the user's umask, as for any new file
        os.replace(tmp_path, path)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


@functools.lru_cache(maxsize=1)
def software_version() -> str:
    """The installed version of pendulum-daq (written into every file the project makes); read
    once per process (the package's metadata is parsed: ~4 ms, every run of a sweep paid it)."""
    try:
        return importlib.metadata.version("pendulum-daq")
    except importlib.metadata.PackageNotFoundError:  # pragma: no cover - not installed
        return "unknown"


def write_columns_csv(path, header, columns, *, force: bool = False) -> Path:
    """Write equal-length ``columns`` as CSV under the row ``header``, one row per index, every
    value as ``repr(float)`` (it reads back bit for bit); never over an existing file without
    ``force``, and the file appears whole or not at all (:func:`atomic_output`). Returns the
    path."""
    import csv

    path = Path(path)
    with atomic_output(path, force=force) as tmp:
        with open(tmp, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(header)
            for row in zip(*columns):
                w.writerow([repr(float(v)) for v in row])
    return path
