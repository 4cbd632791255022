"""An ADS server in a spawn child, over a `ProcessImage` whose fake cycle publishes changing values.

The fake cycle publishes every ``period_s``: cycle_count rising by one, correction_q1 = 0.5 * (cycle // 8)
(so it changes every 8th cycle), a fixed cycle time of 1000 µs, last_exec_us = 123.4, exceed_count =
cycle // 100, cycle_exceeded alternating. Before each publish it checks that nobody changed the to_plc
block since its last publish; at the end it reports that and the from_plc block (the writes that landed).
"""

from __future__ import annotations

import asyncio
import logging
import multiprocessing
import socket
from pathlib import Path
from typing import Self

from plc_link.ads import AdsServer, AdsSettings
from plc_link.contract import to_plc
from plc_link.image import ProcessImage
from plc_link.register_map import RegisterMap

MAP = Path(__file__).resolve().parents[1] / "config" / "registers.yaml"


def recv_exact(s: socket.socket, n: int) -> bytes | None:
    """Exactly ``n`` bytes from ``s``, or None when the peer closes the connection first."""
    out = b""
    while len(out) < n:
        chunk = s.recv(n - len(out))
        if not chunk:
            return None
        out += chunk
    return out


def map_variant(directory: Path, drop: str | None = None, old: str = "", new: str = "") -> RegisterMap:
    """MAP without the register named ``drop`` (one symbol less) and with ``old`` replaced by ``new`` in
    its text (a comment changed, say), read back from a file in ``directory``."""
    lines = [line for line in MAP.read_text().splitlines(keepends=True)
             if drop is None or f"name: {drop}," not in line]
    path = directory / f"registers_{drop}_{len(old)}_{len(new)}.yaml"
    path.write_text("".join(lines).replace(old, new) if old else "".join(lines))
    return RegisterMap.from_yaml(path)


def fake_values(cycle: int) -> dict[str, float]:
    return {"heartbeat": cycle & 0xFFFF, "task_state": 1, "cycle_count": cycle, "exceed_count": cycle // 100,
            "last_exec_us": 123.4, "cycle_time_us": 1000.0, "cycle_exceeded": cycle % 2,
            "correction_q1": 0.5 * (cycle // 8), "correction_q2": -1.25, "wrench_fz": 42.0}


async def _run(settings: dict, period_s: float, conn, log_path: str | None) -> None:
    if log_path:
        logging.basicConfig(filename=log_path, level=logging.INFO)
    image = ProcessImage(RegisterMap.from_yaml(MAP))
    codec = image.out_codec
    server = AdsServer(image, AdsSettings(**settings))
    await server.start()
    conn.send(("ready", server.address))
    loop = asyncio.get_running_loop()
    stopped = asyncio.Event()
    loop.add_reader(conn.fileno(), stopped.set)
    cycle, tampered, last = 0, 0, None
    try:
        while not stopped.is_set():
            cycle += 1
            current = image.snapshot()[2][: codec.words]
            if last is not None and current != last:
                tampered += 1
            vals = fake_values(cycle)
            record = to_plc(**vals)
            last = codec.encode_record(record)
            image.publish(record)
            server.on_cycle()
            await asyncio.sleep(period_s)
    finally:
        loop.remove_reader(conn.fileno())
        await server.stop()
    conn.recv()
    conn.send(("stopped", {"tampered": tampered, "cycles": cycle, "from_plc": image.snapshot()[3],
                           "refused": image.refused_writes}))
    image.close()


def _serve(settings: dict, period_s: float, conn, log_path: str | None) -> None:
    asyncio.run(_run(settings, period_s, conn, log_path))


class AdsChild:
    """``with AdsChild(net_id=..., ...) as child:`` serves on ``child.host:child.port`` until the block ends;
    ``child.report`` then holds the fake cycle's findings."""

    def __init__(self, period_s: float = 0.002, log_path: str | None = None, **settings):
        settings.setdefault("host", "127.0.0.1")
        settings.setdefault("port", 0)
        self.settings, self.period_s, self.log_path = settings, period_s, log_path
        self.report: dict = {}

    def __enter__(self) -> Self:
        ctx = multiprocessing.get_context("spawn")
        self._conn, child = ctx.Pipe()
        self._proc = ctx.Process(target=_serve, args=(self.settings, self.period_s, child, self.log_path), daemon=True)
        self._proc.start()
        child.close()
        if not self._conn.poll(30):
            self._kill()
            raise RuntimeError("the ADS server child did not start")
        _tag, (self.host, self.port) = self._conn.recv()
        return self

    def __exit__(self, *exc) -> None:
        try:
            self._conn.send("stop")
            if self._conn.poll(10):
                self.report = self._conn.recv()[1]
        except (EOFError, OSError):
            pass
        self._kill()

    def _kill(self) -> None:
        self._proc.join(5)
        if self._proc.is_alive():
            self._proc.terminate()
            self._proc.join(2)
        self._conn.close()


def read_by_handle(host: str, port: int, net_id: str, name: str, n: int) -> list[int]:
    """``n`` reads of ``name`` by handle with pyads, back to back (a load client in a process of its own)."""
    import pyads

    plc = pyads.Connection(net_id, 851, f"{host}:{port}")
    plc.open()
    try:
        handle = plc.get_handle(name)
        values = [plc.read_by_name("", pyads.PLCTYPE_UDINT, handle=handle) for _ in range(n)]
        plc.release_handle(handle)
        return values
    finally:
        plc.close()
