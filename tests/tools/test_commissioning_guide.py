"""The commissioning guide's first steps, run as written (issue 27, item 5).

docs/commissioning.md's step 0 (a site config copied from the shipped one, then checked) and step 1 (the
payload identified from poses, first on the shipped example) are read from the guide's own code blocks
and run line by line in a temporary folder laid out as a host install is: the clone's ``config/`` and
``examples/`` and the ``.venv`` whose ``bin/stiffcomp`` the guide names. A small interpreter runs each
line: ``S=...``, ``mkdir -p``, ``cp`` and ``$S ...`` (the command line's `main`, in this process, as
the entry point runs it); any other command fails the test, so the guide cannot drift into steps nobody
ran. The only thing the test adds is what the robot would produce: the user's poses file.
"""

from __future__ import annotations

import logging
import re
import shlex
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from service.config import load_config
from service.errors import ServiceConfigError
from stiffness.files.yaml_schema import read_yaml
from testlib.common import ROOT
from tools.cli import main

GUIDE = ROOT / "docs" / "commissioning.md"

# the site config is the shipped one, and its check binds the shipped default ports (ADS 48898 and the others),
# which the whole host shares: beside the other worker a test holding one of them failed it (ADS 48898 in use)
pytestmark = pytest.mark.serial


def first_bash_block(title: str) -> list[str]:
    """The lines of the first ```bash block in the guide's section ``## {title}``."""
    text = GUIDE.read_text()
    section = text.split(f"\n## {title}\n", 1)[1].split("\n## ", 1)[0]
    block = re.search(r"```bash\n(.*?)```", section, re.DOTALL)
    assert block, f"no bash block in section {title!r} of {GUIDE}"
    return [line for line in block.group(1).splitlines() if line.strip()]


class Shell:
    """The few shell commands the guide's first steps use, run in ``cwd``; stiffcomp in this process."""

    def __init__(self, cwd: Path, capsys):
        self.cwd, self.capsys, self.vars = cwd, capsys, {}
        self.outputs: list[str] = []

    def run(self, line: str) -> None:
        words = shlex.split(line, comments=True)
        commands, current = [], []
        for w in words:
            if w == "&&":
                commands.append(current)
                current = []
            else:
                current.append(w)
        commands.append(current)
        for cmd in commands:
            self.command(cmd, line)

    def command(self, cmd: list[str], line: str) -> None:
        if len(cmd) == 1 and re.fullmatch(r"[A-Z]+=\S+", cmd[0]):
            name, value = cmd[0].split("=", 1)
            self.vars[name] = value
        elif cmd[:2] == ["mkdir", "-p"]:
            for d in cmd[2:]:
                (self.cwd / d).mkdir(parents=True, exist_ok=True)
        elif cmd[0] == "cp" and len(cmd) == 3:
            shutil.copyfile(self.cwd / cmd[1], self.cwd / cmd[2])
        elif cmd[0] == "$S":
            entry = self.cwd / self.vars["S"]
            assert entry.is_file(), f"{line}: the guide's S = {self.vars['S']} is not the host install's stiffcomp"
            code = main(cmd[1:])
            out = self.capsys.readouterr()
            assert code == 0, f"{line}: exit code {code}\n{out.err}"
            self.outputs.append(out.out)
        else:
            pytest.fail(f"the guide's line {line!r} runs {cmd[0]!r}, which this test does not know how to run")


@pytest.fixture
def host_install(tmp_path, monkeypatch):
    """A working folder as the clone is after `make install`, with nothing written into the real one."""
    for name in ("config", "examples"):
        (tmp_path / name).symlink_to(ROOT / name)
    (tmp_path / ".venv").symlink_to(Path(sys.prefix))
    monkeypatch.chdir(tmp_path)
    handlers, level = logging.root.handlers[:], logging.root.level      # `run` configures logging
    yield tmp_path
    logging.root.handlers[:], logging.root.level = handlers, level


