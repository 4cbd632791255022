"""The robot road: the correction answered straight to the robot's own real-time interface (docs/robot.md).

KUKA's RSI (XML over UDP) and ABB's EGM (protobuf over UDP) each send the robot's state every few
milliseconds and expect the sensor's answer within that cycle. `road.RobotRoad` answers them from the
I/O process, with the newest correction the cycle published; `rsi` and `egm` read and write the packets.
"""
