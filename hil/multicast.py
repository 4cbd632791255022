"""Whether this host carries the HIL's CAN between processes: python-can's ``udp_multicast`` joins a multicast
group on the interface the routing table picks for it, and a host whose only interface is loopback (a fresh
network namespace, many containers and CI runners) has none, so the sensor's process dies with
``OSError: [Errno 19] No such device``.

`check_multicast` asks the operating system the same question before any process starts (one socket joins a
group as python-can's bus does, and one datagram goes round through it), and says in one line what to run
where it fails. The two commands make loopback carry multicast (root, or CAP_NET_ADMIN in the namespace):
``ip link set lo multicast on`` marks it able to, ``ip route add 224.0.0.0/4 dev lo`` routes the groups to it.
"""

from __future__ import annotations

import errno
import os
import socket
import struct
import time

FIX = "ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo"
WAIT_S = 2.0


class MulticastError(Exception):
    """This host cannot carry udp_multicast between the HIL's processes (the message says what to run)."""


def check_multicast(group: str, port: int, wait_s: float = WAIT_S) -> None:
    """Join ``group`` on ``port`` as python-can's udp_multicast bus does (the interface INADDR_ANY: the route's),
    send one datagram to it and read it back within ``wait_s``; MulticastError in one line otherwise."""
    hint = (f"the HIL's processes talk CAN over UDP multicast (python-can udp_multicast), and this host {{}}; "
            f"as root run: {FIX}; or cut in lock step, in one process (stiffcomp hil circle --lockstep) "
            "(docs/hil.md, \"What the host needs\")")
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, struct.pack("@I", 1))
        try:
            s.bind(("", port))
            s.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP,
                         socket.inet_aton(group) + struct.pack("@I", socket.INADDR_ANY))
        except OSError as e:
            why = ("has no interface for multicast (no route to 224.0.0.0/4: No such device)"
                   if e.errno == errno.ENODEV else f"cannot join multicast group {group} ({e.strerror or e})")
            raise MulticastError(hint.format(why)) from e
        token = f"stiffcomp-hil-check {os.getpid()} {time.monotonic_ns()}".encode()
        try:
            s.sendto(token, (group, port))
        except OSError as e:
            raise MulticastError(hint.format(f"cannot send to multicast group {group} ({e.strerror or e})")) from e
        deadline = time.monotonic() + wait_s
        while (left := deadline - time.monotonic()) > 0:
            s.settimeout(left)
            try:
                if s.recv(256) == token:
                    return
            except TimeoutError:
                break
    raise MulticastError(hint.format(f"does not deliver multicast back to itself (nothing came back from {group} "
                                     f"in {wait_s:g} s)"))
