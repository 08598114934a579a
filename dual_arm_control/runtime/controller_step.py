"""
The arm controller role: one arm's passive-DS torque per FRI cycle (core PassiveController).

cycle() answers one joint state with the torque for that cycle, computed from the newest valid
DS command and contact wrench. Stale-input policy: a DS command more than command_timeout away
from the cycle, or none yet, gives the hold torque g(q) - D_hold dq (counted); a contact wrench
that old is dropped (counted). The same cycle stamp again is answered with the same torque; an
earlier stamp (simulation reset) restarts the tick schedule and the controller's episode, as does
a stretch of free_gains_after without a contact wrench once touched (the real clock never goes
back). In lockstep, a node answers a DS tick cycle only once the command and wrench of that
tick arrived (needs_tick_inputs).

How far the planners are behind (zero in lockstep): the cycles answered with a DS command or a
contact wrench older than the newest DS tick due (`*_behind`), and the longest such lag, from
the command's tick to the newest tick (`*_lag_max_ms`). In realtime these lags cost the toss
release velocity (docs/performance.md); take_ds_command_lag() gives the DS command's mean lag,
which the controller node reports on /diagnostics (DS_COMMAND_LAG_KEY) and the motion generator
releases the box that much earlier for (runtime.command_latency).

With a gravity-compensated torque interface (KUKA FRI torque mode: the robot adds its own
gravity compensation) the command is the joint torque minus the model's g(q), so gravity is not
compensated twice; the torque limits still bound the whole joint torque.
"""

from dual_arm_control.core.passive_control import hold_torque, PassiveController
from dual_arm_control.runtime.inputs import RefusalCounter
from dual_arm_control.runtime.signals import TorqueSample
from dual_arm_control.runtime.timing import NANOSECONDS_PER_SECOND, seconds_to_ns, TickSchedule
import numpy as np

LAG_COUNTERS = ('ds_command_behind', 'contact_wrench_behind', 'ds_command_lag_max_ms',
                'contact_wrench_lag_max_ms')
DS_COMMAND_LAG_KEY = 'ds_command_lag_mean_ms'
"""The /diagnostics key of a controller's mean DS command lag [ms] since its last report."""
COUNTERS = ('cycles', 'ds_commands_received', 'contact_wrenches_received', 'repeated_answers',
            'holds_no_command', 'holds_stale_command', 'holds_by_controller', 'saturated',
            'no_contact_wrench', 'stale_contact_wrench', 'schedule_restarts') + LAG_COUNTERS


