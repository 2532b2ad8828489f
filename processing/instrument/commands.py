"""The emulated 35670A's command table: each header with what setting or answering it does.

:func:`table` builds the :class:`processing.instrument.scpi.Command` list of one
:class:`processing.instrument.analyzer35670a.Analyzer35670A`. Headers are written as in the
programmer's reference (upper case = short form, ``[...]`` optional, ``#`` a numeric suffix);
README's "Virtual instrument" section lists them with the errors the emulator answers. The
frequency commands (``FREQ:STAR``, ``STOP``, ``SPAN``, ``CENT``, ``RES``) set the selected
mode's: the FFT span and lines, or the swept sine's band and points
(:mod:`processing.instrument.sine_mode`, whose settings the swept-sine rows set).
"""

from __future__ import annotations

import math

from processing.instrument.measurement_mode import ModeConflict
from processing.instrument.scpi import Command, ScpiError
from processing.instrument.sine_mode import planned_points
from processing.instrument.traces import FORMS, VOLT_UNITS, parse_feed

__all__ = ["table"]

SOURCES = {"RANDom": "random", "BRANdom": "burst-random", "PCHirp": "periodic-chirp",
           "PINK": "pink", "SINusoid": "sine", "BCHirp": "burst-chirp", "USER": "user",
           "CAPTure": "capture"}
WINDOWS = {"HANNing": "hann", "UNIForm": "uniform", "FLATtop": "flattop", "FORCe": "force",
           "EXPonential": "exponential"}
AVERAGE_TYPES = {"RMS": "RMS", "VECTor": "VECT", "MAXimum": "MAX", "TIME": "TIME",
                 "ECONfidence": "ECON"}
_NOT_EMULATED_FORMS = ("NYQuist", "POLar", "GDELay")
_MODES = {"FFT": "FFT", "SINE": "SINE", "CORRelation": "CORR", "HISTogram": "HIST",
          "OCTave": "OCT", "ORDer": "ORD"}


def _one(params):
    if not params:
        raise ScpiError(-109)
    if len(params) > 1:
        raise ScpiError(-108, f"one parameter expected, got {len(params)}")
    return params[0]


def _none(params):
    if params:
        raise ScpiError(-108)


def _nr(x: float) -> str:
    return f"{x:.15G}" if math.isfinite(x) else "9.91E+37"


def _code(options: dict, value) -> str:
    return next("".join(c for c in k if not c.islower()) for k, v in options.items()
                if v == value)


def _in_range(name, v, lo, hi, unit=""):
    if not (math.isfinite(v) and lo <= v <= hi):
        raise ScpiError(-222, f"{name} {v:g}{unit}: expected {lo:g} .. {hi:g}{unit}")
    return v


def _flag(on_set, on_query):
    return dict(set=lambda s, p: on_set(s, _one(p).boolean()),
                query=lambda s, p: (_none(p), "1" if on_query(s) else "0")[1])


def table(a) -> list[Command]:
    """The commands of the instrument ``a`` (an ``Analyzer35670A``)."""
    return [*_common(a), *_system(a), *_measure(a), *_source(a), *_inputs(a), *_frequency(a),
            *_sweep(a), *_autolevel(a), *_averaging(a), *_formats(a), *_traces(a)]


# -- IEEE 488.2 common commands, SYSTem, STATus ----------------------------------------------

def _opc(a):
    _ = a.wait()
    return "1"


def _rst(a):
    a.abort()
    a.reset()


def _cls(a):
    a.status.clear()
    a.errors.clear()


def _common(a):
    def q(fn):
        return lambda s, p: (_none(p), fn())[1]

    def c(fn):
        return lambda s, p: (_none(p), fn())[1] and None

    def mask(attr):
        return dict(set=lambda s, p: setattr(a.status, attr, _in_range(
                        attr.upper(), _one(p).integer(), 0, 255)),
                    query=q(lambda: str(getattr(a.status, attr))))

    return [
        Command("*IDN", query=q(a.identity)),
        Command("*OPT", query=q(lambda: '"AY6"')),
        Command("*RST", set=c(lambda: _rst(a))),
        Command("*CLS", set=c(lambda: _cls(a))),
        Command("*OPC", set=c(a.request_opc), query=q(lambda: _opc(a))),
        Command("*WAI", set=c(lambda: a.wait())),
        Command("*ESR", query=q(lambda: str(a.status.read_esr()))),
        Command("*ESE", **mask("ese")),
        Command("*SRE", **mask("sre")),
        Command("*STB", query=q(lambda: str(a.status.stb(len(a.errors) > 0)))),
        Command("*TST", query=q(lambda: "0")),
    ]


