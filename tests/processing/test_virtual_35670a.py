"""The virtual 35670A through real clients only: pyvisa with the pyvisa-py backend on
``TCPIP::127.0.0.1::PORT::SOCKET``, pymeasure's VISA adapter, and ``daq serve`` as a process.

Lab-style scripts: set up, ``INIT``, ``*OPC?``, read traces in ASCII and binary, check
``SYST:ERR?``. The server runs in a thread of the test process on a free port (one per module,
always stopped), except for the command-line tests, which start ``daq serve`` and signal it.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest
from virtual_analyzer import TIMEOUT_MS, errors, serving, session

pyvisa = pytest.importorskip("pyvisa")

SCENE = "ishizaki2009"
SEED = 2009
#: The bench and analyzer settings a 12.5 Hz, 800-line, 30-average set-up makes (README,
#: "Virtual instrument"): 32 Hz sampling, 64 s time records, the DAC at 1024 Hz.
EQUIVALENT = ["acquisition.rate_hz=32.0", "acquisition.simulation_rate_hz=1024.0",
              "acquisition.records=30", "acquisition.record_s=64.0", "acquisition.settle_s=300.0",
              "acquisition.range_a_v=1.0", "acquisition.range_x_v=10.0",
              "acquisition.range_y_v=10.0", "source.type=random", "source.level_vrms=0.1",
              "source.fmin_hz=0.0", "source.fmax_hz=12.5"]


@pytest.fixture(scope="module")
def server():
    from processing.instrument.analyzer35670a import Analyzer35670A
    from rig.scene import load_scene

    with serving(Analyzer35670A(load_scene(SCENE), seed=SEED)) as srv:
        yield srv


# -- the numbers ------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def paper_measurement(server):
    """The paper's bench measured like a lab script would (30 averages, 800 lines, 12.5 Hz),
    read as ASCII, REAL,32 and REAL,64; and the same measurement made with the library."""
    import daq
    import processing
    import rig

    with session(server.resource, TIMEOUT_MS) as inst:
        inst.write("*RST;*CLS")
        inst.write(":INST:SEL FFT;:SOUR:FUNC RAND;:SOUR:VOLT 0.1 VRMS;:OUTP ON")
        inst.write(":FREQ:SPAN 12.5 HZ;RES 800;:WIND HANN")
        inst.write(":AVER:TYPE RMS;COUN 30;:AVER ON")
        inst.write(":CALC1:FEED 'XFR:POW:RAT 2,1';:CALC1:FORM REAL")
        inst.write(":CALC2:FEED 'XFR:POW:RAT 2,1';:CALC2:FORM IMAG")
        inst.write(":CALC3:FEED 'XFR:POW:COH 2,1';:CALC3:FORM MLIN")
        inst.write(":INIT:IMM")
        assert inst.query("*OPC?") == "1"
        got = {"points": int(inst.query("CALC1:DATA:HEAD:POIN?"))}
        inst.write("FORM:DATA ASC")
        got["ASC"] = [inst.query_ascii_values(f"CALC{n}:DATA?") for n in (1, 2)]
        got["x"] = inst.query_ascii_values("CALC1:X:DATA?")
        got["coh"] = inst.query_ascii_values("CALC3:DATA?")
        for fmt, dt in (("REAL,32", "f"), ("REAL,64", "d")):
            inst.write(f"FORM:DATA {fmt}")
            got[fmt] = [inst.query_binary_values(f"CALC{n}:DATA?", datatype=dt,
                                                 is_big_endian=True) for n in (1, 2)]
        got["errors"] = errors(inst)
    mem = daq.MemorySink()
    daq.acquire(rig.load_scene(SCENE, EQUIVALENT), seed=SEED, sinks=[mem])
    got["analysis"] = processing.analyze(
        mem.recording, processing.AnalyzerSettings(lines=800, span_hz=12.5))
    return got


def test_paper_frf_over_scpi_equals_daq_acquire_and_analyze_in_ascii(paper_measurement):
    m = paper_measurement
    h = m["analysis"].h_t.h
    assert m["errors"] == []
    assert m["points"] == len(m["x"]) == 801 == h.size
    np.testing.assert_array_equal(m["x"], m["analysis"].freqs_hz)
    # 17 significant digits read a float64 back exactly; line 0 is NaN (detrended), sent as
    # SCPI's 9.91E+37
    assert m["ASC"][0][0] == 9.91e37
    np.testing.assert_array_equal(m["ASC"][0][1:], h.real[1:])
    np.testing.assert_array_equal(m["ASC"][1][1:], h.imag[1:])
    np.testing.assert_array_equal(m["coh"][1:], m["analysis"].h_t.coherence[1:])


def test_paper_frf_over_scpi_equals_daq_acquire_and_analyze_in_real64(paper_measurement):
    h = paper_measurement["analysis"].h_t.h
    re, im = (np.asarray(v) for v in paper_measurement["REAL,64"])
    assert np.isnan(re[0]) and np.isnan(im[0])
    np.testing.assert_array_equal(re[1:], h.real[1:])
    np.testing.assert_array_equal(im[1:], h.imag[1:])


def test_paper_frf_over_scpi_equals_daq_acquire_and_analyze_in_real32(paper_measurement):
    h = paper_measurement["analysis"].h_t.h
    re, im = (np.asarray(v, dtype=float) for v in paper_measurement["REAL,32"])
    # float32 rounding: at most half an ulp, 2^-24 of the value
    for got, want in ((re, h.real), (im, h.imag)):
        err = np.abs(got[1:] - want[1:])
        assert np.all(err <= 2.0 ** -24 * np.abs(want[1:]) + 1e-45)
        assert np.any(err > 0)  # it really went through float32


def test_paper_measurement_reads_the_resonance(paper_measurement):
    """The trace is the bench's response: |H_t| peaks near the 2.48 Hz mode."""
    re, im = (np.asarray(v) for v in paper_measurement["REAL,64"])
    f = np.asarray(paper_measurement["x"])
    mag = np.hypot(re, im)
    band = (f > 1.5) & (f < 4.0)
    assert abs(f[band][np.argmax(mag[band])] - 2.48) < 0.05


