"""cell/robot/generated/probe/StiffCompProbe.src and .dat: the KUKA robot probes the contour it has cut and writes the probe log
(docs/part.md, "The robot probes its own part"), written from the probe plan through the KRL writer.

What the program must do, and the maker's word for it:

* the trigger: the probe is wired to a fast measurement input; the controller latches the axes at the input's edge
  into ``$AXIS_INT`` (and the Cartesian position into ``$POS_INT``) and sets ``$MEAS_PULSE[n]`` (KUKA System
  Variables, KSS 8.1-8.3: $MEAS_PULSE, $AXIS_INT, $POS_INT), whose interrupt stops the search;
* the input is armed and the interrupt switched on only once the approach has ended: a ``WAIT SEC 0`` stops the
  advance run first (the KRL writer refuses an INTERRUPT ON after a motion without it);
* each log line is written whole with ``krl_fwriteln`` (CREAD/CWRITE manual, $FCT_CALL: krl_fwriteln writes a
  line), built with SWRITE after StrClear (KSS 8.x SI, string functions): no escape sequence in any literal;
* every way out closes the log first (LOG_CLOSE), so the log is complete up to the last good touch;
* the approach direction goes to the log in the robot's root frame, as the reader takes it
  (stiffness/data/probe_log.py): the program turns the base's direction into the root's with
  ``INV_POS($ROBROOT) : $BASE`` (KSS 8.x SI, geometric operator ``:`` and INV_POS), so a rotated base is right.
"""

from __future__ import annotations

from .krl import KrlWriter, krl_real
from .plan import PLAN_ROWS, ProbePlan

HEADER_ROW = "touch,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,approach_x,approach_y,approach_z"
ATTRIBUTES = "&ACCESS RVP\n&REL 1\n&PARAM TEMPLATE = C:\\KRC\\Roboter\\Template\\vorgabe\n&PARAM EDITMASK = *"
RULE = "; " + "-" * 105
INI = """;FOLD INI
  ;FOLD BASISTECH INI
    GLOBAL INTERRUPT DECL 3 WHEN $STOPMESS==TRUE DO IR_STOPM ( )
    INTERRUPT ON 3
    BAS (#INITMOV,0 )
  ;ENDFOLD (BASISTECH INI)
;ENDFOLD (INI)"""


def _head() -> str:
    return f"""DEF StiffCompProbe( )
{RULE}
; stiffcomp: the robot probes the contour it has just cut, with a touch probe in its spindle, and writes the
; probe log `stiffcomp part compare | learn | diagnose` read in place of a CMM's points (docs/part.md,
; "The robot probes its own part"; the log: docs/part_format.md, "A probe log"). Written by
; `stiffcomp robot-programs` (cell/robot/probe_krl.py): change the plan there, not here.
;
; Each touch starts on the contour's nominal normal, clearance short of the wall, and moves along the normal
; toward it at the probing speed vProbe. The probe's trigger is wired to a fast measurement input: the
; controller latches the axes at the input's edge in $AXIS_INT (KUKA System Variables, KSS 8.1-8.3:
; $MEAS_PULSE, $AXIS_INT, $POS_INT), the interrupt stops the search and the latched axes go to the log with
; the approach direction, turned from the base's axes into the robot root's (INV_POS($ROBROOT) : $BASE).
; Each line is written whole with krl_fwriteln; every way out closes the log first.
;
; Copy StiffCompProbe.src and .dat to KRC:\\R1\\Program. ADAPT before the first run: the probe's tool
; (TOOL_DATA[2], its TCP the stylus ball's centre; probeFrame in the .dat the same in DH frame 6), BASE_DATA[2]
; at the contour's centre (any rotation: the approach is turned into the root's axes), and the plan in the
; .dat file. Probe unloaded, spindle stopped, at the cut's tool orientation. Test in T1.
{RULE}
DECL INT k
DECL REAL phi, reach
DECL E6POS pStart, pEnd
DECL STATE_T sw
DECL MODUS_T mw
"""


