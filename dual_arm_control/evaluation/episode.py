"""
Evaluate one episode: the metrics.json contract and the plots, from simulator ground truth.

metrics.json keys (SI units, times in sim seconds from the episode start, null where not
applicable) are listed in METRIC_KEYS; README.md documents them.
"""

from pathlib import Path

from dual_arm_control.contract import ARMS
from dual_arm_control.core.approach import (impact_directions, object_motion_direction,
                                            support_height_below)
from dual_arm_control.core.ballistics import STANDARD_GRAVITY
from dual_arm_control.core.geometry import rpy_to_matrix
from dual_arm_control.core.grasp import grasp_frame
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.evaluation import metrics, plots
from dual_arm_control.evaluation.container_metrics import container_metrics
from dual_arm_control.evaluation.grab_metrics import (belt_grab_impact_speed, grab_metrics,
                                                      grab_succeeded)
from dual_arm_control.graph import EPISODE_START_TIME
from dual_arm_control.runtime.configuration import (motion_config_for_scenario,
                                                    planned_landing, planned_release,
                                                    predicted_landing)
from dual_arm_control.scenario import load_scenario, PLACE_TASKS, TOSS_TASKS
from dual_arm_control.trajectory_log import load_trajectory
import numpy as np

METRIC_KEYS = (
    'success', 't_contact_left', 't_contact_right', 'contact_time_gap', 'impact_speed_left',
    'impact_speed_right', 't_release', 'release_position', 'release_position_error',
    'release_velocity', 'release_velocity_error', 'release_speed_error',
    'release_direction_error', 'release_orientation_error', 'landing_position', 'landing_error',
    'cycle_time', 'place_position_error', 'energy_left', 'energy_right', 'max_slip',
    'torque_clamp_count', 'refused_message_count', 'arm_collision_count', 'box_tilt_at_place',
    'max_joint_speed_ratio_left', 'max_joint_speed_ratio_right', 'joint_speed_limit_time_left',
    'joint_speed_limit_time_right', 'landing_error_in_container', 'landed_in_container',
    'impact_speed_relative_left', 'impact_speed_relative_right', 'belt_drag', 'start_refusal',
    't_task_release', 'grasp_count', 'late_cycles', 'cycle_stalls', 'longest_cycle_gap',
)

# Pass/fail thresholds of an episode, per task family.
CONTACT_GAP_LIMIT = 0.010
RELEASE_POSITION_LIMIT = 0.03
RELEASE_VELOCITY_LIMIT = 0.10
RELEASE_ORIENTATION_LIMIT = 5.0
LANDING_LIMIT = 0.05
PLACE_LIMIT = 0.02
PLACE_SPEED_LIMIT = 0.1
PLACE_TILT_LIMIT = 5.0
SLIP_LIMIT = 0.01
HOLD_DRIFT_LIMIT = 0.001
# The kernel's real-time budget per CPU and second (Linux; -1: unlimited).
RT_RUNTIME_FILE = '/proc/sys/kernel/sched_rt_runtime_us'


def _time(t, index):
    return None if index is None else float(t[index])


def _vector(value):
    return None if value is None else [float(v) for v in value]


def _contact_directions(scenario, cell, models):
    """
    Return ({arm: inward face normal}, {arm: desired impact direction}) at the initial pose.

    models: {arm: ArmModel} of the cell.

    The impact directions are the motion generator's own (the normal tilted toward the task's
    object motion, turned to keep the run-in within the elbow's reach), computed with the
    scenario's configuration.
    """
    yaw = scenario.object.yaw
    R_world_object = np.array([[np.cos(yaw), -np.sin(yaw), 0.0],
                               [np.sin(yaw), np.cos(yaw), 0.0], [0.0, 0.0, 1.0]])
    frames = {arm: grasp_frame(arm, scenario.object.position, R_world_object,
                               scenario.object.size) for arm in ARMS}
    config = motion_config_for_scenario(scenario, cell)
    motion = object_motion_direction(config, scenario.object.position)
    return ({arm: frames[arm].normal for arm in ARMS},
            impact_directions(config, frames, motion,
                              support_height_below(config, scenario.object.position),
                              elbow_reaches=None if scenario.incoming_belt is not None
                              else {arm: models[arm].elbow_reach() for arm in ARMS}))


