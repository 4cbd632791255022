"""The contract's sources: parsed into an explicit (root, name, index) mapping, never eval'd, and the
compiled getter of a cycle's record gives what reading each source on its own gives."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from plc_link import contract
from plc_link.contract import TO_PLC, Producer, Source, TaskValues, _compile
from plc_link.errors import ContractError
from service.signals import Signals

LISTS = ("correction", "dq_deg", "wrench_base", "wrench_sensor", "deflection")
SCALARS = ("status_word", "fault_word", "tare_count", "sensor_samples", "sample_age_ms", "payload_active",
           "reload_count", "acc_x", "acc_y", "acc_z", "box_x", "box_y", "box_z", "box_samples")
ANY_SOURCE = ([f"task.{n}" for n in TaskValues._fields] + [f"signals.{n}" for n in SCALARS]
              + [f"signals.{n}[{i}]" for n in LISTS for i in range(6)])
value = st.floats(allow_nan=False, allow_infinity=False, width=32)


def sample(lists: float = 0.5, scalars: float = 1.0) -> tuple[TaskValues, Signals]:
    task = TaskValues(*range(len(TaskValues._fields)))
    return task, Signals(**{n: [lists] * 6 if n in LISTS else scalars for n in Signals._fields})


@st.composite
def records(draw) -> tuple[TaskValues, Signals]:
    n = len(TaskValues._fields)
    task = TaskValues(*draw(st.lists(value, min_size=n, max_size=n)))
    lists = {n: draw(st.lists(value, min_size=6, max_size=6)) for n in LISTS}
    scalars = {n: draw(value) for n in SCALARS}
    return task, Signals(**lists, **scalars)


@settings(max_examples=60, deadline=None)
@given(records())
def test_the_record_holds_each_source_read_on_its_own(rec):
    task, signals = rec
    produce = Producer()
    produce.check(task, signals)
    record = produce(task, signals)
    assert list(record) == [Source.parse(v.source).read(task, signals) for v in TO_PLC]
    assert record._fields == tuple(v.name for v in TO_PLC)


@settings(max_examples=60, deadline=None)
@given(records(), st.lists(st.sampled_from(ANY_SOURCE), min_size=1, max_size=40))
def test_any_choice_and_order_of_sources_compiles_to_the_same_values(rec, texts):
    """Any subset, in any order, with repeats: part of a list (wrench_sensor[0] alone, as the
    architecture's example adds), scalars between list entries, one root only."""
    task, signals = rec
    sources = tuple(Source.parse(t) for t in texts)
    assert _compile(sources, task, signals)(task, signals) == tuple(s.read(task, signals) for s in sources)


@pytest.mark.parametrize("text", ["signals.correction[-1]", "signals.correction.__class__", "os.system",
                                  "__import__('os')", "signals.correction[0][1]", "task.heartbeat + 1",
                                  "signals.Correction[0]", "task"])
def test_a_source_that_is_not_a_plain_path_is_refused(text):
    with pytest.raises(ContractError, match="must be 'task.NAME' or 'signals.NAME\\[INDEX\\]'"):
        Source.parse(text)


def test_a_missing_quantity_fails_at_check_and_names_the_value(monkeypatch):
    monkeypatch.setattr(contract, "TO_PLC", (*TO_PLC[:3], contract.Value("spindle", "float32", "", "", "signals.spindle")))
    task, signals = sample()
    with pytest.raises(ContractError, match="contract value 'spindle': source 'signals.spindle' does not resolve"):
        contract.Producer().check(task, signals)


def test_no_record_before_check_and_a_list_that_changes_length_is_refused():
    task, signals = sample()
    produce = Producer()
    with pytest.raises(ContractError, match="check"):
        produce(task, signals)
    produce.check(task, signals)
    assert produce(task, signals).correction_q6 == 0.5
    with pytest.raises(ContractError, match="signals.correction"):
        produce(task, signals._replace(correction=[0.5] * 7))


def test_the_contract_evaluates_no_text():
    text = Path(contract.__file__).read_text()
    assert "eval(" not in text and "exec(" not in text
