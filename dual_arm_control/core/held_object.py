"""
The held box's position and velocity read from the pads (joint encoders), not from mocap alone.

Once both pads hold the box (MANIPULATE) it moves with them, and the tools' poses come from
the joint encoders at every DS tick without noise or latency. Motion capture gives the box's
centre with 0.5-2 mm of noise; the tracker, tuned for the low end, turns the high end into
velocity errors of 0.03-0.13 m/s from one 5 ms tick to the next and lags by about 1 %: the
toss's speed loop chased them, the release rule read them, and over the catalogue 33 of 300
boxes slipped more than 1 cm in the pads (9 once read from the pads).

HeldObjectEstimate is a complementary filter. The box's centre is the pads' midpoint plus an
offset held in the grip's frame (the mean of both pads' frames, grip_rotation), so that it
turns with the grasp (a shifted grasp holds the box up to 10 cm off its centre); one pad's
frame would turn the offset with that pad as it rocks on an edge of its face. The offset
starts where the grasp plan puts the centre (the tracker lags after the impact: 7 mm in one
trial) and follows the tracker's estimate slowly (time constant; a slip of the box in the
pads shows up within it). The velocity is that point's as the pads carry it: differenced
between the joint samples (core.sample_time; in realtime, differenced over the tick instead, the
speed jumped 20-40 % from tick to tick and the toss's speed loop threw 10-17 % fast on it) with
the offset held (its slow correction is no motion of the box), and carried half a span forward
on the last two differences (a difference is the mean velocity over its span, half a span old:
0.025 m/s at the toss's 10 m/s^2).
"""

import math

from dual_arm_control.core.geometry import slerp_rotation
from dual_arm_control.core.sample_time import sample_span
import numpy as np


class HeldObjectEstimate:
    """Complementary filter of a held box's centre: pad kinematics fast, mocap slow."""

    def __init__(self):
        """Start with no hold."""
        self.reset()

    def reset(self):
        """Forget the hold (the pads let go)."""
        self._offset = None
        self._midpoint = None
        self._R_world_grip = None
        self._mean_velocity = self._held_velocity = None
        self._R_right_left = None
        self._sample_age = 0.0

    def grip_rotation(self, R_world_left, R_world_right):
        """
        Return the rotation (3, 3) of the pair of pads: the geodesic mean of both pads' frames.

        Each pad's frame is taken as it sat when the hold began (the right one turned onto the
        left's by their relative rotation then), and the two are averaged: a pad rocking on an
        edge of its face turns its own frame, not the box (carried 20 deg yawed, the pads
        turned 13 and 16 deg in opposite senses against the box, their mean 1.5 deg).
        """
        R_world_left = np.asarray(R_world_left, dtype=float)
        R_world_right = np.asarray(R_world_right, dtype=float)
        if self._R_right_left is None:
            self._R_right_left = R_world_right.T @ R_world_left
        return slerp_rotation(R_world_left, R_world_right @ self._R_right_left, 0.5)

    def update(self, p_world_midpoint, R_world_grip, p_world_estimate, v_world_estimate, dt,
               time_constant, planned_offset=None, sample_age=0.0):
        """
        Return the held box's (p (3,) [m], v (3,) [m/s]) for one tick of dt [s].

        p_world_midpoint: the pads' midpoint; R_world_grip (3, 3): the grip's rotation, both
        from joint states sampled sample_age [s] before the tick (the position is carried to the
        tick; a sample seen at the tick before gives no new difference); p/v_world_estimate: the
        tracker's estimate, which the offset follows with time_constant [s] (> 0);
        planned_offset (3,) [m]: where the grasp plan puts the box's centre from the pads'
        midpoint, world frame (default: the tracker's). The first tick of a hold returns the
        centre there with the tracker's velocity.
        """
        midpoint = np.asarray(p_world_midpoint, dtype=float)
        R_world_grip = np.asarray(R_world_grip, dtype=float)
        p_world_estimate = np.asarray(p_world_estimate, dtype=float)
        v_world_estimate = np.asarray(v_world_estimate, dtype=float)
        if self._offset is None or dt <= 0.0:
            midpoint_at_tick = midpoint + sample_age * v_world_estimate
            self._offset = R_world_grip.T @ (
                p_world_estimate - midpoint_at_tick if planned_offset is None
                else np.asarray(planned_offset, dtype=float))
            self._midpoint, self._R_world_grip, self._sample_age = (
                midpoint, R_world_grip, sample_age)
            return midpoint_at_tick + R_world_grip @ self._offset, v_world_estimate
        span = sample_span(dt, self._sample_age, sample_age)
        if span is None:
            self._sample_age += dt
        else:
            mean_velocity = (midpoint - self._midpoint + (R_world_grip - self._R_world_grip)
                             @ self._offset) / span
            self._held_velocity = mean_velocity if self._mean_velocity is None else (
                1.5 * mean_velocity - 0.5 * self._mean_velocity)
            self._mean_velocity = mean_velocity
            self._midpoint, self._R_world_grip, self._sample_age = (
                midpoint, R_world_grip, sample_age)
        velocity = v_world_estimate if self._held_velocity is None else self._held_velocity
        midpoint_at_tick = midpoint + sample_age * velocity
        gain = -math.expm1(-dt / time_constant)
        self._offset = self._offset + gain * (
            R_world_grip.T @ (p_world_estimate - midpoint_at_tick) - self._offset)
        return midpoint_at_tick + R_world_grip @ self._offset, velocity
