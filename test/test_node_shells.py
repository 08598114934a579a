"""
The node shells one at a time in one process: tracker, controller, wrench QP, DS.

Each test builds the node on a private rclpy context in the test's ROS domain; a probe node on
the same EventsExecutor plays the rest of the graph (bridge, DS) and records what the node
publishes. The executor is spun for bounded times only. Expected numbers come from the core
objects the nodes wrap, called directly with the same inputs.
"""

import math

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from dual_arm_control import contract
from dual_arm_control.catalogue import object_spec
from dual_arm_control.core.ballistics import landing_without_drag
from dual_arm_control.core.geometry import (matrix_to_quat_xyzw, quat_xyzw_to_matrix,
                                            rotation_exp)
from dual_arm_control.core.passive_control import (hold_torque, PassiveController,
                                                   PassiveControllerConfig)
from dual_arm_control.core.tracker import TrackerConfig
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.nodes.command_signature import COMMAND_KEY_VARIABLE, command_signature
from dual_arm_control.nodes.ds_motion_generator import DsMotionGenerator
from dual_arm_control.nodes.messages import (arm_command_message, arm_command_of, fill_odometry,
                                             stamp_ns, time_msg)
from dual_arm_control.nodes.object_tracker import ObjectTrackerNode
from dual_arm_control.nodes.passive_controller import PassiveControllerNode
from dual_arm_control.nodes.wrench_qp import WrenchQPNode
from dual_arm_control.runtime.configuration import planned_release, predicted_landing
from dual_arm_control.runtime.controller_step import DS_COMMAND_LAG_KEY
from dual_arm_control.runtime.signals import ArmCommandSample
from dual_arm_control.runtime.timing import seconds_to_ns, TickSchedule
from dual_arm_control.scenario import load_scenario, scenario_path
from graph_helpers import GraphProbe
import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_sensor_data, ReliabilityPolicy

SPIN_TIMEOUT = 10.0
# Wall time the executor keeps spinning to show that a message is NOT sent.
QUIET_TIME = 0.3
GRAVITY = 9.81
CELL = load_cell()


class Harness:
    """A node under test and a probe node that publishes its inputs and records its outputs."""

    def __init__(self, domain_id, node_factory):
        self.probe = GraphProbe(domain_id, name='shell_probe')
        self.node = node_factory(self.probe.context)
        self.probe.executor.add_node(self.node)
        self.received = {}
        self._publishers = {}

    def publisher(self, topic, arm=None):
        """Create a probe publisher on a contract topic; return it."""
        name = topic.resolved(arm)
        self._publishers[name] = self.probe.node.create_publisher(topic.msg_type, name,
                                                                  topic.qos)
        return self._publishers[name]

    def record(self, topic, arm=None):
        """Record the messages of a contract topic in self.received[resolved name]."""
        name = topic.resolved(arm)
        self.received[name] = []
        self.probe.node.create_subscription(topic.msg_type, name, self.received[name].append,
                                            topic.qos)
        return self.received[name]

    def connect(self):
        """Spin until every probe publisher and every recorded node publisher is matched."""
        node_publishers = [p for p in self.node.publishers if p.topic_name in self.received]
        publishers = list(self._publishers.values()) + node_publishers
        assert self.probe.spin_until(
            lambda: all(p.get_subscription_count() > 0 for p in publishers), SPIN_TIMEOUT)

    def send(self, name, msg):
        """Publish msg on the probe publisher of the resolved topic name."""
        self._publishers[name].publish(msg)

    def spin_until(self, condition):
        """Spin until condition() or SPIN_TIMEOUT; return condition()."""
        return self.probe.spin_until(condition, SPIN_TIMEOUT)

    def spin_quietly(self):
        """Spin for QUIET_TIME whatever happens."""
        self.probe.spin_until(lambda: False, QUIET_TIME)

    def close(self):
        """Destroy the node and the probe."""
        self.probe.executor.remove_node(self.node)
        self.node.destroy_node()
        self.probe.close()


@pytest.fixture
def harness_factory(ros_domain):
    """Return a function building a Harness around a node factory(context); close them all."""
    harnesses = []

    def build(node_factory):
        harnesses.append(Harness(ros_domain, node_factory))
        return harnesses[-1]

    yield build
    for harness in harnesses:
        harness.close()


def set_parameter(node, name, value):
    """Set one parameter on the node; return the SetParametersResult."""
    return node.set_parameters([Parameter(name, value=value)])[0]


# -- object_tracker ------------------------------------------------------------------------------

P_WORLD_OBJECT = np.array([0.41, 0.0, 0.32])
SAMPLE_PERIOD_NS = 5_000_000


def mocap_sample(t_ns, position, quat_xyzw):
    """Return a PoseStamped mocap sample."""
    msg = contract.MOCAP_OBJECT_POSE.msg_type()
    msg.header.stamp = time_msg(t_ns)
    msg.header.frame_id = contract.WORLD_FRAME
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (float(v) for v in position)
    (msg.pose.orientation.x, msg.pose.orientation.y, msg.pose.orientation.z,
     msg.pose.orientation.w) = (float(v) for v in quat_xyzw)
    return msg


def noisy_pose(rng):
    """Return (position, quat_xyzw) of the resting object with the twin's mocap noise."""
    position = P_WORLD_OBJECT + rng.normal(0.0, 5e-4, 3)
    return position, matrix_to_quat_xyzw(rotation_exp(rng.normal(0.0, 5e-3, 3)))


@pytest.fixture
def tracker(harness_factory):
    harness = harness_factory(lambda context: ObjectTrackerNode(context=context))
    harness.publisher(contract.MOCAP_OBJECT_POSE)
    harness.record(contract.OBJECT_STATE)
    harness.record(contract.DIAGNOSTICS)
    harness.connect()
    return harness


