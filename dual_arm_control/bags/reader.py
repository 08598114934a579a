"""
BagReader: the messages of an MCAP bag (one file, its split files or a rosbag2 folder) in order.

Messages come out as raw CDR with topic, type name, log time and publish time, in log-time
order across all files of the bag (ties keep the recorded order). Each topic's offered QoS is
read back from the 'offered_qos_profiles' channel metadata (bags/offered_qos.py). Damaged files
(torn, truncated, corrupt: see bags/info.py) are refused unless recovery is asked for; then the
messages of their complete records are read. Files that name their recording (BagWriter's
split metadata) must be the splits 0, 1, ... of one recording, so a stale <stem>_N.mcap left by
an earlier recording is refused instead of being read as a continuation.
"""

from dataclasses import dataclass, field
import heapq
import io
from pathlib import Path
import re

from dual_arm_control.bags import BagError
from dual_arm_control.bags.info import inspect_bag, MAGIC
from dual_arm_control.bags.offered_qos import qos_from_offered_profiles
from dual_arm_control.bags.writer import SPLIT_METADATA_NAME, split_path
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, DataEnd, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
import yaml

METADATA_FILE = 'metadata.yaml'
_READ_ERRORS = (McapError, EOFError, ValueError, KeyError, UnicodeDecodeError, OSError)


@dataclass(frozen=True)
class BagMessage:
    """One recorded message: topic, 'package/msg/Type', log and publish time [ns], CDR bytes."""

    topic: str
    type_name: str
    log_time: int
    publish_time: int
    data: bytes


@dataclass
class BagTopic:
    """A topic of a bag: its type, the offered QoS profiles as recorded (YAML), message count."""

    name: str
    type_name: str
    qos_yaml: str = ''
    count: int = 0

    @property
    def qos(self):
        """Return the QoSProfile to replay this topic with (see qos_from_offered_profiles)."""
        return qos_from_offered_profiles(self.qos_yaml)


@dataclass
class _File:
    """One file of a bag: its inspection summary and, when damaged, the recoverable bytes."""

    path: Path
    summary: object
    channels: dict = field(default_factory=dict)
    schemas: dict = field(default_factory=dict)


# -- the files of a bag ------------------------------------------------------------------------

def bag_files(path):
    """
    Return the files of a bag, in order.

    A rosbag2 folder: the relative_file_paths of its metadata.yaml (or, without one, its
    .mcap files in name order). An .mcap file: it and its split continuations <stem>_1.mcap,
    <stem>_2.mcap, ... as BagWriter names them. The files must be one recording (see
    check_one_recording).
    """
    path = Path(path)
    if path.is_dir():
        files = _folder_files(path)
    elif not path.is_file():
        raise BagError(f'{path}: no such bag file or folder')
    else:
        files = [path]
        while split_path(path, len(files)).is_file():
            files.append(split_path(path, len(files)))
    check_one_recording(files)
    return files


def split_mark(path):
    """
    Return the split metadata {'recording_id', 'split_index'} of a bag file, or None.

    BagWriter writes it right after the MCAP header, so only the records before the first
    chunk or message are read (also of a torn file).
    """
    try:
        with open(path, 'rb') as stream:
            for record in StreamReader(stream).records:
                if isinstance(record, Metadata) and record.name == SPLIT_METADATA_NAME:
                    return dict(record.metadata)
                if isinstance(record, (Chunk, DataEnd, Message)):
                    return None
    except _READ_ERRORS:
        return None
    return None


