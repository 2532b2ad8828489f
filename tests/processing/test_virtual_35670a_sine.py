"""The virtual 35670A's swept-sine mode through pyvisa with the pyvisa-py backend only:
``INST:SEL SINE`` and the swept-sine commands drive :func:`processing.sine_sweep.measure_sine`,
the code behind ``daq sine``, so a trace read over SCPI is that sweep bit for bit.

The server runs in a thread of the test process on a free port (one per module, always
stopped), keeping each measurement's run file and its console lines. Sweeps are short: a few
points across the 2.48 Hz mode of ``ishizaki2009`` with a 10-20 s settle.
"""

from __future__ import annotations

import math
import shlex
import threading

import numpy as np
import pytest

pyvisa = pytest.importorskip("pyvisa")

SCENE = "ishizaki2009"
#: Every VISA read is bounded by this; a fresh checkout also compiles the bench's kernels.
TIMEOUT_MS = 300_000
SEED = 32
#: Five log-spaced points across the 2.48 Hz mode, each settled 20 s and read over 20 cycles.
SWEEP = (":FREQ:STAR 2.4 HZ;STOP 2.56 HZ;RES 5 PNT/SWP;:SWE:SPAC LOG;DIR UP;STIM 20 S;"
         "DWEL 20 CYCLE;:SOUR:VOLT 0.1 VRMS;:SOUR:VOLT:LIM 1 VRMS;:OUTP ON")
#: ... and the same sweep as the library's settings (sine_mode's translation, by hand).
SETTINGS = dict(fmin_hz=2.4, fmax_hz=2.56, points=5, spacing="log", direction="up",
                settle_s=20.0, integrate_cycles=20, integrate_s=0.0, level_vrms=0.1,
                level_limit_vrms=1.0)
TRACES = (":CALC1:FEED 'XFR:POW:RAT 2,1';:CALC1:FORM REAL;:CALC2:FEED 'XFR:POW:RAT 2,1';"
          ":CALC2:FORM IMAG;:CALC3:FEED 'XFR:POW:RAT 3,1';:CALC3:FORM REAL;"
          ":CALC4:FEED 'XFR:POW:RAT 3,1';:CALC4:FORM IMAG")


def _errors(inst) -> list[str]:
    out = []
    for _ in range(40):
        e = inst.query("SYST:ERR?")
        if e.startswith("0,"):
            return out
        out.append(e)
    raise AssertionError(f"the error queue does not empty: {out}")


def _codes(inst) -> list[int]:
    return [int(e.split(",")[0]) for e in _errors(inst)]


def _real64(inst, query) -> np.ndarray:
    return np.asarray(inst.query_binary_values(query, datatype="d", is_big_endian=True))


def _library(seed, **changes):
    import rig
    from processing.sine_sweep import SineSettings, measure_sine

    return measure_sine(rig.load_scene(SCENE), SineSettings(**{**SETTINGS, **changes}), seed)


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    from processing.instrument.analyzer35670a import Analyzer35670A
    from processing.instrument.measurement import equivalent_commands
    from processing.instrument.server import ScpiServer
    from rig.scene import load_scene

    scene = load_scene(SCENE)
    logs = []
    inst = Analyzer35670A(scene, seed=SEED, out_dir=tmp_path_factory.mktemp("kept"),
                          log=logs.append,  # what `daq serve` prints and how it says the same
                          describe=lambda setup, s: equivalent_commands(SCENE, [], s, setup,
                                                                        scene))
    srv = ScpiServer(inst, "127.0.0.1", 0)
    srv.logs = logs
    t = threading.Thread(target=srv.serve_forever, daemon=True)
    t.start()
    try:
        yield srv
    finally:
        inst.abort()
        srv.stop()
        t.join(10)
        srv.close()
        assert not t.is_alive()


