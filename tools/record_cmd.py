"""`stiffcomp record OUT`: record an ATI sensor's CAN traffic to a python-can log for replay.

The bus comes from the config's ``source.can`` section (or --interface/--channel). The sensor
answers only requests, so the recorder sends short-data requests at --request-hz on absolute
deadlines (0: the sensor streams by itself). --virtual-sensor answers on the same virtual bus with
a synthetic milling load, to make a log without hardware. The format follows OUT's suffix
(.asc, .blf, .log, .trc, .csv).
"""

from __future__ import annotations

import signal
import sys
import threading
import time

import can
import numpy as np

from hil.demo_log import milling_wrench
from hil.virtual_sensor import VirtualAtiSensor
from io_base.deadlines import Deadlines
from service.ati import AtiProtocol
from service.config import DEFAULT_CONFIG, load_config
from service.sources.can_source import open_bus
from service.sources.replay import LOG_SUFFIXES
from stiffness.errors import OutputError


class LockedLogger(can.Listener):
    """A log writer shared by the Notifier's thread (received frames) and ours (sent requests)."""

    def __init__(self, path: str):
        self.logger = can.Logger(path)
        self.lock = threading.Lock()

    def on_message_received(self, msg: can.Message) -> None:
        with self.lock:
            self.logger.on_message_received(msg)

    def stop(self) -> None:
        with self.lock:
            self.logger.stop()


def register(sub) -> None:
    p = sub.add_parser("record", help="record the F/T sensor's CAN frames to a log file for replay")
    p.add_argument("out", help=f"log file to write ({', '.join(LOG_SUFFIXES)})")
    p.add_argument("--config", default=str(DEFAULT_CONFIG), help="service config (source.can, source.ati)")
    p.add_argument("--interface", default=None, help="python-can interface (default: source.can.interface)")
    p.add_argument("--channel", default=None, help="channel (default: source.can.channel)")
    p.add_argument("--duration", type=float, default=10.0, metavar="S", help="seconds to record (default 10)")
    p.add_argument("--request-hz", type=float, default=1000.0, help="short-data requests per second (0 = none)")
    p.add_argument("--virtual-sensor", action="store_true",
                   help="answer the requests with a virtual sensor on the same (virtual) bus")
    p.set_defaults(func=run)


def run(args) -> int:
    from pathlib import Path

    if Path(args.out).suffix.lower() not in LOG_SUFFIXES:
        raise OutputError(f"record: {args.out}: the log type must be one of {', '.join(LOG_SUFFIXES)}")
    cfg = load_config(args.config)
    c = cfg.source.can
    interface, channel = args.interface or c.interface, args.channel or c.channel
    protocol = AtiProtocol.from_config(cfg.source.ati)
    try:
        logger = LockedLogger(args.out)       # first: a bad path opens nothing else
    except OSError as e:
        raise OutputError(f"record: {args.out}: cannot write the log: {e.strerror or e}") from e
    sensor = bus = None
    try:
        if args.virtual_sensor:
            sensor = VirtualAtiSensor(open_bus(interface, channel, c.bitrate, **c.options), protocol,
                                      lambda t: milling_wrench(np.array([t]), seed=int(t * 1000),
                                                               spikes=False)[0]).start()
        bus = open_bus(interface, channel, c.bitrate, **c.options)
        notifier = can.Notifier(bus, [logger])
    except BaseException:
        logger.stop()
        if bus is not None:
            bus.shutdown()
        if sensor is not None:
            sensor.stop()
        raise
    stop = threading.Event()
    previous = {s: signal.signal(s, lambda *_: stop.set()) for s in (signal.SIGINT, signal.SIGTERM)}
    arb, data = protocol.request_short_data()
    sent = 0
    try:
        t_end = time.monotonic() + args.duration
        deadlines = Deadlines(1.0 / args.request_hz) if args.request_hz > 0 else None
        while not stop.is_set() and time.monotonic() < t_end:
            if deadlines is None:
                stop.wait(min(0.1, max(0.0, t_end - time.monotonic())))
                continue
            msg = can.Message(arbitration_id=arb, data=data, is_extended_id=False, timestamp=time.time())
            try:
                bus.send(msg, timeout=0.0)
                logger(msg)
                sent += 1
            except can.CanError:
                pass
            deadlines.advance(time.monotonic())
            deadlines.sleep_until()
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
        time.sleep(0.02)                    # let the last answers arrive
        notifier.stop()                     # also stops (flushes and closes) the logger
        bus.shutdown()
        if sensor is not None:
            sensor.stop()
    print(f"recorded {args.out}: {sent} requests sent on {interface}:{channel}")
    text, samples, others = summarize(args.out, cfg.resolve(cfg.source.ati.dbc), protocol.base_id, arb)
    print(text)
    if samples == 0:        # a reference of the idle sensor that holds none of it: say so, exit 1
        heard = (f"{others} other frame(s) came, none of them the sensor's short data at source.ati.base_id = "
                 f"{protocol.base_id:#x}" if others else "nothing answered")
        print(f"record: no sensor sample in {args.out}: {heard} (check source.can.interface, channel and "
              "source.ati.base_id against the sensor's settings; --virtual-sensor records a synthetic one)",
              file=sys.stderr)
        return 1
    return 0


def summarize(path: str, dbc_path, base_id: int, request_id: int | None = None) -> tuple[str, int, int]:
    """Decode the log with the protocol's DBC (cantools) and summarise each signal: (the summary, the samples
    decoded, the frames that are neither a sample nor our own request ``request_id``)."""
    import cantools

    db = cantools.database.load_file(str(dbc_path))
    shift = base_id - min(m.frame_id for m in db.messages)      # the DBC is written for its own base id
    values: dict[str, list[float]] = {}
    others = 0
    with can.LogReader(path) as reader:
        for msg in reader:
            try:
                decoded = db.decode_message(msg.arbitration_id - shift, bytes(msg.data), decode_choices=False)
            except (KeyError, ValueError, cantools.database.DecodeError):
                others += msg.arbitration_id != request_id
                continue
            for name, v in decoded.items():
                values.setdefault(name, []).append(float(v))
    lines = [f"{len(values.get('Fz', []))} samples decoded with {dbc_path}:"]
    for name in ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz", "status"):
        if values.get(name):
            v = np.array(values[name])
            lines.append(f"  {name:>6}: min {v.min():9.2f}  mean {v.mean():9.2f}  max {v.max():9.2f}")
    return "\n".join(lines), len(values.get("Fz", [])), others
