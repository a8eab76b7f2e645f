"""Fixtures of the model tests."""

from collections.abc import Iterator

import pytest

from probaff._threads import limit_threads


@pytest.fixture(scope="module")
def single_thread() -> Iterator[None]:
    """Torch on one thread for a whole module, its module fixtures included.

    A module takes it with ``pytestmark = pytest.mark.usefixtures("single_thread")``: it is
    then set up before the module's other fixtures.
    """
    with limit_threads(1):
        yield
