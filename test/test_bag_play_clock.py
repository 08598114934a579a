"""
bag_play --clock: /clock from the bag's log time, which a node on sim time follows.

The bag is written with BagWriter: joint states every 10 ms of log time from 5 s on, and a
/clock topic at 1000 s and later that --clock must not play. bag_play runs as a process; a node
with use_sim_time in the test process records /clock and reads its own clock whenever a joint
state arrives.
"""

from pathlib import Path
import subprocess
import sys

from builtin_interfaces.msg import Time
from dual_arm_control import contract
from dual_arm_control.bags.writer import BagWriter
from dual_arm_control.nodes.bag_play import main as bag_play_main
from dual_arm_control.nodes.messages import stamp_ns
from graph_helpers import GraphProbe, ros_environment
import rclpy
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

SCRIPTS = Path(sys.prefix) / 'bin'
MS = 1_000_000
FIRST_NS = 5_000 * MS
RECORDED_CLOCK_NS = 1_000_000 * MS
COUNT = 100
PERIOD_NS = 10 * MS
CLOCK_HZ = 100.0
PLAY_TIMEOUT = 60.0


def time_of(ns):
    """Return builtin_interfaces/Time of a time [ns]."""
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def write_bag(path):
    """Write COUNT joint states (position k at log time FIRST_NS + k PERIOD_NS) and a /clock."""
    with BagWriter(path) as writer:
        writer.add_topic('/clock', Clock, contract.CLOCK.publisher_qos)
        writer.add_topic('/sim/joint_states', JointState, contract.JOINT_STATES.publisher_qos)
        for k in range(COUNT):
            log_time = FIRST_NS + k * PERIOD_NS
            writer.write('/clock', serialize_message(
                Clock(clock=time_of(RECORDED_CLOCK_NS + k * PERIOD_NS))), log_time)
            msg = JointState(name=['a'], position=[float(k)])
            msg.header.stamp = time_of(k * PERIOD_NS)
            writer.write('/sim/joint_states', serialize_message(msg), log_time + 1000)


def test_clock_follows_the_bag_log_time_and_drives_a_sim_time_node(tmp_path, ros_domain):
    """
    /clock runs from the bag's first to its last log time at about CLOCK_HZ, never back.

    A node on sim time reads, when joint state k arrives, a time at most one clock period and
    the delivery delay behind the joint state's log time (100 ms allowed on a loaded machine)
    and not ahead of it by more than a period. The bag's own /clock (1000 s) is not played.
    """
    bag = tmp_path / 'bag.mcap'
    write_bag(bag)
    probe = GraphProbe(ros_domain, 'clock_probe')
    node = rclpy.create_node('sim_time_node', context=probe.context, parameter_overrides=[
        Parameter('use_sim_time', value=True)])
    probe.executor.add_node(node)
    clocks, readings = [], []
    node.create_subscription(Clock, '/clock', lambda msg: clocks.append(stamp_ns(msg.clock)),
                             contract.CLOCK.qos)
    node.create_subscription(
        JointState, '/sim/joint_states',
        lambda msg: readings.append((int(msg.position[0]), node.get_clock().now().nanoseconds)),
        contract.CONTROL_QOS)
    try:
        player = subprocess.Popen(
            [str(SCRIPTS / 'bag_play'), str(bag), '--clock', str(CLOCK_HZ),
             '--wait-for-subscribers', '--settle', '2.0'], stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, text=True, stdin=subprocess.DEVNULL,
            env=ros_environment(ros_domain))
        probe.spin_until(lambda: player.poll() is not None, PLAY_TIMEOUT)
        probe.spin_until(lambda: len(readings) >= COUNT, 2.0)
        out, err = player.communicate(timeout=10.0)
        assert player.returncode == 0, out + err
    finally:
        probe.executor.remove_node(node)
        node.destroy_node()
        probe.close()
    last_ns = FIRST_NS + (COUNT - 1) * PERIOD_NS
    print(f'\n{len(clocks)} /clock messages from {clocks[0]} to {clocks[-1]} ns; {out.strip()}')
    assert clocks[0] == FIRST_NS
    assert all(FIRST_NS <= t <= last_ns for t in clocks), 'only the bag time, not its /clock'
    assert clocks == sorted(clocks)
    assert clocks[-1] >= last_ns - 5 * PERIOD_NS
    # 0.99 s at 100 Hz: 100 ticks; missed ticks are dropped, not bunched up.
    assert 50 <= len(clocks) <= 101
    assert [k for k, _ in readings] == list(range(COUNT))
    lags = [FIRST_NS + k * PERIOD_NS - now for k, now in readings]
    assert all(-PERIOD_NS <= lag <= 100 * MS for lag in lags), lags
    assert f'/clock: {len(clocks)}' in out


def test_clock_option_is_checked(tmp_path, capsys):
    """--clock needs a positive rate and timed playback: one line, exit 2."""
    bag = tmp_path / 'bag.mcap'
    write_bag(bag)
    for arguments, expected in (([str(bag), '--clock', '0'], '--clock must be > 0 Hz'),
                                ([str(bag), '--lockstep', '--clock'], 'needs timed playback'),
                                ([str(bag), '--clock', 'fast'], "invalid float value: 'fast'")):
        code = bag_play_main(['bag_play', *arguments])
        err = capsys.readouterr().err
        assert code == 2 and expected in err and len(err.strip().splitlines()) == 1, err
