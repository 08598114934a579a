"""
Rigid-body model of one arm with its grabber (pinocchio), placed in the world frame.

The URDF is the single robot description; drive armature and viscous damping come from the cell
configuration and are passed in. Quantities are in the world frame (dual-arm frame, z up) unless
a name says otherwise; Jacobians and twists are world-aligned at the named point, rows
[linear; angular].
"""

from dual_arm_control.core.arms import JOINTS_PER_ARM
from dual_arm_control.core.elbow_reach import ElbowReach
from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.validation import check_vector, finite_array
import numpy as np
import pinocchio as pin

TOOL_FRAME = 'tool'
FLANGE_FRAME = 'flange'
SENSOR_FRAME = 'ft_sensor'
# pinocchio joint indices (0 is the universe) of A2 (its axis origin is the shoulder), A4 (the
# elbow) and A6 (the wrist).
SHOULDER_JOINT = 2
ELBOW_JOINT = 4
WRIST_JOINT = 6


class ArmModel:
    """
    Kinematics and dynamics of one 7-joint arm, base placed in the world frame.

    Mass matrix and forward dynamics include the joint armature (reflected rotor inertia); the
    forward dynamics apply the viscous joint damping as -damping * dq. Gravity is -9.81 m/s^2
    along world z.
    """

    def __init__(self, urdf_path, joint_names, base_position=(0.0, 0.0, 0.0),
                 R_world_base=None, armature=None, damping=None):
        """
        Build the model from a URDF file.

        urdf_path: the arm URDF (7 revolute joints; tool, flange and ft_sensor frames).
        joint_names: the 7 joint names used in messages (e.g. contract.joint_names(arm)).
        base_position: (3,) world position of the arm base [m].
        R_world_base: (3, 3) rotation of the base in the world frame; identity if None.
        armature: (7,) joint armature [kg m^2]; zeros if None.
        damping: (7,) viscous joint damping [N m s/rad]; zeros if None.
        """
        try:
            model = pin.buildModelFromUrdf(str(urdf_path))
        except (RuntimeError, ValueError, OSError) as error:
            raise ConfigError(f'{urdf_path}: cannot build a pinocchio model: {error}') from None
        if model.nq != JOINTS_PER_ARM or model.nv != JOINTS_PER_ARM:
            raise ConfigError(f'{urdf_path}: expected {JOINTS_PER_ARM} revolute joints, got '
                              f'nq = {model.nq}')
        for frame in (TOOL_FRAME, FLANGE_FRAME, SENSOR_FRAME):
            if not model.existFrame(frame):
                raise ConfigError(f'{urdf_path}: frame {frame!r} is missing')
        names = list(joint_names)
        if len(names) != JOINTS_PER_ARM:
            raise ConfigError(f'joint_names must have {JOINTS_PER_ARM} entries, got {names}')
        rotation = np.eye(3) if R_world_base is None else np.asarray(R_world_base, dtype=float)
        if rotation.shape != (3, 3) or not np.allclose(rotation @ rotation.T, np.eye(3),
                                                       atol=1e-9):
            raise ConfigError(f'R_world_base must be a 3x3 rotation matrix, got {rotation}')
        T_world_base = pin.SE3(rotation, check_vector('base_position', base_position, 3, 'm'))
        model.jointPlacements[1] = T_world_base * model.jointPlacements[1]
        for frame in model.frames:
            if frame.parentJoint == 0 and frame.name != 'universe':
                frame.placement = T_world_base * frame.placement
        zeros = np.zeros(JOINTS_PER_ARM)
        model.armature = check_vector(
            'armature', zeros if armature is None else armature, JOINTS_PER_ARM, 'kg m^2')
        self._damping = check_vector(
            'damping', zeros if damping is None else damping, JOINTS_PER_ARM, 'N m s/rad')
        if np.any(model.armature < 0.0) or np.any(self._damping < 0.0):
            raise ConfigError('armature and damping must be >= 0')
        self.model = model
        self.data = model.createData()
        self.urdf_path = str(urdf_path)
        self.T_world_base = T_world_base
        self._joint_names = tuple(names)
        self._tool_id = model.getFrameId(TOOL_FRAME)
        self._flange_id = model.getFrameId(FLANGE_FRAME)
        self._sensor_id = model.getFrameId(SENSOR_FRAME)

    @property
    def nq(self):
        """Return the number of joints (7)."""
        return self.model.nq

    @property
    def joint_names(self):
        """Joint names as given to the constructor (message names)."""
        return self._joint_names

    @property
    def position_limits(self):
        """(lower, upper) joint position limits [rad], (7,) each."""
        return (self.model.lowerPositionLimit.copy(), self.model.upperPositionLimit.copy())

    @property
    def velocity_limits(self):
        """Joint speed limits [rad/s], (7,)."""
        return self.model.velocityLimit.copy()

    @property
    def torque_limits(self):
        """Joint torque limits [N m], (7,)."""
        return self.model.effortLimit.copy()

    @property
    def armature(self):
        """Joint armature [kg m^2], (7,)."""
        return self.model.armature.copy()

    @property
    def damping(self):
        """Viscous joint damping [N m s/rad], (7,)."""
        return self._damping.copy()

    def _q(self, q):
        return finite_array('q', q, (JOINTS_PER_ARM,))

    def _dq(self, dq):
        return finite_array('dq', dq, (JOINTS_PER_ARM,))

    def _frame_pose(self, q, frame_id):
        pin.forwardKinematics(self.model, self.data, self._q(q))
        placement = pin.updateFramePlacement(self.model, self.data, frame_id)
        return placement.translation.copy(), placement.rotation.copy()

    def tool_pose(self, q):
        """Return (p_world_tool (3,) [m], R_world_tool (3, 3)) at joint positions q [rad]."""
        return self._frame_pose(q, self._tool_id)

    def tool_and_sensor_poses(self, q):
        """Return ((p_world_tool, R_world_tool), (p_world_sensor, R_world_sensor)) in one pass."""
        tool = self._frame_pose(q, self._tool_id)
        sensor = pin.updateFramePlacement(self.model, self.data, self._sensor_id)
        return tool, (sensor.translation.copy(), sensor.rotation.copy())

    def tool_pose_and_jacobian(self, q):
        """
        Return (p_world_tool, R_world_tool, tool Jacobian (6, 7)) from one kinematics pass.

        The same numbers as tool_pose and tool_jacobian, which each run the kinematics anew.
        """
        jacobian = pin.computeFrameJacobian(self.model, self.data, self._q(q), self._tool_id,
                                            pin.LOCAL_WORLD_ALIGNED).copy()
        placement = self.data.oMf[self._tool_id]
        return placement.translation.copy(), placement.rotation.copy(), jacobian

    def flange_pose(self, q):
        """Return (p_world_flange (3,) [m], R_world_flange (3, 3))."""
        return self._frame_pose(q, self._flange_id)

    def sensor_pose(self, q):
        """Return (p_world_sensor (3,) [m], R_world_sensor (3, 3)) of the FT sensor frame."""
        return self._frame_pose(q, self._sensor_id)

    def tool_jacobian(self, q):
        """Return the (6, 7) tool Jacobian, world-aligned at the tool point, [linear; angular]."""
        return pin.computeFrameJacobian(self.model, self.data, self._q(q), self._tool_id,
                                        pin.LOCAL_WORLD_ALIGNED).copy()

    def elbow_jacobian(self, q):
        """Return the (3, 7) linear Jacobian of the elbow (the A4 axis origin), world-aligned."""
        pin.computeJointJacobians(self.model, self.data, self._q(q))
        return pin.getJointJacobian(self.model, self.data, ELBOW_JOINT,
                                    pin.LOCAL_WORLD_ALIGNED)[:3].copy()

    def elbow_reach(self):
        """
        Return the ElbowReach of the arm.

        Its shoulder, the wrist in the tool frame, and the shoulder-wrist distances with the
        elbow (A4) folded to its joint limit and stretched straight.
        """
        q = np.zeros(JOINTS_PER_ARM)
        p_world_tool, R_world_tool = self.tool_pose(q)
        shoulder = self.data.oMi[SHOULDER_JOINT].translation.copy()
        wrist_in_tool = R_world_tool.T @ (self.data.oMi[WRIST_JOINT].translation - p_world_tool)
        straight = float(np.linalg.norm(self.data.oMi[WRIST_JOINT].translation - shoulder))
        lower, upper = self.position_limits
        q[ELBOW_JOINT - 1] = min(abs(lower[ELBOW_JOINT - 1]), abs(upper[ELBOW_JOINT - 1]))
        pin.forwardKinematics(self.model, self.data, q)
        folded = float(np.linalg.norm(self.data.oMi[WRIST_JOINT].translation
                                      - self.data.oMi[SHOULDER_JOINT].translation))
        return ElbowReach(shoulder, wrist_in_tool, folded, straight)

    def tool_twist(self, q, dq):
        """Return (v_world (3,) [m/s], w_world (3,) [rad/s]) of the tool point."""
        twist = self.tool_jacobian(q) @ self._dq(dq)
        return twist[:3], twist[3:]

    def mass_matrix(self, q):
        """Return the (7, 7) joint-space inertia [kg m^2], armature included, symmetric."""
        upper = pin.crba(self.model, self.data, self._q(q))
        return np.triu(upper) + np.triu(upper, 1).T

    def gravity_torque(self, q):
        """Return the (7,) joint torques [N m] that balance gravity at q."""
        return pin.computeGeneralizedGravity(self.model, self.data, self._q(q)).copy()

    def nonlinear_effects(self, q, dq):
        """Return the (7,) Coriolis, centrifugal and gravity torques [N m] (no damping)."""
        return pin.nonLinearEffects(self.model, self.data, self._q(q), self._dq(dq)).copy()

    def forward_dynamics(self, q, dq, tau):
        """Return ddq (7,) [rad/s^2] for joint torques tau [N m], with armature and damping."""
        dq = self._dq(dq)
        tau = finite_array('tau', tau, (JOINTS_PER_ARM,))
        return pin.aba(self.model, self.data, self._q(q), dq, tau - self._damping * dq).copy()