@pytest.fixture
def visa(server):
    rm = pyvisa.ResourceManager("@py")
    inst = rm.open_resource(server.resource, read_termination="\n", write_termination="\n",
                            timeout=TIMEOUT_MS)
    inst.write("*RST;*CLS")
    try:
        yield inst
    finally:
        inst.close()
        rm.close()


def _sweep(inst, server, *lines) -> dict:
    """Set up, INIT, *OPC? and read X and the four traces in REAL,64."""
    inst.write("*RST;*CLS;:INST:SEL SINE")
    for line in lines:
        inst.write(line)
    inst.write(TRACES)
    got = {"seed": SEED + server.instrument.measurements}
    got["measuring"] = int(inst.query(":INIT;:STAT:OPER:COND?"))
    got["opc"] = inst.query("*OPC?")
    got["n"] = server.instrument.measurements
    got["after"] = int(inst.query(":STAT:OPER:COND?"))
    got["event"] = int(inst.query(":STAT:OPER:EVEN?"))
    got["points"] = int(inst.query(":CALC1:DATA:HEAD:POIN?"))
    inst.write(":FORM:DATA REAL,64")
    got["x"] = _real64(inst, ":CALC1:X:DATA?")
    got["h_t"] = _real64(inst, ":CALC1:DATA?") + 1j * _real64(inst, ":CALC2:DATA?")
    got["theta_2"] = _real64(inst, ":CALC3:DATA?") + 1j * _real64(inst, ":CALC4:DATA?")
    return got


@pytest.fixture(scope="module")
def short_sweep(server):
    rm = pyvisa.ResourceManager("@py")
    inst = rm.open_resource(server.resource, read_termination="\n", write_termination="\n",
                            timeout=TIMEOUT_MS)
    try:
        got = _sweep(inst, server, SWEEP)
        # the coherence-like trace and the power of x's fundamental, in ASCII and REAL,32
        inst.write(":FORM:DATA ASC;:CALC3:FEED 'XFR:POW:COH 2,1';:CALC3:FORM MLIN")
        got["coh"] = np.asarray(inst.query_ascii_values(":CALC3:DATA?"))
        inst.write(":FORM:DATA REAL,32;:CALC4:FEED 'XFR:POW 2';:CALC4:FORM MLIN;"
                   ":CALC4:UNIT:VOLT 'V2'")
        got["power_x"] = np.asarray(inst.query_binary_values(
            ":CALC4:DATA?", datatype="f", is_big_endian=True))
        got["errors"] = _errors(inst)
        for feed in ("'XTIM:VOLT 1'", "'XFR:POW:RAT 4,1'", "'XFR:POW 2';:CALC4:UNIT:VOLT 'V2/HZ'"):
            inst.write(f":CALC4:FEED {feed};:CALC4:DATA?")  # answered with an error only
        got["trace_errors"] = _errors(inst)
    finally:
        inst.close()
        rm.close()
    got["sweep"] = _library(got["seed"])
    return got


# -- the numbers ------------------------------------------------------------------------------

def test_sine_traces_over_scpi_equal_measure_sine_bit_for_bit_in_real64(short_sweep):
    g, pts = short_sweep, short_sweep["sweep"].points
    assert g["errors"] == [] and g["opc"] == "1"
    assert g["points"] == len(g["x"]) == len(pts) == 5
    np.testing.assert_array_equal(g["x"], [p.frequency_hz for p in pts])
    np.testing.assert_array_equal(g["h_t"], [p.h_t for p in pts])
    np.testing.assert_array_equal(g["theta_2"], [p.theta_2 for p in pts])
    steps = np.diff(g["x"])  # the sweep's own points: log-spaced, not the FFT's lines
    assert np.all(steps > 0) and steps[-1] > steps[0] * (1 + 1e-3)


def test_coherence_and_power_traces_read_the_fundamentals(short_sweep):
    pts = short_sweep["sweep"].points
    share = np.array([p.fundamental_ratio for p in pts])
    # 17 ASCII digits read a float64 back exactly
    np.testing.assert_array_equal(short_sweep["coh"], share[:, 1] * share[:, 0])
    x = np.array([p.harmonics[1, 0] for p in pts])  # x's fundamental, peak [m]
    np.testing.assert_array_equal(short_sweep["power_x"],
                                  (np.abs(x) ** 2 / 2).astype(np.float32))


