"""The service config: defaults validate, bad values are named with file, key, value and range."""

from __future__ import annotations

import socket

import pytest

from hil.testing import BEYOND_SPRINGS, free_port, model_with, write_config
from service.config import DEFAULT_CONFIG, load_config
from service.errors import ServiceConfigError
from tools.cli import main


def test_default_config_validates():
    cfg = load_config(DEFAULT_CONFIG)
    assert cfg.cycle.period_ms == 1.0
    assert cfg.resolve(cfg.model.file).exists()
    assert cfg.plc.role == "server" and cfg.plc.port == 5020


@pytest.mark.parametrize("override, expected", [
    ({"filter": {"cutof_hz": 50}}, "filter.cutof_hz is not a known key"),
    ({"speed": 3}, "speed is not a known key"),
    ({"filter": {"order": 12}}, "filter.order = 12"),
    ({"filter": {"cutoff_hz": 900}}, "filter.cutoff_hz = 900 must be below half the cycle rate (500 Hz)"),
    ({"cycle": {"period_ms": 0.01}}, "cycle.period_ms = 0.01"),
    ({"source": {"type": "serial"}}, "source.type = 'serial'"),
    ({"limits": {"max_rate_deg_s": [1, 2, 3]}}, "limits.max_rate_deg_s"),
    ({"faults": {"sensor_timeout_ms": 0.5}}, "faults.sensor_timeout_ms = 0.5 must be longer than cycle.period_ms"),
    ({"source": {"replay": {"file": "nowhere.blf"}}}, "source.replay.file = 'nowhere.blf'"),
])
def test_bad_config_names_file_key_value_and_range(tmp_path, override, expected):
    path = write_config(tmp_path, override)
    with pytest.raises(ServiceConfigError) as e:
        load_config(path)
    assert str(path) in str(e.value)
    assert expected in str(e.value)


def test_range_is_stated(tmp_path):
    path = write_config(tmp_path, {"filter": {"order": 12}})
    with pytest.raises(ServiceConfigError, match="less than or equal to 8"):
        load_config(path)


def test_run_with_bad_config_exits_2_and_starts_nothing(tmp_path, capsys):
    port = free_port()
    path = write_config(tmp_path, {"plc": {"port": port}, "limits": {"fault_ramp_s": -1}})
    assert main(["run", "--config", str(path), "--duration", "5"]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and "limits.fault_ramp_s = -1" in err and "greater than 0" in err
    with socket.socket() as s:          # nothing listens: the port is still free
        s.bind(("127.0.0.1", port))


def test_a_model_with_every_library_effect_runs(tmp_path, capsys):
    """`stiffcomp run` accepts a model holding every effect of the library; drift is ignored with one
    warning that names it (docs/service.md)."""
    from stiffness.effects import EFFECTS

    model = tmp_path / "model.yaml"
    every = model_with({"effect": "joint_6dof", "joint": 4, "x_m_per_N": 1e-8, "ry_rad_per_Nm": 2e-7},
                       *BEYOND_SPRINGS)
    assert {e.name for e in every.effects} == set(EFFECTS)
    every.to_yaml(model)
    path = write_config(tmp_path, {"model": {"file": str(model)}, "plc": {"port": free_port()}})
    assert main(["run", "--config", str(path), "--duration", "1"]) == 0
    err = capsys.readouterr().err
    assert err.count("drift ignored by the service") == 1, err
    assert "not supported" not in err
