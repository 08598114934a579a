"""
dual_arm_param: list, get, set, dump and load the parameters of running nodes, like `ros2 param`.

It talks to the standard rcl_interfaces parameter services every node offers, so it works with
any ROS 2 node. Values typed on the command line are YAML (`true`, `1`, `1.0`, `[1.0, 2.0]`,
strings otherwise); an integer given for a double parameter is converted. `dump` writes a file
that `--ros-args --params-file FILE` and `load` read back. Exit codes: 0 success, 1 the node
refused or lacks the parameter, 2 user error (unknown node, bad file).
"""

import argparse
from dataclasses import dataclass
import os
from pathlib import Path
import re
import sys
import time

from dual_arm_control.bags.writer import split_path
from dual_arm_control.core.exceptions import InputError
from mcap.exceptions import McapError
from mcap.reader import make_reader
from rcl_interfaces.msg import ParameterEvent, ParameterType
import rclpy
from rclpy.exceptions import NameValidationException
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter, parameter_value_to_python
from rclpy.parameter_client import AsyncParameterClient
from rclpy.serialization import deserialize_message
import yaml

PARAMETER_EVENTS_TOPIC = '/parameter_events'
DISCOVERY_SETTLE_TIME = 0.5
GRAPH_POLL_PERIOD = 0.02
UNBOUNDED = 2 ** 62
EXIT_FAILED = 1
EXIT_USER_ERROR = 2

_TYPE_NAMES = {
    ParameterType.PARAMETER_NOT_SET: 'not set',
    ParameterType.PARAMETER_BOOL: 'boolean',
    ParameterType.PARAMETER_INTEGER: 'integer',
    ParameterType.PARAMETER_DOUBLE: 'double',
    ParameterType.PARAMETER_STRING: 'string',
    ParameterType.PARAMETER_BYTE_ARRAY: 'byte array',
    ParameterType.PARAMETER_BOOL_ARRAY: 'boolean array',
    ParameterType.PARAMETER_INTEGER_ARRAY: 'integer array',
    ParameterType.PARAMETER_DOUBLE_ARRAY: 'double array',
    ParameterType.PARAMETER_STRING_ARRAY: 'string array',
}
_VALUE_LABELS = {
    ParameterType.PARAMETER_BOOL: 'Boolean value is',
    ParameterType.PARAMETER_INTEGER: 'Integer value is',
    ParameterType.PARAMETER_DOUBLE: 'Double value is',
    ParameterType.PARAMETER_STRING: 'String value is',
    ParameterType.PARAMETER_BYTE_ARRAY: 'Byte values are',
    ParameterType.PARAMETER_BOOL_ARRAY: 'Boolean values are',
    ParameterType.PARAMETER_INTEGER_ARRAY: 'Integer values are',
    ParameterType.PARAMETER_DOUBLE_ARRAY: 'Double values are',
    ParameterType.PARAMETER_STRING_ARRAY: 'String values are',
}
_ARRAY_TYPES = (ParameterType.PARAMETER_BOOL_ARRAY, ParameterType.PARAMETER_INTEGER_ARRAY,
                ParameterType.PARAMETER_DOUBLE_ARRAY, ParameterType.PARAMETER_STRING_ARRAY)


# -- values, names and files (no ROS graph) ---------------------------------------------------

def parse_value(text):
    """
    Return the Python value of a command-line VALUE read as YAML, as `ros2 param set` does.

    Booleans, integers, floats and homogeneous lists of them (a list mixing ints and floats
    becomes floats) keep their YAML type; anything else (mappings, mixed lists, null, text
    that is not YAML) is the string as typed.
    """
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        return text
    if isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, list):
        for kind in (bool, int, str):
            if all(type(item) is kind for item in value):
                return value
        if all(type(item) in (int, float) for item in value):
            return [float(item) for item in value]
    return text


def coerce_value(value, declared_type, text=None):
    """
    Return value converted to the node's declared parameter type where that loses nothing.

    An int, or text such as 1e-5 (a string to YAML 1.1), becomes a float for a double; a list
    of ints becomes floats for a double array; an empty list takes the declared array type; a
    non-string becomes `text` (what the user typed) for a string. Anything else is returned
    unchanged and the node decides.
    """
    if declared_type == ParameterType.PARAMETER_DOUBLE and type(value) in (int, str):
        try:
            return float(value)
        except ValueError:
            return value
    if (declared_type == ParameterType.PARAMETER_DOUBLE_ARRAY and isinstance(value, list)
            and all(type(item) in (int, float) for item in value)):
        return [float(item) for item in value]
    if declared_type == ParameterType.PARAMETER_STRING and not isinstance(value, str):
        return text if text is not None else str(value)
    return value