# -- the language ---------------------------------------------------------------------------

def test_long_short_forms_case_units_suffixes_and_header_paths(visa):
    q = visa.query
    assert q("sens:freq:span 6.25hz;span?") == "6.25"
    assert q(":FREQuency:SPAN 0.01 KHZ;:SENSe:FREQuency:SPAN?") == "12.5"  # 10 Hz rounds up
    assert q("FREQ:SPAN 10 HZ;:FREQ:SPAN?") == "12.5"
    assert q("frequency:resolution 300;resolution?") == "400"
    visa.write("CALCulate3:FEED 'xfrequency:power:ratio 3,1';:calc3:form phase")
    assert q("CALC3:FEED?;FORM?") == '"XFR:POW:RAT 3,1";PHAS'
    assert q("INPut3:STATe?;:INP4?") == "1;1"
    assert q("FREQ:SPAN 25;*CLS;RES 200;*OPC?;:FREQ:SPAN?;RES?") == "1;25;200"  # common: no path
    assert q("*IDN?").split(",")[1] == "35670A"
    assert "emulated" in q("*IDN?").split(",")[3]
    assert q("*OPT?") == '"AY6"'
    assert errors(visa) == []


def test_unknown_and_invalid_commands_answer_real_scpi_errors_in_order(visa):
    visa.write("FOO:BAR 1")
    visa.write("CALC5:FEED 'XFR:POW 1'")
    visa.write("FREQ:SPAN 200 HZ")
    visa.write("FREQ:SPAN 1 MHZ")  # SCPI's MHZ is megahertz: beyond 102.4 kHz
    visa.write("INST:SEL CORR")  # correlation analysis is not emulated
    visa.write("SOUR:FUNC BCH")
    visa.write("CALC1:FEED 'XFR:POW:LIN 1'")
    visa.write("FREQ:SPAN")
    visa.write("FREQ:SPAN 10 PARSEC")
    visa.write("FREQ:STAR 1 HZ")
    visa.write("*IDN? 1")
    visa.write(":SOUR:FUNC RAND;:SOUR:VOLT 0.1 VPK")  # a noise source has no peak level
    visa.write(":AVER OFF;:INIT")  # one average: no coherence
    errs = errors(visa)
    codes = [int(e.split(",")[0]) for e in errs]
    assert codes == [-113, -114, -221, -222, -221, -221, -224, -109, -131, -221, -108, -221,
                     -221], errs
    assert "1 average" in errs[-1]
    assert "simulation_rate_hz" in errs[2] and "largest span is 100 Hz" in errs[2]
    assert "SINE" in errs[4]
    esr = int(visa.query("*ESR?"))
    assert esr & 32 and esr & 16  # command and execution errors
    assert visa.query("FREQ:SPAN?") == "12.5"  # nothing refused was applied


