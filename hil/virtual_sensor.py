"""A virtual ATI Net F/T sensor: a real backend on a python-can bus, not a mock.

It answers short-data requests (0x02) with the two frames of the wrench ``load(t)`` and handles the
bias request (0x04) as the real sensor does: the current load becomes the new zero. Tests use it on
the ``virtual`` interface (one process) and ``udp_multicast`` (between processes); `stiffcomp
record --virtual` records it.
"""

from __future__ import annotations

import argparse
import threading
import time
from collections.abc import Callable
from typing import Self

import can
import numpy as np

from service.ati import REQ_BIAS, REQ_SHORT_DATA, AtiProtocol


class VirtualAtiSensor:
    """Answer requests on ``bus`` in a background thread until `stop`.

    Parameters
    ----------
    bus : can.BusABC
        The sensor's side of the bus (owned: shut down on stop).
    protocol : AtiProtocol
    load : callable t -> (6,) wrench in N, Nm (sensor axes); t in s since start
    status : callable t -> int, optional
        The status word to send (0 = healthy).
    """

    def __init__(self, bus: can.BusABC, protocol: AtiProtocol,
                 load: Callable[[float], np.ndarray], status: Callable[[float], int] | None = None):
        self.bus = bus
        self.protocol = protocol
        self.load = load
        self.status = status or (lambda t: 0)
        self.bias = np.zeros(6)
        self.counter = 0
        self.requests = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="virtual-ati", daemon=True)
        self._t0 = time.monotonic()

    def start(self) -> VirtualAtiSensor:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.bus.shutdown()

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def _run(self) -> None:
        while not self._stop.is_set():
            msg = self.bus.recv(0.02)
            if msg is None or msg.arbitration_id != self.protocol.base_id or len(msg.data) < 1:
                continue
            t = time.monotonic() - self._t0
            if msg.data[0] == REQ_SHORT_DATA:
                self.requests += 1
                for arb, data in self.answer(t):
                    self.bus.send(can.Message(arbitration_id=arb, data=data, is_extended_id=False))
            elif msg.data[0] == REQ_BIAS:
                self.bias = np.asarray(self.load(t), dtype=float).copy()

    def answer(self, t: float) -> list[tuple[int, bytes]]:
        """The frames (id, data) that answer a short-data request at ``t`` (s since start).

        The hook a fault-injecting sensor overrides (a silent or babbling sensor in the HIL tests).
        """
        self.counter = (self.counter + 1) & 0xFFFF
        return self.protocol.encode(np.asarray(self.load(t)) - self.bias, self.status(t), self.counter)


def main(argv: list[str] | None = None) -> int:
    """Run a virtual sensor with a constant load in its own process (e.g. on udp_multicast)."""
    ap = argparse.ArgumentParser(description="a virtual ATI Net F/T sensor on a python-can bus")
    ap.add_argument("--interface", default="udp_multicast")
    ap.add_argument("--channel", default="239.74.163.2")
    ap.add_argument("--base-id", type=lambda s: int(s, 0), default=0x020)
    ap.add_argument("--load", default="0,0,0,0,0,0", help="Fx,Fy,Fz,Tx,Ty,Tz in N and Nm")
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--port", type=int, default=None, help="UDP port (udp_multicast; default: python-can's)")
    args = ap.parse_args(argv)
    load = np.array([float(v) for v in args.load.split(",")])
    sensor = VirtualAtiSensor(can.Bus(interface=args.interface, channel=args.channel,
                                      **({} if args.port is None else {"port": args.port})),
                              AtiProtocol(base_id=args.base_id), lambda t: load).start()
    print("ready", flush=True)
    try:
        time.sleep(args.seconds)
    except KeyboardInterrupt:
        pass
    finally:
        sensor.stop()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