def feed_sample(harness, t_ns, position, quat_xyzw):
    """Send one sample; wait until the tracker answered or refused it."""
    node = harness.node
    handled = len(harness.received['/object/state']) + node.step.refusals.total
    harness.send('/mocap/object_pose', mocap_sample(t_ns, position, quat_xyzw))
    assert harness.spin_until(
        lambda: len(harness.received['/object/state']) + node.step.refusals.total > handled)


def test_tracker_answers_every_valid_sample_with_its_stamp(tracker):
    rng = np.random.default_rng(4)
    sent = []
    invalid = {30: ([math.nan, 0.0, 0.3], [0.0, 0.0, 0.0, 1.0]),
               60: (P_WORLD_OBJECT, [0.0, 0.0, 0.0, 0.0]),
               90: (P_WORLD_OBJECT, [0.0, 0.0, math.inf, 1.0])}
    for k in range(210):
        t_ns = k * SAMPLE_PERIOD_NS
        if k in invalid:
            feed_sample(tracker, t_ns, *invalid[k])
            continue
        position, quat_xyzw = noisy_pose(rng)
        if k == 120:
            position = position + [0.3, 0.0, 0.0]
        feed_sample(tracker, t_ns, position, quat_xyzw)
        sent.append(t_ns)
        if k == 150:
            feed_sample(tracker, t_ns - 2 * SAMPLE_PERIOD_NS, position, quat_xyzw)

    answers = tracker.received['/object/state']
    assert [stamp_ns(msg.header.stamp) for msg in answers] == sent
    assert tracker.node.step.refusals.counts == {'non_finite': 2, 'zero_quaternion': 1,
                                                 'old_stamp': 1}
    assert tracker.node.step.counters['samples_rejected_outlier'] == 1
    assert tracker.node.step.counters['samples_used'] == len(sent) - 1
    outlier_answer = answers[sent.index(120 * SAMPLE_PERIOD_NS)].pose.pose.position
    # The 0.3 m jump is gated out: the answer is the prediction, within a few noise sigmas.
    assert np.linalg.norm([outlier_answer.x, outlier_answer.y, outlier_answer.z]
                          - P_WORLD_OBJECT) < 3e-3
    assert all(msg.header.frame_id == 'world' and msg.child_frame_id == 'object'
               for msg in answers)

    assert tracker.spin_until(lambda: len(tracker.received['/diagnostics']) >= 2)
    stamps = [stamp_ns(msg.header.stamp) for msg in tracker.received['/diagnostics']]
    assert stamps[:2] == [0, 200 * SAMPLE_PERIOD_NS]
    status = tracker.received['/diagnostics'][1].status[0]
    values = {pair.key: pair.value for pair in status.values}
    assert status.name == 'object_tracker' and status.level == DiagnosticStatus.WARN
    assert values['refused_old_stamp'] == '1' and values['refused_zero_quaternion'] == '1'
    assert values['samples_rejected_outlier'] == '1'


def test_tracker_parameters_refused_with_reason_and_applied_at_rest(tracker):
    node = tracker.node
    result = set_parameter(node, 'position_noise', 2.0)
    assert not result.successful and result.reason
    result = set_parameter(node, 'position_noise', 0.0)
    assert not result.successful and 'position_noise' in result.reason
    assert node.get_parameter('position_noise').value == TrackerConfig().position_noise

    assert set_parameter(node, 'position_noise', 0.001).successful
    assert node.pending_config.position_noise == 0.001
    rng = np.random.default_rng(5)
    for k in range(3):
        feed_sample(tracker, k * SAMPLE_PERIOD_NS, *noisy_pose(rng))
    assert node.config.position_noise == 0.001 and node.pending_config is None
    assert node.step.counters['config_changes_applied'] == 1


def test_tracker_restarts_when_the_clock_goes_back(tracker):
    rng = np.random.default_rng(6)
    late_ns = seconds_to_ns(3.0)
    for t_ns in (late_ns, late_ns + SAMPLE_PERIOD_NS, SAMPLE_PERIOD_NS, 0, 2 * SAMPLE_PERIOD_NS):
        feed_sample(tracker, t_ns, *noisy_pose(rng))
    # 3 s back is a reset (restart, answered); 5 ms back after it is a late sample (refused).
    assert [stamp_ns(m.header.stamp) for m in tracker.received['/object/state']] == [
        late_ns, late_ns + SAMPLE_PERIOD_NS, SAMPLE_PERIOD_NS, 2 * SAMPLE_PERIOD_NS]
    assert tracker.node.step.counters['time_resets'] == 1
    assert tracker.node.step.counters['track_starts'] == 2
    assert tracker.node.step.refusals.counts == {'old_stamp': 1}


def test_a_best_effort_mocap_driver_drives_the_tracker(harness_factory):
    """A motion-capture driver publishing with the sensor-data QoS (best effort) connects."""
    harness = harness_factory(lambda context: ObjectTrackerNode(context=context))
    publisher = harness.probe.node.create_publisher(
        contract.MOCAP_OBJECT_POSE.msg_type, contract.MOCAP_OBJECT_POSE.name,
        qos_profile_sensor_data)
    answers = harness.record(contract.OBJECT_STATE)
    assert harness.spin_until(lambda: publisher.get_subscription_count() > 0)
    rng = np.random.default_rng(8)
    for k in range(20):
        publisher.publish(mocap_sample(k * SAMPLE_PERIOD_NS, *noisy_pose(rng)))
        assert harness.spin_until(lambda: len(answers) == k + 1)
    position = answers[-1].pose.pose.position
    assert np.linalg.norm([position.x - P_WORLD_OBJECT[0], position.y - P_WORLD_OBJECT[1],
                           position.z - P_WORLD_OBJECT[2]]) < 2e-3
    assert harness.node.step.counters['samples_used'] == 20


