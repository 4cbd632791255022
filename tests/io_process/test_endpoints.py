"""The probe's config reader: the service's own schemas of the sections it reads, the service's verdict on
any value, and its top-level sections."""

from __future__ import annotations

import tempfile
from pathlib import Path

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from io_process.endpoints import read_endpoints, resolve_path
from io_process.settings import MonitoringSettings
from plc_link.ads.settings import AdsSettings
from plc_link.settings import PlcSettings
from service.config import load_config
from service.errors import ServiceConfigError
from service.paths import DEFAULT_CONFIG, SECTIONS
from stiffness.errors import ConfigError

pytestmark = pytest.mark.slow

SCHEMAS = {"monitoring": MonitoringSettings, "plc": PlcSettings, "ads": AdsSettings}


def test_an_empty_config_reads_the_schemas_defaults(tmp_path):
    path = tmp_path / "service.yaml"
    path.write_text("{}\n")
    ep = read_endpoints(path, SECTIONS)
    for name, schema in SCHEMAS.items():
        assert getattr(ep, name) == schema()


def test_the_shipped_config_reads_as_the_service_reads_it():
    ep, cfg = read_endpoints(DEFAULT_CONFIG, SECTIONS), load_config(DEFAULT_CONFIG)
    for name in SCHEMAS:
        assert getattr(ep, name) == getattr(cfg, name)
    assert resolve_path(ep.path, ep.plc.register_map) == cfg.resolve(cfg.plc.register_map)
    assert ep.register_map().codecs["to_plc"].names == cfg.register_map().codecs["to_plc"].names


KEYS = [(name, key) for name, schema in SCHEMAS.items() for key in schema.model_fields] + [
    ("monitoring", "hots"), ("plc", "prot"), ("ads", "enable")]
values = st.one_of(st.integers(-5, 70_000), st.floats(allow_nan=True, allow_infinity=True), st.booleans(),
                   st.none(), st.text(max_size=6), st.lists(st.integers(0, 9), max_size=2),
                   st.sampled_from(["server", "client", "none", "5020", " 9020", "0.5", "yes", "off", "1e3"]))


@settings(max_examples=80, deadline=None)
@given(key=st.sampled_from(KEYS), value=values)
def test_any_value_is_refused_exactly_when_the_service_refuses_it_and_in_its_words(key, value):
    """The shipped config with one key of a section the probe reads set to ``value``: the probe reads
    what the service reads, and refuses it with the service's message when the service refuses it."""
    name, field = key
    data = yaml.safe_load(DEFAULT_CONFIG.read_text())
    data[name][field] = value
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "service.yaml"         # relative paths still find the shipped files
        path.write_text(yaml.safe_dump(data))
        try:
            cfg = load_config(path)
        except ServiceConfigError as e:
            if "file(s) it names not found" in str(e):
                return                  # a file check (plc.tls, the register map): the probe opens no file
            with pytest.raises(ConfigError) as got:
                read_endpoints(path, SECTIONS)
            assert str(got.value) == str(e)
            return
        assert getattr(read_endpoints(path, SECTIONS), name) == getattr(cfg, name)


def test_a_section_that_is_no_mapping_is_refused_naming_it(tmp_path):
    path = tmp_path / "service.yaml"
    path.write_text("monitoring: 9020\n")
    with pytest.raises(ConfigError, match=r"service\.yaml: monitoring = 9020: Input should be a valid dictionary"):
        read_endpoints(path, SECTIONS)


def test_a_missing_file_is_named(tmp_path):
    with pytest.raises(ConfigError, match="nothing.yaml"):
        read_endpoints(tmp_path / "nothing.yaml")