def _register(name, reg, a):
    def q(fn):
        return lambda s, p: (_none(p), fn())[1]

    def locked(fn):
        def run():
            with a.status.lock:
                return str(fn())
        return run

    return [
        Command(f"STATus:{name}:CONDition", query=q(locked(lambda: reg.condition))),
        Command(f"STATus:{name}[:EVENt]", query=q(locked(reg.read_event))),
        Command(f"STATus:{name}:ENABle",
                set=lambda s, p: setattr(reg, "enable", _in_range(
                    "enable", _one(p).integer(), 0, 32767)),
                query=q(locked(lambda: reg.enable))),
    ]


def _stat_preset(a):
    for r in (a.status.oper, a.status.ques, a.status.dev):
        r.enable = 0


def _system(a):
    def q(fn):
        return lambda s, p: (_none(p), fn())[1]

    st = a.status
    return [
        Command("SYSTem:ERRor[:NEXT]", query=q(a.errors.pop)),
        Command("SYSTem:VERSion", query=q(lambda: "1992.0")),
        Command("SYSTem:PRESet", set=lambda s, p: (_none(p), _rst(a))[1]),
        Command("STATus:PRESet", set=lambda s, p: (_none(p), _stat_preset(a))[1]),
        *_register("OPERation", st.oper, a), *_register("QUEStionable", st.ques, a),
        *_register("DEVice", st.dev, a),
        Command("DISPlay[:STATe]", **_flag(lambda s, v: setattr(a, "display", v),
                                           lambda s: a.display)),
        Command("SYSTem:BEEPer:STATe", **_flag(lambda s, v: setattr(a, "beeper", v),
                                               lambda s: a.beeper)),
    ]


# -- INSTrument, INITiate, ABORt -------------------------------------------------------------

def _select(a, p):
    mode = _one(p).choice(_MODES)
    if mode not in a.modes:
        raise ScpiError(-221, f"INST:SEL {mode}: the {mode} mode is not emulated yet "
                        f"({' and '.join(a.modes)} are)")
    a.select(mode)


def _continuous(a, on):
    if on:
        raise ScpiError(-221, "continuous measurement (INIT:CONT ON) is not emulated: INIT "
                        "starts one measurement")


def _measure(a):
    return [
        Command("INSTrument[:SELect]", set=lambda s, p: _select(a, p),
                query=lambda s, p: (_none(p), a.mode)[1]),
        Command("INITiate[:IMMediate]", set=lambda s, p: (_none(p), a.initiate())[1]),
        Command("INITiate:CONTinuous", **_flag(lambda s, v: _continuous(a, v),
                                               lambda s: False)),
        Command("ABORt", set=lambda s, p: (_none(p), a.abort())[1]),
    ]


# -- OUTPut, SOURce --------------------------------------------------------------------------

def _function(a, p):
    f = _one(p).choice(SOURCES)
    if f in ("burst-chirp", "user", "capture"):
        raise ScpiError(-221, f"source {_code(SOURCES, f)} is not emulated (RAND, BRAN, PCH, "
                        "PINK, SIN are)")
    a.update_source(function=f)


def _level(a, p):
    par = _one(p)
    unit = "".join(ch for ch in par.text.upper() if ch.isalpha() and ch != "E")
    v = par.number({"": 1.0, "V": 1.0, "VRMS": 1.0, "VPK": 1.0})
    _in_range("source level", v, 0.0, 5.0, " V")
    if unit.endswith("VPK"):
        if a.mode != "SINE" and a.setup.source.function not in ("sine", "periodic-chirp"):
            raise ScpiError(-221, "a peak level of a noise source is not defined: give VRMS")
        v = v / math.sqrt(2.0)
    a.update_source(level_vrms=v)


