"""What the I/O process serves, from the service config: the PLC role, ADS, monitoring and the robot road."""

from __future__ import annotations

from io_base.listen import Listener
from io_process.server import IoSettings
from robot_road.road import RoadSettings


def io_settings(cfg, robot) -> IoSettings | None:
    """The I/O process's settings (paths resolved), or None when it has nothing to serve. ``robot``: the model's
    robot (its joint limits, and its kinematics for a Cartesian answer); None only for settings that are read,
    not served (`io_listeners`)."""
    if cfg.plc.role == "none" and not cfg.ads.enabled and not cfg.monitoring.enabled and not cfg.robot.enabled:
        return None
    tls = cfg.plc.tls.model_copy(update={k: str(cfg.resolve(v)) for k, v in cfg.plc.tls.files().items()})
    return IoSettings(plc=cfg.plc.model_copy(update={"tls": tls}), ads=cfg.ads, monitoring=cfg.monitoring,
                      avoid_cpu=cfg.cycle.cpu, robot=road_settings(cfg, robot))


def io_listeners(cfg) -> list[Listener]:
    """Every address the I/O process would listen on for ``cfg``, in the order it starts them: what its own
    settings declare (`IoSettings.listeners`), built without the model (`stiffcomp run --check`)."""
    settings = io_settings(cfg, None)
    return [] if settings is None else settings.listeners()


def road_settings(cfg, robot) -> RoadSettings | None:
    """The robot road's settings (None: ``robot.interface: none``). Without a PLC (``plc.role: none``) the robot's
    packets carry the command word and the heartbeat; a silence of ``faults.plc_heartbeat_timeout_ms`` (0: 100 ms)
    begins a new session, whose answers ramp in over ``limits.fault_ramp_s``. ``robot``: the model's robot,
    for the joint limits and a Cartesian answer; None leaves the road's defaults (settings to read, not to
    serve)."""
    if not cfg.robot.enabled:
        return None
    hb = cfg.faults.plc_heartbeat_timeout_ms
    model = {} if robot is None else {"limits_deg": [(float(lo), float(hi)) for lo, hi in robot.limits_deg],
                                      "robot_file": str(robot.source) if cfg.robot.cartesian else None}
    return RoadSettings(cfg.robot, owns_commands=cfg.plc.role == "none", enable_on_start=cfg.plc.enable_on_start,
                        silence_s=hb / 1000.0 if hb > 0 else 0.1, ramp_s=cfg.limits.fault_ramp_s, **model)
