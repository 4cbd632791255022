"""The PLC interface's exception tree.

PlcError (a ServiceError)            base of every PLC-side error
├── RegisterMapError                 the register map YAML is invalid: names file, key, value, range
└── PlcConnectionError               client role: the PLC cannot be reached or answers with an error
"""

from __future__ import annotations

from service.errors import ServiceConfigError, ServiceError


class PlcError(ServiceError):
    """Base of every error of the PLC interface."""


class RegisterMapError(PlcError, ServiceConfigError):
    """Raised at start-up when the register map is invalid; nothing has been started."""


class PlcConnectionError(PlcError):
    """Raised in the client role when the PLC cannot be reached or refuses a request."""
