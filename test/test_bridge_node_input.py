"""
The bridge node in one process: command validation, lockstep hand-shake, parameters, services.

The node runs with the real twin on an isolated rclpy context; a second node in the same
executor plays the controllers, so each step of the lockstep protocol can be checked.
"""

import math

from dual_arm_control import contract
from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.nodes.command_signature import COMMAND_KEY_VARIABLE, command_signature
from dual_arm_control.nodes.messages import stamp_ns, time_msg
from dual_arm_control.resources import config_path
from dual_arm_control.runtime.fri import command_refusal
from dual_arm_control.runtime.node_settings import node_table
from graph_helpers import GraphProbe
import numpy as np
import pytest
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from sim_bridge.bridge_node import SimBridge
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

NAMES = contract.joint_names('left')
SPIN_TIMEOUT = 10.0


@pytest.mark.parametrize('names, efforts, reason', [
    (NAMES, [0.0] * 7, None),
    (NAMES, [1e3, -1e3, 0.0, 0.0, 0.0, 0.0, 0.0], None),
    (NAMES, [0.0] * 6, 'wrong_length'),
    (NAMES, [0.0] * 8, 'wrong_length'),
    ([], [0.0] * 7, 'joint_names'),
    (NAMES[1:] + NAMES[:1], [0.0] * 7, None),
    (NAMES + ['gripper'], [0.0] * 8, None),
    (NAMES[:6] + NAMES[:1], [0.0] * 7, 'joint_names'),
    (contract.joint_names('right'), [0.0] * 7, 'joint_names'),
    (NAMES[:6], [0.0] * 7, 'joint_names'),
    (NAMES, [0.0, math.nan, 0.0, 0.0, 0.0, 0.0, 0.0], 'non_finite'),
    (NAMES, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, math.inf], 'non_finite'),
    (NAMES, [-math.inf] * 7, 'non_finite'),
])
def test_command_refusal_reasons(names, efforts, reason):
    assert command_refusal(names, efforts, NAMES) == reason


@pytest.mark.parametrize('nanoseconds', [0, 1, 999_999_999, 1_000_000_000, 3_002_000_000,
                                         86_400_123_456_789])
def test_time_message_round_trip(nanoseconds):
    assert stamp_ns(time_msg(nanoseconds)) == nanoseconds


@pytest.mark.parametrize('name, value, allowed', [
    ('mode', 'lockstep', True), ('mode', 'realtime', True), ('mode', 'fast', False),
    ('fri_period', 0.002, True), ('fri_period', 0.005, True), ('fri_period', 0.003, False),
    ('duration', 0.0, True), ('duration', -1.0, False),
    ('object_displacement', [0.1, 0.0, -0.2], True),
    ('object_displacement', [0.1, 0.0], False),
    ('object_displacement', [0.0, math.nan, 0.0], False),
    ('object_displacement', [0.0, 0.0, 5.0], False),
    ('scenario', '', False),
])
def test_parameter_validation(name, value, allowed):
    assert (node_table('sim_bridge').setting(name).problem(value) is None) == allowed


@pytest.fixture
def graph(ros_domain):
    """Yield a bridge (lockstep, real twin) and a probe node sharing one executor."""
    probe = GraphProbe(ros_domain)
    bridge = SimBridge(context=probe.context, parameter_overrides=[
        Parameter('publish_ground_truth', value=False)])
    probe.executor.add_node(bridge)
    yield probe, bridge
    probe.executor.remove_node(bridge)
    bridge.destroy_node()
    probe.close()


def test_invalid_fri_period_refuses_to_start(ros_domain):
    probe = GraphProbe(ros_domain)
    try:
        with pytest.raises(ConfigError, match='fri_period must be one of 0.001, 0.002, 0.005 s'):
            SimBridge(context=probe.context,
                      parameter_overrides=[Parameter('fri_period', value=0.003)])
    finally:
        probe.close()


class Controllers:
    """The probe's stand-in for both controllers: remembers states, sends commands."""

    def __init__(self, probe):
        self.states = {arm: [] for arm in contract.ARMS}
        self._pubs = {}
        for arm in contract.ARMS:
            probe.node.create_subscription(
                JointState, contract.JOINT_STATES.resolved(arm),
                lambda msg, arm=arm: self.states[arm].append(msg), contract.JOINT_STATES.qos)
            self._pubs[arm] = probe.node.create_publisher(
                JointState, contract.TORQUE_COMMAND.resolved(arm), contract.TORQUE_COMMAND.qos)

    def send(self, arm, stamp, efforts, names=None, key=None):
        msg = JointState()
        msg.header.stamp = stamp
        msg.name = contract.joint_names(arm) if names is None else names
        msg.effort = [float(value) for value in efforts]
        if key is not None:
            msg.header.frame_id = command_signature(key, stamp_ns(stamp), msg.name, msg.effort)
        self._pubs[arm].publish(msg)


