"""
bag_play and the bag reader: order, QoS, selection, windows, timed playback, exact replay.

The reader tests use bags written by BagWriter. The playback tests run the bag_play script
into a probe. The replay test records a lockstep paper_toss run of the full graph (2 s of sim
time: standby, reach, contact and grasp), then plays the motion generator's recorded inputs in
lockstep into a fresh ds_motion_generator in another domain and requires its outputs to equal
the recorded ones, field by field, for every recorded DS tick.
"""

from pathlib import Path
import random
import shutil
import subprocess
import sys
import time

from builtin_interfaces.msg import Time
from dual_arm_control import contract
from dual_arm_control.bags import BagError
from dual_arm_control.bags.info import inspect_bag
from dual_arm_control.bags.offered_qos import (DEFAULT_QOS, parse_offered_qos_profiles,
                                               qos_from_offered_profiles)
from dual_arm_control.bags.playback import (parse_remaps, playback_window, select_topics,
                                            wall_offset)
from dual_arm_control.bags.reader import BagReader
from dual_arm_control.bags.writer import BagWriter, header_stamp_ns, offered_qos_profiles
from dual_arm_control.graph import full_graph, run_parameters
from dual_arm_control.nodes.bag_play import main as bag_play_main, split_arguments
from dual_arm_control.nodes.messages import stamp_ns
from dual_arm_control.runtime.timing import TickSchedule
from graph_helpers import (GraphProbe, parameter_arguments, ProcessGroup, record_episode,
                           ros_environment)
import pytest
from rclpy.duration import Duration
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile,
                       ReliabilityPolicy)
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool

SCRIPTS = Path(sys.prefix) / 'bin'
REPOSITORY = Path(__file__).resolve().parents[1]
SCENARIO = REPOSITORY / 'config' / 'scenarios' / 'paper_toss.yaml'
BASE_NS = 1_700_000_000_000_000_000
MS = 1_000_000
FRI_PERIOD_NS = 2 * MS
STARTUP_TIMEOUT = 30.0
PLAY_TIMEOUT = 60.0
# Recorded run: 2 s of sim time reaches contact (~1.73 s) and the grasp (~1.78 s).
SIM_DURATION = 2.0
EPISODE_TIMEOUT = 150.0
DS_INPUTS = ('/clock', '/object/state', '/left/joint_states', '/right/joint_states',
             '/left/ft_wrench', '/right/ft_wrench')
DS_OUTPUTS = {'/left/ds_command': contract.DS_COMMAND, '/right/ds_command': contract.DS_COMMAND,
              '/object/desired_twist': contract.OBJECT_DESIRED_TWIST,
              contract.PHASE.name: contract.PHASE}


def time_of(ns):
    """Return builtin_interfaces/Time of a stamp [ns]."""
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def joint_state(stamp, position):
    """Return the serialized JointState stamped `stamp` [ns] with one position."""
    msg = JointState(name=['a'], position=[float(position)])
    msg.header.stamp = time_of(stamp)
    return serialize_message(msg)


def write_synthetic_bag(path, count=100, period_ns=10 * MS):
    """
    Write /clock, /sim/joint_states and /sim/other at 1 / period for count periods.

    Message k: sim time k * period (clock and stamp), JointState position k, log time
    BASE_NS + k * period (the joint state 1 us after the clock). Return the writer.
    """
    with BagWriter(path, chunk_size=2048) as writer:
        writer.add_topic('/clock', Clock, contract.CLOCK.publisher_qos)
        writer.add_topic('/sim/joint_states', JointState, contract.JOINT_STATES.publisher_qos)
        writer.add_topic('/sim/other', Bool, contract.MONITOR_QOS)
        for k in range(count):
            log_time = BASE_NS + k * period_ns
            writer.write('/clock', serialize_message(Clock(clock=time_of(k * period_ns))),
                         log_time)
            writer.write('/sim/joint_states', joint_state(k * period_ns, k), log_time + 1000)
            writer.write('/sim/other', serialize_message(Bool(data=True)), log_time + 2000)
    return writer


