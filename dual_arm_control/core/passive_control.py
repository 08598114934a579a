"""
Passive-DS torque controller of one arm (Kronander and Billard 2016), as used by the paper.

Per tick, with the tool twist [v; w] = J(q) dq (world-aligned at the tool point):

    F = -D(v_d) (v - v_d)                  D = Q diag(lambda0, lambda1, lambda1) Q^T
    M = -d_w (w - w_d) + K_R log(R_d R^T)  orientation damping and stiffness
    tau = J^T ([F; M] + w_c) + g(q) + N tau_null,   tau_null = -K_n (q - q_n) - d_n dq

w_c is the contact wrench the QP assigns to this pad (applied by the pad on the object), so the
robot pushes with +w_c. g(q) is pinocchio's gravity torque of arm and tool.

Null space: the symmetric (kinematic) projector N = I - J^T (J J^T + eps^2 I)^-1 J. Being
symmetric positive semi-definite it keeps the projected joint damping -d_n N dq dissipative
(d_n is a scalar for that reason), which the dynamically consistent projector (not
symmetric) does not; the price is that null-space torques are not inertially decoupled from
the tool, so they perturb the tool only transiently (J N tau ~ 0: no tool wrench, the tool
equilibrium is unchanged).
The posture spring through N is not a potential force; the passivity guarantee covers the
task law, the orientation spring and all damping terms.

Saturation scales the non-gravity part of tau by one factor s in (0, 1] until every joint is
within its limit (clipping only if gravity alone exceeds a limit): the task torque keeps its
direction, so a dissipative command stays dissipative. A non-finite input or result yields the
hold torque g(q) - D_hold dq (last finite gravity torque if q is not finite) and a status.
"""

import dataclasses
import math

from dual_arm_control.core.exceptions import InputError
from dual_arm_control.core.geometry import rotation_log
from dual_arm_control.core.linear_solve import solve
from dual_arm_control.core.reachability import inverse_kinematics_step, tool_pose_error
from dual_arm_control.core.settings import check_settings, setting
from dual_arm_control.core.validation import all_finite
import numpy as np


JOINTS = 7
_INPUT_NAMES = ('q', 'dq', 'v_world_desired', 'w_world_desired', 'R_world_desired',
                'contact_wrench')
_INPUT_SHAPES = ((JOINTS,), (JOINTS,), (3,), (3,), (3, 3), (6,))
# Damping of the posture's inverse-kinematics steps [(m or rad)^2].
_POSTURE_IK_DAMPING = 1e-3
_NO_WRENCH = np.zeros(6)
_NO_WRENCH.flags.writeable = False


