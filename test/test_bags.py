"""
MCAP bags: ros2msg definitions, the writer, the recorder on the real graph, bag_info.

The graph test records a lockstep paper_toss run (1 s of sim time) and checks the bag against
what the publishers counted (each node prints its published counts on exit) and against what
the bridge provably stepped: every cycle's state and command, one phase per DS tick.
Foxglove's own decoders (test/foxglove, run with Node), rosbags and our reader must decode
every message of it alike.
"""

import array
import dataclasses
import json
import math
import os
from pathlib import Path
import random
import shutil
import signal
import subprocess
import sys
import time

from dual_arm_control import contract
from dual_arm_control.bags import BagError
from dual_arm_control.bags.info import inspect_bag, main as bag_info_main
from dual_arm_control.bags.reader import BagReader
from dual_arm_control.bags.schema import (dependency_names, first_field_type,
                                          message_definition, msg_file, type_name)
from dual_arm_control.bags.writer import (BagWriter, header_stamp_ns, METADATA_NAME,
                                          SPLIT_METADATA_NAME, split_path)
from dual_arm_control.core.exceptions import InputError
from dual_arm_control.graph import full_graph, RECORDER_NODE
from dual_arm_control.nodes.bag_record import main as bag_record_main, message_class
from dual_arm_control.nodes.process import PUBLISHED_COUNTS_PREFIX
from dual_arm_control.runtime.timing import seconds_to_ns, TickSchedule
from dual_arm_control.tools.param_events import parameter_changes
from dual_arm_control.trajectory_log import load_trajectory
from graph_helpers import GraphProbe, record_episode, ros_environment
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Message
from mcap.stream_reader import StreamReader
from mcap.writer import Writer
import numpy as np
import pytest
from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_types_from_msg, get_typestore, Stores
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

SCRIPTS = Path(sys.prefix) / 'bin'
REPOSITORY = Path(__file__).resolve().parents[1]
SCENARIO = REPOSITORY / 'config' / 'scenarios' / 'paper_toss.yaml'
FOXGLOVE = REPOSITORY / 'test' / 'foxglove'
SIM_DURATION = 1.0
FRI_PERIOD_NS = seconds_to_ns(0.002)
TICK_PERIOD = 0.005
STARTUP_TIMEOUT = 20.0
EPISODE_TIMEOUT = 120.0
STOP_TIMEOUT = 10.0
TYPESTORE = get_typestore(Stores.LATEST)


def contract_types():
    """Return the message type names of the contract, each once."""
    return sorted({type_name(topic.msg_type) for topic in contract.ALL_TOPICS})


def joint_state_cdr(stamp_sec, stamp_nanosec, positions):
    """Return a JointState serialized by rosbags (exact CDR length, unlike rmw_serialize)."""
    types = TYPESTORE.types
    msg = types['sensor_msgs/msg/JointState'](
        header=types['std_msgs/msg/Header'](
            stamp=types['builtin_interfaces/msg/Time'](sec=stamp_sec, nanosec=stamp_nanosec),
            frame_id='world'),
        name=['a'], position=np.array(positions, dtype=float), velocity=np.zeros(0),
        effort=np.zeros(0))
    return TYPESTORE.serialize_cdr(msg, 'sensor_msgs/msg/JointState')


def read_messages(paths):
    """Return [(topic, log_time, publish_time, data)] of bag files in file order."""
    records = []
    for path in paths:
        with open(path, 'rb') as stream:
            for _, channel, message in make_reader(stream).iter_messages(log_time_order=False):
                records.append((channel.topic, message.log_time, message.publish_time,
                                message.data))
    return records


# -- message definitions -----------------------------------------------------------------------

@pytest.mark.parametrize('name', contract_types())
def test_definition_describes_the_installed_type(name):
    """
    Rosbags parses the definition into the fields of the rclpy class, with dependencies.

    Every complex field type of every section has a 'MSG:' section of exactly that name (how
    Foxglove resolves it), and the text starts with the type's own .msg file.
    """
    definition = message_definition(name)
    parsed = get_types_from_msg(definition, name)
    package, _, short_name = name.split('/')
    msg_class = getattr(__import__(f'{package}.msg', fromlist=[short_name]), short_name)
    assert [field for field, _ in parsed[name][1]] == list(msg_class.get_fields_and_field_types())
    dependencies = [line[5:] for line in definition.splitlines() if line.startswith('MSG: ')]
    assert len(dependencies) == len(set(dependencies)) == len(parsed) - 1
    assert definition.count('\n' + '=' * 80 + '\n') == len(dependencies)
    sections = definition.split('\n' + '=' * 80 + '\n')
    assert sections[0] == msg_file(name).read_text()
    referenced = set(dependency_names(sections[0], package))
    for section in sections[1:]:
        heading, _, text = section.partition('\n')
        referenced |= set(dependency_names(text, heading[5:].split('/')[0]))
    assert referenced == set(dependencies)


