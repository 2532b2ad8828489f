"""Following a run while it is acquired: the averaged H1 estimate updated as records land.

:func:`follow_run` reads a run file that ``daq acquire`` is still writing (HDF5 SWMR: the reader
reads ``records_complete`` first, then that many rows, so it never sees a half-written record)
and yields a :class:`FollowUpdate` every time more records have landed: the RMS-averaged H_t and
Theta_2 (H1, the analyzer's spectral settings) of the records so far, their coherence, and how far
they are from the exact model stored in the file. It stops when the run has ended (status no
longer "acquiring" and every record read) or when the writer is gone without ending it (killed:
the file's writer lock is free). If several records land between two polls, one update covers
them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Iterator

import numpy as np

__all__ = ["FollowUpdate", "follow_run"]


@dataclass(frozen=True, eq=False)
class FollowUpdate:
    """The averaged estimate after ``records`` of ``records_planned`` records.

    Attributes
    ----------
    records, records_planned : records averaged, records the run plans.
    status : the file's status when read ("acquiring" while the writer runs).
    freqs_hz : (nf,) the analyzer's lines within the display band [Hz].
    h_t, theta_2 : (nf,) complex H1 estimates [m per m/s^2], [rad per m/s^2].
    coherence_x, coherence_y : (nf,) gamma^2 of (a, x) and (a, y).
    h_t_rms_db, theta_2_rms_db : RMS over the band of 20 log10 |estimate / exact model| [dB].
    time_left_s : the run's time left [s] at the rate records have landed so far (the 35670A's
        "average n of N" display with its time to go); None until two landings have been seen
        or once every record is in.
    """

    records: int
    records_planned: int
    status: str
    freqs_hz: np.ndarray
    h_t: np.ndarray
    theta_2: np.ndarray
    coherence_x: np.ndarray
    coherence_y: np.ndarray
    h_t_rms_db: float
    theta_2_rms_db: float
    time_left_s: float | None = None

    def line(self) -> str:
        left = "" if self.time_left_s is None else f", {self.time_left_s:.0f} s left"
        return (f"average {self.records} of {self.records_planned}{left}: "
                f"H_t {self.h_t_rms_db:.2f} dB "
                f"rms from the model, Theta_2 {self.theta_2_rms_db:.2f} dB "
                f"({self.freqs_hz[0]:g}-{self.freqs_hz[-1]:g} Hz), mean coherence "
                f"{np.nanmean(self.coherence_x):.3f} / {np.nanmean(self.coherence_y):.3f}")


def _time_left(landed: list[tuple[float, int]], planned: int) -> float | None:
    """Seconds until ``planned`` records are in, at the mean rate between the first and the
    last landing seen (None before two landings, or when nothing is left)."""
    (t_a, n_a), (t_b, n_b) = landed[0], landed[-1]
    if n_b >= planned or n_b <= n_a or t_b <= t_a:
        return None
    return (planned - n_b) * (t_b - t_a) / (n_b - n_a)


def _writer_alive(path: Path) -> bool:
    """Whether a writer holds the run file's lock (daq.hdf5.Hdf5Sink takes a shared one)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: assume it is
        return True
    try:
        fh = open(path, "rb")
    except OSError:  # gone meanwhile
        return False
    with fh:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            return True
        fcntl.flock(fh, fcntl.LOCK_UN)
    return False


def _estimate(recording, settings) -> FollowUpdate:
    from processing.analyzer import CHANNELS, model_at_lines
    from processing.frf import frequency_response
    from processing.spectra import segment_ffts

    h = recording.header
    spectral = settings.spectral(h.plan.rate_hz, h.plan.samples)
    ffts = segment_ffts({c: recording.values(c) for c in CHANNELS}, spectral,
                        units={c: h.channel(c).unit for c in CHANNELS})
    h_t = frequency_response(ffts, "a", "x")
    theta_2 = frequency_response(ffts, "a", "y")
    f = spectral.freqs_hz
    band = (f >= settings.fmin_hz) & (f <= settings.fmax_hz)
    model = model_at_lines(h, f[band])

    def rms_db(est, exact):
        with np.errstate(divide="ignore", invalid="ignore"):
            d = 20 * np.log10(np.abs(est / exact))
        return float(np.sqrt(np.nanmean(d ** 2)))

    return FollowUpdate(
        records=recording.records, records_planned=h.plan.records, status=recording.status,
        freqs_hz=f[band], h_t=h_t.h[band], theta_2=theta_2.h[band],
        coherence_x=h_t.coherence[band], coherence_y=theta_2.coherence[band],
        h_t_rms_db=rms_db(h_t.h[band], model.h_t),
        theta_2_rms_db=rms_db(theta_2.h[band], model.theta_2))


