"""The bridge's trajectory log of one episode: its ground truth plus the FRI counters."""

import time

import rclpy


def save_episode_log(recorder, fri, cycle_gaps, first_cycle_wall, seed, path):
    """
    Write an episode's trajectory log (TrajectoryRecorder) with its counters to path.

    The counters: the FRI cycle's (refusals, holds, clamps, cycles), the realtime clock's
    (CycleGaps: late cycles, stalls, longest gap [s]), the wall time since the first cycle,
    the FRI period and the twin's noise seed of the episode (which /sim/reset may have
    changed from the scenario's).
    """
    recorder.counters.update(fri.log_counters())
    recorder.counters.update(cycle_gaps.as_dict())
    recorder.counters.update({
        'wall_time': time.monotonic() - first_cycle_wall if first_cycle_wall else 0.0,
        'fri_period': fri.backend.fri_period, 'seed': seed})
    recorder.save(path)


def write_log_on_exit(node):
    """Write the bridge's trajectory log on the way out; return the exit code."""
    exit_logger = rclpy.logging.get_logger(f'{node.get_name()}.exit')
    try:
        path = node.write_trajectory_log()
    except OSError as error:
        exit_logger.error(f'cannot write the trajectory log: {error}')
        return 1
    if path:
        exit_logger.info(f'trajectory log written to {path}')
    return 0
