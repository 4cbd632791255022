"""What the PLC sees: the register map, the Modbus TCP server and client."""
