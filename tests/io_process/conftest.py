"""Fixtures of the io_process tests: every test leaves no thread, socket or process behind."""

import pytest


@pytest.fixture(autouse=True)
def _leak_check(no_leaks):
    """The root conftest's leak check, around every test here."""
    yield