def _offset(a, p):
    v = _one(p).number({"": 1.0, "V": 1.0})
    if v != 0.0:
        raise ScpiError(-221, f"source offset {v:g} V: the emulated source has no DC offset "
                        "(0 V only)")


def _source(a):
    src = lambda: a.setup.source  # noqa: E731
    freq = dict(set=lambda s, p: a.update_source(frequency_hz=_in_range(
                    "source frequency", _one(p).number({"": 1.0, "HZ": 1.0}), 1e-6, 102400.0,
                    " Hz")),
                query=lambda s, p: (_none(p), _nr(src().frequency_hz))[1])
    return [
        Command("OUTPut[:STATe]", **_flag(lambda s, v: a.update_source(enabled=v),
                                          lambda s: src().enabled)),
        Command("SOURce:FUNCtion[:SHAPe]", set=lambda s, p: _function(a, p),
                query=lambda s, p: (_none(p), _code(SOURCES, src().function))[1]),
        Command("SOURce:VOLTage[:LEVel][:IMMediate][:AMPLitude]",
                set=lambda s, p: _level(a, p),
                query=lambda s, p: (_none(p), _nr(src().level_vrms))[1]),
        Command("SOURce:VOLTage[:LEVel][:IMMediate]:OFFSet", set=lambda s, p: _offset(a, p),
                query=lambda s, p: (_none(p), "0")[1]),
        Command("SOURce:FREQuency[:CW]", **freq),
        Command("SOURce:FREQuency:FIXed", **freq),
        Command("SOURce:BURSt", set=lambda s, p: a.update_source(burst_percent=_in_range(
                    "burst", _one(p).number({"": 1.0, "PCT": 1.0}), 0.1, 100.0, " %")),
                query=lambda s, p: (_none(p), _nr(src().burst_percent))[1]),
    ]


# -- INPut, [SENSe:]VOLTage ------------------------------------------------------------------

def _coupling(a, n, p):
    c = _one(p).choice({"DC": "DC", "AC": "AC"})
    if c == "AC":
        raise ScpiError(-221, f"AC coupling of input {n} is not emulated: the inputs are DC "
                        "coupled (the accelerometer has its own 0.05 Hz high-pass)")


def _range(a, n, p):
    if n == 4:
        raise ScpiError(-221, "input 4 is the source drive, recorded without an ADC range")
    par = _one(p)
    unit = "".join(ch for ch in par.text.upper() if ch.isalpha() and ch != "E")
    v = par.number({"": 1.0, "DBVP": 1.0, "DBVPK": 1.0, "DBVRMS": 1.0, "VPK": 1.0, "V": 1.0,
                    "VRMS": math.sqrt(2.0)})
    if unit in ("", "DBVP", "DBVPK", "DBVRMS"):
        db = v + (_RMS_TO_PEAK_DB if unit == "DBVRMS" else 0.0)
    else:
        db = 20.0 * math.log10(v) if v > 0 else -math.inf
    db = math.ceil(db - 1e-9)
    _in_range(f"input {n} range", db, -51, 27, " dBVpk")
    ranges, auto = list(a.setup.ranges_v), list(a.setup.autorange)
    ranges[n - 1], auto[n - 1] = 10.0 ** (db / 20.0), False  # a set range ends autoranging
    a.update(ranges_v=tuple(ranges), autorange=tuple(auto))


_RMS_TO_PEAK_DB = 20.0 * math.log10(math.sqrt(2.0))


def _range_query(a, n):
    if n == 4:
        raise ScpiError(-221, "input 4 is the source drive, recorded without an ADC range")
    return _nr(round(20.0 * math.log10(a.setup.ranges_v[n - 1]), 9))


def _autorange(a, n, on):
    if n == 4:
        if on:
            raise ScpiError(-221, "input 4 is the source drive, recorded without an ADC range")
        return
    auto = list(a.setup.autorange)
    auto[n - 1] = on
    a.update(autorange=tuple(auto))


def _xdcr(a, n, on):
    if n == 4 and on:
        raise ScpiError(-221, "input 4 (the source drive) has no transducer: it reads volts")
    a.update_input(n, xdcr=on)


def _labels(a, n):
    if n == 4:
        return "V"
    unit = a.scene_units()[n]
    return {"m/s^2": "M/S2", "m": "M", "rad": "RAD"}.get(unit, unit.upper())


