"""What the PLC sees: the contract, the register map, the process image, and the I/O process that serves
it over Modbus TCP and ADS (docs/architecture.md)."""
