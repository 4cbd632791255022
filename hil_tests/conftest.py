"""Fixtures of the HIL tests: every test leaves no thread, socket or process behind."""

import pytest


def pytest_collection_modifyitems(config, items):
    """Every test here is a HIL test (`make test-fast` leaves them out)."""
    here = config.rootpath / "hil_tests"
    for item in items:
        if here in item.path.parents:
            item.add_marker(pytest.mark.hil)


@pytest.fixture(autouse=True)
def _leak_check(no_leaks):
    """The root conftest's leak check, around every test here."""
    yield
