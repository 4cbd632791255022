"""What the service's start-up checks and prepares before its first cycle, beside building the stages.

* `check_plc_values`: the values the cycle reads from the PLC are registers of the map;
* `Compiling`: with ``cycle.compiled`` the signal path is compiled (`service.kernel`: numba loads it from its
  disk cache, or compiles it the first time) in a thread that runs while the I/O process starts, so the first
  cycle never waits for a compiler; a model with no compiled form runs on the Python path (one log line).
"""

from __future__ import annotations

import logging
import threading
import time

from plc_link.contract import ACCELEROMETER

from .errors import ServiceConfigError

log = logging.getLogger("stiffcomp.service")


def check_plc_values(cfg, cycle, rmap) -> None:
    """ServiceConfigError naming the register when ``dynamics.feedforward`` or ``accelerometer`` reads a value
    from the PLC that ``plc.register_map`` (``rmap``) does not have."""
    if cfg.accelerometer.enabled and not cfg.accelerometer.replay:
        missing = [n for n in ACCELEROMETER if n not in rmap.codecs["from_plc"].index]
        if missing:
            raise ServiceConfigError(f"{cfg.path}: accelerometer.enabled reads {', '.join(ACCELEROMETER)} from the "
                                     f"PLC, but plc.register_map = {cfg.plc.register_map} has no register "
                                     f"{', '.join(missing)} (docs/register_map.md, \"The accelerometer\")")
    dyn = cycle.compensator.dynamics
    if dyn is not None and dyn.reads_motion and not cfg.accelerometer.enabled:
        raise ServiceConfigError(f"{cfg.path}: dynamics.observer reads the accelerometer, but accelerometer.enabled "
                                 "is false (docs/accelerometer.md)")
    for name in (dyn.plc_values() if dyn is not None else []):
        if name not in rmap.codecs["from_plc"].index:
            raise ServiceConfigError(f"{cfg.path}: dynamics.feedforward reads {name} from the PLC, but "
                                     f"plc.register_map = {cfg.plc.register_map} has no register {name} "
                                     "(docs/register_map.md, \"The plan\")")


class Compiling:
    """The compiled signal path of ``service`` (a `service.app.Service`), made ready in a thread of its own.
    After `join`: ``packers`` and ``steady``, the service's packers and steady cycle
    (`service.value_vector.Values.compiled`), and ``seconds``, how long it took; all None when the path
    cannot compile (no compiled form, no numba: the Python path stays)."""

    def __init__(self, service):
        self.service = service
        self.packers = self.steady = None
        self.seconds: float | None = None
        self._thread = threading.Thread(target=self._compile, name="stiffcomp-compile", daemon=True)
        self._thread.start()

    def join(self) -> None:
        self._thread.join()                 # loaded from numba's cache in well under a second

    def _compile(self) -> None:
        service = self.service
        t0 = time.perf_counter()
        try:
            service.cycle.compensator.compile()
        except Exception as e:  # noqa: BLE001 - any reason (no compiled form, no numba) leaves the Python path
            log.warning("the cycle runs on the Python path: %s", e)
            return
        self.packers, self.steady = service.values.compiled(service, service.to_plc_slots)
        self.seconds = time.perf_counter() - t0
