"""`stiffcomp certs`: a bad option is refused in one line before anything is written, and a certificate
made again over one that was there is said to be replaced."""

from __future__ import annotations

import json

import pytest
import yaml
from cryptography import x509

from hil.testing import write_config
from service.config import load_config
from tools.cli import main

BAD = {   # the options, and what the refusal names
    "expires as made": (["--days", "0"], "--days 0"),
    "expired": (["--days", "-1"], "--days -1"),
    "no number": (["--days", "nan"], "--days nan"),
    "beyond the CA": (["--days", "4000"], "--days 4000"),
    "empty host": (["--host", ""], "--host ''"),
    "blank host": (["--host", "localhost", "--host", "  "], "--host '  '"),
    "role with a colon": (["--client", "plc:oper:ator"], "--client plc:oper:ator"),
    "empty role": (["--client", "plc:"], "--client plc:"),
    "name twice": (["--client", "plc", "--client", "plc:viewer"], "--client plc: given twice"),
}


def refused(capsys, argv: list[str], *words: str) -> None:
    assert main(["certs", *argv, "--key-type", "ec"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and err.startswith("stiffcomp certs: error: ")
    assert all(w in err for w in words), err


@pytest.mark.parametrize(("argv", "named"), BAD.values(), ids=BAD.keys())
def test_a_bad_option_is_refused_naming_it_and_nothing_is_written(tmp_path, capsys, argv, named):
    folder = tmp_path / "certs"
    refused(capsys, [str(folder), *argv], named)
    assert not folder.exists()


@pytest.mark.parametrize("argv", [["--days", "0"], ["--client", "plc:a:b"]])
def test_a_refusal_leaves_a_folder_made_before_as_it_was(tmp_path, capsys, argv):
    folder = tmp_path / "certs"
    assert main(["certs", str(folder), "--client", "plc", "--key-type", "ec"]) == 0
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    capsys.readouterr()
    refused(capsys, [str(folder), "--host", "cell-pc", *argv])
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before       # not even the server's


def test_a_dir_that_is_a_file_is_refused_and_left_alone(tmp_path, capsys):
    path = tmp_path / "service.yaml"
    path.write_text("plc: {}\n")
    refused(capsys, [str(path)], f"DIR {path}: is a file")
    assert path.read_text() == "plc: {}\n" and sorted(p.name for p in tmp_path.iterdir()) == ["service.yaml"]


def test_a_client_certificate_made_again_is_said_to_be_replaced(tmp_path, capsys):
    folder = tmp_path / "certs"
    assert main(["certs", str(folder), "--client", "plc", "--key-type", "ec"]) == 0
    first = capsys.readouterr().out
    old = x509.load_pem_x509_certificate((folder / "plc.pem").read_bytes())
    assert main(["certs", str(folder), "--client", "plc:viewer", "--client", "hmi", "--key-type", "ec"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "replaced" not in first
    plc = [x for x in lines if x.startswith("client plc ")]
    assert len(plc) == 1 and "(role viewer)" in plc[0] and "replaced the one that was there" in plc[0]
    assert not any("replaced" in x for x in lines if x.startswith(("client hmi ", "server", "CA")))
    assert x509.load_pem_x509_certificate((folder / "plc.pem").read_bytes()).serial_number != old.serial_number
    assert main(["certs", str(folder), "--client", "hmi", "--host", "cell-pc", "--json", "--key-type", "ec"]) == 0
    made = json.loads(capsys.readouterr().out)
    assert made["server"]["replaced"] is True and [c["replaced"] for c in made["clients"]] == [True]


def test_the_config_lines_hold_where_the_site_folder_is_mounted(tmp_path, capsys):
    """The printed plc.tls lines, pasted into a config beside DIR, name the files after the folder has
    moved (as a container sees it at /etc/stiffcomp): paths relative to the config's folder."""
    site = tmp_path / "site"
    assert main(["certs", str(site / "certs"), "--key-type", "ec"]) == 0
    out = capsys.readouterr().out
    start = out.index("plc:\n")
    lines = yaml.safe_load(out[start:out.index("\n\n", start)])
    assert f"in a service config in {site}/" in out
    assert main(["certs", str(site / "certs"), "--json"]) == 0
    made = json.loads(capsys.readouterr().out)
    assert made["config"] == lines and made["config_folder"] == str(site)
    mounted = tmp_path / "mounted"
    site.rename(mounted)                        # this machine's paths are gone, as in the container
    cfg = load_config(write_config(mounted, lines))
    files = {k: cfg.resolve(v) for k, v in cfg.plc.tls.files().items()}
    certs = mounted / "certs"
    assert files == {"cert": certs / "server.pem", "key": certs / "server.key", "ca": certs / "ca.pem"}
