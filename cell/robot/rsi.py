"""cell/robot/generated/kuka_rsi/StiffCompCut.src and StiffComp.xml: the KUKA side of the RSI road, written from the service
config's ``robot`` section (robot_road.settings.RobotSettings) through the KRL writer.

Which sensor mode the cut runs in is the maker's: KUKA.RobotSensorInterface (KST RSI 3.3, "RSI_ON"; RSI 4.x the
same) gives RSI_ON a correction mode (#ABSOLUTE, #RELATIVE) and a sensor mode: ``#IPO_FAST``, 4 ms and the default,
in which the correction acts only in sensor-guided motion (``RSI_MOVECORR()``, which moves the robot by the sensor
alone: ros-industrial's kuka_rsi_hw_interface and every third-party RSI driver run it so), and ``#IPO``, 12 ms, in
which the correction is laid over programmed LIN, CIRC and PTP motions (path correction). stiffcomp corrects a
programmed cut, so the cut runs under ``RSI_ON(#ABSOLUTE, #IPO)`` at 12 ms, and the KRL writer refuses a programmed
motion under #IPO_FAST. The service must then be told the robot's 12 ms cycle (``robot.kuka_rsi.cycle_ms: 12``):
``config_notes`` says so when the config says otherwise. KUKA's sentence on the modes was not readable from this
project's machines; #IPO corrects programmed motion in any reading (docs/robot.md, "Which sensor mode").
"""

from __future__ import annotations

from robot_road.settings import RobotSettings

from .krl import KrlWriter
from .probe_krl import ATTRIBUTES, RULE

CUT_CYCLE_MS = 12            # #IPO: the only sensor mode that corrects programmed motions
CUT_SENSOR_MODE = "IPO"


def config_notes(robot: RobotSettings) -> list[str]:
    """What the config must change for the cut the program runs (empty when nothing)."""
    if robot.kuka_rsi.cycle_ms != CUT_CYCLE_MS:
        return [(f"robot.kuka_rsi.cycle_ms is {robot.kuka_rsi.cycle_ms}, but StiffCompCut.src runs RSI_ON(.., "
                 f"#{CUT_SENSOR_MODE}) at {CUT_CYCLE_MS} ms: KUKA.RSI corrects programmed motions only in #IPO "
                 f"(KST RSI 3.3, RSI_ON); set robot.kuka_rsi.cycle_ms: {CUT_CYCLE_MS}")]
    return []