def test_error_queue_is_bounded_and_reports_its_overflow(visa):
    for _ in range(8):
        visa.write(";".join(["NOPE"] * 5))
    errs = errors(visa)
    assert len(errs) == 30
    assert errs[-1].startswith("-350,") and errs[0].startswith("-113,")


def test_malformed_binary_and_overlong_lines_leave_the_connection_alive(visa):
    visa.write_raw(b"\x00\xff\xfeGARBAGE\x01\n")
    visa.write_raw(b"FREQ:SPAN " + b"9" * 70_000 + b"\n")
    visa.write_raw(b"CALC1:FEED 'unterminated\n")
    codes = [int(e.split(",")[0]) for e in errors(visa)]
    assert codes == [-101, -363, -102]
    assert visa.query("*IDN?").startswith("Agilent Technologies,35670A")


# -- the measurement ------------------------------------------------------------------------

def test_status_follows_the_measurement_and_overload_flags_follow_the_range(visa):
    visa.write(":FREQ:SPAN 12.5;RES 100;:AVER:COUN 2;:OUTP ON")
    visa.write(":VOLT1:RANG -40")  # 10 mV peak: the accelerometer's volts clip
    assert int(visa.query(":INIT;:STAT:OPER:COND?")) & 16  # measuring
    assert visa.query("*OPC?") == "1"
    assert visa.query("STAT:OPER:COND?") == "0"
    assert int(visa.query("STAT:OPER:EVEN?")) & (16 | 256) == 16 | 256  # measured, averaged
    assert int(visa.query("STAT:DEV:COND?")) & 1  # input 1 overloaded
    assert int(visa.query("STAT:QUES:COND?")) & 1
    visa.write(":VOLT1:RANG 0;:INIT;*WAI")
    assert visa.query("STAT:DEV:COND?") == "0"
    assert errors(visa) == []


def test_autorange_finds_the_smallest_range_that_holds_the_signal(visa):
    visa.write(":FREQ:SPAN 12.5;RES 100;:AVER:COUN 2;:OUTP ON")
    visa.write(":VOLT1:RANG -51;:VOLT1:RANG:AUTO ON;:VOLT2:RANG 27;:VOLT2:RANG:AUTO ON")
    visa.write(":VOLT1:RANG:UNIT:XDCR OFF;:CALC4:FEED 'XTIM:VOLT 1';:CALC4:FORM REAL;:INIT;*WAI")
    assert visa.query("STAT:DEV:COND?") == "0"  # nothing clipped in the measurement kept
    r1, r2 = (int(visa.query(f":VOLT{n}:RANG?")) for n in (1, 2))
    assert -51 < r1 < 0 and r2 < 27
    visa.write(":FORM REAL,64")
    v = np.asarray(visa.query_binary_values(":CALC4:DATA?", datatype="d", is_big_endian=True))
    # the last record's peak is within the range and, one record of two, not far below it
    assert 20 * np.log10(np.max(np.abs(v))) <= r1 < 20 * np.log10(np.max(np.abs(v))) + 6
    visa.write(":VOLT1:RANG 0")  # a set range ends autoranging
    assert visa.query(":VOLT1:RANG:AUTO?;:VOLT2:RANG:AUTO?") == "0;1"
    # 1 V rms = 1.41 V peak = +3.01 dBVpk, rounded up; -7 dBVrms = -3.99 dBVpk
    assert visa.query(":VOLT3:RANG 1 VRMS;:VOLT3:RANG?;:VOLT3:RANG -7 DBVRMS;RANG?") == "4;-3"
    assert errors(visa) == []


