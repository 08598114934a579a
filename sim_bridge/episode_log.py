"""The bridge's trajectory log of one episode: its ground truth plus the FRI counters."""

import time


def save_episode_log(recorder, fri, late_cycles, first_cycle_wall, seed, path):
    """
    Write an episode's trajectory log (TrajectoryRecorder) with its counters to path.

    The counters: the FRI cycle's (refusals, holds, clamps, cycles), the realtime late cycles,
    the wall time since the first cycle, the FRI period and the twin's noise seed of the episode
    (which /sim/reset may have changed from the scenario's).
    """
    recorder.counters.update(fri.log_counters())
    recorder.counters.update({
        'late_cycles': late_cycles,
        'wall_time': time.monotonic() - first_cycle_wall if first_cycle_wall else 0.0,
        'fri_period': fri.backend.fri_period, 'seed': seed})
    recorder.save(path)
