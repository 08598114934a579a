"""
sim_bridge: the FRI stand-in, a ROS 2 shell around the MuJoCo twin of the two-arm cell.

Each FRI cycle the bridge publishes the state of both arms (joint states, FT wrench), /clock, the
mocap stream and the simulator's ground truth, and applies one torque command per arm. Two modes:

- lockstep (default): the state for cycle k (stamp t_k) is published, and the twin advances only
  when every arm has answered with a command stamped t_k. A refused command counts as the answer
  (the arm holds for that cycle). Runs as fast as the graph allows and is deterministic. Until
  the answers arrive the state is republished every `lockstep_republish_period` wall seconds
  (discovery, lost messages).
- realtime: a wall-clock timer paces the cycles like a real robot. An arm whose command for the
  previous cycle is missing holds (gravity compensation and joint damping) for the cycle, as the
  FRI safety stop would; such watchdog holds and late cycles are counted.

Commands with non-finite values, the wrong length or joint names other than the arm's seven names
in order are refused, counted per reason and logged (throttled); the arm holds for that cycle.
Commands stamped for another cycle, or a second answer to the same cycle, are ignored (counted).
Torques beyond the limits are clamped by the twin and counted. The bridge itself never runs on sim
time: its timers use the steady clock. Lockstep waits for the controllers only: a node that must
see a run from its first cycle (recorder, tracker) should be connected before they start.

The trajectory log (`trajectory_log`) has one row per cycle as TrajectoryRecorder defines it: row
0 is the initial state (zero torque), row k + 1 the state after cycle k with the torque applied
during cycle k; the counters are stored as scalars beside it. /sim/reset restarts the log (time
goes back to 0); the counters keep counting. SIGINT and SIGTERM end the run cleanly: the log is
written and the process exits 0.
"""

from dataclasses import dataclass, field
import math
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from dual_arm_control import contract
from dual_arm_control.core.exceptions import DualArmControlError, InputError
from dual_arm_control.evaluation.trajectory import TrajectoryRecorder
from dual_arm_control.nodes.common import (create_topic_publisher, diagnostic_value,
                                           fill_odometry, recorder_has_matched,
                                           recorder_matched_counts, run_node, seconds_to_ns,
                                           set_odometry, set_pose, set_vector3, stamp_ns,
                                           time_msg)
from dual_arm_control.parameters import parameter_descriptor
from dual_arm_control.resources import config_path
from dual_arm_control.scenario import load_scenario
import numpy as np
from rcl_interfaces.msg import SetParametersResult
import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.node import Node, NodeNameNonExistentError
from sim_bridge.twin import DualArmTwin
from std_srvs.srv import Trigger

MODES = ('lockstep', 'realtime')
FRI_PERIODS = (0.001, 0.002, 0.005)
REFUSAL_REASONS = ('non_finite', 'wrong_length', 'joint_names')
# A realtime cycle is late when it starts more than this fraction of a period after its due time.
LATE_CYCLE_TOLERANCE = 0.5
# Wall time between repeated warnings of the same kind [s].
LOG_THROTTLE_PERIOD = 1.0
# Lockstep: wall time without answers before the wait is reported as a warning [s].
WAITING_WARNING_DELAY = 2.0
MAX_DURATION = 1.0e6
# lockstep_wait_for_subscribers: wall time to let the other nodes' publishers match the
# subscriber (a recorder) once the graph is complete, before the first state [s].
SUBSCRIBER_SETTLE_TIME = 1.0
MAX_OBJECT_DISPLACEMENT = 2.0


def command_refusal(names, efforts, expected_names):
    """
    Return why a torque command is refused, or None if it is acceptable.

    names, efforts: the JointState fields of the command; expected_names: the arm's joint names
    in order. Reasons: 'wrong_length' (not one effort per joint), 'joint_names' (unknown,
    missing or misordered names), 'non_finite' (NaN or Inf effort).
    """
    if len(efforts) != len(expected_names):
        return 'wrong_length'
    if list(names) != list(expected_names):
        return 'joint_names'
    if not all(math.isfinite(value) for value in efforts):
        return 'non_finite'
    return None