def parameter_message(name, value, declared_type=None):
    """Return the rcl_interfaces Parameter message of value; InputError if ROS has no type."""
    if value == [] and declared_type in _ARRAY_TYPES:
        return Parameter(name, Parameter.Type(declared_type), []).to_parameter_msg()
    try:
        return Parameter(name, value=value).to_parameter_msg()
    except (TypeError, ValueError):
        raise InputError(f'{name}: {value!r} is not a ROS parameter value (bool, int, float, '
                         f'string or a list of one of them)') from None


def describe_value(parameter_value):
    """Return the `ros2 param get` line of a ParameterValue, e.g. 'Double value is: 1.5'."""
    label = _VALUE_LABELS.get(parameter_value.type)
    if label is None:
        return 'Parameter not set.'
    return f'{label}: {parameter_value_to_python(parameter_value)}'


def nested_parameters(values):
    """
    Return {dotted name: value} as nested mappings (a.b.c -> {a: {b: {c: v}}}).

    ROS params files join nested keys with dots. A name under an existing leaf (a and a.b both
    set) keeps its remaining dotted key at that level, which reads back to the same name.
    """
    tree = {}
    for name in sorted(values):
        level = tree
        parts = name.split('.')
        for index, part in enumerate(parts[:-1]):
            child = level.setdefault(part, {})
            if not isinstance(child, dict):
                parts = parts[:index] + ['.'.join(parts[index:])]
                break
            level = child
        level[parts[-1]] = values[name]
    return tree


def flat_parameters(tree, prefix=''):
    """Return {dotted name: value} of nested parameter mappings (inverse of nested_parameters)."""
    values = {}
    for key, value in tree.items():
        name = f'{prefix}{key}'
        if isinstance(value, dict):
            values.update(flat_parameters(value, f'{name}.'))
        else:
            values[name] = value
    return values


class _ParamsDumper(yaml.SafeDumper):
    """Block-style mappings, one-line lists: the layout of `ros2 param dump`."""


_ParamsDumper.add_representer(
    list, lambda dumper, items: dumper.represent_sequence(
        'tag:yaml.org,2002:seq', items, flow_style=True))


def dump_text(node_name, values):
    """Return the params-file YAML of one node's {name: value} (floats stay floats)."""
    document = {node_name: {'ros__parameters': nested_parameters(values)}}
    return yaml.dump(document, Dumper=_ParamsDumper, default_flow_style=False, sort_keys=True,
                     width=1 << 16)


def full_node_name(name):
    """Return a node name with its leading slash (ds_motion_generator -> /ds_motion_generator)."""
    return name if name.startswith('/') else f'/{name}'


def _node_entries(document, prefix=''):
    """Yield (node key, ros__parameters mapping) of a params document, nested namespaces joined."""
    for key, value in document.items():
        key = f'{prefix}/{str(key).strip("/")}'
        if not isinstance(value, dict):
            raise InputError(f'{key}: expected a mapping with ros__parameters')
        if 'ros__parameters' in value:
            parameters = value['ros__parameters']
            if not isinstance(parameters, dict):
                raise InputError(f'{key}: ros__parameters is not a mapping')
            yield key, parameters
        else:
            yield from _node_entries(value, key)


def _node_pattern(key):
    """Return the regular expression of a params-file node key (* one token, ** any)."""
    tokens = re.split(r'(\*\*|\*)', key)
    wildcards = {'**': '.*', '*': '[^/]*'}
    return ''.join(wildcards.get(token, re.escape(token)) for token in tokens)


def parameters_for_node(document, node_name):
    """
    Return {dotted name: value} a params document gives to one node.

    Keys are full node names, nested namespaces or wildcards (`/**`, `/**/name`, `/ns/*`);
    wildcard entries apply first so the node's own key overrides them, as in rcl.
    """
    if not isinstance(document, dict):
        raise InputError('expected a mapping of node names to ros__parameters')
    node_name = full_node_name(node_name)
    entries = sorted(_node_entries(document), key=lambda entry: '*' not in entry[0])
    values = {}
    for key, parameters in entries:
        if re.fullmatch(_node_pattern(key), node_name):
            values.update(flat_parameters(parameters))
    return values


