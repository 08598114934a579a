"""
dual_arm_bringup refuses bad input before it starts anything: one line per problem, exit 2.

Each case is a real launcher process. It must name the file and the key with the reason, exit
with code 2 within 2 s (the time a user waits for "you made a typo"), and leave no process.
"""

import os
from pathlib import Path
import subprocess
import sys
import time

from conftest import SOURCE_ROOT
import pytest
import yaml

BRINGUP = Path(sys.executable).parent / 'dual_arm_bringup'
SCENARIO = SOURCE_ROOT / 'config' / 'scenarios' / 'paper_toss.yaml'
REPLY_TIME = 2.0


def scenario_with(tmp_path, **changes):
    """Write paper_toss.yaml with changes {dotted key: value (None deletes)}; return the path."""
    data = yaml.safe_load(SCENARIO.read_text())
    for dotted, value in changes.items():
        *parents, key = dotted.split('.')
        node = data
        for parent in parents:
            node = node[parent]
        if value is None:
            del node[key]
        else:
            node[key] = value
    path = tmp_path / 'scenario.yaml'
    path.write_text(yaml.safe_dump(data))
    return path


def params_file(tmp_path, text):
    path = tmp_path / 'params.yaml'
    path.write_text(text)
    return path


def run_launcher(tmp_path, *arguments):
    """Run the launcher; return (exit code, stderr, wall seconds, processes left with our out)."""
    out = tmp_path / 'run_output'
    started = time.monotonic()
    result = subprocess.run([str(BRINGUP), *map(str, arguments), '--out', str(out)],
                            capture_output=True, text=True, timeout=30, env=dict(os.environ))
    elapsed = time.monotonic() - started
    left = subprocess.run(['pgrep', '-f', str(out)], capture_output=True, text=True).stdout
    return result.returncode, result.stderr, elapsed, left.split()


CASES = {
    'unknown scenario key': (lambda tmp: ['--scenario', scenario_with(tmp, bogus=1)],
                             ["key 'bogus': unknown key"]),
    'scenario value of the wrong type': (
        lambda tmp: ['--scenario', scenario_with(tmp, **{'object.yaw': 'north'})],
        ['object.yaw']),
    'scenario value out of range': (
        lambda tmp: ['--scenario', scenario_with(tmp, **{'speeds.impact': 5.0})],
        ['speeds.impact', 'outside']),
    'unknown object type': (
        lambda tmp: ['--scenario', scenario_with(tmp, **{'object.type': 'piano'})],
        ['piano']),
    'missing scenario key': (
        lambda tmp: ['--scenario', scenario_with(tmp, duration=None)],
        ["missing key 'duration'"]),
    'missing scenario file': (lambda tmp: ['--scenario', tmp / 'nowhere.yaml'],
                              ['nowhere.yaml', 'cannot read']),
    'unknown scenario name': (lambda tmp: ['--scenario', 'paper_tos'],
                              ['paper_tos', 'shipped scenarios: ', 'paper_toss']),
    'missing parameter file': (lambda tmp: ['--scenario', 'paper_toss', '--params',
                                            tmp / 'nowhere.yaml'], ['nowhere.yaml']),
    'unknown parameter': (
        lambda tmp: ['--scenario', 'paper_toss', '--params', params_file(
            tmp, 'wrench_qp:\n  ros__parameters:\n    qp.max_normal_forse: 50.0\n')],
        ['params.yaml', 'wrench_qp', 'qp.max_normal_forse', 'unknown parameter']),
    'parameter of the wrong type': (
        lambda tmp: ['--scenario', 'paper_toss', '--params', params_file(
            tmp, '/**/passive_controller:\n  ros__parameters:\n    lockstep: 5\n')],
        ['params.yaml', 'lockstep must be true or false, got 5']),
    'parameter out of range': (
        lambda tmp: ['--scenario', 'paper_toss', '--params', params_file(
            tmp, 'ds_motion_generator:\n  ros__parameters:\n    impact.impact_speed: 3.0\n')],
        ['params.yaml', 'impact.impact_speed', 'impact_speed = 3', 'outside']),
    'parameter file for no node of the graph': (
        lambda tmp: ['--scenario', 'paper_toss', '--params', params_file(
            tmp, 'planner:\n  ros__parameters:\n    speed: 1.0\n')],
        ['planner: no node of the graph has this name']),
}


@pytest.mark.parametrize('case', sorted(CASES))
def test_bad_input_is_refused_with_its_reason_before_anything_starts(tmp_path, case):
    arguments, expected = CASES[case]
    code, stderr, elapsed, left = run_launcher(tmp_path, *arguments(tmp_path))
    assert code == 2, stderr
    for text in expected:
        assert text in stderr, (text, stderr)
    assert all(line.startswith('dual_arm_bringup: ') for line in stderr.splitlines()), stderr
    assert elapsed < REPLY_TIME, f'{elapsed:.2f} s'
    assert not left, f'processes left: {left}'
    assert not (tmp_path / 'run_output' / 'logs').exists(), 'nothing may have started'
