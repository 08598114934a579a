"""
The grasp wrench of each pad for one DS tick: object wrench (section II-E) split by eq. 10.

WrenchDistributor chains the passive DS on the object (object_wrench.py) and the contact wrench
QP (wrench_qp.py), ramps the grasp in after contact and moves each pad's moment to its tool point,
the form the arm controllers apply through J^T.
"""

from dataclasses import dataclass, replace
import math

from dual_arm_control.core.arms import ARMS
from dual_arm_control.core.exceptions import SolverError
from dual_arm_control.core.geometry import cross3
from dual_arm_control.core.object_wrench import (box_inertia, desired_object_wrench,
                                                 inertial_wrench, ObjectWrenchConfig)
from dual_arm_control.core.pad_contact import pad_contact_geometry
from dual_arm_control.core.phases import Phase
from dual_arm_control.core.settings import check_settings, setting
from dual_arm_control.core.validation import check_range
from dual_arm_control.core.wrench_qp import ContactWrenchQP, NORMAL_FORCE_LIMIT, WrenchQPConfig
import numpy as np

GRASPING_PHASES = (Phase.CONTACT, Phase.MANIPULATE)
# Pad wrenches are rounded to 10 uN / 10 uN m: proxsuite's last bits depend on the heap
# alignment of its Eigen buffers (~1e-12 run to run), and rounding far below any physical
# effect keeps lockstep runs bit-identical.
WRENCH_DECIMALS = 5


def wrench_about_tool(wrench, p_world_contact, p_world_tool):
    """Return a pad wrench (6,) with its moment moved from the contact point to the tool."""
    force = np.asarray(wrench[:3], dtype=float)
    moment = np.asarray(wrench[3:], dtype=float) + cross3(
        np.asarray(p_world_contact) - np.asarray(p_world_tool), force)
    return np.concatenate((force, moment))


@dataclass(frozen=True)
class WrenchDistributorConfig:
    """
    Wrench distribution around the QP (SI units).

    qp and object are the configs of the QP and of the object wrench.
    """

    ramp_time_constant: float = setting(
        0.02, 'tau: the grasp wrench rises as 1 - exp(-t / tau) after contact (and drops to zero '
        'at once outside CONTACT / MANIPULATE).', unit='s', low=0, high=1.0, low_open=True)
    design_acceleration: float = setting(
        6.0, 'Largest object acceleration the grasp must carry on top of gravity; with '
        "grip_safety_factor it raises the QP's normal-force bounds for heavy boxes "
        '(grip_normal_force).', unit='m/s^2', low=0, high=50.0)
    grip_safety_factor: float = setting(
        1.2, "Safety factor on the normal force a box's weight and design_acceleration need "
        '(grip_normal_force).', low=1.0, high=10.0)
    feed_forward_time_constant: float = setting(
        0.02, "Low-pass of the desired object acceleration (the difference of the DS's desired "
        'velocity between ticks) whose inertial wrench is added to f_o^d, clipped to 2 '
        'design_acceleration.', unit='s', low=0, high=1.0, low_open=True)
    square_grip_force: float = setting(
        40.0, 'Normal-force floor and preferred squeeze of a pad (in place of qp.min_normal_force '
        'and qp.squeeze_force, raised for heavy boxes as those are) for a box grasped within '
        'square_grip_yaw of square. The squeeze on a pad resting on its edge turns it over '
        'just before the release and rolls the box off its heading: paper_toss_random (seed 1, '
        '200 trials) leaves with release direction p95 2.87 deg, 3.37 at 70 N. A box yawed '
        'further is turned on its way and needs the full floor: with 40 N for every box, '
        'catalogue_random (seed 11, 300 trials) slips p95 5.17 mm, 17 of its 21 slides over '
        '5 mm boxes yawed 19-25 deg; with this grip 4.60 (4.55 at 70 N).', unit='N', low=0,
        high=NORMAL_FORCE_LIMIT)
    square_grip_yaw: float = setting(
        12.0, "Largest yaw of the box's squeeze axis from the line between the arms (world y), "
        'read from the estimate at the first tick of contact, that gets square_grip_force; '
        '0 turns the square grip off. The worst release directions at 70 N are boxes yawed '
        '6-11 deg.', unit='deg', low=0, high=90.0)
    qp: WrenchQPConfig = WrenchQPConfig()
    object: ObjectWrenchConfig = ObjectWrenchConfig()  # noqa: A003

    def __post_init__(self):
        check_settings(self)
        check_range('square_grip_force', self.square_grip_force, 0.0, self.qp.max_normal_force,
                    'N', high_open=True)


def grip_normal_force(mass, friction_coefficient, acceleration, gravity, safety_factor):
    """
    Return the normal force [N] each of two pads needs to hold a box of mass [kg].

    The friction pyramid of eq. 10 lets each pad carry mu / sqrt(2) f_z along one tangent, and
    the two pads share the load m (g + a) (gravity plus the design acceleration, both along
    the same tangent in the worst case): f_z >= safety m (g + a) / (sqrt(2) mu).
    """
    return (safety_factor * mass * (gravity + acceleration)
            / (np.sqrt(2.0) * friction_coefficient))


def qp_config_for_mass(config, mass):
    """
    Return config.qp with its normal-force bounds raised to hold mass (grip_normal_force).

    The upper bound rises by the ratio max / min; both stay within NORMAL_FORCE_LIMIT (the lower
    one below the upper): a box that needs more is gripped as hard as the limit allows, so no
    valid setting or mass makes the QP's config invalid.
    """
    qp = config.qp
    required = grip_normal_force(mass, qp.friction_coefficient, config.design_acceleration,
                                 config.object.gravity, config.grip_safety_factor)
    if required <= qp.min_normal_force:
        return qp
    ratio = qp.max_normal_force / qp.min_normal_force if qp.min_normal_force > 0 else math.inf
    max_force = min(max(qp.max_normal_force, ratio * required), NORMAL_FORCE_LIMIT)
    min_force = min(required, math.nextafter(max_force, 0.0))
    return replace(qp, min_normal_force=min_force,
                   squeeze_force=min(max(qp.squeeze_force, min_force), max_force),
                   max_normal_force=max_force)


