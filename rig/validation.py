"""Validation helpers shared by every layer's parameter checks: a bad value gets a one-line error
naming the key, the value and what is valid, ``<where> = <value> is invalid: expected <valid>``
(a :class:`rig.errors.ConfigError` unless the caller names its own error class, e.g.
``processing``'s ``SettingsError``; both are ``ValueError``)."""

from __future__ import annotations

import math
import numbers

from rig.errors import ConfigError


def shown(value) -> str:
    """``repr(value)``, a numpy scalar shown as the Python number it holds (``0.5``, not
    ``np.float64(0.5)``), an integer of more than 20 digits by its size (``an integer of 401
    digits``)."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 66:
        return f"an integer of about {int(value.bit_length() * math.log10(2)) + 1} digits"
    return repr(value.item() if type(value).__module__ == "numpy" else value)


def as_float(value) -> float:
    """``float(value)``, or ``inf`` (with the sign) for an integer too large for a float (which
    ``float`` refuses with OverflowError): then it is not finite, and refused as such."""
    try:
        return float(value)
    except OverflowError:
        return math.inf if value > 0 else -math.inf


def _is_real(value) -> bool:
    """A real number (Python's or numpy's, which register as :class:`numbers.Real`), not a
    bool."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _bound(rel: str, x: float, unit: str) -> str:
    return f"{rel} {x:g}" + (f" {unit}" if unit else "")


def number(where: str, value, *, lo: float | None = None, hi: float | None = None,
           lo_open: bool = False, hi_open: bool = False, allow_inf: bool = False,
           unit: str = "", valid: str | None = None, error: type = ConfigError) -> float:
    """``value`` as a float if it is a real number (not a bool or a string), finite (or
    infinite within the bounds if ``allow_inf``; never NaN), ``>= lo`` (``> lo`` if ``lo_open``)
    and ``<= hi`` (``< hi`` if ``hi_open``); else ``error`` naming ``where``, the value and
    ``valid`` (default: "a finite number" and the bounds, with ``unit``)."""
    ok = _is_real(value)
    if ok:
        v = as_float(value)
        ok = (not math.isnan(v) and (allow_inf or math.isfinite(v))
              and (lo is None or v > lo or (v == lo and not lo_open))
              and (hi is None or v < hi or (v == hi and not hi_open)))
    if not ok:
        if valid is None:
            parts = ["a number" if allow_inf else "a finite number"]
            if lo is not None:
                parts.append(_bound(">" if lo_open else ">=", lo, "" if hi is not None else unit))
            if hi is not None:
                parts.append(("and " if lo is not None else "")
                             + _bound("<" if hi_open else "<=", hi, unit))
            valid = " ".join(parts)
        raise error(f"{where} = {shown(value)} is invalid: expected {valid}")
    return v


def positive(where: str, value, *, hi: float | None = None, allow_inf: bool = False,
             unit: str = "", valid: str | None = None, error: type = ConfigError) -> float:
    """:func:`number` ``> 0`` (and ``<= hi``): "a finite number > 0" (with ``unit``), or with
    ``allow_inf`` also ``inf``."""
    return number(where, value, lo=0.0, lo_open=True, hi=hi, allow_inf=allow_inf, unit=unit,
                  valid=valid, error=error)


def integer(where: str, value, *, minimum: int, valid: str | None = None,
            error: type = ConfigError) -> int:
    """``value`` as an int if it is an integer (Python's or numpy's, not a bool, not a float)
    ``>= minimum``; else ``error`` naming ``where``, the value and ``valid`` (default "an
    integer >= minimum")."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        valid = valid or f"an integer >= {minimum}"
        raise error(f"{where} = {shown(value)} is invalid: expected {valid}")
    return int(value)


def finite_at_least(where: str, value, *, lo: float, strict: bool, unit: str) -> float:
    """``value`` as a float if it is a finite number >= ``lo`` (> ``lo`` if ``strict``), else a
    ConfigError naming ``where``, the value and the bound with its ``unit``."""
    return number(where, value, lo=lo, lo_open=strict, unit=unit)