def run_bag_play(domain_id, *arguments, timeout=PLAY_TIMEOUT):
    """Start the bag_play script in a domain; return the process (output piped)."""
    return subprocess.Popen([str(SCRIPTS / 'bag_play'), *map(str, arguments)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            stdin=subprocess.DEVNULL, env=ros_environment(domain_id))


def finish(process, timeout=10.0):
    """Wait for a process; return (exit code, stdout, stderr); kill it if it hangs."""
    try:
        out, err = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        process.kill()
        out, err = process.communicate()
        raise AssertionError(f'{process.args[:2]} did not finish: {out}\n{err}')
    return process.returncode, out, err


# -- reader ------------------------------------------------------------------------------------

def test_split_files_are_merged_in_log_time_order(tmp_path):
    """
    Two files whose log times interleave come out in log-time order, ties in file order.

    File 0 holds even, file 1 odd log times of one topic, plus one message of each file at the
    same log time; rosbag2 folders give the same sequence from metadata.yaml's file list (or,
    without one, from the file names in natural order).
    """
    path = tmp_path / 'run.mcap'
    with BagWriter(path, chunk_size=512) as writer:
        writer.add_topic('/sim/joint_states', JointState, contract.CONTROL_QOS)
        for index in range(2):
            if index:
                writer.split()
            for k in range(index, 40, 2):
                writer.write('/sim/joint_states', joint_state(k * MS, k), BASE_NS + k * MS)
            writer.write('/sim/joint_states', joint_state(0, 100 + index), BASE_NS + 50 * MS)
    expected = list(range(40)) + [100, 101]
    reader = BagReader(path)
    assert reader.files == [path, tmp_path / 'run_1.mcap']
    messages = list(reader.messages())
    positions = [deserialize_message(m.data, JointState).position[0] for m in messages]
    assert positions == expected
    assert [m.publish_time for m in messages[:40]] == [k * MS for k in range(40)]
    assert reader.message_count == 42 and reader.topics['/sim/joint_states'].count == 42
    assert (reader.start_ns, reader.end_ns) == (BASE_NS, BASE_NS + 50 * MS)
    folder = tmp_path / 'rosbag2'
    folder.mkdir()
    shutil.copy(path, folder / 'part_10.mcap')
    shutil.copy(tmp_path / 'run_1.mcap', folder / 'part_2.mcap')
    (folder / 'metadata.yaml').write_text(
        'rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: mcap\n'
        '  relative_file_paths:\n    - part_10.mcap\n    - part_2.mcap\n')
    from_folder = [m.data for m in BagReader(folder).messages()]
    assert from_folder == [m.data for m in messages]
    assert BagReader(folder).files == [folder / 'part_10.mcap', folder / 'part_2.mcap']
    (folder / 'metadata.yaml').unlink()
    (folder / 'part_10.mcap').rename(folder / 'part_9.mcap')
    (folder / 'part_2.mcap').rename(folder / 'part_11.mcap')
    assert BagReader(folder).files == [folder / 'part_9.mcap', folder / 'part_11.mcap']
    (folder / 'metadata.yaml').write_text(
        'rosbag2_bagfile_information:\n  storage_identifier: sqlite3\n'
        '  relative_file_paths: [x.db3]\n')
    with pytest.raises(BagError, match='sqlite3'):
        BagReader(folder)


@pytest.mark.parametrize('qos', [
    contract.CONTROL_QOS, contract.LATCHED_QOS, contract.CLOCK.publisher_qos,
    QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.BEST_EFFORT,
               durability=DurabilityPolicy.VOLATILE, deadline=Duration(seconds=1),
               lifespan=Duration(nanoseconds=250_000_000),
               liveliness=LivelinessPolicy.MANUAL_BY_TOPIC,
               liveliness_lease_duration=Duration(seconds=3)),
])
def test_qos_round_trips_through_the_bag_metadata(tmp_path, qos):
    """The QoS a topic was recorded with is the QoS it is played with, policy by policy."""
    path = tmp_path / 'qos.mcap'
    with BagWriter(path) as writer:
        writer.add_topic('/t', JointState, qos)
    played = BagReader(path).topics['/t'].qos
    for name in ('history', 'reliability', 'durability', 'deadline', 'lifespan',
                 'avoid_ros_namespace_conventions'):
        assert getattr(played, name) == getattr(qos, name), name
    if qos.history == HistoryPolicy.KEEP_LAST:
        assert played.depth == qos.depth
    if qos.liveliness == LivelinessPolicy.MANUAL_BY_TOPIC:
        assert played.liveliness == qos.liveliness
        assert played.liveliness_lease_duration == qos.liveliness_lease_duration


