"""`stiffcomp plc-library --config` reads the config as `stiffcomp run --check` does (issue 45, item 1): the
register map passed as the config, and a misspelt section, each exit 2 in one line naming the file and the key,
and nothing is written (the default layout, written from the wrong file, would send the PLC to the wrong
registers)."""

from __future__ import annotations

import pytest
import yaml

from service.config import DEFAULT_CONFIG, SHIPPED, load_config
from service.errors import ServiceConfigError
from stiffness.files.kinds import KINDS, looks_like
from tools.cli import main


def refused(capsys, code: int, *words: str) -> str:
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
    for w in words:
        assert w in err, err
    return err


def test_the_register_map_as_config_is_refused_naming_what_it_looks_like(tmp_path, capsys):
    rmap = SHIPPED / "registers.yaml"
    code = main(["plc-library", "-o", str(tmp_path / "out"), "--config", str(rmap)])
    refused(capsys, code, str(rmap), "word_order is not a known key", "looks like a register map",
            "plc.register_map")
    assert not (tmp_path / "out").exists()
    code = main(["run", "--check", "--config", str(rmap)])            # the service says the same
    refused(capsys, code, str(rmap), "looks like a register map")


def test_a_misspelt_section_is_refused_as_run_check_refuses_it(tmp_path, capsys):
    data = yaml.safe_load(DEFAULT_CONFIG.read_text())
    data["plcc"] = data.pop("plc") | {"port": 1502}
    cfg = tmp_path / "service.yaml"
    cfg.write_text(yaml.safe_dump(data, sort_keys=False))
    out = tmp_path / "out"
    library = refused(capsys, main(["plc-library", "-o", str(out), "--config", str(cfg)]), str(cfg), "plcc")
    assert not out.exists()
    check = refused(capsys, main(["run", "--check", "--config", str(cfg)]), str(cfg), "plcc")
    assert library.split("error: ", 1)[1] == check.split("error: ", 1)[1]   # word for word the service's refusal


def test_a_bad_value_in_another_section_is_refused_too(tmp_path, capsys):
    data = yaml.safe_load(DEFAULT_CONFIG.read_text())
    data["cycle"]["period_ms"] = -1
    cfg = tmp_path / "service.yaml"
    cfg.write_text(yaml.safe_dump(data, sort_keys=False))
    refused(capsys, main(["plc-library", "-o", str(tmp_path / "out"), "--config", str(cfg)]), str(cfg),
            "cycle.period_ms")


OTHERS = {"registers.yaml": "a register map", "models/kr125_6dof.yaml": "a stiffness model",
          "models/kr125_axial.yaml": "a stiffness model", "robots/kr125.yaml": "a robot file",
          "robots/kr125_urdf.yaml": "a robot file", "robots/kr125_masses.yaml": "a robot file",
          "hil/circle.yaml": "a HIL scenario"}


@pytest.mark.parametrize("name", sorted(OTHERS))
def test_each_shipped_file_of_another_kind_is_named_for_what_it_is(name):
    path = SHIPPED / name
    with pytest.raises(ServiceConfigError) as e:
        load_config(path)
    assert str(e.value).startswith(f"{path}: ") and f"looks like {OTHERS[name]} (its keys " in str(e.value)
    assert "\n" not in str(e.value)


def test_a_config_with_one_stray_key_of_another_kind_is_still_a_config():
    """One key that another kind has (a stray ``circle:``) does not outweigh a config's own sections."""
    sections = ["cycle", "model", "source", "plc"]
    assert looks_like({"cycle": {}, "model": {}, "source": {}, "circle": {}}, sections) is None
    assert looks_like({"plcc": {}}, sections) is None
    for kind in KINDS:
        assert looks_like(dict.fromkeys(kind.keys), sections).startswith(kind.name)
