"""A transport-independent SCPI 1999 / IEEE 488.2 engine: parse a program message, find each
header in a command table, call its handler, keep the error queue.

A *program message* (one line) holds program message units separated by ``;``. Each unit is a
header and its parameters (``FREQ:SPAN 10 HZ``). Headers follow SCPI 1999 vol. 1 ch. 6:

- a node matches its short form (the upper-case part of ``FREQuency``: ``FREQ``) or its long
  form, in any case; a node declared with ``#`` takes a numeric suffix (``CALC2``, ``INP3``;
  none means 1); an optional node (``[SENSe]``) may be left out;
- a query ends in ``?``; a common command starts with ``*``;
- header-path rule: after ``A:B:C``, a unit without a leading ``:`` starts at ``A:B``
  (``FREQ:SPAN 10;RES 800``); a leading ``:`` starts at the root; common commands leave the
  path alone.

Parameters: numbers (NR1/NR2/NR3, ``MIN``/``MAX``/``DEF`` for the handler to resolve) with an
optional unit and SI prefix (``10 HZ``, ``2.5KHZ``, ``1 MHZ`` = 1e6 Hz: SCPI reads ``M`` as
milli except in ``MHZ`` and ``MOHM``), character data (``RAND``), strings (``'XFR:POW 1'`` or
``"..."``) and booleans (``ON``/``OFF``/``1``/``0``).

Errors are :class:`ScpiError` with a real SCPI number and message (SCPI 1999 vol. 2 ch. 21);
they go to a bounded :class:`ErrorQueue` (``SYST:ERR?``), whose overflow replaces the newest
entry with ``-350,"Queue overflow"``. An unknown header is ``-113,"Undefined header"``, never
accepted in silence; after an error the rest of the line is still executed unit by unit.
"""

from __future__ import annotations

import collections
import math
import re
import threading
from dataclasses import dataclass
from typing import Callable

__all__ = ["ScpiError", "ErrorQueue", "Command", "CommandTable", "Param", "Engine",
           "ERROR_MESSAGES", "event_bit"]

#: SCPI 1999 error numbers used here, with their standard messages.
ERROR_MESSAGES = {
    0: "No error",
    -100: "Command error", -101: "Invalid character", -102: "Syntax error",
    -103: "Invalid separator", -104: "Data type error", -108: "Parameter not allowed",
    -109: "Missing parameter", -112: "Program mnemonic too long", -113: "Undefined header",
    -114: "Header suffix out of range", -131: "Invalid suffix", -141: "Invalid character data",
    -151: "Invalid string data",
    -200: "Execution error", -213: "Init ignored", -221: "Settings conflict",
    -222: "Data out of range", -224: "Illegal parameter value", -230: "Data corrupt or stale",
    -350: "Queue overflow", -363: "Input buffer overrun",
}


class ScpiError(Exception):
    """A SCPI error: ``code`` (e.g. -113) and an optional detail appended to the standard
    message (``-221,"Settings conflict; span 200 Hz ..."``)."""

    def __init__(self, code: int, detail: str = ""):
        self.code = int(code)
        self.detail = detail
        super().__init__(self.entry())

    def entry(self) -> str:
        """The ``SYST:ERR?`` answer: ``<code>,"<message>[; detail]"`` (no inner quotes)."""
        msg = ERROR_MESSAGES.get(self.code, "Error")
        if self.detail:
            msg = f"{msg}; {self.detail}"
        return f'{self.code},"{msg.replace(chr(34), chr(39))}"'


