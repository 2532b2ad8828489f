"""Addresses of rerun viewers (no rerun import: the CLI checks them before a run starts)."""

from __future__ import annotations

DEFAULT_PORT = 9876


def host_port(url: str) -> tuple[str, int]:
    """``rerun+http://HOST:PORT/proxy`` -> (HOST, PORT); ValueError naming the URL otherwise."""
    rest = str(url).split("://", 1)[-1].split("/", 1)[0]
    host, _, port = rest.rpartition(":")
    try:
        return (host or "127.0.0.1"), int(port)
    except ValueError:
        raise ValueError(f"viewer URL {url!r} is invalid: expected e.g. "
                         f"rerun+http://127.0.0.1:{DEFAULT_PORT}/proxy") from None


#: Seconds a rerun viewer has to accept a connection and answer it.
ANSWER_TIMEOUT_S = 3.0
# An HTTP/2 client's connection preface and an empty SETTINGS frame: a viewer's gRPC server
# answers with its own SETTINGS frame at once.
_H2_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + b"\x00\x00\x00\x04\x00\x00\x00\x00\x00"


def viewer_silence(url: str, timeout_s: float = ANSWER_TIMEOUT_S) -> str | None:
    """Why nothing answers as a rerun viewer at ``url`` within ``timeout_s`` ("connection
    refused", "no answer within 3 s" ...), or None if a gRPC (HTTP/2) server answers there. A
    peer that accepts connections and never answers would hold the stream's flush forever."""
    import socket
    import time

    host, port = host_port(url)
    t0 = time.monotonic()
    try:
        with socket.create_connection((host, port), timeout=timeout_s) as s:
            s.settimeout(max(0.1, timeout_s - (time.monotonic() - t0)))
            s.sendall(_H2_PREFACE)
            head = s.recv(9)
    except socket.timeout:
        return f"no answer within {timeout_s:g} s"
    except OSError as exc:
        return exc.strerror.lower() if exc.strerror else str(exc)
    if len(head) < 4 or head[3] != 0x04:  # not an HTTP/2 SETTINGS frame
        return "what answers there is not a rerun viewer (no gRPC server)"
    return None
