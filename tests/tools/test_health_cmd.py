"""`stiffcomp health` against a real HTTP server that answers as the I/O process's /health does."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
from contextlib import contextmanager
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import pytest
import yaml

from hil.testing import ROOT, free_port, write_config
from service.paths import SECTIONS
from tools.cli import main


@contextmanager
def health_server(answer: dict | bytes, status: int = 200, path: str = "/health"):
    """An endpoint at ``path`` on a free port, answering ``answer`` (every other path 404); yields the port."""
    body = answer if isinstance(answer, bytes) else json.dumps(answer).encode()

    class Handler(BaseHTTPRequestHandler):
        def do_GET(self):
            code, data = (status, body) if self.path == path else (404, b"not found")
            self.send_response(code)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(data)))
            self.end_headers()
            self.wfile.write(data)

        def log_message(self, *args):
            pass

    server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.02}, name="health-server",
                              daemon=True)
    thread.start()
    try:
        yield server.server_address[1]
    finally:
        server.shutdown()
        server.server_close()
        thread.join()


def probe_config(tmp_path, sections: dict):
    """A config holding only the keys the probe reads (it reads nothing else; the service would want
    more, see test_the_shipped_config_reads_as_the_service_reads_it)."""
    path = tmp_path / "service.yaml"
    path.write_text(yaml.safe_dump(sections))
    return path


def health(tmp_path, port: int, capsys, *options: str) -> tuple[int, str]:
    cfg = probe_config(tmp_path, {"monitoring": {"port": port}})
    code = main(["health", *options, "--config", str(cfg)])
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


def test_live_and_ready_ask_their_own_endpoints(tmp_path, capsys):
    with health_server({"live": True, "reason": "the cycle count rose 0.1 s ago"}, path="/health/live") as port:
        assert health(tmp_path, port, capsys, "--live") == (0, "live: the cycle count rose 0.1 s ago\n")
        code, out = health(tmp_path, port, capsys, "--ready")        # this server serves no /health/ready
        assert code == 1 and out.startswith("not ready: ") and "HTTP 404" in out
    answer = {"ready": False, "reason": "no PLC heartbeat seen yet", "checks": {"plc": False}}
    with health_server(answer, status=503, path="/health/ready") as port:
        assert health(tmp_path, port, capsys, "--ready") == (1, "not ready: no PLC heartbeat seen yet\n")


def test_live_and_ready_exclude_each_other(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        main(["health", "--live", "--ready"])
    assert e.value.code == 2 and "not allowed with" in capsys.readouterr().err


def test_a_bad_config_exits_2_naming_the_key_without_traceback(tmp_path, capsys):
    cfg = probe_config(tmp_path, {"monitoring": {"port": "http"}})
    assert main(["health", "--config", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert f"{cfg}: monitoring.port = 'http'" in err and "Traceback" not in err


def test_a_config_without_http_modbus_server_or_ads_exits_2_saying_so(tmp_path, capsys):
    cfg = probe_config(tmp_path, {"monitoring": {"enabled": False}, "plc": {"role": "none"}, "ads": {"enabled": False}})
    assert main(["health", "--live", "--config", str(cfg)]) == 2
    assert "monitoring.enabled is false, plc.role is none, and ads.enabled is false" in capsys.readouterr().err


def test_without_http_it_reads_the_modbus_block_and_says_where(tmp_path, capsys):
    port = free_port()
    cfg = write_config(tmp_path, {"monitoring": {"enabled": False}, "plc": {"port": port}})
    assert main(["health", "--live", "--config", str(cfg)]) == 1
    assert capsys.readouterr().out == f"not live: no answer from the service at 127.0.0.1:{port}\n"


# -- the probe refuses what the service refuses (docs/deploy.md#health) --------------------------------
# Each mistake in a complete service config: `run --check` refuses it, and the probe refuses it with the
# same line, in one line on stderr, exit 2, before it asks anything (nothing on stdout).
MISTAKES = {
    "misspelt section": {"monitorin": {"port": 9021}},
    "misspelt key": {"monitoring": {"hots": "0.0.0.0"}},
    "empty section": {"monitoring": None},
    "monitoring port 0": {"monitoring": {"port": 0}},
    "plc port 99999": {"plc": {"port": 99999}},
    "tls switch no boolean": {"plc": {"tls": {"plain": "maybe"}}},
    "tls without its files": {"plc": {"tls": {"enabled": True}}},
    "ads port -1": {"ads": {"port": -1}},
}


@pytest.mark.parametrize("mistake", MISTAKES.values(), ids=MISTAKES.keys())
def test_the_probe_refuses_what_the_service_refuses_in_the_same_words(tmp_path, capsys, mistake):
    cfg = write_config(tmp_path, mistake)
    assert main(["run", "--check", "--config", str(cfg)]) == 2
    refused = capsys.readouterr().err
    assert main(["health", "--live", "--config", str(cfg)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1
    assert err.removeprefix("stiffcomp health: error: ") == refused.removeprefix("stiffcomp run: error: ")


def test_the_sections_it_knows_are_the_service_configs():
    from service.config import ServiceConfig

    assert set(SECTIONS) == set(ServiceConfig.model_fields) - {"path"}


@pytest.mark.parametrize("port", ["0", "-1", "99999"])
def test_a_port_option_outside_1_to_65535_is_refused_naming_it(port, capsys):
    assert main(["health", "--live", "--port", port]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and err.startswith(f"stiffcomp health: error: --port {port}: ")


# -- the probe stays light (docs/deploy.md#health) ------------------------------------------------------
# One interpreter, started as the HEALTHCHECK starts it, runs the probe over HTTP against a /health/live
# answered by this test, then the Modbus fallback against a port where nothing listens, and reports the
# modules each left imported. The HTTP probe may import the standard library, pyyaml, pydantic (the
# service's schemas of the sections it reads validate them) and the few project modules on ALLOWED,
# nothing else: so moving a schema or a helper cannot quietly pull NumPy, scipy, pinocchio, the ADS
# server or the model code into the probe. The fallback may add pymodbus and the register map, never
# NumPy, scipy, pinocchio or the service.
ALLOWED = {"tools", "tools.cli", "tools.health_cmd", "tools.health_memo", "tools.run_file", "io_process", "io_process.settings", "plc_link", "plc_link.settings", "io_base", "io_base.settings",
           "io_process.endpoints", "plc_link.ads", "plc_link.ads.settings", "plc_link.ads.ams",
           "service", "service.paths", "stiffness", "stiffness.errors", "stiffness.files",
           "stiffness.files.yaml_syntax", "stiffness.files.yaml_schema"}
OURS = ("tools", "hil", "cell", "service", "io_process", "robot_road", "plc_link", "io_base", "stiffness")
PYDANTIC = ("pydantic", "pydantic_core", "annotated_types", "typing_extensions", "typing_inspection")


def pyyaml(top: str) -> bool:
    """pyyaml, with the modules its C loader (libyaml bound by Cython) registers."""
    return top in ("yaml", "_yaml", "cython_runtime") or top.startswith("_cython_")


def standard(top: str) -> bool:
    """The standard library, with the build's configuration module that sysconfig loads (for pydantic)."""
    return top in sys.stdlib_module_names or top.startswith("_sysconfigdata_")