def _inputs(a):
    v = "[SENSe]:VOLTage#[:DC]:RANGe"

    def nq(fn):
        return lambda s, p: (_none(p), fn(s[0]))[1]

    return [
        Command("INPut#[:STATe]",
                set=lambda s, p: a.update_input(s[0], on=_one(p).boolean()),
                query=nq(lambda n: "1" if a.inputs[n].on else "0")),
        Command("INPut#:COUPling", set=lambda s, p: _coupling(a, s[0], p),
                query=nq(lambda n: "DC")),
        Command(f"{v}[:UPPer]", set=lambda s, p: _range(a, s[0], p),
                query=nq(lambda n: _range_query(a, n))),
        Command(f"{v}:AUTO", set=lambda s, p: _autorange(a, s[0], _one(p).boolean()),
                query=nq(lambda n: "1" if n < 4 and a.setup.autorange[n - 1] else "0")),
        Command(f"{v}:UNIT:XDCR[:STATe]", set=lambda s, p: _xdcr(a, s[0], _one(p).boolean()),
                query=nq(lambda n: "1" if a.inputs[n].xdcr else "0")),
        Command(f"{v}:UNIT:XDCR:LABel", query=nq(lambda n: f'"{_labels(a, n)}"'),
                set=lambda s, p: _same_label(a, s[0], p)),
        Command(f"{v}:UNIT:XDCR:SENSitivity",
                query=nq(lambda n: _nr(abs(a.scene_volts_per_unit()[n]))),
                set=lambda s, p: _fixed_calibration(s[0])),
    ]


def _same_label(a, n, p):
    par = _one(p)
    label = (par.string() if par.is_string else par.text).strip().upper()
    if label != _labels(a, n):
        _fixed_calibration(n)


def _fixed_calibration(n):
    raise ScpiError(-221, f"input {n}'s transducer is the emulated sensor: its calibration "
                    "is fixed (VOLT{n}:RANG:UNIT:XDCR ON|OFF selects it)".replace("{n}", str(n)))


# -- [SENSe:]FREQuency -----------------------------------------------------------------------

def _span(a, p):
    a.update(span_hz=a.check_span(_one(p).number(_hz(), special={"MAX": 102400.0,
                                                                   "MIN": 0.1953125})))


def _hz():
    return {"": 1.0, "HZ": 1.0}


def _start(a, p):
    f = _one(p).number(_hz(), special={"MIN": 0.0, "DEF": 0.0})
    if f != 0.0:
        raise ScpiError(-221, f"start {f:g} Hz: zoom spans are not emulated; baseband spans "
                        "start at 0 Hz")


def _center(a, p):
    f = _one(p).number(_hz())
    if not math.isclose(f, a.setup.span_hz / 2, rel_tol=1e-9):
        raise ScpiError(-221, f"center {f:g} Hz: zoom spans are not emulated; a baseband "
                        f"span's center is span / 2 ({a.setup.span_hz / 2:g} Hz now)")


def _by_mode(a, fft, sine):
    """A handler that is ``sine`` in the swept-sine mode and ``fft`` otherwise."""
    return lambda s, p: (sine if a.mode == "SINE" else fft)(s, p)


