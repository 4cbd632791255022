"""What the PLC sees and how it reaches it: the contract, the register map, the process image that holds the
contract's words, and the two transports, Modbus TCP (server and client) and ADS (docs/architecture.md)."""