# -- passive_controller --------------------------------------------------------------------------

Q_HOME_LEFT = CELL.arm('left').q_home
TICK_PERIOD_NS = 6_000_000  # first 2 ms cycle at least 5 ms after the previous tick


def controller_node(lockstep):
    """Return a factory of the left arm's controller node."""
    def build(context):
        # The posture stays put (no tracking of the DS target): these tests check the shell's
        # translation against one core controller call; test_robust_grab covers the tracking.
        return PassiveControllerNode(context=context, namespace='/left', parameter_overrides=[
            Parameter('arm', value='left'), Parameter('lockstep', value=lockstep),
            Parameter('posture_tracking_step', value=0.0)])
    return build


def controller_harness(harness_factory, lockstep):
    """Return a Harness around the left controller, connected to its three inputs."""
    harness = harness_factory(controller_node(lockstep))
    for topic in (contract.JOINT_STATES, contract.DS_COMMAND, contract.CONTACT_WRENCH):
        harness.publisher(topic, 'left')
    harness.record(contract.TORQUE_COMMAND, 'left')
    harness.connect()
    return harness


@pytest.fixture(params=[True, False], ids=['lockstep', 'realtime'])
def controller(request, harness_factory):
    return controller_harness(harness_factory, request.param)


@pytest.fixture
def lockstep_controller(harness_factory):
    return controller_harness(harness_factory, True)


def joint_state(t_ns, q, dq, arm='left'):
    msg = contract.JOINT_STATES.msg_type()
    msg.header.stamp = time_msg(t_ns)
    msg.name = contract.joint_names(arm)
    msg.position = [float(v) for v in q]
    msg.velocity = [float(v) for v in dq]
    return msg


def ds_command(t_ns, v_world, w_world, R_world):
    """Return the left arm's ds_command message (values unchecked: NaN passes through)."""
    return arm_command_message('left', ArmCommandSample(
        t_ns, np.zeros(3), matrix_to_quat_xyzw(R_world), np.asarray(v_world, float),
        np.asarray(w_world, float)))


def contact_wrench(t_ns, wrench):
    msg = contract.CONTACT_WRENCH.msg_type()
    msg.header.stamp = time_msg(t_ns)
    msg.header.frame_id = contract.WORLD_FRAME
    force, torque = msg.wrench.force, msg.wrench.torque
    force.x, force.y, force.z, torque.x, torque.y, torque.z = (float(v) for v in wrench)
    return msg


def expected_torque(q, dq, command, wrench, config=None):
    """Return the core controller's torque for a command (v, w, R) sent through a message."""
    v_world, w_world, R_world = command
    R_received = quat_xyzw_to_matrix(matrix_to_quat_xyzw(R_world))
    config = config or PassiveControllerConfig(posture_tracking_step=0.0)
    controller = PassiveController(arm_model('left', CELL), Q_HOME_LEFT, config)
    return controller.torque_command(q, dq, v_world, w_world, R_received, wrench).torque


def expected_hold(q, dq):
    model = arm_model('left', CELL)
    torque = hold_torque(model.gravity_torque(q), dq, PassiveControllerConfig().hold_damping)
    return np.clip(torque, -model.torque_limits, model.torque_limits)


def controller_inputs(seed):
    """Return a joint state (q, dq), a DS command (v, w, R) and a contact wrench, seeded."""
    rng = np.random.default_rng(seed)
    q = Q_HOME_LEFT + rng.uniform(-0.1, 0.1, 7)
    dq = rng.uniform(-0.3, 0.3, 7)
    command = (rng.uniform(-0.3, 0.3, 3), rng.uniform(-0.5, 0.5, 3),
               rotation_exp(rng.uniform(-0.2, 0.2, 3)) @ CELL.arm('left').R_world_standby)
    wrench = np.concatenate((rng.uniform(-30.0, 30.0, 3), rng.uniform(-1.0, 1.0, 3)))
    return q, dq, command, wrench


def efforts(msg):
    return np.array(msg.effort)


def test_controller_waits_for_ds_and_wrench_on_lockstep_ticks(lockstep_controller):
    controller = lockstep_controller
    node, commands = controller.node, controller.received['/left/torque_command']
    q, dq, command, wrench = controller_inputs(1)

    controller.send('/left/joint_states', joint_state(0, q, dq))
    assert controller.spin_until(lambda: node.awaited_tick_ns == 0)
    controller.send('/left/ds_command', ds_command(0, *command))
    assert controller.spin_until(lambda: node.step.counters['ds_commands_received'] == 1)
    controller.spin_quietly()
    assert commands == []
    controller.send('/left/contact_wrench', contact_wrench(0, wrench))
    assert controller.spin_until(lambda: len(commands) == 1)
    controller.spin_quietly()
    assert len(commands) == 1 and stamp_ns(commands[0].header.stamp) == 0
    assert commands[0].name == contract.joint_names('left')
    np.testing.assert_allclose(efforts(commands[0]), expected_torque(q, dq, command, wrench),
                               rtol=0.0, atol=1e-9)

    for k, t_ns in enumerate((2_000_000, 4_000_000), start=2):
        controller.send('/left/joint_states', joint_state(t_ns, q, dq))
        assert controller.spin_until(lambda: len(commands) == k)
        assert stamp_ns(commands[-1].header.stamp) == t_ns

    controller.send('/left/joint_states', joint_state(TICK_PERIOD_NS, q, dq))
    assert controller.spin_until(lambda: node.awaited_tick_ns == TICK_PERIOD_NS)
    nan_command = (np.full(3, math.nan), command[1], command[2])
    controller.send('/left/ds_command', ds_command(TICK_PERIOD_NS, *nan_command))
    controller.send('/left/contact_wrench', contact_wrench(TICK_PERIOD_NS, wrench))
    assert controller.spin_until(lambda: len(commands) == 4)
    # The NaN command is refused but ends the wait; the newest valid command (6 ms old) is used.
    assert node.step.refusals.counts == {'ds_command': 1}
    np.testing.assert_allclose(efforts(commands[3]), expected_torque(q, dq, command, wrench),
                               rtol=0.0, atol=1e-9)
    assert node.step.counters['holds_no_command'] == node.step.counters['holds_stale_command'] == 0
    # That cycle ran on a DS command one tick old (its wrench was the tick's own).
    assert (node.step.counters['ds_command_behind'], node.step.counters['ds_command_lag_max_ms'],
            node.step.counters['contact_wrench_behind']) == (1, 6, 0)


