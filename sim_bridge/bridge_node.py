"""
sim_bridge: the FRI stand-in, a ROS 2 shell around the MuJoCo twin of the two-arm cell.

Each FRI cycle the bridge publishes what the robots report (runtime FriCycle.begin: joint
states, FT wrenches, the mocap samples delivered at that cycle), /clock and the simulator's
ground truth, and applies one torque command per arm (FriCycle: refusals, late commands, the
hold policy). With a command key in its environment (nodes.command_signature: the launcher's)
it takes only torque commands its controllers signed; others are dropped and counted. Two modes:

- lockstep (default): the state of cycle k (stamp t_k) is published and the twin advances only
  when every arm answered with a command stamped t_k (a refused command counts as the answer:
  that arm holds). Until then the state is republished every `lockstep_republish_period` wall
  seconds (discovery, lost messages). With lockstep_wait_for_tracker the cycle's mocap samples go
  out first (a conveyor's container's too) and the rest only after the tracker answered each
  (on /object/state, /container/state). Deterministic. With
  lockstep_answer_timeout a cycle goes on without an arm that has not answered within that wall
  time (FriCycle's policy for a missed deadline), so a dead controller cannot stall the twin.
- realtime: a wall-clock timer paces the cycles like a real robot; at each deadline the twin
  advances with whatever arrived (FriCycle's hold policy for the rest); late cycles are counted.

In both modes the first state (and in realtime the clock) waits for the awaited graph
(`wait_for_nodes`, `wait_for_subscribers`, `wait_for_recorder`; lockstep_start.GraphReadiness),
so every node sees the run from its first cycle. A scenario with a conveyor takes its belt
speed commands on /belt/outgoing/speed.

The trajectory log (`trajectory_log`) has one row per cycle: row 0 the initial state (zero
torque), row k + 1 the state after cycle k with the torque applied during it; the counters are
stored beside it. /sim/reset writes the log of the episode it ends, then restarts the twin with
the noise seed `seed` (-1: the scenario's) and the log (time goes back to 0). At the run's end
(`duration`) the bridge exits 0, or with `at_duration` 'wait' stops stepping until /sim/reset
(consecutive episodes of equal length in one graph: the soak). SIGINT and SIGTERM end the run
cleanly: the log is written and the process exits 0.
"""

import math
import sys
import time

from dual_arm_control import contract
from dual_arm_control.core.exceptions import DualArmControlError
from dual_arm_control.nodes.command_signature import command_key, signed
from dual_arm_control.nodes.messages import stamp_ns
from dual_arm_control.nodes.process import create_topic_publisher, run_node
from dual_arm_control.parameters import NodeParameters
from dual_arm_control.runtime.fri import FriCycle
from dual_arm_control.runtime.node_settings import node_table
from dual_arm_control.runtime.timing import CycleGaps, seconds_to_ns, TickSchedule
from dual_arm_control.scenario import load_scenario
from dual_arm_control.trajectory_log import TrajectoryRecorder
import numpy as np
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sim_bridge.belt_speeds import subscribe_belt_speeds
from sim_bridge.bridge_diagnostics import counter_values, diagnostics_message
from sim_bridge.episode_log import save_episode_log, write_log_on_exit
from sim_bridge.ground_truth import GroundTruthStreams
from sim_bridge.lockstep_start import GraphReadiness
from sim_bridge.robot_streams import RobotStreams
from sim_bridge.twin import DualArmTwin
from std_srvs.srv import Trigger

LOG_THROTTLE_PERIOD = 1.0
# Lockstep: wall time without answers before the wait is reported as a warning [s].
WAITING_WARNING_DELAY = 2.0
# Wall time to let the graph's publishers match once it is complete, before the first state [s].
SUBSCRIBER_SETTLE_TIME = 1.0
# Wall time between two checks of the awaited graph before the start [s].
STARTUP_CHECK_PERIOD = 0.05


