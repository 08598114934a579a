"""
dual_arm_eval: run N trials of a scenario, drawn from its randomization block, and summarize.

Trial i is scenario.sample_trial(scenario, i): deterministic in (seed, i), so a batch is
reproducible from the scenario's seed. Each trial is written to OUT/trial_NNN/scenario.yaml (a
complete scenario file that dual_arm_bringup runs as it is) and leaves OUT/trial_NNN/metrics.json
(the per-episode contract of evaluation/episode.py). OUT/summary.json aggregates the batch and
OUT/*.png plots it. Everything runs in lockstep on the twin.
"""

import argparse
from concurrent.futures import as_completed, ProcessPoolExecutor, ThreadPoolExecutor
from dataclasses import dataclass, replace
from functools import lru_cache
import json
import math
import multiprocessing
import os
from pathlib import Path
import queue
import random
import subprocess
import sys
import time

from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.description.cell import load_cell
from dual_arm_control.evaluation.episode import (CONTACT_GAP_LIMIT, episode_metrics,
                                                 LANDING_LIMIT, PLACE_LIMIT, PLACE_SPEED_LIMIT,
                                                 PLACE_TILT_LIMIT, predicted_landing,
                                                 RELEASE_POSITION_LIMIT,
                                                 RELEASE_VELOCITY_LIMIT, SLIP_LIMIT)
from dual_arm_control.evaluation.plots import save_figure
from dual_arm_control.inprocess import run_episode
from dual_arm_control.scenario import (load_scenario, PLACE_TASKS, scenario_document,
                                       scenario_path, TOSS_TASKS)
from dual_arm_control.trial_sampling import sample_trial
import matplotlib
matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402, I100  (the backend is chosen before pyplot loads)
import numpy as np  # noqa: E402, I100
from tqdm import tqdm  # noqa: E402, I100
import yaml  # noqa: E402, I100

RUNNERS = ('graph', 'inprocess')
# Pass/fail metrics plotted against the randomized quantities: (label, scale, limit).
SENSITIVITY_METRICS = {
    'contact_time_gap': ('contact time gap [ms]', 1000.0, CONTACT_GAP_LIMIT),
    'max_slip': ('max pad slip [cm]', 100.0, SLIP_LIMIT),
    'landing_error': ('landing error [cm]', 100.0, LANDING_LIMIT),
}
# Highest ROS domain id Fast DDS accepts on the default port mapping.
MAX_DOMAIN_ID = 232
# Wall time a graph trial may take beyond the launcher's own episode limit (start and stop).
GRAPH_STOP_MARGIN = 60.0
EXIT_USER_ERROR = 2