def first_event(events, name):
    """Return (sim time [s], reason) of the first event called name, or (None, None)."""
    return next(((time, reason) for time, names, reason in events if name in names),
                (None, None))


def episode_metrics(scenario, data, cell, start_time=EPISODE_START_TIME, events=()):
    """
    Return the metrics dict of one episode; times count from start_time [s] of sim time.

    events: the motion generator's [(sim time [s], event names, reason)] of the episode
    (the in-process runner's log, or its node's log lines); they give why a start was
    refused and when the task let go.
    """
    t = data['t'] - start_time
    result = dict.fromkeys(METRIC_KEYS + ('landing_prediction_error', 'place_speed'))
    result['start_refusal'] = first_event(events, 'unreachable')[1]
    released_at = first_event(events[::-1], 'released')[0]
    result['t_task_release'] = None if released_at is None else released_at - start_time
    contact_index = {arm: metrics.first_true_index(data[f'{arm}_pad_contact']) for arm in ARMS}
    models = {arm: arm_model(arm, cell) for arm in ARMS}
    normals, directions = _contact_directions(scenario, cell, models)
    for arm in ARMS:
        velocity = data[f'{arm}_tool_velocity']
        result[f't_contact_{arm}'] = _time(t, contact_index[arm])
        result[f'impact_speed_{arm}'] = metrics.impact_speed(velocity, contact_index[arm])
        result[f'impact_speed_along_direction_{arm}'] = metrics.impact_speed(
            velocity, contact_index[arm], directions[arm])
        result[f'impact_speed_along_normal_{arm}'] = metrics.impact_speed(
            velocity, contact_index[arm], normals[arm])
    if scenario.incoming_belt is not None:
        result.update(grab_metrics(data, contact_index, directions))
    segments = metrics.grasp_segments(t, data['left_pad_contact'], data['right_pad_contact'])
    if scenario.task not in PLACE_TASKS:
        segments = segments[:1]
    result['grasp_count'] = len(segments)
    result['contact_time_gap'] = _contact_time_gap(t, data, contact_index, segments)
    grasp = segments[0][0] if segments else None
    release = segments[-1][1] if segments else None
    result['t_grasp'] = _time(t, grasp)
    result['t_release'] = _time(t, release)
    slips = [metrics.max_pad_slip(data[f'{arm}_tool_position'], data['object_position'],
                                  data['object_quat_xyzw'], begin, end or len(t))
             for begin, end in segments for arm in ARMS]
    result['max_slip'] = None if None in slips or not slips else max(slips)
    if release is not None:
        p_release = data['object_position'][release]
        v_release = data['object_velocity'][release]
        result['release_position'] = _vector(p_release)
        result['release_velocity'] = _vector(v_release)
        planned = None if scenario.conveyor is not None else planned_release(scenario, cell)
        if planned is not None:
            p_plane, v_plane = metrics.release_state_on_plane(
                p_release, v_release, planned[0], planned[1], STANDARD_GRAVITY)
            result['release_position_error'] = float(np.linalg.norm(p_plane - planned[0]))
            result['release_velocity_error'] = metrics.relative_velocity_error(
                v_plane, planned[1])
            result['release_speed_error'] = metrics.relative_speed_error(v_plane, planned[1])
            result['release_direction_error'] = metrics.direction_error_degrees(
                v_plane, planned[1])
        if scenario.release_orientation is not None:
            result['release_orientation_error'] = metrics.rotation_error_degrees(
                data['object_quat_xyzw'][release],
                rpy_to_matrix(np.radians(scenario.release_orientation)))
        height = scenario.object.size[2]
        landed = metrics.landing_index(t, data['object_position'], release + 1, 0.5 * height,
                                       cell.surface_height)
        if scenario.task in TOSS_TASKS and scenario.conveyor is not None:
            container = container_metrics(data, scenario.conveyor, height, release + 1)
            landed = container.pop('container_landing_index')
            result.update(container)
            if landed is not None:
                result['landing_position'] = _vector(data['object_position'][landed])
        elif scenario.task in TOSS_TASKS and landed is not None:
            landing = data['object_position'][landed]
            result['landing_position'] = _vector(landing)
            predicted = predicted_landing(p_release, v_release, height, cell)
            result['landing_prediction_error'] = float(np.linalg.norm((landing - predicted)[:2]))
            target = planned_landing(scenario, cell)
            result['landing_error'] = float(np.linalg.norm((landing - target)[:2]))
        if scenario.task in PLACE_TASKS and scenario.place is not None:
            result['place_position_error'] = float(
                np.linalg.norm(data['object_position'][-1] - scenario.place))
            result['place_speed'] = float(np.linalg.norm(v_release))
            result['box_tilt_at_place'] = metrics.tilt_degrees(data['object_quat_xyzw'][-1])
    home = metrics.return_home_index(t, [data[f'{arm}_tool_position'] for arm in ARMS],
                                     release)
    result['cycle_time'] = _time(t, home)
    end = (home + 1) if home is not None else len(t)
    for arm in ARMS:
        result[f'energy_{arm}'] = metrics.mechanical_energy(
            t[:end], data[f'{arm}_tau'][:end], data[f'{arm}_dq'][:end])
        drift = np.linalg.norm(data[f'{arm}_tool_position'] - data[f'{arm}_tool_position'][0],
                               axis=1)
        result[f'max_tool_drift_{arm}'] = float(drift.max())
        ratio, time_above, _ = metrics.joint_speed_ratio(
            t, data[f'{arm}_dq'], models[arm].velocity_limits)
        result[f'max_joint_speed_ratio_{arm}'] = ratio
        result[f'joint_speed_limit_time_{arm}'] = time_above
    for counter in ('torque_clamp_count', 'refused_message_count', 'watchdog_hold_count'):
        result[counter] = int(data[counter]) if counter in data else None
    result.update(realtime_clock_metrics(data))
    collision_times = data.get('arm_collision_times', np.zeros(0))
    result['arm_collision_count'] = int(len(collision_times))
    result['first_arm_collision'] = None
    if len(collision_times):
        result['first_arm_collision'] = {
            't': float(collision_times[0] - start_time),
            'geoms': [str(name) for name in data['arm_collision_geoms'][0]]}
    result['sim_duration'] = float(data['t'][-1] - data['t'][0])
    result['success'] = bool(_success(scenario, result))
    return result


