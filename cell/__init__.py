"""The programs the cell loads and their generators: the PLC's TwinCAT library and PLCopen export (`cell.plc`,
written to cell/plc/generated/) and the robot controllers' programs, KUKA KRL and RSI, ABB RAPID and EGM
(`cell.robot`, written to cell/robot/generated/)."""
