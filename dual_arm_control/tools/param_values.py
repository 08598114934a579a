"""
Parameter values, node names and params files for dual_arm_param (no ROS graph needed).

Command-line values are read as YAML and converted to the node's declared type where that loses
nothing; values become rcl_interfaces Parameter messages and `ros2 param get` lines. Params
files (`--ros-args --params-file`) are written from and read into {dotted name: value}, with
nested namespaces and the wildcard node keys of rcl.
"""

from pathlib import Path
import re

from dual_arm_control.core.exceptions import InputError
from rcl_interfaces.msg import ParameterType
from rclpy.parameter import Parameter, parameter_value_to_python
import yaml

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
