"""The HIL's one error: a pass that could not run."""


class HilError(Exception):
    """A HIL pass could not run: a device process did not start, died, the service could not be reached, or
    the PLC program could not be loaded (the CLI reports it in one line with exit code 2)."""
