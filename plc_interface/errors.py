"""The PLC interface's exception tree (a root of its own: nothing here depends on the service).

PlcError                             base of every PLC-side error
├── ContractError                    a contract value's source does not resolve (a programming error)
├── RegisterMapError                 the register map YAML is invalid: names file, key, value, range
└── PlcConnectionError               client role: the PLC cannot be reached or answers with an error
"""

from __future__ import annotations


class PlcError(Exception):
    """Base of every error of the PLC interface; the CLI reports it with exit code 2."""


class ContractError(PlcError):
    """Raised at start-up when a value of the contract names a cycle quantity that does not exist."""


class RegisterMapError(PlcError):
    """Raised at start-up when the register map is invalid; nothing has been started."""


class PlcConnectionError(PlcError):
    """Raised in the client role when the PLC cannot be reached or refuses a request."""
