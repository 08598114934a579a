"""
The bridge and the test controllers as separate processes, talking over DDS.

Each test runs the real console scripts in its own ROS domain and reads the ground truth from
the bridge's trajectory log. Lockstep runs are deterministic, so exact counts are asserted there.
"""

import math
import signal

from dual_arm_control import contract
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.graph import CONTROLLER_PRIORITY, ROBOT_PRIORITY
from dual_arm_control.scenario import load_scenario
from dual_arm_control.trajectory_log import load_trajectory
from graph_helpers import GraphProbe, ProcessGroup
import numpy as np
import pytest
from sensor_msgs.msg import JointState

FRI_PERIOD = 0.002
REASONS = ('non_finite', 'wrong_length', 'joint_names')
HOLD_TOLERANCE = 1e-3
BRIDGE_TIMEOUT = 45.0


def tool_drift(data, arm, rows=slice(None)):
    """Return the largest distance [m] of the tool from its initial position over rows."""
    positions = data[f'{arm}_tool_position']
    return float(np.max(np.linalg.norm(positions[rows] - positions[0], axis=1)))


def controller_nodes(arms):
    """Return the full names of the test controllers of the arms (for wait_for_nodes)."""
    return [f'/{arm}/gravity_comp_controller' for arm in arms]


def run_lockstep(tmp_path, ros_domain, name, duration, controller_modes,
                 controller_parameters=None, **bridge_parameters):
    """
    Run the bridge in lockstep with one controller process per arm; return the log.

    The first state waits for the controllers, so a deadline (lockstep_answer_timeout) cannot
    expire while a controller process is still starting on a loaded machine.
    """
    log_path = tmp_path / f'{name}.npz'
    controller_parameters = controller_parameters or {}
    with ProcessGroup(tmp_path, ros_domain) as graph:
        for arm, mode in controller_modes.items():
            graph.start_controller(arm, mode=mode, **controller_parameters.get(arm, {}))
        graph.start_bridge(duration=duration, trajectory_log=str(log_path),
                           wait_for_nodes=controller_nodes(controller_modes), **bridge_parameters)
        exit_code = graph.wait('sim_bridge', BRIDGE_TIMEOUT)
        assert exit_code == 0, graph.log('sim_bridge')
    return load_trajectory(log_path)


def test_gravity_compensation_holds_both_arms_for_five_seconds(tmp_path, ros_domain):
    data = run_lockstep(tmp_path, ros_domain, 'hold', 5.0,
                        {'left': 'gravity', 'right': 'gravity'})
    assert data['t'][-1] == pytest.approx(5.0, abs=1e-9)
    assert np.allclose(np.diff(data['t']), FRI_PERIOD, atol=1e-9)
    for arm in contract.ARMS:
        assert tool_drift(data, arm) < HOLD_TOLERANCE, arm
        assert int(data[f'{arm}_commands_accepted']) == 2500
        assert int(data[f'{arm}_watchdog_holds']) == 0
        for reason in REASONS:
            assert int(data[f'{arm}_refused_{reason}']) == 0, (arm, reason)


def test_zero_torque_lets_both_arms_fall(tmp_path, ros_domain):
    data = run_lockstep(tmp_path, ros_domain, 'fall', 1.0, {'left': 'zero', 'right': 'zero'})
    for arm in contract.ARMS:
        height = data[f'{arm}_tool_position'][:, 2]
        assert height[0] - height.min() > 0.05, arm


def test_a_controller_past_its_deadline_gets_its_last_torque_once_then_the_hold(
        tmp_path, ros_domain):
    """
    The FRI deadline policy, deterministic in lockstep.

    The right controller (zero torque: the arm falls) stalls for ten cycles (0.100-0.118 s);
    the bridge waits 0.8 s wall for each (far above a healthy answer's few ms, even on a loaded
    machine), then applies the arm's previous torque (zero) for the
    first missed cycle and the robot's hold (gravity compensation, hold stiffness toward the
    joints of the first missed cycle, hold damping) for the others; then its zero torque again.
    """
    data = run_lockstep(tmp_path, ros_domain, 'stall', 0.2,
                        {'left': 'gravity', 'right': 'zero'}, lockstep_answer_timeout=0.8,
                        controller_parameters={'right': {'mute_window': [0.1, 0.1195]}})
    rows = {round(t * 1e3): row for row, t in enumerate(data['t'])}
    tau, q, dq = (data[f'right_{name}'] for name in ('tau', 'q', 'dq'))
    model = arm_model('right')
    description = load_cell().arm('right')
    # Row k + 1 holds the torque applied during the cycle that starts at row k.
    first_missed = rows[100]
    np.testing.assert_array_equal(tau[1:first_missed + 1], 0.0)
    np.testing.assert_array_equal(tau[first_missed + 1], np.zeros(7))
    assert np.abs(dq[first_missed]).max() > 0.05, 'the arm is falling'
    for row in range(first_missed + 1, rows[118] + 1):
        hold = (model.gravity_torque(q[row]) - description.hold_damping * dq[row]
                + description.hold_stiffness * (q[first_missed] - q[row]))
        np.testing.assert_allclose(tau[row + 1], hold, atol=1e-5)
        assert np.abs(tau[row + 1]).max() > 5.0, row
    # The hold stops the fall: the joints slow down toward where the commands stopped.
    assert np.abs(dq[rows[118]]).max() < 0.5 * np.abs(dq[first_missed + 1]).max()
    np.testing.assert_array_equal(tau[rows[120] + 1], np.zeros(7))
    assert int(data['right_previous_torque_repeats']) == 1
    assert int(data['right_watchdog_holds']) == 9
    assert int(data['left_watchdog_holds']) == int(data['left_previous_torque_repeats']) == 0


