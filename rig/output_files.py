"""Safe output files: nothing existing is overwritten without ``force``; a file appears complete or
not at all (written under a temporary name in the same directory, then renamed), with the mode
the user's umask gives a new file. Also the version every written file records
(:func:`software_version`). Private infrastructure of the packages above.

A temporary name (:func:`temp_beside`) carries its writer's host and process id,
``.<name>.<host>.<pid>.<random><suffix>``: the writer removes it on any failure or signal it
survives (SIGTERM and SIGHUP raise in the CLI, ``daq.signals``), and the next write to the same
path removes the ones whose writer is dead (SIGKILL, power loss) whatever their random part
(:func:`remove_stale_temps`); a live writer's file is never touched."""

from __future__ import annotations

import contextlib
import functools
import importlib.metadata
import os
import socket
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


def not_a_file(path: Path) -> str | None:
    """Why ``path`` is not a regular file one can read ("does not exist", "is a FIFO", "is a
    directory" ...), or None if it is one. Opening a FIFO for reading waits for a writer:
    commands ask this first."""
    import stat

    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return "does not exist"
    except OSError as exc:
        return f"cannot be read ({exc.strerror})"
    if stat.S_ISREG(mode):
        return None
    for test, what in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISSOCK, "a socket"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device")):
        if test(mode):
            return f"is {what}, not a regular file"
    return "is not a regular file"


def _host() -> str:
    return socket.gethostname().replace(".", "-")


def process_alive(pid: int) -> bool:
    """Whether process ``pid`` (of this host) may still write: it exists and is not a zombie (a
    killed process stays one until its parent reaps it, which a container's init may do late;
    it writes nothing more)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:  # gone meanwhile, or no /proc (not Linux: it exists, so it may write)
        return not Path("/proc").is_dir()
    return stat[stat.rindex(")") + 2:].split()[0] != "Z"  # "pid (comm) state ..."


def temp_beside(path: Path, suffix: str = "") -> Path:
    """A new empty file beside ``path`` named ``.<name>.<host>.<pid>.<random><suffix>`` (module
    docstring), with the mode the user's umask gives; ``suffix`` defaults to ``path``'s own
    (readers that go by the extension)."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{_host()}.{os.getpid()}.",
                               suffix=suffix or path.suffix,
                               dir=path.parent if str(path.parent) else ".")
    os.close(fd)
    os.chmod(tmp, umask_mode())  # what a new file gets (mkstemp's is 0600)
    return Path(tmp)


def remove_stale_temps(path: Path) -> list[Path]:
    """Remove the temporary files of ``path`` (:func:`temp_beside`) whose writer, a process of
    this host, is dead; returns them."""
    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    prefix = f".{path.name}.{_host()}."
    gone = []
    try:
        candidates = [p for p in parent.iterdir() if p.name.startswith(prefix)]
    except OSError:
        return gone
    for p in candidates:
        pid = p.name[len(prefix):].split(".", 1)[0]
        if pid.isdigit() and not process_alive(int(pid)):
            try:
                p.unlink()
                gone.append(p)
            except OSError:
                pass
    return gone


@contextlib.contextmanager
def atomic_output(path: Path, *, force: bool, suffix: str = "", reserve: bool = True,
                  durable: bool = False):
    """Yield a temporary path beside ``path`` (:func:`temp_beside`); on success rename it to
    ``path``, on error or interruption remove it. A dead writer's temporary files of ``path``
    are removed first (:func:`remove_stale_temps`).

    The existing file (if any, and only with ``force``) is replaced only once the new one is
    complete. Without ``force`` the new file is published with a hard link, which fails if
    ``path`` appeared meanwhile (another writer's file is never overwritten; ForceRequired);
    on a file system without hard links, by a check and a rename.

    ``reserve=False`` yields the name without creating the file (for a writer that creates its
    file itself and refuses an existing one); ``durable=True`` flushes the file to disk before
    it is renamed (for files a resumed run trusts after a crash).
    """
    path = check_writable(path, force=force)
    remove_stale_temps(path)
    tmp_path = temp_beside(path, suffix)
    if not reserve:
        tmp_path.unlink()
    try:
        yield tmp_path
        os.chmod(tmp_path, umask_mode())  # the user's umask, as for any new file
        if durable:
            fd = os.open(tmp_path, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
        _publish(tmp_path, path, force)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def _publish(tmp_path: Path, path: Path, force: bool) -> None:
    if force:
        os.replace(tmp_path, path)
        return
    try:
        os.link(tmp_path, path)
    except FileExistsError:  # appeared meanwhile
        raise ForceRequired(f"output {str(path)!r} exists") from None
    except OSError:  # no hard links here (e.g. FAT, some network file systems)
        if os.path.lexists(path):
            raise ForceRequired(f"output {str(path)!r} exists") from None
        os.replace(tmp_path, path)
        return
    tmp_path.unlink()


@functools.lru_cache(maxsize=1)
def software_version() -> str:
    """The installed version of pendulum-daq (written into every file the project makes); read
    once per process (parsing the package's metadata is not free, and every run of a sweep
    would pay it)."""
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
