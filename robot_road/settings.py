"""The ``robot:`` section of the service config: which real-time robot interface the I/O process answers.

Attributes of `RobotSettings`
-----------------------------
interface : ``none`` (the PLC alone, the default) or a declared interface's name (`robot_road.registry`:
    ``kuka_rsi``, ``abb_egm``)
host, port : where the service listens for the robot's UDP packets (the robot sends to this address)
peer : the robot controller's IP address; packets from any other address are dropped, counted and logged
    once. None takes any sender (a warning at start when ``host`` is not a loopback address)
realtime_priority : SCHED_FIFO priority of the I/O process, which answers the robot (0: normal scheduling);
    below the cycle's ``cycle.realtime_priority``, so the 1 ms cycle still comes first
<interface> : each interface's own settings, under its name (``robot.kuka_rsi``), validated by the model its
    declaration gives; one not given is that model's defaults (the shipped robot side's)
"""

from __future__ import annotations

import ipaddress

from pydantic import ConfigDict, Field, ValidationError, field_validator, model_validator
from pydantic_core import InitErrorDetails

from io_base.settings import PORT_MAX, PORT_MIN, is_loopback, peer_address
from stiffness.files.yaml_schema import Strict

from . import registry
from .registry import RobotSection


def _nested(e: ValidationError, *key: str) -> list[InitErrorDetails]:
    """``e``'s errors, their location under ``key`` (a sub-section's name; none for the section's own fields)."""
    return [InitErrorDetails(type=d["type"], loc=(*key, *d["loc"]), input=d["input"], ctx=d.get("ctx", {}))
            for d in e.errors()]


class RobotSettings(Strict):
    """The ``robot:`` section (module docstring). Each interface's sub-section is kept under its name and read as
    an attribute (``robot.kuka_rsi``); one the config does not give reads as its model's defaults."""

    model_config = ConfigDict(extra="allow", allow_inf_nan=False)     # the sub-sections; any other key is refused

    interface: str = "none"
    host: str = "127.0.0.1"
    port: int = Field(49152, ge=PORT_MIN, le=PORT_MAX)
    peer: str | None = None
    realtime_priority: int = Field(0, ge=0, le=98)

    @model_validator(mode="wrap")
    @classmethod
    def _sections(cls, data, handler):
        """Each key that names a declared interface validated by that interface's model; any other key that is
        not a field refused, as every strict section refuses it."""
        if not isinstance(data, dict):
            return handler(data)
        known = set(registry.names())
        errors, sections, rest = [], {}, {}
        for key, value in data.items():
            if key in cls.model_fields:
                rest[key] = value
            elif key in known:
                try:
                    sections[key] = registry.declared(key).settings.model_validate(value)
                except ValidationError as e:
                    errors += _nested(e, key)
            else:
                errors.append(InitErrorDetails(type="extra_forbidden", loc=(key,), input=value))
        try:
            model = handler(rest)
        except ValidationError as e:
            errors = _nested(e) + errors
            model = None
        if errors:
            raise ValidationError.from_exception_data(cls.__name__, errors)
        model.__pydantic_extra__.update(sections)
        return model

    @field_validator("interface")
    @classmethod
    def _declared(cls, v: str) -> str:
        if v != "none" and v not in registry.names():
            raise ValueError(f"{v!r} is no robot interface: none, {', '.join(registry.names())}")
        return v

    def __getattr__(self, name: str):
        try:
            return super().__getattr__(name)
        except AttributeError:
            if name.startswith("_") or name not in registry.names():
                raise
            return self.section_of(name)                        # a sub-section not given: its defaults

    def section_of(self, name: str) -> RobotSection:
        """Interface ``name``'s sub-section (``robot.<name>``): as given, or its model's defaults."""
        given = (self.__pydantic_extra__ or {}).get(name)
        return given if given is not None else registry.declared(name).settings()

    def defaults_warning(self) -> str | None:
        """The warning for an interface named without its own sub-section (it runs on that section's defaults,
        which are the shipped robot side's), or None."""
        if not self.enabled or self.interface in (self.__pydantic_extra__ or {}):
            return None
        return (f"robot.interface is {self.interface} but the config has no robot.{self.interface} section: its "
                f"defaults are used ({self.section.served()}); they match the shipped robot side in "
                f"cell/robot/generated/, so a robot set up otherwise needs robot.{self.interface} (docs/config.md)")

    @field_validator("peer")
    @classmethod
    def _address(cls, v: str | None) -> str | None:
        return None if v is None else str(ipaddress.ip_address(v))

    @property
    def enabled(self) -> bool:
        return self.interface != "none"

    @property
    def declaration(self) -> registry.Declaration:
        """The declaration of the interface in use."""
        return registry.declared(self.interface)

    @property
    def section(self) -> RobotSection:
        """The sub-section of the interface in use (``robot.<interface>``): given, or its model's defaults."""
        return self.section_of(self.interface)

    @property
    def cycle_ms(self) -> int:
        """The robot's cycle (ms) of the interface in use."""
        return self.section.cycle_ms

    @property
    def cartesian(self) -> bool:
        """Whether the answer carries the TCP's motion (RKorr, EGM path correction) rather than joints."""
        return self.section.cartesian_answer

    @property
    def command_element(self) -> str | None:
        """The element of the robot's packets that carries its own command word (``robot.<interface>.
        command_element``), None when the robot sends none (EGM's messages have no such field)."""
        return self.section.command_element if self.enabled else None

    def takes(self, peer_ip: str) -> bool:
        """Whether a packet from ``peer_ip`` is the robot's (``peer``)."""
        return self.peer is None or peer_address(peer_ip) == ipaddress.ip_address(self.peer)

    def served(self) -> str:
        """The start-up line's words: ``KUKA RSI on 127.0.0.1:49152 (4 ms, AK absolute)``."""
        if not self.enabled:
            return "none"
        return f"{self.declaration.title} on {self.host}:{self.port} ({self.section.served()})"

    def exposure_warning(self) -> str | None:
        """The warning for a road that listens beyond this machine and takes any sender, or None."""
        if not self.enabled or self.peer is not None or is_loopback(self.host):
            return None
        return (f"the robot road listens on {self.host}:{self.port} and robot.peer is not set: every host that "
                "reaches this UDP port can send joints and receive the correction; set robot.peer to the robot "
                "controller's address (docs/robot.md)")
