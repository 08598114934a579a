"""
Quantities of the paper experiments computed from trajectories and plans (SI units).

Each function computes one quantity from plain arrays or geometry so it can be tested on
synthetic data; dual_arm_experiment (experiments.py) runs the episodes around them.
"""

import math

from dual_arm_control.core.ballistics import (centre_landing_height, STANDARD_GRAVITY,
                                              UnreachableTargetError)
from dual_arm_control.core.manipulation import TossConfig
from dual_arm_control.core.toss_planning import plan_release
from dual_arm_control.evaluation.metrics import joint_power, mechanical_energy, time_integral
from dual_arm_control.evaluation.workspace import convex_hull
import numpy as np


def reduction_percent(baseline, proposed):
    """Return (baseline - proposed) / baseline * 100 [%], or None if either is missing."""
    if baseline is None or proposed is None or baseline == 0.0:
        return None
    return 100.0 * (baseline - proposed) / baseline


def signed_work(t, tau, dq):
    """Return the integral of tau . dq dt [J]: the paper's mechanical energy, recovery counted."""
    return time_integral(t, joint_power(tau, dq))


def positive_work(t, tau, dq):
    """Return the integral of max(tau . dq, 0) dt [J]: work the drives supply, none recovered."""
    return time_integral(t, np.maximum(joint_power(tau, dq), 0.0))


def energy_without_gravity(t, tau, dq, gravity_torque):
    """
    Return the integral of |(tau - g(q)) . dq| dt [J]: the energy of the torques beyond gravity.

    gravity_torque (N, 7) [N m] is g(q) at every sample. It leaves out the potential energy of
    the arm's own links, which goes down and up by the same amount in every cycle that starts
    and ends at the standby pose.
    """
    return mechanical_energy(t, np.asarray(tau) - np.asarray(gravity_torque), dq)


def cumulative_energy(t, tau, dq):
    """Return the running integral of |tau . dq| [J] at every sample (trapezoidal rule)."""
    power = np.abs(joint_power(tau, dq))
    steps = 0.5 * (power[1:] + power[:-1]) * np.diff(np.asarray(t))
    return np.concatenate(([0.0], np.cumsum(steps)))


def statistics(values):
    """Return {'mean', 'std', 'count'} of the non-missing values (None when there are none)."""
    present = [float(v) for v in values if v is not None]
    if not present:
        return {'mean': None, 'std': None, 'count': 0}
    return {'mean': float(np.mean(present)), 'std': float(np.std(present)),
            'count': len(present)}


def landing_targets(cell, object_size, xs, ys, planning):
    """
    Return (targets (N, 3) [m], refused [(target, reason)]): the grid xs x ys on the front table.

    A target is kept when the whole object footprint lies on the table top and the release
    planner (core.toss_planning with ReleasePlanningConfig planning) finds a release state for
    it; the others are returned with the planner's reason. z is the object centre resting on
    the table.
    """
    table = cell.front_table
    half = 0.5 * np.asarray(object_size, dtype=float)
    height = centre_landing_height(table.top_height, object_size[2])
    nominal = np.asarray(TossConfig().release_position)
    targets, refused = [], []
    for x in xs:
        for y in ys:
            corners = [(x + sx * half[0], y + sy * half[1]) for sx in (-1, 1) for sy in (-1, 1)]
            if not all(table.covers(*corner) for corner in corners):
                continue
            target = np.array([x, y, height])
            try:
                plan_release(target, nominal, planning)
            except UnreachableTargetError as error:
                refused.append((target, str(error)))
                continue
            targets.append(target)
    return np.array(targets).reshape(-1, 3), refused


def served_region_corners(cell, object_size, planning, step):
    """
    Return the corners (M, 3) [m] of the landing region the release planner serves.

    The planner is asked for every point of a step-spaced grid over the front table
    (landing_targets); the corners are the convex hull of the served points, at the resting
    height. Tossing to them measures the region's extent instead of a coarse grid's.
    """
    table = cell.front_table
    low, high = table.center[:2] - 0.5 * table.size[:2], table.center[:2] + 0.5 * table.size[:2]
    xs = np.arange(low[0], high[0] + 1e-9, step)
    ys = np.arange(low[1], high[1] + 1e-9, step)
    served, _ = landing_targets(cell, object_size, xs, ys, planning)
    if len(served) < 3:
        return served
    corners = convex_hull(served[:, :2])
    return np.column_stack((corners, np.full(len(corners), served[0, 2])))


def longest_toss(speed, drop, gravity=STANDARD_GRAVITY):
    """
    Return the longest horizontal distance [m] of a drag-free toss at `speed` [m/s].

    R = v / g sqrt(v^2 + 2 g h) for a landing `drop` h [m] below the release, at the best
    elevation.
    """
    return speed / gravity * math.sqrt(speed ** 2 + 2.0 * gravity * drop)