NEVER = ("numpy", "scipy", "pinocchio", "pin", "matplotlib", "pyarrow", "pandas", "rich", "can")

_RUN = """
import sys
at_start = set(sys.modules)                 # what the interpreter and the venv's .pth files loaded
import contextlib, io, json
from tools.cli import main
with contextlib.redirect_stdout(io.StringIO()) as out:
    http = main(["health", "--live", "--config", sys.argv[1]])
after_http = sorted(sys.modules)
with contextlib.redirect_stdout(io.StringIO()):
    modbus = main(["health", "--live", "--config", sys.argv[2]])
print(json.dumps({"http": http, "out": out.getvalue(), "at_start": sorted(at_start), "after_http": after_http,
                  "after_modbus": sorted(sys.modules)}))
"""


def test_the_probe_imports_the_standard_library_pyyaml_and_its_own_few_modules(tmp_path):
    http_cfg, modbus_cfg = tmp_path / "http.yaml", tmp_path / "modbus.yaml"
    modbus_cfg.write_text(yaml.safe_dump({"monitoring": {"enabled": False}, "plc": {"port": free_port()}}))
    with health_server({"live": True, "reason": "the cycle count rose 0.1 s ago"}, path="/health/live") as port:
        http_cfg.write_text(yaml.safe_dump({"monitoring": {"port": port}}))
        p = subprocess.run([sys.executable, "-c", _RUN, str(http_cfg), str(modbus_cfg)], cwd=ROOT,
                           capture_output=True, text=True, timeout=60, check=False)
    assert p.returncode == 0, p.stderr
    got = json.loads(p.stdout)
    assert got["http"] == 0 and got["out"].startswith("live: ")           # the probe did its whole job

    probe = set(got["after_http"]) - set(got["at_start"])
    tops = {m.split(".")[0] for m in probe}
    foreign = sorted(t for t in tops - set(OURS) - set(PYDANTIC) if not (pyyaml(t) or standard(t)))
    ours = sorted(m for m in probe if m.split(".")[0] in OURS and m not in ALLOWED)
    assert foreign == [] and ours == [], f"the HTTP probe imports {foreign + ours}"

    heavy = sorted(m for m in got["after_modbus"]
                   if m.split(".")[0] in NEVER or m.startswith("service.") and m not in ALLOWED)
    assert heavy == [], f"the Modbus fallback imports {heavy}"
    assert "pymodbus" in {m.split(".")[0] for m in got["after_modbus"]}     # it did read (or try) Modbus
