"""The root of the I/O side's exceptions (nothing here depends on the service).

PlcError                             base of every error of the I/O process, its listeners and the robot road
├── ContractError                    (plc_link.errors) a contract value's source does not resolve
├── RegisterMapError                 (plc_link.errors) the register map YAML is invalid
└── PlcConnectionError               (plc_link.errors) client role: the PLC cannot be reached
"""

from __future__ import annotations


class PlcError(Exception):
    """Base of every error of the I/O side; the CLI reports it with exit code 2."""
