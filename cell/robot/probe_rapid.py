"""cell/robot/generated/probe/StiffCompProbe.modx: the ABB robot probes the contour it has cut and writes the probe log
(docs/part.md, "The robot probes its own part"), written from the probe plan through the RAPID writer.

What the module must do, and the maker's word for it:

* the trigger: ``SearchL \\Stop`` stops the robot at once when the probe's input goes high; the search point is
  the TCP's position at that edge (RAPID reference, SearchL), turned into joints by ``CalcJointT``;
* no string longer than 80 characters: each log line is written in pieces with ``Write .. \\NoNewLine`` (RAPID
  reference, Write), each piece measured by the writer with NumToStr's widest output;
* one ERROR handler takes every error (ERR_WHLSEARCH, ERR_SIGSUPSEARCH, a string's or the file's), closes the log
  (then complete up to the last good touch: a touch is written whole before the next search) and EXITs;
* the approach direction goes to the log in the robot's base, as the reader takes it: the work object's rotation
  (``PoseMult(uframe, oframe)``, its translation zeroed) turns it with ``PoseVect`` (RAPID reference, PoseMult,
  PoseVect), so a rotated work object is right. The work object's user frame is given in the world frame: the
  module takes the robot's base to be the world (a single robot as shipped; ADAPT otherwise).
"""

from __future__ import annotations

from .plan import PLAN_ROWS, ProbePlan
from .probe_krl import HEADER_ROW
from .rapid import RapidWriter, rapid_num

RULE = "    !" + "-" * 102
# the largest values NumToStr is given here: the touch's number, the joints (deg), the approach's components
BOUNDS = {"k": 999.0, "rTool": 500.0, "rStylus": 50.0, "vProbe": 1000.0, "latencyMs": 100.0,
          r"jHit\.robax\.rax_\d": 9999.0, r"dBase\.[xyz]": 1.0, r"PROBE_RPY\.[xyz]": 180.0}


def _head(plan: ProbePlan) -> str:
    lines = [f"    CONST num {name} := {rapid_num(getattr(plan, field))};".ljust(36) + f"! {comment}"
             for _, name, field, comment in PLAN_ROWS]
    xyz = ", ".join(rapid_num(v) for v in plan.probe_xyz_mm)
    rpy = ", ".join(rapid_num(v) for v in plan.probe_rpy_deg)
    v = rapid_num(plan.speed_mm_s)
    return f"""MODULE StiffCompProbe
{RULE}
    ! stiffcomp: the robot probes the contour it has just cut, with a touch probe in its spindle, and writes
    ! the probe log `stiffcomp part compare | learn | diagnose` read in place of a CMM's points (docs/part.md,
    ! "The robot probes its own part"; the log: docs/part_format.md, "A probe log"). Written by
    ! `stiffcomp robot-programs` (cell/robot/probe_rapid.py): change the plan there, not here.
    !
    ! Each touch starts on the contour's nominal normal, CLEARANCE short of the wall, and searches along the
    ! normal toward it at the probing speed with SearchL (RAPID Instructions reference: SearchL; \\Stop halts
    ! the robot at once when diProbe goes high, the search point is the TCP's position at that edge).
    ! CalcJointT turns the search point into the joints through the controller's own kinematics; they go to
    ! the log with the approach direction, turned from wContour's axes into the robot base's (PoseVect with
    ! the work object's rotation). No string is longer than 80 characters: each line is written in pieces.
    ! Any error (no contact, the input already high, the file) closes the log, complete up to the last good
    ! touch, and ends the program.
    !
    ! Load into the motion task (T_ROB1); on RobotWare 6 rename it StiffCompProbe.mod. The plan below matches
    ! config/hil/circle.yaml's probe section (tests/test_probe_programs.py holds them together). ADAPT before
    ! the first run: tProbe (its TCP the stylus ball's centre, as PROBE_XYZ/PROBE_RPY say in DH frame 6),
    ! wContour at the contour's centre (any rotation), diProbe, and the plan. Probe unloaded, spindle stopped,
    ! at the cut's tool orientation. Test in manual reduced speed first.
{RULE}

    ! the plan
{chr(10).join(lines)}
    ! the search speed: vProbe along the path
    CONST speeddata vSearch := [{v}, 500, 5000, 1000];
    ! the stylus ball's centre in the robot YAML's DH frame 6 (its tcp), mm and URDF roll-pitch-yaw deg
    CONST pos PROBE_XYZ := [{xyz}];
    CONST pos PROBE_RPY := [{rpy}];
    CONST string LOG_FILE := "HOME:/probe.csv";

    ! ADAPT: the probe, the contour and the probe's input
    PERS tooldata tProbe := [TRUE, [[{xyz}], [1, 0, 0, 0]], [1.2, [0, 0, 60], [1, 0, 0, 0], 0, 0, 0]];
    PERS wobjdata wContour := [FALSE, TRUE, "", [[1800, 0, 810], [1, 0, 0, 0]], [[0, 0, 0], [1, 0, 0, 0]]];
    ! ADAPT: above the contour's centre, the probe's orientation as the cut's tool's
    CONST robtarget pCentre := [[0, 0, 50], [0, 0, 1, 0], [0, 0, 0, 0], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];

    VAR iodev log;
    VAR robtarget pHit;
    VAR jointtarget jHit;
    ! the work object's rotation, and the approach direction in the robot's base
    VAR pose wRot;
    VAR pos dBase;
"""