def test_qos_of_several_publishers_old_bags_and_fallback():
    """
    The replay QoS of several publishers, of older rosbag2 versions, and the fallback.

    Several publishers: reliable / transient local only if all were; rmw integers (older
    rosbag2) and infinite durations parse; no profile or garbage gives the default.
    """
    mixed = offered_qos_profiles([contract.LATCHED_QOS, QoSProfile(
        depth=5, reliability=ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.VOLATILE)])
    qos = qos_from_offered_profiles(mixed)
    assert qos.reliability == ReliabilityPolicy.BEST_EFFORT
    assert qos.durability == DurabilityPolicy.VOLATILE
    assert qos.depth == contract.LATCHED_QOS.depth
    both_latched = qos_from_offered_profiles(
        offered_qos_profiles([contract.LATCHED_QOS, contract.LATCHED_QOS]))
    assert both_latched.durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert both_latched.reliability == ReliabilityPolicy.RELIABLE
    humble = ('- history: 1\n  depth: 7\n  reliability: 2\n  durability: 1\n'
              '  deadline:\n    sec: 2147483647\n    nsec: 4294967295\n'
              '  lifespan:\n    sec: 9223372036\n    nsec: 854775807\n  liveliness: 1\n'
              '  liveliness_lease_duration:\n    sec: 0\n    nsec: 0\n'
              '  avoid_ros_namespace_conventions: false\n')
    (old,) = parse_offered_qos_profiles(humble)
    assert (old.history, old.depth) == (HistoryPolicy.KEEP_LAST, 7)
    assert old.reliability == ReliabilityPolicy.BEST_EFFORT
    assert old.durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert old.deadline == Duration() and old.lifespan == Duration()
    unset = qos_from_offered_profiles('- history: system_default\n  depth: 0\n'
                                      '  reliability: best_available\n')
    assert (unset.history, unset.depth, unset.reliability, unset.durability) == (
        HistoryPolicy.KEEP_LAST, 100, ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE)
    for text in ('', '[]\n', 'not: [a list', '- just text\n', '42'):
        qos = qos_from_offered_profiles(text)
        assert (qos.history, qos.depth, qos.reliability, qos.durability) == (
            DEFAULT_QOS.history, 100, ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE)


def test_topic_selection_and_remapping():
    """Names and/or a regex select, --exclude removes; unknown names and bad rules are errors."""
    topics = ['/clock', '/left/joint_states', '/right/joint_states', '/left/ground_truth/tool']
    assert select_topics(topics) == sorted(topics)
    assert select_topics(topics, ['/clock'], regex='joint_states$') == [
        '/clock', '/left/joint_states', '/right/joint_states']
    assert select_topics(topics, exclude='ground_truth|^/clock') == [
        '/left/joint_states', '/right/joint_states']
    assert select_topics(topics, ['/clock', '/left/joint_states'], exclude='left') == ['/clock']
    with pytest.raises(BagError, match='/nope'):
        select_topics(topics, ['/nope'])
    with pytest.raises(BagError, match='--regex'):
        select_topics(topics, regex='(')
    assert parse_remaps(['/a:=/b', '/left/js:=/x/y']) == {'/a': '/b', '/left/js': '/x/y'}
    for rule in ('/a=/b', 'a:=/b', '/a:=b', '/a:=/b:=/c', '/a :=/b'):
        with pytest.raises(BagError, match='--remap'):
            parse_remaps([rule])
    with pytest.raises(BagError, match='twice'):
        parse_remaps(['/a:=/b', '/a:=/c'])
    own, ros = split_arguments(['bag_play', 'b.mcap', '--remap', '/a:=/b', '--ros-args',
                                '--log-level', 'warn', '--', '--rate', '2'])
    assert own == ['b.mcap', '--remap', '/a:=/b', '--rate', '2']
    assert ros == ['--ros-args', '--log-level', 'warn']


