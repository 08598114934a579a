"""
BagWriter: serialized ROS 2 messages into MCAP files in the rosbag2 layout, optionally split.

Each file has profile 'ros2', one 'ros2msg' schema per type with the complete definition, one
'cdr' channel per topic with its offered QoS as 'offered_qos_profiles' metadata, chunked and
compressed data, and a summary (statistics, chunk and message indexes) written on close.
Every file also carries the MCAP metadata record SPLIT_METADATA_NAME with the recording's id and
the file's index in the set, so a reader can tell a continuation from a stale file.
"""

from pathlib import Path
import re
import struct
import uuid

from dual_arm_control.bags import BagError
from dual_arm_control.bags.schema import first_field_type, HEADER_TYPE, message_definition
from dual_arm_control.bags.schema import type_name as ros_type_name
from mcap.writer import CompressionType, Writer
from rclpy.qos import DurabilityPolicy, HistoryPolicy, LivelinessPolicy, ReliabilityPolicy

PROFILE = 'ros2'
SCHEMA_ENCODING = 'ros2msg'
MESSAGE_ENCODING = 'cdr'
DEFAULT_CHUNK_SIZE = 1024 * 1024
# Name of the MCAP metadata record with the run's facts (e.g. 'scenario': path).
METADATA_NAME = 'dual_arm_control'
# Name of the MCAP metadata record that places a file in its recording: {'recording_id': hex
# text, the same in every file of one recording; 'split_index': '0', '1', ...}.
SPLIT_METADATA_NAME = 'dual_arm_control/split'
COMPRESSIONS = {'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4,
                'none': CompressionType.NONE}
_CDR_LITTLE_ENDIAN_IDS = (0x01, 0x03)
_POLICY_NAMES = {
    'history': {HistoryPolicy.KEEP_LAST: 'keep_last', HistoryPolicy.KEEP_ALL: 'keep_all'},
    'reliability': {ReliabilityPolicy.RELIABLE: 'reliable',
                    ReliabilityPolicy.BEST_EFFORT: 'best_effort'},
    'durability': {DurabilityPolicy.VOLATILE: 'volatile',
                   DurabilityPolicy.TRANSIENT_LOCAL: 'transient_local'},
    'liveliness': {LivelinessPolicy.AUTOMATIC: 'automatic',
                   LivelinessPolicy.MANUAL_BY_TOPIC: 'manual_by_topic'},
}


def available_compressions():
    """Return the compression names the installed mcap package can write."""
    names = ['none']
    for name, module in (('zstd', 'zstandard'), ('lz4', 'lz4.frame')):
        try:
            __import__(module)
        except ImportError:
            continue
        names.append(name)
    return names


def _duration_yaml(duration):
    """Return a QoS duration as rosbag2's '{sec, nsec}' YAML mapping (0 = unspecified)."""
    nanoseconds = duration.nanoseconds if duration is not None else 0
    seconds, rest = divmod(int(nanoseconds), 1_000_000_000)
    return f'{{sec: {seconds}, nsec: {rest}}}'


def _policy_name(kind, value):
    """Return rosbag2's name of a QoS policy value ('system_default' for the others)."""
    return _POLICY_NAMES[kind].get(value, 'system_default')


def offered_qos_profiles(profiles):
    """Return the 'offered_qos_profiles' YAML of rosbag2 (bag version 9) for QoSProfiles."""
    entries = []
    for qos in profiles:
        entries.append('\n'.join((
            f'- history: {_policy_name("history", qos.history)}',
            f'  depth: {int(qos.depth)}',
            f'  reliability: {_policy_name("reliability", qos.reliability)}',
            f'  durability: {_policy_name("durability", qos.durability)}',
            f'  deadline: {_duration_yaml(qos.deadline)}',
            f'  lifespan: {_duration_yaml(qos.lifespan)}',
            f'  liveliness: {_policy_name("liveliness", qos.liveliness)}',
            f'  liveliness_lease_duration: {_duration_yaml(qos.liveliness_lease_duration)}',
            '  avoid_ros_namespace_conventions: '
            f'{"true" if qos.avoid_ros_namespace_conventions else "false"}')))
    return '\n'.join(entries) + '\n' if entries else '[]\n'