def _main() -> str:
    return f"""{INI}

$TOOL = TOOL_DATA[2]          ; ADAPT: the probe: its TCP the stylus ball's centre
$BASE = BASE_DATA[2]          ; ADAPT: at the contour's centre
$LOAD = LOAD_DATA[2]          ; ADAPT: the probe's load data
toRoot = INV_POS($ROBROOT) : $BASE   ; the base in the robot's root: the approach is written in the root's axes

; the fast measurement input's interrupt: declared here, so RESUME in PROBE_HIT ends SEARCH's motion
INTERRUPT DECL 10 WHEN $MEAS_PULSE[1]==TRUE DO PROBE_HIT( )   ; ADAPT: the fast measurement input the probe is wired to

mw = #SYNC
CWRITE($FCT_CALL, sw, mw, "krl_fopen", logName[], "w", logHandle)
IF (sw.RET1 <> #CMD_OK) THEN
  HALT                        ; the log cannot be written (UserFiles); nothing is open
  RETURN
ENDIF
LOG_HEADER( )

PTP {{A1 0, A2 -60, A3 90, A4 0, A5 60, A6 0}}       ; ADAPT: above the contour's centre
FOR k = 1 TO nTouches
  phi = maskDeg + (360.0 - 2.0 * maskDeg) * (k - 1) / (nTouches - 1)
  reach = rPath + rTool - rStylus                   ; the stylus centre at the nominal wall
  pStart = $POS_ACT
  pStart.X = (reach - clearance) * COS(phi)
  pStart.Y = (reach - clearance) * SIN(phi)
  pStart.Z = -depth
  pEnd = pStart
  pEnd.X = (reach + overrun) * COS(phi)
  pEnd.Y = (reach + overrun) * SIN(phi)
  $VEL.CP = 0.05              ; to the start at 50 mm/s
  LIN pStart
  touched = FALSE
  $VEL.CP = vProbe / 1000.0   ; the search along the normal at the probing speed (m/s)
  SEARCH(pEnd)
  IF NOT touched THEN
    LOG_CLOSE( )              ; the log holds every touch before this one, complete
    HALT                      ; no contact within overrun beyond the nominal wall: check the plan
    RETURN
  ENDIF
  LOG_TOUCH(k, COS(phi), SIN(phi))
  $VEL.CP = 0.05
  LIN pStart                  ; back off along the normal
ENDFOR
LOG_CLOSE( )
LIN_REL {{Z 50}}
END
"""


def _subprograms() -> str:
    return """DEF SEARCH(target:IN)
; the search move; PROBE_HIT's RESUME ends it at the trigger
DECL E6POS target
WAIT SEC 0                    ; stop the advance run: the approach to pStart has ended before the input is armed
$MEAS_PULSE[1] = FALSE        ; arm the input: its edge sets it TRUE and latches the axes (the interrupt needs it FALSE)
INTERRUPT ON 10
LIN target
WAIT SEC 0                    ; stop the advance run: RESUME must find the motion in this subprogram
INTERRUPT OFF 10
END

DEF PROBE_HIT( )
; the trigger: the axes the fast measurement input latched, then the search is abandoned
INTERRUPT OFF 10
BRAKE F
hit = $AXIS_INT
touched = TRUE
RESUME
END

DEF LOG_CLOSE( )
; every way out closes the log: it then holds every touch written so far, each line complete
DECL STATE_T sw
DECL MODUS_T mw
mw = #SYNC
CWRITE($FCT_CALL, sw, mw, "krl_fclose", logHandle)
END
"""


def _swrite_line(*calls: str) -> str:
    """One log line: the buffer cleared, the SWRITE calls (format and values) appended, the line written whole."""
    writes = "\n".join(f"SWRITE(logLine[], sw, ofs, {c})" for c in calls)
    return f"""ok = StrClear(logLine[])
ofs = 0
{writes}
CWRITE($FCT_CALL, sw, mw, "krl_fwriteln", logHandle, logLine[])"""