def read_params_file(path, node_name):
    """Return the parameters a params file gives to node_name; InputError naming the file."""
    try:
        document = yaml.safe_load(Path(path).read_text())
    except OSError as error:
        raise InputError(f'{path}: cannot read: {error.strerror}') from None
    except yaml.YAMLError as error:
        mark = getattr(error, 'problem_mark', None)
        where = f'line {mark.line + 1}, column {mark.column + 1}: ' if mark else ''
        problem = getattr(error, 'problem', None) or ' '.join(str(error).split())
        raise InputError(f'{path}: not valid YAML: {where}{problem}') from None
    try:
        values = parameters_for_node(document, node_name)
    except InputError as error:
        raise InputError(f'{path}: not a ROS params file: {error}') from None
    if not values:
        raise InputError(f'{path}: no parameters for {full_node_name(node_name)} '
                         f'(node keys: {", ".join(str(key) for key in document)})')
    return values


# -- parameter events in a bag ----------------------------------------------------------------

@dataclass(frozen=True)
class ParameterChange:
    """One parameter of a /parameter_events message: kind is 'new', 'changed' or 'deleted'."""

    stamp_ns: int
    log_time_ns: int
    node: str
    name: str
    value: object
    kind: str


def _bag_files(bag_path):
    """Return the files of a bag: the path, then its split files <stem>_<N>.mcap."""
    paths = [Path(bag_path)]
    while split_path(bag_path, len(paths)).exists():
        paths.append(split_path(bag_path, len(paths)))
    return paths


def _event_changes(event, log_time_ns):
    """Return the ParameterChange list of one ParameterEvent message."""
    stamp_ns = event.stamp.sec * 1_000_000_000 + event.stamp.nanosec
    return [ParameterChange(stamp_ns, log_time_ns, event.node, parameter.name,
                            parameter_value_to_python(parameter.value), kind)
            for kind, parameters in (('new', event.new_parameters),
                                     ('changed', event.changed_parameters),
                                     ('deleted', event.deleted_parameters))
            for parameter in parameters]


def parameter_changes(bag_path):
    """
    Return the ParameterChange list of a bag's /parameter_events, in log-time order.

    stamp_ns is the event's stamp (the node's clock), log_time_ns the recorder's. Split files
    (<stem>_<N>.mcap) of the bag are read too.
    """
    changes = []
    for path in _bag_files(bag_path):
        try:
            with open(path, 'rb') as stream:
                messages = [message for _, _, message in make_reader(stream).iter_messages(
                    topics=[PARAMETER_EVENTS_TOPIC])]
        except (OSError, McapError) as error:
            raise InputError(f'{path}: cannot read bag: {error}') from None
        for message in messages:
            changes += _event_changes(deserialize_message(message.data, ParameterEvent),
                                      message.log_time)
    return sorted(changes, key=lambda change: change.log_time_ns)


# -- the ROS client ---------------------------------------------------------------------------

class ParameterTool:
    """An rclpy node on its own context that calls the parameter services of other nodes."""

    def __init__(self, domain_id=None, timeout=5.0):
        self.timeout = timeout
        self.context = rclpy.Context()
        rclpy.init(args=[], context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node(f'dual_arm_param_{os.getpid()}', context=self.context,
                                      start_parameter_services=False)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._clients = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)

    def node_names(self):
        """Return the full names of the graph's nodes (not ours, not hidden), sorted."""
        own = self.node.get_fully_qualified_name()
        deadline = time.monotonic() + self.timeout
        names, stable_since = set(), time.monotonic()
        while time.monotonic() < deadline:
            current = {f'{namespace.rstrip("/")}/{name}'
                       for name, namespace in self.node.get_node_names_and_namespaces()
                       if not name.startswith('_')} - {own}
            if current != names:
                names, stable_since = current, time.monotonic()
            elif names and time.monotonic() - stable_since > DISCOVERY_SETTLE_TIME:
                break
            time.sleep(GRAPH_POLL_PERIOD)
        return sorted(names)

    def client(self, node_name):
        """Return the AsyncParameterClient of a node once its services are up, else InputError."""
        node_name = full_node_name(node_name)
        if node_name not in self._clients:
            try:
                client = AsyncParameterClient(self.node, node_name)
            except NameValidationException:
                raise InputError(f'{node_name} is not a valid node name') from None
            deadline = time.monotonic() + self.timeout
            while not client.services_are_ready() and time.monotonic() < deadline:
                time.sleep(GRAPH_POLL_PERIOD)
            if not client.services_are_ready():
                raise InputError(f'node {node_name} not found: its parameter services did not '
                                 f'appear within {self.timeout:g} s (ROS domain '
                                 f'{self.context.get_domain_id()})')
            self._clients[node_name] = client
        return self._clients[node_name]

    def call(self, node_name, method, *arguments):
        """Call one parameter service of a node and return its response; InputError on timeout."""
        future = getattr(self.client(node_name), method)(*arguments)
        self.executor.spin_until_future_complete(future, timeout_sec=self.timeout)
        if not future.done():
            raise InputError(f'node {full_node_name(node_name)} did not answer {method} within '
                             f'{self.timeout:g} s')
        return future.result()

    def names(self, node_name):
        """Return the node's parameter names, sorted."""
        return sorted(self.call(node_name, 'list_parameters', [], 0).result.names)

    def values(self, node_name, names):
        """Return {name: ParameterValue} (empty if any name is not declared)."""
        return dict(zip(names, self.call(node_name, 'get_parameters', names).values))

    def descriptors(self, node_name, names):
        """Return {name: ParameterDescriptor} (empty if any name is not declared)."""
        return dict(zip(names, self.call(node_name, 'describe_parameters', names).descriptors))

    def set_parameters(self, node_name, messages):
        """Set parameters one by one; return their SetParametersResult list."""
        return self.call(node_name, 'set_parameters', messages).results


