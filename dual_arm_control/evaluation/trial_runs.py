"""
Running dual_arm_eval's trials: each trial scenario file with the in-process runner or the graph.

inprocess: one single-threaded process per trial (a spawned process pool for several jobs).
graph: one dual_arm_bringup run of the whole node graph per trial, each in a ROS domain of its
own; realtime: the same in realtime mode. Every trial leaves metrics.json (and optionally
trajectory.npz) beside its scenario file.
"""

from concurrent.futures import as_completed, ProcessPoolExecutor, ThreadPoolExecutor
from functools import lru_cache
import json
import multiprocessing
import os
from pathlib import Path
import queue
import subprocess
import sys

from dual_arm_control.description.cell import load_cell
from dual_arm_control.evaluation.episode import episode_metrics
from dual_arm_control.evaluation.trial_summary import succeeded, TrialOutcome
from dual_arm_control.inprocess import run_episode
from dual_arm_control.scenario import load_scenario
import numpy as np

# Wall time a graph trial may take beyond the launcher's own episode limit (start and stop).
GRAPH_STOP_MARGIN = 60.0


def usable_cores():
    """Return the number of CPU cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def default_jobs(runner):
    """
    Return the default number of parallel trials of a runner.

    inprocess: one trial per core (a trial is one single-threaded process). graph: one trial
    per two cores, since the six node processes of a lockstep trial keep about 1.5 cores busy.
    realtime: one, since a realtime graph takes all the CPU it gets (docs/performance.md) and a
    second one beside it would make both miss their cycles.
    """
    if runner == 'realtime':
        return 1
    cores = usable_cores()
    return cores if runner == 'inprocess' else max(1, cores // 2)


@lru_cache(maxsize=1)
def _cell():
    return load_cell()


def run_inprocess_trial(scenario_file, keep_trajectory=False):
    """
    Run one trial scenario file with the single-process runner; return its metrics.

    Writes metrics.json (and trajectory.npz with keep_trajectory) beside the scenario file.
    """
    scenario_file = Path(scenario_file)
    cell = _cell()
    scenario = load_scenario(scenario_file, cell=cell)
    log = run_episode(scenario, cell=cell)
    trajectory = log.trajectory
    metrics = episode_metrics(scenario, trajectory, cell, events=log.events)
    (scenario_file.parent / 'metrics.json').write_text(json.dumps(metrics, indent=2) + '\n')
    trajectory_file = scenario_file.parent / 'trajectory.npz'
    if keep_trajectory:
        np.savez_compressed(trajectory_file, **trajectory)
    else:
        trajectory_file.unlink(missing_ok=True)
    return metrics


class TrialError(Exception):
    """A trial that produced no metrics; the message is the reason."""


def run_graph_trial(scenario_file, domain_id, keep_trajectory=False, timeout=600.0,
                    mode='lockstep'):
    """
    Run one trial scenario file with dual_arm_bringup (the whole node graph); return metrics.

    The graph runs in ROS domain domain_id, in mode 'lockstep' or 'realtime'; the launcher's
    output goes to bringup.log beside the scenario file. Raises TrialError when the launcher
    leaves no metrics.json.
    """
    trial_dir = Path(scenario_file).parent
    metrics_file = trial_dir / 'metrics.json'
    metrics_file.unlink(missing_ok=True)
    command = [sys.executable, '-m', 'dual_arm_control.bringup', '--scenario',
               str(scenario_file), '--out', str(trial_dir), '--domain-id', str(domain_id),
               '--timeout', str(timeout), '--mode', mode]
    try:
        result = subprocess.run(command, capture_output=True, text=True, stdin=subprocess.DEVNULL,
                                timeout=timeout + GRAPH_STOP_MARGIN)
    except subprocess.TimeoutExpired:
        raise TrialError(f'dual_arm_bringup did not finish within '
                         f'{timeout + GRAPH_STOP_MARGIN:g} s') from None
    (trial_dir / 'bringup.log').write_text(result.stdout + result.stderr)
    if not keep_trajectory:
        (trial_dir / 'trajectory.npz').unlink(missing_ok=True)
    if not metrics_file.is_file():
        lines = [line for line in result.stderr.splitlines() if line.strip()]
        last = lines[-1] if lines else 'no output'
        raise TrialError(f'dual_arm_bringup exited {result.returncode}: {last}')
    return json.loads(metrics_file.read_text())


def run_trials(scenario_files, runner, jobs, keep_trajectories, timeout, domain_base, progress):
    """Run the trial scenario files; return one TrialOutcome per file, in order."""
    outcomes = [None] * len(scenario_files)

    def record(index, metrics=None, error=None):
        outcomes[index] = TrialOutcome(index, metrics, error)
        done = [outcome for outcome in outcomes if outcome is not None]
        progress.set_postfix(success=f'{sum(succeeded(o) for o in done)}/{len(done)}',
                             refresh=False)
        progress.update(1)

    if runner == 'inprocess' and jobs == 1:
        for index, path in enumerate(scenario_files):
            try:
                record(index, run_inprocess_trial(path, keep_trajectories))
            except Exception as error:  # noqa: B902 (a crashing trial is recorded, not fatal)
                record(index, error=f'{type(error).__name__}: {error}')
        return outcomes
    if runner == 'inprocess':
        executor = ProcessPoolExecutor(max_workers=jobs,
                                       mp_context=multiprocessing.get_context('spawn'))
        submit = (lambda path: executor.submit(run_inprocess_trial, path, keep_trajectories))
    else:
        domains = queue.SimpleQueue()
        for domain_id in range(domain_base, domain_base + jobs):
            domains.put(domain_id)

        def graph_trial(path):
            domain_id = domains.get()
            try:
                return run_graph_trial(path, domain_id, keep_trajectories, timeout,
                                       'realtime' if runner == 'realtime' else 'lockstep')
            finally:
                domains.put(domain_id)

        executor = ThreadPoolExecutor(max_workers=jobs)
        submit = (lambda path: executor.submit(graph_trial, path))
    with executor:
        futures = {submit(path): index for index, path in enumerate(scenario_files)}
        for future in as_completed(futures):
            error = future.exception()
            if error is None:
                record(futures[future], future.result())
            elif isinstance(error, TrialError):
                record(futures[future], error=str(error))
            else:
                record(futures[future], error=f'{type(error).__name__}: {error}')
    return outcomes
