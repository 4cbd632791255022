"""The PLC link's errors, each a `io_base.errors.PlcError`."""

from __future__ import annotations

from io_base.errors import PlcError


class ContractError(PlcError):
    """Raised at start-up when a value of the contract names a cycle quantity that does not exist."""


class RegisterMapError(PlcError):
    """Raised at start-up when the register map is invalid; nothing has been started."""


class PlcConnectionError(PlcError):
    """Raised in the client role when the PLC cannot be reached or refuses a request."""