def _frequency(a):
    f = "[SENSe]:FREQuency"
    sw = lambda: a.sine  # noqa: E731

    def q(fft, sine):
        return _by_mode(a, lambda s, p: (_none(p), _nr(fft()))[1],
                        lambda s, p: (_none(p), _nr(sine()))[1])

    def full(s, p):
        _none(p)
        if a.mode == "SINE":
            raise ScpiError(-221, "FREQ:SPAN:FULL is not valid in the swept-sine mode (the "
                            "reference's): set FREQ:STAR and FREQ:STOP")
        a.update(span_hz=a.check_span(102400.0))

    return [
        Command(f"{f}:SPAN", set=_by_mode(a, lambda s, p: _span(a, p),
                                          lambda s, p: _sine_span(a, p)),
                query=q(lambda: a.setup.span_hz, lambda: sw().stop_hz - sw().start_hz)),
        Command(f"{f}:SPAN:FULL", set=full),
        Command(f"{f}:STOP", set=_by_mode(a, lambda s, p: _span(a, p),
                                          lambda s, p: _sine_band(a, p, stop=True)),
                query=q(lambda: a.setup.span_hz, lambda: sw().stop_hz)),
        Command(f"{f}:STARt", set=_by_mode(a, lambda s, p: _start(a, p),
                                           lambda s, p: _sine_band(a, p, stop=False)),
                query=q(lambda: 0.0, lambda: sw().start_hz)),
        Command(f"{f}:CENTer", set=_by_mode(a, lambda s, p: _center(a, p),
                                            lambda s, p: _sine_center(a, p)),
                query=q(lambda: a.setup.span_hz / 2,
                        lambda: (sw().start_hz + sw().stop_hz) / 2)),
        Command(f"{f}:RESolution",
                set=_by_mode(a, lambda s, p: a.update(lines=a.lines_for(
                    _in_range("lines", _one(p).number(), 1, math.inf))),
                    lambda s, p: a.update_sine(resolution=_resolution(p))),
                query=_by_mode(a, lambda s, p: (_none(p), str(a.setup.lines))[1],
                               lambda s, p: (_none(p), _nr(sw().resolution[0]))[1])),
        Command("[SENSe]:WINDow#[:TYPE]",
                set=lambda s, p: a.update(window=_one(p).choice(_windows())),
                query=lambda s, p: (_none(p), _code(_windows(), a.setup.window))[1]),
        Command("[SENSe]:SWEep:OVERlap",
                set=lambda s, p: a.update(overlap=_in_range(
                    "overlap", _one(p).number({"": 1.0, "PCT": 1.0}), 0.0, 99.0, " %") / 100),
                query=lambda s, p: (_none(p), _nr(round(a.setup.overlap * 100, 12)))[1]),
    ]


def _windows():
    return WINDOWS


# -- swept sine: [SENSe:]FREQuency, [SENSe:]SWEep (INST:SEL SINE) ----------------------------

#: The swept sine's frequency limits [Hz] (the reference: 15.625 mHz .. 51.2 kHz).
SINE_HZ = (0.015625, 51200.0)
RESOLUTION_UNITS = ("PNT/SWP", "PNT/DEC", "PNT/OCT", "HZ", "PCT")


def _value_unit(par, units: tuple, default: str, special=None) -> tuple[float, str]:
    """A number and the one of ``units`` it was sent in (none: ``default``); an SI prefix
    scales it (``MS``: milliseconds)."""
    text = par.text.strip().upper()
    unit = next((u for u in sorted(units, key=len, reverse=True) if text.endswith(u)), "")
    value = par.number({u: 1.0 for u in ("", *units)}, special=special)
    return value, unit or default


def _sine_band(a, p, *, stop: bool):
    f = _in_range("stop" if stop else "start", _one(p).number(
        _hz(), special={"MIN": SINE_HZ[0], "MAX": SINE_HZ[1]}), *SINE_HZ, " Hz")
    a.update_sine(**{"stop_hz" if stop else "start_hz": f})


def _sine_around(a, center: float, span: float):
    lo, hi = center - span / 2, center + span / 2
    if lo < SINE_HZ[0] or hi > SINE_HZ[1]:
        raise ScpiError(-222, f"a span of {span:g} Hz around {center:g} Hz runs from {lo:g} to "
                        f"{hi:g} Hz: expected {SINE_HZ[0]:g} .. {SINE_HZ[1]:g} Hz")
    a.update_sine(start_hz=lo, stop_hz=hi)


def _sine_span(a, p):  # the center stays (FREQ:SPAN:LINK CENT, the preset's)
    span = _in_range("span", _one(p).number(_hz()), *SINE_HZ, " Hz")
    _sine_around(a, (a.sine.start_hz + a.sine.stop_hz) / 2, span)


def _sine_center(a, p):
    _sine_around(a, _one(p).number(_hz()), a.sine.stop_hz - a.sine.start_hz)


def _resolution(p) -> tuple:
    v, unit = _value_unit(_one(p), RESOLUTION_UNITS, "PNT/SWP")
    return _in_range("resolution", v, *SINE_HZ, f" {unit}"), unit


def _settle(p) -> tuple:
    v, unit = _value_unit(_one(p), ("S", "CYCLE"), "S")
    return _in_range("settle time", v, 0.0, 9.9e37, f" {unit}"), unit


