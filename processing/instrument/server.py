"""A raw SCPI socket server (the VISA resource ``TCPIP::HOST::PORT::SOCKET``) in front of one
instrument (anything with ``execute(line) -> responses`` and ``push_error(code, detail)``).

Protocol: program messages end in ``\\n`` (a ``\\r`` before it is dropped); the responses of a
message's queries are joined with ``;`` and end in ``\\n`` (a binary block as it is, then
``\\n``). Clients are served one at a time, in turn; the others wait in the listen backlog
(:data:`BACKLOG`). Safety:

- a line longer than :data:`MAX_LINE` bytes is dropped whole with ``-363,"Input buffer
  overrun"``; a line that is not printable ASCII (binary, control characters) with
  ``-101,"Invalid character"``; the connection lives on;
- an answer a client does not read within :data:`SEND_TIMEOUT_S` (``send_timeout_s``) ends that
  client, as does a
  disconnect (mid-measurement too: the measurement goes on and the next client finds it);
- an unexpected error in a command is ``-200,"Execution error"`` in the queue and one line on
  the console (``log``), never a traceback to either;
- every wait is a 0.2 s slice of a ``select``, so SIGINT/SIGTERM (raised in the main thread)
  and :meth:`ScpiServer.stop` end :meth:`ScpiServer.serve_forever` promptly.
"""

from __future__ import annotations

import selectors
import socket
import threading

__all__ = ["ScpiServer", "MAX_LINE", "BACKLOG", "SEND_TIMEOUT_S", "resource_string"]

MAX_LINE = 64 * 1024
BACKLOG = 8
SEND_TIMEOUT_S = 30.0
_SLICE_S = 0.2


def resource_string(host: str, port: int) -> str:
    """The VISA resource of a raw socket at ``host:port``."""
    return f"TCPIP::{host}::{port}::SOCKET"


def _printable(line: bytes) -> bool:
    return all(32 <= b < 127 or b == 9 for b in line)


class ScpiServer:
    """Listen on ``host:port`` (port 0: a free one; :attr:`address` tells which)."""

    def __init__(self, instrument, host: str = "127.0.0.1", port: int = 5025, *,
                 log=lambda line: None, max_line: int = MAX_LINE,
                 send_timeout_s: float = SEND_TIMEOUT_S):
        self.instrument, self.log, self.max_line = instrument, log, max_line
        self.send_timeout_s = send_timeout_s
        self._stop = threading.Event()
        self.sock = socket.create_server((host, port), backlog=BACKLOG, reuse_port=False)
        self.sock.setblocking(False)
        self.clients_served = 0

    @property
    def address(self) -> tuple[str, int]:
        return self.sock.getsockname()[:2]

    @property
    def resource(self) -> str:
        host, port = self.address
        return resource_string(host, port)

    def stop(self) -> None:
        """Make :meth:`serve_forever` return within a slice (from any thread)."""
        self._stop.set()

    def close(self) -> None:
        self._stop.set()
        self.sock.close()

    def serve_forever(self) -> None:
        """Accept and serve clients one at a time until :meth:`stop` (or a signal)."""
        with selectors.DefaultSelector() as sel:
            sel.register(self.sock, selectors.EVENT_READ)
            while not self._stop.is_set():
                if not sel.select(_SLICE_S):
                    continue
                try:
                    conn, peer = self.sock.accept()
                except (BlockingIOError, InterruptedError):
                    continue
                self.clients_served += 1
                self.log(f"client {peer[0]}:{peer[1]} connected")
                with conn:
                    why = self._serve(conn)
                self.log(f"client {peer[0]}:{peer[1]} {why}")

    def _serve(self, conn: socket.socket) -> str:
        conn.setblocking(False)
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)  # an answer leaves at once
        buf, skipping = bytearray(), False
        with selectors.DefaultSelector() as sel:
            sel.register(conn, selectors.EVENT_READ)
            while not self._stop.is_set():
                if not sel.select(_SLICE_S):
                    continue
                try:
                    chunk = conn.recv(65536)
                except (BlockingIOError, InterruptedError):
                    continue
                except OSError as exc:
                    return f"dropped ({exc.strerror or exc})"
                if not chunk:
                    return "disconnected"
                buf += chunk
                while True:
                    nl = buf.find(b"\n")
                    if nl < 0:
                        if len(buf) > self.max_line:
                            if not skipping:
                                self.instrument.push_error(-363, f"a line over {self.max_line} "
                                                           "bytes was dropped")
                            skipping = True
                            buf.clear()
                        break
                    line, buf = bytes(buf[:nl]), buf[nl + 1:]
                    if skipping or len(line) > self.max_line:
                        if not skipping:
                            self.instrument.push_error(-363, f"a line over {self.max_line} "
                                                       "bytes was dropped")
                        skipping = False
                        continue
                    reply = self._message(line.rstrip(b"\r"))
                    if reply is not None and not self._send(conn, reply):
                        return "dropped (did not read its answer)"
        return "closed (server stopping)"

    def _message(self, line: bytes) -> bytes | None:
        if not _printable(line):
            self.instrument.push_error(-101, "the line holds binary or control characters")
            return None
        try:
            responses = self.instrument.execute(line.decode("ascii"))
        except Exception as exc:  # a bug must not reach the client or the console as a trace
            self.instrument.push_error(-200, f"internal error: {exc}")
            self.log(f"internal error on {line[:60]!r}: {exc}")
            return None
        if not responses:
            return None
        parts = [r if isinstance(r, bytes) else r.encode("ascii") for r in responses]
        return b";".join(parts) + b"\n"

    def _send(self, conn: socket.socket, data: bytes) -> bool:
        view = memoryview(data)
        with selectors.DefaultSelector() as sel:
            sel.register(conn, selectors.EVENT_WRITE)
            waited = 0.0
            while view:
                if not sel.select(_SLICE_S):
                    waited += _SLICE_S
                    if waited >= self.send_timeout_s or self._stop.is_set():
                        return False
                    continue
                try:
                    n = conn.send(view)
                except (BlockingIOError, InterruptedError):
                    continue
                except OSError:
                    return False
                view, waited = view[n:], 0.0
        return True
