"""
Bind a core config dataclass tree to a node's ROS parameters (live tuning).

Every scalar, string, enum and number-vector field of a (nested) frozen config dataclass becomes a
declared parameter named by its dotted path (``impact.region.normal_distance``). The default is
the dataclass's (one source), the description comes from the dataclass documentation, the range
from the same check_range call that validates the field. A set is refused with the core's
ConfigError message as the reason; an accepted set rebuilds the config and hands it to the
node's callback, which applies it at the next tick.
"""

import ast
import dataclasses
import enum
import inspect
import sys
import textwrap

from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.validation import recorded_ranges
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)

_MAX_FLOAT = sys.float_info.max
_MAX_INT = 2 ** 62


@dataclasses.dataclass(frozen=True)
class ConfigField:
    """One leaf of a config tree: dotted name, path of attribute names, default, docs, range."""

    name: str
    path: tuple
    default: object
    description: str
    value_range: object


def _class_field_docs(cls):
    """Return {field: text} from attribute docstrings and 'name: text' lines of the class doc."""
    docs = {}
    for line in (inspect.getdoc(cls) or '').splitlines():
        head, _, text = line.strip().partition(':')
        for name in head.replace(' ', '').split(','):
            if name.isidentifier() and text.strip():
                docs.setdefault(name, text.strip())
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    except (OSError, TypeError, SyntaxError):
        return docs
    body = tree.body[0].body if tree.body and isinstance(tree.body[0], ast.ClassDef) else []
    for statement, following in zip(body, body[1:]):
        if (isinstance(statement, ast.AnnAssign) and isinstance(statement.target, ast.Name)
                and isinstance(following, ast.Expr)
                and isinstance(getattr(following, 'value', None), ast.Constant)
                and isinstance(following.value.value, str)):
            docs[statement.target.id] = ' '.join(following.value.value.split())
    return docs


def _field_ranges(config):
    """Return {field name: (low, high, unit)} recorded while the config validates itself."""
    with recorded_ranges() as ranges:
        dataclasses.replace(config)
    return ranges


def _parameter_value(value):
    """Return value as a ROS parameter value, or None if the field is not a tunable leaf."""
    if isinstance(value, enum.Enum):
        return str(value.value)
    if isinstance(value, bool):
        return value
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):
        return float(value)
    if isinstance(value, str):
        return value
    try:
        items = list(value)
    except TypeError:
        return None
    if items and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in items):
        return [float(v) for v in items]
    return None


def config_fields(config, prefix=''):
    """Return the ConfigField leaves of a config dataclass tree."""
    docs = _class_field_docs(type(config))
    ranges = _field_ranges(config)
    leaves = []
    for field in dataclasses.fields(config):
        value = getattr(config, field.name)
        name = f'{prefix}{field.name}'
        if dataclasses.is_dataclass(value):
            for leaf in config_fields(value, f'{name}.'):
                leaves.append(dataclasses.replace(leaf, path=(field.name,) + leaf.path))
            continue
        default = _parameter_value(value)
        if default is None:
            continue
        low, high, unit = ranges.get(field.name, (None, None, ''))
        description = docs.get(field.name, field.name)
        if unit and f'[{unit}]' not in description:
            description = f'{description} [{unit}]'
        leaves.append(ConfigField(name, (field.name,), default, description,
                                  None if low is None else (low, high)))
    return leaves


def parameter_descriptor(description, read_only=False, floating_range=None, constraints=''):
    """Return a ParameterDescriptor with an optional closed floating-point range (low, high)."""
    descriptor = ParameterDescriptor(description=description, read_only=read_only,
                                     additional_constraints=constraints)
    if floating_range is not None:
        descriptor.floating_point_range = [FloatingPointRange(
            from_value=floating_range[0], to_value=floating_range[1], step=0.0)]
    return descriptor


def _descriptor(leaf):
    """Return the ParameterDescriptor of a leaf: description, and range where numeric."""
    descriptor = ParameterDescriptor(name=leaf.name, description=leaf.description)
    if leaf.value_range is None or isinstance(leaf.default, (bool, str, list)):
        return descriptor
    low, high = leaf.value_range
    if isinstance(leaf.default, int):
        descriptor.integer_range = [IntegerRange(
            from_value=int(max(low, -_MAX_INT)), to_value=int(min(high, _MAX_INT)), step=1)]
    else:
        descriptor.floating_point_range = [FloatingPointRange(
            from_value=float(max(low, -_MAX_FLOAT)), to_value=float(min(high, _MAX_FLOAT)),
            step=0.0)]
    return descriptor


def config_with_values(config, values):
    """Return config rebuilt with {path tuple: value}; raise ConfigError from validation."""
    grouped = {}
    for path, value in values.items():
        grouped.setdefault(path[0], {})[path[1:]] = value
    changes = {}
    for name, sub_values in grouped.items():
        current = getattr(config, name)
        if () in sub_values:
            value = sub_values[()]
            changes[name] = tuple(value) if isinstance(value, list) else value
        else:
            changes[name] = config_with_values(current, sub_values)
    try:
        return dataclasses.replace(config, **changes)
    except (TypeError, ValueError) as error:
        if isinstance(error, ConfigError):
            raise
        raise ConfigError(str(error)) from None


class ConfigParameters:
    """
    The parameters of one config tree on one node.

    on_change(config) is called after every accepted set; the node applies the config at its
    next tick. Refused sets leave the config unchanged and answer with the reason.
    """

    def __init__(self, node, config, on_change=None, prefix=''):
        self._node = node
        self._on_change = on_change
        self._leaves = {leaf.name: leaf for leaf in config_fields(config, prefix)}
        values = {}
        for leaf in self._leaves.values():
            declared = node.declare_parameter(leaf.name, leaf.default, _descriptor(leaf))
            values[leaf.path] = declared.value
        try:
            self._config = config_with_values(config, values)
        except ConfigError as error:
            raise ConfigError(f'node {node.get_name()}: invalid parameters: {error}') from None
        self._pending = None
        node.add_on_set_parameters_callback(self._validate)
        node.add_post_set_parameters_callback(self._apply)

    @property
    def config(self):
        """Return the current config."""
        return self._config

    @property
    def names(self):
        """Return the declared parameter names."""
        return sorted(self._leaves)

    def _validate(self, parameters):
        ours = {self._leaves[p.name].path: p.value for p in parameters if p.name in self._leaves}
        if not ours:
            return SetParametersResult(successful=True)
        try:
            self._pending = config_with_values(self._config, ours)
        except ConfigError as error:
            self._pending = None
            return SetParametersResult(successful=False, reason=str(error))
        return SetParametersResult(successful=True)

    def _apply(self, parameters):
        if self._pending is None or not any(p.name in self._leaves for p in parameters):
            return
        self._config, self._pending = self._pending, None
        if self._on_change is not None:
            self._on_change(self._config)