def _dwell(p) -> tuple:
    v, unit = _value_unit(_one(p), ("S", "CYCLE"), "S")
    if unit == "CYCLE":  # the reference: less than one cycle is one cycle
        return _in_range("integration time", max(v, 1.0), 1.0, 234.0, " CYCLE"), unit
    return _in_range("integration time", v, 250e-6, 32768.0, " S"), unit


def _sweep_mode(a, p):
    if _one(p).choice({"AUTO": "AUTO", "MANual": "MAN"}) == "MAN":
        raise ScpiError(-221, "manual sweep (SWE:MODE MAN, FREQ:MAN) is not emulated: the "
                        "sweep runs FREQ:STAR .. FREQ:STOP")


def _sweep(a):
    f, w = "[SENSe]:FREQuency:RESolution:AUTO", "[SENSe]:SWEep"
    sw = lambda: a.sine  # noqa: E731

    def q(fn):
        return lambda s, p: (_none(p), fn())[1]

    def choice(field, options):
        return dict(set=lambda s, p: a.update_sine(**{field: _one(p).choice(options)}),
                    query=q(lambda: getattr(sw(), field)))

    return [
        Command(f, **_flag(lambda s, v: a.update_sine(auto_resolution=v),
                           lambda s: sw().auto_resolution)),
        Command(f"{f}:MCHange", set=lambda s, p: a.update_sine(max_change_pct=_in_range(
                    "maximum change", _one(p).number({"": 1.0, "PCT": 1.0}), 0.00391, 100.0,
                    " %")),
                query=q(lambda: _nr(sw().max_change_pct))),
        Command(f"{f}:MINimum", set=lambda s, p: a.update_sine(auto_minimum=_resolution(p)),
                query=q(lambda: _nr(sw().auto_minimum[0]))),
        Command(f"{w}:DIRection", **choice("direction", {"UP": "UP", "DOWN": "DOWN"})),
        Command(f"{w}:SPACing", **choice("spacing", {"LINear": "LIN", "LOGarithmic": "LOG"})),
        Command(f"{w}:MODE", set=lambda s, p: _sweep_mode(a, p), query=q(lambda: "AUTO")),
        Command(f"{w}:STIMe", set=lambda s, p: a.update_sine(settle=_settle(p)),
                query=q(lambda: _nr(sw().settle[0]))),
        Command(f"{w}:DWELl", set=lambda s, p: a.update_sine(dwell=_dwell(p)),
                query=q(lambda: _nr(sw().dwell[0]))),
    ]


# -- SOURce:VOLTage autolevel (swept sine) ---------------------------------------------------

REFERENCE_UNITS = ("DBVRMS", "VPK", "DBVPK", "V", "DBV", "EU", "DBEU", "VRMS")


def _reference(p) -> tuple:
    v, unit = _value_unit(_one(p), REFERENCE_UNITS, "VPK")
    if unit in ("EU", "DBEU"):
        if not (math.isfinite(v) and (v > 0 or unit == "DBEU")):
            raise ScpiError(-222, f"reference {v:g} {unit}: expected an amplitude > 0")
        return v, unit
    lin = {"VPK": v / math.sqrt(2.0), "V": v / math.sqrt(2.0), "VRMS": v}.get(unit)
    db = 20.0 * math.log10(lin) if lin is not None and lin > 0 else (
        -math.inf if lin is not None else v - (_RMS_TO_PEAK_DB if unit == "DBVPK" else 0.0))
    _in_range(f"reference {v:g} {unit} =", db, -69.276, 31.66, " dBVrms")
    return v, unit


def _reference_channel(a, p):
    n = int(_one(p).choice({f"INPut{k}": str(k) for k in range(1, 5)}))
    if n == 4:
        raise ScpiError(-221, "input 4 is the source drive: autolevel holds input 1, 2 or 3")
    a.update_sine(reference_input=n)