def parameter_problem(name, value):
    """Return why a bridge parameter value is invalid, or None if it is acceptable."""
    if name == 'mode' and value not in MODES:
        return f'mode must be one of {MODES}, got {value!r}'
    if name == 'fri_period' and not any(math.isclose(value, p) for p in FRI_PERIODS):
        return f'fri_period must be one of {FRI_PERIODS} s (FRI send periods), got {value!r}'
    if name == 'duration' and not 0.0 <= value <= MAX_DURATION:
        return f'duration must be in [0, {MAX_DURATION:g}] s (0: scenario duration), got {value}'
    if name == 'object_displacement':
        if len(value) != 3 or not all(math.isfinite(v) for v in value):
            return f'object_displacement must be 3 finite numbers [m], got {list(value)}'
        if max(abs(v) for v in value) > MAX_OBJECT_DISPLACEMENT:
            return (f'object_displacement components must be within +-{MAX_OBJECT_DISPLACEMENT}'
                    f' m, got {list(value)}')
    if name == 'scenario' and not value:
        return 'scenario must name a scenario YAML file'
    if name == 'lockstep_republish_period' and not 0.01 <= value <= 10.0:
        return f'lockstep_republish_period must be in [0.01, 10] s, got {value}'
    if name == 'diagnostics_period' and not 0.01 <= value <= 100.0:
        return f'diagnostics_period must be in [0.01, 100] s, got {value}'
    if name == 'ground_truth_period' and not 0.0 <= value <= 1.0:
        return f'ground_truth_period must be in [0, 1] s (0: every cycle), got {value}'
    return None


@dataclass
class ArmCounters:
    """What happened to one arm's commands since the bridge started (cumulative)."""

    accepted: int = 0
    refused: dict = field(default_factory=lambda: dict.fromkeys(REFUSAL_REASONS, 0))
    clamps: int = 0
    watchdog_holds: int = 0
    ignored: int = 0

    def as_dict(self):
        """Return the counters as a flat {name: count} mapping."""
        counts = {'commands_accepted': self.accepted}
        counts.update({f'refused_{reason}': n for reason, n in self.refused.items()})
        counts.update({'torque_clamps': self.clamps, 'watchdog_holds': self.watchdog_holds,
                       'ignored_commands': self.ignored})
        return counts


