"""How large a live view's rerun recording (``.rrd``) grows, for the disk preflight of
``--rrd`` (no rerun import: it is checked before a run starts).

A recording holds, per output sample, the three channels in engineering units and in volts
with their time (:data:`BYTES_PER_SAMPLE`); per simulated second, the bench drawing's frames
(30 to 60 a second) and the moving lines (:data:`BYTES_PER_SECOND`); per record, the
analyzer's screen and the status (:data:`BYTES_PER_RECORD`); and once, the blueprint, the model
curves and static entities (:data:`BYTES_FIXED`). The constants are upper bounds of the sizes
rerun-sdk 0.41 writes (measured on runs of 2 and 4 records, 5 and 20 s, 100 to 500 Hz; rerun
compresses nothing of this), so the estimate is "at most", as the run file's is.
"""

from __future__ import annotations

__all__ = ["rrd_bytes_estimate", "BYTES_PER_SAMPLE", "BYTES_PER_SECOND", "BYTES_PER_RECORD",
           "BYTES_FIXED"]

BYTES_PER_SAMPLE = 64  # 6 float64 scalars and an int64 time: 56
BYTES_PER_SECOND = 8_000  # the drawing's frames and lines: ~5,800
BYTES_PER_RECORD = 20_000  # the analyzer's screen and the status: ~14,000
BYTES_FIXED = 500_000  # ~320,000


def rrd_bytes_estimate(*, records: int, record_s: float, rate_hz: float) -> int:
    """Upper estimate of the ``.rrd`` of a run of ``records`` records of ``record_s`` seconds
    sampled at ``rate_hz`` [bytes] (module docstring)."""
    per_record = BYTES_PER_RECORD + record_s * (BYTES_PER_SECOND + BYTES_PER_SAMPLE * rate_hz)
    return int(BYTES_FIXED + records * per_record)