def follow_run(path: str | Path, settings=None, *, poll_s: float = 0.2,
               open_timeout_s: float = 60.0, orphan_s: float = 1.0) -> Iterator[FollowUpdate]:
    """Yield the averaged estimate each time more records of the run file ``path`` have landed
    (module docstring), until the run ends. ``settings``: a
    :class:`processing.analyzer.AnalyzerSettings` (default: the paper's).

    Waits up to ``open_timeout_s`` for the file to appear (the acquisition may start after the
    follower) and for its writer to make it readable. A file that exists, is not readable and
    that no writer holds is refused at once if it is older than ``orphan_s`` (else after
    ``orphan_s``: a writer takes its lock just after creating the file) with the checker's reason (e.g. truncated). Raises
    :class:`rig.errors.ConfigError` in these cases, and for settings the run cannot take (e.g. a
    time record longer than a record)."""
    from daq.hdf5 import run_status, open_run, read_run
    from processing.analyzer import AnalyzerSettings
    from rig.output_files import not_a_file
    from rig.errors import ConfigError

    settings = settings if settings is not None else AnalyzerSettings()
    path = Path(path)
    t0, seen, orphan_since = time.monotonic(), 0, None
    landed: list[tuple[float, int]] = []  # (monotonic time, records in the file) at each landing
    while True:
        try:
            with open_run(path) as f:
                status, n = run_status(f)
        except (ConfigError, OSError, KeyError) as exc:  # not yet (or not now) readable
            now = time.monotonic()
            why = not_a_file(path)
            if why is not None and path.exists():  # a FIFO, a directory: never a run file
                raise ConfigError(f"run file {str(path)!r} {why}") from None
            if not path.exists():
                orphan_since = None
                if now - t0 > open_timeout_s:
                    raise ConfigError(f"{str(path)!r} did not appear within {open_timeout_s:g} "
                                      "s: start the acquisition that writes it (daq acquire "
                                      "--out), or wait longer") from None
            elif not _writer_alive(path):
                orphan_since = now if orphan_since is None else orphan_since
                if now - orphan_since >= orphan_s or _age_s(path) >= orphan_s:
                    raise ConfigError(_unreadable(path, exc) + "; no writer holds it, so it "
                                      "will not become readable") from None
            else:
                orphan_since = None
            if now - t0 > open_timeout_s:
                raise ConfigError(f"{str(path)!r} did not become a readable run file within "
                                  f"{open_timeout_s:g} s: {exc}") from None
            time.sleep(poll_s)
            continue
        t0, orphan_since = time.monotonic(), None
        if n > seen:
            rec = read_run(path, records=range(n))
            seen = n
            landed.append((time.monotonic(), n))
            update = _estimate(rec, settings)
            yield replace(update, time_left_s=_time_left(landed, update.records_planned))
        if status != "acquiring" and n == seen:
            return
        if status == "acquiring" and not _writer_alive(path):
            with open_run(path) as f:  # a last look: records that landed before it died
                status, n = run_status(f)
            if n == seen:
                return
            continue
        time.sleep(poll_s)


def _age_s(path: Path) -> float:
    """Seconds since ``path`` was last modified (0 if it is gone)."""
    try:
        return time.time() - path.stat().st_mtime
    except OSError:
        return 0.0


def _unreadable(path: Path, exc: BaseException) -> str:
    """Why ``path`` is not a readable run file, as ``daq check`` says it."""
    from daq.check import check_file

    fc = check_file(path)
    return fc.line() if not fc.ok else f"{str(path)!r} is not a readable run file: {exc}"