def test_definition_of_odometry_is_what_rosbag2_writes():
    """Depth first, sorted per type, each dependency named as its field spells it."""
    definition = message_definition('nav_msgs/msg/Odometry')
    dependencies = [line[5:] for line in definition.splitlines() if line.startswith('MSG: ')]
    assert dependencies == [
        'geometry_msgs/PoseWithCovariance', 'geometry_msgs/Pose', 'geometry_msgs/Point',
        'geometry_msgs/Quaternion', 'geometry_msgs/TwistWithCovariance', 'geometry_msgs/Twist',
        'geometry_msgs/Vector3', 'std_msgs/Header', 'builtin_interfaces/Time']
    assert '\nstd_msgs/Header header' in definition
    assert '\n\n' + '=' * 80 + '\nMSG: std_msgs/Header\n' in definition
    assert first_field_type('nav_msgs/msg/Odometry') == 'std_msgs/msg/Header'
    assert first_field_type('std_msgs/msg/Bool') == 'bool'


def test_unknown_type_is_refused_with_its_name():
    """A type without a .msg file under share/ is a BagError naming it."""
    with pytest.raises(BagError, match='no_such_msgs/msg/Thing'):
        message_definition('no_such_msgs/msg/Thing')


def test_reader_reads_bags_with_the_earlier_schema_headings(tmp_path):
    """Bags written before the headings followed rosbag2 ('MSG: std_msgs/msg/Header') read."""
    path = tmp_path / 'earlier.mcap'
    definition = message_definition('sensor_msgs/msg/JointState').replace(
        'MSG: std_msgs/Header', 'MSG: std_msgs/msg/Header').replace(
        'MSG: builtin_interfaces/Time', 'MSG: builtin_interfaces/msg/Time')
    with open(path, 'wb') as stream:
        writer = Writer(stream)
        writer.start(profile='ros2', library='dual_arm_control')
        schema = writer.register_schema('sensor_msgs/msg/JointState', 'ros2msg',
                                        definition.encode())
        channel = writer.register_channel('/js', 'cdr', schema)
        for index in range(3):
            writer.add_message(channel, index, joint_state_cdr(index, 0, [index]), index)
        writer.finish()
    messages = list(BagReader(path).messages())
    assert [deserialize_message(m.data, JointState).position[0] for m in messages] == [0, 1, 2]


# -- writer ------------------------------------------------------------------------------------

def test_writer_round_trip_and_split(tmp_path):
    """
    Split files hold every message once, with stamps as publish times and the QoS metadata.

    200 messages of 100 bytes with a 4 KiB size limit and 1 KiB chunks: several files; each
    is complete on its own and rosbags reads the set back in order.
    """
    path = tmp_path / 'split.mcap'
    with BagWriter(path, compression='lz4', chunk_size=1024, split_size=4096) as writer:
        writer.add_topic('/left/joint_states', 'sensor_msgs/msg/JointState',
                         contract.CONTROL_QOS)
        writer.add_topic('/dual_arm/phase', contract.PHASE.msg_type, contract.PHASE.qos)
        for index in range(200):
            writer.write('/left/joint_states', joint_state_cdr(index, 7, [index, 1.0]),
                         1_000_000 + index)
    assert len(writer.paths) >= 3
    assert writer.paths[1] == split_path(path, 1) == tmp_path / 'split_1.mcap'
    assert writer.counts == {'/left/joint_states': 200, '/dual_arm/phase': 0}
    records = read_messages(writer.paths)
    assert [r[1] for r in records] == [1_000_000 + i for i in range(200)]
    assert [r[2] for r in records] == [i * 1_000_000_000 + 7 for i in range(200)]
    assert all(inspect_bag(p).status == 'complete' for p in writer.paths)
    with AnyReader(writer.paths) as reader:
        positions = [reader.deserialize(raw, c.msgtype).position[0]
                     for c, _, raw in reader.messages()]
        qos = {c.topic: c.ext.offered_qos_profiles[0] for c in reader.connections}
    assert positions == list(range(200))
    assert qos['/dual_arm/phase'].durability.name == 'TRANSIENT_LOCAL'
    assert qos['/left/joint_states'].reliability.name == 'RELIABLE'
    assert qos['/left/joint_states'].depth == contract.CONTROL_QOS.depth


def test_writer_refuses_bad_use(tmp_path):
    """Unknown compression, unregistered topics and writes after close are BagErrors."""
    with pytest.raises(BagError, match='compression'):
        BagWriter(tmp_path / 'a.mcap', compression='brotli')
    writer = BagWriter(tmp_path / 'b.mcap')
    with pytest.raises(BagError, match='not registered'):
        writer.write('/nope', b'\x00\x01\x00\x00', 1)
    writer.close()
    with pytest.raises(BagError, match='closed'):
        writer.write('/nope', b'\x00\x01\x00\x00', 1)