def test_controller_holds_without_fresh_command_and_refuses_nan(controller):
    node, commands = controller.node, controller.received['/left/torque_command']
    q, dq, command, wrench = controller_inputs(2)
    if node.lockstep:
        controller.send('/left/ds_command', ds_command(0, np.full(3, math.nan), *command[1:]))
        controller.send('/left/contact_wrench', contact_wrench(0, np.full(6, math.nan)))
        assert controller.spin_until(lambda: node.step.refusals.total == 2)
    controller.send('/left/joint_states', joint_state(0, q, dq))
    assert controller.spin_until(lambda: len(commands) == 1)
    np.testing.assert_allclose(efforts(commands[0]), expected_hold(q, dq), rtol=0.0,
                               atol=1e-9)
    assert node.step.counters['holds_no_command'] == 1

    controller.send('/left/ds_command', ds_command(2_000_000, *command))
    controller.send('/left/contact_wrench', contact_wrench(2_000_000, wrench))
    assert controller.spin_until(
        lambda: node.step.counters['ds_commands_received']
        == node.step.counters['contact_wrenches_received'] == 1)
    controller.send('/left/joint_states', joint_state(2_000_000, q, dq))
    assert controller.spin_until(lambda: len(commands) == 2)
    np.testing.assert_allclose(efforts(commands[1]), expected_torque(q, dq, command, wrench),
                               rtol=0.0, atol=1e-9)

    stale_ns = 2_000_000 + seconds_to_ns(0.05) + 2_000_000
    controller.send('/left/joint_states', joint_state(stale_ns, q, dq))
    if node.lockstep:
        assert controller.spin_until(lambda: node.awaited_tick_ns == stale_ns)
        controller.send('/left/ds_command', ds_command(stale_ns, command[0],
                                                       np.full(3, math.inf), command[2]))
        controller.send('/left/contact_wrench', contact_wrench(stale_ns, np.full(6, math.inf)))
    assert controller.spin_until(lambda: len(commands) == 3)
    np.testing.assert_allclose(efforts(commands[2]), expected_hold(q, dq), rtol=0.0,
                               atol=1e-9)
    assert node.step.counters['holds_stale_command'] == 1

    bad_state = joint_state(stale_ns + 2_000_000, q, dq)
    bad_state.velocity[3] = math.nan
    controller.send('/left/joint_states', bad_state)
    assert controller.spin_until(lambda: node.step.refusals.counts.get('joint_state') == 1)
    controller.spin_quietly()
    assert len(commands) == 3
    assert all(np.all(np.isfinite(efforts(msg))) for msg in commands)
    if node.lockstep:
        assert node.step.refusals.counts == {'ds_command': 2, 'contact_wrench': 2,
                                             'joint_state': 1}


def test_controller_parameters(controller):
    node, commands = controller.node, controller.received['/left/torque_command']
    for name, value, reason in (('damping_along', -1.0, ''),
                                ('damping_along', 0.0, 'damping_along'),
                                ('null_space_stiffness', [1.0] * 6, 'null_space_stiffness'),
                                ('command_timeout', 0.005, 'command_timeout'),
                                ('arm', 'right', 'read-only')):
        result = set_parameter(node, name, value)
        assert not result.successful and reason in result.reason, (name, result.reason)
    assert set_parameter(node, 'damping_along', 250.0).successful
    assert node.controller.config.damping_along == PassiveControllerConfig().damping_along
    q, dq, command, wrench = controller_inputs(3)
    controller.send('/left/ds_command', ds_command(0, *command))
    controller.send('/left/contact_wrench', contact_wrench(0, wrench))
    assert controller.spin_until(lambda: node.step.counters['ds_commands_received']
                                 == node.step.counters['contact_wrenches_received'] == 1)
    controller.send('/left/joint_states', joint_state(0, q, dq))
    assert controller.spin_until(lambda: len(commands) == 1)
    assert node.controller.config.damping_along == 250.0
    config = PassiveControllerConfig(damping_along=250.0, posture_tracking_step=0.0)
    np.testing.assert_allclose(efforts(commands[0]),
                               expected_torque(q, dq, command, wrench, config), atol=1e-9)


@pytest.fixture
def realtime_controller(harness_factory):
    """Return the left controller in realtime (it answers each joint state) with diagnostics."""
    harness = controller_harness(harness_factory, False)
    harness.record(contract.DIAGNOSTICS)
    harness.connect()
    return harness


def reordered_joint_state(t_ns, q, dq, order, extra=()):
    """Return the left arm's joint state with its joints in `order`, then `extra` joints."""
    msg = joint_state(t_ns, q, dq)
    names = contract.joint_names('left')
    msg.name = [names[i] for i in order] + list(extra)
    msg.position = [float(q[i]) for i in order] + [9.0] * len(extra)
    msg.velocity = [float(dq[i]) for i in order] + [-9.0] * len(extra)
    msg.effort = [0.0] * (len(order) + len(extra))
    return msg


