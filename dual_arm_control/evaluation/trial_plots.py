"""
dual_arm_eval's batch plots: metric histograms, landing positions and sensitivity to the draws.

Written as PNG files into the batch's output folder, green for trials that passed and red for
those that failed, with the pass limits of evaluation/episode.py.
"""

import math
from pathlib import Path

from dual_arm_control.evaluation.episode import (CONTACT_GAP_LIMIT, LANDING_LIMIT,
                                                 RELEASE_POSITION_LIMIT, RELEASE_VELOCITY_LIMIT,
                                                 SLIP_LIMIT)
from dual_arm_control.evaluation.plots import save_figure
from dual_arm_control.evaluation.trial_summary import succeeded
from dual_arm_control.runtime.configuration import predicted_landing
from dual_arm_control.scenario import TOSS_TASKS
import matplotlib
matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402, I100  (the backend is chosen before pyplot loads)
import numpy as np  # noqa: E402, I100

# Pass/fail metrics plotted against the randomized quantities: (label, scale, limit or None).
SENSITIVITY_METRICS = {
    'contact_time_gap': ('contact time gap [ms]', 1000.0, CONTACT_GAP_LIMIT),
    'max_slip': ('max pad slip [cm]', 100.0, SLIP_LIMIT),
    'landing_error': ('landing error [cm]', 100.0, LANDING_LIMIT),
    'landing_error_in_container': ('distance to the container centre [cm]', 100.0, None),
}


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
    belt = trial.conveyor if trial.conveyor is not None else trial.incoming_belt
    if spec.belt_speed is not None:
        values['belt speed [m/s]'] = belt.speed
    if spec.container_start is not None:
        values['container start y [m]'] = trial.conveyor.container_start
    if spec.container_start_time is not None:
        values['belt start time [s]'] = trial.conveyor.container_start_time
    if spec.belt_start_time is not None:
        values['belt start time [s]'] = trial.incoming_belt.start_time
    return values


def landing_goal(trial, cell):
    """Return the landing point trial's landing_error is measured from, or None."""
    if trial.task not in TOSS_TASKS:
        return None
    if trial.landing_target is not None:
        return np.asarray(trial.landing_target, dtype=float)
    return predicted_landing(trial.release.position, trial.release.velocity,
                             trial.object.size[2], cell)


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
    if _values(outcomes, 'landing_offset_in_container'):
        _plot_container_landings(outcomes, trials, out_dir / 'container_landings.png')
        written.append('container_landings.png')
    drawn = [randomized_values(scenario, trial) for trial in trials]
    if drawn and drawn[0] and _plot_sensitivity(outcomes, drawn, out_dir / 'sensitivity.png'):
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
                      color='tab:green' if succeeded(outcome) else 'tab:red')
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


def _plot_container_landings(outcomes, trials, path):
    """Where the box passed the container's rim, relative to its centre, inside the opening."""
    figure, axis = plt.subplots(figsize=(6, 5))
    conveyor, box = trials[0].conveyor, trials[0].object.size
    for size, style, label in ((conveyor.inner_size, '-', 'opening'),
                               (np.asarray(conveyor.inner_size) - box[:2], '--',
                                'box centre clears the walls')):
        axis.add_patch(plt.Rectangle((-0.5 * size[0] * 100, -0.5 * size[1] * 100),
                                     size[0] * 100, size[1] * 100, fill=False,
                                     linestyle=style, color='k', label=label))
    for outcome, trial in zip(outcomes, trials):
        offset = outcome.metrics and outcome.metrics.get('landing_offset_in_container')
        if offset is not None:
            axis.plot(100 * offset[0], 100 * offset[1], 'o', markersize=4, alpha=0.7,
                      color='tab:green' if succeeded(outcome) else 'tab:red')
    axis.plot([], [], 'o', color='tab:green', label='trial passed')
    axis.plot([], [], 'o', color='tab:red', label='trial failed')
    axis.set_aspect('equal', adjustable='datalim')
    axis.set_xlabel('box centre - container centre, world x (across the belt) [cm]')
    axis.set_ylabel('world y (along the belt) [cm]')
    axis.grid(True, alpha=0.3)
    axis.legend(fontsize=8)
    save_figure(figure, path)


def _plot_sensitivity(outcomes, drawn, path):
    """
    Each pass/fail metric against each randomized quantity (green: trial passed, red: failed).

    A trial without the metric (no contact, no landing) is an x at the top of its panel.
    Return whether the figure was written: not when no trial has any of the metrics.
    """
    names = list(drawn[0])
    rows = [key for key in SENSITIVITY_METRICS if _values(outcomes, key)]
    if not rows:
        return False
    figure, axes = plt.subplots(len(rows), len(names), figsize=(3.6 * len(names), 3 * len(rows)),
                                sharex='col', sharey='row', squeeze=False)
    for row, key in zip(axes, rows):
        label, scale, limit = SENSITIVITY_METRICS[key]
        top = scale * max(_values(outcomes, key) + ([] if limit is None else [limit])) * 1.1
        for axis, name in zip(row, names):
            for outcome, values in zip(outcomes, drawn):
                colour = 'tab:green' if succeeded(outcome) else 'tab:red'
                value = outcome.metrics.get(key) if outcome.metrics else None
                if value is None:
                    axis.plot(values[name], top, 'x', color=colour)
                else:
                    axis.plot(values[name], scale * value, 'o', color=colour, markersize=3,
                              alpha=0.7)
            if limit is not None:
                axis.axhline(scale * limit, color='tab:red', linestyle='--', linewidth=1.0)
            axis.grid(True, alpha=0.3)
        row[0].set_ylabel(label)
    for axis, name in zip(axes[-1], names):
        axis.set_xlabel(name)
    save_figure(figure, path)
    return True


def _plot_grasp(outcomes, path):
    """Histograms of the contact time gap and the largest pad slip, with their pass limits."""
    figure, axes = plt.subplots(1, 2, figsize=(9, 4))
    for axis, key in zip(axes, ('contact_time_gap', 'max_slip')):
        label, scale, limit = SENSITIVITY_METRICS[key]
        if _values(outcomes, key):
            _histogram(axis, _values(outcomes, key), label, scale, limit)
    save_figure(figure, path)
