#!/usr/bin/env python3
"""The virtual 35670A's overhead: what SCPI adds to the transport and to the measurement.

1. Transport: a pyvisa-py client (``TCPIP::127.0.0.1::PORT::SOCKET``) times ``*IDN?`` round trips
   and 801-point ``REAL,64`` trace reads (``CALC1:DATA?`` after an 800-line measurement) from
   ``daq serve`` and, beside it, from a minimal socket echo server written here that answers the
   same two queries with the same bytes, prebuilt (the transport's floor: the trace's bytes
   matter, pyvisa-py reads a block in more pieces the more ``\n`` bytes it holds). Both servers are processes of
   their own; the reads alternate between them; medians and quartiles, and the ratio of medians
   (target: within 3x of the floor).
2. Measurement: a 30-average FFT measurement of the paper's bench (12.5 Hz span, 1600 lines:
   128 s time records, the scene's 300 s settling) in fast mode, ``INIT`` to ``*OPC?`` over
   SCPI, beside ``daq.acquire`` + ``processing.analyze`` of the same bench and settings in this
   process; interleaved rounds after one warm-up each, wall medians (target: within 1.2x).

    .venv/bin/python benchmarks/scpi.py [--reads 200] [--rounds 5]
"""

from __future__ import annotations

import argparse
import contextlib
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from benchmarks.interleave import quart  # noqa: E402

SETUP = ":INST:SEL FFT;:SOUR:FUNC RAND;:SOUR:VOLT 0.1;:OUTP ON;:FREQ:SPAN 12.5;RES {lines};" \
        ":AVER:TYPE RMS;COUN {averages};:AVER ON;:CALC1:FEED 'XFR:POW:RAT 2,1';:CALC1:FORM REAL"

#: The floor: answers *IDN? and CALC1:DATA? with fixed bytes, one client at a time.
ECHO_SERVER = r"""
import socket, sys
idn = open(sys.argv[1], "rb").read()
block = open(sys.argv[2], "rb").read()
srv = socket.create_server(("127.0.0.1", 0))
print(srv.getsockname()[1], flush=True)
while True:
    conn, _ = srv.accept()
    buf = b""
    with conn:
        while True:
            chunk = conn.recv(65536)
            if not chunk:
                break
            buf += chunk
            while b"\n" in buf:
                line, buf = buf.split(b"\n", 1)
                line = line.strip().upper()
                if line == b"*IDN?":
                    conn.sendall(idn)
                elif line.startswith(b"CALC1:DATA?"):
                    conn.sendall(block)
"""


def _start_serve():
    p = subprocess.Popen([sys.executable, "-m", "daq.cli", "serve", "ishizaki2009", "--scpi",
                          "127.0.0.1:0", "--seed", "2009", "-q"], cwd=ROOT,
                         stdout=subprocess.PIPE, text=True)
    line = p.stdout.readline()
    return p, line.split(" at ")[-1].strip()


def _raw_answer(resource, query: bytes) -> bytes:
    """The emulator's exact answer to ``query`` (a raw socket read up to its length)."""
    _, host, port, _ = resource.split("::")
    with socket.create_connection((host, int(port)), timeout=60) as s:
        s.sendall(query + b"\n")
        data = b""
        while not data.endswith(b"\n") or (data.startswith(b"#") and len(data) < 2 + int(
                data[1:2]) + int(data[2:2 + int(data[1:2])] or 0) + 1):
            data += s.recv(65536)
    return data


def _start_echo(rm, serve_res, tmp: Path):
    emu = _open(rm, serve_res)
    emu.write(SETUP.format(lines=800, averages=2) + ";:INIT;*WAI;:FORM:DATA REAL,64")
    assert emu.query("SYST:ERR?").startswith("0,")
    emu.close()
    (tmp / "idn").write_bytes(_raw_answer(serve_res, b"*IDN?"))
    (tmp / "block").write_bytes(_raw_answer(serve_res, b"CALC1:DATA?"))
    p = subprocess.Popen([sys.executable, "-c", ECHO_SERVER, str(tmp / "idn"),
                          str(tmp / "block")], stdout=subprocess.PIPE, text=True)
    return p, f"TCPIP::127.0.0.1::{p.stdout.readline().strip()}::SOCKET"


