"""
dual_arm_param: list, get, set, dump and load the parameters of running nodes, like `ros2 param`.

It talks to the standard rcl_interfaces parameter services every node offers, so it works with
any ROS 2 node. Values typed on the command line are YAML (`true`, `1`, `1.0`, `[1.0, 2.0]`,
strings otherwise); an integer given for a double parameter is converted. `dump` writes a file
that `--ros-args --params-file FILE` and `load` read back. Exit codes: 0 success, 1 the node
refused or lacks the parameter, 2 user error (unknown node, bad file).

This module is the command line and its subcommands; values and params files are handled by
tools/param_values.py, the parameter services called by tools/param_client.py, and a bag's
recorded parameter changes read by tools/param_events.py.
"""

import argparse
import os
from pathlib import Path
import sys

from dual_arm_control.core.exceptions import InputError
from dual_arm_control.tools.param_client import ParameterTool
from dual_arm_control.tools.param_values import (coerce_value, describe_value, dump_text,
                                                 full_node_name, parameter_message, parse_value,
                                                 read_params_file)
from rcl_interfaces.msg import ParameterType
from rclpy.parameter import parameter_value_to_python

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


def _bound(value):
    """Return a range bound as text; the huge stand-ins for unbounded ends read as inf."""
    if abs(value) < UNBOUNDED:
        return f'{value:g}'
    return 'inf' if value > 0 else '-inf'


def _descriptor_lines(name, descriptor):
    """Return the `list --describe` lines of one parameter: type, range, read-only, text."""
    ranges = list(descriptor.floating_point_range) + list(descriptor.integer_range)
    value_range = (f', range [{_bound(ranges[0].from_value)}, {_bound(ranges[0].to_value)}]'
                   if ranges else '')
    read_only = ', read-only' if descriptor.read_only else ''
    lines = [f'  {name}: {_TYPE_NAMES.get(descriptor.type, "unknown")}{value_range}{read_only}']
    if descriptor.description:
        lines.append(f'      {descriptor.description}')
    return lines


def _print_parameter_names(tool, node_name, describe):
    """Print the parameter names of one node, with their descriptions if describe."""
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
    """Return a ROS domain id (0 - 232) given on the command line; ValueError otherwise."""
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
