"""A run file a writer may have left open: its superblock read by hand, the file opened without
ever hanging, and the "open for writing" mark a killed writer leaves cleared (``h5clear -s``).

Nothing here knows the project's layout (:mod:`daq.hdf5`) or checks (:mod:`daq.check`); both
open files through :func:`open_hdf5`.
"""

from __future__ import annotations

import os
import struct
from pathlib import Path

from rig.output_files import not_a_file
from rig.errors import ConfigError

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX
    fcntl = None

__all__ = ["SWMR_READ_ATTEMPTS", "UnreadableFile", "clear_write_flags", "open_hdf5",
           "superblock", "write_flags", "writer_alive"]

_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def superblock(path: str | Path) -> dict | None:
    """The HDF5 superblock's version, file-consistency flags and end-of-file address, read
    directly from the file (no HDF5 call); None if the file does not start with the HDF5
    signature (user blocks are not searched: the project writes none) or is no regular file (a
    FIFO would block the read)."""
    if not_a_file(path) is not None:
        return None
    with open(path, "rb") as fh:
        head = fh.read(96)
    if len(head) < 9 or head[:8] != _SIGNATURE:
        return None
    version = head[8]
    try:
        if version >= 2:  # signature, version, offsets size, lengths size, flags, 4 addresses
            so = head[9]
            flags = head[11]
            first = 12
        else:  # v0/v1: versions of free space, root symbol table, shared header; sizes; ks; flags
            so = head[13]
            flags = struct.unpack_from("<I", head, 20)[0]
            first = 24 if version == 0 else 28
        fmt = {4: "<I", 8: "<Q"}[so]
        eof = struct.unpack_from(fmt, head, first + 2 * so)[0]
    except (KeyError, struct.error):
        return {"version": version, "flags": None, "eof": None}
    return {"version": version, "flags": flags, "eof": eof}


class UnreadableFile(ConfigError):
    """HDF5 cannot open the file: ``status`` is "not hdf5", "truncated" or "unreadable",
    ``reason`` the sentence saying why."""

    def __init__(self, path: Path, status: str, reason: str):
        super().__init__(f"{str(path)!r} is truncated: {reason}" if status == "truncated"
                         else f"{str(path)!r} is not a readable HDF5 file: {reason}")
        self.status, self.reason = status, reason


def open_hdf5(path: str | Path):
    """Open an HDF5 file read-only without ever hanging: ``(h5py.File, marked)``.

    A file shorter than its superblock's end-of-file address is refused as truncated before
    HDF5 sees it; a file marked "open for writing" (``marked``: a live or killed SWMR writer) is
    opened as a SWMR reader, any other in the plain mode, and a failed open is never retried in
    SWMR mode. Raises :class:`UnreadableFile` (a ConfigError) if it cannot be opened.
    """
    import h5py

    path = Path(path)
    size = path.stat().st_size
    sb = superblock(path)
    if sb is None:
        raise UnreadableFile(path, "not hdf5", f"not an HDF5 file ({size} bytes, no HDF5 "
                                               "signature)")
    if sb["eof"] is not None and size < sb["eof"]:
        raise UnreadableFile(path, "truncated", f"{size} of the {sb['eof']} bytes its "
                                                f"HDF5 superblock records ({sb['eof'] - size} "
                                                "missing); no HDF5 reader opens it")
    marked = bool(sb["flags"]) and sb["version"] >= 3
    try:
        f = _open_swmr(path) if marked else h5py.File(path, "r")
    except (OSError, KeyError) as exc:
        raise UnreadableFile(path, "unreadable", f"HDF5 cannot open it "
                                                 f"({first_line(exc)})") from None
    return f, marked


#: Metadata read attempts of a SWMR reader. HDF5's default (100) retries a checksum failure with
#: a doubling sleep from 1 ns capped at an hour per attempt -- days for a corrupt file; 24
#: attempts retry for ~17 ms in all, ample for a live writer's metadata flush.
SWMR_READ_ATTEMPTS = 24


def _hdf5_library():
    """The HDF5 C library h5py runs on (ctypes), or None if it cannot be found."""
    import ctypes
    import glob

    import h5py

    paths = []
    try:  # the library already loaded into this process (Linux)
        with open("/proc/self/maps") as fh:
            for line in fh:
                name = line.split()[-1]
                if Path(name).name.startswith("libhdf5") and ".so" in name:
                    paths.append(name)
    except OSError:
        pass
    paths += glob.glob(str(Path(h5py.__file__).parent.parent / "h5py.libs" / "libhdf5-*.so*"))
    for p in dict.fromkeys(paths):
        if Path(p).name.startswith("libhdf5_hl") or not Path(p).exists():
            continue
        try:
            lib = ctypes.CDLL(p)
            fn = lib.H5Pset_metadata_read_attempts
        except (OSError, AttributeError):
            continue
        fn.argtypes = [ctypes.c_int64, ctypes.c_uint]
        return lib
    return None


def _open_swmr(path: Path):
    """Open ``path`` as a SWMR reader with :data:`SWMR_READ_ATTEMPTS` metadata read attempts
    (a corrupt file fails in milliseconds instead of sleeping for days)."""
    import h5py

    lib = _hdf5_library()
    if lib is None:  # pragma: no cover - h5py without a findable HDF5: HDF5's default retries
        return h5py.File(path, "r", swmr=True)
    fapl = h5py.h5p.create(h5py.h5p.FILE_ACCESS)
    fapl.set_fclose_degree(h5py.h5f.CLOSE_STRONG)
    if lib.H5Pset_metadata_read_attempts(fapl.id, SWMR_READ_ATTEMPTS) < 0:  # pragma: no cover
        return h5py.File(path, "r", swmr=True)
    fid = h5py.h5f.open(str(path).encode(), h5py.h5f.ACC_RDONLY | h5py.h5f.ACC_SWMR_READ,
                        fapl=fapl)
    return h5py.File(fid)


