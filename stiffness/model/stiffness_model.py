"""A stiffness model: a robot plus a list of effects, read from and written to plain YAML.

Prediction (Eq. 5-7): the external wrench is transported to every DH frame with the unloaded
geometry (Eq. 4); each effect contributes twists at the sites of `stiffness.data.campaign`; the loaded chain

    0T'_k = prod_{s<k} [ E(delta_spring_s) T(s, s+1)(q) E(delta_tip_{s+1}) ]

is compared with the unloaded one. A body's deflection is its loaded position minus its unloaded
position in base axes (mm) and log(R'_k R_k^T) in base axes (deg).
"""

from __future__ import annotations

import copy
import os
from pathlib import Path
from typing import Any

import numpy as np

from ..data.campaign import Context
from ..data.measurements import Dataset
from ..effects import EFFECTS, Effect
from ..effects.joint_spring import JointSpring
from ..errors import ConfigError, quote
from ..files.yaml_schema import FlowList, dump_yaml, read_yaml, validate
from ..kinematics.robot import Robot, load_robot
from ..kinematics.spatial import log_so3, twist_transform
from ..kinematics.statics import PayloadConfig, Statics, statics_for
from ..units import M_TO_MM, RAD_TO_DEG
from .preload_term import PreloadTerm
from .prior import read_covariance

TOP_KEYS = {"name", "description", "robot", "noise", "payload", "preload", "effects", "covariance"}
DEFAULT_NOISE = {"position_mm": 0.03, "rotation_deg": 0.002}