def test_existing_bag_is_replaced_only_with_overwrite(tmp_path, capsys):
    """
    A bag (file and split files) at the output is kept unless overwrite; bag_record exits 2.

    With overwrite every file of the old set goes, so no stale split file is left behind.
    """
    path = tmp_path / 'run.mcap'
    with BagWriter(path) as writer:
        writer.add_topic('/js', 'sensor_msgs/msg/JointState', contract.CONTROL_QOS)
        writer.write('/js', joint_state_cdr(1, 0, [1.0]), 1)
        writer.split()
        writer.write('/js', joint_state_cdr(2, 0, [2.0]), 2)
    before = {p.name: p.read_bytes() for p in writer.paths}
    assert sorted(before) == ['run.mcap', 'run_1.mcap']
    with pytest.raises(BagError, match='run.mcap: a bag is already there.*without overwrite'):
        BagWriter(path)
    assert bag_record_main(['bag_record', '-o', str(path)]) == 2
    assert 'already exists' in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in tmp_path.glob('*.mcap')} == before
    with BagWriter(path, overwrite=True) as writer:
        writer.add_topic('/js', 'sensor_msgs/msg/JointState', contract.CONTROL_QOS)
        writer.write('/js', joint_state_cdr(3, 0, [3.0]), 3)
    assert sorted(p.name for p in tmp_path.glob('*.mcap')) == ['run.mcap']
    messages = list(BagReader(path).messages())
    assert [deserialize_message(m.data, JointState).position[0] for m in messages] == [3.0]


def write_split_bag(path, files, overwrite=False):
    """Write a bag of `files` split files, one JointState each (position = file index)."""
    with BagWriter(path, overwrite=overwrite) as writer:
        writer.add_topic('/js', 'sensor_msgs/msg/JointState', contract.CONTROL_QOS)
        for index in range(files):
            if index:
                writer.split()
            writer.write('/js', joint_state_cdr(index, 0, [index]), index)
    return writer


def test_split_files_are_read_as_one_recording_or_refused(tmp_path):
    """
    Every split file names its recording and index; a stale or missing split is a BagError.

    A stale run_1.mcap from an earlier recording beside a new run.mcap (by the reader and the
    tools that read bags), and a set whose split 1 is missing, are refused naming the file; a
    later split reads alone; files without the marks still read as a set.
    """
    old = write_split_bag(tmp_path / 'old' / 'run.mcap', 3)
    new = write_split_bag(tmp_path / 'run.mcap', 1)
    marks = []
    for path in old.paths:
        with open(path, 'rb') as stream:
            marks.append({r.name: r.metadata for r in make_reader(stream).iter_metadata()})
    assert marks == [{SPLIT_METADATA_NAME: {'recording_id': old.recording_id,
                                            'split_index': str(index)}} for index in range(3)]
    assert old.recording_id != new.recording_id
    assert len(list(BagReader(old.paths[0]).messages())) == 3
    assert BagReader(old.paths[1]).files == [old.paths[1]]
    stale = tmp_path / 'run_1.mcap'
    shutil.copy(old.paths[1], stale)
    with pytest.raises(BagError, match=f'{stale} is not part of the recording in .*run.mcap.*'
                                       'stale split file'):
        BagReader(new.paths[0])
    with pytest.raises(InputError, match='stale split file'):
        parameter_changes(new.paths[0])
    old.paths[1].unlink()
    old.paths[2].rename(old.paths[1])
    with pytest.raises(BagError, match='run_1.mcap: split 2 of its recording where split 1 '
                                       'belongs; a split file is missing'):
        BagReader(old.paths[0])
    for index in range(2):
        with open(tmp_path / f'plain_{index}.mcap' if index else tmp_path / 'plain.mcap',
                  'wb') as stream:
            writer = Writer(stream)
            writer.start(profile='ros2', library='other')
            schema = writer.register_schema(
                'sensor_msgs/msg/JointState', 'ros2msg',
                message_definition('sensor_msgs/msg/JointState').encode())
            channel = writer.register_channel('/js', 'cdr', schema)
            writer.add_message(channel, index, joint_state_cdr(index, 0, [index]), index)
            writer.finish()
    assert len(list(BagReader(tmp_path / 'plain.mcap').messages())) == 2


@pytest.mark.parametrize('main', [bag_record_main, bag_info_main])
def test_help_documents_the_exit_codes(main, capsys):
    """bag_record --help and bag_info --help end with their exit codes."""
    with pytest.raises(SystemExit) as stop:
        main(['bag_record', '--help'] if main is bag_record_main else ['--help'])
    assert stop.value.code == 0
    epilog = capsys.readouterr().out.split('exit codes:')[1]
    assert '0 ' in epilog and '1 ' in epilog and '2 bad' in epilog