def test_traces_a_sweep_cannot_give_answer_settings_conflict_naming_why(short_sweep):
    errs = short_sweep["trace_errors"]
    assert [int(e.split(",")[0]) for e in errs] == [-221] * 3, errs
    for err, why in zip(errs, ["no time record", "input 4 (the source drive) is not measured",
                               "no spectral density"]):
        assert why in err, (why, err)


def test_status_says_measuring_and_sweeping_until_opc(short_sweep):
    assert short_sweep["measuring"] & 16
    assert short_sweep["after"] == 0
    assert short_sweep["event"] & (8 | 16) == 8 | 16  # measured, swept


def test_overload_flags_follow_the_sweeps_points(visa):
    visa.write(":INST:SEL SINE;:FREQ:STAR 2.4;STOP 2.5;RES 2;:SWE:STIM 1 S;DWEL 5 CYCLE")
    visa.write(":OUTP ON;:VOLT2:RANG -20")  # 0.1 V peak: the PSD's x (~0.4 V here) clips
    assert visa.query(":INIT;*OPC?") == "1"
    assert visa.query(":STAT:DEV:COND?;:STAT:QUES:COND?") == "2;1"  # input 2 overloaded
    assert visa.query(":VOLT2:RANG 0;:INIT;*OPC?;:STAT:DEV:COND?") == "1;0"
    assert _errors(visa) == []


def test_kept_file_and_printed_daq_sine_command_hold_the_same_numbers(short_sweep, server,
                                                                      tmp_path):
    from click.testing import CliRunner
    import xarray as xr

    from daq.cli import main

    n = short_sweep["n"]
    kept = server.instrument.out_dir / f"measurement_{n:04d}.h5"
    with xr.open_dataset(kept, group="entry/sweep", engine="h5netcdf") as ds:
        np.testing.assert_array_equal(ds["h_t_real"].values, short_sweep["h_t"].real)
        np.testing.assert_array_equal(ds["theta_2_imag"].values, short_sweep["theta_2"].imag)
    said = [ln.split("\n", 1)[1] for ln in server.logs if ln.startswith("the same with daq:")
            and f" --seed {short_sweep['seed']} " in ln]
    assert len(said) == 1 and said[0].startswith(f"daq sine {SCENE} "), server.logs
    args = shlex.split(said[0])
    assert args[:2] == ["daq", "sine"] and args[-2:] == ["--out", "sweep.h5"]
    out = tmp_path / "again.h5"
    res = CliRunner().invoke(main, [*args[1:-2], "--out", str(out), "-q"])
    assert res.exit_code == 0, res.output
    with xr.open_dataset(out, group="entry/sweep", engine="h5netcdf") as ds:
        np.testing.assert_array_equal(ds["frequency"].values, short_sweep["x"])
        np.testing.assert_array_equal(ds["h_t_real"].values, short_sweep["h_t"].real)
        np.testing.assert_array_equal(ds["h_t_imag"].values, short_sweep["h_t"].imag)