def test_init_while_measuring_is_ignored_and_abort_ends_the_measurement(visa):
    visa.write(":FREQ:SPAN 12.5;RES 1600;:AVER:COUN 2000;:OUTP ON")
    visa.write(":INIT;:INIT")
    t0 = time.perf_counter()
    visa.write(":ABOR")
    assert visa.query("*OPC?") == "1"
    assert time.perf_counter() - t0 < 10.0
    assert [int(e.split(",")[0]) for e in errors(visa)] == [-213]


def test_a_client_that_does_not_read_its_answers_is_dropped_and_the_next_served():
    from processing.instrument.analyzer35670a import Analyzer35670A
    from rig.scene import load_scene

    with serving(Analyzer35670A(load_scene(SCENE)), send_timeout_s=1.0) as srv:
        with socket.create_connection(srv.address, timeout=10) as s:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            line = b";".join([b"*IDN?"] * 10_000) + b"\n"  # 60 kB asking 660 kB
            try:
                for _ in range(30):  # 20 MB of answers, never read: more than the buffers
                    s.sendall(line)
            except OSError:
                pass  # the server already dropped this client
            time.sleep(2.0)
            with session(srv.resource, 10_000) as inst:
                assert "35670A" in inst.query("*IDN?")


def test_a_client_that_leaves_mid_measurement_leaves_the_server_serving(server):
    with socket.create_connection(server.address, timeout=10) as s:
        s.sendall(b"*RST;:FREQ:RES 100;:AVER:COUN 3;:OUTP ON;:INIT;*OPC?\n")
    with session(server.resource, TIMEOUT_MS) as inst:
        assert inst.query("*OPC?") == "1"
        assert int(inst.query("CALC1:DATA:HEAD:POIN?")) == 101
        assert len(inst.query_ascii_values("CALC1:DATA?")) == 101
        assert errors(inst) == []


def test_time_trace_of_the_drive_has_the_time_record_and_the_source_level(visa):
    visa.write(":FREQ:SPAN 12.5;RES 400;:AVER:COUN 2;:SOUR:VOLT 0.2;:OUTP ON")
    visa.write(":CALC4:FEED 'XTIM:VOLT 4';:CALC4:FORM REAL;:INIT;*WAI")
    assert visa.query("CALC4:DATA:HEAD:POIN?") == "1024"
    visa.write("FORM REAL,64")
    v = np.asarray(visa.query_binary_values("CALC4:DATA?", datatype="d", is_big_endian=True))
    t = np.asarray(visa.query_binary_values("CALC4:X:DATA?", datatype="d",
                                            is_big_endian=True))
    assert v.size == t.size == 1024 and t[1] == 1 / 32
    # rms of 32 s of 12.5 Hz band-limited noise: relative scatter ~ 1 / (2 sqrt(B T)) = 2.5 %
    assert abs(np.sqrt(np.mean(v**2)) / 0.2 - 1) < 0.15
    assert errors(visa) == []