@contextlib.contextmanager
def _open_rm():
    import pyvisa

    rm = pyvisa.ResourceManager("@py")
    try:
        yield rm
    finally:
        rm.close()


def _open(rm, resource):
    return rm.open_resource(resource, read_termination="\n", write_termination="\n",
                            timeout=120_000)


def _row(name, xs, unit=1e3, label="ms"):
    q = quart(np.array(xs) * unit)
    return f"| {name} | {q[1]:.3f} [{q[0]:.3f}, {q[2]:.3f}] {label} |"


def transport(rm, serve_res, echo_res, reads: int) -> list[str]:
    emu, floor = _open(rm, serve_res), _open(rm, echo_res)
    times = {k: [] for k in ("idn emu", "idn floor", "trace emu", "trace floor")}
    for i in range(reads):
        for who, inst in (("emu", emu), ("floor", floor))[:: 1 if i % 2 == 0 else -1]:
            t = time.perf_counter()
            inst.query("*IDN?")
            times[f"idn {who}"].append(time.perf_counter() - t)
            t = time.perf_counter()
            v = inst.query_binary_values("CALC1:DATA?", datatype="d", is_big_endian=True)
            times[f"trace {who}"].append(time.perf_counter() - t)
            assert len(v) == 801
    emu.close()
    floor.close()
    rows = [_row(k, v) for k, v in times.items()]
    for q in ("idn", "trace"):
        r = statistics.median(times[f"{q} emu"]) / statistics.median(times[f"{q} floor"])
        rows.append(f"| {q}: emulator / floor (medians) | {r:.2f} |")
    return rows


def measurement(rm, serve_res, rounds: int) -> list[str]:
    import daq
    import processing
    import rig
    from processing.instrument.measurement import (FftSetup, SourceSetup, analyzer_settings,
                                                   bench_overrides)

    setup = FftSetup(span_hz=12.5, lines=1600, averages=30,
                     source=SourceSetup(enabled=True, function="random", level_vrms=0.1))
    base = rig.load_scene("ishizaki2009")
    scene = rig.load_scene("ishizaki2009", bench_overrides(base, setup))
    emu = _open(rm, serve_res)
    emu.write("*RST;*CLS")
    emu.write(SETUP.format(lines=1600, averages=30))

    def over_scpi():
        t = time.perf_counter()
        emu.write(":INIT")
        assert emu.query("*OPC?") == "1"
        return time.perf_counter() - t

    def in_process():
        t = time.perf_counter()
        mem = daq.MemorySink()
        daq.acquire(scene, seed=2009, sinks=[mem])
        processing.analyze(mem.recording, analyzer_settings(setup))
        return time.perf_counter() - t

    over_scpi(), in_process()  # warm-up: numba, caches
    walls = {"SCPI": [], "library": []}
    for r in range(rounds):
        for name, fn in (("SCPI", over_scpi), ("library", in_process))[:: 1 if r % 2 == 0
                                                                         else -1]:
            walls[name].append(fn())
    assert emu.query("SYST:ERR?").startswith("0,")
    emu.close()
    ratio = np.array(walls["SCPI"]) / np.array(walls["library"])
    q = quart(ratio)
    return [_row(f"30 x 128 s measurement, {k}", v, 1.0, "s") for k, v in walls.items()] + [
        f"| SCPI / library, per round | {q[1]:.3f} [{q[0]:.3f}, {q[2]:.3f}] |"]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reads", type=int, default=200)
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args(argv)
    serve, serve_res = _start_serve()
    echo = None
    try:
        with tempfile.TemporaryDirectory() as tmp, _open_rm() as rm:
            echo, echo_res = _start_echo(rm, serve_res, Path(tmp))
            print("| what | median [quartiles] |\n|---|---|")
            for row in transport(rm, serve_res, echo_res, args.reads):
                print(row, flush=True)
            for row in measurement(rm, serve_res, args.rounds):
                print(row, flush=True)
    finally:
        for p in (serve, echo):
            if p is not None:
                p.terminate()
                p.wait(20)


if __name__ == "__main__":
    main()
