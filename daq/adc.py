"""The analog-to-digital converter of one channel: range, resolution, rounding and clipping.

A ``bits``-bit ADC with input range ``+-range_v`` has::

    lsb_v = 2 range_v / 2^bits                          (305.2 uV for +-10 V at 16 bit)
    code  = clip(round(volts / lsb_v), code_min, code_max),  code_min = -2^(bits-1),
                                                         code_max = 2^(bits-1) - 1
    volts = code * lsb_v + offset_v                      (offset_v = 0: a bipolar, offset-free ADC)

Rounding is to the nearest code (ties to even, :func:`numpy.rint`), so an in-range sample is
reproduced within LSB/2. A sample whose nearest code lies outside ``[code_min, code_max]`` is
clipped to the end code and flagged; the flags are counted per record and channel by the
acquisition. Codes are stored in the smallest signed integer type that holds them (int16 for 9..16 bits).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rig.errors import ConfigError

MIN_BITS, MAX_BITS = 2, 32


def code_dtype(bits: int) -> np.dtype:
    """Smallest signed integer type holding ``bits``-bit two's-complement codes."""
    for dt in (np.int8, np.int16, np.int32):
        if bits <= np.iinfo(dt).bits:
            return np.dtype(dt)
    raise ConfigError(f"adc_bits = {bits} is invalid: expected {MIN_BITS} .. {MAX_BITS}")


@dataclass(frozen=True)
class ADC:
    """An ideal bipolar ADC (see the module docstring).

    Attributes
    ----------
    range_v : full scale, the input range is +-range_v [V] (> 0).
    bits : resolution, 2 .. 32.
    lsb_v, offset_v, code_min, code_max, dtype : derived on construction.
    """

    range_v: float
    bits: int = 16

    def __post_init__(self):
        if isinstance(self.bits, bool) or not isinstance(self.bits, (int, np.integer)) or not (
                MIN_BITS <= self.bits <= MAX_BITS):
            raise ConfigError(f"adc_bits = {self.bits!r} is invalid: expected an integer "
                              f"{MIN_BITS} .. {MAX_BITS}")
        if not (isinstance(self.range_v, (int, float)) and math.isfinite(self.range_v)
                and self.range_v > 0):
            raise ConfigError(f"ADC range = {self.range_v!r} V is invalid: expected a finite "
                              "number > 0 (the input range is +-range)")

    @property
    def lsb_v(self) -> float:
        """Size of one code step [V]."""
        return 2.0 * self.range_v / 2.0 ** self.bits

    @property
    def offset_v(self) -> float:
        """Volts of code 0 [V] (0: bipolar, offset-free)."""
        return 0.0

    @property
    def code_min(self) -> int:
        return -(2 ** (self.bits - 1))

    @property
    def code_max(self) -> int:
        return 2 ** (self.bits - 1) - 1

    @property
    def dtype(self) -> np.dtype:
        """Storage type of the codes."""
        return code_dtype(self.bits)

    def digitize(self, volts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Quantise ``volts`` [V] (any shape, finite).

        Returns
        -------
        codes : same shape, :attr:`dtype`.
        clipped : same shape, bool: True where the nearest code was out of range.
        """
        r = np.rint((np.asarray(volts, dtype=float) - self.offset_v) / self.lsb_v)
        clipped = (r < self.code_min) | (r > self.code_max)
        np.clip(r, self.code_min, self.code_max, out=r)
        return r.astype(self.dtype), clipped

    def volts(self, codes: np.ndarray) -> np.ndarray:
        """Volts of ``codes``: ``code * lsb_v + offset_v`` [V] (float64)."""
        return np.asarray(codes, dtype=float) * self.lsb_v + self.offset_v

    def describe(self) -> dict:
        return {"range_v": float(self.range_v), "bits": int(self.bits), "lsb_v": self.lsb_v,
                "offset_v": self.offset_v, "code_min": self.code_min, "code_max": self.code_max,
                "dtype": self.dtype.name}
