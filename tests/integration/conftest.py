"""Fixtures of the multi-process ROS 2 tests."""
import pytest

from integration.ros_helpers import Listener


@pytest.fixture(scope='module')
def listener(request):
    """
    Return the test module's :class:`~integration.ros_helpers.Listener` (closed after the module).

    A module that needs more on it (a latched publisher, a helper) overrides ``listener`` with a
    fixture that takes this one and adds to it.
    """
    lis = Listener(request.module.__name__.rpartition('.')[2] + '_listener')
    yield lis
    lis.close()
