"""cell/robot/generated/abb_egm/StiffCompEgm.modx, StiffCompMoc.cfg and StiffCompUdpuc.cfg: the ABB side of the EGM road, written
from the service config (its ``robot``, ``limits`` and ``faults`` sections) through the RAPID writer.

The settings and whose word they rest on (docs/robot.md, "ABB EGM", gives the same with what each costs):

* ``\\MaxPosDeviation`` of EGMActJoint: the largest deviation from the starting point EGM accepts; for a joint
  instruction in degrees (ABB, *Application manual - Externally Guided Motion*, 3HAC073318-001 (RobotWare 7),
  EGMActJoint, as rpiRobotics/abb_motion_program_exec documents the argument; ABB's text was not reachable here).
  Public programs pass 1000, i.e. no limit in practice; the shipped 1 degree is a deliberate guard twice above the service's
  ``limits.max_correction_deg`` (0.5), and the writer refuses one at or below that limit.
* External Motion Interface Data (MOC.cfg, type EXT_MOTION_DATA): the parameters the EGM manual lists (Name,
  Level, Do Not Restart After Motors Off, Ramp Time, Proportional Position Gain, Low Pass Filter Bandwidth), spelt
  as controllers save them: ``-name``, ``-ext_motion_level``, ``-do_not_restart_after_motors_off``, ``-ramp_time``,
  ``-ext_motion_Kp``, ``-ext_motion_filter_bandwidth`` under ``EXT_MOTION_DATA:`` (saved MOC.cfg files in
  rpiRobotics/abb_motion_program_exec, robot/config_params_egm/MOC.cfg, and panin-anan/abb_SAMXL_Grinding_RAPID,
  SYSPAR/MOC.cfg). Levels: 0 raw, 1 filtering (ros-industrial/abb_librws issue 72), 2 path correction (the
  ``path_corr`` profile of the same saved MOC.cfg). ABB's own text for the codes was not reachable here.
* the UDP unit (SIO.cfg, COM_TRP, RobotWare 6's Transmission Protocol): ``-Name``, ``-Type "UDPUC"``,
  ``-PhyChannel ""``, ``-RemoteAdress`` (RobotWare's spelling), ``-RemotePortNumber``, as controllers save a UDPUC
  unit (SYSPAR/SIO.cfg of panin-anan/abb_SAMXL_Grinding_RAPID and joseballester/abb-rapidserver: the empty
  PhyChannel included).
"""

from __future__ import annotations

from robot_road.settings import RobotSettings
from stiffness.errors import ConfigError

from .rapid import RapidWriter, rapid_num

MAX_DEV_DEG = 1.0
JOINT_DEFAULT_MS, PATH_DEFAULT_MS = 4, 48
RULE = "    !" + "-" * 102


def _consts(robot: RobotSettings, max_correction_deg: float, timeout_ms: float) -> str:
    if MAX_DEV_DEG <= max_correction_deg:
        raise ConfigError(f"EGMActJoint's \\MaxPosDeviation {MAX_DEV_DEG:g} deg must be above limits."
                          f"max_correction_deg {max_correction_deg:g}: EGM would stop the largest correction")
    e = robot.abb_egm
    joint_ms = e.cycle_ms if e.mode == "joint" else JOINT_DEFAULT_MS
    path_ms = e.cycle_ms if e.mode == "path" else PATH_DEFAULT_MS
    timeout_s = rapid_num(round(timeout_ms / 1000.0, 3)) if timeout_ms > 0 else "0.2"
    return f"""    ! the UDP unit StiffCompUdpuc.cfg defines (its -Name)
    CONST string UC_DEVICE := "StiffComp";
    ! the External Motion Interface Data profiles StiffCompMoc.cfg defines
    CONST string EXT_JOINT := "StiffCompJoint";
    CONST string EXT_PATH := "StiffCompPath";
    ! the cycle the controller reads stiffcomp's answers at (robot.abb_egm.cycle_ms of the mode in use):
    ! multiples of 4 ms in joint mode, of 24 ms in path mode
    CONST num JOINT_SAMPLE_MS := {joint_ms};
    CONST num PATH_SAMPLE_MS := {path_ms};
    ! seconds without an answer before EGM raises ERR_UDPUC_COMM (faults.plc_heartbeat_timeout_ms)
    CONST num COMM_TIMEOUT_S := {timeout_s};
    ! joint mode: the largest deviation from the starting fine point EGM accepts, degrees for a joint
    ! (EGM manual, EGMActJoint \\MaxPosDeviation; programs often pass 1000): a guard above limits.max_correction_deg
    CONST num MAX_DEV_DEG := {rapid_num(MAX_DEV_DEG)};
    ! joint mode: each joint has converged within this band (deg)
    CONST egm_minmax JOINT_BAND := [-0.1, 0.1];
"""