def _contact_time_gap(t, data, contact_index, segments):
    """
    Return the largest gap [s] between the pads' first contacts of each grasp, or None.

    A grasp after the first (a regrasp) counts its contacts from the previous release. Rounded
    to whole nanoseconds: the stamps are multiples of the FRI period, and a 10 ms gap must not
    read 0.010000000000000009 s.
    """
    firsts = [contact_index] + [
        {arm: metrics.first_true_index(data[f'{arm}_pad_contact'], release) for arm in ARMS}
        for (_, release), _ in zip(segments, segments[1:])]
    gaps = [abs(t[first['left']] - t[first['right']]) for first in firsts
            if None not in first.values()]
    return round(float(max(gaps)), 9) if gaps else None


def _success(scenario, result):
    """Return whether the episode met its task's criteria."""
    gap = result['contact_time_gap']
    grasped = gap is not None and gap <= CONTACT_GAP_LIMIT and result['t_grasp'] is not None
    no_slip = result['max_slip'] is not None and result['max_slip'] <= SLIP_LIMIT
    if result['arm_collision_count']:
        return False
    grab_speed = belt_grab_impact_speed(scenario)
    if grab_speed is not None and not grab_succeeded(result, grab_speed):
        return False
    if scenario.task in TOSS_TASKS and scenario.conveyor is not None:
        return grasped and no_slip and bool(result['landed_in_container'])
    if scenario.task in TOSS_TASKS:
        return (grasped and no_slip and result['release_position_error'] is not None
                and result['release_position_error'] <= RELEASE_POSITION_LIMIT
                and result['release_velocity_error'] <= RELEASE_VELOCITY_LIMIT
                and result['landing_error'] is not None
                and result['landing_error'] <= LANDING_LIMIT
                and (scenario.release_orientation is None
                     or result['release_orientation_error'] <= RELEASE_ORIENTATION_LIMIT))
    if scenario.task in PLACE_TASKS:
        return (grasped and result['place_position_error'] is not None
                and result['place_position_error'] <= PLACE_LIMIT
                and result['place_speed'] <= PLACE_SPEED_LIMIT
                and result['box_tilt_at_place'] <= PLACE_TILT_LIMIT)
    return grasped and no_slip