def header_stamp_ns(data):
    """
    Return the header stamp [ns] of a CDR message whose first field is std_msgs/Header.

    The stamp (int32 sec, uint32 nanosec) follows the 4-byte encapsulation header. Return None
    for a buffer too short to hold it.
    """
    if len(data) < 12:
        return None
    byte_order = '<' if data[1] in _CDR_LITTLE_ENDIAN_IDS else '>'
    seconds, nanoseconds = struct.unpack_from(f'{byte_order}iI', data, 4)
    return seconds * 1_000_000_000 + nanoseconds


def split_path(path, index):
    """Return the name of the index-th file of a split bag: path, then <stem>_<index><suffix>."""
    path = Path(path)
    if index == 0:
        return path
    return path.with_name(f'{path.stem}_{index}{path.suffix}')


def existing_bag_files(path):
    """Return the files of a bag at path that exist: path and any <stem>_<N><suffix> beside it."""
    path = Path(path)
    pattern = re.compile(rf'{re.escape(path.stem)}_\d+{re.escape(path.suffix)}')
    siblings = (sorted(p for p in path.parent.iterdir() if pattern.fullmatch(p.name))
                if path.parent.is_dir() else [])
    return ([path] if path.exists() else []) + siblings


class _Topic:
    """What a registered topic needs in every file: type, definition, QoS text, counts."""

    def __init__(self, name, msg_type_name, definition, qos_yaml, stamped):
        self.name = name
        self.type_name = msg_type_name
        self.definition = definition
        self.qos_yaml = qos_yaml
        self.stamped = stamped
        self.count = 0