HEAD = f"""MODULE StiffCompEgm
{RULE}
    ! stiffcomp: the stiffness correction through EGM (docs/robot.md, "ABB EGM"). Written by
    ! `stiffcomp robot-programs` (cell/robot/egm.py) from the service config.
    !
    ! Needs the RobotWare option Externally Guided Motion, the UDP unit of StiffCompUdpuc.cfg and the two
    ! profiles of StiffCompMoc.cfg. Load the module into the motion task (T_ROB1); on RobotWare 6 rename it
    ! to StiffCompEgm.mod. It matches config/robot_abb_egm.yaml (tests/test_robot_files.py holds them).
    !
    ! Two ways in, one per robot.abb_egm.mode:
    !   StiffCompCut   path mode: EGMMoveL/EGMMoveC, the programmed cut with stiffcomp's path correction.
    !                  EGM corrects only across the path (the path frame's y and z; x is the motion).
    !   StiffCompHold  joint mode: position guidance at one fine point, e.g. a drilling or plunging pose
    !                  held under load; all six joints are corrected. No move instruction runs meanwhile.
    !
    ! ADAPT before the first run: the tool, the work object, the points and the speeds. Test in manual
    ! reduced speed first.
{RULE}

"""

def _handler(what: str) -> str:
    """The ERROR handler of an EGM routine: stiffcomp silent for COMM_TIMEOUT_S stops it; any other error goes up."""
    return f"""    ERROR
        IF ERRNO = ERR_UDPUC_COMM THEN
            ! stiffcomp stayed silent for COMM_TIMEOUT_S: the {what} is not corrected
            TPWrite "StiffComp: no EGM answer from the service; the {what} stopped";
            EGMReset egmId;
            Stop;
            RETURN;
        ENDIF
        ! any other error goes to the caller
        RAISE;
    ENDPROC"""


BODY = """
    ! ADAPT: the spindle and the part
    PERS tooldata tSpindle := [TRUE, [[0, 0, 305], [1, 0, 0, 0]], [14.2, [0.4, -1.1, 131], [1, 0, 0, 0], 0, 0, 0]];
    PERS wobjdata wPart := [FALSE, TRUE, "", [[1200, 0, 600], [1, 0, 0, 0]], [[0, 0, 0], [1, 0, 0, 0]]];
    ! ADAPT: the cut (the tool's z axis down into the part)
    CONST robtarget pAbove := [[0, 0, 50], [0, 0, 1, 0], [0, 0, 0, 0], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];
    CONST robtarget pPlunge := [[0, 0, -2], [0, 0, 1, 0], [0, 0, 0, 0], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];
    CONST robtarget pSlot := [[100, 0, -2], [0, 0, 1, 0], [0, 0, 0, 0], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];
    CONST robtarget pArcVia := [[150, 50, -2], [0, 0, 1, 0], [0, 0, 0, 0], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];
    CONST robtarget pArcEnd := [[100, 100, -2], [0, 0, 1, 0], [0, 0, 0, 0], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];
    CONST robtarget pOut := [[100, 100, 50], [0, 0, 1, 0], [0, 0, 0, 0], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];
    ! ADAPT: the feed
    CONST speeddata vFeed := [20, 50, 5000, 1000];

    VAR egmident egmId;

    ! path mode (robot.abb_egm.mode: path): the cut with path correction
    PROC StiffCompCut()
        MoveL pAbove, v200, fine, tSpindle \\WObj:=wPart;
        MoveL pPlunge, v20, fine, tSpindle \\WObj:=wPart;
        ! EGM path correction starts and ends in a fine point
        EGMReset egmId;
        EGMGetId egmId;
        ! \\APTR: the correction applies at the point the tool is at now (not a look-ahead sensor)
        EGMSetupUC ROB_1, egmId, EXT_PATH, UC_DEVICE \\PathCorr \\APTR \\CommTimeout:=COMM_TIMEOUT_S;
        ! the sensor frame is the tool frame: stiffcomp's correction is the TCP's
        EGMActMove egmId, tSpindle.tframe \\SampleRate:=PATH_SAMPLE_MS;
        EGMMoveL egmId, pSlot, vFeed, z1, tSpindle \\WObj:=wPart;
        EGMMoveC egmId, pArcVia, pArcEnd, vFeed, fine, tSpindle \\WObj:=wPart;
        EGMReset egmId;
        MoveL pOut, v200, fine, tSpindle \\WObj:=wPart;
{handler_cut}

    ! joint mode (robot.abb_egm.mode: joint): hold the fine point pPlunge for holdTime seconds while
    ! stiffcomp corrects all six joints
    PROC StiffCompHold(num holdTime)
        MoveL pPlunge, v20, fine, tSpindle \\WObj:=wPart;
        EGMReset egmId;
        EGMGetId egmId;
        EGMSetupUC ROB_1, egmId, EXT_JOINT, UC_DEVICE \\Joint \\CommTimeout:=COMM_TIMEOUT_S;
        EGMActJoint egmId \\Tool:=tSpindle \\WObj:=wPart \\J1:=JOINT_BAND \\J2:=JOINT_BAND \\J3:=JOINT_BAND
            \\J4:=JOINT_BAND \\J5:=JOINT_BAND \\J6:=JOINT_BAND \\SampleRate:=JOINT_SAMPLE_MS
            \\MaxPosDeviation:=MAX_DEV_DEG;
        ! returns once the joints have stayed within JOINT_BAND of stiffcomp's target for holdTime;
        ! EGM_STOP_RAMP_DOWN then ramps back to the programmed point
        EGMRunJoint egmId, EGM_STOP_RAMP_DOWN \\J1 \\J2 \\J3 \\J4 \\J5 \\J6 \\CondTime:=holdTime
            \\RampInTime:=0.1 \\RampOutTime:=0.2;
        EGMReset egmId;
        MoveL pAbove, v200, fine, tSpindle \\WObj:=wPart;
{handler_hold}
ENDMODULE"""