class SimBridge(Node):
    """The bridge node: twin + FriCycle + publishers + command subscriptions + services."""

    def __init__(self, node_name='sim_bridge', **node_options):
        super().__init__(node_name, **node_options)
        self.settings = settings = NodeParameters(self, node_table('sim_bridge').settings,
                                                  on_change=self._on_setting)
        self.mode = settings['mode']
        self.fri_period = settings['fri_period']
        self.scenario = load_scenario(settings['scenario'])
        self.twin = DualArmTwin(self.scenario, fri_period=self.fri_period,
                                torque_interface=settings['torque_interface'])
        if settings['seed'] >= 0:
            self.twin.reset(settings['seed'])
        self.fri = FriCycle(self.twin)
        self._command_key = command_key()
        lockstep = self.mode == 'lockstep'
        self._publish_ground_truth = settings['publish_ground_truth']
        self._duration = settings['duration']
        self._trajectory_log = settings['trajectory_log']
        self._republish_period = settings['lockstep_republish_period']
        self._answer_timeout = settings['lockstep_answer_timeout']
        self._ft_schedule = TickSchedule(settings['ft_period']) if settings['ft_period'] else None
        self._ft_due = True
        self._wait_for_tracker = lockstep and settings['lockstep_wait_for_tracker']
        self._diagnostics_period_ns = seconds_to_ns(settings['diagnostics_period'])
        self._ground_truth_period_ns = seconds_to_ns(settings['ground_truth_period'])
        self.finished = False
        self.paused = False
        self.cycle_gaps = CycleGaps(self.fri_period)
        self._cycle = None
        self._awaited_answers = set()
        self._next_diagnostics_ns = 0
        self._next_ground_truth_ns = 0
        self._last_publish_wall = -math.inf
        self._state_published_wall = -math.inf
        self._first_cycle_wall = None
        self._last_warning_wall = {}
        self._recorder = None
        self._create_interfaces()
        self._readiness = GraphReadiness(
            self, self._streams, settings['wait_for_nodes'], settings['wait_for_subscribers'],
            settings['wait_for_recorder'])
        self._started = False
        self._ready_wall = None
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._timer = None
        if self._readiness.waits:
            self._startup_timer = self.create_timer(STARTUP_CHECK_PERIOD, self._on_startup_timer,
                                                    clock=self._steady)
        else:
            self._start_running()
        self.get_logger().info(
            f'sim_bridge up: mode {self.mode}, FRI period {self.fri_period * 1e3:g} ms, torque '
            f'interface {self.twin.torque_interface}, scenario '
            f'{settings["scenario"]}, seed {self.twin.seed}, stops at sim time '
            f'{self.stop_time:g} s, ground truth {"on" if self._publish_ground_truth else "off"}')

    def _create_interfaces(self):
        self._robot = RobotStreams(self, container=self.twin.container is not None)
        self._diagnostics_pub = create_topic_publisher(self, contract.DIAGNOSTICS)
        self._truth = GroundTruthStreams(self, container=self.twin.container is not None)
        for arm in contract.ARMS:
            self.create_subscription(contract.TORQUE_COMMAND.msg_type,
                                     contract.TORQUE_COMMAND.resolved(arm),
                                     lambda msg, arm=arm: self._on_torque_command(arm, msg),
                                     contract.TORQUE_COMMAND.subscription_qos(
                                         self.mode == 'lockstep'))
        self.create_service(Trigger, contract.SIM_RESET_SERVICE, self._on_reset)
        self.create_service(Trigger, contract.SIM_MOVE_OBJECT_SERVICE, self._on_move_object)
        if self._wait_for_tracker:
            for name, topic in (('object', contract.OBJECT_STATE),
                                ('container', contract.CONTAINER_STATE)):
                self.create_subscription(topic.msg_type, topic.name, lambda msg, name=name:
                                         self._on_tracker_answer(name, msg), topic.qos)
        subscribe_belt_speeds(self, self.twin, self._warn_throttled)

    def _streams(self):
        """Return every stream the bridge publishes each cycle."""
        return [*self._robot.streams(), *self._truth.streams()]

    def _on_setting(self, name, value):
        """Apply the runtime-changeable parameters."""
        if name == 'publish_ground_truth':
            self._publish_ground_truth = value
        elif name == 'duration':
            self._duration = value
        elif name == 'diagnostics_period':
            self._diagnostics_period_ns = seconds_to_ns(value)
        elif name == 'ground_truth_period':
            self._ground_truth_period_ns = seconds_to_ns(value)

    @property
    def stop_time(self):
        """Return the sim time at which the run ends [s]: `duration`, or the scenario's."""
        return self._duration if self._duration > 0.0 else self.scenario.duration

    # -- the FRI cycle ---------------------------------------------------------------------------

    def _on_torque_command(self, arm, msg):
        stamp = stamp_ns(msg.header.stamp)
        if self._command_key is not None and not signed(self._command_key, stamp, msg.name,
                                                        msg.effort, msg.header.frame_id):
            self.fri.refuse_foreign(arm)
            self._warn_throttled((arm, 'foreign'), (
                f'{arm} torque command not signed by its controller, dropped (so far: '
                f'{self.fri.counters[arm].foreign})'))
            return
        all_answered = self.fri.answer(arm, stamp, msg.name, msg.effort)
        reason = self.fri.refused(arm)
        if reason is not None:
            self._warn_throttled((arm, reason), (
                f'{arm} torque command refused ({reason}): names {list(msg.name)}, '
                f'{len(msg.effort)} efforts; the arm holds (refusals so far: '
                f'{self.fri.counters[arm].refused})'))
        if self.mode == 'lockstep' and self._started and all_answered and not self.paused:
            self._advance()

    def _on_fri_tick(self):
        """Realtime: one FRI deadline; arms without a command for the cycle hold."""
        if self.paused:
            return
        self.cycle_gaps.tick(time.monotonic())
        for arm in self.fri.missing():
            self._warn_throttled((arm, 'watchdog'), (
                f'{arm}: no torque command for the last FRI cycle (watchdog holds so far: '
                f'{self.fri.counters[arm].watchdog_holds})'))
        self._advance()

    def _on_tracker_answer(self, name, msg):
        if self._awaited_answers:
            self._awaited_answers.discard((name, stamp_ns(msg.header.stamp)))
            if not self._awaited_answers:
                self._publish_cycle_state()

    def _on_startup_timer(self):
        """Start once the awaited graph is ready and has settled for SUBSCRIBER_SETTLE_TIME."""
        now = time.monotonic()
        if not self._readiness.ready():
            self._ready_wall = None
        elif self._ready_wall is None:
            self._ready_wall = now
        elif now - self._ready_wall >= SUBSCRIBER_SETTLE_TIME:
            self.destroy_timer(self._startup_timer)
            self._start_running()

    def _start_running(self):
        """Publish the first state and start the mode's timer (republish, or the FRI clock)."""
        self._start_episode()
        if self.mode == 'lockstep':
            self._timer = self.create_timer(self._republish_period / 2.0,
                                            self._on_republish_timer, clock=self._steady)
        else:
            self._timer = self.create_timer(self.fri_period, self._on_fri_tick,
                                            clock=self._steady)

    def _on_republish_timer(self):
        """Lockstep: go on past the answer deadline, or publish the awaited state again."""
        if self.paused:
            return
        now = time.monotonic()
        if (self._answer_timeout > 0.0 and not self._awaited_answers
                and now - self._state_published_wall >= self._answer_timeout):
            self._warn_throttled(('lockstep', 'deadline'), (
                f'lockstep: no torque command from {self.fri.missing()} within '
                f'{self._answer_timeout:g} s: the cycle goes on, those arms hold'))
            self._advance()
            return
        if now - self._last_publish_wall < self._republish_period:
            return
        if self._awaited_answers:
            self._publish_mocap()
            self._warn_throttled(('lockstep', 'tracker'), (
                'lockstep: waiting for the object tracker to answer the mocap samples stamped '
                f'{sorted((name, s * 1e-9) for name, s in self._awaited_answers)} s'))
            return
        # Both arms again: the DS and the wrench QP re-answer a tick only with a complete set,
        # and a controller that missed their first answer needs it (extra commands are ignored).
        self._publish_joint_states()
        self._publish_ft()
        if now - self._state_published_wall >= WAITING_WARNING_DELAY:
            self._warn_throttled(('lockstep', 'waiting'), (
                f'lockstep: waiting for the torque commands stamped '
                f'{self._cycle.stamp_ns * 1e-9:g} s from {self.fri.missing()}'))

    def _advance(self):
        """Apply this cycle's torques, step the twin, record, publish the next state."""
        if self._first_cycle_wall is None:
            self._first_cycle_wall = time.monotonic()
            self.get_logger().info('first FRI cycle: stepping the twin')
        applied = self.fri.advance()
        if self._recorder is not None:
            self._recorder.append(self.twin, applied)
        self._publish_state()
        if self.twin.time >= self.stop_time - 0.5 * self.fri_period:
            self.paused = self.settings['at_duration'] == 'wait'
            self.finished = not self.paused
            self._publish_diagnostics()
            bridge = self.diagnostic_values()['sim_bridge']
            self.get_logger().info(
                f'reached sim time {self.twin.time:g} s after {self.fri.cycles} cycles (real-time '
                f'factor {bridge["real_time_factor"]:.2f}); '
                f'{"waiting for /sim/reset" if self.paused else "stopping"}')

    def _start_episode(self):
        """Start recording and publish the initial state (after construction and reset)."""
        self._started = True
        self.fri.restart()
        if self._trajectory_log:
            self._recorder = TrajectoryRecorder()
            self._recorder.append(self.twin, self.fri.applied)
        self._next_diagnostics_ns = 0
        self._next_ground_truth_ns = 0
        self._publish_state()

    # -- publishing ------------------------------------------------------------------------------

    def _publish_state(self):
        """Publish the cycle's mocap samples, then (tracker permitting) the rest of its state."""
        self._cycle = self.fri.begin()
        schedule = self._ft_schedule
        self._ft_due = schedule is None or schedule.due(self._cycle.stamp_ns)
        if schedule is not None and self._ft_due:
            schedule.take(self._cycle.stamp_ns)
        self._state_published_wall = time.monotonic()
        self._publish_mocap()
        self._awaited_answers = set() if not self._wait_for_tracker else {
            *(('object', sample.stamp_ns) for sample in self._cycle.mocap),
            *(('container', sample.stamp_ns) for sample in self._cycle.container_mocap)}
        if self._awaited_answers:
            return
        self._publish_cycle_state()

    def _publish_mocap(self):
        self._robot.publish_mocap(self._cycle)
        self._last_publish_wall = time.monotonic()

    def _publish_cycle_state(self):
        self._publish_joint_states()
        self._publish_ft()
        stamp = self._cycle.stamp_ns
        if self._publish_ground_truth and stamp >= self._next_ground_truth_ns:
            self._next_ground_truth_ns = stamp + self._ground_truth_period_ns
            self._truth.publish(self.twin, stamp)
        if stamp >= self._next_diagnostics_ns:
            self._next_diagnostics_ns += self._diagnostics_period_ns
            self._publish_diagnostics()

    def _publish_joint_states(self):
        """Publish /clock and the joint states of the awaited cycle (again)."""
        self._robot.publish_joint_states(self._cycle)
        self._last_publish_wall = time.monotonic()

    def _publish_ft(self):
        if self._ft_due:
            self._robot.publish_ft(self._cycle)

    def _warn_throttled(self, key, message):
        now = time.monotonic()
        if now - self._last_warning_wall.get(key, -math.inf) >= LOG_THROTTLE_PERIOD:
            self._last_warning_wall[key] = now
            self.get_logger().warning(message)

    def diagnostic_values(self):
        """Return {status name: {key: value}} of the counters (also saved in the log)."""
        return counter_values(self.mode, self.twin, self.fri, self.cycle_gaps,
                              self._first_cycle_wall)

    def _publish_diagnostics(self):
        """Publish the counters; an arm is WARN once anything was refused, clamped or held."""
        self._diagnostics_pub.publish(diagnostics_message(self.diagnostic_values(),
                                                          self._cycle.stamp_ns))

    # -- services --------------------------------------------------------------------------------

    def _on_reset(self, request, response):
        written = self.write_trajectory_log()
        seed = self.settings['seed']
        self.twin.reset(seed if seed >= 0 else None)
        self._awaited_answers = set()
        self.paused = False
        self.cycle_gaps.restart()
        if self._started:  # else the start, once the graph is ready, begins the episode
            self._start_episode()
        response.success = True
        response.message = (f'twin reset to the initial state of the scenario, noise seed '
                            f'{self.twin.seed} (log restarted'
                            + (f'; the ended episode written to {written})' if written else ')'))
        self.get_logger().info(response.message)
        return response

    def _on_move_object(self, request, response):
        displacement = np.array(self.settings['object_displacement'], dtype=float)
        try:
            self.twin.move_object(displacement)
        except DualArmControlError as error:
            response.success = False
            response.message = f'cannot move the object: {error}'
            return response
        response.success = True
        response.message = f'object moved by {displacement.tolist()} m'
        self.get_logger().info(response.message)
        return response

    # -- end of run ------------------------------------------------------------------------------

    def write_trajectory_log(self):
        """Write the episode's ground truth and the counters to `trajectory_log` (if set)."""
        if self._recorder is None:
            return None
        save_episode_log(self._recorder, self.fri, self.cycle_gaps, self._first_cycle_wall,
                         self.twin.seed, self._trajectory_log)
        return self._trajectory_log


def main(args=None):
    """Run the bridge until the run's end (exit 0), Ctrl-C or SIGTERM."""
    return run_node(SimBridge, 'sim_bridge', args, on_exit=write_log_on_exit)


if __name__ == '__main__':
    sys.exit(main())