def answer_to(controller, msg):
    """Send a joint state to the realtime controller; return its torque command."""
    commands = controller.received['/left/torque_command']
    count = len(commands)
    controller.send('/left/joint_states', msg)
    assert controller.spin_until(lambda: len(commands) == count + 1)
    return commands[-1]


def test_joint_states_in_any_order_give_the_same_command(realtime_controller):
    q, dq, _, _ = controller_inputs(4)
    for k, order in enumerate(([6, 5, 4, 3, 2, 1, 0], [3, 0, 6, 1, 5, 2, 4])):
        command = answer_to(realtime_controller, reordered_joint_state(2_000_000 * k, q, dq,
                                                                       order))
        assert command.name == contract.joint_names('left')
        np.testing.assert_allclose(efforts(command), expected_hold(q, dq), rtol=0.0, atol=1e-9)
    assert realtime_controller.node.step.refusals.total == 0


def test_extra_joints_in_a_joint_state_are_ignored(realtime_controller):
    q, dq, _, _ = controller_inputs(5)
    msg = reordered_joint_state(0, q, dq, [2, 0, 1, 3, 4, 5, 6],
                                extra=['left_gripper_finger', 'right_A1'])
    command = answer_to(realtime_controller, msg)
    np.testing.assert_allclose(efforts(command), expected_hold(q, dq), rtol=0.0, atol=1e-9)
    assert realtime_controller.node.step.refusals.total == 0


def test_a_joint_state_missing_a_joint_is_refused_and_counted(realtime_controller):
    """No command answers it; the refusal is counted and reported on /diagnostics."""
    controller, node = realtime_controller, realtime_controller.node
    commands, reports = (controller.received['/left/torque_command'],
                         controller.received['/diagnostics'])
    q, dq, _, _ = controller_inputs(6)
    answer_to(controller, joint_state(0, q, dq))
    missing_a4 = reordered_joint_state(2_000_000, q, dq, [0, 1, 2, 4, 5, 6], extra=['right_A4'])
    controller.send('/left/joint_states', missing_a4)
    assert controller.spin_until(lambda: node.step.refusals.counts.get('joint_state') == 1)
    controller.spin_quietly()
    assert len(commands) == 1
    period_ns = seconds_to_ns(node.get_parameter('diagnostics_period').value)
    answer_to(controller, joint_state(period_ns, q, dq))
    assert controller.spin_until(lambda: len(reports) == 2)
    values = {pair.key: pair.value for pair in reports[-1].status[0].values}
    assert values['refused_joint_state'] == '1'
    assert reports[-1].status[0].level == DiagnosticStatus.WARN


def test_the_realtime_controller_reports_the_mean_lag_of_its_ds_commands(realtime_controller):
    """
    Tick 0's command is used on cycles 0-4 and, tick 6's not there yet, on cycle 6 (6 ms old).

    The first report went out on cycle 0 (lag 0); the next, a diagnostics period later, gives
    the mean lag of cycles 2, 4 and 6: 2 ms (its own cycle holds: the command is stale by then).
    """
    controller, node = realtime_controller, realtime_controller.node
    reports = controller.received['/diagnostics']
    q, dq, _, _ = controller_inputs(6)
    controller.send('/left/ds_command', ds_command(0, np.zeros(3), np.zeros(3), np.eye(3)))
    assert controller.spin_until(lambda: node.step.counters['ds_commands_received'] == 1)
    for cycle_ms in (0, 2, 4, 6):
        answer_to(controller, joint_state(cycle_ms * 1_000_000, q, dq))
    period_ns = seconds_to_ns(node.get_parameter('diagnostics_period').value)
    assert period_ns > 6_000_000
    answer_to(controller, joint_state(6_000_000 + period_ns - period_ns % 10_000_000, q, dq))
    assert controller.spin_until(lambda: len(reports) == 2)
    first, last = ({pair.key: pair.value for pair in report.status[0].values}
                   for report in reports)
    assert float(first[DS_COMMAND_LAG_KEY]) == 0.0
    assert float(last[DS_COMMAND_LAG_KEY]) == pytest.approx(2.0)


@pytest.mark.parametrize('lockstep', [True, False], ids=['lockstep', 'realtime'])
def test_sensor_subscriptions_are_best_effort_and_commands_keep_one(harness_factory, lockstep):
    """
    A best-effort driver connects to every sensor input; commands keep only the newest.

    In lockstep the commands are delivered reliably (every stamp is waited for); in realtime
    every volatile input is taken best effort, the newest only, and the latched landing target
    stays reliable so a late joiner still gets it.
    """
    node = harness_factory(controller_node(lockstep)).node
    qos = {sub.topic_name: sub.qos_profile for sub in node.subscriptions}
    sensor = qos['/left/joint_states']
    assert sensor.reliability == ReliabilityPolicy.BEST_EFFORT
    assert sensor.depth == (contract.SENSOR_SUBSCRIPTION_DEPTH if lockstep else 1) <= 10
    command_reliability = (ReliabilityPolicy.RELIABLE if lockstep
                           else ReliabilityPolicy.BEST_EFFORT)
    for name in ('/left/ds_command', '/left/contact_wrench'):
        assert qos[name].reliability == command_reliability and qos[name].depth == 1
    for topic in (contract.FT_WRENCH, contract.MOCAP_OBJECT_POSE):
        assert topic.subscription_qos(lockstep).reliability == ReliabilityPolicy.BEST_EFFORT
    assert contract.TORQUE_COMMAND.subscription_qos(lockstep).depth == (
        contract.TORQUE_COMMAND_SUBSCRIPTION_DEPTH if lockstep else 1)
    assert contract.TORQUE_COMMAND.subscription_qos(lockstep).reliability == command_reliability
    assert contract.LANDING_TARGET.subscription_qos(lockstep).reliability == (
        ReliabilityPolicy.RELIABLE)