def _limit(a, p):
    par = _one(p)
    unit = "".join(ch for ch in par.text.upper() if ch.isalpha() and ch != "E")
    v = par.number({"": 1.0, "V": 1.0, "VRMS": 1.0, "VPK": 1.0, "DBV": 1.0, "DBVRMS": 1.0,
                    "DBVPK": 1.0})
    vrms = {"VPK": v / math.sqrt(2.0), "DBV": 10 ** (v / 20), "DBVRMS": 10 ** (v / 20),
            "DBVPK": 10 ** (v / 20) / math.sqrt(2.0)}.get(unit, v)
    if not (math.isfinite(vrms) and 0 < vrms <= 5.0):
        raise ScpiError(-222, f"autolevel limit {par.text}: expected 0 < limit <= 5 V rms")
    a.update_sine(limit_vrms=vrms)


def _not_emulated(what):
    def handler(s, p):
        raise ScpiError(-221, what)
    return handler


def _slew(p):
    if _one(p).number({"": 1.0, "V/S": 1.0, "VPK/S": 1.0, "VRMS/S": 1.0}) != 0.0:
        raise ScpiError(-221, "a source ramp (SOUR:VOLT:SLEW) is not emulated: the level steps "
                        "at once (0 only)")


def _autolevel(a):
    v = "SOURce:VOLTage"
    sw = lambda: a.sine  # noqa: E731

    def q(fn):
        return lambda s, p: (_none(p), fn())[1]

    lim_inp = _not_emulated("autolevel holds only the reference input: a limit on the other "
                            "inputs (SOUR:VOLT:LIM:INP) is not emulated")
    return [
        Command(f"{v}[:LEVel]:AUTO", **_flag(lambda s, on: a.update_sine(auto_level=on),
                                             lambda s: sw().auto_level)),
        Command(f"{v}[:LEVel]:REFerence", set=lambda s, p: a.update_sine(reference=_reference(p)),
                query=q(lambda: _nr(sw().reference[0]))),
        Command(f"{v}[:LEVel]:REFerence:CHANnel", set=lambda s, p: _reference_channel(a, p),
                query=q(lambda: f"INP{sw().reference_input}")),
        Command(f"{v}[:LEVel]:REFerence:TOLerance",
                set=lambda s, p: a.update_sine(tolerance_db=_in_range(
                    "tolerance", _one(p).number({"": 1.0, "DB": 1.0}), 0.1, 20.0, " dB")),
                query=q(lambda: _nr(sw().tolerance_db))),
        Command(f"{v}:LIMit[:AMPLitude]", set=lambda s, p: _limit(a, p),
                query=q(lambda: _nr(sw().limit_vrms))),
        Command(f"{v}:LIMit:INPut", set=lim_inp, query=lim_inp),
        Command(f"{v}:SLEW", set=lambda s, p: _slew(p), query=q(lambda: "0")),
    ]


# -- [SENSe:]AVERage -------------------------------------------------------------------------

def _tcon(a, p):
    t = _one(p).choice({"NORMal": "NORM", "FREeze": "NORM", "EXPonential": "EXP",
                        "REPeat": "REP"})
    if t == "REP":
        raise ScpiError(-221, "repeated averaging (AVER:TCON REP) is not emulated: a "
                        "measurement stops after AVER:COUN averages")
    a.aver_tcon = t


def _averaging(a):
    return [
        Command("[SENSe]:AVERage[:STATe]", **_flag(lambda s, v: setattr(a, "aver_on", v),
                                                   lambda s: a.aver_on)),
        Command("[SENSe]:AVERage:COUNt",
                set=lambda s, p: a.update(averages=int(_in_range(
                    "average count", _one(p).integer(), 1, 9999999))),
                query=lambda s, p: (_none(p), str(a.setup.averages))[1]),
        Command("[SENSe]:AVERage:TYPE",
                set=lambda s, p: setattr(a, "aver_type", _one(p).choice(AVERAGE_TYPES)),
                query=lambda s, p: (_none(p), a.aver_type)[1]),
        Command("[SENSe]:AVERage:TCONtrol", set=lambda s, p: _tcon(a, p),
                query=lambda s, p: (_none(p), a.aver_tcon)[1]),
    ]


# -- FORMat ----------------------------------------------------------------------------------