def test_lockstep_advances_only_when_both_arms_answered(graph):
    probe, bridge = graph
    controllers = Controllers(probe)
    assert probe.spin_until(lambda: all(controllers.states.values()), SPIN_TIMEOUT)
    first_stamp = controllers.states['left'][-1].header.stamp
    assert stamp_ns(first_stamp) == 0 and bridge.twin.time == 0.0
    hold = {arm: bridge.twin.hold_torques(arm) for arm in contract.ARMS}

    controllers.send('left', first_stamp, hold['left'])
    assert probe.spin_until(lambda: bridge.fri.counters['left'].accepted == 1, SPIN_TIMEOUT)
    controllers.send('right', time_msg(1_000_000_000), hold['right'])
    assert probe.spin_until(lambda: bridge.fri.counters['right'].ignored == 1, SPIN_TIMEOUT)
    assert bridge.twin.time == 0.0 and bridge.fri.cycles == 0

    controllers.send('right', first_stamp, [math.nan] * 7)
    assert probe.spin_until(lambda: bridge.fri.cycles == 1, SPIN_TIMEOUT)
    assert bridge.twin.time == pytest.approx(bridge.fri_period)
    assert bridge.fri.counters['right'].refused['non_finite'] == 1
    assert probe.spin_until(
        lambda: stamp_ns(controllers.states['right'][-1].header.stamp) == 2_000_000,
        SPIN_TIMEOUT)

    controllers.send('left', first_stamp, hold['left'])
    assert probe.spin_until(lambda: bridge.fri.counters['left'].ignored == 1, SPIN_TIMEOUT)
    assert bridge.fri.cycles == 1


def test_with_a_command_key_a_foreign_command_answers_no_cycle(ros_domain, monkeypatch):
    """Unsigned commands for the cycle (huge, NaN) are dropped; the signed one is applied."""
    key = 'f00d' * 8
    monkeypatch.setenv(COMMAND_KEY_VARIABLE, key)
    probe = GraphProbe(ros_domain)
    bridge = SimBridge(context=probe.context, parameter_overrides=[
        Parameter('publish_ground_truth', value=False)])
    probe.executor.add_node(bridge)
    try:
        controllers = Controllers(probe)
        assert probe.spin_until(lambda: all(controllers.states.values()), SPIN_TIMEOUT)
        stamp = controllers.states['left'][-1].header.stamp
        controllers.send('left', stamp, [1e6] * 7)
        controllers.send('left', stamp, [math.nan] * 7)
        controllers.send('left', stamp, [0.0] * 7, key=b'not the key')
        assert probe.spin_until(lambda: bridge.fri.counters['left'].foreign == 3, SPIN_TIMEOUT)
        assert bridge.fri.missing() == list(contract.ARMS)
        hold = {arm: bridge.twin.hold_torques(arm) for arm in contract.ARMS}
        for arm in contract.ARMS:
            controllers.send(arm, stamp, hold[arm], key=key.encode())
        assert probe.spin_until(lambda: bridge.fri.cycles == 1, SPIN_TIMEOUT)
        left = bridge.fri.counters['left']
        assert left.accepted == 1 and left.clamps == 0 and left.refused['non_finite'] == 0
        assert np.allclose(bridge.fri.applied['left'], hold['left'], rtol=0.0, atol=1e-12)
    finally:
        probe.executor.remove_node(bridge)
        bridge.destroy_node()
        probe.close()


def test_lockstep_republishes_an_unanswered_state(graph):
    probe, bridge = graph
    controllers = Controllers(probe)
    assert probe.spin_until(lambda: len(controllers.states['right']) >= 3, SPIN_TIMEOUT)
    stamps = {stamp_ns(msg.header.stamp) for msg in controllers.states['right']}
    assert stamps == {0} and bridge.fri.cycles == 0


def test_runtime_parameters(graph):
    _, bridge = graph
    refused = bridge.set_parameters([Parameter('object_displacement', value=[0.0, 0.0, 5.0])])
    assert not refused[0].successful and 'object_displacement' in refused[0].reason
    read_only = bridge.set_parameters([Parameter('mode', value='realtime')])
    assert not read_only[0].successful and bridge.mode == 'lockstep'
    accepted = bridge.set_parameters([Parameter('duration', value=2.5)])
    assert accepted[0].successful and bridge.stop_time == 2.5


def call(probe, service_name, timeout=SPIN_TIMEOUT):
    """Call a std_srvs/Trigger service from the probe; return the response."""
    client = probe.node.create_client(Trigger, service_name)
    assert client.wait_for_service(timeout_sec=timeout)
    future = client.call_async(Trigger.Request())
    assert probe.spin_until(future.done, timeout)
    return future.result()


