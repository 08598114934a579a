"""
Time on the FRI grid: nanoseconds, the tick schedule of slower loops, estimates at a cycle.

Also the wall-clock pacing of a realtime loop (late cycles, stalls).

Every process computes the same ticks from the same cycle stamps, which is what keeps a
multi-process lockstep run and an in-process run on the same schedule.
"""

from dual_arm_control.core.geometry import rotation_exp
from dual_arm_control.core.motion_signals import ObjectMeasurement
import numpy as np

NANOSECONDS_PER_SECOND = 1_000_000_000


def seconds_to_ns(seconds):
    """Return a time in seconds as integer nanoseconds (rounded, so 0.002 * k stays exact)."""
    return int(round(seconds * NANOSECONDS_PER_SECOND))


class TickSchedule:
    """
    Which FRI cycles carry a tick of a slower loop (DS and QP at 200 Hz on a 2 ms FRI grid).

    A tick is due on the first cycle of each period of the loop's time grid (t // period
    increases), so the loop keeps its rate on average (ticks at 0, 6, 10, 16, 20 ms for 5 ms
    on a 2 ms grid) and every process that sees the same cycle stamps computes the same
    ticks. Time going backwards (a simulation reset) starts the schedule again.
    """

    def __init__(self, period):
        self.period_ns = seconds_to_ns(period)
        self.last_tick_ns = None

    def went_back(self, t_ns):
        """Return True if t_ns [ns] is earlier than the last tick (the clock went back)."""
        return self.last_tick_ns is not None and t_ns < self.last_tick_ns

    def due(self, t_ns):
        """Return True if a tick is due at t_ns [ns] (does not record it)."""
        if self.last_tick_ns is None or self.went_back(t_ns):
            return True
        return t_ns // self.period_ns > self.last_tick_ns // self.period_ns

    def take(self, t_ns):
        """Record a tick at t_ns; return the time since the previous tick [s]."""
        fresh = self.last_tick_ns is None or t_ns <= self.last_tick_ns
        elapsed_ns = self.period_ns if fresh else t_ns - self.last_tick_ns
        self.last_tick_ns = t_ns
        return elapsed_ns / NANOSECONDS_PER_SECOND

    def reset(self):
        """Forget the previous tick."""
        self.last_tick_ns = None


class CycleGaps:
    """
    The wall-clock gaps between the cycles of a realtime loop: late cycles, stalls, the longest.

    A cycle is late when it starts more than late_tolerance of a period after its due time. A
    stall is a gap of stall_periods periods or more: that many commands missing in a row on a
    real FRI connection, which a toss does not survive (on Linux the kernel's real-time
    throttling stops every SCHED_FIFO task of a CPU for up to 50 ms of each second once they
    used 95 % of it). A gap while the loop was paused is not one: restart() after a pause.
    """

    def __init__(self, period, late_tolerance=0.5, stall_periods=5):
        if period <= 0.0:
            raise ValueError(f'period must be positive, got {period}')
        self.late_gap = period * (1.0 + late_tolerance)
        self.stall_gap = period * stall_periods
        self.late = 0
        self.stalls = 0
        self.longest = 0.0
        self._last = None

    def tick(self, now):
        """Count the cycle starting at wall time now [s]."""
        if self._last is not None:
            gap = now - self._last
            self.late += gap > self.late_gap
            self.stalls += gap >= self.stall_gap
            self.longest = max(self.longest, gap)
        self._last = now

    def restart(self):
        """Forget the previous cycle (the loop was paused)."""
        self._last = None

    def as_dict(self):
        """Return the counters: late cycles, stalls and the longest gap [s]."""
        return {'late_cycles': self.late, 'cycle_stalls': self.stalls,
                'longest_cycle_gap': self.longest}


def estimate_at(estimate, t_ns):
    """
    Return (p, R, v, w) of an ObjectState predicted to t_ns with its own twist.

    Constant linear and angular velocity over the few milliseconds between the estimate's
    stamp and t_ns; at the estimate's own stamp the values are returned unchanged.
    """
    dt = (t_ns - estimate.stamp_ns) / NANOSECONDS_PER_SECOND
    R_world = estimate.R_world_object
    if dt == 0.0:
        return estimate.position, R_world, estimate.linear_velocity, estimate.angular_velocity
    return (estimate.position + estimate.linear_velocity * dt,
            rotation_exp(estimate.angular_velocity * dt) @ R_world,
            estimate.linear_velocity, estimate.angular_velocity)


def object_measurement_at(estimate, stamp_ns, arms):
    """
    Return the ObjectMeasurement of the estimate (ObjectState or None) predicted to stamp_ns.

    Without a valid estimate, a stand-in between the pads of arms {arm: ArmMeasurement}.
    """
    if estimate is None or not estimate.valid:
        midpoint = 0.5 * (arms['left'].p_world_tool + arms['right'].p_world_tool)
        return ObjectMeasurement(midpoint, np.eye(3), np.zeros(3))
    position, rotation, linear, _ = estimate_at(estimate, stamp_ns)
    return ObjectMeasurement(position, rotation, linear)