def _log_header() -> str:
    numbers = [_swrite_line(f'"# {key}: %.6f", {name}') for key, name in (
        ("tool_radius_mm", "rTool"), ("stylus_radius_mm", "rStylus"))]
    frame = _swrite_line('"# probe_frame: {xyz_mm: [%.4f, %.4f, %.4f], ", probeFrame.X, probeFrame.Y, probeFrame.Z',
                         '"rpy_deg: [%.6f, %.6f, %.6f]}", probeFrame.C, probeFrame.B, probeFrame.A')
    timing = [_swrite_line(f'"# {key}: %.6f", {name}') for key, name in (
        ("probing_speed_mm_s", "vProbe"), ("trigger_latency_ms", "latencyMs"))]
    lines = "\n".join([*numbers, frame, *timing])
    return f"""DEF LOG_HEADER( )
; the probe log's '#' lines and header (docs/part_format.md, "A probe log"); URDF roll-pitch-yaw is KUKA's C, B, A
DECL STATE_T sw
DECL MODUS_T mw
DECL INT ofs
DECL BOOL ok
mw = #SYNC
CWRITE($FCT_CALL, sw, mw, "krl_fwriteln", logHandle, "# stiffcomp probe: StiffCompProbe.src")
{lines}
CWRITE($FCT_CALL, sw, mw, "krl_fwriteln", logHandle, "{HEADER_ROW}")
END
"""


def _log_touch() -> str:
    return f"""DEF LOG_TOUCH(k:IN, dx:IN, dy:IN)
; one touch: the latched axes and the approach direction, turned from the base's axes into the robot root's
DECL INT k, ofs
DECL REAL dx, dy, ax, ay, az
DECL FRAME tip
DECL STATE_T sw
DECL MODUS_T mw
DECL BOOL ok
mw = #SYNC
tip = $NULLFRAME
tip.X = dx
tip.Y = dy
tip = toRoot : tip
ax = tip.X - toRoot.X
ay = tip.Y - toRoot.Y
az = tip.Z - toRoot.Z
{_swrite_line('"%d,%.6f,%.6f,%.6f,", k, hit.A1, hit.A2, hit.A3', '"%.6f,%.6f,%.6f,", hit.A4, hit.A5, hit.A6',
              '"%.6f,%.6f,%.6f", ax, ay, az')}
END
"""


def probe_src() -> str:
    """StiffCompProbe.src: the program, the same for every plan (the plan is the .dat's)."""
    parts = [_head(), _main(), _subprograms(), _log_header(), _log_touch()]
    return KrlWriter("StiffCompProbe.src").add(ATTRIBUTES, "\n\n".join(p.rstrip("\n") for p in parts)).render()


def probe_dat(plan: ProbePlan) -> str:
    """StiffCompProbe.dat: the plan's values."""
    x, y, z = (krl_real(v) for v in plan.probe_xyz_mm)
    roll, pitch, yaw = (krl_real(v) for v in plan.probe_rpy_deg)
    decls = []
    for name, _, field, comment in PLAN_ROWS:
        value = getattr(plan, field)
        literal = f"INT {name}={value}" if isinstance(value, int) else f"REAL {name}={krl_real(value)}"
        decls.append(f"DECL {literal}".ljust(32) + f"; {comment}")
    frame = f"{{X {x},Y {y},Z {z},A {yaw},B {pitch},C {roll}}}"
    text = f"""&ACCESS RVP
&REL 1
DEFDAT StiffCompProbe
{RULE}
; stiffcomp: the probing plan of StiffCompProbe.src (docs/part.md, "The robot probes its own part"), written by
; `stiffcomp robot-programs` from config/hil/circle.yaml's probe section, the HIL's virtual probe of the same
; plan, and the robot YAML's tcp (tests/test_probe_programs.py holds them together). ADAPT them to your
; contour and probe.
{RULE}
{chr(10).join(decls)}
DECL FRAME probeFrame={frame}   ; the stylus ball's centre in the robot YAML's DH frame 6 (its tcp)
DECL CHAR logName[12]
logName[]="probe.csv"           ; written to C:\\KRC\\ROBOTER\\UserFiles

DECL AXIS hit={{A1 0.0,A2 0.0,A3 0.0,A4 0.0,A5 0.0,A6 0.0}}     ; the axes latched at the last trigger
DECL BOOL touched=FALSE
DECL INT logHandle=0
DECL FRAME toRoot={{X 0.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0}}   ; $BASE in the robot's root frame
DECL CHAR logLine[160]           ; one line of the log, built with SWRITE
ENDDAT"""
    return KrlWriter("StiffCompProbe.dat").add(text).render()