def cut_src(robot: RobotSettings) -> str:
    """StiffCompCut.src: the cut with the correction laid over it (#IPO) in the config's correction mode."""
    mode = robot.kuka_rsi.correction.upper()
    body = f"""DEF StiffCompCut( )
{RULE}
; stiffcomp: a cut with the stiffness correction switched on around it (docs/robot.md, "KUKA RSI"). Written by
; `stiffcomp robot-programs` (cell/robot/rsi.py) from the service config's robot section.
;
; Copy to KRC:\\R1\\Program. The RSI context "StiffComp" (RSI 4: StiffComp.rsix, made in RSI Visual as
; docs/robot.md describes; RSI 3.x: StiffComp.rsi with .rsi.xml and .rsi.diagram) and its ETHERNET
; object's StiffComp.xml go to C:\\KRC\\ROBOTER\\Config\\User\\Common\\SensorInterface.
;
; The sensor mode is #IPO (12 ms): KUKA.RobotSensorInterface lays a correction over programmed motions only in
; #IPO; #IPO_FAST (4 ms) corrects only sensor-guided motion, RSI_MOVECORR() (KST RSI 3.3, RSI_ON). The service's
; robot.kuka_rsi.cycle_ms must be 12.
;
; stiffcomp answers every packet from the moment it runs: start the service before this program reaches
; RSI_ON. The robot stops when the ETHERNET object's Timeout count of late answers is reached.
;
; ADAPT before the first run: the tool and base (TOOL_DATA[1], BASE_DATA[1]), the points of the cut,
; the feed, and the AXISCORR (or POSCORR) limits in the context. Test in T1 at low override first.
{RULE}
DECL INT ret        ; the RSI functions' return value
DECL INT contId     ; the RSI context's id

;FOLD INI
  ;FOLD BASISTECH INI
    GLOBAL INTERRUPT DECL 3 WHEN $STOPMESS==TRUE DO IR_STOPM ( )
    INTERRUPT ON 3
    BAS (#INITMOV,0 )
  ;ENDFOLD (BASISTECH INI)
  ;FOLD USER INI
    ;Make your modifications here
  ;ENDFOLD (USER INI)
;ENDFOLD (INI)

$TOOL = TOOL_DATA[1]          ; ADAPT: the spindle's tool frame
$BASE = BASE_DATA[1]          ; ADAPT: the part's base frame
$LOAD = LOAD_DATA[1]          ; ADAPT: the spindle's load data

; approach, without correction
PTP {{A1 0, A2 -90, A3 90, A4 0, A5 45, A6 0}}
LIN {{X 0, Y 0, Z 50, A 0, B 0, C 180}}              ; ADAPT: above the start of the cut

; the context: StiffComp (RSI 4 finds StiffComp.rsix; on RSI 3.x write "StiffComp.rsi")
ret = RSI_CREATE("StiffComp", contId, TRUE)
IF (ret <> RSIOK) THEN
  HALT                        ; the context or StiffComp.xml is not in the SensorInterface folder
ENDIF

; {robot.kuka_rsi.correction} correction (robot.kuka_rsi.correction: {robot.kuka_rsi.correction}). #IPO: the 12 ms
; cycle (robot.kuka_rsi.cycle_ms: 12), the sensor mode in which RSI corrects programmed motions
ret = RSI_ON(#{mode}, #{CUT_SENSOR_MODE})
IF (ret <> RSIOK) THEN
  HALT                        ; RSI could not start the context (an object that cannot bind, the network)
ENDIF

; OPTIONAL command element (StiffComp.xml's StiffCmd, robot.kuka_rsi.command_element: StiffCmd):
; $SEN_PINT[1] = 1            ; bit 0: enable the correction for the cut

; the cut: the correction is laid over these programmed motions
$VEL.CP = 0.02                ; ADAPT: the feed, m/s
LIN {{X 0, Y 0, Z -2, A 0, B 0, C 180}}              ; plunge
LIN {{X 100, Y 0, Z -2, A 0, B 0, C 180}} C_DIS      ; a slot along X
CIRC {{X 150, Y 50, Z -2, A 0, B 0, C 180}}, {{X 100, Y 100, Z -2, A 0, B 0, C 180}}
LIN {{X 100, Y 100, Z 50, A 0, B 0, C 180}}          ; retract
WAIT SEC 0                    ; stop the advance run: the motions end before the correction is switched off;
                              ; out of the material the wrench, and with it the correction, is back at zero

; $SEN_PINT[1] = 0            ; OPTIONAL: disable; the service ramps its correction to zero
ret = RSI_OFF()
IF (ret <> RSIOK) THEN
  HALT
ENDIF
ret = RSI_DELETE(contId)

PTP {{A1 0, A2 -90, A3 90, A4 0, A5 45, A6 0}}
END"""
    return KrlWriter("StiffCompCut.src").add(ATTRIBUTES, body).render()