def test_formats_units_and_byte_order_describe_one_trace(visa):
    """MLOG, MLIN, PHAS, UPH, REAL and IMAG of one ratio agree; transducer units off read the
    ratio in V/V (the calibrations' ratio, XDCR:SENS?); FORM:BORD SWAP is little-endian; ASC,n
    has n digits."""
    visa.write(":FREQ:RES 100;:AVER:COUN 2;:OUTP ON;:CALC1:FEED 'XFR:POW:RAT 2,1';:INIT;*WAI")

    def read(form, order="NORM"):
        visa.write(f":CALC1:FORM {form};:FORM REAL,64;:FORM:BORD {order}")
        return np.asarray(visa.query_binary_values(":CALC1:DATA?", datatype="d",
                                                   is_big_endian=order == "NORM"))[1:]

    re, im = read("REAL"), read("IMAG")
    np.testing.assert_array_equal(read("REAL", "SWAP"), re)
    h = re + 1j * im
    np.testing.assert_allclose(read("MLIN"), np.abs(h), rtol=1e-15)
    np.testing.assert_allclose(read("MLOG"), 20 * np.log10(np.abs(h)), rtol=1e-12)
    np.testing.assert_allclose(read("PHAS"), np.degrees(np.angle(h)), rtol=1e-15)
    uph = read("UPH")
    np.testing.assert_allclose(np.mod(uph - read("PHAS") + 180, 360) - 180, 0, atol=1e-9)
    assert np.max(np.abs(np.diff(uph))) < 180
    sens = [float(visa.query(f":VOLT{n}:RANG:UNIT:XDCR:SENS?")) for n in (1, 2)]
    visa.write(":VOLT1:RANG:UNIT:XDCR OFF;:VOLT2:RANG:UNIT:XDCR OFF")
    np.testing.assert_allclose(read("MLIN"), np.abs(h) * sens[1] / sens[0], rtol=1e-13)
    visa.write(":FORM:BORD NORM;:FORM ASC,6;:CALC1:FORM REAL")
    first = visa.query(":CALC1:DATA?").split(",")[1]
    assert len(first.lstrip("+-").split("E")[0].replace(".", "")) == 6
    assert visa.query(":FORM?") == "ASC,6"
    assert errors(visa) == []


def test_source_off_measures_noise_spectra_without_a_model_comparison(visa):
    visa.write(":FREQ:RES 100;:AVER:COUN 2;:OUTP OFF;:CALC1:FEED 'XFR:POW 2';:INIT;*WAI")
    visa.write("FORM REAL,64")
    p = np.asarray(visa.query_binary_values("CALC1:DATA?", datatype="d", is_big_endian=True))
    assert p.size == 101 and np.all(np.isfinite(p[1:]))
    assert errors(visa) == []


def test_pymeasure_instrument_on_the_socket_reads_identity_status_and_a_trace(server):
    """pymeasure's own VISA adapter and SCPI properties, as a driver written with it uses them
    (the style of the community 35670A driver's hardware suite)."""
    pymeasure = pytest.importorskip("pymeasure.instruments")
    from pymeasure.instruments import Instrument, SCPIMixin

    class Analyzer(SCPIMixin, Instrument):
        span = Instrument.control("SENSe:FREQuency:SPAN?", "SENSe:FREQuency:SPAN %g", "span",
                                  cast=float)
        output_enabled = Instrument.control("OUTPut:STATe?", "OUTPut:STATe %d", "source on",
                                            values={True: 1, False: 0}, map_values=True,
                                            cast=int)
        operation_condition = Instrument.measurement("STATus:OPERation:CONDition?", "oper")

    dev = Analyzer(server.resource, name="virtual 35670A", read_termination="\n",
                   write_termination="\n", timeout=TIMEOUT_MS)
    try:
        dev.reset()
        assert "35670A" in dev.id
        dev.span = 10
        assert dev.span == 12.5
        dev.output_enabled = True
        assert dev.output_enabled is True
        dev.write("FREQ:RES 100;:AVER:COUN 2;:INIT")
        dev.complete  # *OPC?
        assert dev.operation_condition == 0
        data = dev.values("CALC1:DATA?")
        assert len(data) == 101
        assert dev.next_error[0] == 0
    finally:
        dev.adapter.close()
    assert pymeasure  # imported for the adapter


# -- the command line -----------------------------------------------------------------------

#: How long a signalled ``daq serve`` may take to exit: well under a second on an idle machine;
#: the bound only stops a hang (a loaded CI host has taken over 20 s).
STOP_WAIT_S = 90