# -- subcommands ------------------------------------------------------------------------------

def _bound(value):
    """Return a range bound as text; the huge stand-ins for unbounded ends read as inf."""
    if abs(value) < UNBOUNDED:
        return f'{value:g}'
    return 'inf' if value > 0 else '-inf'


def _descriptor_lines(name, descriptor):
    ranges = list(descriptor.floating_point_range) + list(descriptor.integer_range)
    value_range = (f', range [{_bound(ranges[0].from_value)}, {_bound(ranges[0].to_value)}]'
                   if ranges else '')
    read_only = ', read-only' if descriptor.read_only else ''
    lines = [f'  {name}: {_TYPE_NAMES.get(descriptor.type, "unknown")}{value_range}{read_only}']
    if descriptor.description:
        lines.append(f'      {descriptor.description}')
    return lines


def _print_parameter_names(tool, node_name, describe):
    names = tool.names(node_name)
    descriptors = tool.descriptors(node_name, names) if describe else {}
    for name in names:
        descriptor = descriptors.get(name)
        print('\n'.join(_descriptor_lines(name, descriptor)) if descriptor is not None
              else f'  {name}')


def command_list(tool, args):
    """Print the parameter names of one node, or of every node of the graph."""
    if args.node:
        _print_parameter_names(tool, args.node, args.describe)
        return 0
    node_names = tool.node_names()
    if not node_names:
        print(f'no nodes found in ROS domain {tool.context.get_domain_id()}', file=sys.stderr)
        return EXIT_FAILED
    for node_name in node_names:
        print(f'{node_name}:')
        try:
            _print_parameter_names(tool, node_name, args.describe)
        except InputError as error:
            print(f'  ({error})')
    return 0


def command_get(tool, args):
    """Print one parameter value; exit 1 if the node does not declare it."""
    value = tool.values(args.node, [args.name]).get(args.name)
    if value is None:
        print(f'Parameter {args.name} is not declared on {full_node_name(args.node)}',
              file=sys.stderr)
        return EXIT_FAILED
    if args.hide_type:
        print(parameter_value_to_python(value))
    else:
        print(describe_value(value))
    return 0 if value.type != ParameterType.PARAMETER_NOT_SET else EXIT_FAILED


def command_set(tool, args):
    """Set one parameter from its YAML text; exit 1 with the node's reason if refused."""
    descriptor = tool.descriptors(args.node, [args.name]).get(args.name)
    declared_type = descriptor.type if descriptor is not None else None
    value = coerce_value(parse_value(args.value), declared_type, args.value)
    message = parameter_message(args.name, value, declared_type)
    result = tool.set_parameters(args.node, [message])[0]
    if result.successful:
        print('Set parameter successful')
        return 0
    if descriptor is None:
        print(f'Setting parameter failed: not declared on {full_node_name(args.node)}')
    else:
        print(f'Setting parameter failed: {result.reason}')
    return EXIT_FAILED


def command_dump(tool, args):
    """Write (or print) a params file with every parameter value of the node."""
    node_name = full_node_name(args.node)
    names = tool.names(node_name)
    values = {name: parameter_value_to_python(value)
              for name, value in tool.values(node_name, names).items()
              if value.type != ParameterType.PARAMETER_NOT_SET}
    text = dump_text(node_name, values)
    if args.output is None:
        print(text, end='')
        return 0
    try:
        Path(args.output).write_text(text)
    except OSError as error:
        raise InputError(f'{args.output}: cannot write: {error.strerror}') from None
    print(f'Saved {len(values)} parameters of {node_name} to {args.output}')
    return 0


