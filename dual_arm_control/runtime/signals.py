"""
The signals the roles exchange, as plain values: what each topic carries, and nothing else.

A node copies message fields into these and back (float64 both ways, so nothing is lost); the
in-process runner hands them from one step to the next. Both therefore feed every step the same
numbers. Constructors check their input and raise InputError naming the problem, which the
steps count as a refusal. Stamps are integer nanoseconds of sim time.
"""

from dataclasses import dataclass
import math

from dual_arm_control.core.exceptions import InputError
from dual_arm_control.core.geometry import matrix_to_quat_xyzw, quat_xyzw_to_matrix
from dual_arm_control.core.phases import Phase, task_from_name
import numpy as np

MIN_QUATERNION_NORM = 1e-6


def _finite(name, values, size):
    try:
        array = np.array(values, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(f'{name} must be numbers, got {values!r}') from None
    if array.size != size:
        raise InputError(f'{name} has {array.size} values, expected {size}')
    if not np.isfinite(array).all():
        raise InputError(f'{name} contains NaN or Inf')
    return array


def _quaternion(name, values):
    quat_xyzw = _finite(name, values, 4)
    if np.linalg.norm(quat_xyzw) < MIN_QUATERNION_NORM:
        raise InputError(f'{name} is zero: no orientation')
    return quat_xyzw


@dataclass(frozen=True)
class JointStateSample:
    """One arm's joints at a cycle: position [rad], velocity [rad/s], effort [N m], (7,)."""

    stamp_ns: int
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray


def joint_state_sample(stamp_ns, names, position, velocity, effort, expected_names):
    """
    Return the JointStateSample of expected_names from a JointState's fields.

    Joints are matched by name, in any order; other joints are ignored. A missing joint, a
    field whose length differs from the names, or a NaN/Inf raises InputError. Effort may be
    empty (zeros then); position and velocity may not.
    """
    names = list(names)
    missing = [name for name in expected_names if name not in names]
    if missing:
        raise InputError(f'joint state lacks joints {missing} (has {names})')
    index = [names.index(name) for name in expected_names]
    arrays = []
    for field, values in (('position', position), ('velocity', velocity), ('effort', effort)):
        if field == 'effort' and len(values) == 0:
            arrays.append(np.zeros(len(index)))
            continue
        array = _finite(field, values, len(names))
        arrays.append(array[index])
    return JointStateSample(int(stamp_ns), *arrays)


@dataclass(frozen=True)
class WrenchSample:
    """A wrench [force (3) N; torque (3) N m] at a stamp (FT reading or pad wrench)."""

    stamp_ns: int
    wrench: np.ndarray


def wrench_sample(stamp_ns, force, torque):
    """Return a WrenchSample of force and torque (3,) each; InputError if not finite."""
    return WrenchSample(int(stamp_ns), np.concatenate((_finite('force', force, 3),
                                                       _finite('torque', torque, 3))))


@dataclass(frozen=True)
class PoseSample:
    """A measured pose: position [m] (3,) and orientation quat_xyzw (4,), world frame."""

    stamp_ns: int
    position: np.ndarray
    quat_xyzw: np.ndarray


def pose_sample(stamp_ns, position, quat_xyzw):
    """Return a PoseSample; InputError on NaN/Inf or a zero quaternion."""
    return PoseSample(int(stamp_ns), _finite('position', position, 3),
                      _quaternion('orientation', quat_xyzw))


@dataclass(frozen=True)
class ObjectState:
    """
    The tracker's estimate at a stamp: pose and twist in the world, or no estimate.

    valid False (no track yet) leaves the arrays at zero and the identity quaternion.
    pose_covariance and twist_covariance (6, 6), rows x, y, z, rotation x, y, z (world), are
    the filter's where it reports them (None otherwise).
    """

    stamp_ns: int
    valid: bool
    position: np.ndarray
    quat_xyzw: np.ndarray
    linear_velocity: np.ndarray
    angular_velocity: np.ndarray
    pose_covariance: np.ndarray = None
    twist_covariance: np.ndarray = None

    @property
    def R_world_object(self):
        """Return the (3, 3) orientation of the estimate."""
        return quat_xyzw_to_matrix(self.quat_xyzw)


def object_state(stamp_ns, position, quat_xyzw, linear_velocity, angular_velocity):
    """Return a valid ObjectState; InputError if a value is not finite or the quaternion zero."""
    return ObjectState(int(stamp_ns), True, _finite('position', position, 3),
                       _quaternion('orientation', quat_xyzw),
                       _finite('linear velocity', linear_velocity, 3),
                       _finite('angular velocity', angular_velocity, 3))


def no_object_state(stamp_ns):
    """Return the ObjectState that says there is no estimate at stamp_ns."""
    return ObjectState(int(stamp_ns), False, np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]),
                       np.zeros(3), np.zeros(3))