def check_one_recording(files):
    """
    Raise BagError unless the files are consecutive splits of one recording, in order.

    The first file may be any split (a later part read alone). Files without split metadata
    (other writers, bags from before it existed) pass when none of the set has any.
    """
    marks = [split_mark(file) for file in files]
    if all(mark is None for mark in marks):
        return
    recording = (marks[0] or {}).get('recording_id')
    first_index = (marks[0] or {}).get('split_index', '0')
    if not first_index.isdigit():
        raise BagError(f'{files[0]}: split_index {first_index!r} of its {SPLIT_METADATA_NAME} '
                       'metadata is not a number')
    first_index = int(first_index)
    for position, (file, mark) in enumerate(zip(files, marks)):
        mark = mark or {}
        index = first_index + position
        if mark.get('recording_id') != recording:
            raise BagError(
                f'{file} is not part of the recording in {files[0]}: it belongs to '
                f'recording {mark.get("recording_id", "(none recorded)")}, '
                f'{files[0].name} to {recording or "(none recorded)"}; a stale split file '
                'from an earlier recording? Move or delete it')
        if mark.get('split_index') != str(index):
            raise BagError(f'{file}: split {mark.get("split_index")} of its recording '
                           f'where split {index} belongs; a split file is missing')


def _folder_files(folder):
    """Return the data files of a rosbag2 folder."""
    metadata_path = folder / METADATA_FILE
    if not metadata_path.is_file():
        files = sorted(folder.glob('*.mcap'), key=_natural_key)
        if not files:
            raise BagError(f'{folder}: no {METADATA_FILE} and no .mcap files')
        return files
    try:
        metadata = yaml.safe_load(metadata_path.read_text())
    except (OSError, yaml.YAMLError) as error:
        raise BagError(f'{metadata_path}: cannot read: {error}') from error
    information = (metadata or {}).get('rosbag2_bagfile_information') if isinstance(
        metadata, dict) else None
    if not isinstance(information, dict):
        raise BagError(f'{metadata_path}: no rosbag2_bagfile_information mapping')
    storage = information.get('storage_identifier', 'mcap')
    if storage != 'mcap':
        raise BagError(f'{metadata_path}: storage {storage!r} is not supported (only mcap)')
    names = information.get('relative_file_paths') or []
    if not names:
        raise BagError(f'{metadata_path}: relative_file_paths is empty')
    files = [folder / name for name in names]
    for file in files:
        if not file.is_file():
            raise BagError(f'{metadata_path}: listed file {file} does not exist')
        if file.suffix in ('.zstd', '.lz4'):
            raise BagError(f'{file}: file-compressed bags are not supported; decompress it')
    return files


def _natural_key(path):
    """Sort key that puts bag_2.mcap before bag_10.mcap."""
    return [int(part) if part.isdigit() else part for part in re.split(r'(\d+)', path.name)]


def _damage_line(summary):
    """Return 'FILE is torn (why); N messages are recoverable' for a damaged file."""
    return (f'{summary.path} is {summary.status} ({summary.problem}); '
            f'{summary.message_count} messages are recoverable')


