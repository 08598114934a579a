"""
The elbow's reach: a run-in that the arm can follow without folding its elbow past its limit.

The elbow joint (A4) sets the distance between the shoulder (the A2 axis origin) and the wrist
(the A6 axis origin): the more it folds, the closer they come, down to min_wrist_distance at its
joint limit (0.40 m for the iiwa 7, 0.41 m for the iiwa 14 at 120 deg). The wrist sits at a
fixed point of the tool frame (0.241 m behind the pad on the flange axis), so a tool pose puts
it at a known place, and a pad that runs in toward its face along e1 drags the wrist along -e1
behind it (eq. 5's run-in, the last rho of the reach). In the dual-arm cell the boxes sit close
to the shoulders and the paper's tilt of e1 toward the object's motion (forward, +x) makes the
run-in start with the wrist closer to the shoulder than the elbow can fold: the arm then runs
along its elbow limit, the passive controller trades orientation for position, and the pads
meet their faces several degrees off flush, one corner first.

The elbow's other end: stretched straight (A4 = 0) the wrist is max_wrist_distance from the
shoulder and no farther, and an arm driven toward a wrist beyond it lags its pad while the other
arm does not. reachable_release_rotation turns the carried box's yaw until, at the release
point, no wrist lies more than an allowed overreach beyond it.
"""

import math
from typing import NamedTuple

from dual_arm_control.core.geometry import (cross3, matrix_to_rpy, rotation_exp, unit,
                                            vector_norm)
from dual_arm_control.core.grasp import grasp_frame
import numpy as np

# Fractions of the turn from the preferred direction toward the clearest one tried, in order.
_TURN_STEPS = 8


class ElbowReach(NamedTuple):
    """Where an arm's wrist may go: outside a sphere about its shoulder (world frame, m)."""

    shoulder: np.ndarray
    """(3,) the A2 axis origin, fixed in the world while A1 turns."""
    wrist_in_tool: np.ndarray
    """(3,) the A6 axis origin in the tool frame."""
    min_wrist_distance: float
    """Shoulder-wrist distance with the elbow folded to its joint limit."""
    max_wrist_distance: float
    """Shoulder-wrist distance with the elbow straight (A4 = 0)."""


def wrist_offset(reach, p_world_tool, R_world_tool):
    """Return the wrist's position relative to the shoulder (3,) [m] for a tool pose."""
    return (np.asarray(p_world_tool, dtype=float)
            + np.asarray(R_world_tool, dtype=float) @ reach.wrist_in_tool - reach.shoulder)


def run_in_elbow_margin(reach, p_world_grasp, R_world_grasp, direction, run_in):
    """
    Return the least elbow margin [m] over a run-in: min over s in [0, run_in] of |w(s)| - r.

    The pad holds the grasp orientation R and runs the last run_in [m] to p_world_grasp along
    direction (3,), unit, so the wrist goes through w(s) = w_d - s e1 relative to the shoulder;
    r is min_wrist_distance. |w(s)| is least at s = clip(w_d . e1, 0, run_in).
    """
    return _run_in_margin(reach, wrist_offset(reach, p_world_grasp, R_world_grasp),
                          np.asarray(direction, dtype=float), run_in)


def _run_in_margin(reach, wrist, direction, run_in):
    """Return run_in_elbow_margin from the wrist's offset w_d (3,) at the grasp pose."""
    nearest = min(max(float(wrist @ direction), 0.0), run_in)
    return vector_norm(wrist - nearest * direction) - reach.min_wrist_distance


def clearest_direction(reach, p_world_grasp, R_world_grasp, normal, max_tilt):
    """
    Return the direction (3,) of the cone whose run-in keeps the wrist farthest out.

    The cone holds the directions within max_tilt [rad] of the inward normal; the answer is the
    normal tilted fully away from the wrist's offset w_d, which minimises w_d . e1 over the cone
    and with it how far the run-in draws the wrist in.
    """
    return _clearest_direction(wrist_offset(reach, p_world_grasp, R_world_grasp), normal,
                               max_tilt)


