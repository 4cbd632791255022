"""The service's exception tree (one per subsystem, each class says when it is raised).

ServiceError                      base of every error the cyclic service raises on bad input
├── ServiceConfigError            default.yaml (or a file it names) is invalid: names file, key, value, range
├── ModelUnsupportedError         the stiffness model holds an effect the real-time predictor cannot evaluate
├── SourceError                   the F/T source cannot be opened (file missing, CAN interface unavailable)
├── TraceError                    the trace file (--trace) cannot be written: its folder, suffix, pyarrow
└── SensorError                   a reading from the F/T sensor is unusable (raised per reading; its
    │                             ``fault`` names the fault bit `service.faults.FaultMonitor` sets)
    ├── SensorTimeout             no sample for longer than ``faults.sensor_timeout_ms``
    ├── SensorStatusError         the sensor's status word reports an error
    ├── SensorSaturated           a gauge channel sits at the INT16 limit (the reading is clipped)
    ├── SensorValueError          NaN, inf or a value outside the configured range
    └── CanFrameError             a malformed CAN frame (wrong length) or an unknown identifier

The I/O side has its own tree, rooted at `io_base.errors.PlcError`; the CLI catches each root.
"""

from __future__ import annotations

from plc_link.contract import Fault


class ServiceError(Exception):
    """Base of every error the service raises on bad input; the CLI reports it with exit code 2."""


class ServiceConfigError(ServiceError):
    """Raised at start-up when the service config is invalid; nothing has been started."""


class ModelUnsupportedError(ServiceError):
    """Raised at start-up when the model holds an effect the real-time predictor does not support."""


class SourceError(ServiceError):
    """Raised when the F/T source cannot be opened or read (missing file, unknown CAN interface)."""


class TraceError(ServiceError):
    """Raised at start-up when the trace file (``stiffcomp run --trace``) cannot be written."""


class SensorError(ServiceError):
    """A reading from the F/T sensor is unusable. Subclasses name why, and ``fault`` the bit it sets (as
    python-can's errors carry their ``error_code``): a new kind of sensor error names its own fault."""

    fault: Fault = Fault.VALUE_INVALID


class SensorTimeout(SensorError):
    """No sample arrived for longer than the configured timeout."""

    fault = Fault.SENSOR_TIMEOUT


class SensorStatusError(SensorError):
    """The sensor's status word is not zero (the sensor reports an internal error)."""

    fault = Fault.SENSOR_STATUS


class SensorSaturated(SensorError):
    """A channel reads the INT16 limit: the gauge is saturated and the value is clipped."""

    fault = Fault.SENSOR_SATURATED


class SensorValueError(SensorError):
    """A value is NaN, infinite or outside the configured measuring range."""

    fault = Fault.VALUE_INVALID


class CanFrameError(SensorError):
    """A CAN frame is malformed (wrong data length) or carries an identifier the protocol does not define."""

    fault = Fault.CAN_FRAME