def test_the_guides_first_steps_run_as_written_on_a_host_install(host_install, capsys):
    shell = Shell(host_install, capsys)
    for line in first_bash_block("0. A site config"):
        shell.run(line)
    site = host_install / "site" / "service.yaml"
    assert read_yaml(site) == read_yaml(ROOT / "config" / "default.yaml")          # the copy, as it is
    assert shell.outputs[-1].startswith("site/service.yaml: ok, the service would start")
    cfg = load_config(site)
    for key, rel in cfg.files().items():             # the copy's relative paths find the shipped files
        assert cfg.resolve(rel).resolve() == (ROOT / "config" / rel).resolve(), key

    # step 1: the user's poses are the robot's; here the example's readings stand in for them
    shutil.copyfile(ROOT / "examples" / "payload_poses.csv", host_install / "site" / "poses.csv")
    for line in first_bash_block("1. Identify the payload"):
        shell.run(line)
    example, own = shell.outputs[-2:]
    assert example.splitlines()[1:] == own.splitlines()[1:]        # the same readings, the same result
    tool = re.search(r"tool: \{mass_kg: ([\d.]+), cog_mm: \[([-\d., ]+)\]\}", example)
    bias = re.search(r"bias: \[([-\d., ]+)\]", example)
    # the example's truth, as the guide states it (ten poses with a sensor's noise)
    assert float(tool.group(1)) == pytest.approx(14.2, abs=0.05)
    np.testing.assert_allclose([float(v) for v in tool.group(2).split(",")], [1.5, -0.8, 128.0], atol=0.5)
    bias_error = np.array([float(v) for v in bias.group(1).split(",")]) - [4.1, -2.7, 6.3, 0.12, -0.08, 0.03]
    assert np.all(np.abs(bias_error) <= [0.2, 0.2, 0.2, 0.02, 0.02, 0.02]), bias_error
    assert "14.2 kg spindle, centre of gravity [1.5, -0.8, 128] mm" in GUIDE.read_text().replace("\n", " ")


def test_the_container_variant_names_the_images_files(host_install):
    """The container lines cannot run here (no Docker in the suite): they take the image's own config,
    which names the shipped files by absolute paths inside the image, and check it with --check."""
    text = GUIDE.read_text().split("\n## 0. A site config\n", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```bash\n(.*?)```", text, re.DOTALL)
    assert len(blocks) == 2
    container = blocks[1]
    assert "docker run --rm --entrypoint cat stiffcomp /etc/stiffcomp/service.yaml > site/service.yaml" in container
    assert 'stiffcomp run --config /etc/stiffcomp/service.yaml --check' in container
    assert "/etc/stiffcomp/service.yaml" in (ROOT / "Dockerfile").read_text()


def test_every_path_that_does_not_resolve_is_named_in_one_error(host_install):
    """A copy whose relative paths are found neither beside it nor in the shipped config/ folder: one error
    lists them all (it used to name one per attempt); a file put beside the copy takes over the shipped one."""
    site = host_install / "site"
    site.mkdir()
    text = (ROOT / "config" / "default.yaml").read_text()
    for old, new in (("file: models/kr125_6dof.yaml", "file: models/mine.yaml"),
                     ("register_map: registers.yaml", "register_map: regs/registers.yaml"),
                     ("file: replay/demo_milling.blf", "file: /nowhere/demo.blf")):
        assert old in text
        text = text.replace(old, new)
    (site / "service.yaml").write_text(text)
    with pytest.raises(ServiceConfigError) as err:
        load_config("site/service.yaml")
    lines = str(err.value).splitlines()
    assert lines[0].startswith("site/service.yaml: 3 file(s) it names not found (a relative path is looked up "
                               "beside it, in site/, then in the shipped ")
    assert lines[1:] == ["  model.file = 'models/mine.yaml'", "  plc.register_map = 'regs/registers.yaml'",
                         "  source.replay.file = '/nowhere/demo.blf'"]
    (site / "models").mkdir()
    shutil.copyfile(ROOT / "config" / "models" / "kr125_6dof.yaml", site / "models" / "kr125_6dof.yaml")
    (site / "service.yaml").write_text((ROOT / "config" / "default.yaml").read_text())
    cfg = load_config(site / "service.yaml")
    assert cfg.resolve(cfg.model.file) == site / "models" / "kr125_6dof.yaml"           # beside it first
    assert cfg.resolve(cfg.plc.register_map).resolve() == (ROOT / "config" / "registers.yaml").resolve()
