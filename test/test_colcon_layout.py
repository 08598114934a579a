"""A real `colcon build` installs everything where `ros2 run` and the ament index look."""

import os
from pathlib import Path
import shutil
import subprocess
import sys

from conftest import SOURCE_ROOT
from dual_arm_control.executables import EXECUTABLES
import pytest

PACKAGE = 'dual_arm_control'


def _tracked_files():
    """Return the repository's tracked and new (not ignored) files."""
    listing = subprocess.run(
        ['git', 'ls-files', '--cached', '--others', '--exclude-standard'], cwd=SOURCE_ROOT,
        check=True, capture_output=True, text=True).stdout
    return [line for line in listing.splitlines() if (SOURCE_ROOT / line).is_file()]


@pytest.fixture(scope='module')
def colcon_install(tmp_path_factory):
    """Build a clean copy of the source with colcon into a temporary workspace."""
    colcon = shutil.which('colcon', path=os.path.dirname(sys.executable))
    assert colcon, 'colcon (colcon-core + colcon-ros) must be installed in the test venv'
    workspace = tmp_path_factory.mktemp('colcon_ws')
    source = workspace / 'src' / PACKAGE
    for relative in _tracked_files():
        target = source / relative
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(SOURCE_ROOT / relative, target)
    env = dict(os.environ, AMENT_PREFIX_PATH=sys.prefix)
    result = subprocess.run(
        [colcon, 'build', '--base-paths', 'src', '--event-handlers', 'console_direct+'],
        cwd=workspace, env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    return workspace / 'install' / PACKAGE


def test_every_executable_is_where_ros2_run_looks(colcon_install):
    lib_dir = colcon_install / 'lib' / PACKAGE
    installed = {p.name for p in lib_dir.iterdir() if os.access(p, os.X_OK)}
    assert set(EXECUTABLES) <= installed, f'missing in {lib_dir}: {set(EXECUTABLES) - installed}'


def test_ament_index_marker_and_share_files(colcon_install):
    marker = colcon_install / 'share' / 'ament_index' / 'resource_index' / 'packages' / PACKAGE
    assert marker.is_file()
    share = colcon_install / 'share' / PACKAGE
    assert (share / 'package.xml').is_file()
    for relative in ('config/objects.yaml', 'config/cell.yaml', 'urdf/iiwa7.urdf',
                     'urdf/iiwa14.urdf'):
        assert (share / relative).is_file(), f'{relative} not installed under {share}'
    shipped = {p.name for p in (SOURCE_ROOT / 'config' / 'scenarios').glob('*.yaml')}
    installed = {p.name for p in (share / 'config' / 'scenarios').glob('*.yaml')}
    assert shipped and shipped == installed


def test_installed_executable_starts_from_the_install_space(colcon_install, tmp_path):
    site_packages = next(colcon_install.glob('lib/python3*/site-packages'))
    env = dict(os.environ, PYTHONPATH=str(site_packages),
               AMENT_PREFIX_PATH=f'{colcon_install}{os.pathsep}{sys.prefix}')
    probe = subprocess.run(
        [sys.executable, '-c', 'import dual_arm_control.resources as r; '
         'print(r.__file__); print(r.share_directory())'],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=60)
    assert probe.returncode == 0, probe.stderr
    module_file, share_dir = probe.stdout.split()
    assert Path(module_file).is_relative_to(colcon_install)
    assert Path(share_dir) == colcon_install / 'share' / PACKAGE
    bringup = colcon_install / 'lib' / PACKAGE / 'dual_arm_bringup'
    result = subprocess.run([str(bringup), '--help'], cwd=tmp_path, env=env,
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert '--scenario' in result.stdout
