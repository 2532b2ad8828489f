"""What a run needs -- disk space for its file, memory for its records -- checked before anything
is simulated, and how a full disk is recognised when it happens anyway.

:func:`preflight` refuses a run whose file could exceed the free space of the output's directory
or whose memory need exceeds the machine's memory, with a ConfigError naming the setting, the
estimate and what is available. The estimates are upper bounds (no compression counted): the
file is the channels' int16 codes, the per-sample clip and saturation flags and the float64
ground truth of every record, plus the exact model response on the record's FFT grid; the memory
is a few copies of one record of those and of the model response's arrays (the acquisition
holds one record at a time).
"""

from __future__ import annotations

import errno
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

from rig.errors import ConfigError

__all__ = ["RunNeeds", "estimate_needs", "run_file_bytes", "is_disk_full",
           "machine_memory_bytes", "preflight"]

_RESPONSES = 40  # model responses stored (real and imaginary parts count once: complex)
_FIXED_FILE = 256 * 1024  # metadata, scales, scene, attributes
_TRUTH_SCALARS = 4  # stage acceleration, mirror translation and rotation, source volts


@dataclass(frozen=True)
class RunNeeds:
    """Upper estimates of what a run needs: ``file_bytes`` on disk, ``memory_bytes`` in RAM."""

    file_bytes: int
    memory_bytes: int


def _per_sample_bytes(channels: int, bodies: int, truth: bool) -> int:
    """Bytes per sample instant: each channel's int16 code and its clip and saturation flags,
    and the float64 ground truth (four scalars and one angle per body) if kept."""
    return channels * (2 + 1 + 1) + ((_TRUTH_SCALARS + bodies) * 8 if truth else 0)


def _response_bytes(samples: int) -> int:
    """Bytes of the model responses on the record's FFT grid (complex128)."""
    return (samples // 2 + 1) * _RESPONSES * 16


def run_file_bytes(*, records: int, samples: int, channels: int, bodies: int,
                   truth: bool) -> int:
    """Upper estimate of a run file's size [bytes] (no compression counted) for ``records``
    records of ``samples`` samples on ``channels`` channels, with the ground truth of a
    ``bodies``-body pendulum if ``truth``: the one size estimate of a run file (``daq acquire``'s
    preflight, a sweep's dry run)."""
    per_sample = _per_sample_bytes(channels, bodies, truth)
    return int(records * (samples * per_sample + 64) + _response_bytes(samples) + _FIXED_FILE)


def estimate_needs(*, records: int, samples: int, channels: int, bodies: int,
                   truth: bool) -> RunNeeds:
    """Upper estimates for ``records`` records of ``samples`` samples on ``channels`` channels,
    with the ground truth of a ``bodies``-body pendulum if ``truth``: the file
    (:func:`run_file_bytes`) and the memory."""
    per_sample = _per_sample_bytes(channels, bodies, truth)
    memory = 4 * samples * per_sample + 3 * _response_bytes(samples)
    return RunNeeds(run_file_bytes(records=records, samples=samples, channels=channels,
                                   bodies=bodies, truth=truth), int(memory))


def machine_memory_bytes() -> int | None:
    """Physical memory of the machine [bytes] (None if unknown)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not POSIX
        return None


def _size(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if n < 1000 or unit == "TB":
            return f"{n:.3g} {unit}"
        n /= 1000
    return f"{n:.3g} TB"  # pragma: no cover


def preflight(plan, scene, out: str | Path | None) -> RunNeeds:
    """Refuse (ConfigError) a run of ``plan`` (daq.records.RecordPlan) for ``scene`` whose
    estimated file exceeds the free space beside ``out`` (if given) or whose memory need exceeds
    the machine's memory; returns the estimates."""
    needs = estimate_needs(records=plan.records, samples=plan.samples,
                           channels=3,  # a, x, y (daq.channels)
                           bodies=scene.chain.n, truth=scene.acquisition.truth)
    mem = machine_memory_bytes()
    if mem is not None and needs.memory_bytes > mem:
        raise ConfigError(
            f"acquisition.record_s = {plan.record_s:g} s at {plan.rate_hz:g} Hz gives records "
            f"of {plan.samples} samples, which need about {_size(needs.memory_bytes)} of memory; "
            f"this machine has {_size(mem)}: shorten the records (or lower the rate)")
    if out is not None:
        parent = Path(os.path.abspath(out)).parent  # where it is written (a link is replaced)
        free = shutil.disk_usage(parent).free
        if needs.file_bytes > free:
            raise ConfigError(
                f"the run file could need up to {_size(needs.file_bytes)} ({plan.records} "
                f"records of {plan.samples} samples) but {str(parent)!r} has {_size(free)} "
                "free: free some space, write elsewhere or take fewer or shorter records")
    return needs


def is_disk_full(exc: BaseException) -> bool:
    """Whether ``exc`` (or what caused it) is a write failing for want of space (ENOSPC; HDF5
    reports it inside a RuntimeError/OSError message as errno 28)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if getattr(exc, "errno", None) in (errno.ENOSPC, errno.EDQUOT):
            return True
        text = str(exc)
        if "No space left on device" in text or f"errno = {errno.ENOSPC}," in text:
            return True
        exc = exc.__cause__ or exc.__context__
    return False
