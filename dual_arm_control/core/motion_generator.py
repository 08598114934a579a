"""
The dual-arm motion generator: one tick of phases, contact, reach-with-impact and object DS.

The paper's pieces as the per-arm commands of one DS tick (sections II-III, appendix A): FT
compensation, contact, phases, the coordinated modulated DS with impact (eqs. 1-6), the task's
object DS (eqs. 7-9, lift, place), the orientation DS, release and retract. Time enters as dt.

halt() stops the task until a reset or go-home request (an arm's controller is lost, the robot
holds that arm): the phase stays, a grasped box stays squeezed by the living arm against the held
one and its wrench QP share, otherwise the tools hold their poses.
"""

from dataclasses import replace
import functools

from dual_arm_control.core.approach import (first_touch_gaps, impact_directions,
                                            support_height_below, synchronised_arrival,
                                            TOSS_TASKS, yield_to_single_contact)
from dual_arm_control.core.arms import ARMS
from dual_arm_control.core.contact import ContactDetector, FtBiasEstimator
from dual_arm_control.core.elbow_reach import reachable_release_rotation
from dual_arm_control.core.grasp import face_rectangle, grasp_frame
from dual_arm_control.core.held_object import HeldObjectEstimate
from dual_arm_control.core.impact import impact_ds_velocity, impact_geometry
from dual_arm_control.core.manipulation import (cooperative_manipulation_velocity,
                                                desired_relative_velocity, level_rotation,
                                                lift_velocity, object_angular_velocity,
                                                object_orientation_ds, release_rotation,
                                                release_velocity, toss_geometry, toss_velocity)
from dual_arm_control.core.motion_signals import ArmCommand, DeferredMapping, MotionOutput
from dual_arm_control.core.moving_grab import (belt_feed_forward, decayed_belt_velocity,
                                               filtered_belt_velocity)
from dual_arm_control.core.orientation import (
    intermediate_target_orientation, orientation_coupling, orientation_ds_angular_velocity)
from dual_arm_control.core.phases import (Phase, PhaseInputs, PhaseMachine, PhaseMachineOutput,
                                          Task)
from dual_arm_control.core.place import place_rotation, place_velocity
from dual_arm_control.core.release import commands_clear_of_the_box
from dual_arm_control.core.resting_object import RestingObjectFilter
from dual_arm_control.core.sample_time import sample_span
from dual_arm_control.core.speed_shaping import (
    arm_velocities_near_object, boosted_velocity, reach_speed, released_velocity,
    saturated_velocity, SpeedErrorIntegrator, SpeedFilter)
from dual_arm_control.core.validation import finite_array
import numpy as np