def _clearest_direction(wrist, normal, max_tilt):
    """Return clearest_direction from the wrist's offset w_d (3,) at the grasp pose."""
    normal = unit(normal, 'normal')
    tangential = wrist - (wrist @ normal) * normal
    length = vector_norm(tangential)
    if length < 1e-9:
        return normal
    return math.cos(max_tilt) * normal - math.sin(max_tilt) / length * tangential


def elbow_clear_direction(direction, normal, max_tilt, reach, p_world_grasp, R_world_grasp,
                          run_in, clearance):
    """
    Return the impact direction e1 (3,): direction itself if its run-in clears the elbow limit.

    Clearing means the run-in's least elbow margin (run_in_elbow_margin) is at least
    clearance [m], or as much as the grasp pose itself has if that is less. Otherwise e1 turns
    from direction toward clearest_direction (within max_tilt [rad] of the inward normal, the
    friction cone the impact direction keeps) by the smallest of eight equal steps that
    clears, or all the way.
    """
    direction = unit(direction, 'direction')
    wrist = wrist_offset(reach, p_world_grasp, R_world_grasp)
    grasp_margin = _run_in_margin(reach, wrist, direction, 0.0)
    required = min(clearance, grasp_margin)
    if _run_in_margin(reach, wrist, direction, run_in) >= required - 1e-9:
        return direction
    clearest = _clearest_direction(wrist, normal, max_tilt)
    axis = cross3(direction, clearest)
    sine = vector_norm(axis)
    turn = (math.atan2(sine, float(direction @ clearest)) / sine * axis if sine > 1e-12
            else np.zeros(3))
    for step in range(1, _TURN_STEPS + 1):
        candidate = rotation_exp(step / _TURN_STEPS * turn) @ direction
        if _run_in_margin(reach, wrist, candidate, run_in) >= required - 1e-9:
            return candidate
    return clearest


def wrist_overreach(reaches, p_world_object, R_world_object, size, offset=(0.0, 0.0, 0.0),
                    roll=0.0):
    """
    Return the largest wrist overreach [m] of the arms holding a box at a pose.

    Over the arms ({arm: ElbowReach}), the shoulder-wrist distance with the pad on its grasp
    frame (core.grasp.grasp_frame: box size (3,) [m], grasp offset, pad roll) less the
    straight-arm distance: positive for a pose some arm cannot reach.
    """
    excess = -math.inf
    for arm, reach in reaches.items():
        frame = grasp_frame(arm, p_world_object, R_world_object, size, offset, roll)
        wrist = wrist_offset(reach, frame.p_world_grasp, frame.R_world_grasp)
        excess = max(excess, vector_norm(wrist) - reach.max_wrist_distance)
    return excess


def reachable_release_rotation(reaches, p_world_release, v_world_release, R_world_held, size,
                               offset, roll, overreach, step=math.radians(1.0)):
    """
    Return the orientation (3, 3) the box keeps to its release: R_world_held, turned if need be.

    A box grabbed yawed puts one pad ahead of the other along the toss; at the release point
    p_world_release (3,) [m] the wrist of the arm ahead may lie beyond its straight-arm reach.
    That arm then stretches to its elbow singularity and falls behind while the other carries
    on, and the box turns in the grasp. The answer turns R_world_held about world z toward the
    toss heading (the horizontal direction of v_world_release (3,)) in steps of step [rad],
    stopping at the first yaw at which no wrist lies more than overreach [m] beyond its reach
    (wrist_overreach); if none does, the yaw of the least overreach. Turning the box costs
    speed and grip too, so a small overreach, which the arm rides out stretched for an
    instant, is left alone.
    """
    R_world_held = np.asarray(R_world_held, dtype=float)
    yaw = matrix_to_rpy(R_world_held)[2]
    heading = math.atan2(v_world_release[1], v_world_release[0])
    turn = math.remainder(heading - yaw, 2.0 * math.pi)
    steps = int(math.ceil(abs(turn) / step - 1e-9))
    best, least = R_world_held, math.inf
    for index in range(steps + 1):
        candidate = rotation_exp(np.array([0.0, 0.0, turn * index / max(steps, 1)])) \
            @ R_world_held
        excess = wrist_overreach(reaches, p_world_release, candidate, size, offset, roll)
        if excess <= overreach:
            return candidate
        if excess < least - 1e-9:
            best, least = candidate, excess
    return best
