"""The probe's light config reader: the schema's defaults, and exactly the schema's verdict on any value."""

from __future__ import annotations

import math
from dataclasses import asdict, fields
from pathlib import Path

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from plc_interface.defaults import MonitoringEndpoint, PlcEndpoint
from plc_interface.endpoints import endpoints_from, read_endpoints, resolve_path
from plc_interface.settings import MonitoringSettings, PlcSettings
from service.config import load_config
from service.paths import DEFAULT_CONFIG
from stiffness.errors import ConfigError

SECTIONS = {"monitoring": (MonitoringEndpoint, MonitoringSettings), "plc": (PlcEndpoint, PlcSettings)}
KEYS = [(name, f.name) for name, (light, _) in SECTIONS.items() for f in fields(light)]


def test_an_empty_config_reads_the_schemas_defaults(tmp_path):
    path = tmp_path / "service.yaml"
    path.write_text("{}\n")
    ep = read_endpoints(path)
    for name, (_, schema) in SECTIONS.items():
        got, default = asdict(getattr(ep, name)), schema()
        assert got == {k: getattr(default, k) for k in got}


def test_the_shipped_config_reads_as_the_service_reads_it():
    ep, cfg = read_endpoints(DEFAULT_CONFIG), load_config(DEFAULT_CONFIG)
    for name in SECTIONS:
        got = asdict(getattr(ep, name))
        assert got == {k: getattr(getattr(cfg, name), k) for k in got}
    assert resolve_path(ep.path, ep.plc.register_map) == cfg.resolve(cfg.plc.register_map)
    assert ep.register_map().codecs["to_plc"].names == cfg.register_map().codecs["to_plc"].names


values = st.one_of(st.integers(-5, 70_000), st.floats(allow_nan=True, allow_infinity=True), st.booleans(),
                   st.none(), st.text(max_size=6), st.lists(st.integers(0, 9), max_size=2),
                   st.sampled_from(["server", "client", "none", "5020", " 9020", "0.5", "yes", "off", "1e3"]))


@settings(max_examples=150, deadline=None)
@given(key=st.sampled_from(KEYS), value=values)
def test_any_value_is_read_as_the_schema_reads_it(key, value):
    """The fast path takes plain values; every other value goes to the schema: the probe accepts exactly
    what the service accepts, with the same value, and names the file, key and value when it refuses."""
    name, field = key
    data = yaml.safe_load(yaml.safe_dump({name: {field: value}}))        # as a config file holds it
    path = Path("site/service.yaml")
    try:
        want = getattr(SECTIONS[name][1].model_validate(data[name]), field)
    except ValueError:
        with pytest.raises(ConfigError) as e:
            endpoints_from(data, path)
        assert str(path) in str(e.value) and f"{name}.{field}" in str(e.value)
        return
    got = getattr(getattr(endpoints_from(data, path), name), field)
    assert type(got) is type(want) and (got == want or math.isnan(got) and math.isnan(want))


def test_a_section_that_is_no_mapping_is_refused_naming_it(tmp_path):
    path = tmp_path / "service.yaml"
    path.write_text("monitoring: 9020\n")
    with pytest.raises(ConfigError, match=r"service\.yaml: monitoring = 9020: expected a mapping"):
        read_endpoints(path)


def test_a_missing_file_is_named(tmp_path):
    with pytest.raises(ConfigError, match="nothing.yaml"):
        read_endpoints(tmp_path / "nothing.yaml")
