"""
dual_arm_experiment: regenerate the paper's experiments 1, 2, 3 and 5 and docs/results.md.

`dual_arm_experiment NAME [--out DIR]`, NAME one of fast_toss (IV-A, Figures 6-7: the node graph
via dual_arm_bringup), toss_workspace (Figure 8), place_vs_toss (IV-B, Figures 9-10),
toss_to_target (landing error over the front table), report (docs/results.md from the JSON
files). Each experiment writes OUT/results.json and its PNG plots; runs are deterministic
(lockstep graph, in-process runner, fixed seeds).
"""

import argparse
from dataclasses import replace
import json
import math
from pathlib import Path
import subprocess
import sys
import tempfile
import time

from dual_arm_control.contract import ARMS
from dual_arm_control.core.ballistics import (centre_landing_height,
                                              release_velocity_minimum_speed)
from dual_arm_control.core.exceptions import ConfigError, DualArmControlError
from dual_arm_control.core.motion_generator import MotionGeneratorConfig
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.evaluation import experiment_plots as plots
from dual_arm_control.evaluation import metrics as episode_tools
from dual_arm_control.evaluation import workspace
from dual_arm_control.evaluation.episode import episode_metrics, LANDING_LIMIT
from dual_arm_control.evaluation.experiment_metrics import (
    cumulative_energy, energy_without_gravity, landing_targets, longest_toss, positive_work,
    reduction_percent, statistics)
from dual_arm_control.evaluation.paper_results import EXPERIMENTS, RESULTS_FILE
from dual_arm_control.graph import EPISODE_START_TIME
from dual_arm_control.inprocess import run_episode, RunnerConfig
from dual_arm_control.scenario import load_scenario, ReleaseConfig, scenario_path, Speeds
from dual_arm_control.trajectory_log import load_trajectory
import numpy as np

# Experiment 2: the tosses (release at paper_toss's release position) and the workspace model.
TOSS_SPEEDS = (0.6, 0.75, 0.9, 1.05)
TOSS_ELEVATIONS_DEG = (15.0, 30.0, 45.0)
TOSS_HEADINGS_DEG = (-30.0, -15.0, 0.0, 15.0, 30.0)
WORKSPACE_SAMPLES = 2000000
WORKSPACE_SEED = 7
WORKSPACE_GRID = workspace.Grid(x0=0.0, y0=-1.0, cell=0.025, nx=56, ny=80)
WORKSPACE_Z_BAND = (0.25, 0.75)
WORKSPACE_SLAB = 0.10
PAD_MAX_TILT_DEG = 30.0
# Experiment 3: task speeds, repetitions (noise seeds) and the near-zero contact probe.
TASK_SPEEDS = (0.5, 0.6, 0.7, 0.8, 0.9, 1.0)
REPEATS = 3
PLACE_DURATION = 8.0
NEAR_ZERO_IMPACT_SPEED = 0.15
# Experiment 5: the landing-target grid over the front table.
TARGET_X = (0.74, 0.79, 0.84, 0.89)
TARGET_Y = (-0.10, 0.0, 0.10)
MAX_RELEASE_SPEED = 1.05


class ExperimentError(DualArmControlError):
    """An experiment could not produce its results (a run failed to start or finish)."""


def _episode(scenario, cell, config=None):
    """Run one in-process episode; return (metrics, trajectory with t from the episode start)."""
    log = run_episode(scenario, config=config, cell=cell)
    data = log.trajectory
    result = episode_metrics(scenario, data, cell)
    return result, dict(data, t=data['t'] - EPISODE_START_TIME)


def _write(out_dir, results):
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / RESULTS_FILE).write_text(json.dumps(results, indent=1, sort_keys=True) + '\n')


def _events(result):
    contacts = [result[f't_contact_{arm}'] for arm in ARMS
                if result[f't_contact_{arm}'] is not None]
    return {'contact': min(contacts, default=None), 'release': result['t_release']}


