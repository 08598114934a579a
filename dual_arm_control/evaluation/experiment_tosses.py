"""
The paper's tossing experiments: 1 fast_toss, 2 toss_workspace and 5 toss_to_target.

fast_toss runs paper_toss on the node graph (dual_arm_bringup, lockstep; Figures 6-7),
toss_workspace compares many tosses' landings with the joint reachable space (Figure 8),
toss_to_target measures the landing error over a grid of targets on the front table. Each
writes OUT/results.json and its plots.
"""

from dataclasses import replace
import math
from pathlib import Path
import tempfile
import time

from dual_arm_control.contract import ARMS
from dual_arm_control.core.ballistics import centre_landing_height
from dual_arm_control.core.motion_config import MotionGeneratorConfig
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.evaluation import experiment_plots as plots
from dual_arm_control.evaluation import metrics as episode_tools
from dual_arm_control.evaluation import workspace
from dual_arm_control.evaluation.episode import LANDING_LIMIT
from dual_arm_control.evaluation.experiment_metrics import (landing_targets, longest_toss,
                                                            served_region_corners, statistics)
from dual_arm_control.evaluation.experiment_runs import (results_header, run_graph_episode,
                                                         run_inprocess_episode, write_results)
from dual_arm_control.graph import EPISODE_START_TIME
from dual_arm_control.runtime.configuration import motion_config_for_scenario
from dual_arm_control.scenario import load_scenario, scenario_path
from dual_arm_control.trajectory_log import load_trajectory
import numpy as np

# Experiment 2: tosses planned for landing targets over a wide grid, and the workspace model.
WORKSPACE_TARGET_X = (0.75, 0.85, 0.95, 1.05, 1.15)
WORKSPACE_TARGET_Y = (-0.45, -0.30, -0.15, 0.0, 0.15, 0.30, 0.45)
# The corners of the region the planner serves, from a grid this fine [m], are tossed to as well.
WORKSPACE_CORNER_STEP = 0.02
WORKSPACE_SAMPLES = 2000000
WORKSPACE_SEED = 7
WORKSPACE_GRID = workspace.Grid(x0=0.0, y0=-1.0, cell=0.025, nx=56, ny=80)
WORKSPACE_Z_BAND = (0.25, 0.75)
WORKSPACE_SLAB = 0.10
PAD_MAX_TILT_DEG = 30.0
# Experiment 5: the landing-target grid over the front table, 0.4 m x 0.6 m.
TARGET_X = (0.75, 0.85, 0.95, 1.05, 1.15)
TARGET_Y = (-0.30, -0.15, 0.0, 0.15, 0.30)


def _events(result):
    """Return the first pad contact and the release instant of an episode's metrics."""
    contacts = [result[f't_contact_{arm}'] for arm in ARMS
                if result[f't_contact_{arm}'] is not None]
    return {'contact': min(contacts, default=None), 'release': result['t_release']}


def run_fast_toss(out_dir, limit=None, timeout=600.0):
    """Experiment 1: paper_toss on the node graph (dual_arm_bringup, lockstep); Figures 6-7."""
    started = time.monotonic()
    cell = load_cell()
    path = scenario_path('paper_toss')
    with tempfile.TemporaryDirectory(prefix='fast_toss_') as tmp:
        graph_started = time.monotonic()
        graph_metrics = run_graph_episode(path, tmp, timeout)
        graph_wall = time.monotonic() - graph_started
        data = load_trajectory(Path(tmp) / 'trajectory.npz')
    data = dict(data, t=data['t'] - EPISODE_START_TIME)
    scenario = load_scenario(path, cell=cell)
    inprocess, _ = run_inprocess_episode(scenario, cell)
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
    results = results_header('fast_toss', 'dual_arm_bringup (node graph, lockstep)', started, None)
    results.update({
        'scenario': 'paper_toss',
        'graph_wall_time': graph_wall, 'metrics': graph_metrics,
        'desired_release': {'position': scenario.release.position.tolist(),
                            'velocity': scenario.release.velocity.tolist()},
        'peak_grasped_object_speed': float(object_speed.max()) if grasped.any() else None,
        'inprocess_max_difference': differences,
        'plots': ['fig6_tool_speeds.png', 'fig6_closeup.png', 'fig7a_object_motion.png',
                  'fig7b_trajectories_3d.png']})
    write_results(out_dir, results)
    return results