class SimBridge(Node):
    """The bridge node: twin + publishers + command subscriptions + services."""

    def __init__(self, node_name='sim_bridge', **node_options):
        super().__init__(node_name, **node_options)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._declare_parameters()
        self.add_post_set_parameters_callback(self._on_parameters_set)
        self.mode = self.get_parameter('mode').value
        self.fri_period = self.get_parameter('fri_period').value
        scenario_path = self.get_parameter('scenario').value
        self.scenario = load_scenario(scenario_path)
        self.twin = DualArmTwin(self.scenario, fri_period=self.fri_period)
        self._publish_ground_truth = self.get_parameter('publish_ground_truth').value
        self._duration = self.get_parameter('duration').value
        self._trajectory_log = self.get_parameter('trajectory_log').value
        self._republish_period = self.get_parameter('lockstep_republish_period').value
        self._wait_for_tracker = (self.mode == 'lockstep'
                                  and self.get_parameter('lockstep_wait_for_tracker').value)
        self._mocap_samples = []
        self._awaited_tracker_ns = set()
        self._wait_for_subscribers = (self.mode == 'lockstep' and self.get_parameter(
            'lockstep_wait_for_subscribers').value)
        self._wait_for_recorder = (self.mode == 'lockstep' and self.get_parameter(
            'lockstep_wait_for_recorder').value)
        self._recorder_matched = None
        self._awaited_nodes = [name for name in
                               self.get_parameter('lockstep_wait_for_nodes').value
                               if name and self.mode == 'lockstep']
        self._diagnostics_period_ns = seconds_to_ns(
            self.get_parameter('diagnostics_period').value)
        self._ground_truth_period_ns = seconds_to_ns(
            self.get_parameter('ground_truth_period').value)

        self.finished = False
        self.counters = {arm: ArmCounters() for arm in contract.ARMS}
        self.cycles = 0
        self.late_cycles = 0
        self._joint_names = {arm: contract.joint_names(arm) for arm in contract.ARMS}
        self._answers = dict.fromkeys(contract.ARMS)
        self._awaited_ns = 0
        self._next_diagnostics_ns = 0
        self._next_ground_truth_ns = 0
        self._last_publish_wall = -math.inf
        self._state_published_wall = -math.inf
        self._first_cycle_wall = None
        self._last_tick_wall = None
        self._last_warning_wall = {}
        self._recorder = None
        self._last_applied = {}

        self._create_interfaces()
        self._started = False
        self._subscribed_wall = None
        if not (self._wait_for_subscribers or self._awaited_nodes or self._wait_for_recorder):
            self._start_episode()
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        if self.mode == 'lockstep':
            self._timer = self.create_timer(self._republish_period / 2.0, self._on_republish_timer,
                                            clock=steady)
        else:
            self._timer = self.create_timer(self.fri_period, self._on_fri_tick, clock=steady)
        self.get_logger().info(
            f'sim_bridge up: mode {self.mode}, FRI period {self.fri_period * 1e3:g} ms, scenario '
            f'{scenario_path}, seed {self.scenario.seed}, stops at sim time '
            f'{self.stop_time:g} s, ground truth {"on" if self._publish_ground_truth else "off"}')

    # -- set-up ---------------------------------------------------------------------------------

    def _declare_parameters(self):
        """Declare every parameter with its description, range and mutability."""
        self.declare_parameter(
            'scenario', str(config_path('scenarios', 'hold.yaml')), parameter_descriptor(
                'scenario YAML: cell, object, initial state, seed, perturbations',
                read_only=True))
        self.declare_parameter(
            'mode', 'lockstep', parameter_descriptor(
                'lockstep: advance when every arm answered (deterministic); realtime: paced by '
                'the wall clock with the FRI watchdog', read_only=True,
                constraints=f'one of {MODES}'))
        self.declare_parameter(
            'fri_period', 0.002, parameter_descriptor(
                'FRI cycle: state out, torque command in [s]', read_only=True,
                floating_range=(FRI_PERIODS[0], FRI_PERIODS[-1]),
                constraints=f'one of {FRI_PERIODS}'))
        self.declare_parameter(
            'duration', 0.0, parameter_descriptor(
                'sim time at which the run ends and the bridge exits 0 [s]; 0 = the duration of '
                'the scenario', floating_range=(0.0, MAX_DURATION)))
        self.declare_parameter(
            'trajectory_log', '', parameter_descriptor(
                'if set: .npz ground-truth trajectory written on exit (empty = none)',
                read_only=True))
        self.declare_parameter(
            'publish_ground_truth', True, parameter_descriptor(
                'publish /ground_truth/* topics (evaluation only, costs CPU)'))
        self.declare_parameter(
            'ground_truth_period', 0.0, parameter_descriptor(
                'sim time between ground-truth messages [s]; 0 = every FRI cycle',
                floating_range=(0.0, 1.0)))
        self.declare_parameter(
            'object_displacement', [0.0, 0.0, 0.0], parameter_descriptor(
                'displacement [x, y, z] applied by the move_object service [m]',
                constraints=f'each component within +-{MAX_OBJECT_DISPLACEMENT} m'))
        self.declare_parameter(
            'lockstep_republish_period', 0.1, parameter_descriptor(
                'lockstep: wall time without answers after which the state is published again '
                '[s]', read_only=True, floating_range=(0.01, 10.0)))
        self.declare_parameter(
            'lockstep_wait_for_tracker', False, parameter_descriptor(
                'lockstep: publish the mocap samples of a cycle first and the rest of the state '
                'only after the object tracker answered each of them (an /object/state with the '
                'stamp of the sample)', read_only=True))
        self.declare_parameter(
            'lockstep_wait_for_subscribers', False, parameter_descriptor(
                'lockstep: publish the first state only once every topic the bridge publishes '
                'has a subscriber (a recorder that must see every cycle)', read_only=True))
        self.declare_parameter(
            'lockstep_wait_for_recorder', False, parameter_descriptor(
                'lockstep: publish the first state only once bag_record reports (on '
                f'{contract.RECORDER_STATUS.name}) that it matched every publisher of its topics '
                'the bridge sees, so a recording loses nothing', read_only=True))
        self.declare_parameter(
            'lockstep_wait_for_nodes', [''], parameter_descriptor(
                'lockstep: publish the first state only once these nodes (full names, e.g. '
                '/ds_motion_generator, /bag_record) and their publishers are in the graph, plus '
                "a settling second, so every node sees the run from its first cycle ('' entries "
                'are ignored)', read_only=True))
        self.declare_parameter(
            'diagnostics_period', 1.0, parameter_descriptor(
                'sim time between /diagnostics messages [s]', floating_range=(0.01, 100.0)))

    def _create_interfaces(self):
        """Create publishers (each with its reused message), subscriptions and services."""
        self._clock_stream = _Stream(self, contract.CLOCK)
        self._mocap = _Stream(self, contract.MOCAP_OBJECT_POSE, frame_id=contract.WORLD_FRAME)
        self._diagnostics_pub = create_topic_publisher(self, contract.DIAGNOSTICS)
        if self._wait_for_recorder:
            self.create_subscription(
                contract.RECORDER_STATUS.msg_type, contract.RECORDER_STATUS.name,
                self._on_recorder_status, contract.RECORDER_STATUS.qos)
        self._object_truth = _Stream(self, contract.GROUND_TRUTH_OBJECT,
                                     frame_id=contract.WORLD_FRAME, child_frame_id='object')
        self._joint_states, self._ft, self._tool_truth = {}, {}, {}
        self._pad_wrench_truth, self._pad_contact_truth = {}, {}
        self._command_subs = {}
        for arm in contract.ARMS:
            self._joint_states[arm] = _Stream(self, contract.JOINT_STATES, arm)
            self._joint_states[arm].msg.name = self._joint_names[arm]
            self._ft[arm] = _Stream(self, contract.FT_WRENCH, arm, frame_id=f'{arm}_ft_sensor')
            self._tool_truth[arm] = _Stream(self, contract.GROUND_TRUTH_TOOL, arm,
                                            frame_id=contract.WORLD_FRAME,
                                            child_frame_id=f'{arm}_tool')
            self._pad_wrench_truth[arm] = _Stream(self, contract.GROUND_TRUTH_PAD_WRENCH, arm,
                                                  frame_id=contract.WORLD_FRAME)
            self._pad_contact_truth[arm] = _Stream(self, contract.GROUND_TRUTH_PAD_CONTACT, arm)
            self._command_subs[arm] = self.create_subscription(
                contract.TORQUE_COMMAND.msg_type, contract.TORQUE_COMMAND.resolved(arm),
                lambda msg, arm=arm: self._on_torque_command(arm, msg),
                contract.TORQUE_COMMAND.qos)
        self._reset_srv = self.create_service(Trigger, contract.SIM_RESET_SERVICE,
                                              self._on_reset)
        self._move_srv = self.create_service(Trigger, contract.SIM_MOVE_OBJECT_SERVICE,
                                             self._on_move_object)
        if self._wait_for_tracker:
            self._tracker_sub = self.create_subscription(
                contract.OBJECT_STATE.msg_type, contract.OBJECT_STATE.name,
                self._on_tracker_answer, contract.OBJECT_STATE.qos)

    # -- parameters ------------------------------------------------------------------------------

    def _on_set_parameters(self, parameters):
        """Refuse invalid values with a reason naming the parameter, value and allowed set."""
        for parameter in parameters:
            problem = parameter_problem(parameter.name, parameter.value)
            if problem is not None:
                return SetParametersResult(successful=False, reason=problem)
        return SetParametersResult(successful=True)

    def _on_parameters_set(self, parameters):
        """Apply the runtime-changeable parameters."""
        for parameter in parameters:
            if parameter.name == 'publish_ground_truth':
                self._publish_ground_truth = parameter.value
            elif parameter.name == 'duration':
                self._duration = parameter.value
            elif parameter.name == 'diagnostics_period':
                self._diagnostics_period_ns = seconds_to_ns(parameter.value)
            elif parameter.name == 'ground_truth_period':
                self._ground_truth_period_ns = seconds_to_ns(parameter.value)

    @property
    def stop_time(self):
        """Return the sim time at which the run ends [s]: `duration`, or the scenario's."""
        return self._duration if self._duration > 0.0 else self.scenario.duration

    # -- the FRI cycle ---------------------------------------------------------------------------

    def _on_torque_command(self, arm, msg):
        """Take one arm's command for the awaited cycle; in lockstep, advance when all answered."""
        counters = self.counters[arm]
        if stamp_ns(msg.header.stamp) != self._awaited_ns or self._answers[arm] is not None:
            counters.ignored += 1
            return
        reason = command_refusal(msg.name, msg.effort, self._joint_names[arm])
        if reason is None:
            counters.accepted += 1
            self._answers[arm] = np.array(msg.effort, dtype=float)
        else:
            counters.refused[reason] += 1
            self._answers[arm] = reason
            self._warn_throttled((arm, reason), f'{arm} torque command refused ({reason}): names '
                                 f'{list(msg.name)}, {len(msg.effort)} efforts; the arm holds '
                                 f'(refusals so far: {counters.refused})')
        if self.mode == 'lockstep' and self._all_answered():
            self._advance()

    def _all_answered(self):
        """Return True once every arm answered the awaited cycle."""
        return all(answer is not None for answer in self._answers.values())

    def _graph_ready(self):
        """Return True once the awaited subscribers, recorder and nodes are all there."""
        if self._wait_for_subscribers and not all(
                s.publisher.get_subscription_count() > 0 for s in self._streams()):
            return False
        if self._wait_for_recorder and not self._recorder_ready():
            return False
        present = {f'{namespace.rstrip("/")}/{name}'
                   for name, namespace in self.get_node_names_and_namespaces()}
        for full_name in self._awaited_nodes:
            if full_name not in present:
                return False
            namespace, _, name = full_name.rpartition('/')
            try:
                if not self.get_publisher_names_and_types_by_node(name, namespace or '/'):
                    return False
            except NodeNameNonExistentError:
                return False
        return True

    def _on_recorder_status(self, msg):
        """Keep the recorder's matched publishers per topic."""
        self._recorder_matched = recorder_matched_counts(msg)

    def _recorder_ready(self):
        """Return True once the recorder matched every publisher the bridge sees."""
        return recorder_has_matched(self, self._recorder_matched)

    def _streams(self):
        """Return every state and ground-truth stream the bridge publishes."""
        streams = [self._clock_stream, self._mocap, self._object_truth]
        for per_arm in (self._joint_states, self._ft, self._tool_truth, self._pad_wrench_truth,
                        self._pad_contact_truth):
            streams += list(per_arm.values())
        return streams

    def _on_fri_tick(self):
        """Realtime: one FRI cycle; an arm without a command for the last cycle holds."""
        now = time.monotonic()
        if self._last_tick_wall is not None:
            if now - self._last_tick_wall > self.fri_period * (1.0 + LATE_CYCLE_TOLERANCE):
                self.late_cycles += 1
        self._last_tick_wall = now
        for arm, answer in self._answers.items():
            if answer is None:
                self.counters[arm].watchdog_holds += 1
                self._warn_throttled((arm, 'watchdog'), (
                    f'{arm}: no torque command for the last FRI cycle; the arm holds (watchdog '
                    f'holds so far: {self.counters[arm].watchdog_holds})'))
        self._advance()

    def _warn_throttled(self, key, message):
        """Log a warning at most once per LOG_THROTTLE_PERIOD for each key (arm, reason)."""
        now = time.monotonic()
        if now - self._last_warning_wall.get(key, -math.inf) >= LOG_THROTTLE_PERIOD:
            self._last_warning_wall[key] = now
            self.get_logger().warning(message)

    def _on_tracker_answer(self, msg):
        """Lockstep: count the tracker's answer to a mocap sample; go on when all are in."""
        if not self._awaited_tracker_ns:
            return
        self._awaited_tracker_ns.discard(stamp_ns(msg.header.stamp))
        if not self._awaited_tracker_ns:
            self._publish_cycle_state()

    def _on_republish_timer(self):
        """Lockstep: publish the awaited mocap samples or state again if answers are overdue."""
        if time.monotonic() - self._last_publish_wall < self._republish_period:
            return
        if not self._started:
            if not self._graph_ready():
                self._subscribed_wall = None
            elif self._subscribed_wall is None:
                self._subscribed_wall = time.monotonic()
            elif time.monotonic() - self._subscribed_wall >= SUBSCRIBER_SETTLE_TIME:
                self._start_episode()
            return
        if self._awaited_tracker_ns:
            self._publish_mocap()
            self._warn_throttled(('lockstep', 'tracker'), (
                f'lockstep: waiting for the object tracker to answer the mocap samples stamped '
                f'{sorted(s * 1e-9 for s in self._awaited_tracker_ns)} s'))
            return
        # Both arms again: the DS and the wrench QP re-answer a tick only with a complete set,
        # and a controller that missed their first answer needs it (extra commands are ignored).
        self._publish_joint_states()
        self._publish_ft(time_msg(self._awaited_ns))
        if time.monotonic() - self._state_published_wall < WAITING_WARNING_DELAY:
            return
        self._warn_throttled(('lockstep', 'waiting'), (
            f'lockstep: waiting for the torque commands stamped {self._awaited_ns * 1e-9:g} s '
            f'from {[arm for arm, answer in self._answers.items() if answer is None]}'))

    def _advance(self):
        """Apply this cycle's torques (commands or hold), step the twin, publish the new state."""
        if self._first_cycle_wall is None:
            self._first_cycle_wall = time.monotonic()
            self.get_logger().info('first FRI cycle: stepping the twin')
        torques = {arm: answer if isinstance(answer, np.ndarray) else self.twin.hold_torques(arm)
                   for arm, answer in self._answers.items()}
        try:
            report = self.twin.step(torques)
        except InputError as error:
            self.get_logger().error(f'twin refused the torques ({error}); both arms hold')
            torques = {arm: self.twin.hold_torques(arm) for arm in contract.ARMS}
            report = self.twin.step(torques)
        for arm in contract.ARMS:
            if report.clamped[arm]:
                self.counters[arm].clamps += 1
            limits = self.twin.torque_limits(arm)
            self._last_applied[arm] = np.clip(torques[arm], -limits, limits)
        self.cycles += 1
        if self._recorder is not None:
            self._recorder.append(self.twin, self._last_applied)
        self._publish_state()
        if self.twin.time >= self.stop_time - 0.5 * self.fri_period:
            self.finished = True
            self._publish_diagnostics()
            bridge = self.diagnostic_values()['sim_bridge']
            self.get_logger().info(
                f'reached sim time {self.twin.time:g} s after {self.cycles} cycles (real-time '
                f'factor {bridge["real_time_factor"]:.2f}); stopping')

    def _start_episode(self):
        """
        Start recording and publish the initial state (after construction and reset).

        With lockstep_wait_for_subscribers the first start waits (republish timer) until every
        topic the bridge publishes has a subscriber, so a recorder sees every cycle from 0.
        """
        self._started = True
        self._last_applied = {arm: np.zeros(contract.JOINTS_PER_ARM) for arm in contract.ARMS}
        if self._trajectory_log:
            self._recorder = TrajectoryRecorder()
            self._recorder.append(self.twin, self._last_applied)
        self._next_diagnostics_ns = 0
        self._next_ground_truth_ns = 0
        self._publish_state()

    # -- publishing ------------------------------------------------------------------------------

    def _publish_state(self):
        """
        Publish everything observable at the twin's current time and await its answers.

        The cycle's mocap samples go first; with lockstep_wait_for_tracker the rest follows
        once the tracker has answered each of them, so every estimate built from a sample
        delivered at this cycle exists before anyone sees the cycle's joint states.
        """
        self._awaited_ns = seconds_to_ns(self.twin.time)
        self._answers = dict.fromkeys(contract.ARMS)
        self._state_published_wall = time.monotonic()
        self._mocap_samples = self.twin.mocap_samples()
        self._publish_mocap()
        if self._wait_for_tracker and self._mocap_samples:
            self._awaited_tracker_ns = {seconds_to_ns(s.stamp) for s in self._mocap_samples}
            return
        self._publish_cycle_state()

    def _publish_mocap(self):
        """Publish the mocap samples delivered at this cycle (stamp = sampling time)."""
        for sample in self._mocap_samples:
            self._mocap.msg.header.stamp = time_msg(seconds_to_ns(sample.stamp))
            set_pose(self._mocap.msg.pose, sample.p_world, sample.quat_xyzw)
            self._mocap.publish()
        self._last_publish_wall = time.monotonic()

    def _publish_cycle_state(self):
        """Publish the joint states, FT wrenches, /clock, ground truth and diagnostics."""
        stamp = time_msg(self._awaited_ns)
        self._publish_joint_states()
        self._publish_ft(stamp)
        if self._publish_ground_truth and self._awaited_ns >= self._next_ground_truth_ns:
            self._next_ground_truth_ns = self._awaited_ns + self._ground_truth_period_ns
            self._publish_truth(stamp)
        if self._awaited_ns >= self._next_diagnostics_ns:
            self._next_diagnostics_ns += self._diagnostics_period_ns
            self._publish_diagnostics()

    def _publish_ft(self, stamp):
        """Publish both arms' FT readings of the awaited cycle."""
        for arm in contract.ARMS:
            force, torque = self.twin.ft_wrench(arm)
            ft = self._ft[arm]
            ft.msg.header.stamp = stamp
            set_vector3(ft.msg.wrench.force, force)
            set_vector3(ft.msg.wrench.torque, torque)
            ft.publish()

    def _publish_joint_states(self):
        """Publish /clock and the joint states of the awaited cycle (again)."""
        stamp = time_msg(self._awaited_ns)
        self._clock_stream.msg.clock = stamp
        self._clock_stream.publish()
        for arm in contract.ARMS:
            sample = self.twin.joint_state(arm)
            joint_states = self._joint_states[arm]
            joint_states.msg.header.stamp = stamp
            joint_states.msg.position = sample.position.tolist()
            joint_states.msg.velocity = sample.velocity.tolist()
            joint_states.msg.effort = sample.measured_torque.tolist()
            joint_states.publish()
        self._last_publish_wall = time.monotonic()

    def _publish_truth(self, stamp):
        """Publish the simulator's ground truth: object, tools, pad wrenches and contacts."""
        self._object_truth.msg.header.stamp = stamp
        set_odometry(self._object_truth.msg, *self.twin.object_pose(), *self.twin.object_twist())
        self._object_truth.publish()
        for arm in contract.ARMS:
            p_world_tool, R_world_tool = self.twin.tool_pose(arm)
            tool = self._tool_truth[arm]
            tool.msg.header.stamp = stamp
            fill_odometry(tool.msg, p_world_tool, R_world_tool, *self.twin.tool_twist(arm))
            tool.publish()
            force_world, in_contact = self.twin.pad_contact(arm)
            _, torque_world = self.twin.pad_wrench(arm)
            wrench = self._pad_wrench_truth[arm]
            wrench.msg.header.stamp = stamp
            set_vector3(wrench.msg.wrench.force, force_world)
            set_vector3(wrench.msg.wrench.torque, torque_world)
            wrench.publish()
            self._pad_contact_truth[arm].msg.data = bool(in_contact)
            self._pad_contact_truth[arm].publish()

    def diagnostic_values(self):
        """Return {status name: {key: value}} of the counters (also saved in the log)."""
        wall = time.monotonic() - self._first_cycle_wall if self._first_cycle_wall else 0.0
        bridge = {'mode': self.mode, 'sim_time': self.twin.time, 'cycles': self.cycles,
                  'late_cycles': self.late_cycles,
                  'real_time_factor': self.twin.time / wall if wall > 0.0 else 0.0}
        values = {'sim_bridge': bridge}
        for arm in contract.ARMS:
            values[f'sim_bridge: {arm} arm'] = self.counters[arm].as_dict()
        return values

    def _publish_diagnostics(self):
        """Publish the counters; an arm is WARN once anything was refused, clamped or held."""
        msg = DiagnosticArray()
        msg.header.stamp = time_msg(self._awaited_ns)
        for name, values in self.diagnostic_values().items():
            status = DiagnosticStatus(name=name, hardware_id='sim_bridge')
            trouble = (values.get('watchdog_holds', 0) + values.get('torque_clamps', 0)
                       + sum(values.get(f'refused_{r}', 0) for r in REFUSAL_REASONS))
            status.level = DiagnosticStatus.WARN if trouble else DiagnosticStatus.OK
            status.message = 'commands refused, clamped or missing' if trouble else 'ok'
            status.values = [KeyValue(key=key, value=diagnostic_value(value))
                             for key, value in values.items()]
            msg.status.append(status)
        self._diagnostics_pub.publish(msg)

    # -- services --------------------------------------------------------------------------------

    def _on_reset(self, request, response):
        """Reset the twin to the scenario's initial state and start a new episode log."""
        self.twin.reset()
        self._start_episode()
        response.success = True
        response.message = 'twin reset to the initial state of the scenario (log restarted)'
        self.get_logger().info(response.message)
        return response

    def _on_move_object(self, request, response):
        """Move the object by the `object_displacement` parameter."""
        displacement = np.array(self.get_parameter('object_displacement').value, dtype=float)
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
        path, recorder = self._trajectory_log, self._recorder
        if recorder is None:
            return None
        recorder.counters.update({
            'torque_clamp_count': sum(c.clamps for c in self.counters.values()),
            'refused_message_count': sum(sum(c.refused.values())
                                         for c in self.counters.values()),
            'watchdog_hold_count': sum(c.watchdog_holds for c in self.counters.values()),
            'cycles': self.cycles, 'late_cycles': self.late_cycles,
            'wall_time': (time.monotonic() - self._first_cycle_wall
                          if self._first_cycle_wall else 0.0),
            'fri_period': self.fri_period, 'seed': self.scenario.seed})
        for arm, counters in self.counters.items():
            recorder.counters.update({f'{arm}_{key}': value
                                      for key, value in counters.as_dict().items()})
        recorder.save(path)
        return path


class _Stream:
    """A publisher of the contract and the message it reuses (filled in place, then sent)."""

    def __init__(self, node, topic, arm=None, frame_id=None, child_frame_id=None):
        self.publisher = create_topic_publisher(node, topic, arm)
        self.msg = topic.msg_type()
        if frame_id is not None:
            self.msg.header.frame_id = frame_id
        if child_frame_id is not None:
            self.msg.child_frame_id = child_frame_id

    def publish(self):
        """Send the message as it is filled now."""
        self.publisher.publish(self.msg)


def _write_log(node):
    """Write the bridge's trajectory log on the way out; return the exit code."""
    exit_logger = rclpy.logging.get_logger(f'{node.get_name()}.exit')
    try:
        path = node.write_trajectory_log()
    except OSError as error:
        exit_logger.error(f'cannot write the trajectory log: {error}')
        return 1
    if path:
        exit_logger.info(f'trajectory log written to {path}')
    return 0


def main(args=None):
    """Run the bridge until the run's end (exit 0), Ctrl-C or SIGTERM."""
    return run_node(SimBridge, 'sim_bridge', args, on_exit=_write_log)


if __name__ == '__main__':
    sys.exit(main())
