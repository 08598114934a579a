"""
The graph as users run it: live tuning, clean shutdown, a node that dies, a reset.

Every test starts `dual_arm_bringup` as a real process tree in its own ROS domain and acts on it
from the test process.
"""

import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

from conftest import SOURCE_ROOT
from dual_arm_control import contract
from dual_arm_control.benchmarks.graph_bench import child_pids
from dual_arm_control.nodes.messages import stamp_ns
from graph_helpers import GraphProbe
import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from std_srvs.srv import Trigger

pytestmark = pytest.mark.slow
BRINGUP = Path(sys.executable).parent / 'dual_arm_bringup'
SHUTDOWN_LIMIT = 5.0


def alive(pid):
    """Return True if a process exists and is not a zombie."""
    try:
        return Path(f'/proc/{pid}/stat').read_text().split(') ')[1][0] != 'Z'
    except (OSError, IndexError):
        return False


def start_launcher(tmp_path, *arguments):
    out = tmp_path / 'run'
    domain = os.environ['ROS_DOMAIN_ID']
    process = subprocess.Popen([str(BRINGUP), '--out', str(out), '--domain-id', domain,
                                *arguments],
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                               env=dict(os.environ), cwd=tmp_path)
    return process, out


def wait_for_child_pids(process, count, timeout=30.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        pids = child_pids(process.pid)
        if len(pids) >= count:
            return pids
        time.sleep(0.1)
    raise AssertionError(f'launcher started {child_pids(process.pid)}, expected {count} nodes')


def stop(process):
    if process.poll() is None:
        process.kill()
    return process.communicate(timeout=30)[0]


def test_sigterm_stops_every_node_within_five_seconds(tmp_path, ros_domain):
    process, _ = start_launcher(tmp_path)
    try:
        pids = wait_for_child_pids(process, 6)
        time.sleep(3.0)
        assert process.poll() is None, 'the graph must keep running without a scenario'
        started = time.monotonic()
        process.send_signal(signal.SIGTERM)
        process.wait(timeout=SHUTDOWN_LIMIT + 5.0)
        assert time.monotonic() - started <= SHUTDOWN_LIMIT
        assert not [pid for pid in pids if alive(pid)], 'orphaned node processes'
    finally:
        stop(process)


def test_a_dying_node_stops_the_graph_with_a_failure(tmp_path, ros_domain):
    process, out = start_launcher(tmp_path, '--scenario',
                                  str(SOURCE_ROOT / 'config' / 'scenarios' / 'paper_toss.yaml'))
    try:
        pids = wait_for_child_pids(process, 6)
        time.sleep(2.0)
        controller = next(pid for pid in pids if 'right' in Path(
            f'/proc/{pid}/cmdline').read_text().replace('\0', ' '))
        os.kill(controller, signal.SIGKILL)
        started = time.monotonic()
        code = process.wait(timeout=SHUTDOWN_LIMIT + 5.0)
        assert time.monotonic() - started <= SHUTDOWN_LIMIT
        assert code != 0
        assert not [pid for pid in pids if alive(pid)]
        assert not (out / 'metrics.json').exists()
    finally:
        print(stop(process))


def test_live_impact_speed_changes_the_measured_impact(tmp_path, ros_domain):
    params = tmp_path / 'params.yaml'
    params.write_text('ds_motion_generator:\n  ros__parameters:\n    auto_start_time: 0.0\n'
                      'sim_bridge:\n  ros__parameters:\n    duration: 30.0\n')
    process, _ = start_launcher(
        tmp_path, '--scenario', str(SOURCE_ROOT / 'config' / 'scenarios' / 'paper_toss.yaml'),
        '--params', str(params))
    probe = GraphProbe(ros_domain, 'parameter_tuner')
    try:
        wait_for_child_pids(process, 6)
        tool_velocity, first_contact = {}, []

        def on_tool(msg):
            v = msg.twist.twist.linear
            tool_velocity[stamp_ns(msg.header.stamp)] = np.array([v.x, v.y, v.z])

        def on_pad(msg):
            f = msg.wrench.force
            if not first_contact and np.linalg.norm([f.x, f.y, f.z]) > 0.0:
                first_contact.append(stamp_ns(msg.header.stamp))

        node = probe.node
        node.create_subscription(contract.GROUND_TRUTH_TOOL.msg_type,
                                 contract.GROUND_TRUTH_TOOL.resolved('left'), on_tool, 100)
        node.create_subscription(contract.GROUND_TRUTH_PAD_WRENCH.msg_type,
                                 contract.GROUND_TRUTH_PAD_WRENCH.resolved('left'), on_pad, 100)
        client = AsyncParameterClient(node, 'ds_motion_generator')
        assert probe.spin_until(lambda: client.services_are_ready(), 30.0)
        refused = client.set_parameters([Parameter('impact.region.normal_distance',
                                                   Parameter.Type.DOUBLE, -0.01)])
        assert probe.spin_until(refused.done, 10.0)
        result = refused.result().results[0]
        assert not result.successful and 'normal_distance' in result.reason
        accepted = client.set_parameters([Parameter('impact.impact_speed',
                                                    Parameter.Type.DOUBLE, 0.3)])
        assert probe.spin_until(accepted.done, 10.0)
        assert accepted.result().results[0].successful
        start = node.create_client(Trigger, contract.START_EPISODE_SERVICE)
        assert start.wait_for_service(timeout_sec=10.0)
        response = start.call_async(Trigger.Request())
        assert probe.spin_until(response.done, 10.0) and response.result().success
        assert probe.spin_until(lambda: bool(first_contact), 60.0), 'no contact'
        before = max(s for s in tool_velocity if s < first_contact[0])
        impact_speed = np.linalg.norm(tool_velocity[before])
        print(f'impact speed with impact.impact_speed = 0.3 m/s: {impact_speed:.3f} m/s')
        assert impact_speed == pytest.approx(0.3, rel=0.15)
    finally:
        probe.close()
        print(stop(process)[-3000:])


def test_a_controller_that_missed_the_first_tick_catches_up(tmp_path, ros_domain):
    """
    Lockstep recovers when a controller joins after the DS and QP answered the first tick.

    The bridge starts without waiting for the graph; the right controller starts only once the
    bridge reports that it waits for it. The bridge then republishes the cycle's whole state,
    the DS and the wrench QP answer the repeated tick again, and the run completes.
    """
    from dual_arm_control.bringup import Launcher
    from dual_arm_control.graph import full_graph, run_parameters
    from dual_arm_control.resources import config_path
    parameters = run_parameters('full', config_path('scenarios', 'paper_toss.yaml'), 'lockstep')
    parameters['sim_bridge'].pop('wait_for_nodes')
    parameters['sim_bridge']['duration'] = 0.1
    late = [spec for spec in full_graph() if spec.label == 'right_passive_controller']
    early = [spec for spec in full_graph() if spec not in late]
    graph = Launcher(early, tmp_path, ros_domain, node_parameters=parameters)
    late_controller = Launcher(late, tmp_path, ros_domain, node_parameters=parameters)
    bridge_log = tmp_path / 'logs' / 'sim_bridge.log'
    try:
        graph.start()
        deadline = time.monotonic() + 60.0
        while "stamped 0 s from ['right']" not in bridge_log.read_text():
            assert time.monotonic() < deadline and 'sim_bridge' not in graph.poll(), (
                bridge_log.read_text())
            time.sleep(0.2)
        late_controller.start()
        deadline = time.monotonic() + 60.0
        while 'sim_bridge' not in graph.poll() and time.monotonic() < deadline:
            time.sleep(0.2)
        assert graph.poll().get('sim_bridge') == 0, bridge_log.read_text()
    finally:
        late_controller.stop()
        graph.stop()


def test_sim_reset_replays_the_episode_in_every_node(tmp_path, ros_domain):
    """
    /sim/reset in a lockstep run starts the whole graph over: the episode repeats exactly.

    Reset once the toss is done (2.3 s, in retract; the run would end at 4 s). The bridge,
    tracker, DS, QP and both controllers all restart on the clock going back, so the second
    episode goes through the same phases at the same sim times to the millisecond, and its
    metrics (the bridge's log restarted at the reset) are a success.
    """
    reset_time_ns = 2_300_000_000
    params = tmp_path / 'params.yaml'
    params.write_text('sim_bridge:\n  ros__parameters:\n    duration: 4.0\n')
    process, out = start_launcher(
        tmp_path, '--scenario', str(SOURCE_ROOT / 'config' / 'scenarios' / 'paper_toss.yaml'),
        '--params', str(params))
    probe = GraphProbe(ros_domain, 'reset_caller')
    episodes = [[]]
    clock = []

    def on_phase(msg):
        t_ns, phase = stamp_ns(msg.header.stamp), msg.status[0].message
        if episodes[-1] and t_ns < episodes[-1][-1][0]:
            episodes.append([])
        if not episodes[-1] or episodes[-1][-1][1] != phase:
            episodes[-1].append((t_ns, phase))

    try:
        node = probe.node
        # The publishers' depth: joining the running graph late, the probe still gets every
        # phase from t = 0 (the latched history) and loses none while it lags.
        node.create_subscription(contract.PHASE.msg_type, contract.PHASE.name, on_phase,
                                 contract.PHASE.publisher_qos)
        node.create_subscription(contract.CLOCK.msg_type, contract.CLOCK.name,
                                 lambda msg: clock.append(stamp_ns(msg.clock)), contract.CLOCK.qos)
        reset = node.create_client(Trigger, contract.SIM_RESET_SERVICE)
        assert probe.spin_until(reset.service_is_ready, 60.0)
        assert probe.spin_until(lambda: clock and clock[-1] >= reset_time_ns, 120.0), clock[-1:]
        response = reset.call_async(Trigger.Request())
        assert probe.spin_until(response.done, 10.0) and response.result().success
        assert probe.spin_until(lambda: process.poll() is not None, 120.0)
    finally:
        probe.close()
        log = stop(process)
    assert process.returncode == 0, log[-3000:]
    first, second = episodes
    print(f'phases before the reset: {first}\nphases after: {second}')
    assert [phase for _, phase in first[:6]] == [
        'standby', 'reach', 'contact', 'manipulate', 'release', 'retract']
    assert second[:6] == first[:6]
    metrics = json.loads((out / 'metrics.json').read_text())
    assert metrics['success'], metrics