def _main() -> str:
    return """    PROC StiffCompProbe()
        VAR num phi;
        VAR num reach;
        VAR robtarget pStart;
        VAR robtarget pEnd;

        Open LOG_FILE, log \\Write;
        LogHeader;
        wRot := PoseMult(wContour.uframe, wContour.oframe);
        wRot.trans := [0, 0, 0];
        MoveL pCentre, v200, fine, tProbe \\WObj:=wContour;
        ! the stylus centre at the nominal wall
        reach := rPath + rTool - rStylus;
        FOR k FROM 1 TO nTouches DO
            phi := maskDeg + (360 - 2 * maskDeg) * (k - 1) / (nTouches - 1);
            pStart := Offs(pCentre, (reach - CLEARANCE) * Cos(phi), (reach - CLEARANCE) * Sin(phi), -50 - depth);
            pEnd := Offs(pCentre, (reach + OVERRUN) * Cos(phi), (reach + OVERRUN) * Sin(phi), -50 - depth);
            MoveL pStart, v50, fine, tProbe \\WObj:=wContour;
            ! the search along the normal at the probing speed
            SearchL \\Stop, diProbe, pHit, pEnd, vSearch, tProbe \\WObj:=wContour;
            jHit := CalcJointT(pHit, tProbe \\WObj:=wContour);
            dBase := PoseVect(wRot, [Cos(phi), Sin(phi), 0]);
            LogTouch k;
            ! back off along the normal
            MoveL pStart, v50, fine, tProbe \\WObj:=wContour;
        ENDFOR
        MoveL pCentre, v200, fine, tProbe \\WObj:=wContour;
        Close log;
    ERROR
        ! every error: ERR_WHLSEARCH (no contact within OVERRUN), ERR_SIGSUPSEARCH (diProbe already high), a
        ! string's or the file's. The robot stands (SearchL \\Stop); the log is closed with every touch before
        ! this one complete, and the program ends.
        Close log;
        TPWrite "StiffCompProbe: stopped, error" \\Num:=ERRNO;
        EXIT;
    ENDPROC
"""


def _log() -> str:
    joints = "\n".join(f'        Write log, NumToStr(jHit.robax.rax_{i}, 6) + "," \\NoNewLine;' for i in range(1, 7))
    return f"""
    ! the probe log's '#' lines and header (docs/part_format.md, "A probe log"), each string under 80 characters;
    ! numbers through NumToStr with 6 decimals (Write's \\Num keeps fewer digits)
    PROC LogHeader()
        Write log, "# stiffcomp probe: StiffCompProbe.modx";
        Write log, "# tool_radius_mm: " + NumToStr(rTool, 6);
        Write log, "# stylus_radius_mm: " + NumToStr(rStylus, 6);
        Write log, "# probe_frame: {{xyz_mm: [" \\NoNewLine;
        Write log, NumToStr(PROBE_XYZ.x, 4) + ", " \\NoNewLine;
        Write log, NumToStr(PROBE_XYZ.y, 4) + ", " \\NoNewLine;
        Write log, NumToStr(PROBE_XYZ.z, 4) + "], rpy_deg: [" \\NoNewLine;
        Write log, NumToStr(PROBE_RPY.x, 6) + ", " \\NoNewLine;
        Write log, NumToStr(PROBE_RPY.y, 6) + ", " \\NoNewLine;
        Write log, NumToStr(PROBE_RPY.z, 6) + "]}}";
        Write log, "# probing_speed_mm_s: " + NumToStr(vProbe, 6);
        Write log, "# trigger_latency_ms: " + NumToStr(latencyMs, 6);
        Write log, "{HEADER_ROW}";
    ENDPROC

    ! one touch: the joints at the trigger and the approach direction in the robot's base, in pieces
    PROC LogTouch(num k)
        Write log, NumToStr(k, 0) + "," \\NoNewLine;
{joints}
        Write log, NumToStr(dBase.x, 6) + "," \\NoNewLine;
        Write log, NumToStr(dBase.y, 6) + "," \\NoNewLine;
        Write log, NumToStr(dBase.z, 6);
    ENDPROC
ENDMODULE"""


def probe_modx(plan: ProbePlan) -> str:
    """StiffCompProbe.modx for ``plan``."""
    return RapidWriter("StiffCompProbe.modx", BOUNDS).add(_head(plan) + "\n" + _main() + _log()).render()
