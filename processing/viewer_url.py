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
