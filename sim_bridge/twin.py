"""
ROS-free MuJoCo twin of the cell: two torque-controlled arms behind an FRI-like interface.

One call to step() is one FRI cycle: the torques are held for fri_period (fri_period / dt
physics steps at dt = 1 ms). Sensors: joint state, FT wrench per grabber (noise and bias),
motion capture of the object (rate, latency, noise, dropouts) and, with a conveyor, of the
container (sim_bridge.belt). All randomness comes from generators seeded by the scenario seed
and drawn in a fixed order, so two runs with the same scenario and torques are bit-identical.
"""

from collections import deque
import copy

from dual_arm_control.core.arms import ARMS
from dual_arm_control.core.exceptions import ConfigError, InputError
from dual_arm_control.core.geometry import matrix_to_quat_xyzw, rotation_exp
from dual_arm_control.core.validation import finite_array
from dual_arm_control.description.cell import load_cell
from dual_arm_control.runtime.node_settings import FRI_PERIOD, FRI_PERIODS, TORQUE_INTERFACES
import mujoco
import numpy as np
from sim_bridge.arm_collisions import ArmCollisionMonitor
from sim_bridge.belt import ContainerDrive
from sim_bridge.incoming_belt import build_cell_model, IncomingBeltDrive
from sim_bridge.pad_forces import pad_wrench
from sim_bridge.safety_hold import hold_command
from sim_bridge.scene import PHYSICS_TIMESTEP, quat_wxyz_to_xyzw, site_pose
from sim_bridge.twin_samples import JointSample, MocapSample, StepReport, TwinState

# A sample or perturbation due at time t is taken at the first physics tick with
# tick * dt >= t - TIME_EPSILON [s] (floating-point tolerance on the sim clock).
TIME_EPSILON = 1e-9


