"""Shared test fixtures: an isolated ROS environment per test, the source root, a yaw rotation."""

import os
from pathlib import Path
import random
import sys

import domain_coordinator
from dual_arm_control.core.geometry import rpy_to_matrix
import pytest

SOURCE_ROOT = Path(__file__).resolve().parent.parent

os.environ.setdefault('AMENT_PREFIX_PATH', sys.prefix)
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
# Tests kill processes (SIGKILL) on purpose; Fast DDS shared-memory segments they leave behind
# made later discovery in the same session intermittently fail. UDP loopback has no such state.
os.environ.setdefault('FASTDDS_BUILTIN_TRANSPORTS', 'UDPv4')


def yaw_rotation(yaw):
    """Return the rotation (3, 3) by yaw [rad] about the world z axis."""
    return rpy_to_matrix((0.0, 0.0, yaw))


@pytest.fixture
def source_root():
    """Return the repository root."""
    return SOURCE_ROOT


def random_domain():
    """Return a random domain id to try (domain_coordinator takes the next free one)."""
    return random.SystemRandom().randint(1, 100)


@pytest.fixture
def ros_domain(monkeypatch):
    """Give the test (and every process it starts) a ROS domain id reserved while it runs."""
    with domain_coordinator.domain_id(random_domain) as reserved:
        monkeypatch.setenv('ROS_DOMAIN_ID', str(reserved))
        yield str(reserved)
