"""
The motion generator role: phases and the coordinated DS (core DualArmMotionGenerator).

cycle() is called with every FRI cycle's joint states and FT readings of both arms and the
newest object estimate. On DS ticks (TickSchedule, 200 Hz on the FRI grid) it steps the
generator and returns the tick's outputs; the same stamp again (a republished cycle) returns
the same outputs; other cycles return None. A cycle stamped before the last tick means the clock
went back (simulation reset): the role starts over as at start-up.

An episode starts on request, or by itself at auto_start_ns once an object estimate exists, and
only if both arms reach their grasp frames within their joint limits (core.reachability, checked at
the start on the estimate; shifted or rolled grasps tried when the centred one is not): else the
arms stay in standby, event 'unreachable' with the reason. A box to be set down that no grasp both
picks up and sets down on its place is staged on its pallet and picked up again (runtime.regrasp;
events 'regrasp', 'regrasp_second_pass' or 'regrasp_retract_stalled' and a reset, or
'regrasp_abandoned'). A landing target given while the episode runs (set_landing_target) re-plans
the release state (core.toss_planning) from the next tick until the release; one no release serves,
or that comes after it, is refused with its reason. With a conveyor (config.conveyor.enabled) every
tick up to the release aims the toss at the container's predicted position at the landing
(runtime.conveyor_aim): the start waits, event 'waiting_for_container', until the container will be
in range, then 'container_in_range'; after the start a tick that cannot aim keeps the previous aim.
A box on the incoming belt (config.moving_grab.enabled) is waited for likewise ('waiting_for_box',
'box_in_range') until it is predicted in the grab range a reach duration ahead, its grasp there
reachable. A tick whose inputs the generator refuses is answered with a stop command (zero velocity
at the current tool pose), so the controllers damp the arms to rest instead of waiting for an
answer.

Every torque command heard (command_heard) feeds a ControllerWatch; at the first tick out of
standby an arm's controller is found lost (silent longer than controller_timeout), the generator
halts the task where it is (core DualArmMotionGenerator.halt: a held box stays held, squeezed by
the living arm against the arm the robot holds) and the tick's phase carries the event
'controller_lost'.
"""

from dataclasses import dataclass

from dual_arm_control.core.arms import ARMS
from dual_arm_control.core.ballistics import UnreachableTargetError
from dual_arm_control.core.exceptions import InputError
from dual_arm_control.core.motion_generator import DualArmMotionGenerator
from dual_arm_control.core.motion_signals import arm_measurement, ArmCommand
from dual_arm_control.core.moving_grab import grab_wait_reason, predicted_box_position
from dual_arm_control.core.phases import Phase, Task
from dual_arm_control.core.place import pallet_floor, place_rotation
from dual_arm_control.core.reachability import GraspPlan, plan_grasp
from dual_arm_control.runtime.configuration import config_for_landing_target
from dual_arm_control.runtime.controller_watch import ControllerWatch
from dual_arm_control.runtime.conveyor_aim import container_aim
from dual_arm_control.runtime.inputs import RefusalCounter
from dual_arm_control.runtime.regrasp import staged_regrasp
from dual_arm_control.runtime.signals import arm_command_from, PhaseSample, TwistSample
from dual_arm_control.runtime.timing import (estimate_at, NANOSECONDS_PER_SECOND,
                                             object_measurement_at, TickSchedule)
import numpy as np

COMMANDS = ('start', 'go_home', 'reset')


@dataclass(frozen=True)
class MotionTick:
    """
    What one DS tick publishes, stamped with the tick.

    commands {arm: ArmCommandSample}; desired_twist (TwistSample): the object DS; phase
    (PhaseSample); output: the core MotionOutput (None for a stop answer), for markers.
    """

    stamp_ns: int
    commands: dict
    desired_twist: TwistSample
    phase: PhaseSample
    output: object