class ControllerStep:
    """
    The controller role of one arm.

    model: the arm's ArmModel; q_null (7,) [rad]: null-space posture; config:
    PassiveControllerConfig; ds_period [s]: the DS tick period; command_timeout [s];
    torque_interface: 'full' or 'gravity_compensated'.
    """

    def __init__(self, model, q_null, config, ds_period, command_timeout,
                 torque_interface='full', on_refusal=None):
        self._model = model
        self._gravity_compensated = torque_interface == 'gravity_compensated'
        self._q_null = q_null
        self._controller = PassiveController(model, q_null, config)
        self._torque_limits = np.asarray(model.torque_limits, dtype=float)
        self._pending_config = None
        self._schedule = TickSchedule(ds_period)
        self.command_timeout_ns = seconds_to_ns(command_timeout)
        self._command = None
        self._command_rotation = None
        self._wrench = None
        self._last_cycle_ns = None
        self._last_answer = None
        self._last_contact_ns = None
        self.refusals = RefusalCounter(on_refusal)
        self.counters = dict.fromkeys(COUNTERS, 0)
        self._ds_command_lag_ns = self._ds_command_lag_cycles = 0

    @property
    def controller(self):
        """Return the core PassiveController in use."""
        return self._controller

    def reconfigure(self, config):
        """Use config from the next cycle on."""
        self._pending_config = config

    def set_command_timeout(self, command_timeout):
        """Set the age [s] beyond which a DS command or contact wrench is stale."""
        self.command_timeout_ns = seconds_to_ns(command_timeout)

    def command(self, sample):
        """Keep an ArmCommandSample as the newest DS command."""
        self.counters['ds_commands_received'] += 1
        self._command = sample
        self._command_rotation = None

    def wrench(self, sample):
        """Keep a WrenchSample as the newest contact wrench."""
        self.counters['contact_wrenches_received'] += 1
        self._wrench = sample

    def needs_tick_inputs(self, stamp_ns):
        """Return True if cycle stamp_ns is a DS tick not answered yet (lockstep waits)."""
        if stamp_ns == self._last_cycle_ns:
            return False
        return self._schedule.due(stamp_ns)

    def cycle(self, joint_state):
        """Return the TorqueSample answering a JointStateSample."""
        stamp_ns = joint_state.stamp_ns
        if stamp_ns == self._last_cycle_ns and self._last_answer is not None:
            self.counters['repeated_answers'] += 1
            return self._last_answer
        if self._last_cycle_ns is not None and stamp_ns < self._last_cycle_ns:
            self._schedule.reset()
            self._controller.set_null_space_posture(self._q_null)
            self._controller.start_episode()
            self._last_contact_ns = None
            self.counters['schedule_restarts'] += 1
        self._last_cycle_ns = stamp_ns
        self.counters['cycles'] += 1
        if self._schedule.due(stamp_ns):
            self._schedule.take(stamp_ns)
        if self._pending_config is not None:
            self._controller.reconfigure(self._pending_config)
            self._pending_config = None
        torque = self._torque(stamp_ns, joint_state.position, joint_state.velocity)
        if self._gravity_compensated:
            torque = torque - self._model.gravity_torque(joint_state.position)
        self._last_answer = TorqueSample(stamp_ns, torque)
        return self._last_answer

    def _torque(self, stamp_ns, q, dq):
        command = self._command
        if command is None:
            self.counters['holds_no_command'] += 1
            return self.hold(q, dq)
        if abs(stamp_ns - command.stamp_ns) > self.command_timeout_ns:
            self.counters['holds_stale_command'] += 1
            return self.hold(q, dq)
        self._ds_command_lag_ns += self._count_lag('ds_command', command)
        self._ds_command_lag_cycles += 1
        self._count_lag('contact_wrench', self._wrench)
        contact_wrench = None
        if self._wrench is None:
            self.counters['no_contact_wrench'] += 1
        elif abs(stamp_ns - self._wrench.stamp_ns) > self.command_timeout_ns:
            self.counters['stale_contact_wrench'] += 1
        else:
            contact_wrench = self._wrench.wrench
        self._end_episode_without_contact(stamp_ns, contact_wrench)
        if self._command_rotation is None:
            self._command_rotation = command.R_world_desired
        self._controller.track_posture(command.p_world_attractor, self._command_rotation)
        result = self._controller.torque_command(q, dq, command.v_world, command.w_world,
                                                 self._command_rotation, contact_wrench)
        self.counters['holds_by_controller'] += int(result.held)
        self.counters['saturated'] += int(result.saturated)
        return result.torque

    def take_ds_command_lag(self):
        """
        Return the mean lag [s] of the DS commands used since the last call, or None if none.

        A cycle's lag runs from the tick of the command it used to the newest tick due: 0 in
        lockstep, where each tick's cycle waits for that tick's command.
        """
        cycles, self._ds_command_lag_cycles = self._ds_command_lag_cycles, 0
        lag_ns, self._ds_command_lag_ns = self._ds_command_lag_ns, 0
        return lag_ns / cycles / NANOSECONDS_PER_SECOND if cycles else None

    def _count_lag(self, name, sample):
        """
        Count an input (DS command or contact wrench; None: none yet) older than the tick.

        Return its lag [ns] behind the newest tick due (0 if on time or none).
        """
        if sample is None:
            return 0
        lag_ns = self._schedule.last_tick_ns - sample.stamp_ns
        if lag_ns > 0:
            self.counters[f'{name}_behind'] += 1
            self.counters[f'{name}_lag_max_ms'] = max(self.counters[f'{name}_lag_max_ms'],
                                                      lag_ns // 1_000_000)
        return max(lag_ns, 0)

    def _end_episode_without_contact(self, stamp_ns, contact_wrench):
        """Start a new controller episode once no contact wrench came for free_gains_after."""
        if contact_wrench is not None and contact_wrench.any():
            self._last_contact_ns = stamp_ns
        elif (self._last_contact_ns is not None and stamp_ns - self._last_contact_ns
              >= seconds_to_ns(self._controller.config.free_gains_after)):
            self._controller.start_episode()
            self._last_contact_ns = None

    def hold(self, q, dq):
        """Return the safety hold g(q) - D_hold dq within the torque limits [N m]."""
        torque = hold_torque(self._model.gravity_torque(q), dq,
                             self._controller.config.hold_damping)
        return np.clip(torque, -self._torque_limits, self._torque_limits)