def event_bit(code: int) -> int:
    """The standard event status register bit an error sets (IEEE 488.2 11.5.1): command
    (-1xx) 5, execution (-2xx) 4, device-dependent (-3xx) 3, query (-4xx) 2."""
    return {1: 1 << 5, 2: 1 << 4, 3: 1 << 3, 4: 1 << 2}.get(-code // 100, 0)


class ErrorQueue:
    """A bounded first-in first-out error queue (``capacity`` entries)."""

    def __init__(self, capacity: int = 30):
        self.capacity = capacity
        self._q: collections.deque[ScpiError] = collections.deque()
        self._lock = threading.Lock()  # a measurement thread reports its errors too

    def push(self, err: ScpiError) -> None:
        with self._lock:
            if len(self._q) >= self.capacity:
                self._q[-1] = ScpiError(-350)
                return
            self._q.append(err)

    def pop(self) -> str:
        with self._lock:
            return self._q.popleft().entry() if self._q else '0,"No error"'

    def clear(self) -> None:
        with self._lock:
            self._q.clear()

    def __len__(self) -> int:
        return len(self._q)


# -- parameters --------------------------------------------------------------------------------

_PREFIX = {"EX": 1e18, "PE": 1e15, "T": 1e12, "G": 1e9, "MA": 1e6, "K": 1e3, "M": 1e-3,
           "U": 1e-6, "N": 1e-9, "P": 1e-12, "F": 1e-15, "A": 1e-18}
_NUMBER = re.compile(r"^([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*([A-Za-z/%0-9]*)$")


@dataclass(frozen=True)
class Param:
    """One parameter as sent (``text``), decoded on demand by the handler."""

    text: str

    @property
    def is_string(self) -> bool:
        return len(self.text) >= 2 and self.text[0] == self.text[-1] and self.text[0] in "'\""

    def string(self) -> str:
        """String data (``'...'`` or ``"..."``, doubled quotes inside undone); -151 otherwise."""
        if not self.is_string:
            raise ScpiError(-151, f"expected a quoted string, got {self.text}")
        q = self.text[0]
        return self.text[1:-1].replace(q + q, q)

    def number(self, units: dict[str, float] | None = None, *, special: dict | None = None
               ) -> float:
        """A decimal number, scaled by its unit: ``units`` maps each accepted unit (upper case,
        without prefix, "" for none) to its factor; an SI prefix multiplies (``KHZ``).
        ``special`` maps ``MIN``/``MAX``/``DEF`` (and their long forms) to values."""
        t = self.text.strip()
        up = t.upper()
        if special:
            for key, value in special.items():
                if up in (key, {"MIN": "MINIMUM", "MAX": "MAXIMUM", "DEF": "DEFAULT"}.get(key)):
                    return float(value)
        m = _NUMBER.match(t)
        if not m:
            raise ScpiError(-104 if not t[:1].isdigit() else -102,
                            f"expected a number, got {t}")
        value = float(m.group(1))
        unit = m.group(2).upper()
        units = units or {"": 1.0}
        return value * _unit_factor(unit, units)

    def integer(self, **kw) -> int:
        v = self.number(**kw)
        if not math.isfinite(v) or v != round(v):
            raise ScpiError(-104, f"expected a whole number, got {self.text}")
        return int(round(v))

    def boolean(self) -> bool:
        t = self.text.strip().upper()
        if t in ("ON", "1"):
            return True
        if t in ("OFF", "0"):
            return False
        try:
            return round(float(t)) != 0
        except ValueError:
            raise ScpiError(-104, f"expected ON, OFF, 1 or 0, got {self.text}") from None

    def choice(self, options: dict[str, str]) -> str:
        """Character data: ``options`` maps long forms (``RANDom``: upper case = short form)
        to values; the short or long form matches, in any case. -141 otherwise."""
        t = self.text.strip().upper()
        for long, value in options.items():
            short = "".join(c for c in long if not c.islower())
            if t in (short.upper(), long.upper()):
                return value
        valid = ", ".join("".join(c for c in k if not c.islower()) for k in options)
        raise ScpiError(-141, f"{self.text} is not one of {valid}")


def _unit_factor(unit: str, units: dict[str, float]) -> float:
    if unit in units:
        return units[unit]
    if unit in ("MHZ", "MOHM") and unit[1:] in units:  # SCPI: mega here, not milli
        return 1e6 * units[unit[1:]]
    for p in sorted(_PREFIX, key=len, reverse=True):
        if unit.startswith(p) and unit[len(p):] in units and unit[len(p):]:
            return _PREFIX[p] * units[unit[len(p):]]
    valid = ", ".join(u for u in units if u) or "none"
    raise ScpiError(-131, f"unit {unit} is invalid here: expected {valid} (with an SI prefix)")


def split_quoted(text: str, sep: str) -> tuple[list[str], bool]:
    """``text`` split at ``sep`` outside ``'...'`` and ``"..."`` strings, each piece stripped
    (the last one too, possibly empty); and whether every string is terminated."""
    out, cur, quote = [], [], None
    for ch in text:
        if quote:
            cur.append(ch)
            if ch == quote:
                quote = None
        elif ch in "'\"":
            quote = ch
            cur.append(ch)
        elif ch == sep:
            out.append("".join(cur).strip())
            cur = []
        else:
            cur.append(ch)
    out.append("".join(cur).strip())
    return out, quote is None


def split_params(text: str) -> list[Param]:
    """Parameters separated by commas outside quotes (-102 for an unterminated string)."""
    out, terminated = split_quoted(text, ",")
    if not terminated:
        raise ScpiError(-102, "unterminated string")
    if out == [""]:
        return []
    if any(p == "" for p in out):
        raise ScpiError(-103, "empty parameter between commas")
    return [Param(p) for p in out]


# -- the command table -----------------------------------------------------------------------

@dataclass(frozen=True)
class _Node:
    short: str
    long: str
    optional: bool
    suffix: bool


def _nodes(pattern: str) -> tuple[_Node, ...]:
    out = []
    for part in re.findall(r"\[:?[A-Za-z*#]+\]|:?[A-Za-z*]+#?", pattern):
        optional = part.startswith("[")
        name = part.strip("[]:")
        suffix = name.endswith("#")
        name = name.rstrip("#")
        short = "".join(c for c in name if not c.islower())
        out.append(_Node(short.upper(), name.upper(), optional, suffix))
    return tuple(out)


@dataclass(frozen=True)
class Command:
    """One header of the table: ``pattern`` like ``CALCulate#:DATA:HEADer:POINts`` or
    ``[SENSe]:FREQuency:SPAN``; ``set(suffixes, params)`` and/or ``query(suffixes, params) ->
    str | bytes``; ``suffix_max``: the largest numeric suffix each ``#`` node accepts."""

    pattern: str
    set: Callable | None = None
    query: Callable | None = None
    suffix_max: int = 4


_SUFFIXED = re.compile(r"^([A-Z*]+?)(\d+)$")


class CommandTable:
    """Headers -> commands. ``find(nodes)`` returns ``(command, suffixes)`` or raises -113/-114."""

    def __init__(self, commands):
        self._commands = [(c, _nodes(c.pattern)) for c in commands]
        self._found: dict = {}  # tokens -> (command, suffixes): headers repeat in every script

    def find(self, tokens: list[str]) -> tuple[Command, tuple[int, ...]]:
        key = tuple(tokens)
        got = self._found.get(key)
        if got is None:
            got = self._search(tokens)
            if len(self._found) < 4096:
                self._found[key] = got
        return got

    def _search(self, tokens: list[str]) -> tuple[Command, tuple[int, ...]]:
        bad_suffix = None
        for cmd, nodes in self._commands:
            got = _match(nodes, tokens, ())
            if got is None:
                continue
            if any(s < 1 or s > cmd.suffix_max for s in got):
                bad_suffix = ScpiError(-114, f"{':'.join(tokens)}: suffix expected 1.."
                                       f"{cmd.suffix_max}")
                continue
            return cmd, got
        raise bad_suffix or ScpiError(-113, ":".join(tokens))


def _match(nodes, tokens, suffixes):
    if not nodes:
        return suffixes if not tokens else None
    node = nodes[0]
    if tokens:
        tok = tokens[0]
        m = _SUFFIXED.match(tok)
        name, num = (m.group(1), int(m.group(2))) if m else (tok, None)
        if tok in (node.short, node.long) and (not node.suffix or num is None):
            got = _match(nodes[1:], tokens[1:], suffixes + ((1,) if node.suffix else ()))
            if got is not None:
                return got
        elif node.suffix and num is not None and name in (node.short, node.long):
            got = _match(nodes[1:], tokens[1:], suffixes + (num,))
            if got is not None:
                return got
    if node.optional:
        return _match(nodes[1:], tokens, suffixes + ((1,) if node.suffix else ()))
    return None


# -- the engine ----------------------------------------------------------------------------------

_HEADER = re.compile(r"^(:?)([A-Za-z][A-Za-z0-9]*(?::[A-Za-z][A-Za-z0-9]*)*|\*[A-Za-z]+)(\?)?")
MAX_MNEMONIC = 12


class Engine:
    """Executes program messages against a :class:`CommandTable`; errors go to ``errors`` and
    to ``on_error(code)`` (the instrument's event status register).

    :meth:`execute` returns the responses of the line's queries, in order (``str`` or
    ``bytes``): the transport joins them with ``;`` and terminates the message.
    """

    def __init__(self, table: CommandTable, errors: ErrorQueue,
                 on_error: Callable[[int], None] = lambda code: None):
        self.table, self.errors, self.on_error = table, errors, on_error

    def error(self, err: ScpiError) -> None:
        self.errors.push(err)
        self.on_error(err.code)

    def execute(self, line: str) -> list:
        responses, path = [], []
        for unit in _split_units(line, self):
            if unit is None:
                continue
            try:
                path = self._unit(unit, path, responses)
            except ScpiError as err:
                self.error(err)
        return responses

    def _unit(self, unit: str, path: list[str], responses: list) -> list[str]:
        m = _HEADER.match(unit)
        if not m:
            bad = next((c for c in unit if not (c.isalnum() or c in ":*?_ ")), None)
            raise ScpiError(-101 if bad else -102, f"cannot read the header of {unit[:40]}")
        root, header, query = m.group(1), m.group(2).upper(), m.group(3) == "?"
        rest = unit[m.end():]
        if rest and not rest[0].isspace():
            raise ScpiError(-102 if rest[0] not in ":*" else -113,
                            f"cannot read the header of {unit[:40]}")
        tokens = header.split(":")
        if any(len(t.rstrip("0123456789")) > MAX_MNEMONIC for t in tokens):
            raise ScpiError(-112, header)
        common = header.startswith("*")
        full = tokens if (root or common) else path + tokens
        cmd, suffixes = self.table.find(full)
        params = split_params(rest.strip())
        handler = cmd.query if query else cmd.set
        if handler is None:
            raise ScpiError(-113, f"{header}{'?' if query else ''} (only the "
                            f"{'command' if query else 'query'} exists)")
        result = handler(suffixes, params)
        if query:
            responses.append(result)
        return path if common else full[:-1]


def _split_units(line: str, engine: Engine):
    """Units separated by ``;`` outside quotes; ``None`` for an empty unit (ignored)."""
    units, terminated = split_quoted(line, ";")
    for unit in units if terminated else units[:-1]:
        yield unit or None
    if not terminated:
        engine.error(ScpiError(-102, "unterminated string"))
