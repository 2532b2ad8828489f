"""Validation helpers shared by the rig's parameter classes: errors name the key, the value and
what is valid (:class:`rig.errors.ConfigError`)."""

from __future__ import annotations

import math

from rig.errors import ConfigError


def finite_at_least(where: str, value, *, lo: float, strict: bool, unit: str) -> float:
    """``value`` as a float if it is a finite number >= ``lo`` (> ``lo`` if ``strict``), else a
    ConfigError naming ``where``, the value and the bound with its ``unit``."""
    ok = not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)
    if not ok or value < lo or (strict and value == lo):
        rel = ">" if strict else ">="
        raise ConfigError(f"{where} = {value!r} is invalid: expected a finite number {rel} {lo:g}"
                          f" {unit}")
    return float(value)