def test_header_stamp_reads_both_byte_orders():
    """The stamp after the CDR encapsulation is read in the message's byte order."""
    little = b'\x00\x01\x00\x00' + (5).to_bytes(4, 'little') + (9).to_bytes(4, 'little')
    big = b'\x00\x00\x00\x00' + (5).to_bytes(4, 'big') + (9).to_bytes(4, 'big')
    assert header_stamp_ns(little) == header_stamp_ns(big) == 5_000_000_009
    assert header_stamp_ns(b'\x00\x01') is None


# -- the recorder on the real graph ------------------------------------------------------------

def start_recorder(tmp_path, domain_id, output, *arguments):
    """Start bag_record in a domain; return the process once its subscriptions exist."""
    log_path = tmp_path / f'{Path(output).stem}_record.log'
    log_file = open(log_path, 'w')
    process = subprocess.Popen(
        [str(SCRIPTS / 'bag_record'), '-o', str(output), *arguments],
        stdout=log_file, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
        env=ros_environment(domain_id))
    log_file.close()
    deadline = time.monotonic() + STARTUP_TIMEOUT
    while 'recording' not in log_path.read_text():
        assert process.poll() is None and time.monotonic() < deadline, log_path.read_text()
        time.sleep(0.1)
    return process, log_path


def stop_process(process, sig=signal.SIGINT):
    """Signal a process and wait for it; return (exit code, resource usage)."""
    process.send_signal(sig)
    deadline = time.monotonic() + STOP_TIMEOUT
    while time.monotonic() < deadline:
        pid, status, usage = os.wait4(process.pid, os.WNOHANG)
        if pid:
            process.returncode = os.waitstatus_to_exitcode(status)
            return process.returncode, usage
        time.sleep(0.05)
    process.kill()
    process.wait()
    raise AssertionError(f'process {process.args[0]} did not stop on {sig!r}')


@pytest.fixture(scope='module')
def graph_bag(tmp_path_factory):
    """Record a 1 s lockstep paper_toss run; return (bag path, trajectory log, measurements)."""
    tmp_path = tmp_path_factory.mktemp('graph_bag')
    domain_id = random.SystemRandom().randint(1, 200)
    params = tmp_path / 'params.yaml'
    awaited = [RECORDER_NODE, *(spec.full_name for spec in full_graph())]
    params.write_text(f'sim_bridge:\n  ros__parameters:\n    duration: {SIM_DURATION}\n'
                      '    wait_for_subscribers: true\n'
                      '    wait_for_recorder: true\n'
                      f'    wait_for_nodes: {json.dumps(awaited)}\n')
    bag = tmp_path / 'graph.mcap'
    recorder, log_path = start_recorder(tmp_path, domain_id, bag, '--use-sim-time')
    try:
        started = time.monotonic()
        bringup = subprocess.run(
            [str(SCRIPTS / 'dual_arm_bringup'), '--scenario', str(SCENARIO), '--params',
             str(params), '--out', str(tmp_path / 'run'), '--domain-id', str(domain_id)],
            capture_output=True, text=True, timeout=EPISODE_TIMEOUT, env=dict(os.environ))
        graph_wall = time.monotonic() - started
    finally:
        exit_code, usage = stop_process(recorder)
    assert exit_code == 0, log_path.read_text()
    assert bringup.returncode in (0, 1), bringup.stdout + bringup.stderr
    measurements = {'graph_wall': graph_wall, 'recorder_cpu': usage.ru_utime + usage.ru_stime,
                    'recorder_log': log_path.read_text(),
                    'published': published_counts(tmp_path / 'run' / 'logs')}
    return bag, load_trajectory(tmp_path / 'run' / 'trajectory.npz'), measurements


def published_counts(log_dir):
    """Return {topic: messages published} summed over the counts the nodes printed on exit."""
    counts = {}
    logs = sorted(Path(log_dir).glob('*.log'))
    for log in logs:
        for line in log.read_text().splitlines():
            if line.startswith(PUBLISHED_COUNTS_PREFIX):
                for topic, count in json.loads(line[len(PUBLISHED_COUNTS_PREFIX):]).items():
                    counts[topic] = counts.get(topic, 0) + count
    return counts


def stamps_of(records, topic):
    """Return the publish times (header stamps) of a topic's records, in file order."""
    return [publish_time for name, _, publish_time, _ in records if name == topic]