def command_load(tool, args):
    """Set every parameter a params file gives the node; report each, exit 1 if any failed."""
    values = args.parameters
    declared = set(tool.names(args.node))
    descriptors = tool.descriptors(args.node, sorted(declared & set(values)))
    messages = []
    failures = 0
    for name, value in sorted(values.items()):
        descriptor = descriptors.get(name)
        if descriptor is not None and descriptor.read_only:
            print(f'Skipped read-only parameter {name} (set at start-up only)')
            continue
        declared_type = descriptor.type if descriptor is not None else None
        try:
            messages.append(parameter_message(name, coerce_value(value, declared_type),
                                              declared_type))
        except InputError as error:
            failures += 1
            print(f'Setting parameter {name} failed: {error}')
    for message, result in zip(messages, tool.set_parameters(args.node, messages)):
        if result.successful:
            print(f'Set parameter {message.name} successful')
        else:
            failures += 1
            reason = result.reason
            if message.name not in declared:
                reason = f'not declared on {full_node_name(args.node)}'
            print(f'Setting parameter {message.name} failed: {reason}')
    return EXIT_FAILED if failures else 0


def _domain_id(text):
    value = int(text)
    if not 0 <= value <= 232:
        raise ValueError(text)
    return value


def build_parser():
    """Return the argument parser of dual_arm_param."""
    common = argparse.ArgumentParser(add_help=False)
    environment_domain = os.environ.get('ROS_DOMAIN_ID', '').strip()
    common.add_argument('--domain-id', type=_domain_id, default=environment_domain or None,
                        help='ROS domain id (default: ROS_DOMAIN_ID, else 0)')
    common.add_argument('--timeout', type=float, default=5.0,
                        help="seconds to wait for a node's services and answers (default 5)")
    parser = argparse.ArgumentParser(prog='dual_arm_param', description=__doc__.split('\n')[1])
    commands = parser.add_subparsers(dest='command', required=True, metavar='COMMAND')

    listing = commands.add_parser('list', parents=[common], help='list parameter names')
    listing.add_argument('node', nargs='?', help='full node name (default: every node)')
    listing.add_argument('-d', '--describe', action='store_true',
                         help='also print type, range, read-only and description')
    listing.set_defaults(handler=command_list)

    getting = commands.add_parser('get', parents=[common], help='print a parameter value')
    getting.add_argument('node', help='full node name, e.g. /ds_motion_generator')
    getting.add_argument('name', help='parameter name, e.g. impact.impact_speed')
    getting.add_argument('--hide-type', action='store_true', help='print the value only')
    getting.set_defaults(handler=command_get)

    setting = commands.add_parser('set', parents=[common], help='set a parameter value')
    setting.add_argument('node', help='full node name')
    setting.add_argument('name', help='parameter name')
    setting.add_argument('value', help='value in YAML: true, 1, 1.0, [1.0, 2.0], text')
    setting.set_defaults(handler=command_set)

    dumping = commands.add_parser('dump', parents=[common],
                                  help='write every parameter of a node as a params file')
    dumping.add_argument('node', help='full node name')
    dumping.add_argument('-o', '--output', help='file to write (default: standard output)')
    dumping.set_defaults(handler=command_dump)

    loading = commands.add_parser('load', parents=[common],
                                  help='set the parameters a params file gives a node')
    loading.add_argument('node', help='full node name')
    loading.add_argument('file', help='params file (node key, /** or wildcards)')
    loading.set_defaults(handler=command_load)
    return parser


def main(argv=None):
    """Run one subcommand; return 0, 1 (refused / not declared) or 2 (user error)."""
    args = build_parser().parse_args(argv)
    try:
        if args.command == 'load':
            args.parameters = read_params_file(args.file, args.node)
        with ParameterTool(args.domain_id, args.timeout) as tool:
            return args.handler(tool, args)
    except InputError as error:
        print(f'dual_arm_param: {error}', file=sys.stderr)
        return EXIT_USER_ERROR
    except KeyboardInterrupt:
        return EXIT_FAILED
    except BrokenPipeError:
        sys.stdout = open(os.devnull, 'w')
        return EXIT_FAILED


if __name__ == '__main__':
    sys.exit(main())
