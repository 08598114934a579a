"""
bag_info: what an MCAP bag holds, like `ros2 bag info`, and what survives of a damaged one.

A complete bag is described from its summary section. A bag without a readable summary (the
recorder was killed: 'torn'; the summary was cut off: 'truncated') or with a damaged record
('corrupt') is scanned record by record: every complete chunk up to the damage is decoded and
counted, and the report says where and why the scan stopped. Exit code 0 for a complete bag,
1 for anything else, with one line on stderr naming the problem.
"""

import argparse
from dataclasses import dataclass, field
from datetime import datetime, timezone
import io
from pathlib import Path
import struct
import sys

from dual_arm_control.bags import BagError
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.reader import breakup_chunk, make_reader
from mcap.records import Channel, Chunk, Header, Message, Schema

MAGIC = b'\x89MCAP0\r\n'
RECORD_PREFIX_SIZE = 9
_KNOWN_OPCODES = frozenset(int(opcode) for opcode in Opcode)
_FIRST_USER_OPCODE = 0x80


@dataclass
class TopicInfo:
    """One topic of a bag: message type and number of messages."""

    type_name: str
    count: int = 0


@dataclass
class BagSummary:
    """
    What a bag file holds.

    status is 'complete', 'torn' (no data end: writing was interrupted), 'truncated' (data
    complete, summary cut off) or 'corrupt'; problem says where and why for the last three.
    Times are log times [ns]; None without messages.
    """

    path: Path
    size: int
    status: str = 'complete'
    problem: str = ''
    profile: str = ''
    library: str = ''
    compressions: set = field(default_factory=set)
    chunk_count: int = 0
    topics: dict = field(default_factory=dict)
    start_ns: int = None
    end_ns: int = None
    recovered_bytes: int = 0

    @property
    def message_count(self):
        """Return the number of messages over all topics."""
        return sum(topic.count for topic in self.topics.values())

    @property
    def duration_ns(self):
        """Return end - start log time [ns] (0 without messages)."""
        return 0 if self.start_ns is None else self.end_ns - self.start_ns


def inspect_bag(path):
    """Return the BagSummary of an MCAP file; raise BagError if it is no MCAP file at all."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as error:
        raise BagError(f'cannot read {path}: {error.strerror or error}') from error
    if len(data) < len(MAGIC) and MAGIC.startswith(data):
        raise BagError(f'{path}: truncated: {len(data)} bytes, shorter than the MCAP magic')
    if not data.startswith(MAGIC):
        raise BagError(f'{path}: not an MCAP file (the first bytes are not the MCAP magic)')
    summary = BagSummary(path=path, size=len(data))
    if data.endswith(MAGIC) and len(data) > 2 * len(MAGIC) and _read_summary(data, summary):
        return summary
    _scan_records(data, summary)
    return summary


def _read_summary(data, summary):
    """Fill the summary from the file's summary section; return False if it has none."""
    try:
        reader = make_reader(io.BytesIO(data))
        header = reader.get_header()
        mcap_summary = reader.get_summary()
    except (McapError, EOFError, struct.error, ValueError, KeyError) as error:
        summary.problem = f'summary section unreadable ({error})'
        return False
    if mcap_summary is None or mcap_summary.statistics is None:
        return False
    statistics = mcap_summary.statistics
    summary.profile, summary.library = header.profile, header.library
    summary.compressions = {index.compression or 'none'
                            for index in mcap_summary.chunk_indexes}
    summary.chunk_count = statistics.chunk_count
    for channel_id, channel in mcap_summary.channels.items():
        schema = mcap_summary.schemas.get(channel.schema_id)
        topic = summary.topics.setdefault(
            channel.topic, TopicInfo(schema.name if schema else '(no schema)'))
        topic.count += statistics.channel_message_counts.get(channel_id, 0)
    if statistics.message_count:
        summary.start_ns = statistics.message_start_time
        summary.end_ns = statistics.message_end_time
    summary.recovered_bytes = len(data)
    return True