def test_lockstep_runs_are_bit_identical(tmp_path, ros_domain):
    modes = {'left': 'gravity', 'right': 'zero'}
    first = run_lockstep(tmp_path, ros_domain, 'first', 1.0, modes, publish_ground_truth=False)
    second = run_lockstep(tmp_path, ros_domain, 'second', 1.0, modes, publish_ground_truth=False)
    assert np.ptp(first['right_q'], axis=0).max() > 0.05, 'the falling arm must move'
    for key in ('t', 'object_position', 'object_quat_xyzw') + tuple(
            f'{arm}_{name}' for arm in contract.ARMS
            for name in ('q', 'dq', 'tau', 'tool_position', 'pad_force')):
        assert np.array_equal(first[key], second[key]), key


BAD_COMMANDS = ('nan', 'inf', 'short', 'long', 'unknown_names', 'duplicate_names', 'no_names')
REASON_OF = {'nan': 'non_finite', 'inf': 'non_finite', 'short': 'wrong_length',
             'long': 'wrong_length', 'unknown_names': 'joint_names',
             'duplicate_names': 'joint_names', 'no_names': 'joint_names'}
BAD_CYCLES = 350
OVER_LIMIT_CYCLES = 10
BAD_RUN_CYCLES = 400


def command_kind(cycle):
    """Return what the misbehaving right controller sends for a cycle index."""
    if cycle < BAD_CYCLES:
        return BAD_COMMANDS[cycle % len(BAD_COMMANDS)]
    if cycle < BAD_CYCLES + OVER_LIMIT_CYCLES:
        return 'over_limit'
    return 'nan'


def bad_command(kind, stamp, names, torque_limits):
    """Return the JointState the misbehaving controller sends."""
    names = list(names)
    efforts = [0.0] * len(names)
    if kind == 'nan':
        efforts[3] = math.nan
    elif kind == 'inf':
        efforts[0] = -math.inf
    elif kind == 'short':
        efforts = efforts[:-1]
    elif kind == 'long':
        efforts = efforts + [0.0]
    elif kind == 'unknown_names':
        names[6] = 'right_A8'
    elif kind == 'duplicate_names':
        names[1] = names[0]
    elif kind == 'no_names':
        names = []
    elif kind == 'over_limit':
        efforts = (1.5 * np.asarray(torque_limits)).tolist()
    msg = JointState(name=names, effort=efforts)
    msg.header.stamp = stamp
    return msg


def expected_counts(cycles):
    """Return {reason: refusals} and the clamp count of the first `cycles` cycles."""
    refused = dict.fromkeys(REASONS, 0)
    clamps = 0
    for cycle in range(cycles):
        kind = command_kind(cycle)
        if kind == 'over_limit':
            clamps += 1
        else:
            refused[REASON_OF[kind]] += 1
    return refused, clamps


def assert_bridge_finishes(probe, graph):
    """Spin the probe until the bridge process exits; assert it exited 0 (else show its log)."""
    assert probe.spin_until(lambda: graph.poll('sim_bridge') is not None, BRIDGE_TIMEOUT)
    assert graph.poll('sim_bridge') == 0, graph.log('sim_bridge')


def diagnostics_values(msg, status_name):
    """Return {key: int} of one status of a DiagnosticArray."""
    status = next(s for s in msg.status if s.name == status_name)
    return {kv.key: int(kv.value) for kv in status.values if kv.value.lstrip('-').isdigit()}


