"""Health and metrics of the running service, served by the I/O process (never by the cycle).

`Monitor` samples the process image every 100 ms on the I/O loop: the task's counters, the fault
word, the sensor's sample count and age, and every cycle's exec time and jitter (the image's timing
ring, so the histograms miss no cycle). From that it answers

* ``GET /health``: JSON ``{"healthy", "reason", ...}``; healthy when the task runs (its cycle count
  rose within the last second and its state is RUN), no fault is latched, and the share of exceeded
  deadlines over the last 10 s is below ``health_max_exceed_rate``. `stiffcomp health` asks it.
* ``GET /metrics``: the Prometheus text exposition, when ``monitoring.metrics`` is on.

HTTP is served by the standard library's WSGI server in a thread of the I/O process (the cycle's
process is untouched); the sampler runs on the loop, the handler reads what it last computed.
"""

from __future__ import annotations

import asyncio
import json
import logging
import threading
import time
from collections import deque
from typing import Any
from wsgiref.simple_server import WSGIRequestHandler, WSGIServer, make_server

from .contract import Fault, Status, TaskState
from .image import ProcessImage
from .settings import MonitoringSettings

log = logging.getLogger("stiffcomp.monitoring")

SAMPLE_S = 0.1
WINDOW_S = 10.0


class _Quiet(WSGIRequestHandler):
    def log_message(self, *args) -> None:      # one line per scrape would fill the log
        pass


class Monitor:
    """Health and metrics from the image; `start`/`stop` on the I/O loop.

    Parameters
    ----------
    image : ProcessImage
    settings : MonitoringSettings
    metrics : object with the `plc_interface.metrics.ServiceMetrics` methods, or None
    parts : callable () -> list of the I/O server's parts (for client counts), optional
    """

    def __init__(self, image: ProcessImage, settings: MonitoringSettings, metrics: Any = None, parts=None):
        self.image = image
        self.settings = settings
        self.metrics = metrics
        self.parts = parts or (list)
        self.window: deque[tuple[float, int, int]] = deque()
        self.last_change = (0.0, -1)            # (time, cycle count) of the last rise
        self.health: dict = {"healthy": False, "reason": "the service has not published a cycle yet"}
        self._n_timing = 0
        self._fault_word = 0
        self._task: asyncio.Task | None = None
        self._http: WSGIServer | None = None
        self._thread: threading.Thread | None = None

    async def start(self) -> None:
        from .errors import PlcError

        s = self.settings
        try:
            self._http = make_server(s.host, s.port, self._app, handler_class=_Quiet)
        except OSError as e:
            raise PlcError(f"cannot serve monitoring HTTP on {s.host}:{s.port}: {e}") from e
        self._thread = threading.Thread(target=self._http.serve_forever, kwargs={"poll_interval": 0.2},
                                        name="stiffcomp-monitoring", daemon=True)
        self._thread.start()
        self._n_timing = self.image.timings_since(0)[0]
        self._task = asyncio.get_running_loop().create_task(self._run())
        log.info("monitoring on http://%s:%d (/health%s)", s.host, s.port, ", /metrics" if self.metrics else "")

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            try:
                await self._task
            except asyncio.CancelledError:
                pass
        if self._http is not None:
            self._http.shutdown()
            self._http.server_close()
            self._thread.join(5)

    async def _run(self) -> None:
        while True:
            try:
                self.sample(time.monotonic())
            except Exception as e:  # noqa: BLE001 - monitoring must never take the I/O process down
                log.error("monitoring sample failed: %r", e)
            await asyncio.sleep(SAMPLE_S)

    # -- what is computed ---------------------------------------------------------------------
    def sample(self, now: float) -> None:
        """Read the image once; update the health verdict and the metrics."""
        values = self.image.outputs()
        cycles, exceeded = int(values.get("cycle_count", 0)), int(values.get("exceed_count", 0))
        if cycles != self.last_change[1]:
            self.last_change = (now, cycles)
        self.window.append((now, cycles, exceeded))
        while self.window and now - self.window[0][0] > WINDOW_S:
            self.window.popleft()
        t0, c0, e0 = self.window[0]
        deadlines = (cycles - c0) + (exceeded - e0)
        rate = (exceeded - e0) / deadlines if deadlines > 0 else 0.0
        word = int(values.get("fault_word", 0))
        state = int(values.get("task_state", TaskState.RUN))
        if cycles == 0:
            healthy, reason = False, "the service has not run a cycle yet"
        elif state != TaskState.RUN or values.get("status_word", 0) and int(values["status_word"]) & Status.STOPPED:
            healthy, reason = False, "the task is stopped"
        elif now - self.last_change[0] > 1.0:
            healthy, reason = False, f"the cycle count has not risen for {now - self.last_change[0]:.1f} s"
        elif word:
            healthy, reason = False, f"fault: {', '.join(Fault.spell(word))} (fault_word {word:#06x})"
        elif rate > self.settings.health_max_exceed_rate:
            healthy, reason = False, (f"{100 * rate:.1f} % of deadlines exceeded over the last {now - t0:.0f} s "
                                      f"(bound {100 * self.settings.health_max_exceed_rate:g} %)")
        else:
            healthy, reason = True, f"running: {cycles} cycles, {100 * rate:.2f} % exceeded over {now - t0:.0f} s"
        self.health = {"healthy": healthy, "reason": reason, "cycle_count": cycles, "exceed_count": exceeded,
                       "exceed_rate_10s": round(rate, 5), "fault_word": word,
                       "faults": Fault.spell(word)}
        if self.metrics is not None:
            self._update_metrics(values, word)

    def _update_metrics(self, values: dict[str, float], word: int) -> None:
        m = self.metrics
        self._n_timing, rows = self.image.timings_since(self._n_timing)
        m.observe_cycles(rows[:, 0].tolist(), rows[:, 1].tolist())
        m.update_values(values)
        for f in Fault:
            if word & f and not self._fault_word & f:
                m.count_fault(f.kind)
        self._fault_word = word
        if "sample_age_ms" in values and len(self.window) > 1:
            (t0, _c, _e), n0 = self.window[-2], getattr(self, "_samples_prev", values.get("sensor_samples", 0))
            dt = self.window[-1][0] - t0
            m.set_sensor((values.get("sensor_samples", 0) - n0) / dt if dt > 0 else 0.0,
                         values["sample_age_ms"] / 1000.0)
        self._samples_prev = values.get("sensor_samples", 0)
        for part in self.parts():
            clients = getattr(part, "clients", None)
            if clients is not None:
                m.set_clients(getattr(part, "protocol", type(part).__name__.lower()), clients)

    # -- HTTP ------------------------------------------------------------------------------------
    def _app(self, environ, start_response):
        path = environ.get("PATH_INFO", "")
        if path == "/health":
            body = json.dumps(self.health).encode()
            start_response("200 OK" if self.health["healthy"] else "503 Service Unavailable",
                           [("Content-Type", "application/json"), ("Content-Length", str(len(body)))])
            return [body]
        if path == "/metrics" and self.metrics is not None:
            body = self.metrics.render()
            start_response("200 OK", [("Content-Type", "text/plain; version=0.0.4; charset=utf-8"),
                                      ("Content-Length", str(len(body)))])
            return [body]
        body = b"not found: /health" + (b", /metrics" if self.metrics is not None else b"") + b"\n"
        start_response("404 Not Found", [("Content-Type", "text/plain"), ("Content-Length", str(len(body)))])
        return [body]
