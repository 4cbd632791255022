"""How a HIL run starts the service: its config written with the run's settings and the files the
scenario's config names (the config resolves them itself), and readiness from the service's /health,
not from its log."""

from __future__ import annotations

import shutil

import pytest
import yaml

from hil.run import HilError, ServiceProcess, write_service_config
from hil.testing import CONFIG, free_port, write_config
from io_process.endpoints import read_health
from plc_link.contract import TaskState
from service.config import load_config
from testlib.hil import EXAMPLES, scenario


def resolved(cfg) -> dict[str, str]:
    return {k: str(cfg.resolve(v).resolve()) for k, v in cfg.files().items()}


def test_the_run_config_names_the_files_the_scenarios_config_names(tmp_path):
    """A scenario whose service config sits in a folder of its own, naming its files relative to it."""
    site = tmp_path / "site"
    (site / "maps").mkdir(parents=True)
    shutil.copy(CONFIG / "registers.yaml", site / "maps" / "plant.yaml")
    shutil.copy(CONFIG / "ati_netft_can.dbc", site / "ft.dbc")
    data = yaml.safe_load((CONFIG / "hil" / "service.yaml").read_text())
    data["plc"]["register_map"] = "maps/plant.yaml"
    data["source"]["ati"]["dbc"] = "ft.dbc"
    data["model"]["file"] = str(CONFIG / "models" / "kr125_6dof.yaml")
    (site / "service.yaml").write_text(yaml.safe_dump(data))
    sc = scenario()
    sc.service = str(site / "service.yaml")
    model = EXAMPLES / "truth_reference.yaml"
    written = load_config(write_service_config(sc, model, tmp_path, "239.74.1.2", 43000, 5999,
                                               {"filter": {"cutoff_hz": 80.0}}))
    assert written.path.parent == tmp_path
    expected = resolved(load_config(site / "service.yaml")) | {"model.file": str(model.resolve())}
    assert resolved(written) == expected
    assert expected["plc.register_map"] == str(site / "maps" / "plant.yaml")
    assert (written.plc.port, written.source.can.channel, written.source.can.options["port"]) == (5999, "239.74.1.2", 43000)
    assert written.filter.cutoff_hz == 80.0


def test_ready_when_health_says_the_task_runs_whatever_the_log_says(tmp_path):
    """With the log at WARNING the service never writes "service running"; /health still says RUN."""
    cfg = write_config(tmp_path, {"plc": {"port": free_port()}, "cycle": {"stats_log_interval_s": 0}})
    service = ServiceProcess(cfg, tmp_path, log_level="WARNING")
    try:
        service.wait_running()
        assert read_health(*service.health_at)["task_state"] == TaskState.RUN
        assert "service running" not in service.log_path.read_text()
    finally:
        service.stop()


def test_a_service_that_exits_at_start_is_reported_with_its_log(tmp_path):
    data = yaml.safe_load((CONFIG / "registers.yaml").read_text())
    data["to_plc"]["registers"].append({**data["to_plc"]["registers"][-1]})
    (tmp_path / "broken.yaml").write_text(yaml.safe_dump(data))
    cfg = write_config(tmp_path, {"plc": {"register_map": str(tmp_path / "broken.yaml")}})
    service = ServiceProcess(cfg, tmp_path)
    try:
        with pytest.raises(HilError, match="the service exited with 2") as e:
            service.wait_running()
        assert "plc.register_map" in str(e.value)
    finally:
        service.stop()
