"""The status screen: every value blank once the service stops answering, and why a correction is zero
(issue 17, item 7). Pure: readings by name in, the rendered text out."""

from __future__ import annotations

from rich.console import Console

from plc_link.contract import Fault, Status, TaskState, to_plc
from tools.status_view import StatusView, why_zero

RUNNING_OK = int(Status.RUNNING | Status.ACTIVE | Status.SENSOR_OK | Status.PLC_SEEN)


def text(view: StatusView) -> str:
    console = Console(record=True, width=120, color_system=None)
    console.print(view.render())
    return console.export_text()


def reading(cycle: int, status: int = RUNNING_OK, fault: int = 0, correction: float = 0.01) -> dict[str, float]:
    values = to_plc(cycle_count=cycle, task_state=int(TaskState.RUN), status_word=status, fault_word=fault,
                    last_exec_us=120.0, **{f"correction_q{k}": correction for k in range(1, 7)},
                    wrench_fx=321.5, deflection_dx=0.4)
    return values._asdict()


def test_every_value_is_blank_once_the_service_stops_answering():
    view = StatusView("modbus 127.0.0.1:5020")
    for k in range(5):
        view.update(reading(1000 * k), 0.25 * k)
    live = text(view)
    assert "RUN" in live and "4,000 /s" in live and "sensor ok" in live and "+321.50" in live
    view.failed("no answer from the service at 127.0.0.1:5020")
    gone = text(view)
    assert "no answer from the service" in gone and "every value blank" in gone
    for shown in ("RUN", "/s", "running", "sensor ok", "321.50", "+0.01000", "0.4000", "applied"):
        assert shown not in gone, shown
    view.update(reading(9000), 2.0)                        # it answers again: values, rates afresh
    back = text(view)
    assert "RUN" in back and "rate —" in back and "every value blank" not in back


def test_status_says_why_the_correction_is_zero():
    enabled_off = int(Status.RUNNING | Status.SENSOR_OK | Status.PLC_SEEN)
    assert "enable bit" in why_zero(enabled_off, 0)
    faulted = int(Status.RUNNING | Status.FAULTED | Status.SENSOR_OK)
    assert "plc_heartbeat" in why_zero(faulted, int(Fault.PLC_HEARTBEAT))
    ramping = int(Status.RUNNING | Status.RAMPING | Status.SENSOR_OK)
    assert "ramping" in why_zero(ramping, 0)
    assert "stopped" in why_zero(int(Status.STOPPED), 0)
    assert "sensor sample" in why_zero(int(Status.RUNNING), 0)
    view = StatusView("modbus 127.0.0.1:5020")
    view.update(reading(10, status=enabled_off, correction=0.0), 0.0)
    assert "zero: the PLC's enable bit (command_word bit 0) is off" in text(view)
    view.update(reading(20), 0.25)
    assert any(line.split() == ["correction", "applied"] for line in text(view).splitlines())


def test_status_shows_the_payload_set_in_use_by_index_and_name():
    view = StatusView("modbus 127.0.0.1:5020", payload_names={0: "gravity bodies", 3: "spindle + D20 mill"})
    view.update({**reading(1000), "payload_active": 3.0}, 0.0)
    assert "3  spindle + D20 mill" in text(view)
    view.update({**reading(2000), "payload_active": 9.0}, 0.25)
    assert "9  (no set of this index in the config)" in text(view)
    view.update({k: v for k, v in reading(3000).items() if k != "payload_active"}, 0.5)   # a map without it
    assert "payload" not in text(view)


def test_the_reload_count_is_shown_and_blank_without_an_answer():
    view = StatusView("modbus 127.0.0.1:5020")
    view.update({**reading(1000), "reload_count": 3.0}, 0.0)
    assert any(line.split()[:2] == ["reloads", "3"] for line in text(view).splitlines())
    view.failed("no answer")
    assert any(line.split() == ["reloads", "—"] for line in text(view).splitlines())