def _form(a, p):
    if not p or len(p) > 2:
        raise ScpiError(-109 if not p else -108)
    kind = p[0].choice({"ASCii": "ASC", "REAL": "REAL"})
    if kind == "ASC":
        digits = 17 if len(p) == 1 else int(_in_range("ASCII digits", p[1].integer(), 3, 17))
        a.form, a.digits = "ASC", digits
        return
    bits = 64 if len(p) == 1 else p[1].integer()
    if bits not in (32, 64):
        raise ScpiError(-222, f"REAL,{bits}: expected REAL,32 or REAL,64")
    a.form = f"REAL,{bits}"


def _formats(a):
    return [
        Command("FORMat[:DATA]", set=lambda s, p: _form(a, p),
                query=lambda s, p: (_none(p), f"ASC,{a.digits}" if a.form == "ASC"
                                    else a.form)[1]),
        Command("FORMat:BORDer",
                set=lambda s, p: setattr(a, "swapped", _one(p).choice(
                    {"NORMal": False, "SWAPped": True})),
                query=lambda s, p: (_none(p), "SWAP" if a.swapped else "NORM")[1]),
    ]


# -- CALCulate -------------------------------------------------------------------------------

def _feed(a, n, p):
    par = _one(p)
    if not par.is_string:
        raise ScpiError(-104, f"CALC{n}:FEED takes a string, e.g. 'XFR:POW:RAT 2,1'")
    feed = parse_feed(par.string())
    if feed is None:
        raise ScpiError(-224, f"feed {par.text} is not emulated (XFR:POW n, XFR:POW:RAT m,n, "
                        "XFR:POW:COH m,n, XFR:POW:CROS m,n, XTIM:VOLT n)")
    a.update_trace(n, feed=feed)


def _calc_form(a, n, p):
    par = _one(p)
    try:
        a.update_trace(n, form=par.choice(FORMS))
    except ScpiError:
        if par.text.upper() in {x.upper() for x in _NOT_EMULATED_FORMS} | {"NYQ", "POL", "GDEL"}:
            raise ScpiError(-221, f"format {par.text} is not emulated (MLOG, MLIN, PHAS, UPH, "
                            "REAL, IMAG are)") from None
        raise


def _volt_unit(a, n, p):
    par = _one(p)
    u = (par.string() if par.is_string else par.text).strip().upper()
    if u not in VOLT_UNITS:
        raise ScpiError(-224, f"unit {u}: expected one of {', '.join(VOLT_UNITS)}")
    a.update_trace(n, volt_unit=u)


def _points(a, n):
    t = a.traces[n].feed
    if a.mode == "SINE":
        if a.result is not None:
            return str(len(a.trace_values(n, x=True)))
        try:
            planned = planned_points(a.sine)
        except ModeConflict as exc:
            raise ScpiError(-221, str(exc)) from None
        if planned is None:
            raise ScpiError(-230, "with auto resolution the points are known after the sweep")
        return str(planned)
    s = a.result.setup if a.result is not None else a.setup
    return str(s.nperseg if t.kind == "time" else s.lines + 1)


def _data(a, n, x):
    try:
        return a.encode(a.trace_values(n, x=x))
    except ModeConflict as exc:
        raise ScpiError(-221, str(exc)) from None


def _traces(a):
    c = "CALCulate#"

    def nq(fn):
        return lambda s, p: (_none(p), fn(s[0]))[1]

    return [
        Command(f"{c}:FEED", set=lambda s, p: _feed(a, s[0], p),
                query=nq(lambda n: f'"{a.traces[n].feed.text}"')),
        Command(f"{c}:FORMat", set=lambda s, p: _calc_form(a, s[0], p),
                query=nq(lambda n: a.traces[n].form)),
        Command(f"{c}:DATA", query=nq(lambda n: _data(a, n, False))),
        Command(f"{c}:X:DATA", query=nq(lambda n: _data(a, n, True))),
        Command(f"{c}:DATA:HEADer:POINts", query=nq(lambda n: _points(a, n))),
        Command(f"{c}:UNIT:VOLTage", set=lambda s, p: _volt_unit(a, s[0], p),
                query=nq(lambda n: f'"{a.traces[n].volt_unit}"')),
        Command(f"{c}:UNIT:ANGLe",
                set=lambda s, p: setattr(a, "degrees", _one(p).choice(
                    {"DEGree": True, "RADian": False})),
                query=lambda s, p: (_none(p), "DEG" if a.degrees else "RAD")[1]),
    ]