@dataclass(frozen=True)
class TrialOutcome:
    """What one trial left: its metrics dict, or None and the reason it produced none."""

    index: int
    metrics: object = None
    error: object = None


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
    """
    cores = usable_cores()
    return cores if runner == 'inprocess' else max(1, cores // 2)


def trial_directory(out_dir, index):
    """Return OUT/trial_NNN, the folder of trial number index."""
    return Path(out_dir) / f'trial_{index:03d}'


def write_trial_scenario(trial, path, source, index):
    """Write a concrete trial scenario as a complete scenario file at path."""
    path.parent.mkdir(parents=True, exist_ok=True)
    header = (f'# dual_arm_eval: trial {index} drawn from {source}; a complete scenario, '
              f'runnable with dual_arm_bringup --scenario <this file>.\n')
    path.write_text(header + yaml.safe_dump(scenario_document(trial), sort_keys=False,
                                            default_flow_style=None))


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
    trajectory = run_episode(scenario, cell=cell).trajectory
    metrics = episode_metrics(scenario, trajectory, cell)
    (scenario_file.parent / 'metrics.json').write_text(json.dumps(metrics, indent=2) + '\n')
    trajectory_file = scenario_file.parent / 'trajectory.npz'
    if keep_trajectory:
        np.savez_compressed(trajectory_file, **trajectory)
    else:
        trajectory_file.unlink(missing_ok=True)
    return metrics


class TrialError(Exception):
    """A trial that produced no metrics; the message is the reason."""


def run_graph_trial(scenario_file, domain_id, keep_trajectory=False, timeout=600.0):
    """
    Run one trial scenario file with dual_arm_bringup (the whole node graph); return metrics.

    The graph runs in ROS domain domain_id; the launcher's output goes to bringup.log beside
    the scenario file. Raises TrialError when the launcher leaves no metrics.json.
    """
    trial_dir = Path(scenario_file).parent
    metrics_file = trial_dir / 'metrics.json'
    metrics_file.unlink(missing_ok=True)
    command = [sys.executable, '-m', 'dual_arm_control.bringup', '--scenario',
               str(scenario_file), '--out', str(trial_dir), '--domain-id', str(domain_id),
               '--timeout', str(timeout)]
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


def _numeric(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def summarize(metrics_list):
    """
    Aggregate the trials' metrics: return {'trials', 'success_rate', 'metrics'}.

    metrics_list holds one metrics dict per trial, or None for a trial that produced none (it
    counts as a failure). success_rate = trials with success true / all trials. For every key
    whose non-null values are all numbers (bools excluded), 'metrics' gives mean, median, p95
    (numpy percentile, linear interpolation), min and max over the trials where it is not
    null, and count = the number of those trials. Keys keep the order they first appear in.
    """
    trials = len(metrics_list)
    present = [metrics for metrics in metrics_list if metrics]
    successes = sum(1 for metrics in present if metrics.get('success') is True)
    values = {}
    for metrics in present:
        for key, value in metrics.items():
            if value is not None:
                values.setdefault(key, []).append(value)
    statistics = {}
    for key, items in values.items():
        if not all(_numeric(item) for item in items):
            continue
        array = np.array(items, dtype=float)
        statistics[key] = {'mean': float(array.mean()), 'median': float(np.median(array)),
                           'p95': float(np.percentile(array, 95)), 'min': float(array.min()),
                           'max': float(array.max()), 'count': int(array.size)}
    return {'trials': trials, 'success_rate': successes / trials if trials else None,
            'metrics': statistics}


def _exceeds(key, value, limit, unit):
    """Return 'key value > limit unit'; the value in full when it rounds to the limit."""
    text = f'{value:.4g}'
    if float(text) <= limit:
        text = repr(value)
    return f'{key} {text} > {limit:g}{" " + unit if unit else ""}'


def failure_reason(task, metrics):
    """Return why a finished trial of task failed its success criteria (evaluation/episode.py)."""
    reasons = []
    collisions = metrics.get('arm_collision_count')
    if collisions:
        first = metrics.get('first_arm_collision') or {}
        reasons.append(f'{collisions} arm collisions (first: {" - ".join(first.get("geoms", []))} '
                       f'at {first.get("t", float("nan")):.3f} s)')
    gap = metrics.get('contact_time_gap')
    if gap is None:
        reasons.append('no contact of both pads')
    elif gap > CONTACT_GAP_LIMIT:
        reasons.append(_exceeds('contact_time_gap', gap, CONTACT_GAP_LIMIT, 's'))
    if gap is not None and metrics.get('t_grasp') is None:
        reasons.append('no sustained grasp')
    checks = [('max_slip', SLIP_LIMIT, 'm')]
    if task in TOSS_TASKS:
        checks += [('release_position_error', RELEASE_POSITION_LIMIT, 'm'),
                   ('release_velocity_error', RELEASE_VELOCITY_LIMIT, ''),
                   ('landing_error', LANDING_LIMIT, 'm')]
        if metrics.get('t_grasp') is not None and metrics.get('t_release') is None:
            reasons.append('no release')
        elif metrics.get('t_release') is not None and metrics.get('landing_error') is None:
            reasons.append('no landing within the run')
    elif task in PLACE_TASKS:
        checks = [('place_position_error', PLACE_LIMIT, 'm'),
                  ('place_speed', PLACE_SPEED_LIMIT, 'm/s'),
                  ('box_tilt_at_place', PLACE_TILT_LIMIT, 'deg')]
    for key, limit, unit in checks:
        value = metrics.get(key)
        if value is not None and value > limit:
            reasons.append(_exceeds(key, value, limit, unit))
    return '; '.join(reasons) or 'failed its success criteria'


def randomized_values(scenario, trial):
    """Return {quantity: drawn value} of the quantities scenario's randomization varies."""
    spec = scenario.randomization
    if spec is None:
        return {}
    values = {}
    if spec.object_position[0] > 0.0:
        values['object dx [cm]'] = 100.0 * (trial.object.position[0] - scenario.object.position[0])
    if spec.object_position[1] > 0.0:
        values['object dy [cm]'] = 100.0 * (trial.object.position[1] - scenario.object.position[1])
    if spec.object_yaw > 0.0:
        values['object yaw offset [deg]'] = math.degrees(
            math.remainder(trial.object.yaw - scenario.object.yaw, 2.0 * math.pi))
    if spec.mass is not None or spec.object_types is not None:
        values['mass [kg]'] = trial.object.mass
    if spec.size_scale is not None:
        values['size scale [-]'] = trial.object.size[0] / scenario.object.size[0]
    if spec.object_types is not None:
        values['squeezed width [cm]'] = 100.0 * trial.object.size[1]
    if spec.friction is not None:
        values['friction [-]'] = trial.object.friction
    if spec.mocap_noise is not None:
        values['mocap noise [mm]'] = 1000.0 * trial.sensors.mocap.position_noise
    if spec.mocap_latency is not None:
        values['mocap latency [ms]'] = 1000.0 * trial.sensors.mocap.latency
    return values