def _serve(*extra):
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    p = subprocess.Popen([sys.executable, "-m", "daq.cli", "serve", SCENE, "--scpi",
                          "127.0.0.1:0", "--seed", "1", *extra],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                         # as from an interactive shell: a background job or a test worker
                         # may have SIGINT ignored, which the child would inherit
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    line = p.stdout.readline()  # bounded by the test's own timeout below
    assert "TCPIP::127.0.0.1::" in line, line
    resource = line.split(" at ")[-1].strip()
    return p, resource


@pytest.mark.parametrize("sig, code, name", [(signal.SIGINT, 130, "SIGINT"),
                                             (signal.SIGTERM, 143, "SIGTERM")])
def test_daq_serve_prints_the_resource_and_stops_in_one_line_on_a_signal(sig, code, name):
    p, resource = _serve()
    try:
        with session(resource, 20_000) as inst:
            assert "35670A" in inst.query("*IDN?")
        p.send_signal(sig)
        _, err = p.communicate(timeout=STOP_WAIT_S)
    finally:
        if p.poll() is None:
            p.kill()
            p.communicate(timeout=10)  # also closes the pipes
    assert p.returncode == code
    assert "Traceback" not in err
    assert err.strip().splitlines()[-1].startswith(f"stopped ({name}) after 0 measurements")


def test_daq_serve_stops_on_sigterm_while_a_client_waits_in_opc():
    p, resource = _serve("--realtime", "-q")
    try:
        port = int(resource.split("::")[2])
        with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
            s.sendall(b":FREQ:RES 100;:AVER:COUN 5;:OUTP ON;:INIT;*OPC?\n")
            time.sleep(1.0)  # paced: 300 s of settling in real time, *OPC? is waiting
            p.send_signal(signal.SIGTERM)
            _, err = p.communicate(timeout=STOP_WAIT_S)
            assert s.recv(100) == b""  # closed without an answer
    finally:
        if p.poll() is None:
            p.kill()
            p.communicate(timeout=10)  # also closes the pipes
    assert p.returncode == 143
    assert "Traceback" not in err
    assert err.strip().splitlines()[-1].startswith("stopped (SIGTERM) after 1 measurement")


def test_daq_serve_out_keeps_each_measurements_run_file_whose_analysis_is_the_trace(tmp_path):
    import daq
    import processing
    from processing.instrument.measurement import FftSetup, SourceSetup, analyzer_settings

    p, resource = _serve("--out", str(tmp_path), "-q")
    try:
        with session(resource, TIMEOUT_MS) as inst:
            inst.write(":FREQ:RES 200;:AVER:COUN 3;:OUTP ON;:CALC1:FEED 'XFR:POW:RAT 3,1'")
            inst.write(":CALC1:FORM IMAG;:INIT;*WAI;:FORM REAL,64")
            im = np.asarray(inst.query_binary_values(":CALC1:DATA?", datatype="d",
                                                     is_big_endian=True))
            assert errors(inst) == []
        p.send_signal(signal.SIGINT)
        p.communicate(timeout=STOP_WAIT_S)
    finally:
        if p.poll() is None:
            p.kill()
            p.communicate(timeout=10)  # also closes the pipes
    files = sorted(tmp_path.glob("*.h5"))
    assert [f.name for f in files] == ["measurement_0001.h5"]
    setup = FftSetup(lines=200, averages=3, source=SourceSetup(enabled=True))
    a = processing.analyze(daq.read_run(files[0]), analyzer_settings(setup))
    np.testing.assert_array_equal(im[1:], a.theta_2.h.imag[1:])


def test_daq_serve_refuses_a_bad_address_and_a_busy_port_in_one_line():
    bad = subprocess.run([sys.executable, "-m", "daq.cli", "serve", SCENE, "--scpi", "nowhere"],
                         capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "'nowhere' is not HOST:PORT" in bad.stderr
    with socket.create_server(("127.0.0.1", 0)) as busy:
        port = busy.getsockname()[1]
        r = subprocess.run([sys.executable, "-m", "daq.cli", "serve", SCENE, "--scpi",
                            f"127.0.0.1:{port}"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 1
    assert f"cannot listen on 127.0.0.1:{port}" in r.stderr and "Traceback" not in r.stderr
