"""Scene parameters written once: a dataclass field's metadata holds its key's type, unit, default,
valid range and doc, and the scene's key tables, its validation and its documentation are
generated from it.

``param(default, doc, unit=..., lo=..., strict=...)`` declares a field (``dataclasses.field``
with a :class:`Key` in ``metadata["key"]``); :func:`keys_of` lists a class's keys in field order
(the order of the scene's sections, of ``daq scene show`` and of the settings stored in a run
file); :func:`check_fields` validates the fields that carry a static range (``__post_init__``),
with the project's one-line error: ``section.key = value is invalid: expected ...``.
:func:`check_value` checks one value against its :class:`Key` (type and choices), the check the
scene loader and a dataset sweep's axes share.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from typing import Any

from rig.errors import ConfigError
from rig.validation import as_float, finite_at_least, shown

REQUIRED = object()


@dataclass(frozen=True)
class Key:
    """One scene key: its type (``float``, ``int``, ``str``, ``bool``, ``floats`` = a number or a
    list of numbers), its default (``REQUIRED`` if none), a one-line description, the allowed
    choices, and, for a number with a static range, the bound ``lo`` (``strict``: ``> lo``, else
    ``>= lo``) and the unit named in the error."""

    type: str
    default: Any = REQUIRED
    doc: str = ""
    choices: tuple = ()
    unit: str = ""
    lo: float | None = None
    strict: bool = False


def param(default: Any, doc: str, *, unit: str = "", choices: tuple = (), lo: float | None = None,
          strict: bool = False, type: str | None = None) -> Any:
    """A dataclass field that is a scene key (see the module docstring); ``type`` defaults to the
    field's annotation."""
    key = Key(type or "", default, doc, tuple(choices), unit, lo, strict)
    return dataclasses.field(default=default, metadata={"key": key})


@functools.cache
def keys_of(cls) -> dict[str, Key]:
    """``{name: Key}`` of the fields of ``cls`` declared with :func:`param`, in field order
    (computed once per class; the table is shared: do not modify it)."""
    out = {}
    for f in dataclasses.fields(cls):
        key = f.metadata.get("key")
        if key is not None:
            out[f.name] = key if key.type else dataclasses.replace(key, type=str(f.type))
    return out


def check_fields(obj, section: str) -> None:
    """Validate (and coerce to float) every field of the frozen dataclass ``obj`` whose key has a
    static range, and every integer field with choices (the +1/-1 signs)."""
    for name, key in keys_of(type(obj)).items():
        value = getattr(obj, name)
        if key.lo is not None:
            object.__setattr__(obj, name, finite_at_least(f"{section}.{name}", value, lo=key.lo,
                                                          strict=key.strict, unit=key.unit))
        elif key.type == "int" and key.choices == (1, -1):
            if isinstance(value, bool) or value not in (1, -1):
                raise ConfigError(f"{section}.{name} = {shown(value)} is invalid: expected +1 or -1")
        elif key.type == "bool" and not isinstance(value, bool):
            raise ConfigError(f"{section}.{name} = {shown(value)} is invalid: expected true or false")


def check_value(where: str, key: Key, value: Any) -> Any:
    """``value`` checked against ``key``'s type and choices (ints and floats as given, numbers of
    a ``float`` key as float); ConfigError ``where = value is invalid: expected ...``."""
    if value is None and key.default is None:
        return None

    def number(v, what):
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ConfigError(f"{where} = {shown(v)} is invalid: expected {what}")
        if not math.isfinite(as_float(v)):
            raise ConfigError(f"{where} = {shown(v)} is invalid: expected a finite number")
        return float(v)

    def chosen(v):
        if key.choices and v not in key.choices:
            raise ConfigError(f"{where} = {shown(v)} is invalid: expected one of "
                              f"{', '.join(map(str, key.choices))}")
        return v

    if key.type == "float":
        return number(value, "a number")
    if key.type == "bool":
        if not isinstance(value, bool):
            raise ConfigError(f"{where} = {shown(value)} is invalid: expected true or false")
        return value
    if key.type == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{where} = {shown(value)} is invalid: expected an integer")
        return chosen(value)
    if key.type == "str":
        if not isinstance(value, str):
            raise ConfigError(f"{where} = {shown(value)} is invalid: expected a string")
        return chosen(value)
    if key.type == "floats":
        if isinstance(value, list):
            if not value:
                raise ConfigError(f"{where} = [] is invalid: expected a number or a non-empty list")
            for i, v in enumerate(value):
                if isinstance(v, bool) or not isinstance(v, (int, float)):
                    raise ConfigError(f"{where} of body {i + 1} = {shown(v)} is invalid: expected a "
                                      "number")
            return [number(v, "a finite number") for v in value]
        return number(value, "a number or a list of numbers")
    raise AssertionError(key.type)