def test_move_object_service_moves_the_object_by_the_parameter(graph):
    probe, bridge = graph
    before, _ = bridge.twin.object_pose()
    displacement = [0.03, -0.02, 0.05]
    assert bridge.set_parameters([Parameter('object_displacement',
                                            value=displacement)])[0].successful
    response = call(probe, contract.SIM_MOVE_OBJECT_SERVICE)
    assert response.success, response.message
    after, _ = bridge.twin.object_pose()
    assert np.allclose(after - before, displacement, atol=1e-9)


def test_reset_service_returns_to_the_initial_state(graph):
    probe, bridge = graph
    controllers = Controllers(probe)
    assert probe.spin_until(lambda: all(controllers.states.values()), SPIN_TIMEOUT)
    initial = {arm: bridge.twin.joint_state(arm).position.copy() for arm in contract.ARMS}
    for arm in contract.ARMS:
        controllers.send(arm, time_msg(0), np.zeros(7))
    assert probe.spin_until(lambda: bridge.fri.cycles == 1, SPIN_TIMEOUT)
    assert bridge.twin.time > 0.0
    response = call(probe, contract.SIM_RESET_SERVICE)
    assert response.success, response.message
    assert bridge.twin.time == 0.0
    for arm in contract.ARMS:
        assert np.array_equal(bridge.twin.joint_state(arm).position, initial[arm])


def test_belt_speed_topic_commands_the_conveyor(ros_domain):
    probe = GraphProbe(ros_domain)
    bridge = SimBridge(context=probe.context, parameter_overrides=[
        Parameter('scenario', value=str(config_path('scenarios', 'conveyor_toss.yaml'))),
        Parameter('lockstep_wait_for_tracker', value=False)])
    probe.executor.add_node(bridge)
    truth = []
    probe.node.create_subscription(contract.GROUND_TRUTH_CONTAINER.msg_type,
                                   contract.GROUND_TRUTH_CONTAINER.name, truth.append,
                                   contract.GROUND_TRUTH_CONTAINER.qos)
    controllers = Controllers(probe)
    try:
        while not truth and bridge.fri.cycles < 20:
            cycles = bridge.fri.cycles
            assert probe.spin_until(lambda: all(
                states and stamp_ns(states[-1].header.stamp) == bridge.fri.awaited_ns
                for states in controllers.states.values()), SPIN_TIMEOUT)
            for arm in contract.ARMS:
                controllers.send(arm, controllers.states[arm][-1].header.stamp,
                                 bridge.twin.hold_torques(arm))
            assert probe.spin_until(lambda: bridge.fri.cycles > cycles, SPIN_TIMEOUT)
        assert probe.spin_until(lambda: truth, SPIN_TIMEOUT)
        assert truth[-1].pose.pose.position.y == pytest.approx(
            bridge.scenario.conveyor.container_start)
        publisher = probe.node.create_publisher(Float64, contract.OUTGOING_BELT_SPEED.name,
                                                contract.OUTGOING_BELT_SPEED.qos)
        assert bridge.twin.container.belt.commanded == pytest.approx(0.25)
        publisher.publish(Float64(data=0.12))
        assert probe.spin_until(
            lambda: bridge.twin.container.belt.commanded == pytest.approx(0.12), SPIN_TIMEOUT)
        publisher.publish(Float64(data=math.nan))
        publisher.publish(Float64(data=0.3))
        assert probe.spin_until(
            lambda: bridge.twin.container.belt.commanded == pytest.approx(0.3), SPIN_TIMEOUT)
    finally:
        probe.executor.remove_node(bridge)
        bridge.destroy_node()
        probe.close()


def test_incoming_belt_speed_topic_commands_the_incoming_belt(ros_domain):
    probe = GraphProbe(ros_domain)
    bridge = SimBridge(context=probe.context, parameter_overrides=[
        Parameter('scenario', value=str(config_path('scenarios', 'conveyor_grab.yaml'))),
        Parameter('lockstep_wait_for_tracker', value=False)])
    probe.executor.add_node(bridge)
    try:
        belt = bridge.twin.incoming_belt
        assert bridge.twin.container is None
        assert belt.belt.commanded == pytest.approx(0.2)
        publisher = probe.node.create_publisher(Float64, contract.INCOMING_BELT_SPEED.name,
                                                contract.INCOMING_BELT_SPEED.qos)
        publisher.publish(Float64(data=0.12))
        assert probe.spin_until(lambda: belt.belt.commanded == pytest.approx(0.12),
                                SPIN_TIMEOUT)
        publisher.publish(Float64(data=math.inf))
        publisher.publish(Float64(data=0.28))
        assert probe.spin_until(lambda: belt.belt.commanded == pytest.approx(0.28),
                                SPIN_TIMEOUT)
    finally:
        probe.executor.remove_node(bridge)
        bridge.destroy_node()
        probe.close()
