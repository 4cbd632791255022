"""Hardware-in-the-loop: the service closed around virtual devices that speak the real protocols.

virtual_sensor  a virtual ATI Net F/T sensor on any python-can bus (the real protocol)
virtual_plc     the virtual PLC: the TwinCAT program the cell loads (plc_program), run by st_runtime on its
                own cycle, its requests over the cell's network (cell_network: Modbus TCP or the image)
demo_log        the synthetic milling log the replay source ships with
testing         helpers the tests, HIL tests and benchmarks share (configs, free ports, leaks)
scenario    the YAML of a run (config/hil/circle.yaml)
path        the circle and its inverse kinematics (the PLC's joint references)
milling     the process force of an end mill following the feed direction
robot_stub  the "real" robot: commanded joints + load -> deflected TCP, from a truth model
sensor      the virtual ATI sensor process (process force + noise + tool weight, fault modes)
plc_process the virtual PLC process (hil.virtual_plc driving the robot)
run         one pass and the with/without comparison, each device in its own process
report      path errors and the Fig. 8 plot
"""
