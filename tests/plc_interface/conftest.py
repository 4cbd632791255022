"""Fixtures of the PLC interface tests: every test leaves no thread, socket or child process behind."""

from stiffcomp_testlib import no_leaks  # noqa: F401  (an autouse fixture)
