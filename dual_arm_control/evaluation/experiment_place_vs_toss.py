"""
The paper's experiment 3 (IV-B, Figures 9-10): cycle time and energy, pick-and-place vs toss.

At each task speed both tasks run REPEATS times (sensor-noise seeds) on the in-process runner.
The pick-and-place baseline is the paper's: it contacts the object at near-zero speed (0.11 m/s)
and puts it down at rest. One more pick-and-place run grabs at the toss's impact speed, to
separate the gain of the impact from that of the toss. Writes OUT/results.json and plots.
"""

from dataclasses import replace
from pathlib import Path
import time

from dual_arm_control.contract import ARMS
from dual_arm_control.core.motion_config import MotionGeneratorConfig
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.evaluation import experiment_plots as plots
from dual_arm_control.evaluation.experiment_metrics import (
    cumulative_energy, energy_without_gravity, positive_work, reduction_percent, signed_work,
    statistics)
from dual_arm_control.evaluation.experiment_runs import (results_header, run_inprocess_episode,
                                                         write_results)
from dual_arm_control.evaluation.paper_results import PAPER_RESULTS
from dual_arm_control.inprocess import RunnerConfig
from dual_arm_control.scenario import load_scenario, ReleaseConfig, Speeds
import numpy as np

# Experiment 3: task speeds, repetitions (noise seeds) and the near-zero contact probe.
TASK_SPEEDS = (0.5, 0.75, 1.0)
REPEATS = 10
PLACE_DURATION = 8.0
PLACE_IMPACT_SPEED = PAPER_RESULTS['place_contact_speed']['value']
# The near-zero-speed place decelerates from v to its contact speed between these distances
# to the grasp points [m]; with the reach-with-impact profile (0.5-0.25 m) it would crawl
# the last 25 cm at 0.11 m/s (contact at 5.3 s instead of 1.3 s at v = 1.0 m/s).
PLACE_SLOWDOWN = (0.05, 0.25)


def _task_runs(task, speed, seed, cell, bases, impact=None):
    """
    Run one pick_and_place or pick_and_toss episode at task speed v; return (row, data).

    impact [m/s] sets the pick-and-place contact speed; the toss keeps its scenario's.
    """
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
        motion = replace(motion, place=replace(motion.place, max_speed=speed))
        if impact is not None and impact < base.speeds.impact:
            motion = replace(motion, speed=replace(motion.speed, near_distance=PLACE_SLOWDOWN[0],
                                                   far_distance=PLACE_SLOWDOWN[1]))
        config = RunnerConfig(motion_base=motion)
    result, data = run_inprocess_episode(scenario, cell, config)
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
    row['signed_work'] = sum(signed_work(t[:end], data[f'{arm}_tau'][:end],
                                         data[f'{arm}_dq'][:end]) for arm in ARMS)
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
                row, data = _task_runs(task, speed, bases[task].seed + repeat, cell, bases,
                                       impact=PLACE_IMPACT_SPEED)
                rows.append(row)
                if speed == speeds[-1]:
                    series.setdefault(task, []).append(data)
            runs.extend(rows)
            per_task[task] = {key: statistics([row[key] for row in rows]) for key in (
                'cycle_time', 'energy', 'energy_left', 'energy_right', 'signed_work',
                'positive_work',
                'energy_without_gravity', 'max_slip', 'impact_speed_left',
                'impact_speed_right', 'release_speed')}
            per_task[task]['successes'] = sum(1 for row in rows if row['success'])
            per_task[task]['runs'] = len(rows)
        place, toss = per_task['pick_and_place'], per_task['pick_and_toss']
        summary.append({'speed': speed, 'pick_and_place': place, 'pick_and_toss': toss, **{
            f'{key}_reduction_percent': reduction_percent(place[key]['mean'],
                                                          toss[key]['mean'])
            for key in ('cycle_time', 'energy', 'signed_work', 'positive_work',
                        'energy_without_gravity')}})
    probe, _ = _task_runs('pick_and_place', speeds[-1], bases['pick_and_place'].seed, cell,
                          bases, impact=bases['pick_and_toss'].speeds.impact)
    plots.figure9_speeds(series, Path(out_dir) / 'fig9a_speeds.png', speeds[-1])
    plots.figure9_energy(series, Path(out_dir) / 'fig9b_energy.png', speeds[-1],
                         cumulative_energy)
    plots.figure10_bars(summary, Path(out_dir) / 'fig10_time_energy.png')
    results = results_header('place_vs_toss', 'in-process (dual_arm_control.inprocess)',
                             started, limit)
    results.update({
        'speeds': list(speeds), 'repeats': repeats, 'runs': runs, 'summary': summary,
        'equal_impact_probe': probe,
        'settings': {'toss_scenario': 'paper_toss', 'place_scenario': 'paper_place',
                     'place_target': bases['pick_and_place'].place.tolist(),
                     'toss_release_position': bases['pick_and_toss'].release.position.tolist(),
                     'impact_speed': bases['pick_and_toss'].speeds.impact,
                     'place_impact_speed': PLACE_IMPACT_SPEED,
                     'place_slowdown': list(PLACE_SLOWDOWN),
                     'place_duration': PLACE_DURATION},
        'plots': ['fig9a_speeds.png', 'fig9b_energy.png', 'fig10_time_energy.png']})
    write_results(out_dir, results)
    return results