class StiffnessModel:
    """A robot and its effects.

    Parameters
    ----------
    robot : Robot
    effects : list of Effect
    name, description : str
    robot_ref : str
        The robot file as written in the YAML (kept when the model is saved).
    noise : dict
        Expected measurement noise, ``position_mm`` and ``rotation_deg`` (weights of the fit).
    payload : PayloadConfig, optional
        What the sensor carried while the campaign was measured: with the robot's masses it gives the
        static joint torque tau_s at which backlash, nonlinear stiffness and hysteresis act.
    covariance : dict, optional
        What the campaign that identified the model told of its parameters (the YAML's ``covariance``:
        params, std_error, correlation; written by `stiffcomp fit`), the prior of a later fit such as
        `stiffcomp part learn` (`stiffness.model.prior.Prior.from_model`).
    """

    def __init__(self, robot: Robot, effects: list[Effect], name: str = "model", description: str = "",
                 robot_ref: str | None = None, noise: dict[str, float] | None = None,
                 source: str = "<model>", payload: PayloadConfig | None = None,
                 covariance: dict[str, Any] | None = None):
        self.robot = robot
        self.covariance = covariance
        self.payload = payload
        self.effects = list(effects)
        self.name = name
        self.description = description
        self.robot_ref = robot_ref
        self.noise = dict(DEFAULT_NOISE | (noise or {}))
        self.source = source
        self.check()

    # -- YAML -----------------------------------------------------------------------------------
    @classmethod
    def from_yaml(cls, path: str | Path) -> StiffnessModel:
        path = Path(path)
        if not path.exists():
            raise ConfigError(f"{path}: model file not found")
        data = read_yaml(path)
        return cls.from_dict(data, source=str(path), base_dir=path.parent)

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "<model>", base_dir: Path | None = None,
                  robot: Robot | None = None) -> StiffnessModel:
        unknown = sorted(set(data) - TOP_KEYS)
        if unknown:
            raise ConfigError(f"{source}: {unknown[0]} is not a known key (known: {', '.join(sorted(TOP_KEYS))})")
        robot_ref = data.get("robot")
        if robot is None:
            if not isinstance(robot_ref, str):
                raise ConfigError(f"{source}: robot = {quote(robot_ref)}: must name a robot YAML file "
                                  "(a path relative to the model file)")
            robot_path = (base_dir or Path(".")) / robot_ref
            if not robot_path.exists():
                raise ConfigError(f"{source}: robot = {quote(robot_ref)}: file {robot_path} not found")
            robot = load_robot(robot_path)
        noise = data.get("noise") or {}
        if not isinstance(noise, dict) or set(noise) - set(DEFAULT_NOISE):
            raise ConfigError(f"{source}: noise must be a mapping with keys {', '.join(DEFAULT_NOISE)}")
        for k, v in noise.items():
            if not isinstance(v, (int, float)) or not v > 0:
                raise ConfigError(f"{source}: noise.{k} = {quote(v)} must be a number > 0")
        payload = None
        if data.get("payload") is not None:
            if not isinstance(data["payload"], dict):
                raise ConfigError(f"{source}: payload must be a mapping with mass_kg and cog_mm")
            payload = validate(PayloadConfig, data["payload"], source, "payload")
        entries = data.get("effects")
        if not isinstance(entries, list) or not entries:
            raise ConfigError(f"{source}: effects must be a non-empty list of effect entries")
        effects = []
        for k, entry in enumerate(entries):
            where = f"{source}: effects[{k}]"
            if not isinstance(entry, dict) or "effect" not in entry:
                raise ConfigError(f"{where}: each entry needs 'effect: NAME' "
                                  f"(one of {', '.join(sorted(EFFECTS))})")
            name = entry["effect"]
            if name not in EFFECTS:
                raise ConfigError(f"{where}: effect = {quote(name)} is not in the library "
                                  f"(one of {', '.join(sorted(EFFECTS))})")
            effects.append(EFFECTS[name].from_config(entry, robot, where))
        effects += _read_preload(data.get("preload"), robot, source)
        return cls(robot, effects, str(data.get("name", Path(source).stem)), str(data.get("description", "")),
                   robot_ref, noise, source, payload, read_covariance(data.get("covariance"), source))

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"name": self.name}
        if self.description:
            out["description"] = self.description
        out["robot"] = self.robot_ref
        out["noise"] = {k: float(v) for k, v in self.noise.items()}
        if self.payload is not None:
            out["payload"] = self.payload.model_dump()
        effects, preload = [], []
        for e in self.effects:
            entry = e.to_config()
            if np.isfinite(e.std_error).any():
                entry["fit"] = {f"{p.key}_std_error": float(f"{s * p.yaml_factor:.3g}")
                                for p, s in zip(e.params, e.std_error) if np.isfinite(s)}
            (preload if isinstance(e, PreloadTerm) else effects).append(entry)
        if preload:
            out["preload"] = preload
        out["effects"] = effects
        if self.covariance is not None:
            out["covariance"] = _flow_rows(self.covariance)
        return out

    def to_yaml(self, path: str | Path, header: str = "") -> None:
        """The model as YAML at ``path``. A robot read from a file is referred to relative to ``path``'s
        folder, so the written model loads from wherever it is written."""
        d = self.to_dict()
        d["robot"] = self.robot_ref_from(Path(path).resolve().parent)
        text = dump_yaml(d, sort_keys=False, width=110)
        Path(path).write_text((header + "\n" if header else "") + text)

    def robot_ref_from(self, folder: Path) -> str | None:
        """The robot reference as seen from ``folder``: relative to it when the robot came from a file
        (absolute across drives), else the reference as read."""
        robot_file = Path(self.robot.source)
        if not robot_file.is_file():
            return self.robot_ref
        try:
            return os.path.relpath(robot_file.resolve(), folder)
        except ValueError:                      # another drive (Windows)
            return str(robot_file.resolve())

    def copy(self) -> StiffnessModel:
        """A copy through the YAML form; a model holding an effect from outside the library (a part's
        placement while learning, `stiffness.part.learn`) is copied effect by effect instead."""
        if all(EFFECTS.get(e.name) is type(e) or isinstance(e, PreloadTerm) for e in self.effects):
            return StiffnessModel.from_dict(self.to_dict(), self.source, robot=self.robot)
        return StiffnessModel(self.robot, [copy.deepcopy(e) for e in self.effects], self.name, self.description,
                              self.robot_ref, self.noise, self.source, self.payload, self.covariance)

    def check(self) -> None:
        """Reject the same effect twice at one place, or a spring component given twice."""
        seen: set[tuple[str, Any]] = set()
        comps: set[tuple[int, str]] = set()
        for e in self.effects:
            if isinstance(e, JointSpring):
                for c in e.components:
                    if (e.joint, c) in comps:
                        raise ConfigError(f"{self.source}: joint {e.joint}'s spring component {c} is given twice")
                    comps.add((e.joint, c))
                continue
            key = (e.name, e.joint)
            if key in seen:
                raise ConfigError(f"{self.source}: effect {e.label} appears twice")
            seen.add(key)

    def negative_compliances(self) -> list[str]:
        """Each compliance below zero as 'effect@joint1.key = value unit' (YAML units); none: []."""
        return [f"{e.label}.{p.key} = {v * p.yaml_factor:.4g} {p.unit}"
                for e in self.effects for p, v in zip(e.params, e.theta) if p.compliance and v < 0]

    def unphysical(self) -> str | None:
        """What makes the model impossible for a real robot, in words; None when nothing does.

        A negative compliance: the joint would deflect against the load, and a correction from it
        pushes the tool the wrong way. A fit may return one (`stiffcomp fit` shows it and can bound
        it with ``--nonnegative``); a model to compensate with must not hold one.
        """
        bad = self.negative_compliances()
        if not bad:
            return None
        return (f"{len(bad)} negative compliance(s), which no robot has (a compliance must be >= 0): "
                + "; ".join(bad))

    def require_physical(self) -> None:
        """Raise ConfigError naming the source, the effects and the keys when `unphysical`."""
        problem = self.unphysical()
        if problem:
            raise ConfigError(f"{self.source}: {problem}. Refit with `stiffcomp fit --nonnegative`, or "
                              "remove the component")

    # -- parameters -----------------------------------------------------------------------------
    @property
    def theta(self) -> np.ndarray:
        return np.concatenate([e.theta for e in self.effects]) if self.effects else np.zeros(0)

    @theta.setter
    def theta(self, value: np.ndarray) -> None:
        k = 0
        for e in self.effects:
            n = len(e.params)
            e.theta = np.array(value[k:k + n], dtype=float)
            k += n

    def param_slices(self) -> list[slice]:
        out, k = [], 0
        for e in self.effects:
            out.append(slice(k, k + len(e.params)))
            k += len(e.params)
        return out

    def param_labels(self) -> list[str]:
        return [f"{e.label}.{p.key}" for e in self.effects for p in e.params]

    def has(self, name: str, joint: int | None = None) -> bool:
        return any(e.name == name and (joint is None or e.joint == joint) for e in self.effects)

    # -- evaluation -----------------------------------------------------------------------------
    def preloads(self) -> list[tuple[int, np.ndarray, np.ndarray]]:
        """The identified static torque corrections (joint, columns, beta) (`stiffness.model.preload_term`)."""
        return [(e.joint, e.columns, e.theta) for e in self.effects if isinstance(e, PreloadTerm)]

    def statics(self) -> Statics | None:
        """tau_s(q) of this model's robot, payload and identified preload (`stiffness.kinematics.statics`); None when
        nothing weighs."""
        return statics_for(self.robot, self.payload, preloads=self.preloads())

    def context(self, data: Dataset) -> Context:
        ctx = Context(self.robot, data, self.statics())
        self.bind_preload(ctx)
        return ctx

    def bind_preload(self, ctx: Context, theta: np.ndarray | None = None) -> None:
        """Set ``ctx.preload_torque`` to the identified static torque correction at ``theta`` (the
        model's own by default), so the axial effects act at the total torque these parameters give."""
        theta = self.theta if theta is None else theta
        terms = [(e, sl) for e, sl in zip(self.effects, self.param_slices()) if isinstance(e, PreloadTerm)]
        if not terms or ctx.statics is None:
            ctx.preload_torque = None
            return
        tau = np.zeros((ctx.n_readings, 6))
        for e, sl in terms:
            tau[:, e.joint - 1] += e.correction(ctx, theta[sl])
        ctx.preload_torque = tau

    def frame_wrenches(self, ctx: Context, theta: np.ndarray | None = None) -> np.ndarray:
        """Wrenches at DH frames 0..6 after the input effects (R, 7, 6)."""
        theta = self.theta if theta is None else theta
        w = ctx.wrench_sensor
        changed = False
        for e, sl in zip(self.effects, self.param_slices()):
            if e.kind == "input":
                w = e.wrench(ctx, theta[sl], w)
                changed = True
        return ctx.wrenches_at_frames(w) if changed else ctx.frame_wrench

    def input_map(self) -> np.ndarray:
        """L (6, 6) with W_true = L W_measured: the model's input effects (e.g. sensor misalignment),
        composed in the model's order, each evaluated by its own equation on the unit wrenches.

        Input effects are linear in the wrench; the identity when the model has none. The service's
        fast path folds L into the sensor's rotation; a virtual sensor reports L^-1 W_true.
        """
        L = np.eye(6)
        for e in self.effects:
            if e.kind == "input":
                L = e.wrench(None, e.theta, L.T).T      # rows are wrenches: map each unit column
        return L

    def twists(self, ctx: Context, theta: np.ndarray | None = None) -> np.ndarray:
        """Total site twists (R, 12, 6) in m, rad."""
        theta = self.theta if theta is None else theta
        self.bind_preload(ctx, theta)
        W = self.frame_wrenches(ctx, theta)
        tw = np.zeros((ctx.n_readings, 12, 6))
        for e, sl in zip(self.effects, self.param_slices()):
            if e.kind == "site":
                tw += e.twists(ctx, theta[sl], W)
        return tw

    def predict(self, data: Dataset | Context, theta: np.ndarray | None = None,
                linear: bool = False) -> np.ndarray:
        """Predicted deflection of every row, (N, 6) in [mm, mm, mm, deg, deg, deg]."""
        ctx = data if isinstance(data, Context) else self.context(data)
        tw = self.twists(ctx, theta)
        if linear:
            return np.einsum("nsab,nsb->na", ctx.G, tw[ctx.row_reading])
        return loaded_deflection(ctx, tw)