def test_offset_duration_window_and_rate_schedule(tmp_path):
    """
    The playback window and the wall-clock schedule.

    The window starts start_offset after the first message and lasts duration (half open);
    at rate r a message is due (log time - window start) / r after the start of playback.
    """
    assert playback_window(1000, 5000) == (1000, 5001)
    assert playback_window(BASE_NS, BASE_NS + 990 * MS, 0.25, 0.5) == (
        BASE_NS + 250 * MS, BASE_NS + 750 * MS)
    for offset, duration, match in ((-0.1, None, 'start-offset'), (2.0, None, 'beyond'),
                                    (0.0, 0.0, 'duration')):
        with pytest.raises(BagError, match=match):
            playback_window(BASE_NS, BASE_NS + 990 * MS, offset, duration)
    assert wall_offset(BASE_NS + 990 * MS, BASE_NS, 2.0) == pytest.approx(0.495, abs=1e-12)
    assert wall_offset(BASE_NS + 300 * MS, BASE_NS + 100 * MS, 0.5) == pytest.approx(0.4)
    path = tmp_path / 'window.mcap'
    write_synthetic_bag(path)
    reader = BagReader(path)
    first, stop = playback_window(reader.start_ns, reader.end_ns, 0.25, 0.5)
    played = [deserialize_message(m.data, JointState).position[0]
              for m in reader.messages(['/sim/joint_states'], first, stop)]
    assert played == list(range(25, 75))