class _Scan:
    """The state of a record-by-record scan: known schemas and channels, counts, times."""

    def __init__(self, summary):
        self.summary = summary
        self.schemas = {}
        self.channels = {}

    def add(self, record):
        """Take one record found in the data section or inside a chunk."""
        if isinstance(record, Schema):
            self.schemas[record.id] = record
        elif isinstance(record, Channel):
            self.channels[record.id] = record
        elif isinstance(record, Message):
            channel = self.channels.get(record.channel_id)
            if channel is None:
                raise BagError(f'message on unknown channel {record.channel_id}')
            schema = self.schemas.get(channel.schema_id)
            topic = self.summary.topics.setdefault(
                channel.topic, TopicInfo(schema.name if schema else '(no schema)'))
            topic.count += 1
            summary = self.summary
            summary.start_ns = (record.log_time if summary.start_ns is None
                                else min(summary.start_ns, record.log_time))
            summary.end_ns = (record.log_time if summary.end_ns is None
                              else max(summary.end_ns, record.log_time))


def _record_name(opcode):
    """Return the MCAP name of an opcode ('Chunk', 'Message', ...)."""
    try:
        return Opcode(opcode).name.title().replace('_', '')
    except ValueError:
        return f'0x{opcode:02x}'


def _scan_records(data, summary):
    """Decode the data section record by record until its end, a tear or corrupt bytes."""
    scan = _Scan(summary)
    offset = len(MAGIC)
    data_end_seen = False
    while True:
        if offset == len(data):
            _stop(summary, 'truncated' if data_end_seen else 'torn',
                  f'the file ends at byte {offset} after a complete record, with no '
                  f'{"footer" if data_end_seen else "data end record or summary"}')
            return
        if len(data) - offset < RECORD_PREFIX_SIZE:
            _stop(summary, 'truncated' if data_end_seen else 'torn',
                  f'the file ends inside a record header at byte {len(data)}')
            return
        opcode = data[offset]
        (length,) = struct.unpack_from('<Q', data, offset + 1)
        start = offset + RECORD_PREFIX_SIZE
        if opcode not in _KNOWN_OPCODES and opcode < _FIRST_USER_OPCODE:
            _stop(summary, 'corrupt', f'invalid record opcode 0x{opcode:02x} at byte {offset}')
            return
        if start + length > len(data):
            _stop(summary, 'truncated' if data_end_seen else 'torn',
                  f'the file ends inside a {_record_name(opcode)} record at byte {offset} '
                  f'({len(data) - start} of its {length} bytes present)')
            return
        try:
            if opcode == Opcode.FOOTER and data_end_seen:
                _stop(summary, 'truncated',
                      f'no readable summary ({summary.problem or "summary section missing"})')
                return
            if not data_end_seen:
                _decode(scan, opcode, data[start:start + length])
        except (BagError, McapError, EOFError, struct.error, ValueError, KeyError,
                UnicodeDecodeError) as error:
            _stop(summary, 'corrupt', f'{_record_name(opcode)} record at byte {offset} is '
                                      f'damaged ({error})')
            return
        offset = start + length
        if opcode == Opcode.DATA_END:
            data_end_seen = True
        if not data_end_seen:
            summary.recovered_bytes = offset


def _decode(scan, opcode, content):
    """Decode one data-section record into the scan (chunks are decompressed, CRC-checked)."""
    stream = ReadDataStream(io.BytesIO(content))
    if opcode == Opcode.HEADER:
        header = Header.read(stream)
        scan.summary.profile, scan.summary.library = header.profile, header.library
    elif opcode == Opcode.SCHEMA:
        scan.add(Schema.read(stream))
    elif opcode == Opcode.CHANNEL:
        scan.add(Channel.read(stream))
    elif opcode == Opcode.MESSAGE:
        scan.add(Message.read(stream, len(content)))
    elif opcode == Opcode.CHUNK:
        chunk = Chunk.read(stream)
        try:
            records = breakup_chunk(chunk, validate_crc=True)
        except Exception as error:  # zstandard and lz4 raise their own error types
            raise BagError(f'its {chunk.compression or "uncompressed"} data does not '
                           f'decompress: {error}') from error
        for record in records:
            scan.add(record)
        scan.summary.chunk_count += 1
        scan.summary.compressions.add(chunk.compression or 'none')


