"""
A config dataclass tree as flat, dotted parameters, and back.

Every scalar, string, enum and number-vector field of a (nested) frozen config dataclass is a
parameter named by its dotted path (``impact.region.normal_distance``). Its facts come from the
field's Setting (core/settings.py) where it has one; fields not yet declared with setting() fall
back to the class documentation and the range their validation records. The ROS parameter layer,
the launcher's file checks and the parameter reference read the tree through this module.
"""

import ast
import dataclasses
import enum
import inspect
import textwrap

from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.settings import Setting, SETTING_KEY
from dual_arm_control.core.validation import recorded_ranges


@dataclasses.dataclass(frozen=True)
class ConfigLeaf:
    """One leaf of a config tree: dotted name, path of attribute names, its Setting."""

    name: str
    path: tuple
    setting: Setting

    @property
    def default(self):
        """Return the leaf's default as a parameter value."""
        return parameter_value(self.setting.default)


def parameter_value(value):
    """Return value as a parameter value, or None if it is not a tunable leaf."""
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


def _undeclared_setting(config, field, value, docs, ranges):
    """Return a Setting for a field declared without setting() (documentation and ranges)."""
    low, high, unit = ranges.get(field.name, (-float('inf'), float('inf'), ''))
    choices = tuple(member.value for member in type(value)) if isinstance(
        value, enum.Enum) else ()
    return Setting(field.name, parameter_value(value), docs.get(field.name, field.name), unit,
                   low, high, choices=choices)


def config_leaves(config, prefix=''):
    """Return the ConfigLeaf of every tunable field of a config dataclass tree."""
    docs = ranges = None
    leaves = []
    for field in dataclasses.fields(config):
        value = getattr(config, field.name)
        name = f'{prefix}{field.name}'
        if dataclasses.is_dataclass(value):
            for leaf in config_leaves(value, f'{name}.'):
                leaves.append(dataclasses.replace(leaf, path=(field.name,) + leaf.path))
            continue
        if parameter_value(value) is None:
            continue
        if SETTING_KEY in field.metadata:
            entry = dataclasses.replace(field.metadata[SETTING_KEY], name=field.name,
                                        default=parameter_value(value))
        else:
            if docs is None:
                docs = _class_field_docs(type(config))
                with recorded_ranges() as ranges:
                    dataclasses.replace(config)
            entry = _undeclared_setting(config, field, value, docs, ranges)
        leaves.append(ConfigLeaf(name, (field.name,), entry))
    return leaves


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