def _send(robot: RobotSettings) -> str:
    k = robot.kuka_rsi
    extra = [e for e in (k.command_element, k.heartbeat_element, k.payload_element) if e is not None]
    if extra:
        options = "\n".join(f'         <ELEMENT TAG="{tag}" TYPE="LONG" INDX="{i}" />' for i, tag in enumerate(extra, 1))
    else:
        options = '         <!-- <ELEMENT TAG="StiffCmd" TYPE="LONG" INDX="1" /> -->'
    return f"""   <SEND>
      <ELEMENTS>
         <!-- INTERNAL elements are the robot's own values; the packet always carries <IPOC> as well -->
         <ELEMENT TAG="DEF_RIst" TYPE="DOUBLE" INDX="INTERNAL" />   <!-- Cartesian actual (not read; for a capture) -->
         <ELEMENT TAG="DEF_AIPos" TYPE="DOUBLE" INDX="INTERNAL" />  <!-- axes' actual positions (deg) -->
         <ELEMENT TAG="DEF_ASPos" TYPE="DOUBLE" INDX="INTERNAL" />  <!-- axes' setpoints: the joints the cycle uses (robot.kuka_rsi.joints) -->
         <ELEMENT TAG="DEF_Delay" TYPE="LONG" INDX="INTERNAL" />    <!-- the robot's count of late answers -->
         <!-- OPTIONAL: the command word from the KRL program (robot.kuka_rsi.command_element: StiffCmd). -->
         <!-- Place a SEN_PINT object (Index 1) in the context, wire its output to the ETHERNET object's input 1 -->
         <!-- and remove the comment marks around the next line; the KRL program then writes $SEN_PINT[1] -->
         <!-- (bit 0 enable, bit 1 tare, bit 2 reset), and its enable bit alone switches the correction. -->
{options}
      </ELEMENTS>
   </SEND>"""


def ethernet_xml(robot: RobotSettings) -> str:
    """StiffComp.xml: the ETHERNET object's configuration for the config's address, port, type and answer."""
    k = robot.kuka_rsi
    holdon = "1" if k.correction == "absolute" else "0"
    tags = [f"RKorr.{c}" for c in "XYZABC"] if k.cartesian else [f"AK.A{i}" for i in range(1, 7)]
    received = "\n".join(f'         <ELEMENT TAG="{t}" TYPE="DOUBLE" INDX="{i}" HOLDON="{holdon}" />'
                         for i, t in enumerate(tags, 1))
    return f"""<ROOT>
   <!-- stiffcomp: the configuration file of the RSI context's ETHERNET object (docs/robot.md, "KUKA RSI"). -->
   <!-- Copy it to C:\\KRC\\ROBOTER\\Config\\User\\Common\\SensorInterface on the controller; the ETHERNET -->
   <!-- object's ConfigFile parameter names it (StiffComp.xml). Written by `stiffcomp robot-programs`. -->
   <!-- It matches config/robot_kuka_rsi.yaml; tests/test_robot_files.py holds the two together. -->
   <CONFIG>
      <!-- ADAPT: the address of the PC running stiffcomp on the RSI network (robot.host). It must be in the -->
      <!-- robot's RSI subnet; KUKA blocks 192.168.0.x for it. -->
      <IP_NUMBER>{robot.host}</IP_NUMBER>
      <!-- the UDP port stiffcomp listens on (robot.port) -->
      <PORT>{robot.port}</PORT>
      <!-- the Type of the answer's <Sen> element (robot.kuka_rsi.sen_type): both sides must name the same, -->
      <!-- case included, or the robot does not take the answers -->
      <SENTYPE>{k.sen_type}</SENTYPE>
      <!-- FALSE: the robot waits for an answer every cycle -->
      <ONLYSEND>FALSE</ONLYSEND>
   </CONFIG>
{_send(robot)}
   <RECEIVE>
      <ELEMENTS>
         <!-- the axis correction AK A1..A6 (deg), wired to the AXISCORR object's inputs 1..6. -->
         <!-- HOLDON="1": a late answer keeps the last value, right for an absolute correction -->
         <!-- (robot.kuka_rsi.correction: absolute). With a relative correction use HOLDON="0", or a late -->
         <!-- answer repeats the last increment every cycle. -->
         <!-- For a Cartesian correction (robot.kuka_rsi.cartesian: true) the tags are RKorr.X RKorr.Y RKorr.Z -->
         <!-- RKorr.A RKorr.B RKorr.C (mm, deg), wired to a POSCORR object instead. -->
{received}
      </ELEMENTS>
   </RECEIVE>
</ROOT>
"""