def test_recorded_counts_match_what_was_published(graph_bag):
    """
    Nothing is lost: per topic, the bag holds exactly as many messages as the publishers sent.

    Every node prints its published counts on exit (after its subscribers acknowledged the
    last message). The bridge publishes its first state only once the recorder reports that it
    matched every publisher the bridge sees (wait_for_recorder). On top of the
    counts, every stepped cycle's joint states, FT readings and torque commands are there once
    from sim time 0, and one phase per DS tick (TickSchedule) of the stepped cycles.
    """
    bag, log, measurements = graph_bag
    records = read_messages([bag])
    recorded = {}
    for name, *_ in records:
        recorded[name] = recorded.get(name, 0) + 1
    published = measurements['published']
    assert set(published) >= {contract.CLOCK.name, contract.PHASE.name,
                              contract.DS_COMMAND.resolved('left')}
    assert {topic: recorded.get(topic, 0) for topic in published} == published
    cycles = int(log['cycles'])
    last_stepped_ns = (cycles - 1) * FRI_PERIOD_NS
    schedule = TickSchedule(TICK_PERIOD)
    ticks = []
    for k in range(cycles + 1):
        if schedule.due(k * FRI_PERIOD_NS):
            schedule.take(k * FRI_PERIOD_NS)
            ticks.append(k * FRI_PERIOD_NS)
    every_cycle = list(range(0, last_stepped_ns + 1, FRI_PERIOD_NS))
    for arm in contract.ARMS:
        assert int(log[f'{arm}_commands_accepted']) == cycles
        # F/T readings go out on the DS ticks only (the bridge's ft_period), the rest each cycle.
        for topic, expected in ((contract.TORQUE_COMMAND, every_cycle),
                                (contract.JOINT_STATES, every_cycle),
                                (contract.FT_WRENCH, [t for t in ticks if t <= last_stepped_ns])):
            stamps = [s for s in stamps_of(records, topic.resolved(arm)) if s <= last_stepped_ns]
            # The bridge republishes a state whose answers are overdue: duplicates are allowed.
            assert sorted(set(stamps)) == expected, topic.name
    phase = stamps_of(records, contract.PHASE.name)
    assert sorted(set(phase)) in (ticks, ticks[:-1])
    assert len(ticks) > 150
    print(f'\ncycles {cycles}, DS ticks {len(ticks)}; recorded = published on '
          f'{len(published)} topics, {sum(published.values())} messages')
    log_times = [log_time for _, log_time, _, _ in records]
    assert all(b >= a for a, b in zip(log_times, log_times[1:]))
    size = sum(len(data) for *_, data in records)
    wall = measurements['graph_wall']
    print(f'\nrecorded {len(records)} messages ({size / 1e6:.2f} MB serialized, bag '
          f'{bag.stat().st_size / 1e6:.2f} MB) over the {wall:.1f} s graph run (wall, start-up '
          f'included): {len(records) / wall:.0f} msg/s; recorder CPU '
          f'{measurements["recorder_cpu"]:.2f} s ({100 * measurements["recorder_cpu"] / wall:.0f}'
          ' % of one core)')