# -- wrench_qp -----------------------------------------------------------------------------------

def tool_poses():
    """Return {arm: (p_world_tool, R_world_tool)} of both arms at home."""
    return {arm: arm_model(arm, CELL).tool_pose(CELL.arm(arm).q_home) for arm in contract.ARMS}


@pytest.fixture
def wrench_qp(harness_factory):
    """Return a wrench_qp harness whose box spans the gap between the two tools at home."""
    tools = tool_poses()
    gap = tools['left'][0][1] - tools['right'][0][1]
    size = [0.2, float(gap), 0.2]
    harness = harness_factory(lambda context: WrenchQPNode(context=context, parameter_overrides=[
        Parameter('object_size', value=size)]))
    for topic in (contract.OBJECT_STATE, contract.OBJECT_DESIRED_TWIST, contract.PHASE):
        harness.publisher(topic)
    for arm in contract.ARMS:
        harness.publisher(contract.JOINT_STATES, arm)
        harness.record(contract.CONTACT_WRENCH, arm)
    harness.connect()
    harness.p_world_object = 0.5 * (tools['left'][0] + tools['right'][0])
    return harness


def send_tick(harness, t_ns, phase, object_velocity=(0.0, 0.0, 0.0)):
    """Send one DS tick's inputs (object state 5 ms old); return the two published wrenches."""
    count = len(harness.received['/left/contact_wrench'])
    state = contract.OBJECT_STATE.msg_type()
    state.header.stamp = time_msg(t_ns - 5_000_000)
    position = harness.p_world_object - 0.005 * np.asarray(object_velocity)
    state.pose.pose.position.x, state.pose.pose.position.y, state.pose.pose.position.z = (
        float(v) for v in position)
    state.pose.pose.orientation.w = 1.0
    twist = state.twist.twist.linear
    twist.x, twist.y, twist.z = (float(v) for v in object_velocity)
    harness.send('/object/state', state)
    desired = contract.OBJECT_DESIRED_TWIST.msg_type()
    desired.header.stamp = time_msg(t_ns)
    harness.send('/object/desired_twist', desired)
    phase_msg = DiagnosticArray(status=[DiagnosticStatus(
        name='dual_arm/phase', message=phase,
        values=[KeyValue(key='task', value='pick_and_toss'),
                KeyValue(key='time_in_phase', value='0.000000')])])
    phase_msg.header.stamp = time_msg(t_ns)
    harness.send('/dual_arm/phase', phase_msg)
    for arm in contract.ARMS:
        msg = contract.JOINT_STATES.msg_type()
        msg.header.stamp = time_msg(t_ns)
        msg.name = contract.joint_names(arm)
        msg.position = [float(v) for v in CELL.arm(arm).q_home]
        msg.velocity = [0.0] * 7
        harness.send(contract.JOINT_STATES.resolved(arm), msg)
    assert harness.spin_until(
        lambda: all(len(harness.received[contract.CONTACT_WRENCH.resolved(arm)]) > count
                    for arm in contract.ARMS))
    wrenches = {}
    for arm in contract.ARMS:
        msg = harness.received[contract.CONTACT_WRENCH.resolved(arm)][-1]
        assert stamp_ns(msg.header.stamp) == t_ns and msg.header.frame_id == 'world'
        force, torque = msg.wrench.force, msg.wrench.torque
        wrenches[arm] = np.array([force.x, force.y, force.z, torque.x, torque.y, torque.z])
    return wrenches


def test_wrench_qp_zero_outside_grasp_and_squeeze_in_manipulate(wrench_qp):
    mass = object_spec('paper_cube').mass
    t_ns = 0
    for phase in ('standby', 'reach', 'reach'):
        wrenches = send_tick(wrench_qp, t_ns, phase)
        assert all(np.array_equal(w, np.zeros(6)) for w in wrenches.values())
        t_ns += TICK_PERIOD_NS
    for phase in ['contact'] * 2 + ['manipulate'] * 40:
        wrenches = send_tick(wrench_qp, t_ns, phase)
        t_ns += TICK_PERIOD_NS
    tools = tool_poses()
    net_force = wrenches['left'][:3] + wrenches['right'][:3]
    net_moment = sum(wrenches[arm][3:] + np.cross(tools[arm][0] - wrench_qp.p_world_object,
                                                  wrenches[arm][:3]) for arm in contract.ARMS)
    # Left pad on the +y face pushes along -y, the right pad along +y, within the normal-force
    # bounds of a square box's grip; after 42 grasp ticks of 6 ms the 20 ms ramp is complete to
    # exp(-12.6) ~ 3e-6.
    config = wrench_qp.node.config
    floor = wrench_qp.node.step.last_result.normal_force_floor
    assert floor == config.square_grip_force
    assert floor * (1.0 - 1e-5) <= -wrenches['left'][1] <= config.qp.max_normal_force
    assert floor * (1.0 - 1e-5) <= wrenches['right'][1] <= config.qp.max_normal_force
    np.testing.assert_allclose(net_force, [0.0, 0.0, mass * GRAVITY], atol=1e-3)
    np.testing.assert_allclose(net_moment, np.zeros(3), atol=1e-3)
    assert wrench_qp.node.step.counters['infeasible_ticks'] == 0

    wrenches = send_tick(wrench_qp, t_ns, 'release')
    assert all(np.array_equal(w, np.zeros(6)) for w in wrenches.values())

    wrenches = send_tick(wrench_qp, t_ns + TICK_PERIOD_NS, 'dance')
    assert wrench_qp.node.refusals.counts == {'phase': 1}
    assert all(np.array_equal(w, np.zeros(6)) for w in wrenches.values())