def _toss_for_target(base, target, cell):
    """
    Return (scenario, planned TossConfig, elevation [deg], heading [deg]) of base tossed to target.

    The scenario is base as toss_to_target with that landing target; the TossConfig is the
    release state the motion generator plans for it.
    """
    scenario = replace(base, task='toss_to_target', release=None, landing_target=target,
                       speeds=replace(base.speeds, toss=None))
    toss = motion_config_for_scenario(scenario, cell).toss
    direction = np.asarray(toss.release_direction)
    return (scenario, toss, math.degrees(math.asin(direction[2])),
            math.degrees(math.atan2(direction[1], direction[0])))


def _flight(data, result, object_height, cell):
    """Return the object's path (N, 3) from release to landing, every 10 ms."""
    t = data['t']
    release = int(np.searchsorted(t, result['t_release'] - 1e-9))
    landed = episode_tools.landing_index(t, data['object_position'], release + 1,
                                         0.5 * object_height, cell.surface_height)
    end = len(t) if landed is None else landed + 1
    return data['object_position'][release:end:5]


def _tossing_space(landings, joint, grid):
    """Return (hull, its grid mask, the mask outside the joint space, extension [%])."""
    hull = workspace.convex_hull(np.array(landings)) if landings else np.zeros((0, 2))
    toss_mask = workspace.polygon_mask(hull, grid)
    return (hull, toss_mask, *workspace.extension_percent(joint, toss_mask))