def _header(name, runner, started, limit):
    return {'experiment': name, 'command': f'dual_arm_experiment {name}', 'runner': runner,
            'wall_time': time.monotonic() - started, 'limited': limit is not None}


def run_fast_toss(out_dir, limit=None, timeout=600.0):
    """Experiment 1: paper_toss on the node graph (dual_arm_bringup, lockstep); Figures 6-7."""
    from dual_arm_control.bringup import executable_command
    started = time.monotonic()
    cell = load_cell()
    path = scenario_path('paper_toss')
    with tempfile.TemporaryDirectory(prefix='fast_toss_') as tmp:
        command = executable_command('dual_arm_bringup') + [
            '--scenario', str(path), '--out', tmp, '--mode', 'lockstep', '--timeout',
            str(timeout)]
        graph_started = time.monotonic()
        try:
            completed = subprocess.run(command, capture_output=True, text=True,
                                       timeout=timeout + 60.0)
        except subprocess.TimeoutExpired:
            raise ExperimentError(
                f'dual_arm_bringup did not finish in {timeout + 60:g} s') from None
        graph_wall = time.monotonic() - graph_started
        metrics_path = Path(tmp) / 'metrics.json'
        if completed.returncode not in (0, 1) or not metrics_path.is_file():
            last = (completed.stderr.strip().splitlines() or ['no output'])[-1]
            raise ExperimentError(f'dual_arm_bringup exited {completed.returncode}: {last}')
        graph_metrics = json.loads(metrics_path.read_text())
        data = load_trajectory(Path(tmp) / 'trajectory.npz')
    data = dict(data, t=data['t'] - EPISODE_START_TIME)
    scenario = load_scenario(path, cell=cell)
    inprocess, _ = _episode(scenario, cell)
    compared = ('t_contact_left', 't_contact_right', 't_release', 'cycle_time',
                'release_position_error', 'landing_error')
    differences = {key: abs(graph_metrics[key] - inprocess[key]) for key in compared
                   if graph_metrics[key] is not None and inprocess[key] is not None}
    events = _events(graph_metrics)
    plots.figure6_tool_speeds(data, events, Path(out_dir) / 'fig6_tool_speeds.png')
    plots.figure6_closeup(data, events, Path(out_dir) / 'fig6_closeup.png')
    plots.figure7_object_motion(data, events, Path(out_dir) / 'fig7a_object_motion.png')
    plots.figure7_trajectories(data, Path(out_dir) / 'fig7b_trajectories_3d.png')
    grasped = np.zeros(len(data['t']), dtype=bool)
    if graph_metrics['t_grasp'] is not None and graph_metrics['t_release'] is not None:
        grasped = ((data['t'] >= graph_metrics['t_grasp'])
                   & (data['t'] <= graph_metrics['t_release']))
    object_speed = np.linalg.norm(data['object_velocity'][grasped], axis=1)
    results = _header('fast_toss', 'dual_arm_bringup (node graph, lockstep)', started, None)
    results.update({
        'scenario': 'paper_toss', 'graph_exit_code': completed.returncode,
        'graph_wall_time': graph_wall, 'metrics': graph_metrics,
        'desired_release': {'position': scenario.release.position.tolist(),
                            'velocity': scenario.release.velocity.tolist()},
        'peak_grasped_object_speed': float(object_speed.max()) if grasped.any() else None,
        'inprocess_max_difference': differences,
        'plots': ['fig6_tool_speeds.png', 'fig6_closeup.png', 'fig7a_object_motion.png',
                  'fig7b_trajectories_3d.png']})
    _write(out_dir, results)
    return results