def test_auto_resolution_and_autolevel_drive_the_librarys_as_documented(visa, server):
    g = _sweep(visa, server,
               ":FREQ:STAR 2.4;STOP 2.56;:SWE:SPAC LOG;STIM 10 S;DWEL 10 CYCLE",
               ":FREQ:RES:AUTO ON;AUTO:MCH 40 PCT;MIN 5 PNT/SWP",
               ":SOUR:VOLT:AUTO ON;REF 3E-4 EU;REF:TOL 2 DB;CHAN INP3",
               ":SOUR:VOLT 0.1;:SOUR:VOLT:LIM 1 VRMS;:OUTP ON")
    assert _errors(visa) == []
    # 40 % of change: 20 log10(1.4) dB and asin(0.4); 2 dB: 1 - 10^(-2/20) of y's 0.3 mrad
    sweep = _library(g["seed"], settle_s=10.0, integrate_cycles=10,
                     auto_resolution=(20 * math.log10(1.4), math.degrees(math.asin(0.4))),
                     auto_level=("y", 3e-4, 1 - 10 ** (-0.1)))
    pts = sweep.points
    np.testing.assert_array_equal(g["x"], [p.frequency_hz for p in pts])
    np.testing.assert_array_equal(g["h_t"], [p.h_t for p in pts])
    np.testing.assert_array_equal(g["theta_2"], [p.theta_2 for p in pts])
    steps = np.diff(g["x"])
    assert steps.min() < steps.max() / 4  # finer across the mode than on its flanks
    assert len({p.level_vrms for p in pts}) > 1  # the level followed y


# -- the settings -----------------------------------------------------------------------------

PRESET = {":FREQ:STAR?": "0.1", ":FREQ:STOP?": "10", ":FREQ:RES?": "101",
          ":FREQ:RES:AUTO?": "0", ":FREQ:RES:AUTO:MCH?": "2", ":FREQ:RES:AUTO:MIN?": "401",
          ":SWE:SPAC?": "LIN", ":SWE:DIR?": "UP", ":SWE:MODE?": "AUTO", ":SWE:STIM?": "5",
          ":SWE:DWEL?": "5", ":SOUR:VOLT:AUTO?": "0", ":SOUR:VOLT:REF?": "2",
          ":SOUR:VOLT:REF:CHAN?": "INP2", ":SOUR:VOLT:REF:TOL?": "2",
          ":SOUR:VOLT:LIM?": "1.41421356237309", ":SOUR:VOLT:SLEW?": "0"}


def test_each_query_answers_its_setting_and_rst_returns_the_preset(visa):
    visa.write(":INST:SEL SINE")
    visa.write(":FREQ:STAR 1.5 HZ;STOP 3.5;RES 20 PNT/DEC;:FREQ:RES:AUTO ON;AUTO:MCH 10;MIN 50")
    visa.write(":SWE:SPAC LOG;DIR DOWN;MODE AUTO;STIM 2 CYCLE;DWEL 30 MS")
    visa.write(":SOUR:VOLT:AUTO ON;REF -20 DBVPK;REF:TOL 0.5;CHAN INP1;:SOUR:VOLT:LIM 3 VPK")
    got = visa.query(";".join(PRESET)).split(";")
    assert got == ["1.5", "3.5", "20", "1", "10", "50", "LOG", "DOWN", "AUTO", "2", "0.03", "1",
                   "-20", "INP1", "0.5", "2.12132034355964", "0"]
    assert visa.query(":FREQ:SPAN?;CENT?") == "2;2.5"
    visa.write(":FREQ:SPAN 1")  # about the center (the preset's FREQ:SPAN:LINK CENT)
    assert visa.query(":FREQ:STAR?;STOP?") == "2;3"
    visa.write("*RST")
    assert visa.query(":INST:SEL?") == "FFT"
    visa.write(":INST:SEL SINE")
    assert dict(zip(PRESET, visa.query(";".join(PRESET)).split(";"))) == PRESET
    assert _errors(visa) == []