def test_log_times_are_the_sim_time_of_receipt(graph_bag):
    """
    Recorded with use_sim_time, log time is the recorder's sim time when a message arrived.

    Every log time is a sim time the bridge published on /clock (or 0 before the first);
    messages without a header have publish time = log time. /clock and stamped messages are
    logged at their own sim time, typically (median) within one FRI cycle: the recorder's clock
    follows /clock through its own subscription, and under load the recorder may work off a
    backlog at a later sim time, so single messages can be logged later.
    """
    bag, _, _ = graph_bag
    records = read_messages([bag])
    topics = BagReader(bag).topics
    clock_values = [deserialize_message(data, Clock).clock for name, _, _, data in records
                    if name == contract.CLOCK.name]
    clock_ns = [value.sec * 1_000_000_000 + value.nanosec for value in clock_values]
    clock_logs = [log_time for name, log_time, _, _ in records if name == contract.CLOCK.name]
    assert {log_time for _, log_time, _, _ in records} <= {0, *clock_ns}
    clock_lags = sorted(abs(now - logged) for logged, now in zip(clock_logs, clock_ns))
    assert clock_lags[len(clock_lags) // 2] <= FRI_PERIOD_NS, clock_lags
    lags = []
    for name, log_time, publish_time, data in records:
        if first_field_type(topics[name].type_name) == 'std_msgs/msg/Header':
            lags.append(abs(log_time - publish_time))
        else:
            assert publish_time == log_time, name
    lags.sort()
    print(f'\n|log time - header stamp| over {len(lags)} stamped messages: median '
          f'{lags[len(lags) // 2] / 1e6:.1f} ms, 99 % {lags[len(lags) * 99 // 100] / 1e6:.1f} '
          f'ms, max {lags[-1] / 1e6:.1f} ms of sim time')
    assert lags[len(lags) // 2] <= FRI_PERIOD_NS, lags[-10:]


def test_independent_readers_agree(graph_bag):
    """Rosbags decodes every message; summary, full scan and rosbags agree on the counts."""
    bag, _, _ = graph_bag
    with open(bag, 'rb') as stream:
        reader = make_reader(stream)
        header = reader.get_header()
        summary = reader.get_summary()
        scanned = {}
        for schema, channel, _ in reader.iter_messages():
            assert schema.encoding == 'ros2msg' and channel.message_encoding == 'cdr'
            assert 'offered_qos_profiles' in channel.metadata
            scanned[channel.topic] = scanned.get(channel.topic, 0) + 1
    assert header.profile == 'ros2'
    from_summary = {summary.channels[c].topic: n
                    for c, n in summary.statistics.channel_message_counts.items() if n}
    assert from_summary == scanned
    decoded = {}
    with AnyReader([bag]) as reader:
        for connection, _, raw in reader.messages():
            msg = reader.deserialize(raw, connection.msgtype)
            assert msg.__msgtype__ == connection.msgtype
            decoded[connection.topic] = decoded.get(connection.topic, 0) + 1
    assert decoded == scanned
    expected = {contract.CLOCK.name, contract.PHASE.name, '/left/joint_states',
                '/right/torque_command', contract.OBJECT_STATE.name, '/rosout'}
    assert expected <= set(decoded)
    info = inspect_bag(bag)
    assert info.status == 'complete' and info.compressions == {'zstd'}
    assert {name: topic.count for name, topic in info.topics.items() if topic.count} == scanned


def float_values(value, out):
    """Append the float fields of a decoded message (rclpy or rosbags), in field order."""
    if isinstance(value, float):
        out.append(value)
    elif isinstance(value, np.ndarray) and value.dtype.kind == 'f':
        out.extend(float(item) for item in value)
    elif isinstance(value, array.array):
        out.extend(value if value.typecode in 'fd' else ())
    elif isinstance(value, (list, tuple, np.ndarray)):
        for item in value:
            float_values(item, out)
    elif hasattr(value, 'get_fields_and_field_types'):
        for name in value.get_fields_and_field_types():
            float_values(getattr(value, name), out)
    elif dataclasses.is_dataclass(value):
        for field in dataclasses.fields(value):
            float_values(getattr(value, field.name), out)
    return out


def decoded_row(log_time, msg):
    """
    Return what decode_bag.mjs prints of a message: [log time, header stamp, first float, sum, n].

    Times as decimal text, the stamp None without a header, NaN and infinities as None; the sum
    adds left to right as JavaScript does.
    """
    header = getattr(msg, 'header', None)
    stamp = None if header is None else str(
        header.stamp.sec * 1_000_000_000 + header.stamp.nanosec)
    values = float_values(msg, [])
    total = 0.0
    for value in values:
        total += value
    first = values[0] if values else None
    return [str(log_time), stamp, first if first is None or math.isfinite(first) else None,
            total if math.isfinite(total) else None, len(values)]


def foxglove_decode(paths):
    """Run test/foxglove/decode_bag.mjs (Foxglove's libraries) on bag files; return its JSON."""
    assert (FOXGLOVE / 'node_modules' / '@foxglove' / 'rosmsg2-serialization').is_dir(), (
        f'the npm packages of {FOXGLOVE} are missing: run ./bootstrap.sh')
    result = subprocess.run(['node', str(FOXGLOVE / 'decode_bag.mjs'), *map(str, paths)],
                            capture_output=True, text=True, timeout=EPISODE_TIMEOUT)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def test_foxglove_decodes_a_message_of_every_contract_type(tmp_path):
    """Foxglove's rosmsg + rosmsg2-serialization decode one default message of each type."""
    path = tmp_path / 'types.mcap'
    expected = {}
    with BagWriter(path) as writer:
        for index, name in enumerate(contract_types()):
            topic = f'/type_{index}'
            msg = message_class(name)()
            writer.add_topic(topic, name, contract.CONTROL_QOS)
            writer.write(topic, serialize_message(msg), index)
            expected[topic] = [decoded_row(index, msg)]
    decoded = foxglove_decode([path])
    assert {topic: (c['failures'], c['errors']) for topic, c in decoded.items()} == {
        topic: (0, []) for topic in expected}
    assert {topic: c['messages'] for topic, c in decoded.items()} == expected


def test_foxglove_rosbags_and_our_reader_decode_every_message_alike(graph_bag):
    """
    Every message of every channel decodes with Foxglove's libraries, rosbags and our reader.

    Per topic the three give the same messages in the same order: log time, header stamp, the
    first float field and the sum and number of all float fields of each message.
    """
    bag, _, _ = graph_bag
    foxglove = foxglove_decode([bag])
    failed = {topic: c['errors'] for topic, c in foxglove.items() if c['failures']}
    assert not failed, failed
    from_foxglove = {topic: c['messages'] for topic, c in foxglove.items()}
    ours = {}
    reader = BagReader(bag)
    for message in reader.messages():
        msg = deserialize_message(message.data, message_class(message.type_name))
        ours.setdefault(message.topic, []).append(decoded_row(message.log_time, msg))
    from_rosbags = {}
    with AnyReader([bag]) as rosbags_reader:
        for connection, log_time, raw in rosbags_reader.messages():
            msg = rosbags_reader.deserialize(raw, connection.msgtype)
            from_rosbags.setdefault(connection.topic, []).append(decoded_row(log_time, msg))
    counts = {topic: len(rows) for topic, rows in ours.items()}
    assert {topic: c['count'] for topic, c in foxglove.items() if c['count']} == counts
    assert counts == {name: t.count for name, t in reader.topics.items() if t.count}
    for topic in counts:
        assert from_foxglove[topic] == ours[topic], topic
        assert from_rosbags[topic] == ours[topic], topic
    stamped = [topic for topic, rows in ours.items() if rows[0][1] is not None]
    joint_states = ours[contract.JOINT_STATES.resolved('left')]
    assert len(stamped) >= 15 and {row[4] for row in joint_states} == {21}
    print(f'\n{sum(counts.values())} messages on {len(counts)} topics ({len(stamped)} with a '
          'header) decode alike with Foxglove, rosbags and our reader')


def test_recorder_qos_follows_publishers():
    """Reliable and latched only if every publisher offers it."""
    from dual_arm_control.nodes.bag_record import compatible_qos, RECORDER_DEPTH

    class Publisher:
        def __init__(self, reliability, durability):
            self.qos_profile = type('Q', (), {'reliability': reliability,
                                              'durability': durability})

    reliable = Publisher(ReliabilityPolicy.RELIABLE, DurabilityPolicy.TRANSIENT_LOCAL)
    best_effort = Publisher(ReliabilityPolicy.BEST_EFFORT, DurabilityPolicy.VOLATILE)
    both = compatible_qos([reliable, best_effort])
    assert both.reliability == ReliabilityPolicy.BEST_EFFORT
    assert both.durability == DurabilityPolicy.VOLATILE
    latched = compatible_qos([reliable])
    assert latched.reliability == ReliabilityPolicy.RELIABLE
    assert latched.durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert latched.depth == RECORDER_DEPTH


# -- torn, truncated and garbage files ---------------------------------------------------------

def messages_before_tear(path):
    """Count the messages mcap's streaming reader yields before it hits the tear."""
    count = 0
    with open(path, 'rb') as stream:
        try:
            for record in StreamReader(stream).records:
                count += isinstance(record, Message)
        except (McapError, EOFError, ValueError):
            pass
    return count


def bag_info(capsys, path):
    """Run bag_info on one file; return (exit code, stdout, stderr)."""
    code = bag_info_main([str(path)])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_killed_recorder_leaves_a_recoverable_torn_bag(tmp_path):
    """
    SIGKILL mid-recording: bag_info says 'torn' and recovers exactly the complete chunks.

    A probe publishes 4000 JointStates into the recorder (4 KiB chunks, no compression); the
    count recovered equals what mcap's own streaming reader yields before the tear.
    """
    domain_id = random.SystemRandom().randint(1, 200)
    bag = tmp_path / 'torn.mcap'
    recorder, log_path = start_recorder(tmp_path, domain_id, bag, '/probe/joint_states',
                                        '--chunk-size', '4096', '--compression', 'none')
    probe = GraphProbe(domain_id, 'bag_probe')
    try:
        from sensor_msgs.msg import JointState
        publisher = probe.node.create_publisher(JointState, '/probe/joint_states',
                                                contract.CONTROL_QOS)
        assert probe.spin_until(lambda: publisher.get_subscription_count() > 0, STARTUP_TIMEOUT)
        msg = JointState(name=['a'] * 7, position=[1.0] * 7)
        for index in range(4000):
            msg.header.stamp.sec = index
            publisher.publish(msg)
            if index % 200 == 0:
                probe.executor.spin_once(timeout_sec=0.001)
        time.sleep(1.0)
        stop_process(recorder, signal.SIGKILL)
    finally:
        probe.close()
        if recorder.poll() is None:
            recorder.kill()
    info = inspect_bag(bag)
    assert info.status == 'torn', info.problem
    assert info.chunk_count >= 5
    assert 0 < info.message_count == messages_before_tear(bag) <= 4000
    assert info.topics['/probe/joint_states'].type_name == 'sensor_msgs/msg/JointState'
    script = subprocess.run([str(SCRIPTS / 'bag_info'), str(bag)], capture_output=True,
                            text=True, timeout=30)
    assert script.returncode == 1 and 'Status:            torn' in script.stdout
    assert len(script.stderr.strip().splitlines()) == 1
    assert f'recovered {info.message_count}' in script.stderr


def test_truncated_and_garbage_files_give_one_line_errors(graph_bag, tmp_path, capsys):
    """Cut data, cut summary, a stub, garbage and a damaged chunk: exit 1, one stderr line."""
    bag, _, _ = graph_bag
    data = bag.read_bytes()
    complete = inspect_bag(bag)
    cases = {
        'half.mcap': (data[:len(data) // 2], 'torn'),
        'summary_cut.mcap': (data[:len(data) - 200], 'truncated'),
    }
    for name, (content, status) in cases.items():
        path = tmp_path / name
        path.write_bytes(content)
        info = inspect_bag(path)
        assert info.status == status, info.problem
        assert info.message_count <= complete.message_count
        code, out, err = bag_info(capsys, path)
        assert code == 1 and len(err.strip().splitlines()) == 1 and 'Traceback' not in err
    assert inspect_bag(tmp_path / 'summary_cut.mcap').message_count == complete.message_count
    first_chunk_damaged = bytearray(data[:len(data) // 2])
    first_chunk_damaged[300] ^= 0xFF
    errors = {'stub.mcap': (data[:5], 'shorter than the MCAP magic'),
              'garbage.mcap': (random.Random(3).randbytes(5000), 'not an MCAP file'),
              'damaged.mcap': (bytes(first_chunk_damaged), 'damaged')}
    for name, (content, expected) in errors.items():
        path = tmp_path / name
        path.write_bytes(content)
        code, out, err = bag_info(capsys, path)
        assert code == 1 and expected in err and len(err.strip().splitlines()) == 1, err
    code, _, err = bag_info(capsys, tmp_path / 'missing.mcap')
    assert code == 1 and 'cannot read' in err
    script = subprocess.run([str(SCRIPTS / 'bag_info'), str(tmp_path / 'garbage.mcap')],
                            capture_output=True, text=True, timeout=30)
    assert script.returncode == 1 and script.stderr.count('\n') == 1
    assert script.stderr.startswith('bag_info: ')


def test_a_flipped_byte_anywhere_in_the_data_is_reported_as_damage(graph_bag, tmp_path):
    """
    Damage inside a compressed chunk fails the CRC or the decompressor: both are reported.

    The file is cut in half (no summary), so its records are scanned and every chunk is
    decompressed.
    """
    bag, _, _ = graph_bag
    data = bag.read_bytes()[:bag.stat().st_size // 2]
    path = tmp_path / 'flipped.mcap'
    for offset in range(160, 1200, 7):
        damaged = bytearray(data)
        damaged[offset] ^= 0xFF
        path.write_bytes(bytes(damaged))
        summary = inspect_bag(path)
        assert summary.status in ('corrupt', 'torn'), (offset, summary.status)
        assert 'damaged' in summary.problem or 'ends inside' in summary.problem, \
            summary.problem


def test_bringup_record_flag_writes_a_complete_bag(tmp_path):
    """
    `dual_arm_bringup --record` leaves OUT/bag.mcap, complete, with every phase of the run.

    0.2 s of sim time: the phase is transient local, so all its ticks up to the last stepped
    cycle (40 at 200 Hz) are recorded whatever the discovery timing. The bag replaces an
    earlier one in OUT with its split files, and its log times are sim time.
    """
    out = tmp_path / 'run'
    out.mkdir()
    for name in ('bag.mcap', 'bag_1.mcap'):
        (out / name).write_bytes(b'an earlier run')
    record_episode(SCENARIO, out, 0.2, EPISODE_TIMEOUT)
    assert not (out / 'bag_1.mcap').exists()
    info = inspect_bag(out / 'bag.mcap')
    assert info.status == 'complete', (out / 'logs' / 'bag_record.log').read_text()
    # Every DS tick of the 0.2 s; the first may be there several times: the DS re-answers the
    # cycle-0 state each time the bridge republishes it while the nodes discover each other.
    phase_stamps = [message.publish_time for _, channel, message in
                    make_reader(open(out / 'bag.mcap', 'rb')).iter_messages()
                    if channel.topic == contract.PHASE.name]
    schedule = TickSchedule(0.005)
    ticks = []
    for cycle in range(100):
        if schedule.due(2_000_000 * cycle):
            schedule.take(2_000_000 * cycle)
            ticks.append(2_000_000 * cycle)
    assert len(ticks) == 40
    assert sorted(set(phase_stamps)) == ticks
    assert {stamp for stamp in phase_stamps if phase_stamps.count(stamp) > 1} <= {0}
    assert 'closed' in (out / 'logs' / 'bag_record.log').read_text()
    with open(out / 'bag.mcap', 'rb') as stream:
        metadata = {record.name: record.metadata
                    for record in make_reader(stream).iter_metadata()}
    assert metadata[METADATA_NAME] == {'scenario': str(SCENARIO.resolve())}
    assert metadata[SPLIT_METADATA_NAME]['split_index'] == '0'
    clock = [message.log_time for _, channel, message in
             make_reader(open(out / 'bag.mcap', 'rb')).iter_messages()
             if channel.topic == contract.CLOCK.name]
    assert 0 <= clock[0] <= clock[-1] <= seconds_to_ns(0.2 + 0.01)
    assert '(zstd, sim time)' in (out / 'logs' / 'bag_record.log').read_text()