def toss_release_velocities(limit=None):
    """Return [(speed [m/s], elevation [deg], heading [deg], velocity (3,))] of experiment 2."""
    tosses = []
    for speed in TOSS_SPEEDS:
        for elevation in TOSS_ELEVATIONS_DEG:
            for heading in TOSS_HEADINGS_DEG:
                e, h = math.radians(elevation), math.radians(heading)
                velocity = speed * np.array([math.cos(e) * math.cos(h),
                                             math.cos(e) * math.sin(h), math.sin(e)])
                tosses.append((speed, elevation, heading, velocity))
    return tosses[:limit]


def _flight(data, result, object_height, cell):
    """Return the object's path (N, 3) from release to landing, every 10 ms."""
    t = data['t']
    release = int(np.searchsorted(t, result['t_release'] - 1e-9))
    landed = episode_tools.landing_index(t, data['object_position'], release + 1,
                                         0.5 * object_height, cell.surface_height)
    end = len(t) if landed is None else landed + 1
    return data['object_position'][release:end:5]


def run_toss_workspace(out_dir, limit=None):
    """Experiment 2: landings of many tosses against the joint reachable space; Figure 8."""
    started = time.monotonic()
    cell = load_cell()
    base = load_scenario('paper_toss', cell=cell)
    tosses, flights, landings = [], [], []
    for speed, elevation, heading, velocity in toss_release_velocities(limit):
        scenario = replace(base, release=ReleaseConfig(base.release.position, velocity),
                           speeds=replace(base.speeds, toss=speed))
        result, data = _episode(scenario, cell)
        landing = result['landing_position']
        valid = (result['t_grasp'] is not None and result['t_release'] is not None
                 and landing is not None and cell.front_table.covers(*landing[:2]))
        tosses.append({'speed': speed, 'elevation_deg': elevation, 'heading_deg': heading,
                       'release_velocity_desired': velocity.tolist(), 'valid': valid,
                       'success': result['success'], 'landing_position': landing,
                       'release_position': result['release_position'],
                       'release_velocity': result['release_velocity'],
                       'release_position_error': result['release_position_error'],
                       'release_velocity_error': result['release_velocity_error'],
                       'landing_prediction_error': result.get('landing_prediction_error'),
                       'max_slip': result['max_slip']})
        if valid:
            landings.append(landing[:2])
            flights.append(_flight(data, result, base.object.size[2], cell))
    samples = WORKSPACE_SAMPLES if limit is None else min(WORKSPACE_SAMPLES, 20000 * limit)
    reachable = {arm: workspace.pad_facing_tool_positions(
        arm_model(arm, cell), arm, samples, np.random.default_rng(WORKSPACE_SEED),
        math.radians(PAD_MAX_TILT_DEG)) for arm in ARMS}
    grid = WORKSPACE_GRID
    joint = workspace.joint_reachable_mask(reachable['left'], reachable['right'],
                                           0.5 * base.object.size[1], grid, WORKSPACE_Z_BAND,
                                           WORKSPACE_SLAB)
    hull = workspace.convex_hull(np.array(landings)) if landings else np.zeros((0, 2))
    toss_mask = workspace.polygon_mask(hull, grid)
    added, extension = workspace.extension_percent(joint, toss_mask)
    xs, ys = grid.centres()
    centre_row = joint[:, int(np.argmin(np.abs(ys)))]
    release = base.release.position
    drop = release[2] - centre_landing_height(cell.front_table.top_height, base.object.size[2])
    speeds = sorted({toss[0] for toss in toss_release_velocities(limit)})
    plots.figure8_top_view(grid, joint, toss_mask, added, hull, np.array(landings), cell,
                           Path(out_dir) / 'fig8_top_view.png')
    plots.figure8_trajectories(flights, reachable, cell, Path(out_dir) / 'fig8_trajectories.png',
                               WORKSPACE_Z_BAND)
    results = _header('toss_workspace', 'in-process (dual_arm_control.inprocess)', started,
                      limit)
    results.update({
        'tosses': tosses, 'toss_count': len(tosses), 'valid_count': len(landings),
        'success_count': sum(1 for toss in tosses if toss['success']),
        'release_position': base.release.position.tolist(),
        'method': {'samples_per_arm': samples, 'seed': WORKSPACE_SEED,
                   'kept_samples': {arm: len(reachable[arm]) for arm in ARMS},
                   'pad_max_tilt_deg': PAD_MAX_TILT_DEG, 'z_band': list(WORKSPACE_Z_BAND),
                   'slab_height': WORKSPACE_SLAB, 'half_width': 0.5 * base.object.size[1],
                   'grid': {'x0': grid.x0, 'y0': grid.y0, 'cell': grid.cell, 'nx': grid.nx,
                            'ny': grid.ny}},
        'joint_area': workspace.mask_area(joint, grid),
        'toss_area': workspace.mask_area(toss_mask, grid),
        'toss_hull_area': workspace.polygon_area(hull),
        'added_area': workspace.mask_area(added, grid),
        'extension_percent': extension,
        'joint_max_x_at_y0': float(xs[centre_row].max()) if centre_row.any() else None,
        'longest_toss': longest_toss(speeds[-1], drop), 'fastest_toss': speeds[-1],
        'farthest_landing': max((float(np.hypot(*(np.asarray(p) - release[:2])))
                                 for p in landings), default=None),
        'landing_extent': {'x': [float(min(p[0] for p in landings)),
                                 float(max(p[0] for p in landings))] if landings else None,
                           'y': [float(min(p[1] for p in landings)),
                                 float(max(p[1] for p in landings))] if landings else None},
        'plots': ['fig8_top_view.png', 'fig8_trajectories.png']})
    _write(out_dir, results)
    return results