class MotionGeneratorStep:
    """
    The motion generator role.

    config: MotionGeneratorConfig; models: {arm: ArmModel} (tool and sensor poses from joint
    positions); ds_period [s]; auto_start_ns: sim time of the automatic start (0 = only on
    request); controller_timeout [s]: silence after which an arm's controller is lost (0 = no
    watch). command_latency [s]: how late the next tick's command acts on the arms (0 in
    lockstep; realtime: runtime.command_latency), which the toss release leads by.
    """

    def __init__(self, config, models, ds_period, auto_start_ns=0, on_refusal=None,
                 controller_timeout=0.0):
        self._initial_config = config
        self.controllers = ControllerWatch(round(controller_timeout * 1e9))
        self._models = models
        self._elbow_reaches = {arm: models[arm].elbow_reach() for arm in ARMS}
        self._ds_period = ds_period
        self._auto_start_ns = int(auto_start_ns)
        self.refusals = RefusalCounter(on_refusal)
        self.time_resets, self.command_latency = 0, 0.0
        self._pending_config = self._landing_target = None
        self._start_over(config)

    def _start_over(self, config):
        self._generator = DualArmMotionGenerator(config)
        self._generator.set_elbow_reaches(self._elbow_reaches)
        self._schedule = TickSchedule(self._ds_period)
        self._started = self._auto_start_ns == 0
        self._requests = dict.fromkeys(COMMANDS, False)
        self._last_tick = None
        self.grasp_plan = None
        self.controllers.restart()
        self.container_aim = None
        self.waiting_reason = ''
        self.regrasp = None
        self._regrasp_reason = ''
        self._start_after_reset = False

    @property
    def config(self):
        """Return the MotionGeneratorConfig in use (a pending change not included)."""
        return self._generator.config

    @property
    def pending_config(self):
        """Return the configuration the next tick applies (the current one if none pends)."""
        return self._pending_config or self._generator.config

    @property
    def phase(self):
        """Return the current core Phase."""
        return self._generator.phase

    @property
    def last_tick(self):
        """Return the MotionTick of the last tick, or None."""
        return self._last_tick

    def reconfigure(self, config):
        """
        Apply config at the next tick (the phase and filters are kept, and a landing target).

        During a regrasp's first pass config is the task's, its place kept at the staging pose.
        """
        if self.regrasp is not None:
            config = self.regrasp.reconfigured(config)
        if self._landing_target is not None:
            try:
                config = config_for_landing_target(config, self._landing_target)
            except UnreachableTargetError as error:
                self._landing_target = None
                self.refusals.refuse('landing_target', f'landing target dropped: {error}')
        self._pending_config = config

    def set_landing_target(self, target):
        """
        Toss to landing target (3,) [m] (object centre at rest) from the next tick on.

        Return '' when the new release state is planned, else the reason it is refused (also
        counted as refusal 'landing_target').
        """
        if self._generator.phase in (Phase.RELEASE, Phase.RETRACT):
            reason = f'landing target {np.round(target, 3).tolist()} m came after the release'
        else:
            try:
                self._pending_config = config_for_landing_target(self.pending_config, target)
                self._landing_target = np.array(target, dtype=float)
                return ''
            except (UnreachableTargetError, InputError) as error:
                reason = str(error)
        self.refusals.refuse('landing_target', reason)
        return reason

    def request(self, command):
        """Ask for 'start', 'go_home' or 'reset' at the next tick."""
        if command not in COMMANDS:
            raise ValueError(f'unknown command {command!r}; expected one of {COMMANDS}')
        self._requests[command] = True

    def command_heard(self, arm, stamp_ns):
        """Note a torque command of arm's controller stamped stamp_ns [ns] (it is alive)."""
        self.controllers.heard(arm, stamp_ns)

    def is_new_tick(self, stamp_ns):
        """Return True if the cycle stamp_ns is a DS tick not computed yet."""
        return self._schedule.due(stamp_ns) and stamp_ns != self._schedule.last_tick_ns

    def cycle(self, stamp_ns, joints, ft_wrenches, estimate, container=None):
        """
        Advance on one FRI cycle; return its MotionTick on DS ticks, else None.

        joints {arm: JointStateSample}; ft_wrenches {arm: WrenchSample} (raw sensor readings);
        estimate: the newest ObjectState (predicted to the cycle with its own twist), or None;
        container: the tracker's ObjectState of the conveyor's container, or None.
        """
        if self._schedule.went_back(stamp_ns):
            self._start_over(self.regrasp.task_config if self.regrasp is not None
                             else self._pending_config or self._generator.config)
            self._pending_config = None
            self.time_resets += 1
        if stamp_ns == self._schedule.last_tick_ns and self._last_tick is not None:
            return self._last_tick
        if not self._schedule.due(stamp_ns):
            return None
        dt = self._schedule.take(stamp_ns)
        if self._pending_config is not None:
            self._generator.reconfigure(self._pending_config)
            self._pending_config = None
        arms = {arm: arm_measurement(
            self._models[arm], joints[arm].position, ft_wrenches[arm].wrench,
            (stamp_ns - joints[arm].stamp_ns) / NANOSECONDS_PER_SECOND) for arm in ARMS}
        has_object = estimate is not None and estimate.valid
        aim_reason = self._aim_at_container(stamp_ns, arms, estimate, container)
        requested = self._requests['start']
        start = requested or (not self._started and has_object
                              and stamp_ns >= self._auto_start_ns)
        wait_events = ('waiting_for_container', 'container_in_range')
        moving_grab = self._generator.config.moving_grab.enabled
        if start and has_object and moving_grab and not aim_reason:
            wait_events = ('waiting_for_box', 'box_in_range')
            aim_reason = self._plan_moving_grasp(joints, estimate, stamp_ns)
        container_events = ()
        if start and aim_reason:
            container_events = () if self.waiting_reason else wait_events[:1]
            self.waiting_reason, start = aim_reason, False
        elif start and self.waiting_reason:
            container_events, self.waiting_reason = wait_events[1:], ''
        self._started = self._started or start
        lost_reason = self._halt_if_lost(stamp_ns)
        refused_start = ''
        if start and has_object and not moving_grab:
            refused_start = self._plan_grasp(joints, estimate, stamp_ns)
            start = not refused_start
        try:
            output = self._generator.step(arms, object_measurement_at(estimate, stamp_ns, arms),
                                          dt, start_episode=start,
                                          go_home=self._requests['go_home'],
                                          reset=self._requests['reset'],
                                          command_latency=self.command_latency)
        except InputError as error:
            self.refusals.refuse('tick', f'tick at {stamp_ns} ns: {error}')
            self._last_tick = _stop_tick(stamp_ns, arms, self._generator)
            return self._last_tick
        regrasp_step = self._advance_regrasp(output.phase.time_in_phase)
        start_after_reset, self._start_after_reset = self._start_after_reset, False
        self._requests = dict.fromkeys(COMMANDS, False)
        self._requests['start'] = ((requested and bool(self.waiting_reason)) or start_after_reset
                                   or regrasp_step == 'second_pass')
        if regrasp_step == 'retract_stalled':
            self._requests['reset'] = self._start_after_reset = True
        phase = output.phase
        reason = '' if phase.transition is None else phase.transition.reason
        events = phase.events
        if container_events:
            events, reason = tuple(events) + container_events, self.waiting_reason or reason
        if refused_start:
            events, reason = tuple(events) + ('unreachable',), refused_start
        if self._regrasp_reason:
            events, reason = tuple(events) + ('regrasp',), self._regrasp_reason
            self._regrasp_reason = ''
        if regrasp_step:
            events = tuple(events) + (f'regrasp_{regrasp_step}',)
        if lost_reason:
            events, reason = tuple(events) + ('controller_lost',), lost_reason
        self._last_tick = MotionTick(
            stamp_ns=stamp_ns,
            commands={arm: arm_command_from(stamp_ns, output.commands[arm]) for arm in ARMS},
            desired_twist=TwistSample(stamp_ns, np.asarray(output.object_velocity, float),
                                      np.asarray(output.object_angular_velocity, float)),
            phase=PhaseSample(stamp_ns, phase.phase, phase.task, phase.time_in_phase,
                              events, reason),
            output=output)
        return self._last_tick

    def _advance_regrasp(self, time_in_phase):
        """Move a regrasp on after a tick (runtime.regrasp); return its step, or ''."""
        if self.regrasp is None:
            return ''
        step = self.regrasp.advance(self._generator.phase, time_in_phase,
                                    self._requests['go_home'] or self._requests['reset'])
        if step:
            self._pending_config = self.regrasp.task_config
        if step == 'abandoned':
            self.regrasp = None
        return step

    def _halt_if_lost(self, stamp_ns):
        """
        Halt the task when an arm's controller is newly lost; return why, or ''.

        Judged only once the episode has left standby: at start-up the controllers of a
        realtime graph may miss a few cycles (measured: 18 ms of silence at 0.07 s) and answer
        again long before the reach; a controller still silent then halts the task at once.
        """
        lost = self.controllers.newly_lost(stamp_ns,
                                           judge=self._generator.phase is not Phase.STANDBY)
        if not lost:
            return ''
        self._generator.halt()
        silences = ', '.join(
            f'{arm} ({self.controllers.silence_ns(arm, stamp_ns) * 1e-9:.3f} s)' for arm in lost)
        return f'controller lost, no torque command: {silences}; the task stops where it is'

    def _aim_at_container(self, stamp_ns, arms, estimate, container):
        """Aim the toss at the container (conveyor only); return why it cannot, else ''."""
        config = self._generator.config
        phase = self._generator.phase
        if not config.conveyor.enabled or phase in (Phase.RELEASE, Phase.RETRACT) or (
                self._started and phase is Phase.STANDBY and not self.waiting_reason):
            return ''
        time_in_phase = 0.0 if self._last_tick is None else self._last_tick.phase.time_in_phase
        release_point = (None if phase in (Phase.STANDBY, Phase.REACH)
                         else config.toss.release_position)
        self.container_aim = container_aim(
            stamp_ns, config, phase, time_in_phase,
            {arm: arms[arm].p_world_tool for arm in ARMS}, estimate, container,
            self._generator.grasp[0], release_point)
        if self.container_aim.config is not None:
            self._generator.reconfigure(self.container_aim.config)
        return self.container_aim.reason

    def _plan_moving_grasp(self, joints, estimate, stamp_ns):
        """
        Plan the grasp of a box on the belt where it will be at the contact; return why not.

        The box is predicted a reach duration ahead at the generator's filtered belt velocity
        (core.moving_grab); outside the grab range, or out of the arms' reach there, the reach
        waits (the reason says which).
        """
        config = self._generator.config
        position, rotation, _, _ = estimate_at(estimate, stamp_ns)
        predicted = predicted_box_position(position, self._generator.belt_velocity,
                                           config.moving_grab.reach_duration)
        reason = grab_wait_reason(predicted, config.moving_grab)
        if reason or not config.reachability.enabled:
            return reason
        plan = self._adopt_grasp_plan(joints, predicted, rotation)
        if not plan.reachable:
            return f'grasp at the predicted contact out of reach: {plan.reason}'
        return ''

    def _plan_grasp(self, joints, estimate, stamp_ns):
        """Check the grasp before the reach; use its shift, or return why it is refused."""
        config = self._generator.config
        if not config.reachability.enabled:
            return ''
        position, rotation, _, _ = estimate_at(estimate, stamp_ns)
        plan = self._adopt_grasp_plan(joints, position, rotation)
        if not plan.reachable:
            reason = f'grasp out of reach: {plan.reason}'
            self.refusals.refuse('unreachable_grasp', reason)
            return reason
        return ''

    def _adopt_grasp_plan(self, joints, position, rotation):
        """
        Plan the grasp of the box at (position, rotation); a reachable one is the grasp.

        A box to be set down is grasped where the arms also reach the place; a place where it
        would come within place.pallet_clearance of the pallet (core.place.pallet_floor) is
        refused, as the box could not come down there. A box no grasp both picks up and sets
        down on its place is staged on its pallet first (core.regrasp, runtime.regrasp), if a
        staging pose serves; the second pass's plan ends the regrasp.
        """
        config = self._generator.config
        second_pass = self.regrasp is not None and self.regrasp.second_pass
        if second_pass:
            self.regrasp = None
        place = None
        if config.task is Task.PICK_AND_PLACE:
            place = (np.asarray(config.place.position, dtype=float), place_rotation(config.place))
            if pallet_floor(place[0], config.place, config.object_size) > -np.inf:
                self.grasp_plan = GraspPlan(np.zeros(3), False, (
                    f'place {np.round(place[0][:2], 3).tolist()} m too near the pallet: the box '
                    f'would come within {1000.0 * config.place.pallet_clearance:.0f} mm of it '
                    f'and could not be set down'), {})
                return self.grasp_plan
        q_current = {arm: joints[arm].position for arm in ARMS}
        self.grasp_plan = plan_grasp(
            self._models, q_current, position, rotation, np.asarray(config.object_size),
            config.reachability, config.impact.support_clearance, place)
        if ((not self.grasp_plan.reachable or self.grasp_plan.short) and not second_pass
                and config.regrasp.enabled and config.place.pallet and place is not None
                and not config.moving_grab.enabled):
            self.regrasp, self.grasp_plan, self._regrasp_reason = staged_regrasp(
                self._models, q_current, position, rotation, place, config, self.grasp_plan)
            if self.regrasp is not None:
                self._generator.reconfigure(self.regrasp.staging_config())
        if self.grasp_plan.reachable:
            self._generator.set_grasp(self.grasp_plan.offset, self.grasp_plan.roll)
        return self.grasp_plan


def _stop_tick(stamp_ns, arms, generator):
    """Return the MotionTick that stops both arms where they are (zero velocity)."""
    commands = {arm: arm_command_from(stamp_ns, ArmCommand(
        np.zeros(3), np.zeros(3), arms[arm].R_world_tool, arms[arm].p_world_tool))
        for arm in ARMS}
    phase = generator.phase
    return MotionTick(stamp_ns, commands, TwistSample(stamp_ns, np.zeros(3), np.zeros(3)),
                      PhaseSample(stamp_ns, phase, generator.config.task, 0.0, ('refused',),
                                  'inputs refused: stop'), None)