def egm_modx(robot: RobotSettings, max_correction_deg: float, timeout_ms: float) -> str:
    """StiffCompEgm.modx for the config's mode, sample rate, the service's correction limit and its timeout."""
    body = BODY.replace("{handler_cut}", _handler("cut")).replace("{handler_hold}", _handler("hold"))
    return RapidWriter("StiffCompEgm.modx").add(HEAD + _consts(robot, max_correction_deg, timeout_ms) + body).render()


def moc_cfg() -> str:
    """StiffCompMoc.cfg: the two External Motion Interface Data profiles the module names."""
    return """MOC:CFG_1.0:6:0::
#
# stiffcomp: the two External Motion Interface Data profiles StiffCompEgm.modx names in EGMSetupUC
# (docs/robot.md, "ABB EGM"). Written by `stiffcomp robot-programs` (cell/robot/egm.py). Load this file,
# StiffCompMoc.cfg, into the Motion topic ("Load parameters if no duplicates" keeps your other Motion
# parameters), then restart the controller.
#
# StiffCompJoint: joint mode (EGMActJoint, EGMRunJoint). Level 1 filters the correction (0: raw, which
#   needs a low-pass of its own against vibration). ADAPT ramp time, gain and bandwidth to the robot.
# StiffCompPath: path mode (EGMActMove, EGMMoveL/EGMMoveC). Level 2 is the path level; without a
#   profile at that level the path correction stops with event 50452.
# The attribute names and level codes are those of MOC.cfg files saved by controllers (docs/robot.md, "ABB EGM",
# names them); compare once with a profile saved from RobotStudio's configuration editor of your RobotWare.
#
EXT_MOTION_DATA:

      -name "StiffCompJoint" -ext_motion_level 1 -do_not_restart_after_motors_off\\
      -ramp_time 0.2 -ext_motion_Kp 5 -ext_motion_filter_bandwidth 20

      -name "StiffCompPath" -ext_motion_level 2 -do_not_restart_after_motors_off
"""


def udpuc_cfg(robot: RobotSettings) -> str:
    """StiffCompUdpuc.cfg: the UDP unit EGM sends to, at the config's address and port."""
    return f"""SIO:CFG_1.0:6:1::
#
# stiffcomp: the UDP unit EGM sends to (docs/robot.md, "ABB EGM"). Written by `stiffcomp robot-programs`
# (cell/robot/egm.py). Load it with RobotStudio (Controller tab, Configuration, Load Parameters, "Load
# parameters and replace duplicates") or on the FlexPendant (Control Panel, Configuration, File, Load
# Parameters), then restart the controller.
# It matches config/robot_abb_egm.yaml; tests/test_robot_files.py holds the two together.
#
# Name: the unit StiffCompEgm.modx names in EGMSetupUC.
# RemoteAdress (RobotWare spells it so): ADAPT to the address of the PC running stiffcomp (robot.host),
#   on the network of the controller's port that carries EGM.
# RemotePortNumber: the UDP port stiffcomp listens on (robot.port).
# No local port: stiffcomp answers to the port each packet comes from. PhyChannel stays empty, as a
#   controller saves a UDP unit.
# This file is in RobotWare 6's format (topic Communication, type Transmission Protocol). On RobotWare 7
# enter the same four values under Communication, UDP Unicast Device.
#
COM_TRP:

      -Name "StiffComp" -Type "UDPUC" -PhyChannel "" -RemoteAdress "{robot.host}"\\
      -RemotePortNumber {robot.port}
"""