def _task_runs(task, speed, seed, cell, bases, impact=None):
    """Run one pick_and_place or pick_and_toss episode at task speed v; return (row, data)."""
    base = bases[task]
    if task == 'pick_and_toss':
        direction = base.release.velocity / np.linalg.norm(base.release.velocity)
        scenario = replace(base, seed=seed, speeds=Speeds(reach=speed, impact=base.speeds.impact,
                                                          toss=speed),
                           release=ReleaseConfig(base.release.position, speed * direction))
        config = None
    else:
        scenario = replace(base, seed=seed, duration=PLACE_DURATION, speeds=Speeds(
            reach=speed, impact=impact or base.speeds.impact, toss=speed))
        motion = MotionGeneratorConfig()
        config = RunnerConfig(motion_base=replace(motion, place=replace(motion.place,
                                                                        max_speed=speed)))
    result, data = _episode(scenario, cell, config)
    t = data['t']
    end = len(t) if result['cycle_time'] is None else int(np.searchsorted(
        t, result['cycle_time'] - 1e-9)) + 1
    row = {'task': task, 'speed': speed, 'seed': seed, 'impact_speed_setting':
           scenario.speeds.impact}
    for key in ('success', 'cycle_time', 'energy_left', 'energy_right', 'max_slip',
                'impact_speed_left', 'impact_speed_right', 't_release', 'landing_error',
                'place_position_error', 'release_position_error', 'release_velocity_error'):
        row[key] = result.get(key)
    row['release_speed'] = (None if result['release_velocity'] is None
                            else float(np.linalg.norm(result['release_velocity'])))
    row['energy'] = result['energy_left'] + result['energy_right']
    row['positive_work'] = sum(positive_work(t[:end], data[f'{arm}_tau'][:end],
                                             data[f'{arm}_dq'][:end]) for arm in ARMS)
    row['energy_without_gravity'] = 0.0
    for arm in ARMS:
        model = arm_model(arm, cell)
        gravity = np.array([model.gravity_torque(q) for q in data[f'{arm}_q'][:end]])
        row['energy_without_gravity'] += energy_without_gravity(
            t[:end], data[f'{arm}_tau'][:end], data[f'{arm}_dq'][:end], gravity)
    return row, data


