"""The link supervision's state table, written once in docs/plc.md ("The block's state table"), played row by
row on the program the cell loads: the generated library's MAIN run by the HIL's virtual PLC (`st_runtime`,
`hil.virtual_plc`) over the cell's network, against a process image whose records the test publishes.

Each row's event is played on a program brought into the row's state, then the state it is in is checked.
Events are named by their text in the table, so a row added or reworded there fails here until it is played.
A read here is one request, sent in one PLC cycle and taken in the next (the blocks end a request at the call
after the one that started it). The service moves its heartbeat and cycle count together, as the rows' "moved"
does.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from hil.cell_network import ImageNetwork, PlcFaults
from hil.plc_program import generate_program
from hil.virtual_plc import VirtualPlc
from plc_link.contract import to_plc
from plc_link.image import ProcessImage
from plc_link.register_map import RegisterMap

ROOT = Path(__file__).resolve().parents[2]
RMAP = RegisterMap.from_yaml(ROOT / "config" / "registers.yaml")
TIMEOUT, DT = 0.15, 0.004                # GVL_StiffCompSettings.tServiceTimeout; the PLC's cycle
STATES = {"waiting (after start)": "waiting", "waiting": "waiting", "alive": "alive", "lost": "lost"}


def table() -> list[dict[str, str]]:
    """The rows of the state table in docs/plc.md, column name -> cell (backticks dropped)."""
    text = (ROOT / "docs" / "plc.md").read_text()
    section = text.split("## The block's state table", 1)[1].split("\n## ", 1)[0]
    cells = [[c.strip().replace("`", "") for c in ln.strip().strip("|").split("|")]
             for ln in section.splitlines() if ln.startswith("|")]
    return [dict(zip(cells[0], row)) for row in cells[2:]]


@pytest.fixture(scope="module")
def program(tmp_path_factory):
    return generate_program(RMAP, 502, 1, tmp_path_factory.mktemp("plc"))


class Link:
    """The program and the service's values it reads, moved by the table's events."""

    def __init__(self, program):
        self.image = ProcessImage(RMAP)
        self.network = ImageNetwork(self.image, RMAP)
        self.plc = VirtualPlc(program, self.network, RMAP, lambda t: [0.0] * 6, True, DT)
        self.t, self.hb, self.count, self.seen = 0.0, 7, 7000, False

    def read(self, good: bool = True) -> bool:
        """One request under these conditions, sent and taken: bAlive after it."""
        self.image.publish(to_plc(heartbeat=self.hb, cycle_count=self.count, status_word=1))
        self.network.faults = PlcFaults() if good else PlcFaults(drop_at=0.0, drop_for_s=math.inf)
        for _ in range(2):
            self.plc.cycle(self.t)
            self.t += DT
        self.seen = self.seen or good
        return self.plc.fb.bAlive

    def move(self) -> bool:
        self.hb, self.count = self.hb + 1, self.count + 1
        return self.read()

    def wait(self, seconds: float, good: bool = True) -> list[bool]:
        return [self.read(good) for _ in range(round(seconds / (2 * DT)))]

    def state(self) -> str:
        """waiting: no good read yet; alive or lost: what one more good read without a move finds."""
        if not self.seen:
            return "waiting"
        return "alive" if self.read() else "lost"


def into(program, state: str) -> Link:
    link = Link(program)
    if state != "waiting":
        link.move()
        link.wait(2 * TIMEOUT if state == "lost" else 2 * DT)
    return link


EVENTS = {      # the table's event -> bAlive after each read it takes
    "good read": lambda link: [link.read()],
    "good read, moved": lambda link: [link.move()],
    "good read, not moved": lambda link: [link.read()],
    "good read, not moved, before tServiceTimeout": lambda link: link.wait(TIMEOUT / 2),
    "a read fails": lambda link: link.wait(6 * DT, good=False),
    "a read fails, before tServiceTimeout": lambda link: link.wait(6 * DT, good=False),
    "tServiceTimeout without a move": lambda link: link.wait(1.5 * TIMEOUT)[-1:],
}


def test_the_table_names_every_state_and_only_events_the_test_plays():
    rows = table()
    assert len(rows) >= 8 and {r["event"] for r in rows} <= set(EVENTS)
    assert {STATES[r["state"]] for r in rows} == {STATES[r["next state"]] for r in rows} == {"waiting", "alive", "lost"}


@pytest.mark.parametrize("row", table(), ids=lambda r: f"{r['state']}: {r['event']}")
def test_the_program_follows_the_row(program, row):
    link = into(program, STATES[row["state"]])
    alive = EVENTS[row["event"]](link)
    assert alive == [row["bAlive"] == "TRUE"] * len(alive), (row, alive)
    assert link.state() == STATES[row["next state"]]


def test_the_timeout_is_where_the_table_puts_it(program):
    link = into(program, "alive")
    assert all(link.wait(TIMEOUT - 4 * DT)) and not link.wait(6 * DT)[-1]
