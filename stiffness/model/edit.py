"""Editing a model: add a library effect at a joint or link (what `stiffcomp model add` does)."""

from __future__ import annotations

from ..effects import EFFECTS
from ..effects.axial import AxialEffect
from ..errors import ConfigError, quote
from .stiffness_model import StiffnessModel


def add_effect(model: StiffnessModel, effect: str, joint: int | None = None,
               values: dict | None = None, preload: dict | None = None) -> StiffnessModel:
    """A copy of ``model`` with the library effect ``effect`` added (parameters at their defaults).

    ``joint`` is the joint (1..6) or, for link_bending, the link; global effects take none.
    ``preload``: the model's ``preload`` entry for that joint (`stiffness.model.preload_term`; ``{"joint": J}``
    starts at the robot's masses, a diagnosis gives the start it found), replacing any there. Only an
    effect that sits at zero total torque (`AxialEffect`: backlash, the soft zone) can use one: a preload
    for any other is refused, as it would be identified from nothing.
    """
    if effect not in EFFECTS:
        raise ConfigError(f"effect {quote(effect)} is not in the library (one of {', '.join(sorted(EFFECTS))})")
    cls = EFFECTS[effect]
    entry = {"effect": effect, **(values or {})}
    if cls.per_joint:
        if joint is None:
            raise ConfigError(f"effect {effect} needs --joint (one of {', '.join(map(str, cls.joints))})")
        entry[cls.location_key] = joint
    elif joint is not None:
        raise ConfigError(f"effect {effect} is global: it takes no --joint")
    if preload is not None and not issubclass(cls, AxialEffect):
        usable = ", ".join(n for n, c in EFFECTS.items() if issubclass(c, AxialEffect))
        raise ConfigError(f"--preload: effect {effect} cannot use a preload (only an effect at the joint's total "
                          f"torque can: {usable}); {effect} does not move with the static torque")
    data = model.to_dict()
    data["name"] = f"{model.name}+{effect}" + (f"@{joint}" if joint is not None else "")
    data["effects"] = data["effects"] + [entry]
    if preload is not None:
        data["preload"] = [p for p in data.get("preload", []) if p["joint"] != preload["joint"]] + [preload]
    return StiffnessModel.from_dict(data, model.source, robot=model.robot)
