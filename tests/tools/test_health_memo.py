"""The health probe validates a config once (issue 45, item 6): a later probe of the same file, unchanged, and of
the same code imports neither pydantic nor pyyaml; any edit of the file, or of the code the validation imported
(found in sys.modules, issue 51, item 6), makes the probe validate again and refuse what the service refuses; a
run folder it cannot write costs only speed."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from importlib.util import find_spec
from pathlib import Path

import yaml
from test_health_cmd import OURS, health_server

from hil.testing import ROOT
from tools import health_memo
from tools.cli import main

_PROBE = """
import sys
from tools.cli import main
code = main(["health", "--config", sys.argv[1]])
print(json.dumps({"code": code, "modules": sorted(sys.modules)}), file=sys.stderr)
"""


def probe(config, run_dir) -> dict:
    """One probe as the HEALTHCHECK runs it, in an interpreter of its own: its exit code and modules."""
    p = subprocess.run([sys.executable, "-c", "import json\n" + _PROBE, str(config)], cwd=ROOT, capture_output=True,
                       text=True, timeout=60, check=False, env={"STIFFCOMP_RUN_DIR": str(run_dir), "PATH": ""})
    return json.loads(p.stderr.strip().splitlines()[-1])


def test_a_config_validated_once_is_not_validated_again_until_it_changes(tmp_path):
    cfg = tmp_path / "service.yaml"
    with health_server({"healthy": True, "reason": "stand-in"}) as port:
        cfg.write_text(yaml.safe_dump({"monitoring": {"port": port}}))
        first = probe(cfg, tmp_path / "run")
        second = probe(cfg, tmp_path / "run")
        cfg.write_text(yaml.safe_dump({"monitoring": {"port": port}, "filter": {"cutoff_hz": 30}}))   # an edit
        edited = probe(cfg, tmp_path / "run")
    assert first["code"] == second["code"] == edited["code"] == 0
    assert "pydantic" in first["modules"] and "yaml" in first["modules"]       # validated with the schemas
    assert "pydantic" not in second["modules"] and "yaml" not in second["modules"], second["modules"]
    assert "pydantic" in edited["modules"]                                        # the edit: validated again


def test_an_edit_the_service_refuses_is_refused_though_the_file_was_remembered(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("STIFFCOMP_RUN_DIR", str(tmp_path / "run"))
    cfg = tmp_path / "service.yaml"
    with health_server({"healthy": True, "reason": "stand-in"}) as port:
        cfg.write_text(yaml.safe_dump({"monitoring": {"port": port}}))
        assert main(["health", "--config", str(cfg)]) == 0
        assert health_memo.recall(cfg) == ("127.0.0.1", port)
        cfg.write_text(yaml.safe_dump({"monitorin": {"port": port}}))
        assert main(["health", "--config", str(cfg)]) == 2
    assert f"{cfg}: monitorin is not a known key" in capsys.readouterr().err


def test_other_schema_code_or_a_damaged_memo_is_not_trusted(tmp_path, monkeypatch):
    monkeypatch.setenv("STIFFCOMP_RUN_DIR", str(tmp_path / "run"))
    cfg = tmp_path / "service.yaml"
    cfg.write_text("monitoring: {port: 9999}\n")
    health_memo.remember(cfg, health_memo.digest(cfg), "127.0.0.1", 9999)
    assert health_memo.recall(cfg) == ("127.0.0.1", 9999)
    monkeypatch.setattr(health_memo, "code_key", lambda files: "an upgrade")
    assert health_memo.recall(cfg) is None
    monkeypatch.undo()
    monkeypatch.setenv("STIFFCOMP_RUN_DIR", str(tmp_path / "run"))
    health_memo.memo_path(cfg).write_text("{not json")
    assert health_memo.recall(cfg) is None
    health_memo.remember(cfg, "the sha of other bytes", "127.0.0.1", 9999)     # changed while it was validated
    assert health_memo.recall(cfg) is None
    health_memo.remember(cfg, health_memo.digest(cfg), "127.0.0.1", 9999)
    me = health_memo.os.getuid()
    monkeypatch.setattr(health_memo.os, "getuid", lambda: me + 1)                # as another user sees it
    assert health_memo.recall(cfg) is None


def test_a_run_folder_that_cannot_be_written_costs_only_speed(tmp_path, monkeypatch, capsys):
    (tmp_path / "file").write_text("")
    monkeypatch.setenv("STIFFCOMP_RUN_DIR", str(tmp_path / "file" / "run"))       # under a file: no folder
    cfg = tmp_path / "service.yaml"
    with health_server({"healthy": True, "reason": "stand-in"}) as port:
        cfg.write_text(yaml.safe_dump({"monitoring": {"port": port}}))
        assert main(["health", "--config", str(cfg)]) == 0
        assert main(["health", "--config", str(cfg)]) == 0
    assert health_memo.recall(cfg) is None


def test_the_memo_is_keyed_by_every_project_module_the_validation_imported(tmp_path):
    """Found, not listed: the memo's files are those of the project's modules the probe had imported, the
    schemas and the YAML reader among them."""
    cfg = tmp_path / "service.yaml"
    with health_server({"healthy": True, "reason": "stand-in"}) as port:
        cfg.write_text(yaml.safe_dump({"monitoring": {"port": port}}))
        first = probe(cfg, tmp_path / "run")
    memo = json.loads(next((tmp_path / "run").glob("*.probe.json")).read_text())
    ours = {Path(find_spec(m).origin).resolve().relative_to(ROOT).as_posix() for m in first["modules"]
            if m.split(".")[0] in OURS}
    assert set(memo["files"]) == ours
    assert {"io_process/endpoints.py", "plc_link/settings.py", "plc_link/ads/settings.py", "io_process/settings.py",
            "stiffness/files/yaml_schema.py", "tools/health_memo.py"} <= ours


def test_a_change_of_any_file_the_validation_imported_misses_the_memo(tmp_path, monkeypatch):
    """The memo's files, copied to a tree of their own with their times: the same tree hits; one file touched
    (an upgrade of any module the validation imported) misses."""
    monkeypatch.setenv("STIFFCOMP_RUN_DIR", str(tmp_path / "run"))
    cfg = tmp_path / "service.yaml"
    cfg.write_text("monitoring: {port: 9999}\n")
    health_memo.remember(cfg, health_memo.digest(cfg), "127.0.0.1", 9999)
    files = json.loads(health_memo.memo_path(cfg).read_text())["files"]
    tree = tmp_path / "tree"
    for rel in files:
        (tree / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(health_memo.ROOT / rel, tree / rel)
    monkeypatch.setattr(health_memo, "ROOT", tree)
    assert health_memo.recall(cfg) == ("127.0.0.1", 9999)
    schema = tree / "plc_link" / "settings.py"
    os.utime(schema, ns=(schema.stat().st_atime_ns, schema.stat().st_mtime_ns + 1_000_000_000))
    assert health_memo.recall(cfg) is None