def test_wrench_qp_parameters(wrench_qp):
    node = wrench_qp.node
    for name, value, reason in (('qp.min_normal_force', 120.0, 'max_normal_force'),
                                ('ramp_time_constant', 0.0, 'ramp_time_constant'),
                                ('square_grip_force', 105.0, 'square_grip_force'),
                                ('object_mass', -1.0, ''),
                                ('object_size', [0.2, 0.0, 0.2],
                                 'object_size[1] = 0 m is outside (0, 2] m'),
                                ('object_size', [0.2, 0.2], 'object_size'),
                                ('scenario', 'hold', 'read-only')):
        result = set_parameter(node, name, value)
        assert not result.successful and reason in result.reason, (name, result.reason)
    assert set_parameter(node, 'square_grip_yaw', 0.0).successful
    assert set_parameter(node, 'qp.squeeze_force', 86.0).successful
    assert set_parameter(node, 'object_mass', 1.5).successful
    t_ns = 0
    for phase in ['standby'] + ['manipulate'] * 40:
        wrenches = send_tick(wrench_qp, t_ns, phase, object_velocity=(0.0, 0.0, 0.1))
        t_ns += TICK_PERIOD_NS
    assert node.config.qp.squeeze_force == 86.0 and node.step.object_mass == 1.5
    # Net force = m g up minus the object DS damping on the 0.1 m/s upward object velocity.
    net_force = wrenches['left'][:3] + wrenches['right'][:3]
    expected_z = 1.5 * GRAVITY - node.config.object.linear_damping * 0.1
    np.testing.assert_allclose(net_force, [0.0, 0.0, expected_z], atol=1e-3)
    np.testing.assert_allclose([-wrenches['left'][1], wrenches['right'][1]], [86.0, 86.0],
                               atol=1e-3)


# -- ds_motion_generator -------------------------------------------------------------------------

FRI_PERIOD_NS = 2_000_000
AUTO_START_TIME = 0.02


@pytest.fixture
def motion_generator(harness_factory):
    harness = harness_factory(lambda context: DsMotionGenerator(
        context=context, parameter_overrides=[
            Parameter('scenario', value=str(scenario_path('paper_toss'))),
            Parameter('auto_start_time', value=AUTO_START_TIME),
            Parameter('lockstep', value=True)]))
    for arm in contract.ARMS:
        harness.publisher(contract.JOINT_STATES, arm)
        harness.publisher(contract.FT_WRENCH, arm)
        harness.record(contract.DS_COMMAND, arm)
    harness.publisher(contract.OBJECT_STATE)
    harness.record(contract.PHASE)
    harness.connect()
    return harness


def test_with_a_command_key_only_signed_commands_are_a_sign_of_life(harness_factory,
                                                                    monkeypatch):
    """An unsigned torque command (a flood) is no sign of life of a controller."""
    key = 'ab' * 16
    monkeypatch.setenv(COMMAND_KEY_VARIABLE, key)
    harness = harness_factory(lambda context: DsMotionGenerator(
        context=context, parameter_overrides=[
            Parameter('scenario', value=str(scenario_path('paper_toss'))),
            Parameter('lockstep', value=True)]))
    for arm in contract.ARMS:
        harness.publisher(contract.TORQUE_COMMAND, arm)
    harness.connect()
    watch = harness.node.step.controllers
    watch.newly_lost(0, judge=False)
    for arm, signature_key in (('left', None), ('right', key.encode())):
        command = contract.TORQUE_COMMAND.msg_type()
        command.name = contract.joint_names(arm)
        command.effort = [0.0] * 7
        if signature_key is not None:
            command.header.frame_id = command_signature(signature_key, 0, command.name,
                                                        command.effort)
        harness.send(contract.TORQUE_COMMAND.resolved(arm), command)
    assert harness.spin_until(lambda: watch.silence_ns('right', 0) == 0)
    harness.spin_quietly()
    assert watch.silence_ns('left', 0) is None


def controller_report(name, lag_ms):
    """Return a controller's /diagnostics message carrying its mean DS command lag [ms]."""
    return DiagnosticArray(status=[DiagnosticStatus(
        name=name, values=[KeyValue(key='cycles', value='100'),
                           KeyValue(key=DS_COMMAND_LAG_KEY, value=lag_ms)])])


@pytest.mark.parametrize('lockstep', [True, False], ids=['lockstep', 'realtime'])
def test_in_realtime_the_release_leads_by_the_lag_the_controllers_report(harness_factory,
                                                                         lockstep):
    """
    Realtime: the mean of the controllers' reports, a bad one refused; lockstep: none.

    A realtime cycle runs on the left joint state once every input came (depth 1, best effort:
    each cycle is taken in before the next is sent), so the second cycle is the first tick.
    """
    harness = harness_factory(lambda context: DsMotionGenerator(
        context=context, parameter_overrides=[
            Parameter('scenario', value=str(scenario_path('paper_toss'))),
            Parameter('lockstep', value=lockstep)]))
    subscribed = [sub.topic_name for sub in harness.node.subscriptions]
    assert (contract.DIAGNOSTICS.name in subscribed) is not lockstep
    if lockstep:
        return
    for arm in contract.ARMS:
        harness.publisher(contract.JOINT_STATES, arm)
        harness.publisher(contract.FT_WRENCH, arm)
    harness.publisher(contract.OBJECT_STATE)
    harness.publisher(contract.DIAGNOSTICS)
    harness.connect()
    step = harness.node.step
    for name, lag_ms in (('left/passive_controller', '4.0'),
                         ('right/passive_controller', '6.0'),
                         ('right/passive_controller', 'nan')):
        harness.send(contract.DIAGNOSTICS.name, controller_report(name, lag_ms))
    assert harness.spin_until(lambda: step.refusals.counts.get('diagnostics') == 1)
    for t_ns in (0, FRI_PERIOD_NS):
        feed_cycle(harness, t_ns)
        harness.spin_quietly()
    assert step.last_tick is not None
    assert step.command_latency == pytest.approx(0.005)


