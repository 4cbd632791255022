"""Why a server cannot listen on an address, in words and with what to do: pymodbus only says "Could not
start listen, please check address", and an OS error names neither the key nor the remedy.

`why_not_listening` binds a socket to the address itself and reads the operating system's answer: a
port below 1024 that needs privilege, an address in use, an address this machine does not have. A
`Listener` is one such address, named by the config key that sets its port.
"""

from __future__ import annotations

import errno
import socket
from typing import NamedTuple

PRIVILEGED_BELOW = 1024     # Linux' default net.ipv4.ip_unprivileged_port_start


class Listener(NamedTuple):
    """An address a server listens on: ``key``, the config key that sets its port (the name every refusal
    gives), ``host``, ``port`` and ``transport`` ("tcp" or "udp")."""

    key: str
    host: str
    port: int
    transport: str = "tcp"


def why_not_listening(host: str, port: int, key: str, error: BaseException | None = None) -> str:
    """What keeps a server from listening on ``host:port`` (the config's ``key`` names the port), said
    as the operating system says it when this process binds the address now; ``error`` (the server's own
    failure) is the answer when the bind succeeds here."""
    why = bind_problem(host, port, key)
    if why is not None:
        return why
    return str(error) if error is not None else "the address could not be listened on"


def bind_problem(host: str, port: int, key: str, transport: str = "tcp") -> str | None:
    """Why this process cannot bind ``host:port`` (``transport`` tcp or udp) now, in words with what to do, or
    None when it can (`bind_error`)."""
    e = bind_error(host, port, transport)
    if e is None:
        return None
    if isinstance(e, socket.gaierror):
        return f"{host} is not an address of this machine ({e.strerror or e})"
    return explain(e, host, port, key, transport)


def bind_error(host: str, port: int, transport: str = "tcp") -> OSError | None:
    """The operating system's error of binding ``host:port`` (``transport`` tcp or udp) now (a socket.gaierror
    for a name that resolves to no address), or None when the bind succeeds. The socket is closed at once:
    `stiffcomp run --check` asks this of every address the service would listen on. TCP binds as the servers
    do (SO_REUSEADDR: a port in TIME_WAIT is no reason); UDP without it, as the robot road binds (with it, a
    second UDP socket could share a port in use)."""
    kind = socket.SOCK_DGRAM if transport == "udp" else socket.SOCK_STREAM
    try:
        family, kind, proto, _, address = socket.getaddrinfo(host, port, type=kind)[0]
    except UnicodeError as e:
        return socket.gaierror(str(e))
    except socket.gaierror as e:
        return e
    with socket.socket(family, kind, proto) as s:
        if kind == socket.SOCK_STREAM:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(address)
        except OSError as e:
            return e
    return None


def explain(e: OSError, host: str, port: int, key: str, transport: str = "tcp") -> str:
    """An OS error of binding ``host:port`` (``transport`` tcp or udp) in words, with what to do."""
    if e.errno in (errno.EACCES, errno.EPERM) and port < PRIVILEGED_BELOW:
        return (f"port {port} is a privileged port (below {PRIVILEGED_BELOW}): binding it needs root or the "
                f"capability CAP_NET_BIND_SERVICE; set {key} to a port of {PRIVILEGED_BELOW} or above, or give "
                "the service the capability (systemd: AmbientCapabilities=CAP_NET_BIND_SERVICE; docs/security.md)")
    if e.errno == errno.EADDRINUSE:
        return (f"port {port} is in use by another process (ss -l{transport[0]}np 'sport = :{port}' shows which); stop it "
                f"or set {key} to a free port")
    if e.errno == errno.EADDRNOTAVAIL:
        return f"{host} is not an address of this machine: listen on one of its addresses (or 0.0.0.0), {key} {port}"
    return f"{e.strerror or e} ({key})"