def run_toss_workspace(out_dir, limit=None):
    """Experiment 2: landings of many tosses against the joint reachable space; Figure 8."""
    started = time.monotonic()
    cell = load_cell()
    base = load_scenario('paper_toss', cell=cell)
    tosses, flights, landings = [], [], []
    planning = MotionGeneratorConfig().release_planning
    grid_targets, _ = landing_targets(cell, base.object.size, WORKSPACE_TARGET_X,
                                      WORKSPACE_TARGET_Y, planning)
    corners = served_region_corners(cell, base.object.size, planning, WORKSPACE_CORNER_STEP)
    targets = np.vstack((grid_targets, corners))
    for target in targets[:limit]:
        scenario, toss, elevation, heading = _toss_for_target(base, target, cell)
        result, data = run_inprocess_episode(scenario, cell)
        landing = result['landing_position']
        valid = (result['t_grasp'] is not None and result['t_release'] is not None
                 and landing is not None and cell.front_table.covers(*landing[:2]))
        tosses.append({'target': target.tolist(), 'speed': toss.toss_speed,
                       'elevation_deg': elevation, 'heading_deg': heading,
                       'release_position_planned': list(toss.release_position),
                       'valid': valid, 'success': result['success'], 'landing_position': landing,
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
    hull, toss_mask, added, extension = _tossing_space(landings, joint, grid)
    on_target = [toss['landing_position'][:2] for toss in tosses if toss['success']]
    extension_on_target = _tossing_space(on_target, joint, grid)[3]
    xs, ys = grid.centres()
    centre_row = joint[:, int(np.argmin(np.abs(ys)))]
    release = np.asarray(MotionGeneratorConfig().toss.release_position)
    drop = release[2] - centre_landing_height(cell.front_table.top_height, base.object.size[2])
    speeds = sorted(toss['speed'] for toss in tosses) or [0.0]
    plots.figure8_top_view(grid, joint, toss_mask, added, hull, np.array(landings), cell,
                           Path(out_dir) / 'fig8_top_view.png')
    plots.figure8_trajectories(flights, reachable, cell, Path(out_dir) / 'fig8_trajectories.png',
                               WORKSPACE_Z_BAND)
    results = results_header('toss_workspace', 'in-process (dual_arm_control.inprocess)',
                             started, limit)
    results.update({
        'tosses': tosses, 'toss_count': len(tosses), 'valid_count': len(landings),
        'success_count': sum(1 for toss in tosses if toss['success']),
        'release_position': release.tolist(),
        'target_grid': {'x': list(WORKSPACE_TARGET_X), 'y': list(WORKSPACE_TARGET_Y),
                        'served_region_corners': corners.tolist(),
                        'corner_grid_step': WORKSPACE_CORNER_STEP},
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
        'extension_percent_on_target': extension_on_target,
        'joint_max_x_at_y0': float(xs[centre_row].max()) if centre_row.any() else None,
        'longest_toss': longest_toss(speeds[-1], drop), 'fastest_toss': speeds[-1],
        'farthest_landing': max((float(np.hypot(*(np.asarray(p) - release[:2])))
                                 for p in landings), default=None),
        'landing_extent': {'x': [float(min(p[0] for p in landings)),
                                 float(max(p[0] for p in landings))] if landings else None,
                           'y': [float(min(p[1] for p in landings)),
                                 float(max(p[1] for p in landings))] if landings else None},
        'plots': ['fig8_top_view.png', 'fig8_trajectories.png']})
    write_results(out_dir, results)
    return results


def run_toss_to_target(out_dir, limit=None):
    """
    Experiment 5: toss_to_target over a grid of landing targets on the front table.

    Each target's release state (point, direction, speed) comes from the release planner
    (core.toss_planning); a target it refuses is listed with its reason, not attempted.
    """
    started = time.monotonic()
    cell = load_cell()
    base = load_scenario('paper_toss', cell=cell)
    planning = MotionGeneratorConfig().release_planning
    targets, refused = landing_targets(cell, base.object.size, TARGET_X, TARGET_Y, planning)
    rows = []
    for target in targets[:limit]:
        scenario, toss, elevation, _ = _toss_for_target(base, target, cell)
        result, _ = run_inprocess_episode(scenario, cell)
        error = result['landing_error']
        rows.append({
            'target': target.tolist(), 'release_position_planned': list(toss.release_position),
            'release_speed_planned': toss.toss_speed,
            'release_elevation_deg': elevation,
            'landing_position': result['landing_position'], 'landing_error': error,
            'landing_offset': None if result['landing_position'] is None else
            (np.asarray(result['landing_position'][:2]) - target[:2]).tolist(),
            'hit': error is not None and error <= LANDING_LIMIT, 'success': result['success'],
            'max_joint_speed_ratio': max(result[f'max_joint_speed_ratio_{arm}'] for arm in ARMS),
            **{key: result.get(key) for key in (
                'release_position_error', 'release_speed_error', 'release_direction_error',
                'release_velocity_error', 'landing_prediction_error', 'max_slip',
                'contact_time_gap')}})
    plots.landing_errors(rows, cell, Path(out_dir) / 'landing_errors.png')
    errors = [row['landing_error'] for row in rows]
    offsets = np.array([row['landing_offset'] for row in rows
                        if row['landing_offset'] is not None]).reshape(-1, 2)
    present = [e for e in errors if e is not None]
    results = results_header('toss_to_target', 'in-process (dual_arm_control.inprocess)',
                             started, limit)
    results.update({
        'targets': rows, 'grid': {'x': list(TARGET_X), 'y': list(TARGET_Y)},
        'refused': [{'target': target.tolist(), 'reason': reason} for target, reason in refused],
        'landing_error': {**statistics(errors), 'max': max(present, default=None),
                          'median': float(np.median(present)) if present else None,
                          'p95': float(np.percentile(present, 95)) if present else None,
                          'missing': sum(1 for e in errors if e is None)},
        'landing_bias': offsets.mean(axis=0).tolist() if len(offsets) else None,
        **{key: statistics([row[key] for row in rows]) for key in (
            'release_position_error', 'release_speed_error', 'release_direction_error',
            'landing_prediction_error', 'max_slip')},
        'hit_count': sum(1 for row in rows if row['hit']),
        'success_count': sum(1 for row in rows if row['success']), 'landing_limit': LANDING_LIMIT,
        'max_release_speed': planning.max_release_speed, 'plots': ['landing_errors.png']})
    write_results(out_dir, results)
    return results