def test_bad_commands_are_refused_counted_and_the_arm_holds(tmp_path, ros_domain):
    log_path = tmp_path / 'bad.npz'
    names = contract.joint_names('right')
    torque_limits = arm_model('right').torque_limits
    probe = GraphProbe(ros_domain)
    period_ns = round(FRI_PERIOD * 1e9)
    diagnostics = {}

    def answer(state):
        cycle = (state.header.stamp.sec * 10**9 + state.header.stamp.nanosec) // period_ns
        command_pub.publish(bad_command(command_kind(cycle), state.header.stamp, names,
                                        torque_limits))

    def keep_diagnostics(msg):
        diagnostics[msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec] = msg

    command_pub = probe.node.create_publisher(
        JointState, contract.TORQUE_COMMAND.resolved('right'), contract.TORQUE_COMMAND.qos)
    probe.node.create_subscription(JointState, contract.JOINT_STATES.resolved('right'), answer,
                                   contract.JOINT_STATES.qos)
    probe.node.create_subscription(contract.DIAGNOSTICS.msg_type, contract.DIAGNOSTICS.name,
                                   keep_diagnostics, contract.DIAGNOSTICS.qos)
    try:
        with ProcessGroup(tmp_path, ros_domain) as graph:
            graph.start_controller('left', mode='gravity')
            graph.start_bridge(duration=BAD_RUN_CYCLES * FRI_PERIOD, diagnostics_period=0.1,
                               trajectory_log=str(log_path), publish_ground_truth=False)
            assert_bridge_finishes(probe, graph)
    finally:
        probe.close()
    data = load_trajectory(log_path)
    hold_rows = data['t'] <= BAD_CYCLES * FRI_PERIOD + 1e-9
    assert tool_drift(data, 'right', hold_rows) < HOLD_TOLERANCE
    assert tool_drift(data, 'left') < HOLD_TOLERANCE
    refused, clamps = expected_counts(BAD_RUN_CYCLES)
    for reason, count in refused.items():
        assert int(data[f'right_refused_{reason}']) == count, reason
        assert int(data[f'left_refused_{reason}']) == 0, reason
    assert int(data['right_torque_clamps']) == clamps == OVER_LIMIT_CYCLES
    assert int(data['left_torque_clamps']) == 0
    # Row k + 1 of the log holds the torque applied during cycle k (row 0: the initial state).
    over_limit_rows = slice(BAD_CYCLES + 1, BAD_CYCLES + 1 + OVER_LIMIT_CYCLES)
    assert np.array_equal(data['right_tau'][over_limit_rows],
                          np.tile(torque_limits, (OVER_LIMIT_CYCLES, 1)))
    # /diagnostics at sim time 0.5 s counts the answers to the cycles 0..249.
    half_way = 500_000_000
    assert half_way in diagnostics, sorted(diagnostics)
    values = diagnostics_values(diagnostics[half_way], 'sim_bridge: right arm')
    refused, _ = expected_counts(250)
    for reason, count in refused.items():
        assert values[f'refused_{reason}'] == count, reason
    assert values['torque_clamps'] == 0
    assert diagnostics_values(diagnostics[half_way], 'sim_bridge')['cycles'] == 250


def test_realtime_watchdog_holds_an_arm_whose_controller_stops(tmp_path, ros_domain):
    log_path = tmp_path / 'realtime.npz'
    # Long enough that a probe discovering the bridge seconds late still sees it run.
    duration = 8.0
    probe = GraphProbe(ros_domain)
    sim_time = []
    probe.node.create_subscription(
        contract.CLOCK.msg_type, contract.CLOCK.name,
        lambda msg: sim_time.append(msg.clock.sec + 1e-9 * msg.clock.nanosec), contract.CLOCK.qos)
    try:
        with ProcessGroup(tmp_path, ros_domain) as graph:
            # Scheduled as dual_arm_bringup schedules a realtime graph (SCHED_FIFO), so the
            # test measures the watchdog, not the other tests' leftover load on 2 cores.
            for arm in contract.ARMS:
                graph.start_controller(arm, realtime_priority=CONTROLLER_PRIORITY,
                                       mode='gravity')
            graph.start_bridge(realtime_priority=ROBOT_PRIORITY, mode='realtime',
                               duration=duration, trajectory_log=str(log_path),
                               publish_ground_truth=False,
                               wait_for_nodes=controller_nodes(contract.ARMS))
            assert probe.spin_until(lambda: sim_time and sim_time[-1] >= 1.0, BRIDGE_TIMEOUT), (
                graph.log('sim_bridge'))
            assert sim_time[-1] < duration - 2.0, 'the probe saw the bridge too late'
            graph.stop('right_controller')
            stopped_at = sim_time[-1]
            assert_bridge_finishes(probe, graph)
    finally:
        probe.close()
    data = load_trajectory(log_path)
    silent_cycles = (duration - stopped_at) / FRI_PERIOD
    right_holds = int(data['right_watchdog_holds'])
    assert right_holds >= 0.8 * silent_cycles
    assert right_holds <= int(data['cycles'])
    assert int(data['left_commands_accepted']) > 0.5 * int(data['cycles'])
    assert tool_drift(data, 'right') < HOLD_TOLERANCE
    assert tool_drift(data, 'left') < HOLD_TOLERANCE


