"""Health and metrics of the running service, served by the I/O process (never by the cycle).

`Monitor` samples the process image every 100 ms on the I/O loop: the task's counters, the fault
word, the sensor's sample count and age, and every cycle's exec time and jitter (the image's timing
ring, so the histograms miss no cycle). From that it answers

* ``GET /health``, ``/health/live``, ``/health/ready`` (`io_process.endpoints.PROBES`):
  `io_process.health.HealthMonitor`'s verdicts as JSON (200 when it passes, 503 when not).
  ``/health``: the task runs (its cycle count rose within the last second, state RUN), no fault is
  latched, and the share of exceeded deadlines over the last 10 s is below ``health_max_exceed_rate``.
  ``/health/live``: the cycle count rises. ``/health/ready``: healthy, the sensor fresh and the PLC's
  heartbeat seen. A verdict older than ``STALE_S`` (the I/O loop has stopped sampling) fails all three.
  `io_process.endpoints.read_health` asks them: `stiffcomp health` and the HIL (for readiness).
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
from typing import Any
from wsgiref.simple_server import WSGIRequestHandler, WSGIServer, make_server

from io_base.deadlines import cancel
from plc_link.image import ProcessImage

from .endpoints import PROBES
from .health import HealthMonitor
from .settings import MonitoringSettings

log = logging.getLogger("stiffcomp.monitoring")

SAMPLE_S = 0.1
STALE_S = 2.0      # s; verdicts older than this mean the I/O loop no longer samples: not even live
_ROUTES = {path: (probe, key) for probe, (path, key) in PROBES.items()}


class _Quiet(WSGIRequestHandler):
    def log_message(self, *args) -> None:      # one line per scrape would fill the log
        pass


class Monitor:
    """Health and metrics from the image; `start`/`stop` on the I/O loop.

    Parameters
    ----------
    image : ProcessImage
    settings : MonitoringSettings
    metrics : object with the `io_process.metrics.ServiceMetrics` methods, or None
    parts : callable () -> list of the I/O server's parts (for client counts), optional
    """

    def __init__(self, image: ProcessImage, settings: MonitoringSettings, metrics: Any = None, parts=None):
        self.image = image
        self.settings = settings
        self.metrics = metrics
        self.parts = parts or (list)
        self.monitor = HealthMonitor(settings.health_max_exceed_rate)
        # (monotonic time of the sample, the verdicts by probe): one reference, swapped whole, so the
        # HTTP thread never sees half an update
        self.verdicts: tuple[float | None, dict[str, dict]] = (None, {
            probe: {key: False, "reason": "the service has not published a cycle yet"}
            for probe, (_, key) in PROBES.items()})
        self._n_timing = 0
        self._samples_prev: tuple[float, float] | None = None
        self._task: asyncio.Task | None = None
        self._http: WSGIServer | None = None
        self._thread: threading.Thread | None = None

    async def start(self) -> None:
        from io_base.errors import PlcError

        s = self.settings
        try:
            self._http = make_server(s.host, s.port, self._app, handler_class=_Quiet)
        except OSError as e:
            from io_base.listen import explain

            raise PlcError(f"cannot serve monitoring HTTP on {s.host}:{s.port}: "
                           f"{explain(e, s.host, s.port, 'monitoring.port')}") from e
        self._thread = threading.Thread(target=self._http.serve_forever, kwargs={"poll_interval": 0.2},
                                        name="stiffcomp-monitoring", daemon=True)
        self._thread.start()
        self._n_timing = self.image.timings_since(0)[0]
        self._task = asyncio.get_running_loop().create_task(self._run())
        log.info("monitoring on http://%s:%d (%s%s)", s.host, s.port, ", ".join(_ROUTES),
                 ", /metrics" if self.metrics else "")

    async def stop(self) -> None:
        await cancel(self._task)
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
        self.monitor.update(now, values)
        self.verdicts = (now, self.monitor.verdicts(now))
        m = self.metrics
        if m is None:
            return
        self._n_timing, rows = self.image.timings_since(self._n_timing)
        m.observe_cycles(rows[:, 0].tolist(), rows[:, 1].tolist())
        m.update_values(values)                     # counts each fault bit that rises, by kind
        samples = values.get("sensor_samples")
        if samples is not None and self._samples_prev is not None and now > self._samples_prev[0]:
            t0, n0 = self._samples_prev
            m.set_sensor((samples - n0) / (now - t0), values.get("sample_age_ms", 0.0) / 1000.0)
        self._samples_prev = None if samples is None else (now, samples)
        for part in self.parts():
            clients = getattr(part, "clients", None)
            if clients is not None:
                m.set_clients(part.protocol, clients)

    # -- HTTP ------------------------------------------------------------------------------------
    def answer(self, probe: str, now: float) -> dict:
        """The verdict of ``probe`` (a key of `PROBES`) as served at monotonic time ``now``."""
        sampled_at, verdicts = self.verdicts
        if sampled_at is not None and now - sampled_at > STALE_S:
            key = PROBES[probe][1]
            return {key: False, "reason": f"the I/O process has not sampled the process image for "
                                          f"{now - sampled_at:.1f} s (its loop is stuck)"}
        return verdicts[probe]

    def _app(self, environ, start_response):
        path = environ.get("PATH_INFO", "")
        if path in _ROUTES:
            probe, key = _ROUTES[path]
            verdict = self.answer(probe, time.monotonic())
            body = json.dumps(verdict).encode()
            start_response("200 OK" if verdict[key] else "503 Service Unavailable",
                           [("Content-Type", "application/json"), ("Content-Length", str(len(body)))])
            return [body]
        if path == "/metrics" and self.metrics is not None:
            body = self.metrics.render()
            start_response("200 OK", [("Content-Type", "text/plain; version=0.0.4; charset=utf-8"),
                                      ("Content-Length", str(len(body)))])
            return [body]
        body = ("not found: " + ", ".join(_ROUTES) + (", /metrics" if self.metrics is not None else "")
                + "\n").encode()
        start_response("404 Not Found", [("Content-Type", "text/plain"), ("Content-Length", str(len(body)))])
        return [body]
