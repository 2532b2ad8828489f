"""The virtual 35670A served in a thread on a free port, and pyvisa clients of it, shared by the
SCPI tests (imported by test modules: pytest puts this directory on sys.path).

:func:`serving` runs a :class:`processing.instrument.server.ScpiServer` in a daemon thread and
always stops, joins and closes it; :func:`session` opens a pyvisa-py socket session with the
line terminations a lab script sets, bounded by ``timeout_ms`` per read, and always closes it;
:func:`errors` empties ``SYST:ERR?``. The fixture :func:`visa` (a reset session to the
test module's ``server`` fixture) is made visible by ``tests/processing/conftest.py``.
"""

from __future__ import annotations

import threading
from contextlib import contextmanager

import pytest

#: Every VISA read is bounded by this; the first measurement of a fresh checkout also compiles
#: the bench's numba kernels (tens of seconds on a loaded machine).
TIMEOUT_MS = 300_000


@contextmanager
def serving(instrument, **options):
    """Serve ``instrument`` on ``127.0.0.1`` at a free port; yield the server, then abort the
    instrument, stop the server and join its thread (10 s at most)."""
    from processing.instrument.server import ScpiServer

    srv = ScpiServer(instrument, "127.0.0.1", 0, **options)
    t = threading.Thread(target=srv.serve_forever, daemon=True)
    t.start()
    try:
        yield srv
    finally:
        instrument.abort()
        srv.stop()
        t.join(10)
        srv.close()
        assert not t.is_alive()


@contextmanager
def session(resource: str, timeout_ms: int):
    """A pyvisa-py session to ``resource`` (``\\n`` terminations, ``timeout_ms`` a read)."""
    import pyvisa

    rm = pyvisa.ResourceManager("@py")
    inst = rm.open_resource(resource, read_termination="\n", write_termination="\n",
                            timeout=timeout_ms)
    try:
        yield inst
    finally:
        inst.close()
        rm.close()


def errors(inst) -> list[str]:
    """Read ``SYST:ERR?`` until ``0,...``: the queued errors, oldest first (40 at most)."""
    out = []
    for _ in range(40):
        e = inst.query("SYST:ERR?")
        if e.startswith("0,"):
            return out
        out.append(e)
    raise AssertionError(f"the error queue does not empty: {out}")


@pytest.fixture
def visa(server):
    """A session to the module's ``server``, reset with ``*RST;*CLS``."""
    with session(server.resource, TIMEOUT_MS) as inst:
        inst.write("*RST;*CLS")
        yield inst