def _flow_rows(covariance: dict[str, Any]) -> dict[str, Any]:
    """The covariance section with its correlation matrix written one row per line."""
    out = dict(covariance)
    out["correlation"] = [FlowList(row) for row in covariance["correlation"]]
    return out


def _read_preload(entries: Any, robot: Robot, source: str) -> list[PreloadTerm]:
    """The model's ``preload`` list: one entry per joint whose static torque is identified."""
    if entries is None:
        return []
    if not isinstance(entries, list):
        raise ConfigError(f"{source}: preload = {quote(entries)} must be a list of entries "
                          "(joint and the base parameters' corrections, docs/effects.md)")
    out = []
    for k, entry in enumerate(entries):
        where = f"{source}: preload[{k}]"
        if not isinstance(entry, dict):
            raise ConfigError(f"{where} = {quote(entry)} must be a mapping with 'joint'")
        out.append(PreloadTerm.from_config(entry, robot, where))
    return out


def loaded_deflection(ctx: Context, tw: np.ndarray) -> np.ndarray:
    """Compose the loaded chain from site twists (R, 12, 6) and return row deflections (N, 6)."""
    R = ctx.n_readings
    E_spring = twist_transform(tw[:, :6])
    tip = tw[:, 6:]
    E_tip = twist_transform(tip) if np.any(tip) else None
    Fp = np.empty((R, 8, 4, 4))
    Fp[:, 0] = np.eye(4)
    for s in range(1, 7):
        T = Fp[:, s - 1] @ E_spring[:, s - 1] @ ctx.A[:, s - 1]
        Fp[:, s] = T if E_tip is None else T @ E_tip[:, s - 1]
    Fp[:, 7] = Fp[:, 6] @ ctx.robot.T_flange_tcp
    F = ctx.F
    dp = (Fp[:, 1:, :3, 3] - F[:, 1:, :3, 3]) * M_TO_MM                         # (R, 7, 3)
    dr = log_so3(Fp[:, 1:, :3, :3] @ np.swapaxes(F[:, 1:, :3, :3], -1, -2)) * RAD_TO_DEG
    per_reading = np.concatenate([dp, dr], axis=-1)                         # (R, 7, 6)
    return ctx.in_row_axes(per_reading[ctx.row_reading, ctx.body])