@dataclasses.dataclass(frozen=True)
class PassiveControllerConfig:
    """
    Gains of the passive-DS torque law; defaults within the authors' setup's ranges.

    Vector fields are 7 numbers, joints A1..A7.
    """

    damping_along: float = setting(
        400.0, 'lambda0, damping along the desired velocity (reference 70-150; 400 tracks the '
        '0.5 m/s impact within 7 % and the 0.85 m/s toss within 5 % in the twin).',
        unit='N s/m', low=0, high=1e4, low_open=True)
    damping_across: float = setting(
        400.0, 'lambda1, damping across the desired velocity (reference 70-150).',
        unit='N s/m', low=0, high=1e4, low_open=True)
    direction_blend_speed: float = setting(
        0.01, 'Below about this desired speed D blends continuously to lambda1 I.',
        unit='m/s', low=0, high=10.0, low_open=True)
    angular_damping: float = setting(
        6.0, 'd_w, damping on w - w_d from the first contact wrench of an episode on '
        '(reference 6).',
        unit='N m s/rad', low=0, high=1e3)
    orientation_stiffness: float = setting(
        10.0, 'K_R, stiffness toward the desired orientation from the first contact wrench of '
        'an episode on.', unit='N m/rad', low=0, high=1e4)
    free_angular_damping: float = setting(
        10.0, 'd_w until the first contact wrench of an episode (the reach).',
        unit='N m s/rad', low=0, high=1e3)
    free_orientation_stiffness: float = setting(
        80.0, 'K_R until the first contact wrench of an episode (the reach). In the folded '
        "postures of the reach the arm's inertia couples the tool's linear and angular motion; "
        'with 10 the pads met yawed faces 5-19 deg off flush, one corner first '
        '(catalogue_random). Not after the grasp: stiff while the hands open, it cost the toss '
        '3 % of its release speed.',
        unit='N m/rad', low=0, high=1e4)
    free_gains_after: float = setting(
        2.0, 'Once touched, the contact gains stay on until no contact wrench has come for this '
        'long; then the free gains return (and the elbow lift goes off) for the next reach, as '
        "start_episode does when the clock restarts, which a real robot's clock never does. "
        'Longer than the retract to standby (1.1-1.3 s in the twin): at 0.5 s the stiffer '
        'orientation slowed it, cycle time p95 +0.2 s (paper_toss_random).',
        unit='s', low=0, high=100.0, low_open=True)
    null_space_stiffness: tuple = setting(
        (10.0,) * JOINTS, 'K_n, posture stiffness per joint.',
        unit='N m/rad', low=0, high=1e4, size=JOINTS)
    null_space_damping: float = setting(
        1.0, 'd_n, joint damping in the null space, same on every joint.',
        unit='N m s/rad', low=0, high=1e3)
    null_space_error_limit: float = setting(
        0.4, 'Per-joint posture error saturation.', unit='rad', low=0, high=10.0, low_open=True)
    elbow_lift_force: float = setting(
        0.0, 'Upward force on the elbow, applied in the null space from the first contact wrench '
        'of an episode on (not in the reach, where at 10 N it leaked through the torque-level '
        'projector and doubled the impact gap): of the postures that hold the tool, the arm '
        'prefers the elbow-up one. For a pick-and-place cell: at 20 N, 3 of the 4 forearms that '
        "met the front table's edge as boxes were set down at the arms' reach stayed clear (2 x "
        '60 catalogue_random_place trials). Off by default: in the toss carry it raised the '
        'slip p95 from 6.2 to 7.2 mm (catalogue_random, 300 trials).',
        unit='N', low=0, high=500.0)
    posture_tracking_step: float = setting(
        0.01, 'Largest change of the null-space posture per control cycle as it follows an '
        "inverse-kinematics solution of the DS's target pose within the joint limits (0: the "
        "posture stays where it was set). The arm's redundancy then steers it to a configuration "
        'that can hold the target, not into a joint limit on the way.',
        unit='rad', low=0, high=1.0)
    projector_damping: float = setting(
        1e-3, 'eps of the damped pseudo-inverse in the null-space projector.',
        unit='m, rad', low=0, high=1.0, low_open=True)
    joint_speed_onset: float = setting(
        0.8, "Fraction of a joint's speed limit (URDF) above which joint_speed_brake_torque "
        'brakes it.', low=0.1, high=1.0)
    joint_speed_brake_time: float = setting(
        0.0, "Time in which the brake would take a joint's speed excess out on the drive's own "
        'inertia (armature); at or above the FRI period the brake cannot oscillate. 0 (the '
        'default) switches it off: at 0.002 s the paper toss keeps every joint within 1.3x its '
        'limit (2.9x unbraked) but the braked arms lag unevenly and the box slips over 1 cm in '
        'a third of paper_toss_random (README, known limits).', unit='s', low=0, high=1.0)
    hold_damping: tuple = setting(
        (10.0, 10.0, 8.0, 8.0, 4.0, 2.0, 2.0), 'D_hold of the safety hold torque g(q) - D_hold '
        'dq, per joint.', unit='N m s/rad', low=0, high=1e4, size=JOINTS)

    def __post_init__(self):
        """Validate every field; raise ConfigError naming the field, value and range."""
        check_settings(self)


