"""`stiffcomp hil circle`'s options are checked before any pass runs: a value outside what the scenario or
the service takes, an option of the dynamic pass without it, and the dynamic pass without the static one it
builds on each exit 2 naming the option (nothing is ignored in silence, nothing starts)."""

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
], ids=["delay<0", "delay>100", "center-nan", "service-delay<0", "delay-alone", "dynamic-options-alone",
        "dynamic-without-static"])
def test_a_bad_option_exits_2_naming_it_before_any_pass(args, message, capsys, tmp_path):
    report = tmp_path / "report"
    assert main(["hil", "circle", "--lockstep", "--report", str(report), *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert re.search(message, err), err
    assert not report.exists()                      # no pass ran
