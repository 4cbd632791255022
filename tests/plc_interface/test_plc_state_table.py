"""The link supervision's state table, written once in docs/plc.md ("The block's state table"), and the HIL's
virtual PLC (`hil.virtual_plc.PlcLogic`) held to it row by row: its `link_ok` is the table's ``bAlive``.

Each row's event is played on a PlcLogic brought into the row's state, then the state it is in is checked.
Events are named by their text in the table, so a row added or reworded there fails here until it is played.
The service moves its heartbeat and cycle count together, as the rows' "moved" does.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.virtual_plc import PlcLogic
from plc_interface.register_map import RegisterMap

ROOT = Path(__file__).resolve().parents[2]
RMAP = RegisterMap.from_yaml(ROOT / "config" / "registers.yaml")
TIMEOUT, DT = 0.05, 0.004
STATES = {"waiting (after start)": "waiting", "waiting": "waiting", "alive": "alive", "lost": "lost"}


def table() -> list[dict[str, str]]:
    """The rows of the state table in docs/plc.md, column name -> cell (backticks dropped)."""
    text = (ROOT / "docs" / "plc.md").read_text()
    section = text.split("## The block's state table", 1)[1].split("\n## ", 1)[0]
    cells = [[c.strip().replace("`", "") for c in ln.strip().strip("|").split("|")]
             for ln in section.splitlines() if ln.startswith("|")]
    return [dict(zip(cells[0], row)) for row in cells[2:]]


class Link:
    """A PlcLogic and the service's values it reads, moved by the table's events."""

    def __init__(self):
        self.logic = PlcLogic(RMAP, lambda t: [0.0] * 6, service_timeout_s=TIMEOUT)
        self.names = RMAP.codecs["to_plc"].names
        self.t, self.hb, self.count = 0.0, 7, 7000

    def read(self, good: bool = True) -> bool:
        self.t += DT
        v = dict.fromkeys(self.names, 0.0) | {"heartbeat": self.hb, "cycle_count": self.count, "status_word": 1}
        self.logic.step(self.t, [v[n] for n in self.names] if good else None)
        return self.logic.link_ok

    def move(self) -> bool:
        self.hb, self.count = self.hb + 1, self.count + 1
        return self.read()

    def wait(self, seconds: float, good: bool = True) -> list[bool]:
        return [self.read(good) for _ in range(round(seconds / DT))]

    def state(self) -> str:
        """waiting: no good read yet; alive or lost: what one more good read without a move finds."""
        if self.logic.hb_change_t is None:
            return "waiting"
        return "alive" if self.read() else "lost"


def into(state: str) -> Link:
    link = Link()
    if state != "waiting":
        link.move()
        link.wait(2 * TIMEOUT if state == "lost" else DT)
    return link


EVENTS = {      # the table's event -> bAlive after each read it takes
    "good read": lambda link: [link.read()],
    "good read, moved": lambda link: [link.move()],
    "good read, not moved": lambda link: [link.read()],
    "good read, not moved, before tServiceTimeout": lambda link: link.wait(TIMEOUT / 2),
    "a read fails": lambda link: link.wait(3 * DT, good=False),
    "a read fails, before tServiceTimeout": lambda link: link.wait(3 * DT, good=False),
    "tServiceTimeout without a move": lambda link: link.wait(1.5 * TIMEOUT)[-1:],
}


def test_the_table_names_every_state_and_only_events_the_test_plays():
    rows = table()
    assert len(rows) >= 8 and {r["event"] for r in rows} <= set(EVENTS)
    assert {STATES[r["state"]] for r in rows} == {STATES[r["next state"]] for r in rows} == {"waiting", "alive", "lost"}


@pytest.mark.parametrize("row", table(), ids=lambda r: f"{r['state']}: {r['event']}")
def test_the_virtual_plc_follows_the_row(row):
    link = into(STATES[row["state"]])
    alive = EVENTS[row["event"]](link)
    assert alive == [row["bAlive"] == "TRUE"] * len(alive), (row, alive)
    assert link.state() == STATES[row["next state"]]


def test_the_timeout_is_where_the_table_puts_it():
    link = into("alive")
    assert all(link.wait(TIMEOUT - 2 * DT)) and not link.wait(3 * DT)[-1]