def joint_speed_brake_torque(dq, velocity_limits, armature, onset, brake_time):
    """
    Return the torque (7,) [N m] that brakes every joint faster than onset x its speed limit.

    The passive DS law drives the tool at the task's velocity with whatever joint speeds the
    arm's posture asks for, and a folded elbow unfolding for a toss asks for several times the
    iiwa's joint speed limits; the KUKA controller stops an arm that exceeds one. The brake
    opposes only the excess, armature / brake_time per rad/s over the onset: the task's
    damping then makes up for the braked joint with the others (the arm is redundant), so
    the tool keeps its velocity where the posture allows it. As the joint's inertia is at
    least its armature, a brake_time of at least the control period gives a per-cycle gain
    of at most 1: the discrete brake does not oscillate.
    """
    if brake_time <= 0.0:
        return np.zeros_like(dq)
    excess = np.maximum(np.abs(dq) - onset * velocity_limits, 0.0)
    return -armature / brake_time * excess * np.sign(dq)


@dataclasses.dataclass(frozen=True)
class TorqueCommand:
    """
    Output of one controller tick.

    torque: (7,) joint torques to send [N m], finite and within the limits.
    task_wrench: (6,) [F; M] + w_c at the tool before saturation, world frame [N, N m]
        (zeros on hold).
    saturated: the torque limits scaled (or clipped) the command.
    held: the hold torque was sent instead of the control law.
    status: 'ok', 'saturated' or 'hold: <reason>'.
    """

    torque: np.ndarray
    task_wrench: np.ndarray
    saturated: bool
    held: bool
    status: str


def passive_ds_damping_matrix(v_desired, damping_along, damping_across, blend_speed):
    """
    Return the (3, 3) damping D(v_d) [N s/m] of the passive DS, world frame.

    D = Q diag(lambda0, lambda1, lambda1) Q^T with Q e1 = v_d / ||v_d||, written as
    lambda1 I + (lambda0 - lambda1) v_d v_d^T / (||v_d||^2 + blend_speed^2): symmetric positive
    definite, v_d stays an eigenvector, continuous everywhere and isotropic (lambda1 I) at
    v_d = 0, equal to the Kronander-Billard matrix within (blend_speed / ||v_d||)^2.
    """
    v_desired = np.asarray(v_desired, dtype=float)
    scale = (damping_along - damping_across) / (v_desired @ v_desired + blend_speed ** 2)
    matrix = scale * np.outer(v_desired, v_desired)
    matrix[np.diag_indices(3)] += damping_across
    return matrix


def passive_ds_force(v_world_tool, v_world_desired, config):
    """
    Return F = -D(v_d) (v - v_d) (3,) [N] of the passive DS (Kronander and Billard 2016).

    D is passive_ds_damping_matrix(v_d, ...), applied without forming the matrix.
    """
    v_world_desired = np.asarray(v_world_desired, dtype=float)
    error = v_world_desired - np.asarray(v_world_tool, dtype=float)
    scale = ((config.damping_along - config.damping_across) * (v_world_desired @ error)
             / (v_world_desired @ v_world_desired + config.direction_blend_speed ** 2))
    return config.damping_across * error + scale * v_world_desired


def orientation_error_vector(R_error):
    """
    Return the rotation vector (3,) [rad] of a rotation matrix, theta in [0, pi].

    Same result as geometry.rotation_log, in scalar arithmetic for the torque loop; near
    theta = pi it defers to rotation_log.
    """
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = R_error.tolist()
    cos_theta = min(1.0, max(-1.0, 0.5 * (r00 + r11 + r22 - 1.0)))
    theta = math.acos(cos_theta)
    if math.pi - theta < 1e-6:
        return rotation_log(R_error)
    factor = 0.5 if theta < 1e-9 else 0.5 * theta / math.sin(theta)
    return np.array([factor * (r21 - r12), factor * (r02 - r20), factor * (r10 - r01)])


def orientation_moment(w_world_tool, w_world_desired, R_world_tool, R_world_desired, stiffness,
                       damping):
    """
    Return M (3,) [N m]: damping on w - w_d plus a stiffness toward R_world_desired.

    M = -d_w (w - w_d) + K_R log(R_d R^T) with K_R = stiffness [N m/rad], d_w = damping
    [N m s/rad]; the spring is the gradient of K_R theta^2 / 2 with theta the angle between the
    two orientations, so it stores and returns energy only.
    """
    error = orientation_error_vector(R_world_desired @ R_world_tool.T)
    return (damping * (np.asarray(w_world_desired) - np.asarray(w_world_tool))
            + stiffness * error)


