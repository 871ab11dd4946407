"""Starting the viewer's server (viser) on a host and port: their checks, a port that
can be bound, and a start that fails with a typed error rather than waiting forever.

viser's ``ViserServer`` starts a server thread and waits, without a time limit, for it to
report that it listens; a thread that fails (a port out of range: ``OverflowError``; a
host it cannot bind: every one of its 1000 port attempts fails) never reports, and the
constructor never returns. :func:`start_server` therefore checks first that the server
can listen (:func:`listen_port`) and then waits for viser at most
:data:`SERVER_START_TIMEOUT` seconds.
"""

from __future__ import annotations

import errno
import socket
import threading
from typing import Any

from ..core import checks
from ..errors import InvalidArgumentType, InvalidInput, InvalidOption

__all__ = [
    "PORT_ATTEMPTS",
    "SERVER_START_TIMEOUT",
    "check_host",
    "check_port",
    "listen_port",
    "start_server",
]

#: How long [s] the server may take to start before :func:`start_server` gives up with
#: :class:`qpik.InvalidInput` (it starts in well under a second).
SERVER_START_TIMEOUT = 10.0
#: How many ports from the one asked for viser tries when they are busy.
PORT_ATTEMPTS = 1000


def check_host(host: Any) -> str:
    """``host`` if it is a str (an interface's address or name; whether the server can
    listen there is checked when it starts); else :class:`qpik.InvalidArgumentType`."""
    if not isinstance(host, str):
        raise InvalidArgumentType(
            "host", "an interface address or name (a str)", checks.type_name(host)
        )
    return host


def check_port(port: Any) -> int:
    """``port`` as an int in ``[0, 65535]`` (0: any free port), as ``qpik view --port``
    checks it; else :class:`qpik.InvalidOption` (:class:`qpik.InvalidArgumentType` for a
    non-int)."""
    return checks.check_integer("port", port, 0, 65535)


def _bind_error(addresses: list[Any], port: int) -> OSError | None:
    """The error binding ``port`` on every one of ``addresses`` (``getaddrinfo``'s),
    as asyncio's server binds them (``SO_REUSEADDR``, IPv6 sockets IPv6 only); ``None``
    when all bind."""
    for family, kind, proto, _, address in addresses:
        try:
            with socket.socket(family, kind, proto) as sock:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
                if family == socket.AF_INET6 and hasattr(socket, "IPPROTO_IPV6"):
                    sock.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_V6ONLY, 1)
                sock.bind((address[0], port, *address[2:]))
        except OSError as exc:
            return exc
    return None


def listen_port(host: str, port: int) -> int:
    """The port the server will listen on: ``port`` when ``host`` can bind it, else (it is
    busy) the next free one, as viser picks it (0: any free port). An unresolvable
    ``host``, one that is not this machine's, a port it may not bind, or
    :data:`PORT_ATTEMPTS` busy ports: :class:`qpik.InvalidOption` naming ``host`` or
    ``port`` (rather than a server thread that dies and a viewer that waits forever)."""
    where = "an address or name of this machine's interfaces"
    try:
        addresses = socket.getaddrinfo(
            host or None, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE
        )
    except (OSError, UnicodeError, ValueError) as exc:
        reason = getattr(exc, "strerror", None) or str(exc)
        raise InvalidOption(
            "host", host, where, f"host {host!r} cannot be resolved to listen on: {reason}"
        ) from None
    if not addresses:
        raise InvalidOption("host", host, where, f"host {host!r} resolves to no address")
    last = min(port + PORT_ATTEMPTS, 65536) if port else 1
    for candidate in range(port, last):
        error = _bind_error(addresses, candidate)
        if error is None:
            return candidate
        if error.errno != errno.EADDRINUSE:
            field = "host" if error.errno == errno.EADDRNOTAVAIL else "port"
            raise InvalidOption(
                field,
                host if field == "host" else port,
                where if field == "host" else "a port this process may listen on",
                f"{field} {host if field == 'host' else port!r}: cannot listen on "
                f"{host}:{candidate}: {error.strerror or error}",
            )
    raise InvalidOption(
        "port", port, "a free port", f"ports {port} to {last - 1} on {host} are all in use"
    )


def start_server(viser: Any, host: str, port: int, label: str) -> Any:
    """A started ``viser.ViserServer`` on ``host`` and ``port`` (:func:`listen_port`).

    viser's constructor waits, without a time limit, for its server thread to report that
    it listens; a thread that fails never does. The constructor therefore runs in a helper
    thread, waited for :data:`SERVER_START_TIMEOUT` seconds at most:
    :class:`qpik.InvalidInput` then (and a server that starts after all is stopped)."""
    port = listen_port(host, port)
    lock = threading.Lock()
    state: dict[str, Any] = {}
    done = threading.Event()

    def construct() -> None:
        try:
            server = viser.ViserServer(host=host, port=port, label=label, verbose=False)
        except BaseException as exc:  # handed to the waiting thread
            state["error"] = exc
        else:
            with lock:
                abandoned = state.get("abandoned", False)
                state["server"] = server
            if abandoned:
                server.stop()
        finally:
            done.set()

    threading.Thread(target=construct, name="qpik-viewer-start", daemon=True).start()
    done.wait(SERVER_START_TIMEOUT)
    with lock:
        if "server" in state:
            return state["server"]
        if "error" in state:
            raise state["error"]
        state["abandoned"] = True
    raise InvalidInput(
        f"the viewer's server did not start on {host}:{port} within "
        f"{SERVER_START_TIMEOUT:g} s (its thread failed: see the messages above)"
    )
