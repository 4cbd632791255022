"""`stiffcomp health` against a real HTTP server that answers as the I/O process's /health does."""

from __future__ import annotations

import json
import threading
from contextlib import contextmanager
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

from hil.testing import free_port, write_config
from tools.cli import main


@contextmanager
def health_server(answer: dict | bytes, status: int = 200):
    """A /health endpoint on a free port, answering ``answer``; yields the port."""
    body = answer if isinstance(answer, bytes) else json.dumps(answer).encode()

    class Handler(BaseHTTPRequestHandler):
        def do_GET(self):
            code, data = (status, body) if self.path == "/health" else (404, b"not found")
            self.send_response(code)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(data)))
            self.end_headers()
            self.wfile.write(data)

        def log_message(self, *args):
            pass

    server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    thread = threading.Thread(target=server.serve_forever, name="health-server", daemon=True)
    thread.start()
    try:
        yield server.server_address[1]
    finally:
        server.shutdown()
        server.server_close()
        thread.join()


def health(tmp_path, port: int, capsys) -> tuple[int, str]:
    cfg = write_config(tmp_path, {"monitoring": {"port": port}})
    code = main(["health", "--config", str(cfg)])
    return code, capsys.readouterr().out


def test_healthy_exits_0_and_says_why(tmp_path, capsys):
    with health_server({"healthy": True, "reason": "running, no fault", "exceed_rate": 0.001}) as port:
        code, out = health(tmp_path, port, capsys)
    assert code == 0
    assert out == "healthy: running, no fault\n"


def test_unhealthy_exits_1_with_the_reason_in_one_line(tmp_path, capsys):
    answer = {"healthy": False, "reason": "fault word 0x0001:\nsensor_timeout"}
    with health_server(answer, status=503) as port:
        code, out = health(tmp_path, port, capsys)
    assert code == 1
    assert out == "unhealthy: fault word 0x0001: sensor_timeout\n"


def test_an_answer_without_the_health_json_is_unhealthy(tmp_path, capsys):
    with health_server(b"<html>proxy error</html>", status=502) as port:
        code, out = health(tmp_path, port, capsys)
    assert code == 1 and "HTTP 502" in out


def test_nothing_listening_exits_1_naming_the_address(tmp_path, capsys):
    port = free_port()
    code, out = health(tmp_path, port, capsys)
    assert code == 1
    assert out.strip() == f"unhealthy: no answer from the service's I/O process at 127.0.0.1:{port}"