def landing_goal(trial, cell):
    """Return the landing point trial's landing_error is measured from, or None."""
    if trial.task not in TOSS_TASKS:
        return None
    if trial.landing_target is not None:
        return np.asarray(trial.landing_target, dtype=float)
    return predicted_landing(trial.release.position, trial.release.velocity,
                             trial.object.size[2], cell)


def run_trials(scenario_files, runner, jobs, keep_trajectories, timeout, domain_base, progress):
    """Run the trial scenario files; return one TrialOutcome per file, in order."""
    outcomes = [None] * len(scenario_files)

    def record(index, metrics=None, error=None):
        outcomes[index] = TrialOutcome(index, metrics, error)
        done = [outcome for outcome in outcomes if outcome is not None]
        progress.set_postfix(success=f'{sum(_succeeded(o) for o in done)}/{len(done)}',
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
                return run_graph_trial(path, domain_id, keep_trajectories, timeout)
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


def _succeeded(outcome):
    return outcome.metrics is not None and outcome.metrics.get('success') is True


def _values(outcomes, key):
    return [o.metrics[key] for o in outcomes
            if o.metrics is not None and o.metrics.get(key) is not None]


def _histogram(axis, values, label, scale=1.0, limit=None, desired=None):
    """Histogram of values * scale, with the pass limit (red) and desired value (green)."""
    axis.hist(np.asarray(values) * scale, bins=max(5, min(20, len(values) // 3)),
              color='tab:blue', alpha=0.8)
    if limit is not None:
        axis.axvline(limit * scale, color='tab:red', linestyle='--', label='pass limit')
    if desired is not None:
        axis.axvline(desired * scale, color='tab:green', linestyle='--', label='desired')
    axis.set_xlabel(label)
    axis.set_ylabel('trials')
    axis.grid(True, alpha=0.3)
    if limit is not None or desired is not None:
        axis.legend(fontsize=8)


def plot_batch(outcomes, trials, scenario, out_dir, cell):
    """Write the batch plots into out_dir; return the names of the files written."""
    out_dir = Path(out_dir)
    written = []
    landing_errors = _values(outcomes, 'landing_error')
    if landing_errors:
        figure, axis = plt.subplots(figsize=(6, 4))
        _histogram(axis, landing_errors, 'landing error [cm]', 100.0, LANDING_LIMIT)
        save_figure(figure, out_dir / 'landing_error.png')
        written.append('landing_error.png')
    speeds = {arm: _values(outcomes, f'impact_speed_along_direction_{arm}')
              for arm in ('left', 'right')}
    if any(speeds.values()):
        figure, axes = plt.subplots(1, 2, figsize=(9, 4), sharey=True)
        for axis, (arm, values) in zip(axes, speeds.items()):
            if values:
                _histogram(axis, values, f'{arm} impact speed along the impact direction [m/s]',
                           desired=scenario.speeds.impact)
        save_figure(figure, out_dir / 'impact_speeds.png')
        written.append('impact_speeds.png')
    release = {'release_position_error': ('release position error [cm]', 100.0,
                                          RELEASE_POSITION_LIMIT),
               'release_velocity_error': ('release velocity error [%]', 100.0,
                                          RELEASE_VELOCITY_LIMIT)}
    if any(_values(outcomes, key) for key in release):
        figure, axes = plt.subplots(1, 2, figsize=(9, 4))
        for axis, (key, (label, scale, limit)) in zip(axes, release.items()):
            if _values(outcomes, key):
                _histogram(axis, _values(outcomes, key), label, scale, limit)
        save_figure(figure, out_dir / 'release_errors.png')
        written.append('release_errors.png')
    if _values(outcomes, 'contact_time_gap'):
        _plot_grasp(outcomes, out_dir / 'grasp.png')
        written.append('grasp.png')
    if landing_errors:
        _plot_landing_positions(outcomes, trials, cell, out_dir / 'landing_positions.png')
        written.append('landing_positions.png')
    drawn = [randomized_values(scenario, trial) for trial in trials]
    if drawn and drawn[0]:
        _plot_sensitivity(outcomes, drawn, out_dir / 'sensitivity.png')
        written.append('sensitivity.png')
    return written


def _plot_landing_positions(outcomes, trials, cell, path):
    """Top view of the landing points (green: trial passed, red: failed) and their targets."""
    figure, axis = plt.subplots(figsize=(6, 6))
    goals = []
    for outcome, trial in zip(outcomes, trials):
        goal = landing_goal(trial, cell)
        if goal is not None:
            goals.append(goal)
        landing = outcome.metrics and outcome.metrics.get('landing_position')
        if landing is not None:
            axis.plot(landing[0], landing[1], 'o', markersize=4, alpha=0.7,
                      color='tab:green' if _succeeded(outcome) else 'tab:red')
    goals = np.unique(np.round(np.array(goals)[:, :2], 6), axis=0)
    for goal in goals:
        axis.plot(goal[0], goal[1], 'kx', markersize=10)
        axis.add_patch(plt.Circle(goal, LANDING_LIMIT, fill=False, linestyle='--', color='k'))
    axis.plot([], [], 'o', color='tab:green', label='landing, trial passed')
    axis.plot([], [], 'o', color='tab:red', label='landing, trial failed')
    axis.plot([], [], 'kx', label=f'target, {100 * LANDING_LIMIT:g} cm circle')
    axis.set_aspect('equal', adjustable='datalim')
    axis.set_xlabel('world x [m]')
    axis.set_ylabel('world y [m]')
    axis.grid(True, alpha=0.3)
    axis.legend(fontsize=8)
    save_figure(figure, path)


def _plot_sensitivity(outcomes, drawn, path):
    """
    Each pass/fail metric against each randomized quantity (green: trial passed, red: failed).

    A trial without the metric (no contact, no landing) is an x at the top of its panel.
    """
    names = list(drawn[0])
    rows = [key for key in SENSITIVITY_METRICS if _values(outcomes, key)]
    figure, axes = plt.subplots(len(rows), len(names), figsize=(3.6 * len(names), 3 * len(rows)),
                                sharex='col', sharey='row', squeeze=False)
    for row, key in zip(axes, rows):
        label, scale, limit = SENSITIVITY_METRICS[key]
        top = scale * max(_values(outcomes, key) + [limit]) * 1.1
        for axis, name in zip(row, names):
            for outcome, values in zip(outcomes, drawn):
                colour = 'tab:green' if _succeeded(outcome) else 'tab:red'
                value = outcome.metrics.get(key) if outcome.metrics else None
                if value is None:
                    axis.plot(values[name], top, 'x', color=colour)
                else:
                    axis.plot(values[name], scale * value, 'o', color=colour, markersize=3,
                              alpha=0.7)
            axis.axhline(scale * limit, color='tab:red', linestyle='--', linewidth=1.0)
            axis.grid(True, alpha=0.3)
        row[0].set_ylabel(label)
    for axis, name in zip(axes[-1], names):
        axis.set_xlabel(name)
    save_figure(figure, path)


def _plot_grasp(outcomes, path):
    """Histograms of the contact time gap and the largest pad slip, with their pass limits."""
    figure, axes = plt.subplots(1, 2, figsize=(9, 4))
    for axis, key in zip(axes, ('contact_time_gap', 'max_slip')):
        label, scale, limit = SENSITIVITY_METRICS[key]
        if _values(outcomes, key):
            _histogram(axis, _values(outcomes, key), label, scale, limit)
    save_figure(figure, path)


def parse_arguments(argv=None):
    """Parse dual_arm_eval's command line."""
    parser = argparse.ArgumentParser(
        prog='dual_arm_eval', description=__doc__.split('\n')[1],
        epilog='Exit code: 0 when summary.json is written and at least one trial produced '
               'metrics (failed trials are results), 1 when none did, 2 on a user error.')
    parser.add_argument('--scenario', required=True,
                        help='scenario YAML file (any file, or a name under config/scenarios); '
                             'its optional randomization block sets what varies between trials')
    parser.add_argument('--trials', type=int, default=1, help='number of trials N (default 1)')
    parser.add_argument('--out', type=Path, required=True,
                        help='output directory: summary.json, plots, trial_NNN/ folders')
    parser.add_argument('--runner', choices=RUNNERS, default='graph',
                        help='graph (default): each trial is a dual_arm_bringup run of the whole '
                             'node graph, as the product runs; inprocess: the same core objects '
                             'in one process per trial, ~8x faster, for large sweeps')
    parser.add_argument('--jobs', type=int,
                        help='trials run in parallel (default: one per core for inprocess, one '
                             'per two cores for graph, whose six node processes keep ~1.5 cores '
                             'busy); each graph trial gets a ROS domain of its own')
    parser.add_argument('--seed', type=int,
                        help="base seed of the draws (default: the scenario file's seed)")
    parser.add_argument('--keep-trajectories', action='store_true',
                        help="keep each trial's ground-truth trajectory.npz")
    parser.add_argument('--trial-timeout', type=float, default=600.0,
                        help='wall-clock limit of one graph trial [s]')
    parser.add_argument('--domain-base', type=int,
                        help='first ROS domain id of the graph trials, which use DOMAIN_BASE .. '
                             'DOMAIN_BASE + JOBS - 1 (default: random)')
    return parser.parse_args(argv)


def _check_arguments(args):
    """Return a message for the first invalid argument, or None."""
    if args.trials < 1:
        return f'--trials must be >= 1, got {args.trials}'
    if args.jobs is not None and args.jobs < 1:
        return f'--jobs must be >= 1, got {args.jobs}'
    if args.seed is not None and args.seed < 0:
        return f'--seed must be >= 0, got {args.seed}'
    if args.trial_timeout <= 0.0:
        return f'--trial-timeout must be > 0 s, got {args.trial_timeout:g}'
    if args.domain_base is not None and args.domain_base < 0:
        return f'--domain-base must be >= 0, got {args.domain_base}'
    return None


def main(argv=None):
    """Run the batch; return the exit code."""
    args = parse_arguments(argv)
    problem = _check_arguments(args)
    if problem:
        print(f'dual_arm_eval: {problem}', file=sys.stderr)
        return EXIT_USER_ERROR
    cell = load_cell()
    try:
        scenario = load_scenario(args.scenario, cell=cell)
        if args.seed is not None:
            scenario = replace(scenario, seed=args.seed)
        trials = [sample_trial(scenario, index, cell) for index in range(args.trials)]
    except ConfigError as error:
        print(f'dual_arm_eval: {error}', file=sys.stderr)
        return EXIT_USER_ERROR
    jobs = min(args.jobs or default_jobs(args.runner), args.trials)
    domain_base = (args.domain_base if args.domain_base is not None
                   else random.SystemRandom().randint(1, max(1, MAX_DOMAIN_ID - jobs + 1)))
    if args.runner == 'graph' and domain_base + jobs - 1 > MAX_DOMAIN_ID:
        print(f'dual_arm_eval: the graph trials need ROS domains {domain_base} .. '
              f'{domain_base + jobs - 1}, beyond {MAX_DOMAIN_ID}', file=sys.stderr)
        return EXIT_USER_ERROR
    try:
        args.out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        print(f'dual_arm_eval: cannot create {args.out}: {error.strerror}', file=sys.stderr)
        return EXIT_USER_ERROR
    source = scenario_path(args.scenario)
    files = []
    for index, trial in enumerate(trials):
        files.append(trial_directory(args.out, index) / 'scenario.yaml')
        write_trial_scenario(trial, files[-1], source, index)
    started = time.monotonic()
    with tqdm(total=args.trials, file=sys.stderr, unit='trial',
              desc=f'{scenario.name} ({args.runner}, {jobs} jobs)') as progress:
        outcomes = run_trials(files, args.runner, jobs, args.keep_trajectories,
                              args.trial_timeout, domain_base, progress)
    wall_time = time.monotonic() - started
    aggregate = summarize([outcome.metrics for outcome in outcomes])
    failures = [{'trial': outcome.index,
                 'reason': outcome.error or failure_reason(scenario.task, outcome.metrics)}
                for outcome in outcomes if not _succeeded(outcome)]
    summary = {'scenario': str(source), 'runner': args.runner, 'trials': aggregate['trials'],
               'jobs': jobs, 'seed': scenario.seed, 'success_rate': aggregate['success_rate'],
               'metrics': aggregate['metrics'], 'failures': failures,
               'wall_time': wall_time, 'trials_per_hour': 3600.0 * args.trials / wall_time}
    (args.out / 'summary.json').write_text(json.dumps(summary, indent=2) + '\n')
    plot_batch(outcomes, trials, scenario, args.out, cell)
    succeeded = sum(_succeeded(outcome) for outcome in outcomes)
    print(f'dual_arm_eval: {succeeded}/{args.trials} trials succeeded; '
          f'{args.out / "summary.json"}')
    return 0 if any(outcome.metrics is not None for outcome in outcomes) else 1


if __name__ == '__main__':
    sys.exit(main())
