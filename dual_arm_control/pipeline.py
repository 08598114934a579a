"""
The controller pipeline without ROS: scenario to configs, wrench distribution, rate schedule.

The nodes wrap these same pieces (one per process); the in-process runner (inprocess.py) chains
them directly for fast tuning. Nothing here imports rclpy.
"""

from dataclasses import dataclass, replace

from dual_arm_control.contract import ARMS
from dual_arm_control.core.ballistics import release_velocity_minimum_speed
from dual_arm_control.core.exceptions import SolverError
from dual_arm_control.core.geometry import rotation_exp
from dual_arm_control.core.motion_generator import MotionGeneratorConfig
from dual_arm_control.core.object_wrench import (box_inertia, desired_object_wrench,
                                                 ObjectWrenchConfig)
from dual_arm_control.core.phases import Phase
from dual_arm_control.core.validation import check_range
from dual_arm_control.core.wrench_qp import (ContactWrenchQP, pad_contact_geometry,
                                             WrenchQPConfig)
import numpy as np

GRASPING_PHASES = (Phase.CONTACT, Phase.MANIPULATE)
# Pad wrenches are rounded to 10 uN / 10 uN m: proxsuite's last bits depend on the heap
# alignment of its Eigen buffers (~1e-12 run to run), and rounding far below any physical
# effect keeps lockstep runs bit-identical.
WRENCH_DECIMALS = 5
# The place DS aims this far below the box's resting pose [m], so the table, not the release,
# stops the box: it is put down while still held, then released at rest.
PLACE_PRESS_DEPTH = 0.01


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


def object_state_at(state, t_ns):
    """
    Return (p, R, v, w) of a stamped object estimate predicted to t_ns with its own twist.

    state: (stamp_ns, p_world (3,) [m], R_world (3, 3), v_world (3,) [m/s], w_world (3,)
    [rad/s]); constant linear and angular velocity over the few milliseconds of the gap.
    """
    state_ns, p_world, R_world, v_world, w_world = state
    dt = (t_ns - state_ns) / NANOSECONDS_PER_SECOND
    return p_world + v_world * dt, rotation_exp(w_world * dt) @ R_world, v_world, w_world


def motion_config_for_scenario(scenario, cell, base=None):
    """Return the MotionGeneratorConfig of a scenario: task, object, targets, speeds, standby."""
    base = MotionGeneratorConfig() if base is None else base
    config = replace(
        base, task=scenario.task, object_size=tuple(scenario.object.size),
        standby_positions=tuple(tuple(cell.arm(arm).standby_position) for arm in ARMS),
        standby_rotations=tuple(tuple(map(tuple, cell.arm(arm).R_world_standby))
                                for arm in ARMS),
        impact=replace(base.impact, impact_speed=scenario.speeds.impact),
        speed=replace(base.speed, reach_speed=scenario.speeds.reach))
    toss = replace(base.toss, toss_speed=scenario.speeds.toss)
    if scenario.release is not None:
        velocity = np.asarray(scenario.release.velocity, dtype=float)
        toss = replace(toss, release_position=tuple(scenario.release.position),
                       release_direction=tuple(velocity), toss_speed=float(
                           np.linalg.norm(velocity)))
    elif scenario.landing_target is not None:
        solution = release_velocity_minimum_speed(np.asarray(toss.release_position),
                                                  np.asarray(scenario.landing_target))
        toss = replace(toss, release_direction=tuple(solution.velocity),
                       toss_speed=float(solution.speed))
    config = replace(config, toss=toss)
    if scenario.place is not None:
        pressed = np.asarray(scenario.place, dtype=float) - [0.0, 0.0, PLACE_PRESS_DEPTH]
        config = replace(config, place=replace(base.place, position=tuple(pressed)))
    return config


def wrench_about_tool(wrench, p_world_contact, p_world_tool):
    """Return a pad wrench (6,) with its moment moved from the contact point to the tool."""
    force = np.asarray(wrench[:3], dtype=float)
    moment = np.asarray(wrench[3:], dtype=float) + np.cross(
        np.asarray(p_world_contact) - np.asarray(p_world_tool), force)
    return np.concatenate((force, moment))


@dataclass(frozen=True)
class WrenchDistributorConfig:
    """
    Wrench distribution around the QP (SI units).

    Fields: ramp_time_constant s > 0, the grasp wrench rises as 1 - exp(-t / tau) after contact
    (and drops to zero at once outside CONTACT / MANIPULATE); qp and object: the QP's and the
    object wrench's configs.
    """

    ramp_time_constant: float = 0.02
    qp: WrenchQPConfig = WrenchQPConfig()
    object: ObjectWrenchConfig = ObjectWrenchConfig()  # noqa: A003

    def __post_init__(self):
        check_range('ramp_time_constant', self.ramp_time_constant, 0.0, 1.0, 's',
                    low_open=True)


@dataclass(frozen=True)
class DistributedWrenches:
    """Per-arm pad wrenches (6,) on the object [N, N m], world, and the QP's report."""

    wrenches: dict
    object_wrench: np.ndarray
    gain: float
    feasible: bool
    status: str


class WrenchDistributor:
    """Object wrench (passive DS on the object, section II-E) split over the pads (eq. 10)."""

    def __init__(self, config, object_mass, object_size):
        self._config = config
        self._qp = ContactWrenchQP(config.qp)
        self._mass = float(object_mass)
        self._size = np.asarray(object_size, dtype=float)
        self._inertia_object = box_inertia(self._mass, self._size)
        self._gain = 0.0

    def reconfigure(self, config):
        """Use new weights, limits and gains from the next tick on."""
        self._config = config
        self._qp = ContactWrenchQP(config.qp)

    def step(self, phase, p_world_tools, R_world_tools, p_world_object, R_world_object,
             v_world_object, w_world_object, v_world_desired, w_world_desired, dt):
        """Return the DistributedWrenches of one tick; zero wrenches outside grasp phases."""
        zero = {arm: np.zeros(6) for arm in ARMS}
        if phase not in GRASPING_PHASES:
            self._gain = 0.0
            return DistributedWrenches(zero, np.zeros(6), 0.0, True, 'not grasping')
        self._gain += (1.0 - self._gain) * -np.expm1(-dt / self._config.ramp_time_constant)
        inertia_world = R_world_object @ self._inertia_object @ R_world_object.T
        object_wrench = desired_object_wrench(v_world_object, w_world_object, v_world_desired,
                                              w_world_desired, self._mass, inertia_world,
                                              self._config.object)
        contacts = {arm: pad_contact_geometry(arm, p_world_tools[arm], R_world_tools[arm],
                                              p_world_object, R_world_object, self._size)
                    for arm in ARMS}
        try:
            result = self._qp.contact_wrenches(object_wrench, p_world_object, contacts)
        except SolverError as error:
            return DistributedWrenches(zero, object_wrench, self._gain, False, str(error))
        wrenches = {arm: np.round(self._gain * wrench_about_tool(
            result.wrenches[arm], contacts[arm].p_world_contact, p_world_tools[arm]),
            WRENCH_DECIMALS) for arm in ARMS}
        return DistributedWrenches(wrenches, object_wrench, self._gain, result.feasible,
                                   result.status)