class DualArmMotionGenerator:
    """Stateful motion generator: call step() once per DS tick with dt in seconds."""

    def __init__(self, config):
        self._phase_machine = PhaseMachine(config.phases, config.task)
        self._ft = {arm: FtBiasEstimator(config.ft) for arm in ARMS}
        self._contact = {arm: ContactDetector(config.contact) for arm in ARMS}
        self._reach_speed = SpeedFilter(config.speed.time_constant)
        self._object_speed = SpeedFilter(config.toss_speed_time_constant)
        self._toss_feedback = SpeedErrorIntegrator(config.toss.speed_integral_gain,
                                                   config.toss.speed_correction_limit)
        self._held_object = HeldObjectEstimate()
        self._resting_object = RestingObjectFilter()
        self._release_object_velocity = self._toss_velocity = self._belt_velocity = np.zeros(3)
        self._grasp_offset, self._grasp_roll = np.zeros(3), 0.0
        self._elbow_reaches = self._reach_tools = None
        self._grasped_rotation = self._pick_height = self._halt = None
        self.reconfigure(config)

    @property
    def config(self):
        """Return the current configuration."""
        return self._config

    @property
    def belt_velocity(self):
        """Return the box's filtered belt velocity (3,) [m/s] (moving grab only, else 0)."""
        return self._belt_velocity.copy()

    @property
    def phase(self):
        """Return the current Phase."""
        return self._phase_machine.phase

    @property
    def grasp(self):
        """Return the grasp: offset (3,) [m] from the face centres (object frame), roll [rad]."""
        return self._grasp_offset.copy(), self._grasp_roll

    def set_grasp(self, offset, roll=0.0):
        """Grasp the faces at offset (3,) [m] from their centres, pads rolled by roll [rad]."""
        self._grasp_offset = finite_array('grasp_offset', offset, (3,)).copy()
        self._grasp_roll = float(finite_array('grasp_roll', roll, ()))

    def set_elbow_reaches(self, elbow_reaches):
        """Keep run-ins (not a moving grab's) and releases in reach ({arm: ElbowReach})."""
        self._elbow_reaches = elbow_reaches

    def halt(self):
        """Stop the task where it is from the next tick on (module text)."""
        if self._halt is None:
            self._halt = {}

    def reconfigure(self, config):
        """Apply a new configuration at the next tick; the phase and filters are kept."""
        self._config = config
        self._toss_feedback.integral_gain = config.toss.speed_integral_gain
        self._toss_feedback.limit_ratio = config.toss.speed_correction_limit
        self._phase_machine.select_task(config.task)
        self._toss_geometry = toss_geometry(config.toss, config.coordination)
        self._release_velocity = release_velocity(config.toss)
        self._release_rotation = release_rotation(config.toss)
        self._place_rotation = place_rotation(config.place)
        self._object_orientation_ds = object_orientation_ds(
            config.toss, config.orientation.max_angular_speed,
            config.place if config.task is Task.PICK_AND_PLACE else None)
        self._standby_positions = np.asarray(config.standby_positions, dtype=float)
        self._standby_rotations = np.asarray(config.standby_rotations, dtype=float)

    def step(self, arms, obj, dt, start_episode=False, go_home=False, reset=False,
             command_latency=0.0):
        """
        Advance one tick of dt seconds and return the MotionOutput.

        arms: {arm: ArmMeasurement}; obj: ObjectMeasurement (the tracker's estimate);
        command_latency: s from the tick to its command reaching the arms (PhaseInputs).
        """
        config = self._config
        p_tools = np.array([finite_array('p_world_tool', arms[arm].p_world_tool, (3,))
                            for arm in ARMS])
        R_tools = [finite_array('R_world_tool', arms[arm].R_world_tool, (3, 3)) for arm in ARMS]
        p_object = finite_array('p_world_object', obj.p_world_object, (3,))
        v_object = finite_array('v_world_object', obj.v_world_object, (3,))
        R_object = finite_array('R_world_object', obj.R_world_object, (3, 3))
        sample_ages = finite_array('sample_age', [arms[arm].sample_age for arm in ARMS], (2,))
        held = (self._phase_machine.phase is Phase.MANIPULATE and self._halt is None
                and config.held_object_time_constant > 0.0)
        if held:
            p_object, v_object = self._held_object.update(
                p_tools.mean(axis=0), self._held_object.grip_rotation(*R_tools), p_object,
                v_object, dt, config.held_object_time_constant,
                planned_offset=-R_object @ self._grasp_offset,
                sample_age=sample_ages.mean())
        else:
            self._held_object.reset()
        resting = (self._phase_machine.phase in (Phase.STANDBY, Phase.REACH)
                   and self._halt is None and not config.moving_grab.enabled)
        p_object, R_object = self._resting_object.update(resting, p_object, R_object, dt,
                                                         config.resting_object)
        frames = {arm: grasp_frame(arm, p_object, R_object, config.object_size,
                                   self._grasp_offset, self._grasp_roll) for arm in ARMS}
        pad_forces, contacts = {}, {}
        for index, arm in enumerate(ARMS):
            compensated = self._ft[arm].update(arms[arm].ft_wrench_sensor,
                                               arms[arm].R_world_sensor, dt)
            pad_forces[arm] = compensated.wrench_world[:3]
            contacts[arm] = self._contact[arm].update(
                pad_forces[arm], p_tools[index], R_tools[index], frames[arm].p_world_grasp,
                frames[arm].normal, dt)
        if reset or go_home:
            self._halt = None
        if self._halt is not None:
            return self._halted_step(p_tools, R_tools, frames, contacts, pad_forces)
        phase_output = self._phase_machine.update(PhaseInputs(
            p_world_tool_left=p_tools[0], p_world_tool_right=p_tools[1],
            p_world_object=p_object, v_world_object=v_object,
            contact_left=contacts['left'], contact_right=contacts['right'],
            p_world_release=self._toss_geometry.release_position,
            v_world_release=self._release_velocity,
            p_world_place=np.asarray(config.place.position, dtype=float),
            p_world_lift=np.asarray(config.lift.position, dtype=float),
            p_world_standby_left=self._standby_positions[0],
            p_world_standby_right=self._standby_positions[1],
            start_episode=start_episode, go_home=go_home, reset=reset,
            command_latency=command_latency), dt)
        phase = phase_output.phase
        if phase_output.transition is not None and phase is Phase.REACH:
            self._reach_speed.reset(0.0)
            self._reach_tools = None
        if config.moving_grab.enabled and phase in (Phase.STANDBY, Phase.REACH):
            self._belt_velocity = filtered_belt_velocity(
                self._belt_velocity, v_object, dt, config.moving_grab.velocity_time_constant)
        object_velocity = self._object_velocity(p_object, v_object, phase, dt)
        omega_object = self._object_angular_velocity(R_object, phase)
        elbow_reaches = None if config.moving_grab.enabled else self._elbow_reaches
        directions = DeferredMapping(functools.partial(
            impact_directions, config, frames, object_velocity,
            support_height_below(config, p_object), self._grasp_roll, elbow_reaches))
        if phase is Phase.REACH:
            faces = [face_rectangle(arm, p_object, R_object, config.object_size) for arm in ARMS]
            commands = self._reach(p_tools, R_tools, frames, faces, directions, dt, sample_ages)
            commands = yield_to_single_contact(commands, contacts, frames)
            if config.moving_grab.enabled:
                commands = self._follow_belt(commands)
        elif phase in (Phase.CONTACT, Phase.MANIPULATE):
            commands = self._carry(p_tools, R_tools, frames, object_velocity, omega_object)
            self._release_object_velocity = (
                released_velocity(self._toss_velocity, object_velocity,
                                  config.toss.release_correction_share)
                if config.task in TOSS_TASKS else object_velocity)
        elif phase is Phase.RELEASE:
            commands = self._open_hands(R_tools, frames)
        else:
            commands = self._standby(p_tools, R_tools)
            if phase is Phase.RETRACT:
                commands = commands_clear_of_the_box(
                    commands, p_tools, p_object, v_object, config.release_clearance,
                    config.release_opening_speed, config.max_linear_speed)
        toss = config.task in TOSS_TASKS
        return MotionOutput(
            phase=phase_output, commands=commands, object_velocity=object_velocity,
            object_angular_velocity=omega_object, contacts=contacts, pad_forces=pad_forces,
            grasp_frames=frames, impact_directions=directions,
            release_position=self._toss_geometry.release_position if toss else None,
            release_velocity=self._release_velocity if toss else None)

    def _halted_step(self, p_tools, R_tools, frames, contacts, pad_forces):
        """
        Return the MotionOutput of a halted tick: the task stops where it is (module text).

        A held box (CONTACT, MANIPULATE) gets the carry's commands with a zero object twist (a
        point attractor back to where the halt found it pulled the pair along: worse) and each
        pad pressed into its face at halt_squeeze_speed; otherwise the tools hold their poses.
        """
        halt, phase, first = self._halt, self._phase_machine.phase, not self._halt
        zero = np.zeros(3)
        if first:
            halt.update(tools=p_tools.copy(), rotations=tuple(R.copy() for R in R_tools))
        if phase in (Phase.CONTACT, Phase.MANIPULATE):
            commands = self._carry(p_tools, R_tools, frames, zero, zero)
            commands = {arm: replace(commands[arm], v_world=commands[arm].v_world
                                     + self._config.halt_squeeze_speed * frames[arm].normal)
                        for arm in ARMS}
        else:
            commands = self._standby(p_tools, R_tools, halt['tools'], halt['rotations'])
        return MotionOutput(
            phase=PhaseMachineOutput(phase, self._phase_machine.task,
                                     self._phase_machine.time_in_phase,
                                     ('halted',) if first else ()),
            commands=commands, object_velocity=zero, object_angular_velocity=zero,
            contacts=contacts, pad_forces=pad_forces, grasp_frames=frames,
            impact_directions={arm: frames[arm].normal for arm in ARMS},
            release_position=None, release_velocity=None)

    def _object_velocity(self, p_object, v_object, phase, dt):
        """
        Return the desired object velocity (3,) m/s of the task's object DS (eqs. 7-9).

        After contact the object's speed rises from the impact speed to the task speed with
        toss_speed_time_constant: the toss field is boosted to that speed (and corrected by the
        outer loop on the carried object's velocity error), the place and lift fields (which
        slow down near their targets) are capped by it. Zero outside the reach (whose impact
        directions follow it) and the carry: no object motion is asked for then.
        """
        config = self._config
        task_speed = (config.toss.toss_speed if config.task in TOSS_TASKS
                      else config.place.max_speed if config.task is Task.PICK_AND_PLACE
                      else config.lift.max_speed)
        carried = phase in (Phase.CONTACT, Phase.MANIPULATE)
        belt = np.zeros(3)
        if carried and config.moving_grab.enabled:
            belt = self._belt_velocity = decayed_belt_velocity(
                self._belt_velocity, dt, config.moving_grab.carry_time_constant)
        if carried:
            speed = self._object_speed.update(task_speed, dt)
        else:
            self._object_speed.reset(config.impact.impact_speed)
            self._toss_feedback.reset()
            speed = self._object_speed.speed
            self._pick_height = float(p_object[2])
            if phase is not Phase.REACH:
                return np.zeros(3)
        if config.task in TOSS_TASKS:
            velocity = boosted_velocity(toss_velocity(p_object, self._toss_geometry).velocity,
                                        speed)
            if config.moving_grab.enabled:
                velocity = velocity + belt
            self._toss_velocity = velocity
            if phase is Phase.MANIPULATE:
                return self._toss_feedback.update(velocity, v_object, dt)
            return velocity
        if config.task is Task.PICK_AND_PLACE:
            velocity = place_velocity(p_object, config.place, config.coordination,
                                      self._pick_height, config.object_size)
        else:
            velocity = lift_velocity(p_object, config.lift, config.coordination)
        return saturated_velocity(velocity, speed)

    def _object_angular_velocity(self, R_object, phase):
        """Return omega^o (3,) [rad/s]: the object's orientation while tossed or placed (eq. 8)."""
        config = self._config
        mode = config.toss.orientation
        if phase is not Phase.MANIPULATE:
            self._grasped_rotation = None
        if phase is Phase.MANIPULATE and config.task is Task.PICK_AND_PLACE:
            return object_angular_velocity(R_object, self._place_rotation,
                                           self._object_orientation_ds)
        if phase is not Phase.MANIPULATE or config.task not in TOSS_TASKS or mode == 'free':
            return np.zeros(3)
        if mode == 'given':
            target = self._release_rotation
        elif mode == 'hold':
            if self._grasped_rotation is None:
                self._grasped_rotation = R_object if self._elbow_reaches is None else \
                    reachable_release_rotation(
                        self._elbow_reaches, self._toss_geometry.release_position,
                        self._release_velocity, R_object, config.object_size,
                        self._grasp_offset, self._grasp_roll, config.toss.release_overreach)
            target = self._grasped_rotation
        else:
            target = level_rotation(R_object)
        return object_angular_velocity(R_object, target, self._object_orientation_ds)

    def _reach(self, p_tools, R_tools, frames, faces, directions, dt, sample_ages):
        """
        Return the coordinated reach-with-impact commands (eqs. 1-6, Proposition 2).

        The tools' measured velocities are differenced between their joint samples, sampled
        sample_ages (2,) [s] before the tick (core.sample_time).
        """
        config = self._config
        grasp_points = np.array([frames[arm].p_world_grasp for arm in ARMS])
        geometry = impact_geometry(grasp_points, np.array([directions[arm] for arm in ARMS]),
                                   config.coordination, config.impact)
        x = p_tools.reshape(6)
        field_output = impact_ds_velocity(x, geometry)
        distance = float(np.max(np.linalg.norm(p_tools - grasp_points, axis=1)))
        target_speed = reach_speed(distance, config.impact.impact_speed, config.speed)
        speed = self._reach_speed.update(target_speed, dt)
        velocity = arm_velocities_near_object(field_output.velocity, speed, distance,
                                              config.speed)
        if config.impact.synchronisation_distance > 0.0:
            normals = np.array([face.normal for face in faces])
            pad, schedule = config.arrival_synchroniser()
            gaps = first_touch_gaps(faces, p_tools, R_tools, *pad)
            spans = None if self._reach_tools is None or dt <= 0.0 else sample_span(
                dt, self._reach_tools[1], sample_ages)
            measured = None if spans is None else (p_tools - self._reach_tools[0]) / spans[:, None]
            velocity = synchronised_arrival(velocity, gaps, normals, schedule, measured)
        self._reach_tools = p_tools, sample_ages
        velocity = saturated_velocity(velocity, config.max_linear_speed)
        eta = orientation_coupling(p_tools.mean(axis=0), grasp_points.mean(axis=0),
                                   config.orientation)
        commands = {}
        for index, arm in enumerate(ARMS):
            R_target = intermediate_target_orientation(self._standby_rotations[index],
                                                       frames[arm].R_world_grasp, eta)
            commands[arm] = ArmCommand(
                velocity[index],
                orientation_ds_angular_velocity(R_tools[index], R_target, config.orientation),
                R_target, grasp_points[index])
        return commands

    def _follow_belt(self, commands):
        """Return the reach commands moving with the box on the belt (feed-forward)."""
        velocity = belt_feed_forward([commands[arm].v_world for arm in ARMS],
                                     self._belt_velocity, self._config.moving_grab.tracking_gain)
        velocity = saturated_velocity(velocity, self._config.max_linear_speed)
        return {arm: replace(commands[arm], v_world=velocity[index])
                for index, arm in enumerate(ARMS)}

    def _carry(self, p_tools, R_tools, frames, object_velocity, omega_object):
        """Return the commands that carry the object with the desired object twist (eq. 8)."""
        config = self._config
        grasp_points = np.array([frames[arm].p_world_grasp for arm in ARMS])
        velocity = cooperative_manipulation_velocity(
            p_tools.reshape(6), object_velocity,
            desired_relative_velocity(grasp_points, omega_object), grasp_points,
            config.coordination).reshape(2, 3)
        velocity = saturated_velocity(velocity, config.max_carry_speed)
        return self._grasp_pose_commands(velocity, R_tools, frames, omega_object)

    def _open_hands(self, R_tools, frames):
        """Return the release commands: keep the release velocity, pull the pads off the faces."""
        config = self._config
        velocity = saturated_velocity(
            self._release_object_velocity
            - config.release_opening_speed * np.array([frames[arm].normal for arm in ARMS]),
            config.max_carry_speed)
        return self._grasp_pose_commands(velocity, R_tools, frames, np.zeros(3))

    def _grasp_pose_commands(self, velocity, R_tools, frames, omega_object):
        """Return the commands that move the tools at velocity (2, 3) turning to the grasp."""
        return {arm: ArmCommand(velocity[index], omega_object + orientation_ds_angular_velocity(
                    R_tools[index], frames[arm].R_world_grasp, self._config.orientation),
                    frames[arm].R_world_grasp, frames[arm].p_world_grasp)
                for index, arm in enumerate(ARMS)}

    def _standby(self, p_tools, R_tools, targets=None, rotations=None):
        """Return point-attractor commands toward each arm's standby pose (or the given ones)."""
        config = self._config
        targets = self._standby_positions if targets is None else targets
        rotations = self._standby_rotations if rotations is None else rotations
        commands = {}
        for index, arm in enumerate(ARMS):
            target, R_target = targets[index], rotations[index]
            velocity = saturated_velocity(-config.standby_gain * (p_tools[index] - target),
                                          config.max_linear_speed)
            commands[arm] = ArmCommand(
                velocity,
                orientation_ds_angular_velocity(R_tools[index], R_target, config.orientation),
                R_target, target)
        return commands