def squeeze_axis_yaw(R_world_object):
    """
    Return the yaw [deg] of the box's squeeze axis (object y) from world y, in [0, 90].

    The pads hold the box on its +-y faces, so a half turn is the same grasp.
    """
    squeeze_axis = np.asarray(R_world_object, dtype=float)[:, 1]
    yaw = abs(math.degrees(math.atan2(-squeeze_axis[0], squeeze_axis[1])))
    return min(yaw, 180.0 - yaw)


def grip_qp_config(config, mass, yaw_deg):
    """
    Return the QP config of a grasp of a box of mass [kg] whose squeeze axis is yaw_deg off.

    Within config.square_grip_yaw the pads' floor and squeeze are config.square_grip_force;
    either way qp_config_for_mass raises them to hold the box.
    """
    if yaw_deg < config.square_grip_yaw:
        force = config.square_grip_force
        config = replace(config, qp=replace(config.qp, min_normal_force=force,
                                            squeeze_force=force))
    return qp_config_for_mass(config, mass)


@dataclass(frozen=True)
class DistributedWrenches:
    """
    Per-arm pad wrenches (6,) on the object [N, N m], world, and the QP's report.

    normal_force_floor: the grasp's lower bound on the pads' normal force [N] (0 outside one).
    """

    wrenches: dict
    object_wrench: np.ndarray
    gain: float
    feasible: bool
    status: str
    normal_force_floor: float = 0.0


class WrenchDistributor:
    """
    Object wrench (passive DS on the object, section II-E) split over the pads (eq. 10).

    The grip (grip_qp_config) is chosen at the first tick of a grasp from the box's estimated
    yaw and kept until the grasp ends.
    """

    def __init__(self, config, object_mass, object_size):
        self._config = config
        self._mass = float(object_mass)
        self._grip_yaw = None
        self._qp = None
        self._size = np.asarray(object_size, dtype=float)
        self._inertia_object = box_inertia(self._mass, self._size)
        self._gain = 0.0
        self._v_desired_previous = None
        self._a_desired = np.zeros(3)

    def reconfigure(self, config):
        """Use new weights, limits and gains from the next tick on."""
        self._config = config
        if self._grip_yaw is not None:
            self._qp = self._grip_qp(self._grip_yaw)

    def _grip_qp(self, yaw_deg):
        return ContactWrenchQP(grip_qp_config(self._config, self._mass, yaw_deg))

    def step(self, phase, p_world_tools, R_world_tools, p_world_object, R_world_object,
             v_world_object, w_world_object, v_world_desired, w_world_desired, dt):
        """Return the DistributedWrenches of one tick; zero wrenches outside grasp phases."""
        zero = {arm: np.zeros(6) for arm in ARMS}
        if phase not in GRASPING_PHASES:
            self._gain = 0.0
            self._v_desired_previous = None
            self._a_desired = np.zeros(3)
            self._grip_yaw = None
            return DistributedWrenches(zero, np.zeros(6), 0.0, True, 'not grasping')
        if self._grip_yaw is None:
            self._grip_yaw = squeeze_axis_yaw(R_world_object)
            self._qp = self._grip_qp(self._grip_yaw)
        floor = self._qp.config.min_normal_force
        self._gain += (1.0 - self._gain) * -np.expm1(-dt / self._config.ramp_time_constant)
        inertia_world = R_world_object @ self._inertia_object @ R_world_object.T
        object_wrench = desired_object_wrench(v_world_object, w_world_object, v_world_desired,
                                              w_world_desired, self._mass, inertia_world,
                                              self._config.object)
        object_wrench += inertial_wrench(self._mass, inertia_world,
                                         self._desired_acceleration(v_world_desired, dt),
                                         np.zeros(3))
        contacts = {arm: pad_contact_geometry(arm, p_world_tools[arm], R_world_tools[arm],
                                              p_world_object, R_world_object, self._size)
                    for arm in ARMS}
        try:
            result = self._qp.contact_wrenches(object_wrench, p_world_object, contacts)
        except SolverError as error:
            return DistributedWrenches(zero, object_wrench, self._gain, False, str(error),
                                       floor)
        wrenches = {arm: np.round(self._gain * wrench_about_tool(
            result.wrenches[arm], contacts[arm].p_world_contact, p_world_tools[arm]),
            WRENCH_DECIMALS) for arm in ARMS}
        return DistributedWrenches(wrenches, object_wrench, self._gain, result.feasible,
                                   result.status, floor)

    def _desired_acceleration(self, v_world_desired, dt):
        """Return the filtered, clipped desired object acceleration (3,) [m/s^2]."""
        config = self._config
        v_world_desired = np.asarray(v_world_desired, dtype=float)
        if self._v_desired_previous is not None and dt > 0.0:
            raw = (v_world_desired - self._v_desired_previous) / dt
            self._a_desired = self._a_desired + (raw - self._a_desired) * -np.expm1(
                -dt / config.feed_forward_time_constant)
        self._v_desired_previous = v_world_desired
        limit = 2.0 * config.design_acceleration
        norm = float(np.linalg.norm(self._a_desired))
        return self._a_desired * (limit / norm) if norm > limit else self._a_desired
