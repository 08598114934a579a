"""
The product end to end: the whole node graph in separate processes, in lockstep, on the twin.

Each test runs `dual_arm_bringup` (the README's main job) and asserts on the simulator's ground
truth in metrics.json. Thresholds are the issue's: contacts within 10 ms, impact speed within
15 %, slip below 1 cm, release within 3 cm and 10 %, landing within 5 cm of the ballistic
prediction, placing within 3 cm below 0.1 m/s.
"""

import json
import os
from pathlib import Path
import subprocess
import sys

from conftest import SOURCE_ROOT
import pytest

pytestmark = pytest.mark.slow
SCENARIOS = SOURCE_ROOT / 'config' / 'scenarios'
EPISODE_TIMEOUT = 240


def run_episode(scenario, out_dir, *extra):
    """
    Run one episode (a shipped scenario's name or a file's Path) with the launcher.

    Return (exit code, metrics dict, output text).
    """
    bringup = Path(sys.executable).parent / 'dual_arm_bringup'
    path = scenario if isinstance(scenario, Path) else SCENARIOS / f'{scenario}.yaml'
    result = subprocess.run(
        [str(bringup), '--scenario', str(path), '--out',
         str(out_dir), *extra], capture_output=True, text=True, timeout=EPISODE_TIMEOUT,
        env=dict(os.environ), cwd=out_dir.parent)
    metrics_file = out_dir / 'metrics.json'
    metrics = json.loads(metrics_file.read_text()) if metrics_file.is_file() else {}
    return result.returncode, metrics, result.stdout + result.stderr


def _logs(out_dir):
    return '\n'.join(f'--- {p.name}\n{p.read_text()[-3000:]}'
                     for p in sorted((out_dir / 'logs').glob('*.log')))


def test_paper_place(tmp_path, ros_domain):
    out = tmp_path / 'paper_place'
    code, m, output = run_episode('paper_place', out)
    assert m, output + _logs(out)
    print(json.dumps(m, indent=1))
    assert m['place_position_error'] <= 0.02
    # Let go once the table has stopped the box: 0.027 m/s as the pads leave it (0.076 when
    # it was let go still descending, 3 mm above the table; limit of the task 0.1).
    assert m['place_speed'] < 0.05
    assert m['success'] and code == 0


def test_paper_place_regrasp(tmp_path, ros_domain):
    """The node graph stages the box on the pallet, picks it up again and places it."""
    out = tmp_path / 'paper_place_regrasp'
    code, m, output = run_episode('paper_place_regrasp', out)
    assert m, output + _logs(out)
    print(json.dumps(m, indent=1))
    assert m['grasp_count'] == 2, output + _logs(out)
    assert m['place_position_error'] <= 0.02 and m['place_speed'] < 0.1
    assert m['contact_time_gap'] <= 0.010 and m['max_slip'] <= 0.01
    assert m['success'] and code == 0


def test_a_refused_start_is_in_the_metrics(tmp_path, ros_domain):
    """A place too near the pallet: the graph's motion generator refuses it and says why."""
    from dataclasses import replace

    from dual_arm_control.description.cell import load_cell
    from dual_arm_control.evaluation.trials import write_trial_scenario
    from dual_arm_control.scenario import load_scenario
    cell = load_cell()
    place = (0.66, 0.0, cell.surface_height(0.66, 0.0) + 0.1)
    refused = replace(load_scenario('paper_place', cell=cell), place=place, duration=1.0)
    write_trial_scenario(refused, tmp_path / 'refused.yaml', 'paper_place', 0)
    out = tmp_path / 'refused'
    code, m, output = run_episode(tmp_path / 'refused.yaml', out)
    assert m, output + _logs(out)
    assert 'too near the pallet' in (m['start_refusal'] or ''), output + _logs(out)
    assert not m['success'] and code != 0


def test_box_displaced_during_reach_is_still_grasped_and_tossed(tmp_path, ros_domain):
    out = tmp_path / 'displaced'
    code, m, output = run_episode('paper_toss_displaced', out)
    assert m, output + _logs(out)
    print(json.dumps(m, indent=1))
    assert m['t_contact_left'] > 1.0 - 0.3, 'the push must happen before contact'
    assert m['contact_time_gap'] <= 0.010
    assert m['t_release'] is not None and m['landing_position'] is not None
    assert m['release_position_error'] <= 0.03
    assert m['success'] and code == 0