def test_out_of_range_values_answer_data_out_of_range_and_keep_the_setting(visa):
    visa.write(":INST:SEL SINE")
    bad = [":FREQ:STAR 0.01", ":FREQ:STOP 60 KHZ", ":FREQ:RES 0", ":FREQ:RES:AUTO:MCH 150",
           ":FREQ:RES:AUTO:MIN 1E6 PNT/SWP", ":SWE:STIM -1", ":SWE:DWEL 300 CYCLE",
           ":SWE:DWEL 100 US", ":SOUR:VOLT:REF 100 VRMS", ":SOUR:VOLT:REF:TOL 30",
           ":SOUR:VOLT:LIM 6 VRMS", ":SOUR:VOLT:LIM 0"]
    for line in bad:
        visa.write(line)
    errs = _errors(visa)
    assert [int(e.split(",")[0]) for e in errs] == [-222] * len(bad), errs
    assert "stop 60000 Hz: expected 0.015625 .. 51200 Hz" in errs[1]
    assert dict(zip(PRESET, visa.query(";".join(PRESET)).split(";"))) == PRESET
    visa.write(":SWE:SPAC CUB;:SWE:DWEL 5 FORTNIGHT;:SOUR:VOLT:REF:CHAN INP5")
    assert _codes(visa) == [-141, -131, -141]


def test_settings_the_bench_cannot_carry_answer_settings_conflict_naming_why(visa):
    visa.write(":INST:SEL SINE")
    visa.write(":SWE:MODE MAN;:SOUR:VOLT:REF:CHAN INP4;:SOUR:VOLT:SLEW 1 VPK/S")
    visa.write(":SOUR:VOLT:LIM:INP 1;:FREQ:SPAN:FULL")
    visa.write(":OUTP OFF;:INIT")  # nothing drives the bench
    visa.write(":OUTP ON;:FREQ:STOP 60;:INIT")  # the bench samples at 100 Hz
    visa.write(":FREQ:STOP 10;RES 10 PNT/DEC;:INIT")  # points per decade of a linear sweep
    visa.write(":FREQ:RES 11;:SWE:STIM 7200 S;:INIT")  # beyond the emulator's settle
    visa.write(":SWE:STIM 1;:FREQ:STAR 5;STOP 4;:INIT")
    visa.write(":FREQ:STAR 1;:SOUR:VOLT 2 VRMS;:INIT")  # above the 2 Vpk autolevel limit
    visa.write(":SOUR:VOLT 0.1;:VOLT2:RANG:AUTO ON;:INIT")
    errs = _errors(visa)
    assert [int(e.split(",")[0]) for e in errs] == [-221] * 12, errs
    for err, why in zip(errs, ["manual sweep", "input 4 is the source drive", "SLEW",
                               "LIM:INP", "FREQ:SPAN:FULL", "OUTP ON", "below 50 Hz",
                               "PNT/DEC has no meaning with SWE:SPAC LIN", "at most 3600 s",
                               "start 5 Hz is not below stop 4 Hz", "SOUR:VOLT:LIM",
                               "VOLT2:RANG:AUTO ON"]):
        assert why in err, (why, err)


def test_abort_ends_a_long_sweep(visa, server):
    visa.write(":INST:SEL SINE;:FREQ:STAR 0.1;STOP 10;RES 2000;:SWE:STIM 50 S;:OUTP ON")
    visa.write(":INIT;:ABOR")
    assert visa.query("*OPC?") == "1"
    assert server.logs[-1] == f"measurement {server.instrument.measurements} aborted"
    assert _errors(visa) == []


def test_switching_back_to_fft_measures_there_and_each_mode_keeps_its_frequencies(visa):
    visa.write(":INST:SEL SINE;:FREQ:STAR 2;STOP 3;:INST:SEL FFT")
    visa.write(":FREQ:SPAN 12.5;RES 100;:AVER:COUN 2;:OUTP ON;:CALC1:FEED 'XFR:POW:RAT 2,1'")
    visa.write(":INIT")
    assert visa.query("*OPC?") == "1"
    x = visa.query_ascii_values(":CALC1:X:DATA?")
    assert len(x) == 101 and x[-1] == 12.5
    assert visa.query(":FREQ:STAR?;STOP?;:INST:SEL SINE;:FREQ:STAR?;STOP?") == "0;12.5;2;3"
    assert visa.query(":CALC1:DATA:HEAD:POIN?") == "101"  # the grid planned: FREQ:RES 101
    visa.write(":CALC1:DATA?")  # the FFT's traces went with its mode
    assert _codes(visa) == [-230]
