"""
What the paper's experiments share: one episode (in-process or the node graph), results.json.

Each experiment module (experiment_tosses.py, experiment_place_vs_toss.py,
experiment_catalogue.py) runs its episodes through run_inprocess_episode or run_graph_episode
and writes OUT/results.json with results_header + write_results.
"""

import json
from pathlib import Path
import subprocess
import time

from dual_arm_control.core.exceptions import DualArmControlError
from dual_arm_control.evaluation.episode import episode_metrics
from dual_arm_control.evaluation.paper_results import RESULTS_FILE
from dual_arm_control.graph import EPISODE_START_TIME
from dual_arm_control.inprocess import run_episode


class ExperimentError(DualArmControlError):
    """An experiment could not produce its results (a run failed to start or finish)."""


def run_inprocess_episode(scenario, cell, config=None):
    """Run one in-process episode; return (metrics, trajectory with t from the episode start)."""
    log = run_episode(scenario, config=config, cell=cell)
    data = log.trajectory
    result = episode_metrics(scenario, data, cell)
    return result, dict(data, t=data['t'] - EPISODE_START_TIME)


def run_graph_episode(scenario_path, out_dir, timeout, record=False):
    """
    Run one episode through dual_arm_bringup (lockstep) into out_dir; return its metrics.

    record: also record the graph's topics into out_dir/bag.mcap. ExperimentError if the run
    does not finish within timeout [s] (plus a minute to start and stop) or leaves no metrics.
    """
    from dual_arm_control.bringup import executable_command
    command = executable_command('dual_arm_bringup') + [
        '--scenario', str(scenario_path), '--out', str(out_dir), '--mode', 'lockstep',
        '--timeout', str(timeout)] + (['--record'] if record else [])
    try:
        completed = subprocess.run(command, capture_output=True, text=True,
                                   timeout=timeout + 60.0)
    except subprocess.TimeoutExpired:
        raise ExperimentError(f'dual_arm_bringup did not finish in {timeout + 60:g} s') from None
    metrics_path = Path(out_dir) / 'metrics.json'
    if completed.returncode not in (0, 1) or not metrics_path.is_file():
        last = (completed.stderr.strip().splitlines() or ['no output'])[-1]
        raise ExperimentError(f'dual_arm_bringup exited {completed.returncode}: {last}')
    return json.loads(metrics_path.read_text())


def write_results(out_dir, results):
    """Write results as OUT/results.json (sorted keys), creating out_dir."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / RESULTS_FILE).write_text(json.dumps(results, indent=1, sort_keys=True) + '\n')


def results_header(name, runner, started, limit):
    """Return the fields every results.json starts with: name, command, runner, wall time."""
    return {'experiment': name, 'command': f'dual_arm_experiment {name}', 'runner': runner,
            'wall_time': time.monotonic() - started, 'limited': limit is not None}