class BagWriter:
    """
    Write serialized messages of registered topics into an MCAP bag (one or more files).

    log_time is the receive time [ns] on the recorder's clock, wall or sim time (kept
    non-decreasing per file), publish_time the message's header stamp when its type starts
    with std_msgs/Header, else the log time. split_size [bytes] or split_duration [s] start a
    new file <stem>_<N>.mcap once exceeded; split() starts one at once. metadata {key: text}
    goes into every file as the MCAP metadata record METADATA_NAME (e.g. the run's scenario
    file, so tools that read the bag can rebuild the scene). An existing bag at path (the file
    or its split files) is refused unless overwrite, which deletes all of them first.
    """

    def __init__(self, path, compression='zstd', chunk_size=DEFAULT_CHUNK_SIZE, split_size=None,
                 split_duration=None, metadata=None, overwrite=False):
        if compression not in available_compressions():
            raise BagError(f'compression {compression!r} is not available; choose one of '
                           f'{available_compressions()}')
        if chunk_size <= 0:
            raise BagError(f'chunk_size must be positive, got {chunk_size}')
        for name, value in (('split_size', split_size), ('split_duration', split_duration)):
            if value is not None and value <= 0:
                raise BagError(f'{name} must be positive, got {value}')
        self.path = Path(path)
        existing = existing_bag_files(self.path)
        if existing and not overwrite:
            raise BagError(f'{self.path}: a bag is already there '
                           f'({", ".join(p.name for p in existing)}); refusing to replace it '
                           'without overwrite (bag_record --overwrite)')
        for stale in existing:
            try:
                stale.unlink()
            except OSError as error:
                raise BagError(f'cannot replace {stale}: {error}') from error
        self.recording_id = uuid.uuid4().hex
        self.compression = compression
        self._chunk_size = int(chunk_size)
        self._split_size = split_size
        self._split_duration_ns = (int(split_duration * 1e9) if split_duration is not None
                                   else None)
        self.metadata = {str(key): str(value) for key, value in (metadata or {}).items()}
        self._topics = {}
        self.paths = []
        self._file = None
        self._writer = None
        self._open_next_file()

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.close()

    @property
    def counts(self):
        """Return {topic: messages written} over all files."""
        return {name: topic.count for name, topic in self._topics.items()}

    @property
    def topics(self):
        """Return {topic: 'package/msg/Type'} of the registered topics."""
        return {name: topic.type_name for name, topic in self._topics.items()}

    def add_topic(self, topic, msg_type, qos_profiles):
        """Register a topic with its message class or type name and offered QoS profile(s)."""
        if topic in self._topics:
            raise BagError(f'topic {topic} is already registered')
        if not isinstance(qos_profiles, (list, tuple)):
            qos_profiles = [qos_profiles]
        name = ros_type_name(msg_type)
        entry = _Topic(topic, name, message_definition(name), offered_qos_profiles(qos_profiles),
                       first_field_type(name) == HEADER_TYPE)
        self._topics[topic] = entry
        self._register(entry)

    def write(self, topic, data, log_time_ns):
        """Append one serialized (CDR) message of a registered topic received at log_time_ns."""
        if self._writer is None:
            raise BagError(f'bag {self.path} is closed')
        entry = self._topics.get(topic)
        if entry is None:
            raise BagError(f'topic {topic} is not registered in bag {self.path}')
        if self._split_due(log_time_ns):
            self._finish_file()
            self._open_next_file()
        log_time_ns = max(int(log_time_ns), self._last_log_time)
        if self._first_log_time is None:
            self._first_log_time = log_time_ns
        self._last_log_time = log_time_ns
        publish_time = header_stamp_ns(data) if entry.stamped else None
        channel_id = self._channels[topic]
        self._sequences[topic] += 1
        self._writer.add_message(channel_id, log_time_ns, bytes(data),
                                 log_time_ns if publish_time is None else publish_time,
                                 self._sequences[topic])
        entry.count += 1

    def split(self):
        """Close the current file with its summary and continue in the next split file."""
        if self._writer is None:
            raise BagError(f'bag {self.path} is closed')
        self._finish_file()
        self._open_next_file()

    def close(self):
        """Write the summary and close the current file (idempotent)."""
        if self._writer is not None:
            self._finish_file()

    def _split_due(self, log_time_ns):
        """Return True if the current file has reached the split size or duration."""
        if self._first_log_time is None:
            return False
        if self._split_size is not None and self._file.tell() >= self._split_size:
            return True
        return (self._split_duration_ns is not None
                and log_time_ns - self._first_log_time >= self._split_duration_ns)

    def _open_next_file(self):
        """Open the next file of the bag and register every known topic in it."""
        path = split_path(self.path, len(self.paths))
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            self._file = open(path, 'xb')
        except OSError as error:
            raise BagError(f'cannot create bag file {path}: {error}') from error
        self.paths.append(path)
        self._writer = Writer(self._file, chunk_size=self._chunk_size,
                              compression=COMPRESSIONS[self.compression])
        self._writer.start(profile=PROFILE, library='dual_arm_control')
        self._writer.add_metadata(SPLIT_METADATA_NAME, {
            'recording_id': self.recording_id, 'split_index': str(len(self.paths) - 1)})
        if self.metadata:
            self._writer.add_metadata(METADATA_NAME, self.metadata)
        self._schemas = {}
        self._channels = {}
        self._sequences = {}
        self._first_log_time = None
        self._last_log_time = 0
        for entry in self._topics.values():
            self._register(entry)

    def _register(self, entry):
        """Register the schema (once per type) and the channel of a topic in the current file."""
        schema_id = self._schemas.get(entry.type_name)
        if schema_id is None:
            schema_id = self._writer.register_schema(
                entry.type_name, SCHEMA_ENCODING, entry.definition.encode())
            self._schemas[entry.type_name] = schema_id
        self._channels[entry.name] = self._writer.register_channel(
            entry.name, MESSAGE_ENCODING, schema_id,
            {'offered_qos_profiles': entry.qos_yaml})
        self._sequences[entry.name] = 0

    def _finish_file(self):
        """Write the current file's summary and footer and close it."""
        try:
            self._writer.finish()
        finally:
            self._file.close()
            self._writer = None