class BagReader:
    """
    The messages of a bag in log-time order, with its topics (type, QoS, count) and time span.

    Damaged files raise BagError naming the file, the damage and what is recoverable, unless
    recover=True: then `damaged` lists their summaries (bags/info.py BagSummary) and only the
    messages of their complete records are read.
    """

    def __init__(self, path, recover=False):
        self.path = Path(path)
        self._files = [self._open(file, recover) for file in bag_files(path)]
        self.damaged = [f.summary for f in self._files if f.summary.status != 'complete']
        self.topics = {}
        for file in self._files:
            self._add_topics(file)
        starts = [f.summary.start_ns for f in self._files if f.summary.start_ns is not None]
        ends = [f.summary.end_ns for f in self._files if f.summary.end_ns is not None]
        self.start_ns = min(starts) if starts else None
        self.end_ns = max(ends) if ends else None

    @property
    def files(self):
        """Return the paths of the bag's files, in order."""
        return [file.path for file in self._files]

    @property
    def message_count(self):
        """Return the number of (readable) messages over all topics."""
        return sum(topic.count for topic in self.topics.values())

    def _open(self, path, recover):
        """Inspect one file; refuse a damaged one unless recovering."""
        summary = inspect_bag(path)
        if summary.status != 'complete' and not recover:
            raise BagError(f'{_damage_line(summary)}: pass --recover to play them')
        file = _File(path, summary)
        if summary.status == 'complete':
            with open(path, 'rb') as stream:
                mcap_summary = make_reader(stream).get_summary()
            file.channels = dict(mcap_summary.channels)
            file.schemas = dict(mcap_summary.schemas)
        else:
            for record in _recoverable_records(path, summary):
                if isinstance(record, Schema):
                    file.schemas[record.id] = record
                elif isinstance(record, Channel):
                    file.channels[record.id] = record
        return file

    def _add_topics(self, file):
        """Merge one file's channels and counts into the bag's topics."""
        for channel in file.channels.values():
            schema = file.schemas.get(channel.schema_id)
            type_name = schema.name if schema is not None else ''
            topic = self.topics.get(channel.topic)
            if topic is None:
                topic = self.topics[channel.topic] = BagTopic(
                    channel.topic, type_name, channel.metadata.get('offered_qos_profiles', ''))
            elif topic.type_name != type_name:
                raise BagError(f'{file.path}: topic {channel.topic} has type {type_name} here '
                               f'but {topic.type_name} in an earlier file')
        for name, info in file.summary.topics.items():
            if name in self.topics:
                self.topics[name].count += info.count

    def metadata(self, name):
        """Return the first metadata record called name ({key: value}) of the bag, or None."""
        for file in self._files:
            if file.summary.status != 'complete':
                continue
            try:
                with open(file.path, 'rb') as stream:
                    for record in make_reader(stream).iter_metadata():
                        if record.name == name:
                            return dict(record.metadata)
            except _READ_ERRORS as error:
                raise BagError(f'{file.path}: cannot read metadata: {error}') from error
        return None

    def messages(self, topics=None, start_ns=None, end_ns=None):
        """
        Yield BagMessages of the given topics (default all) with start_ns <= log time < end_ns.

        Log-time order across files; equal log times keep the order of the files and, within
        a file, the recorded order.
        """
        wanted = None if topics is None else frozenset(topics)
        streams = [self._file_messages(file, wanted, start_ns, end_ns)
                   for file in self._files]
        return heapq.merge(*streams, key=lambda message: message.log_time)

    def _file_messages(self, file, wanted, start_ns, end_ns):
        """Yield the selected messages of one file in log-time order."""
        if file.summary.status != 'complete':
            records = [r for r in _recoverable_records(file.path, file.summary)
                       if isinstance(r, Message)]
            records.sort(key=lambda record: record.log_time)
            for record in records:
                message = self._message(file, record, wanted, start_ns, end_ns)
                if message is not None:
                    yield message
            return
        with open(file.path, 'rb') as stream:
            reader = make_reader(stream)
            try:
                for _, _, record in reader.iter_messages(
                        topics=None if wanted is None else list(wanted),
                        starting_at=start_ns, ending_before=end_ns, log_time_order=True):
                    message = self._message(file, record, wanted, start_ns, end_ns)
                    if message is not None:
                        yield message
            except _READ_ERRORS as error:
                raise BagError(f'{file.path}: cannot read messages: {error}') from error

    def _message(self, file, record, wanted, start_ns, end_ns):
        """Return the BagMessage of a record, or None if it is outside the selection."""
        channel = file.channels.get(record.channel_id)
        if channel is None or (wanted is not None and channel.topic not in wanted):
            return None
        if (start_ns is not None and record.log_time < start_ns) or (
                end_ns is not None and record.log_time >= end_ns):
            return None
        return BagMessage(channel.topic, self.topics[channel.topic].type_name, record.log_time,
                          record.publish_time, bytes(record.data))


def _recoverable_records(path, summary):
    """Return the records of a damaged file's complete part (up to the damage), in order."""
    data = path.read_bytes()[:max(summary.recovered_bytes, len(MAGIC))]
    records = []
    reader = StreamReader(io.BytesIO(data), validate_crcs=True)
    try:
        for record in reader.records:
            records.append(record)
    except _READ_ERRORS:
        pass
    return records