def hold_torque(gravity_torque, dq, hold_damping):
    """Return g - D_hold dq (7,) [N m]; non-finite velocity entries contribute nothing."""
    dq = np.asarray(dq, dtype=float)
    damping = np.where(np.isfinite(dq), np.asarray(hold_damping) * dq, 0.0)
    return np.asarray(gravity_torque, dtype=float) - damping


def saturated_torque(gravity_torque, control_torque, torque_limits):
    """
    Return (tau (7,), saturated) with tau = g + s * control_torque within +-torque_limits.

    s in [0, 1] is the largest factor keeping every joint within its limit; if gravity alone
    violates a limit the result is clipped as well.
    """
    torque = gravity_torque + control_torque
    if (np.abs(torque) <= torque_limits).all():
        return torque, False
    over = (np.abs(torque) > torque_limits) & (control_torque != 0.0)
    factor = 1.0
    if np.any(over):
        headroom = torque_limits[over] - np.sign(control_torque[over]) * gravity_torque[over]
        factor = float(np.clip(np.min(headroom / np.abs(control_torque[over])), 0.0, 1.0))
    torque = np.clip(gravity_torque + factor * control_torque, -torque_limits, torque_limits)
    return torque, True


class PassiveController:
    """
    Passive-DS torque controller of one arm, state = null-space posture and last gravity torque.

    model: an object with the ArmModel API (tool_pose, tool_jacobian, gravity_torque,
    torque_limits); q_null: (7,) posture of the null-space spring [rad].
    """

    def __init__(self, model, q_null, config=None):
        """Bind the arm model; read its torque limits once."""
        self.model = model
        self._torque_limits = np.asarray(model.torque_limits, dtype=float).copy()
        self._velocity_limits = np.asarray(model.velocity_limits, dtype=float).copy()
        self._armature = np.asarray(model.armature, dtype=float).copy()
        self._position_limits = model.position_limits
        self.reconfigure(PassiveControllerConfig() if config is None else config)
        self.q_null = None
        self.set_null_space_posture(q_null)
        self.last_gravity_torque = np.zeros(JOINTS)
        self.touched = False

    def reconfigure(self, config):
        """
        Use config's gains from the next call on, keeping the controller's state.

        The tracked null-space posture, the last gravity torque and whether the arm has touched
        stay: a gain tuned live while the arms hold a box changes that gain only, and does not
        pull the arm back toward the posture it started the episode in.
        """
        self.config = config
        self._null_stiffness = np.array(config.null_space_stiffness)
        self._null_damping = float(config.null_space_damping)
        self._hold_damping = np.array(config.hold_damping)
        self._regulariser = config.projector_damping ** 2 * np.eye(6)

    def start_episode(self):
        """Return to the free-motion gains without elbow lift until the next contact wrench."""
        self.touched = False

    def set_null_space_posture(self, q_null):
        """Set the posture [rad] (7,) the null-space spring pulls toward."""
        q_null = np.array(q_null, dtype=float)
        if q_null.shape != (JOINTS,) or not np.isfinite(q_null).all():
            raise InputError(f'q_null must be {JOINTS} finite joint positions, got {q_null}')
        q_null.flags.writeable = False
        self.q_null = q_null

    def track_posture(self, p_world_target, R_world_target):
        """
        Move the null-space posture one inverse-kinematics step toward the target tool pose.

        The step starts from the posture itself (not the measured joints), is capped at
        posture_tracking_step and keeps every joint within its limits.
        """
        if self.config.posture_tracking_step <= 0.0:
            return
        p_world_tool, R_world_tool, jacobian = self.model.tool_pose_and_jacobian(self.q_null)
        error = tool_pose_error(p_world_tool, R_world_tool, p_world_target, R_world_target)
        posture = inverse_kinematics_step(self.model, np.array(self.q_null), error,
                                          *self._position_limits, _POSTURE_IK_DAMPING,
                                          self.config.posture_tracking_step, jacobian)
        posture.flags.writeable = False
        self.q_null = posture

    def null_space_torque(self, jacobian, q, dq):
        """
        Return N tau_null (7,) [N m]: posture and elbow-lift torques projected off the tool.

        The elbow lift acts once the arm has touched (start_episode turns it off again).
        """
        limit = self.config.null_space_error_limit
        error = np.minimum(np.maximum(q - self.q_null, -limit), limit)
        torque = -self._null_stiffness * error - self._null_damping * dq
        if self.touched and self.config.elbow_lift_force > 0.0:
            torque += self.model.elbow_jacobian(q)[2] * self.config.elbow_lift_force
        return torque - jacobian.T @ solve(
            jacobian @ jacobian.T + self._regulariser, jacobian @ torque)

    def torque_command(self, q, dq, v_world_desired, w_world_desired, R_world_desired,
                       contact_wrench=None):
        """
        Return the TorqueCommand of one tick of the passive-DS law.

        q, dq: (7,) measured joint positions [rad] and velocities [rad/s].
        v_world_desired, w_world_desired: (3,) desired tool twist from the DS [m/s, rad/s].
        R_world_desired: (3, 3) desired tool orientation.
        contact_wrench: (6,) [f; m] the pad must apply on the object, world frame, moment
            about the tool point [N, N m]; None = no contact.
        Non-finite numbers never raise: the hold torque is returned with the reason in the
        status. Misshaped inputs (a programming error) raise InputError.
        """
        q = np.asarray(q, dtype=float)
        dq = np.asarray(dq, dtype=float)
        v_world_desired = np.asarray(v_world_desired, dtype=float)
        w_world_desired = np.asarray(w_world_desired, dtype=float)
        R_world_desired = np.asarray(R_world_desired, dtype=float)
        contact_wrench = (_NO_WRENCH if contact_wrench is None
                          else np.asarray(contact_wrench, dtype=float))
        inputs = (q, dq, v_world_desired, w_world_desired, R_world_desired, contact_wrench)
        for array, shape, name in zip(inputs, _INPUT_SHAPES, _INPUT_NAMES):
            if array.shape != shape:
                raise InputError(f'{name} must have shape {shape}, got {array.shape}')
        if all_finite(q):
            gravity = self.model.gravity_torque(q)
            if all_finite(gravity):
                self.last_gravity_torque = gravity
        if not all_finite(np.concatenate([a.ravel() for a in inputs])):
            bad = [name for array, name in zip(inputs, _INPUT_NAMES)
                   if not np.isfinite(array).all()]
            return self._hold(dq, 'non-finite ' + ', '.join(bad))
        _, R_world_tool, jacobian = self.model.tool_pose_and_jacobian(q)
        twist = jacobian @ dq
        config = self.config
        self.touched = self.touched or bool(contact_wrench.any())
        if self.touched:
            stiffness, damping = config.orientation_stiffness, config.angular_damping
        else:
            stiffness, damping = config.free_orientation_stiffness, config.free_angular_damping
        task_wrench = np.concatenate((
            passive_ds_force(twist[:3], v_world_desired, config),
            orientation_moment(twist[3:], w_world_desired, R_world_tool, R_world_desired,
                               stiffness, damping)))
        task_wrench += contact_wrench
        control = (jacobian.T @ task_wrench + self.null_space_torque(jacobian, q, dq)
                   + joint_speed_brake_torque(dq, self._velocity_limits, self._armature,
                                              self.config.joint_speed_onset,
                                              self.config.joint_speed_brake_time))
        torque, saturated = saturated_torque(self.last_gravity_torque, control,
                                             self._torque_limits)
        if not all_finite(torque):
            return self._hold(dq, 'non-finite control torque')
        return TorqueCommand(torque=torque, task_wrench=task_wrench, saturated=saturated,
                             held=False, status='saturated' if saturated else 'ok')

    def _hold(self, dq, reason):
        """Return the hold TorqueCommand (last gravity torque minus damping), saturated."""
        torque = hold_torque(self.last_gravity_torque, dq, self._hold_damping)
        torque = np.clip(np.nan_to_num(torque), -self._torque_limits, self._torque_limits)
        return TorqueCommand(torque=torque, task_wrench=np.zeros(6), saturated=False,
                             held=True, status=f'hold: {reason}')
