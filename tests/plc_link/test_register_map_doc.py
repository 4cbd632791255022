"""docs/register_map.md documents every bit the contract owns, with the contract's numbers (issue 17, item 7)."""

from __future__ import annotations

import re
from pathlib import Path

from plc_link.contract import COMMAND_BITS, Command, Fault, Status

DOC = (Path(__file__).resolve().parents[2] / "docs" / "register_map.md").read_text()


def table(heading: str) -> dict[str, str]:
    """First column -> second column of the table under ``## heading``."""
    part = DOC.split(f"## {heading}", 1)[1].split("\n## ", 1)[0]
    rows = [line.split("|")[1:3] for line in part.splitlines() if re.match(r"\| [0-9]", line)]
    return {a.strip(): b.strip().strip("`") for a, b in rows}


def test_every_fault_bit_is_documented_at_its_bit():
    rows = table("Fault bits (`fault_word`)")
    assert rows == {str(f.bit_length() - 1): f.kind for f in Fault}


def test_every_status_bit_is_documented_at_its_bit():
    rows = table("Status bits (`status_word`)")
    assert {int(k): v.lower().replace(" ", "_") for k, v in rows.items()} == {
        s.bit_length() - 1: (s.name or "").lower() for s in Status}


def test_every_command_bit_and_the_undefined_ones_are_documented():
    rows = table("Command bits (`command_word`)")
    assert {k: v for k, v in rows.items() if k.isdigit()} == {str(c.bit_length() - 1): (c.name or "").lower()
                                                            for c in Command}
    assert COMMAND_BITS == 0x7 and "3 – 15" in rows and "command_invalid" in DOC


def test_no_word_on_a_pymodbus_pin_that_is_gone():
    assert "3.13" not in DOC and "<3.13" not in DOC