def run_place_vs_toss(out_dir, limit=None, repeats=REPEATS):
    """Experiment 3: cycle time and energy of pick-and-place vs pick-and-toss; Figures 9-10."""
    started = time.monotonic()
    cell = load_cell()
    bases = {'pick_and_toss': load_scenario('paper_toss', cell=cell),
             'pick_and_place': load_scenario('paper_place', cell=cell)}
    speeds = TASK_SPEEDS[:limit]
    runs, series, summary = [], {}, []
    for speed in speeds:
        per_task = {}
        for task in bases:
            rows = []
            for repeat in range(repeats):
                row, data = _task_runs(task, speed, bases[task].seed + repeat, cell, bases)
                rows.append(row)
                if speed == speeds[-1]:
                    series.setdefault(task, []).append(data)
            runs.extend(rows)
            per_task[task] = {key: statistics([row[key] for row in rows]) for key in (
                'cycle_time', 'energy', 'energy_left', 'energy_right', 'positive_work',
                'energy_without_gravity', 'max_slip', 'impact_speed_left',
                'impact_speed_right', 'release_speed')}
            per_task[task]['successes'] = sum(1 for row in rows if row['success'])
            per_task[task]['runs'] = len(rows)
        place, toss = per_task['pick_and_place'], per_task['pick_and_toss']
        summary.append({'speed': speed, 'pick_and_place': place, 'pick_and_toss': toss, **{
            f'{key}_reduction_percent': reduction_percent(place[key]['mean'],
                                                          toss[key]['mean'])
            for key in ('cycle_time', 'energy', 'positive_work', 'energy_without_gravity')}})
    probe, _ = _task_runs('pick_and_place', speeds[-1], bases['pick_and_place'].seed, cell,
                          bases, impact=NEAR_ZERO_IMPACT_SPEED)
    plots.figure9_speeds(series, Path(out_dir) / 'fig9a_speeds.png', speeds[-1])
    plots.figure9_energy(series, Path(out_dir) / 'fig9b_energy.png', speeds[-1],
                         cumulative_energy)
    plots.figure10_bars(summary, Path(out_dir) / 'fig10_time_energy.png')
    results = _header('place_vs_toss', 'in-process (dual_arm_control.inprocess)', started,
                      limit)
    results.update({
        'speeds': list(speeds), 'repeats': repeats, 'runs': runs, 'summary': summary,
        'near_zero_contact_probe': probe,
        'settings': {'toss_scenario': 'paper_toss', 'place_scenario': 'paper_place',
                     'place_target': bases['pick_and_place'].place.tolist(),
                     'toss_release_position': bases['pick_and_toss'].release.position.tolist(),
                     'impact_speed': bases['pick_and_toss'].speeds.impact,
                     'place_duration': PLACE_DURATION},
        'plots': ['fig9a_speeds.png', 'fig9b_energy.png', 'fig10_time_energy.png']})
    _write(out_dir, results)
    return results


