"""The robot interfaces the road can answer, each declared once: its name, its settings, its road-side class and
the HIL's virtual controller of it. Everything else (the config's ``robot.interface`` and sub-section, the road,
the HIL, ``stiffcomp hil --robot-interface``, ``stiffcomp run --check``) reads the declaration.

An interface is one module that calls `declare` when imported (as python-can finds a backend by its name):

* the built-in ones are named in `BUILT_IN` and imported when first asked for, so a config that names none of
  them loads neither;
* another package's interface is found through its entry point in the group ``stiffcomp.robot_interfaces``
  (the entry point names the module), or declared by importing its module.

A declared interface's settings are a sub-section of ``robot:`` under its name (``robot.kuka_rsi``), validated by
its own model, which answers what the road asks of every robot (`RobotSection`).
"""

from __future__ import annotations

import functools
import importlib
from dataclasses import dataclass
from importlib.metadata import entry_points
from typing import Protocol, runtime_checkable

ENTRY_POINTS = "stiffcomp.robot_interfaces"
BUILT_IN = {"kuka_rsi": "robot_road.kuka_rsi", "abb_egm": "robot_road.abb_egm"}


@runtime_checkable
class RobotSection(Protocol):
    """What the road asks of every interface's sub-section of ``robot:``.

    Attributes
    ----------
    cycle_ms : the robot's cycle (ms): a packet is answered within it, and its stamps rise by it
    cartesian_answer : whether the answer carries the TCP's motion rather than joints (the road then needs the
        model's robot)
    command_element : the setting that names the element of the robot's packets carrying its own command word,
        None when the robot sends none (the road then enables as ``plc.enable_on_start`` says)
    """

    cycle_ms: int

    @property
    def cartesian_answer(self) -> bool: ...

    @property
    def command_element(self) -> str | None: ...

    def served(self) -> str:
        """The start-up line's words for this section: ``4 ms, AK absolute``."""

    def follows_no_path(self) -> str | None:
        """Why the robot, set so, runs no programmed path (None: the interface corrects the path it runs)."""


@dataclass(frozen=True)
class Declaration:
    """One robot interface.

    Attributes
    ----------
    name : ``robot.interface``'s value, and the key of its sub-section of ``robot:``
    title : its maker's name for it, as logs and the start-up line say it (``KUKA RSI``)
    settings : the model of its sub-section (a `RobotSection`; its defaults are the shipped robot side's)
    road : the road's side of it (a `robot_road.interface.RobotInterface`)
    controller : ``"module:Class"`` of the HIL's virtual controller of it (a `hil.virtual_robot.RobotController`),
        imported only by the HIL
    """

    name: str
    title: str
    settings: type
    road: type
    controller: str


_DECLARED: dict[str, Declaration] = {}


def declare(declaration: Declaration) -> Declaration:
    """Make ``declaration`` known by its name (a module's own declaration, run when it is imported)."""
    if declaration.name == "none":
        raise ValueError("'none' is robot.interface's word for no robot road, not an interface's name")
    _DECLARED[declaration.name] = declaration
    return declaration


@functools.cache
def _entry_points() -> dict[str, str]:
    """The interfaces installed packages declare (read once per process: a package installed while it runs is
    found by the next one)."""
    return {ep.name: ep.value for ep in entry_points(group=ENTRY_POINTS)}


def names() -> list[str]:
    """Every interface that can be asked for: the built-in ones, those of installed packages, those declared."""
    return sorted(set(BUILT_IN) | set(_entry_points()) | set(_DECLARED))


def declared(name: str) -> Declaration:
    """The declaration of interface ``name``, its module imported when it is not yet; KeyError names the ones
    there are."""
    if name not in _DECLARED:
        module = BUILT_IN.get(name) or _entry_points().get(name)
        if module is not None:
            importlib.import_module(module.partition(":")[0])
    if name not in _DECLARED:
        raise KeyError(f"no robot interface {name!r}; there are {', '.join(names())}")
    return _DECLARED[name]


def load(spec: str):
    """The object a ``"module:name"`` string names (a declaration's virtual controller)."""
    module, _, attr = spec.partition(":")
    return getattr(importlib.import_module(module), attr)
