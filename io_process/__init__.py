"""The I/O process: the service's second process, its server and the listeners it starts (Modbus TCP or the
Modbus client, ADS, the robot road), their monitoring, health and metrics (docs/architecture.md)."""