def stamp_of(msg):
    """Return a message's header stamp in integer nanoseconds."""
    return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec


def test_mocap_and_ground_truth_topics_agree_with_the_log(tmp_path, ros_domain):
    scenario = load_scenario('cube_drop')
    mocap = scenario.sensors.mocap
    log_path = tmp_path / 'cube_drop.npz'
    duration = 1.0
    probe = GraphProbe(ros_domain)
    received = {'mocap': [], 'object': [], 'left_tool': [], 'right_pad': []}
    subscriptions = [
        probe.node.create_subscription(topic.msg_type, topic.resolved(arm), received[key].append,
                                       topic.qos)
        for key, topic, arm in (('mocap', contract.MOCAP_OBJECT_POSE, None),
                                ('object', contract.GROUND_TRUTH_OBJECT, None),
                                ('left_tool', contract.GROUND_TRUTH_TOOL, 'left'),
                                ('right_pad', contract.GROUND_TRUTH_PAD_WRENCH, 'right'))]
    try:
        with ProcessGroup(tmp_path, ros_domain) as graph:
            graph.start_bridge(scenario=str(scenario.path), duration=duration,
                               trajectory_log=str(log_path), ground_truth_period=0.0)
            # Lockstep waits for the controllers only: connect the observers before they start.
            assert probe.spin_until(
                lambda: all(sub.get_publisher_count() > 0 for sub in subscriptions),
                BRIDGE_TIMEOUT)
            for arm in contract.ARMS:
                graph.start_controller(arm, mode='gravity')
            assert_bridge_finishes(probe, graph)
    finally:
        probe.close()
    data = load_trajectory(log_path)
    row_of_stamp = {round(t * 1e9): row for row, t in enumerate(data['t'])}
    assert data['object_position'][0, 2] - data['object_position'][-1, 2] > 0.04, 'it fell'

    # Ground truth: each cycle (the initial state may precede discovery), the logged values.
    for msg in received['object']:
        p = msg.pose.pose.position
        assert [p.x, p.y, p.z] == data['object_position'][row_of_stamp[stamp_of(msg)]].tolist()
    for msg in received['left_tool']:
        p, v = msg.pose.pose.position, msg.twist.twist.linear
        row = row_of_stamp[stamp_of(msg)]
        assert [p.x, p.y, p.z] == data['left_tool_position'][row].tolist()
        assert [v.x, v.y, v.z] == data['left_tool_velocity'][row].tolist()
    for key in ('object', 'left_tool', 'right_pad'):
        assert 0.9 * len(data['t']) < len(received[key]) <= len(data['t']), key
    for msg in received['right_pad']:
        force = msg.wrench.force
        assert [force.x, force.y, force.z] == data['right_pad_force'][
            row_of_stamp[stamp_of(msg)]].tolist() == [0.0, 0.0, 0.0]

    # Mocap: stamped with the sampling time, within the noise of the ground truth.
    sampled = (duration - mocap.latency) * mocap.rate_hz
    samples = received['mocap']
    assert (1.0 - mocap.dropout_probability) * sampled * 0.85 < len(samples) <= sampled + 1
    errors = np.array([
        np.array([msg.pose.position.x, msg.pose.position.y, msg.pose.position.z])
        - data['object_position'][row_of_stamp[stamp_of(msg)]]
        for msg in samples if stamp_of(msg) in row_of_stamp])
    assert len(errors) > 50
    sigma = mocap.position_noise
    assert np.abs(errors).max() < 5.0 * sigma
    assert 0.7 * sigma < errors.std() < 1.3 * sigma
    assert np.abs(errors.mean(axis=0)).max() < 4.0 * sigma / np.sqrt(len(errors))


def test_sigterm_stops_the_bridge_cleanly_and_writes_the_log(tmp_path, ros_domain):
    log_path = tmp_path / 'stopped.npz'
    probe = GraphProbe(ros_domain)
    states = []
    probe.node.create_subscription(JointState, contract.JOINT_STATES.resolved('left'),
                                   states.append, contract.JOINT_STATES.qos)
    try:
        with ProcessGroup(tmp_path, ros_domain) as graph:
            bridge = graph.start_bridge(trajectory_log=str(log_path))
            assert probe.spin_until(lambda: states, BRIDGE_TIMEOUT)
            bridge.send_signal(signal.SIGTERM)
            assert graph.wait('sim_bridge', BRIDGE_TIMEOUT) == 0, graph.log('sim_bridge')
    finally:
        probe.close()
    data = load_trajectory(log_path)
    assert data['t'].tolist() == [0.0], 'no controller answered: the twin stayed at t = 0'
    assert int(data['cycles']) == 0