def _stop(summary, status, problem):
    """Record why the scan stopped."""
    summary.status = status
    summary.problem = problem


def _format_time(stamp_ns):
    """Return a log time as 'Mon DD YYYY HH:MM:SS.nnnnnnnnn (seconds.nanoseconds)' in UTC."""
    seconds, nanoseconds = divmod(stamp_ns, 1_000_000_000)
    moment = datetime.fromtimestamp(seconds, tz=timezone.utc)
    return (f'{moment:%b %d %Y %H:%M:%S}.{nanoseconds:09d} '
            f'({seconds}.{nanoseconds:09d})')


def _format_size(size):
    """Return a byte count in B, KiB, MiB or GiB."""
    for unit in ('B', 'KiB', 'MiB'):
        if size < 1024:
            return f'{size:.1f} {unit}' if unit != 'B' else f'{size} B'
        size /= 1024
    return f'{size:.1f} GiB'


def format_report(summary):
    """Return the human-readable report of a BagSummary (the layout of `ros2 bag info`)."""
    lines = [f'Files:             {summary.path}',
             f'Bag size:          {_format_size(summary.size)}',
             'Storage id:        mcap',
             f'Profile:           {summary.profile or "(none)"}',
             f'Status:            {summary.status}']
    if summary.status != 'complete':
        lines.append(f'Problem:           {summary.problem}')
        lines.append(f'Recovered:         {summary.message_count} messages in '
                     f'{summary.chunk_count} complete chunks (first {summary.recovered_bytes} '
                     f'of {summary.size} bytes)')
    lines.append(f'Duration:          {summary.duration_ns / 1e9:.9f}s')
    if summary.start_ns is not None:
        lines.append(f'Start:             {_format_time(summary.start_ns)}')
        lines.append(f'End:               {_format_time(summary.end_ns)}')
    lines.append(f'Messages:          {summary.message_count}')
    lines.append(f'Chunks:            {summary.chunk_count}')
    lines.append(f'Compression:       {", ".join(sorted(summary.compressions)) or "none"}')
    width = max((len(name) for name in summary.topics), default=0)
    for index, (name, topic) in enumerate(sorted(summary.topics.items())):
        label = 'Topic information: ' if index == 0 else ' ' * 19
        lines.append(f'{label}Topic: {name:<{width}} | Type: {topic.type_name} | '
                     f'Count: {topic.count} | Serialization Format: cdr')
    return '\n'.join(lines)


def main(argv=None):
    """Print the report of each bag file given; return 0 if all are complete, else 1."""
    parser = argparse.ArgumentParser(
        prog='bag_info', description=__doc__.split('\n')[1],
        epilog='exit codes: 0 every file is a complete bag; 1 a file is damaged (torn, '
               'truncated, corrupt: the report shows what is recoverable), not an MCAP file or '
               'unreadable; 2 bad arguments')
    parser.add_argument('paths', nargs='+', type=Path, help='MCAP bag file(s)')
    args = parser.parse_args(argv)
    status = 0
    for path in args.paths:
        try:
            summary = inspect_bag(path)
        except BagError as error:
            print(f'bag_info: {error}', file=sys.stderr)
            status = 1
            continue
        print(format_report(summary))
        if summary.status != 'complete':
            print(f'bag_info: {path}: {summary.status}: {summary.problem}; recovered '
                  f'{summary.message_count} messages from {summary.chunk_count} complete '
                  f'chunks', file=sys.stderr)
            status = 1
    return status


if __name__ == '__main__':
    sys.exit(main())