def run_toss_to_target(out_dir, limit=None):
    """Experiment 5: toss_to_target over a grid of landing targets on the front table."""
    started = time.monotonic()
    cell = load_cell()
    base = load_scenario('paper_toss', cell=cell)
    release_position = np.asarray(MotionGeneratorConfig().toss.release_position)
    targets = landing_targets(cell, base.object.size, release_position, TARGET_X, TARGET_Y,
                              MAX_RELEASE_SPEED)[:limit]
    rows = []
    for target in targets:
        scenario = replace(base, task='toss_to_target', release=None, landing_target=target)
        result, _ = _episode(scenario, cell)
        solution = release_velocity_minimum_speed(release_position, target)
        error = result['landing_error']
        rows.append({
            'target': target.tolist(), 'release_speed_planned': solution.speed,
            'release_elevation_deg': math.degrees(solution.elevation),
            'landing_position': result['landing_position'], 'landing_error': error,
            'hit': error is not None and error <= LANDING_LIMIT, 'success': result['success'],
            'release_position_error': result['release_position_error'],
            'release_velocity_error': result['release_velocity_error'],
            'landing_prediction_error': result.get('landing_prediction_error'),
            'max_slip': result['max_slip'], 'contact_time_gap': result['contact_time_gap']})
    plots.landing_errors(rows, cell, Path(out_dir) / 'landing_errors.png')
    errors = [row['landing_error'] for row in rows]
    shortfalls = [float(np.hypot(*(np.asarray(row['target'][:2]) - release_position[:2]))
                        - np.hypot(*(np.asarray(row['landing_position'][:2])
                                     - release_position[:2])))
                  for row in rows if row['landing_position'] is not None]
    results = _header('toss_to_target', 'in-process (dual_arm_control.inprocess)', started,
                      limit)
    results.update({
        'release_position': release_position.tolist(), 'targets': rows,
        'landing_error': {**statistics(errors), 'max': max(
            (e for e in errors if e is not None), default=None), 'missing': sum(
            1 for e in errors if e is None)},
        'shortfall': statistics(shortfalls),
        'release_position_error': statistics([row['release_position_error'] for row in rows]),
        'landing_prediction_error': statistics([row['landing_prediction_error']
                                                for row in rows]),
        'hit_count': sum(1 for row in rows if row['hit']),
        'success_count': sum(1 for row in rows if row['success']), 'landing_limit': LANDING_LIMIT,
        'max_release_speed': MAX_RELEASE_SPEED, 'plots': ['landing_errors.png']})
    _write(out_dir, results)
    return results


RUNNERS = {'fast_toss': run_fast_toss, 'toss_workspace': run_toss_workspace,
           'place_vs_toss': run_place_vs_toss, 'toss_to_target': run_toss_to_target}


def parse_arguments(argv=None):
    """Parse the command line."""
    parser = argparse.ArgumentParser(
        prog='dual_arm_experiment', description=__doc__.split('\n')[1])
    parser.add_argument('name', choices=EXPERIMENTS + ('report',),
                        help='experiment to regenerate, or report (docs/results.md)')
    parser.add_argument('--out', type=Path,
                        help='output directory (default docs/results/NAME); for report the '
                             'markdown file (default docs/results.md)')
    parser.add_argument('--results', type=Path, default=Path('docs/results'),
                        help="report only: directory holding the experiments' results")
    parser.add_argument('--limit', type=int,
                        help='quick check: only the first N tosses / speeds / targets '
                             '(toss_workspace also samples fewer arm configurations)')
    parser.add_argument('--repeats', type=int, default=REPEATS,
                        help='place_vs_toss only: runs per task and speed (noise seeds)')
    return parser.parse_args(argv)


def main(argv=None):
    """Run one experiment or the report; return the exit code."""
    args = parse_arguments(argv)
    if args.limit is not None and args.limit < 1:
        print(f'dual_arm_experiment: --limit must be >= 1, got {args.limit}', file=sys.stderr)
        return 2
    if args.repeats < 1:
        print(f'dual_arm_experiment: --repeats must be >= 1, got {args.repeats}',
              file=sys.stderr)
        return 2
    try:
        if args.name == 'report':
            from dual_arm_control.evaluation.report import write_report
            out = args.out or Path('docs/results.md')
            write_report(args.results, out)
            print(f'dual_arm_experiment: wrote {out}')
            return 0
        out = args.out or Path('docs/results') / args.name
        kwargs = {'limit': args.limit}
        if args.name == 'place_vs_toss':
            kwargs['repeats'] = args.repeats
        results = RUNNERS[args.name](out, **kwargs)
    except ConfigError as error:
        print(f'dual_arm_experiment: {error}', file=sys.stderr)
        return 2
    except (DualArmControlError, OSError) as error:
        print(f'dual_arm_experiment: {args.name} failed: {error}', file=sys.stderr)
        return 1
    print(f'dual_arm_experiment: {args.name} done in {results["wall_time"]:.1f} s, results in '
          f'{out / RESULTS_FILE}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
