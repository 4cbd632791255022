"""The record one cycle computes (`Signals`) and where each of its values lives in the cycle's float vector.

The compiled cycle writes the whole record as one vector of floats (`SIGNAL_SLOTS`: name -> offset and
length); the service packs the PLC's registers and the trace from it, and `Cycle.signals` reads it back as
the named record. The five six-vectors follow one another, so the signal path (`Compensator`) keeps them as
one view of 30 floats, each at its own named place (`VECTOR_AT`).
"""

from __future__ import annotations

from typing import NamedTuple


class Signals(NamedTuple):
    """What one cycle computed (the ``signals`` of the contract's sources)."""

    status_word: int
    fault_word: int
    correction: list[float]         # δq after limits, deg
    dq_deg: list[float]             # δq before limits, deg
    wrench_base: list[float]        # filtered, compensated wrench, base axes (N, Nm about the sensor origin)
    wrench_sensor: list[float]      # the same in sensor axes
    deflection: list[float]         # predicted TCP deflection, mm and deg, base axes
    tare_count: int
    sensor_samples: int             # good samples since start
    sample_age_ms: float            # age of the newest good sample (ms; since start before the first)
    payload_active: int             # the payload set in use (service.payloads)
    reload_count: int               # accepted reloads of the config (service.reload)
    acc_x: float                    # the arm's acceleration at the tool, base axes, m/s^2, gravity and bias
    acc_y: float                    # removed (service.accelerometer); 0 without an accelerometer or while
    acc_z: float                    # its samples do not arrive
    box_x: float                    # the box's reading the accelerometer last took, as it came: box axes, m/s^2,
    box_y: float                    # gravity and bias in (what the PLC passed or the replay released); 0
    box_z: float                    # without an accelerometer
    box_samples: int                # the readings taken since start, mod 65536: one more in each cycle that
                                    # took a new one


# Signals as one float vector, field by field in their order (a list takes six places): what the compiled
# cycle writes and the service packs for the PLC and the trace (`Cycle.vector`); name -> (offset, length)
VECTORS = ("correction", "dq_deg", "wrench_base", "wrench_sensor", "deflection")
SIGNAL_SLOTS: dict[str, tuple[int, int]] = {}
for _name in Signals._fields:
    SIGNAL_SLOTS[_name] = (sum(n for _, n in SIGNAL_SLOTS.values()), 6 if _name in VECTORS else 1)
SIGNAL_SIZE = sum(n for _, n in SIGNAL_SLOTS.values())
VECTORS_START = SIGNAL_SLOTS[VECTORS[0]][0]     # the five vectors follow one another from here
VECTORS_SIZE = 6 * len(VECTORS)
assert [SIGNAL_SLOTS[n][0] for n in VECTORS] == list(range(VECTORS_START, VECTORS_START + VECTORS_SIZE, 6))
# each vector's place in the signal path's own view of the five (`Compensator.vector`)
VECTOR_AT = {name: SIGNAL_SLOTS[name][0] - VECTORS_START for name in VECTORS}
SCALARS = ("status_word", "fault_word", "tare_count", "sensor_samples", "sample_age_ms", "payload_active",
           "reload_count", "acc_x", "acc_y", "acc_z", "box_x", "box_y", "box_z", "box_samples")
SCALAR_AT = {name: SIGNAL_SLOTS[name][0] for name in SCALARS}


def six(name: str, doc: str) -> property:
    """The vector ``name`` as a property: six floats kept in the signal path's ``vector`` at `VECTOR_AT`."""
    k = VECTOR_AT[name]

    def get(self) -> list[float]:
        return self.vector[k:k + 6].tolist()

    def put(self, values) -> None:
        self.vector[k:k + 6] = values

    return property(get, put, doc=doc)
