"""The cyclic compensation service: sources, filter, gravity, compensation, limits, faults, loop."""