class DualArmTwin:
    """
    MuJoCo twin of the two arms, their grabbers, the object and the static scene.

    Frames: world = dual-arm frame (z up); quaternions (x, y, z, w). Torques are joint torques
    [N m] in URDF joint order A1..A7.
    """

    def __init__(self, scenario, cell=None, fri_period=FRI_PERIOD, torque_interface='full'):
        """
        Build the model for a scenario and reset to its initial state.

        scenario: dual_arm_control.scenario.Scenario; cell: CellDescription (config/cell.yaml
        if None); fri_period: FRI cycle [s], one of FRI_PERIODS; torque_interface: 'full'
        (commands are the whole joint torque) or 'gravity_compensated' (the robot adds its own
        gravity compensation to the commanded torque, as KUKA's controller does in FRI torque
        mode).
        """
        if torque_interface not in TORQUE_INTERFACES:
            raise ConfigError(f'torque_interface must be one of {TORQUE_INTERFACES}, got '
                              f'{torque_interface!r}')
        self.torque_interface = torque_interface
        if not any(abs(fri_period - period) < 1e-12 for period in FRI_PERIODS):
            raise ConfigError(f'fri_period = {fri_period} s is not one of {FRI_PERIODS} s')
        self.scenario = scenario
        self.cell = cell or load_cell()
        self.model, self.index = build_cell_model(self.cell, scenario)
        self.data = mujoco.MjData(self.model)
        self._scratch = mujoco.MjData(self.model)
        self._fri_period = float(fri_period)
        self._substeps = int(round(fri_period / PHYSICS_TIMESTEP))
        self._torque_limits = {arm: self.model.actuator_ctrlrange[self.index.arms[arm].actuators,
                                                                  1].copy() for arm in ARMS}
        mocap = scenario.sensors.mocap
        self._sample_period_ticks = 1.0 / (mocap.rate_hz * PHYSICS_TIMESTEP)
        self._latency = mocap.latency
        self._collisions = ArmCollisionMonitor(self.model, self.index)
        self.container = None if scenario.conveyor is None else ContainerDrive(
            self.model, scenario.conveyor, scenario.seed, mocap)
        self.incoming_belt = None if scenario.incoming_belt is None else IncomingBeltDrive(
            self.model, scenario.incoming_belt, scenario.seed)
        self.reset()

    @property
    def arms(self):
        """Arm names, ('left', 'right')."""
        return ARMS

    @property
    def time(self):
        """Sim time [s] since reset."""
        return self._tick * PHYSICS_TIMESTEP

    @property
    def fri_period(self):
        """FRI cycle [s]: the duration of one step()."""
        return self._fri_period

    @property
    def physics_timestep(self):
        """Physics step [s]."""
        return PHYSICS_TIMESTEP

    def set_belt_speed(self, speed):
        """Command the outgoing belt's speed [m/s] (toward world -y); InputError without one."""
        if self.container is None:
            raise InputError('this scenario has no conveyor')
        self.container.belt.command(float(finite_array('belt speed', [speed], (1,))[0]))

    def set_incoming_belt_speed(self, speed):
        """Command the incoming belt's speed [m/s] (toward world -y); InputError without one."""
        if self.incoming_belt is None:
            raise InputError('this scenario has no incoming belt')
        self.incoming_belt.belt.command(float(finite_array('belt speed', [speed], (1,))[0]))

    @property
    def arm_collisions(self):
        """Every ArmCollision since reset(), in order."""
        return tuple(self._collision_log)

    def torque_limits(self, arm):
        """Return the (7,) joint torque limits [N m] of an arm (URDF effort limits)."""
        return self._torque_limits[self._arm(arm)].copy()

    def reset(self, seed=None):
        """Return to the initial state of the scenario; reseed the noise (seed None: its own)."""
        self.seed = int(self.scenario.seed if seed is None else seed)
        mujoco.mj_resetData(self.model, self.data)
        for arm in ARMS:
            self.data.qpos[self.index.arms[arm].qpos] = \
                self.scenario.initial_configuration[arm]
        adr = self.index.object_qpos
        yaw = float(self.scenario.object.yaw)
        self.data.qpos[adr:adr + 3] = self.scenario.object.position
        self.data.qpos[adr + 3:adr + 7] = [np.cos(0.5 * yaw), 0.0, 0.0, np.sin(0.5 * yaw)]
        self._container_pending = deque()
        if self.container is not None:
            self.container.reset(self.data)
        if self.incoming_belt is not None:
            self.incoming_belt.reset(self.data)
        mujoco.mj_forward(self.model, self.data)
        self._tick = 0
        self._next_sample = 0
        self._next_perturbation = 0
        self._pending = deque()
        mocap_seed, ft_seed = np.random.SeedSequence(self.seed).spawn(2)
        self._mocap_rng = np.random.default_rng(mocap_seed)
        self._ft_rng = np.random.default_rng(ft_seed)
        self._collisions.reset()
        self._collision_log = []
        self._sample_mocap()
        self._update_ft()

    def step(self, torques):
        """
        Apply joint torques for one FRI period and advance the simulation.

        torques: {'left': (7,), 'right': (7,)} [N m], clamped to the torque limits. Returns a
        StepReport whose clamped[arm] is True where a command exceeded a limit. Raises
        InputError on a missing arm, a wrong shape or a non-finite value; nothing is applied.
        """
        if not isinstance(torques, dict) or set(torques) != set(ARMS):
            keys = sorted(torques) if isinstance(torques, dict) else type(torques).__name__
            raise InputError(f'torques must be a dict with keys {ARMS}, got {keys}')
        commands = {arm: finite_array(f'torques[{arm!r}]', torques[arm], (7,)) for arm in ARMS}
        if self.torque_interface == 'gravity_compensated':
            commands = {arm: commands[arm] + self.gravity_torques(arm) for arm in ARMS}
        clamped, applied = {}, {}
        for arm in ARMS:
            limit = self._torque_limits[arm]
            clamped[arm] = bool(np.any(np.abs(commands[arm]) > limit))
            applied[arm] = np.clip(commands[arm], -limit, limit)
            self.data.ctrl[self.index.arms[arm].actuators] = applied[arm]
        for _ in range(self._substeps):
            self._apply_due_perturbations()
            if self.container is not None:
                self.container.drive(self.data, self.time, PHYSICS_TIMESTEP)
            if self.incoming_belt is not None:
                self.incoming_belt.drive(self.data, self.time)
            mujoco.mj_step(self.model, self.data)
            self._tick += 1
            self._sample_mocap()
        collisions = self._collisions.update(self.data, self.time)
        self._update_ft()
        self._collision_log.extend(collisions)
        return StepReport(clamped=clamped, applied=applied, arm_collisions=tuple(collisions))

    def hold_torques(self, arm, stop_position=None):
        """
        Return the (7,) command [N m] that makes an arm hold, as the robot's safety stop would.

        sim_bridge.safety_hold: gravity compensation, hold_stiffness (config/cell.yaml) toward
        stop_position (7,) [rad] (None: no stiffness), minus hold_damping * joint velocity.
        """
        index = self.index.arms[self._arm(arm)]
        description = self.cell.arm(arm)
        return hold_command(self.gravity_torques(arm), self.data.qpos[index.qpos],
                            self.data.qvel[index.dof], description.hold_damping,
                            description.hold_stiffness, stop_position, self._torque_limits[arm],
                            self.torque_interface == 'gravity_compensated')

    def gravity_torques(self, arm):
        """Return the (7,) joint torques [N m] that balance gravity (MuJoCo's own model)."""
        index = self.index.arms[self._arm(arm)]
        scratch = self._scratch
        scratch.qpos[:] = self.data.qpos
        scratch.qvel[:] = 0.0
        mujoco.mj_kinematics(self.model, scratch)
        mujoco.mj_comPos(self.model, scratch)
        bias = np.zeros(self.model.nv)
        mujoco.mj_rne(self.model, scratch, 0, bias)
        return bias[index.dof]

    def joint_state(self, arm):
        """Return the JointSample of an arm (measured torque = applied motor torque)."""
        index = self.index.arms[self._arm(arm)]
        return JointSample(position=self.data.qpos[index.qpos].copy(),
                           velocity=self.data.qvel[index.dof].copy(),
                           measured_torque=self.data.qfrc_actuator[index.dof].copy())

    def ft_wrench(self, arm):
        """
        Return (force (3,) [N], torque (3,) [N m]) measured by an arm's FT sensor.

        The wrench the grabber side (grabber weight and inertia, pad contacts) exerts on the
        flange, in the ft_sensor frame, about its origin; with the scenario's noise and bias,
        drawn once per FRI period.
        """
        force, torque = self._ft_cache[self._arm(arm)]
        return force.copy(), torque.copy()

    def ft_wrench_true(self, arm):
        """Return the noise- and bias-free FT wrench (force, torque), as ft_wrench()."""
        index = self.index.arms[self._arm(arm)]
        return (-self.data.sensordata[index.force_sensor].copy(),
                -self.data.sensordata[index.torque_sensor].copy())

    def object_pose(self):
        """Return (p_world (3,) [m], quat_xyzw (4,)) of the object centre."""
        adr = self.index.object_qpos
        return (self.data.qpos[adr:adr + 3].copy(),
                quat_wxyz_to_xyzw(self.data.qpos[adr + 3:adr + 7]))

    def object_twist(self):
        """Return (v_world (3,) [m/s], w_world (3,) [rad/s]) of the object centre."""
        adr = self.index.object_dof
        R_world_object = self.data.xmat[self.index.object_body].reshape(3, 3)
        return (self.data.qvel[adr:adr + 3].copy(),
                R_world_object @ self.data.qvel[adr + 3:adr + 6])

    def tool_pose(self, arm):
        """Return (p_world_tool (3,) [m], R_world_tool (3, 3)), ground truth."""
        return site_pose(self.data, self.index.arms[self._arm(arm)].tool_site)

    def tool_twist(self, arm):
        """Return (v_world (3,) [m/s], w_world (3,) [rad/s]) of the tool point, ground truth."""
        velocity = np.zeros(6)
        mujoco.mj_objectVelocity(self.model, self.data, mujoco.mjtObj.mjOBJ_SITE,
                                 self.index.arms[self._arm(arm)].tool_site, velocity, 0)
        return velocity[3:].copy(), velocity[:3].copy()

    def pad_contact(self, arm):
        """Return (force_world (3,) [N], in_contact): total force the pad exerts on the object."""
        force, _, in_contact = self._pad_wrench(arm)
        return force, in_contact

    def pad_wrench(self, arm):
        """Return (force_world (3,) [N], torque_world (3,) [N m] about the tool point)."""
        force, torque, _ = self._pad_wrench(arm)
        return force, torque

    def move_object(self, displacement):
        """Translate the object by displacement (3,) [m] in the world, keeping its velocity."""
        displacement = finite_array('displacement', displacement, (3,))
        adr = self.index.object_qpos
        self.data.qpos[adr:adr + 3] += displacement
        mujoco.mj_forward(self.model, self.data)

    def mocap_samples(self):
        """Return the MocapSamples whose delivery time (stamp + latency) has come, oldest first."""
        return self._delivered(self._pending)

    def container_mocap_samples(self):
        """Return the container's ContainerSamples delivered by now, oldest first."""
        return self._delivered(self._container_pending)

    def _delivered(self, queue):
        delivered = []
        while queue and queue[0].stamp + self._latency <= self.time + TIME_EPSILON:
            delivered.append(queue.popleft())
        return delivered

    def state(self):
        """Return a TwinState snapshot (physics, clock, sensor queues and RNG states)."""
        spec = mujoco.mjtState.mjSTATE_INTEGRATION
        physics = np.zeros(mujoco.mj_stateSize(self.model, spec))
        mujoco.mj_getState(self.model, self.data, physics, spec)
        return TwinState(
            physics=physics, tick=self._tick, ctrl=self.data.ctrl.copy(),
            next_sample=self._next_sample, next_perturbation=self._next_perturbation,
            pending=tuple(self._pending), ft_cache=copy.deepcopy(self._ft_cache),
            rng_states=(copy.deepcopy(self._mocap_rng.bit_generator.state),
                        copy.deepcopy(self._ft_rng.bit_generator.state)),
            colliding_pairs=self._collisions.colliding_pairs,
            container=None if self.container is None else self.container.state(),
            container_pending=tuple(self._container_pending),
            incoming_belt=None if self.incoming_belt is None else self.incoming_belt.state())

    def set_state(self, state):
        """Restore a snapshot taken by state()."""
        mujoco.mj_setState(self.model, self.data, state.physics,
                           mujoco.mjtState.mjSTATE_INTEGRATION)
        self.data.ctrl[:] = state.ctrl
        mujoco.mj_forward(self.model, self.data)
        self._tick = state.tick
        self._next_sample = state.next_sample
        self._next_perturbation = state.next_perturbation
        self._pending = deque(state.pending)
        self._ft_cache = copy.deepcopy(state.ft_cache)
        self._mocap_rng.bit_generator.state = copy.deepcopy(state.rng_states[0])
        self._ft_rng.bit_generator.state = copy.deepcopy(state.rng_states[1])
        self._collisions.colliding_pairs = state.colliding_pairs
        self._container_pending = deque(state.container_pending)
        if self.container is not None:
            self.container.set_state(state.container)
        if self.incoming_belt is not None:
            self.incoming_belt.set_state(state.incoming_belt)

    def _arm(self, arm):
        if arm not in ARMS:
            raise InputError(f'unknown arm {arm!r}; expected one of {ARMS}')
        return arm

    def _apply_due_perturbations(self):
        perturbations = self.scenario.perturbations
        while self._next_perturbation < len(perturbations) and \
                perturbations[self._next_perturbation].time <= self.time + TIME_EPSILON:
            self.move_object(perturbations[self._next_perturbation].object_displacement)
            self._next_perturbation += 1

    def _sample_mocap(self):
        """Take the mocap samples due at the current tick (noise drawn even if dropped)."""
        mocap = self.scenario.sensors.mocap
        while self._next_sample * self._sample_period_ticks <= self._tick + TIME_EPSILON:
            self._next_sample += 1
            if self.container is not None:
                self._container_pending.append(self.container.sample(self.data, self.time))
            p_world, quat_xyzw = self.object_pose()
            position_noise = self._mocap_rng.normal(0.0, mocap.position_noise, 3)
            rotation_noise = self._mocap_rng.normal(0.0, mocap.orientation_noise, 3)
            dropped = self._mocap_rng.uniform() < mocap.dropout_probability
            if dropped or mocap.occluded(self.time):
                continue
            p_world = p_world + mocap.outlier_offset(self.time)
            R_world_object = rotation_exp(rotation_noise) @ self.data.xmat[
                self.index.object_body].reshape(3, 3)
            self._pending.append(MocapSample(stamp=self.time, p_world=p_world + position_noise,
                                             quat_xyzw=_same_hemisphere(
                                                 matrix_to_quat_xyzw(R_world_object),
                                                 quat_xyzw)))

    def _update_ft(self):
        ft = self.scenario.sensors.ft
        cache = {}
        for arm in ARMS:
            force, torque = self.ft_wrench_true(arm)
            cache[arm] = (force + ft.force_bias + self._ft_rng.normal(0.0, ft.force_noise, 3),
                          torque + ft.torque_bias + self._ft_rng.normal(0.0, ft.torque_noise,
                                                                        3))
        self._ft_cache = cache

    def _pad_wrench(self, arm):
        index = self.index.arms[self._arm(arm)]
        return pad_wrench(self.model, self.data, index.pad_geom, self.index.object_geom,
                          index.tool_site)


def _same_hemisphere(quat_xyzw, reference_xyzw):
    """Return quat_xyzw or its negative, whichever is closer to reference_xyzw."""
    return quat_xyzw if float(np.dot(quat_xyzw, reference_xyzw)) >= 0.0 else -quat_xyzw
