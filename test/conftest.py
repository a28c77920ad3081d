"""Test configuration: the ``ros`` marker, and a ROS domain of its own per test process.

Every pytest process takes a free ROS_DOMAIN_ID (a lock file per id under the temp dir,
held for the life of the process) and localhost-only discovery, so that concurrent test
runs, and the nodes they start as subprocesses, cannot hear each other.
"""

import atexit
import os

from gyro_rotor.tools.launch import claim_domain_id
import pytest

# the same lock files as gyro_rotor.launch (demo, soak), so no two of them share a domain
_CLAIM = claim_domain_id(first=1, last=200)
atexit.register(_CLAIM.release)

os.environ['ROS_DOMAIN_ID'] = str(_CLAIM.domain_id)
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_PYTHON_CHECK_FIELDS', '1')
os.environ.setdefault('MPLBACKEND', 'Agg')


def _have_rclpy() -> bool:
    try:
        import rclpy  # noqa: F401
    except ImportError:
        return False
    return True


HAVE_RCLPY = _have_rclpy()


def pytest_collection_modifyitems(config, items):
    """Skip tests marked ``ros`` where rclpy is not importable."""
    if HAVE_RCLPY:
        return
    skip = pytest.mark.skip(reason='rclpy (ROS 2 Jazzy) is not importable')
    for item in items:
        if 'ros' in item.keywords:
            item.add_marker(skip)


@pytest.fixture(scope='session')
def ros_domain_id() -> int:
    """Return the ROS_DOMAIN_ID of this test process."""
    return int(os.environ['ROS_DOMAIN_ID'])
