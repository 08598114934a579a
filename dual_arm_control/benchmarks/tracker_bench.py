"""
Time ObjectTracker.update + ObjectTracker.state on a 200 Hz synthetic mocap stream.

Run: python -m dual_arm_control.benchmarks.tracker_bench [--cycles N]. Prints the median and
99th percentile in microseconds of update, of state, and of one cycle of both.
"""

import argparse
import time

from dual_arm_control.core.geometry import matrix_to_quat_xyzw, rotation_exp
from dual_arm_control.core.tracker import ObjectTracker
import numpy as np

PERIOD = 0.005  # mocap sample period [s] (200 Hz, as the twin's default)
LATENCY = 0.005


def measured_cycles(cycles, seed=0):
    """Return per-cycle (update, state) durations [us] for a noisy moving, spinning object."""
    rng = np.random.default_rng(seed)
    tracker = ObjectTracker()
    velocity = np.array([0.6, -0.4, 0.25])
    angular_velocity = np.array([0.5, 1.0, 1.5])
    durations = np.empty((cycles, 2))
    for k in range(cycles):
        stamp = k * PERIOD
        position = velocity * stamp + rng.normal(0.0, 5e-4, 3)
        rotation = rotation_exp(angular_velocity * stamp + rng.normal(0.0, 5e-3, 3))
        quat_xyzw = matrix_to_quat_xyzw(rotation)
        start = time.perf_counter_ns()
        tracker.update(stamp, position, quat_xyzw)
        updated = time.perf_counter_ns()
        tracker.state(stamp + LATENCY)
        done = time.perf_counter_ns()
        durations[k] = ((updated - start) * 1e-3, (done - updated) * 1e-3)
    return durations


def main(argv=None):
    """Run the benchmark and print median / p99 microseconds."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--cycles', type=int, default=5000, help='mocap samples to process')
    arguments = parser.parse_args(argv)
    durations = measured_cycles(arguments.cycles)[100:]
    for name, values in (('update', durations[:, 0]), ('state', durations[:, 1]),
                         ('update + state', durations.sum(axis=1))):
        print(f'{name:>15}: median {np.median(values):7.1f} us   '
              f'p99 {np.percentile(values, 99):7.1f} us   ({len(values)} cycles)')


if __name__ == '__main__':
    main()
