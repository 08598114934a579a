"""ament_flake8 (99 columns, single quotes, Google import order) on all project code."""

from ament_flake8.main import main_with_errors

from conftest import SOURCE_ROOT

CHECKED_PATHS = ['dual_arm_control', 'sim_bridge', 'test', 'launch', 'setup.py', 'tools']


def test_flake8():
    paths = [str(SOURCE_ROOT / p) for p in CHECKED_PATHS if (SOURCE_ROOT / p).exists()]
    return_code, errors = main_with_errors(argv=paths)
    assert return_code == 0, f'{len(errors)} flake8 errors:\n' + '\n'.join(errors)