def feed_cycle(harness, t_ns):
    """Publish one FRI cycle of the resting cell: object estimate, joint states, FT readings."""
    stamp = time_msg(t_ns)
    estimate = contract.OBJECT_STATE.msg_type()
    estimate.header.stamp = stamp
    estimate.header.frame_id = contract.WORLD_FRAME
    fill_odometry(estimate, P_WORLD_OBJECT, np.eye(3), np.zeros(3), np.zeros(3))
    harness.send(contract.OBJECT_STATE.name, estimate)
    for arm in contract.ARMS:
        q_home = CELL.arm(arm).q_home
        harness.send(contract.JOINT_STATES.resolved(arm),
                     joint_state(t_ns, q_home, np.zeros_like(q_home), arm))
        wrench = contract.FT_WRENCH.msg_type()
        wrench.header.stamp = stamp
        harness.send(contract.FT_WRENCH.resolved(arm), wrench)


def run_cycles(harness, count):
    """Feed count cycles from t = 0; return [(phase, stamp, left DS command)] per DS tick."""
    phases = harness.received[contract.PHASE.name]
    commands = harness.received[contract.DS_COMMAND.resolved('left')]
    first_phase, first_command = len(phases), len(commands)
    schedule = TickSchedule(0.005)
    ticks = 0
    for cycle in range(count):
        t_ns = cycle * FRI_PERIOD_NS
        feed_cycle(harness, t_ns)
        if schedule.due(t_ns):
            schedule.take(t_ns)
            ticks += 1
            assert harness.spin_until(lambda: len(commands) - first_command == ticks
                                      and len(phases) - first_phase == ticks), t_ns
    result = []
    for phase, command in zip(phases[first_phase:], commands[first_command:]):
        sample = arm_command_of(command)
        result.append((phase.status[0].message, sample.stamp_ns,
                       (*sample.p_world_attractor, *sample.v_world)))
    return result


def test_motion_generator_starts_over_when_the_clock_goes_back(motion_generator):
    """
    After a simulation reset the DS replays its episode from standby, tick for tick.

    The first pass auto-starts at 20 ms and reaches; the same cycles fed again from t = 0 give
    the same phases and the same commands, because the node rebuilt its generator and armed
    its auto start again instead of carrying on in reach.
    """
    first_pass = run_cycles(motion_generator, 41)
    phases = [phase for phase, _, _ in first_pass]
    assert phases[0] == 'standby' and phases[-1] == 'reach', phases
    moving = [command for phase, _, command in first_pass if phase == 'reach']
    assert max(np.linalg.norm(command[3:]) for command in moving) > 0.0
    second_pass = run_cycles(motion_generator, 41)
    assert second_pass == first_pass


def test_a_landing_target_on_the_topic_replans_the_release_and_a_bad_one_is_counted(
        motion_generator):
    """A world-frame point re-plans the toss; another frame or NaN is refused and counted."""
    publisher = motion_generator.publisher(contract.LANDING_TARGET)
    motion_generator.connect()
    step = motion_generator.node.step
    nominal = step.pending_config.toss.release_position
    target = contract.LANDING_TARGET.msg_type()
    target.header.frame_id = contract.WORLD_FRAME
    target.point.x, target.point.y, target.point.z = 0.95, 0.15, 0.25
    publisher.publish(target)
    assert motion_generator.spin_until(
        lambda: step.pending_config.toss.release_position != nominal)
    planned = step.pending_config.toss
    landing = landing_without_drag(np.asarray(planned.release_position),
                                   planned.toss_speed * np.asarray(planned.release_direction),
                                   0.25)
    np.testing.assert_allclose(landing.position[:2], [0.95, 0.15], atol=1e-6)
    target.header.frame_id = 'left_tool'
    publisher.publish(target)
    assert motion_generator.spin_until(
        lambda: step.refusals.counts.get('landing_target', 0) == 1)
    target.header.frame_id = contract.WORLD_FRAME
    target.point.x = float('nan')
    publisher.publish(target)
    assert motion_generator.spin_until(
        lambda: step.refusals.counts.get('landing_target', 0) == 2)
    assert step.pending_config.toss == planned


def test_the_landing_target_parameter_replans_the_release_or_says_why_not(motion_generator):
    """Default: where paper_toss lands; a new point re-plans, one out of reach is refused."""
    node = motion_generator.node
    step = node.step
    scenario = load_scenario(scenario_path('paper_toss'), cell=CELL)
    default = node.get_parameter('landing_target').value
    expected = predicted_landing(*planned_release(scenario, CELL), scenario.object.size[2], CELL)
    np.testing.assert_allclose(default, expected, atol=1e-12)
    nominal = step.pending_config.toss
    [result] = node.set_parameters([Parameter('landing_target', value=[0.95, -0.15, 0.25])])
    assert result.successful, result.reason
    planned = step.pending_config.toss
    assert planned != nominal
    landing = landing_without_drag(np.asarray(planned.release_position),
                                   planned.toss_speed * np.asarray(planned.release_direction),
                                   0.25)
    np.testing.assert_allclose(landing.position[:2], [0.95, -0.15], atol=1e-6)
    [result] = node.set_parameters([Parameter('landing_target', value=[1.6, 0.0, 0.25])])
    assert not result.successful and 'max_release_speed' in result.reason
    assert step.pending_config.toss == planned
    assert list(node.get_parameter('landing_target').value) == [0.95, -0.15, 0.25]
