"""Trace data as the 35670A sends it: ``FORM:DATA ASC`` (comma-separated decimals) or
``REAL,32`` / ``REAL,64`` in an IEEE 488.2 definite-length block (``#<n><length><bytes>``,
big-endian IEEE 754, the instrument's byte order).

ASCII numbers have ``digits`` significant digits (default 17: a float64 reads back exactly);
non-finite ASCII values are sent as SCPI's ``9.91E+37`` (NaN), ``+-9.9E+37`` (infinity); binary
blocks carry IEEE 754 NaN and infinities as they are (the 0 Hz line of a ratio is NaN: the
analyzer's detrend removes it).
"""

from __future__ import annotations

import numpy as np

__all__ = ["FORMATS", "encode", "definite_block"]

#: FORM:DATA choices: name -> (kind, size).
FORMATS = {"ASC": ("ascii", 0), "REAL,32": ("real", 32), "REAL,64": ("real", 64)}

NAN_VALUE, INF_VALUE = 9.91e37, 9.9e37


def definite_block(payload: bytes) -> bytes:
    """``#<n><length><payload>`` (IEEE 488.2 7.7.6.2); ``n`` = digits of the length (1..9)."""
    length = str(len(payload))
    if len(length) > 9:
        raise ValueError(f"a definite-length block holds at most 999,999,999 bytes, "
                         f"got {len(payload)}")
    return b"#" + str(len(length)).encode() + length.encode() + payload


def encode(values, fmt: str, digits: int = 17) -> str | bytes:
    """``values`` (real, 1-D) as ``fmt`` (a key of :data:`FORMATS`): str for ASCII, the block
    bytes for REAL (non-finite values as in the module docstring)."""
    v = np.asarray(values, dtype=float).ravel()
    kind, size = FORMATS[fmt]
    if kind == "ascii":
        if not np.all(np.isfinite(v)):
            v = np.where(np.isnan(v), NAN_VALUE, v)
            v = np.where(np.isposinf(v), INF_VALUE, v)
            v = np.where(np.isneginf(v), -INF_VALUE, v)
        return ",".join(f"{x:+.{digits - 1}E}" for x in v)
    dtype = ">f4" if size == 32 else ">f8"
    return definite_block(v.astype(dtype).tobytes())