def test_damaged_bag_needs_recover(tmp_path, capsys, ros_domain):
    """
    A torn bag is refused in one line (exit 2); with recovery it yields what bag_info finds.

    The line names the damage and the recoverable count; the recovered messages come in
    order. Other user errors are one line and exit 2 as well.
    """
    complete = tmp_path / 'complete.mcap'
    write_synthetic_bag(complete)
    torn = tmp_path / 'torn.mcap'
    data = complete.read_bytes()
    torn.write_bytes(data[:len(data) // 2])
    info = inspect_bag(torn)
    assert info.status == 'torn' and 0 < info.message_count < 300
    with pytest.raises(BagError, match=f'torn .*{info.message_count} messages are recoverable'):
        BagReader(torn)
    reader = BagReader(torn, recover=True)
    messages = list(reader.messages())
    assert len(messages) == info.message_count == reader.message_count
    assert [m.log_time for m in messages] == sorted(m.log_time for m in messages)
    assert [s.status for s in reader.damaged] == ['torn']
    code = bag_play_main(['bag_play', str(torn)])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and '--recover' in err
    code, out, err = finish(run_bag_play(ros_domain, torn, '--recover', '--rate', '20'),
                            timeout=PLAY_TIMEOUT)
    assert code == 0 and err.count('\n') == 1 and 'is torn' in err, out + err
    assert f'1 pass, {info.message_count} messages' in out
    for arguments, expected in (([str(tmp_path / 'missing.mcap')], 'no such bag'),
                                ([str(complete), '--rate', '-1'], '--rate must be > 0'),
                                ([str(complete), '--topics', '/nope'], '/nope'),
                                ([str(complete), '--wait-for', '/sim/joint_states'],
                                 'needs --lockstep'),
                                ([str(complete), '--lockstep', '--wait-for', '/clock'],
                                 'no header stamp'),
                                ([str(complete), '--remap', '/a:=/b'], 'not in the bag'),
                                ([str(complete), '--bogus'], 'unrecognized')):
        code = bag_play_main(['bag_play', *arguments])
        err = capsys.readouterr().err
        assert code == 2 and expected in err and len(err.strip().splitlines()) == 1, err


# -- timed playback into a probe ---------------------------------------------------------------

class Capture:
    """Probe subscriptions that note (wall arrival time, message) per topic."""

    def __init__(self, probe, topics):
        self.messages = {name: [] for name in topics}
        self.subscriptions = [
            probe.node.create_subscription(
                msg_type, name, lambda msg, name=name: self.messages[name].append(
                    (time.monotonic(), msg)), contract.CONTROL_QOS)
            for name, msg_type in topics.items()]

    def clear(self):
        """Forget what was captured."""
        for messages in self.messages.values():
            messages.clear()


def test_timed_playback_rate_filter_remap_and_loop(tmp_path, ros_domain):
    """
    Timed playback honours --rate, --topics, --remap, the window and --loops.

    Rate 2: 100 joint states over 0.99 s of log time arrive in order within 0.495 s of wall
    time, with the 100 /clock messages; /sim/other is filtered out and the joint states come
    only under their new name. Tolerance +-0.2 s on the span: a behaviour check on a shared
    2-core machine that still tells rate 2 from rates 1 (0.99 s) and 4 (0.25 s).
    --loops 3 with a 0.2 s window from 0.5 s plays positions 50..69 three times.
    """
    bag = tmp_path / 'synthetic.mcap'
    write_synthetic_bag(bag)
    probe = GraphProbe(ros_domain, 'play_probe')
    capture = Capture(probe, {'/clock': Clock, '/replayed/joint_states': JointState,
                              '/sim/joint_states': JointState, '/sim/other': Bool})
    try:
        player = run_bag_play(ros_domain, bag, '--rate', '2', '--topics', '/clock',
                              '/sim/joint_states', '--remap',
                              '/sim/joint_states:=/replayed/joint_states',
                              '--wait-for-subscribers', '--settle', '0.5')
        probe.spin_until(lambda: player.poll() is not None, PLAY_TIMEOUT)
        probe.spin_until(lambda: len(capture.messages['/replayed/joint_states']) >= 100, 2.0)
        code, out, err = finish(player)
        assert code == 0, out + err
        states = capture.messages['/replayed/joint_states']
        assert [msg.position[0] for _, msg in states] == list(range(100))
        assert [stamp_ns(msg.header.stamp) for _, msg in states] == [
            k * 10 * MS for k in range(100)]
        assert [stamp_ns(msg.clock) for _, msg in capture.messages['/clock']] == [
            k * 10 * MS for k in range(100)]
        assert not capture.messages['/sim/joint_states'] and not capture.messages['/sim/other']
        span = states[-1][0] - states[0][0]
        print(f'\nrate 2: 100 joint states over {span:.3f} s of wall time (0.495 s expected); '
              f'{out.strip()}')
        assert span == pytest.approx(0.495, abs=0.2)
        assert '/clock: 100, /replayed/joint_states: 100' in out

        capture.clear()
        player = run_bag_play(ros_domain, bag, '--rate', '4', '--topics', '/sim/joint_states',
                              '--start-offset', '0.5', '--duration', '0.2', '--loops', '3',
                              '--wait-for-subscribers', '--settle', '0.5')
        probe.spin_until(lambda: player.poll() is not None, PLAY_TIMEOUT)
        probe.spin_until(lambda: len(capture.messages['/sim/joint_states']) >= 60, 2.0)
        code, out, err = finish(player)
        assert code == 0, out + err
        positions = [msg.position[0] for _, msg in capture.messages['/sim/joint_states']]
        assert positions == list(range(50, 70)) * 3
        assert 'bag_play: 3 passes, 60 messages' in out and not capture.messages['/clock']
    finally:
        probe.close()


# -- exact replay of the motion generator --------------------------------------------------------

def missing_inputs(bag):
    """
    Return what the bag lacks of the motion generator's inputs ('' if nothing).

    Every FRI cycle of the run needs /clock, both arms' joint states and the tracker's
    per-cycle /object/state, and every DS tick both arms' FT readings, each stamped with the
    cycle, from sim time 0 on.
    """
    stamps = {topic: set() for topic in DS_INPUTS}
    for message in BagReader(bag).messages(list(DS_INPUTS)):
        stamps[message.topic].add(header_stamp_ns(message.data))
    cycles = set(range(0, max(stamps['/clock'], default=-1) + 1, FRI_PERIOD_NS))
    schedule = TickSchedule(0.005)
    ticks = set()
    for stamp in sorted(cycles):
        if schedule.due(stamp):
            schedule.take(stamp)
            ticks.add(stamp)
    needed = {topic: ticks if topic.endswith('ft_wrench') else cycles for topic in stamps}
    lacking = {topic: len(needed[topic] - found) for topic, found in stamps.items()
               if needed[topic] - found}
    return f'{len(cycles)} cycles; cycles missing per topic: {lacking}' if lacking else ''


@pytest.fixture(scope='module')
def recorded_run(tmp_path_factory):
    """
    Record a lockstep paper_toss run (SIM_DURATION) with `dual_arm_bringup --record`.

    The recorded bridge starts only once the recorder matched every publisher, so every input
    of the motion generator is in the bag from sim time 0.
    """
    out = tmp_path_factory.mktemp('recorded') / 'run'
    started = time.monotonic()
    record_episode(SCENARIO, out, SIM_DURATION, EPISODE_TIMEOUT)
    assert inspect_bag(out / 'bag.mcap').status == 'complete'
    missing = missing_inputs(out / 'bag.mcap')
    assert not missing, f'the recording lacks motion generator inputs: {missing}'
    return out / 'bag.mcap', time.monotonic() - started


def ds_parameters():
    """Return the ds_motion_generator parameters of a full-graph lockstep run of SCENARIO."""
    (spec,) = [spec for spec in full_graph() if spec.name == 'ds_motion_generator']
    return dict(spec.parameters, **run_parameters('full', SCENARIO.resolve())[spec.name])


def test_lockstep_replay_reproduces_the_motion_generator_exactly(recorded_run, tmp_path):
    """
    A fresh motion generator fed the recorded inputs in lockstep answers exactly as recorded.

    The fresh ds_motion_generator (the recorded run's parameters, in another domain) answers
    every DS tick of the run (the ticks of the latched, complete phase) and nothing else; each
    recorded command of each arm, desired object twist and phase equals its answer to the same
    tick, every field (floats bit for bit). Inputs: /clock, /object/state and both arms' joint
    states and FT readings in recorded order; barrier /dual_arm/phase: after a tick's inputs
    bag_play waits for the node's phase of that tick before the next cycle.
    """
    bag, record_wall = recorded_run
    recorded = {name: {} for name in DS_OUTPUTS}
    for message in BagReader(bag).messages(list(DS_OUTPUTS)):
        msg = deserialize_message(message.data, DS_OUTPUTS[message.topic].msg_type)
        recorded[message.topic].setdefault(stamp_ns(msg.header.stamp), []).append(msg)
    ticks = sorted(recorded[contract.PHASE.name])
    assert len(ticks) == int(SIM_DURATION / 0.005)
    domain_id = random.SystemRandom().randint(1, 200)
    with ProcessGroup(tmp_path, domain_id) as group:
        group.start('ds_motion_generator', 'ds_motion_generator',
                    parameter_arguments(**ds_parameters()))
        probe = GraphProbe(domain_id, 'replay_probe')
        replayed = {name: {} for name in DS_OUTPUTS}
        try:
            for name, topic in DS_OUTPUTS.items():
                probe.node.create_subscription(
                    topic.msg_type, name, lambda msg, name=name: replayed[name].setdefault(
                        stamp_ns(msg.header.stamp), []).append(msg), topic.qos)
            assert probe.spin_until(
                lambda: all(probe.node.count_publishers(name) for name in DS_OUTPUTS),
                STARTUP_TIMEOUT), group.log('ds_motion_generator')
            started = time.monotonic()
            player = run_bag_play(domain_id, bag, '--lockstep', '--topics', *DS_INPUTS,
                                  '--wait-for', contract.PHASE.name)
            probe.spin_until(lambda: player.poll() is not None, PLAY_TIMEOUT)
            probe.spin_until(lambda: all(len(replayed[n]) >= len(ticks) for n in DS_OUTPUTS),
                             2.0)
            code, out, err = finish(player)
            replay_wall = time.monotonic() - started
        finally:
            probe.close()
        assert code == 0, out + err + group.log('ds_motion_generator')
    assert f'{len(ticks)} barriers' in out and ' 0 timeouts' in out, out
    compared = {}
    phases = set()
    for name in DS_OUTPUTS:
        assert sorted(replayed[name]) == ticks, name
        for stamp, originals in recorded[name].items():
            assert len(originals) == 1, (name, stamp)
            mismatched = [msg for msg in replayed[name][stamp] if msg != originals[0]]
            assert not mismatched, (name, stamp, originals[0], mismatched[0])
            compared[name] = compared.get(name, 0) + 1
            if name == contract.PHASE.name:
                phases.add(originals[0].status[0].message)
    assert compared[contract.PHASE.name] == len(ticks)
    assert {'standby', 'reach', 'contact'} <= phases
    print(f'\nreplay: {len(ticks)} DS ticks; recorded messages equal to the replay: {compared} '
          f'(phases {sorted(phases)}); recording {record_wall:.1f} s, replay '
          f'{replay_wall:.1f} s wall; {out.strip()}')
