"""
A config dataclass tree as flat, dotted parameters, and back.

Every scalar, string, enum and number-vector field of a (nested) frozen config dataclass is a
parameter named by its dotted path (``impact.region.normal_distance``). Its facts (default,
range, unit, description) come from the field's Setting, declared with core.settings.setting();
a tunable field declared without one is a programming error. The ROS parameter layer, the
launcher's file checks and the parameter reference read the tree through this module.
"""

import dataclasses
import enum

from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.settings import Setting, SETTING_KEY


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


def config_leaves(config, prefix=''):
    """Return the ConfigLeaf of every tunable field of a config dataclass tree."""
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
        if SETTING_KEY not in field.metadata:
            raise TypeError(f'{type(config).__name__}.{field.name} is a tunable value declared '
                            'without core.settings.setting()')
        entry = dataclasses.replace(field.metadata[SETTING_KEY], name=field.name,
                                    default=parameter_value(value))
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