@dataclass(frozen=True)
class ArmCommandSample:
    """
    The DS command of one arm for a tick, world frame.

    p_world_attractor (3,) [m]: the current attractor (grasp point, standby); quat_xyzw (4,):
    desired tool orientation; v_world (3,) [m/s] and w_world (3,) [rad/s]: desired tool twist.
    """

    stamp_ns: int
    p_world_attractor: np.ndarray
    quat_xyzw: np.ndarray
    v_world: np.ndarray
    w_world: np.ndarray

    @property
    def R_world_desired(self):
        """Return the desired tool orientation (3, 3)."""
        return quat_xyzw_to_matrix(self.quat_xyzw)


def arm_command_sample(stamp_ns, p_world_attractor, quat_xyzw, v_world, w_world):
    """Return an ArmCommandSample; InputError if a value is not finite or the quaternion zero."""
    return ArmCommandSample(int(stamp_ns), _finite('attractor', p_world_attractor, 3),
                            _quaternion('orientation', quat_xyzw),
                            _finite('linear velocity', v_world, 3),
                            _finite('angular velocity', w_world, 3))


def arm_command_from(stamp_ns, command):
    """Return the ArmCommandSample of a core ArmCommand (rotation carried as a quaternion)."""
    return ArmCommandSample(int(stamp_ns), np.asarray(command.p_world_attractor, dtype=float),
                            matrix_to_quat_xyzw(command.R_world_desired),
                            np.asarray(command.v_world, dtype=float),
                            np.asarray(command.w_world, dtype=float))


@dataclass(frozen=True)
class TwistSample:
    """A twist at a stamp: linear (3,) [m/s] and angular (3,) [rad/s], world frame."""

    stamp_ns: int
    linear: np.ndarray
    angular: np.ndarray


def twist_sample(stamp_ns, linear, angular):
    """Return a TwistSample; InputError if a value is not finite."""
    return TwistSample(int(stamp_ns), _finite('linear', linear, 3),
                       _finite('angular', angular, 3))


@dataclass(frozen=True)
class PhaseSample:
    """The task phase at a DS tick: phase, task, time in phase [s], events, transition reason."""

    stamp_ns: int
    phase: Phase
    task: object
    time_in_phase: float
    events: tuple
    reason: str


def phase_sample(stamp_ns, phase, task, time_in_phase, events=(), reason=''):
    """Return a PhaseSample from names (as a message carries them); InputError if unknown."""
    try:
        phase = Phase(phase)
        task = task_from_name(task)
        time_in_phase = float(time_in_phase)
    except (ValueError, TypeError) as error:
        raise InputError(f'bad phase report: {error}') from None
    if not math.isfinite(time_in_phase):
        raise InputError('time in phase is not finite')
    return PhaseSample(int(stamp_ns), phase, task, time_in_phase, tuple(events), str(reason))


@dataclass(frozen=True)
class TorqueSample:
    """The joint torques [N m] (7,) an arm controller commands for one FRI cycle."""

    stamp_ns: int
    effort: np.ndarray