def first_line(exc: BaseException) -> str:
    """The first line of ``exc``'s message (h5py's and HDF5's run on over several lines), or
    ``"no message"``: the reason quoted in a one-line report."""
    text = str(exc).strip().splitlines()
    return text[0] if text else "no message"


def write_flags(path: str | Path) -> int | None:
    """The superblock's file-consistency flags byte (non-zero: marked "open for writing"), or
    None if the file has no version 2/3 superblock at offset 0."""
    with open(path, "rb") as fh:
        head = fh.read(12)
    if len(head) < 12 or head[:8] != _SIGNATURE or head[8] < 2:
        return None
    return head[11]


def _lookup3(data: bytes, initval: int = 0) -> int:
    """Bob Jenkins' lookup3 ``hashlittle``: the checksum of HDF5's version 2/3 superblock."""
    mask = 0xFFFFFFFF

    def rot(x, k):
        return ((x << k) | (x >> (32 - k))) & mask

    length = len(data)
    a = b = c = (0xDEADBEEF + length + initval) & mask
    i = 0
    while length > 12:
        a = (a + int.from_bytes(data[i:i + 4], "little")) & mask
        b = (b + int.from_bytes(data[i + 4:i + 8], "little")) & mask
        c = (c + int.from_bytes(data[i + 8:i + 12], "little")) & mask
        a = (a - c) & mask; a ^= rot(c, 4); c = (c + b) & mask    # noqa: E702
        b = (b - a) & mask; b ^= rot(a, 6); a = (a + c) & mask    # noqa: E702
        c = (c - b) & mask; c ^= rot(b, 8); b = (b + a) & mask    # noqa: E702
        a = (a - c) & mask; a ^= rot(c, 16); c = (c + b) & mask   # noqa: E702
        b = (b - a) & mask; b ^= rot(a, 19); a = (a + c) & mask   # noqa: E702
        c = (c - b) & mask; c ^= rot(b, 4); b = (b + a) & mask    # noqa: E702
        i += 12
        length -= 12
    if length == 0:
        return c
    tail = data[i:] + bytes(12 - length)
    a = (a + int.from_bytes(tail[0:4], "little")) & mask
    b = (b + int.from_bytes(tail[4:8], "little")) & mask
    c = (c + int.from_bytes(tail[8:12], "little")) & mask
    c ^= b; c = (c - rot(b, 14)) & mask   # noqa: E702
    a ^= c; a = (a - rot(c, 11)) & mask   # noqa: E702
    b ^= a; b = (b - rot(a, 25)) & mask   # noqa: E702
    c ^= b; c = (c - rot(b, 16)) & mask   # noqa: E702
    a ^= c; a = (a - rot(c, 4)) & mask    # noqa: E702
    b ^= a; b = (b - rot(a, 14)) & mask   # noqa: E702
    c ^= b; c = (c - rot(b, 24)) & mask   # noqa: E702
    return c


def writer_alive(path: str | Path) -> bool:
    """True while a process holds a lock on ``path``: a run's writer holds a shared lock on its
    file from start to end (:class:`daq.hdf5.Hdf5Sink`), so a file whose status is still
    "acquiring" is being written if this is True, and was left by a killed writer if False.
    (Any other process holding a lock on it, e.g. an HDF5 reader with file locking, reads as
    alive too.) False where locks do not exist (not POSIX)."""
    if fcntl is None:  # pragma: no cover - not POSIX
        return False
    with open(path, "rb") as fh:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            return True
        fcntl.flock(fh, fcntl.LOCK_UN)
    return False


def clear_write_flags(path: str | Path) -> bool:
    """Clear the "open for writing" mark a killed writer left in the superblock (``h5clear -s``).

    Only the superblock's file-consistency flags byte and its checksum are rewritten. Refuses
    while the writer of a run is still alive (it holds a shared lock on the file). Returns True if
    a mark was cleared, False if there was none.
    """
    path = Path(path)
    why = not_a_file(path)
    if why is not None:
        raise ConfigError(f"run file {str(path)!r} {why}")
    flags = write_flags(path)
    if flags is None:
        raise ConfigError(f"{str(path)!r} has no version 2/3 HDF5 superblock at offset 0; "
                          "nothing to clear")
    if flags == 0:
        return False
    with open(path, "r+b") as fh:
        if fcntl is not None:
            try:
                fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                raise ConfigError(f"{str(path)!r} is still being written (its writer holds a "
                                  "lock); read it with SWMR instead") from None
        head = bytearray(fh.read(12))
        size_of_offsets = head[9]
        n = 12 + 4 * size_of_offsets
        fh.seek(0)
        sb = bytearray(fh.read(n + 4))
        if int.from_bytes(sb[n:n + 4], "little") != _lookup3(bytes(sb[:n])):
            raise ConfigError(f"{str(path)!r}: superblock checksum mismatch; not touching it")
        sb[11] = 0
        sb[n:n + 4] = _lookup3(bytes(sb[:n])).to_bytes(4, "little")
        fh.seek(0)
        fh.write(sb)
        fh.flush()
        os.fsync(fh.fileno())
    return True
