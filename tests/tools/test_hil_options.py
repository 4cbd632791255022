"""`stiffcomp hil circle`'s options are checked before any pass runs: a value outside what the scenario or
the service takes, an option of the dynamic pass without it, and the dynamic pass without the static one it
builds on each exit 2 naming the option (nothing is ignored in silence, nothing starts). So do a --repeat that
is not a whole number of 1 or more, a circle the arm cannot follow from --center-q (the inverse kinematics
fails), a --cmm, --probe or --modes-data file in a folder that does not exist (written at the end of the cut), and
--added-damping or --mode-error the service would refuse
(after two passes, naming its temporary config)."""

from __future__ import annotations

import re

import pytest

from tools.cli import main


@pytest.mark.parametrize("args, message", [
    (["--extra-delay-ms", "-5"], r"--extra-delay-ms: plc\.extra_delay_ms = -5\.0: .*greater than or equal to 0"),
    (["--extra-delay-ms", "500"], r"--extra-delay-ms: plc\.extra_delay_ms = 500\.0: .*less than or equal to 100"),
    (["--center-q", "0", "-60", "90", "0", "60", "nan"], r"--center-q: circle\.center_q_deg\.5 = nan: .*finite"),
    (["--dynamic-compensation", "--delay-ms", "-3"], r"--delay-ms: dynamics\.delay_ms = -3\.0: .*greater than or equal to 0"),
    (["--delay-ms", "5"], r"--delay-ms: only with --dynamic-compensation"),
    (["--mode-error", "0.2", "--feedforward"], r"--mode-error, --feedforward: only with --dynamic-compensation"),
    (["--dynamic-compensation", "--no-compensation"], r"--dynamic-compensation builds on the compensated pass"),
    (["--center-q", "0", "0", "0", "0", "0", "0"], (r"--center-q 0 0 0 0 0 0: the circle of 35 mm about the tool at "
     r"this pose cannot be followed: inverse kinematics did not converge .* at 0 deg along the circle \(a point out "
     r"of the arm's reach.*the scenario's: 0 -60 90 0 60 0\)")),
    (["--cmm", "{tmp}/missing/part.csv"], r"--cmm {tmp}/missing/part\.csv: the folder {tmp}/missing does not exist"),
    (["--probe", "{tmp}/missing/probe.csv"], r"--probe {tmp}/missing/probe\.csv: the folder {tmp}/missing does not exist"),
    (["--dynamic-compensation", "--modes-data", "{tmp}/missing/tap.csv"],
     r"--modes-data {tmp}/missing/tap\.csv: the folder {tmp}/missing does not exist"),
    (["--dynamic-compensation", "--added-damping", "-1"],
     r"--added-damping: dynamics\.structure\.added_damping = -1\.0: .*greater than or equal to 0"),
    (["--dynamic-compensation", "--added-damping", "3"],
     r"--added-damping: dynamics\.structure\.added_damping = 3\.0: .*less than or equal to 2"),
    (["--dynamic-compensation", "--mode-error", "-1"], (r"--mode-error -1: must be a finite number above -1 \(the "
     r"service's mode frequencies are the identified ones times 1 \+ F")),
    (["--dynamic-compensation", "--mode-error", "nan"], r"--mode-error nan: must be a finite number above -1"),
    (["--repeat", "0"], r"--repeat 0: must be a whole number, at least 1"),
    (["--repeat", "2.5"], r"--repeat 2\.5: must be a whole number, at least 1"),
    (["--repeat", "three"], r"--repeat three: must be a whole number, at least 1"),
    (["--probe", "{tmp}/probe.qif"], r"--probe {tmp}/probe\.qif: the suffix must be \.csv"),
    (["--cmm", "{tmp}/part.parquet"], r"--cmm {tmp}/part\.parquet: the suffix must be \.csv or \.qif"),
], ids=["delay<0", "delay>100", "center-nan", "service-delay<0", "delay-alone", "dynamic-options-alone",
        "dynamic-without-static", "center-out-of-reach", "cmm-folder", "probe-folder", "modes-data-folder", "added-damping<0",
        "added-damping>2", "mode-error=-1", "mode-error=nan", "repeat=0", "repeat=2.5", "repeat=three", "probe-suffix",
        "cmm-suffix"])
def test_a_bad_option_exits_2_naming_it_before_any_pass(args, message, capsys, tmp_path):
    refused(args, message, capsys, tmp_path)


def refused(args, message, capsys, tmp_path):
    """`stiffcomp hil circle --lockstep --report DIR ARGS` exits 2 with one line matching ``message`` ({tmp}:
    ``tmp_path``), and no pass ran: no report, nothing in ``tmp_path``."""
    report = tmp_path / "report"
    args = [a.replace("{tmp}", str(tmp_path)) for a in args]
    assert main(["hil", "circle", "--lockstep", "--report", str(report), *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert re.search(message.replace("{tmp}", re.escape(str(tmp_path))), err), err
    assert not report.exists() and list(tmp_path.iterdir()) == []       # no pass ran, no folder was made


def test_a_mode_error_the_service_would_refuse_is_refused_after_the_tap_test_before_any_pass(capsys, tmp_path):
    """--mode-error 100 puts the stub's 10 and 16 Hz at 1,011 and 1,617 Hz: above the 500 Hz a mode may have.
    The modes are known once the tap test is identified (seconds, in this process), so that is where it stops."""
    refused(["--dynamic-compensation", "--mode-error", "100"], r"--mode-error 100: the identified modes' frequencies "
            r"times 1 \+ it are not what the service takes: dynamics\.structure\.modes\.0\.hz = 1010\.\d+: .*less "
            r"than or equal to 500; dynamics\.structure\.modes\.1\.hz = 1617\.\d+", capsys, tmp_path)