def realtime_clock_metrics(data):
    """
    Return the realtime FRI clock's late cycles, stalls and longest gap [s] of a log.

    All None where no realtime clock ticked (lockstep, or a log without them).
    """
    ticked = 'longest_cycle_gap' in data and float(data['longest_cycle_gap']) > 0.0
    return {key: cast(data[key]) if ticked else None
            for key, cast in (('late_cycles', int), ('cycle_stalls', int),
                              ('longest_cycle_gap', float))}


def hold_metrics(data):
    """Return the metrics of a hold run (twin under a gravity-compensation test controller)."""
    result = {'sim_duration': float(data['t'][-1] - data['t'][0])}
    for arm in ARMS:
        drift = np.linalg.norm(data[f'{arm}_tool_position'] - data[f'{arm}_tool_position'][0],
                               axis=1)
        result[f'max_tool_drift_{arm}'] = float(drift.max())
    for counter in ('torque_clamp_count', 'refused_message_count', 'watchdog_hold_count'):
        result[counter] = int(data[counter]) if counter in data else None
    result.update(realtime_clock_metrics(data))
    result['success'] = all(result[f'max_tool_drift_{arm}'] <= HOLD_DRIFT_LIMIT for arm in ARMS)
    return result


def evaluate_episode(scenario_path, trajectory_path, out_dir, graph='full', events=()):
    """
    Compute the metrics of an episode and write its plots into out_dir; return the metrics.

    events: as for episode_metrics.
    """
    out_dir = Path(out_dir)
    data = load_trajectory(trajectory_path)
    if graph == 'hold':
        plots.plot_tool_drift(data, out_dir / 'tool_drift.png')
        return hold_metrics(data)
    cell = load_cell()
    scenario = load_scenario(scenario_path, cell=cell)
    result = episode_metrics(scenario, data, cell, events=events)
    instants = {'contact': min((v for v in (result['t_contact_left'],
                                            result['t_contact_right']) if v is not None),
                               default=None),
                'release': result['t_release']}
    shifted = dict(data, t=data['t'] - EPISODE_START_TIME)
    plots.plot_tool_speeds(shifted, instants, out_dir / 'tool_speeds.png')
    plots.plot_object_motion(shifted, instants, out_dir / 'object_motion.png')
    plots.plot_trajectories_3d(shifted, out_dir / 'trajectories_3d.png')
    return result


SUMMARY_FIELDS = (('contact_time_gap', 'contact gap', 1e3, 'ms'),
                  ('impact_speed_left', 'impact left', 1.0, 'm/s'),
                  ('impact_speed_right', 'impact right', 1.0, 'm/s'),
                  ('max_slip', 'slip', 1e3, 'mm'),
                  ('release_position_error', 'release error', 1e3, 'mm'),
                  ('release_velocity_error', 'release velocity error', 100.0, '%'),
                  ('release_orientation_error', 'release orientation error', 1.0, 'deg'),
                  ('landing_error', 'landing error', 1e3, 'mm'),
                  ('landing_error_in_container', 'distance to the container centre', 1e3,
                   'mm'),
                  ('place_position_error', 'place error', 1e3, 'mm'),
                  ('cycle_time', 'cycle time', 1.0, 's'),
                  ('cycle_stalls', 'FRI clock stalls (5 cycles or more)', 1, ''),
                  ('longest_cycle_gap', 'longest FRI cycle gap', 1e3, 'ms'))


def metrics_summary(metrics):
    """Return one line per key metric of an episode (all of them are in metrics.json)."""
    return '\n'.join(f'  {label}: {metrics[key] * scale:.3g} {unit}'.rstrip()
                     for key, label, scale, unit in SUMMARY_FIELDS
                     if metrics.get(key) is not None)


def clock_stall_note(metrics, rt_runtime_file=RT_RUNTIME_FILE):
    """Return what the stalls of a realtime run's FRI clock mean, for the console."""
    try:
        budget = f'{int(Path(rt_runtime_file).read_text()):d} us'
    except (OSError, ValueError):
        budget = 'unknown here'
    return (f'the FRI clock stalled {metrics["cycle_stalls"]} times (gaps of 5 cycles or more, '
            f'the longest {metrics["longest_cycle_gap"] * 1e3:.0f} ms) and the robots held an '
            f'arm {metrics["watchdog_hold_count"]} times: the real-time processes did not get '
            f'the CPU they need at this FRI rate. On Linux the kernel stops every SCHED_FIFO '
            f'task of a CPU for the rest of a second once they used sched_rt_runtime_us of it '
            f'({budget}); see docs/performance.md.')
