"""ament_pep257 docstring conventions on all project code."""

from ament_pep257.main import main

from conftest import SOURCE_ROOT

CHECKED_PATHS = ['dual_arm_control', 'sim_bridge', 'test', 'launch', 'setup.py', 'tools']


def test_pep257():
    paths = [str(SOURCE_ROOT / p) for p in CHECKED_PATHS if (SOURCE_ROOT / p).exists()]
    assert main(argv=paths) == 0, 'pep257 errors: see the output above'
