"""
ROS parameters from the parameter table (runtime/node_settings.py and the core config trees).

NodeParameters declares a node's own settings, ConfigParameters the leaves of the core config
tree it tunes (``impact.region.normal_distance``). Each parameter is declared with the Setting's
default, description, unit and range; a set is refused with the reason the Setting (or the core
config's validation) gives, and an accepted set is handed to the node's callback, which applies
it at its next tick.
"""

import math
import sys

from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.runtime.config_tree import config_leaves, config_with_values
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)

_MAX_FLOAT = sys.float_info.max
_MAX_INT = 2 ** 62


def setting_descriptor(entry, name=None):
    """Return the ParameterDescriptor of a Setting: description with unit, range, read-only."""
    description = entry.description
    if entry.unit and f'[{entry.unit}]' not in description:
        description = f'{description} [{entry.unit}]'
    descriptor = ParameterDescriptor(name=name or entry.name, description=description,
                                     read_only=entry.read_only,
                                     additional_constraints=entry.interval_text())
    bounded = math.isfinite(entry.low) or math.isfinite(entry.high)
    if entry.choices and entry.kind is float:
        descriptor.floating_point_range = [FloatingPointRange(
            from_value=float(min(entry.choices)), to_value=float(max(entry.choices)), step=0.0)]
    elif bounded and entry.kind is int:
        descriptor.integer_range = [IntegerRange(
            from_value=int(max(entry.low, -_MAX_INT)), to_value=int(min(entry.high, _MAX_INT)),
            step=1)]
    elif bounded and entry.kind is float:
        descriptor.floating_point_range = [FloatingPointRange(
            from_value=float(max(entry.low, -_MAX_FLOAT)),
            to_value=float(min(entry.high, _MAX_FLOAT)), step=0.0)]
    return descriptor


def _declared_default(value):
    return list(value) if isinstance(value, tuple) else value


class NodeParameters:
    """
    A node's own settings as declared ROS parameters.

    defaults overrides table defaults: {name: value}, or a function of the values declared so
    far (in table order) returning one, e.g. an object's mass from the node's scenario;
    extra_problem(values) may refuse a combination of values; on_change(name, value) is called
    after every accepted set of one of them.
    """

    def __init__(self, node, settings, defaults=None, extra_problem=None, on_change=None):
        self._node = node
        self._settings = {entry.name: entry for entry in settings}
        self._extra_problem = extra_problem
        self._on_change = on_change
        self.values = {}
        for entry in settings:
            overrides = defaults(self.values) if callable(defaults) else (defaults or {})
            default = _declared_default(overrides.get(entry.name, entry.default))
            self.values[entry.name] = node.declare_parameter(
                entry.name, default, setting_descriptor(entry)).value
        problem = self._problem(self.values)
        if problem is not None:
            raise ConfigError(f'node {node.get_name()}: invalid parameters: {problem}')
        node.add_on_set_parameters_callback(self._validate)
        node.add_post_set_parameters_callback(self._apply)

    def __getitem__(self, name):
        """Return the current value of a node setting."""
        return self.values[name]

    def _problem(self, values):
        for name, value in values.items():
            reason = self._settings[name].problem(value)
            if reason is not None:
                return reason
        return None if self._extra_problem is None else self._extra_problem(values)

    def _validate(self, parameters):
        ours = {p.name: p.value for p in parameters if p.name in self._settings}
        if not ours:
            return SetParametersResult(successful=True)
        reason = self._problem(dict(self.values, **ours))
        return SetParametersResult(successful=reason is None, reason=reason or '')

    def _apply(self, parameters):
        for parameter in parameters:
            if parameter.name in self._settings:
                self.values[parameter.name] = parameter.value
                if self._on_change is not None:
                    self._on_change(parameter.name, parameter.value)


class ConfigParameters:
    """
    The parameters of one config tree on one node.

    on_change(config) is called after every accepted set; the node applies the config at its
    next tick. Refused sets leave the config unchanged and answer with the reason.
    """

    def __init__(self, node, config, on_change=None, prefix=''):
        self._node = node
        self._on_change = on_change
        self._leaves = {leaf.name: leaf for leaf in config_leaves(config, prefix)}
        values = {}
        for leaf in self._leaves.values():
            declared = node.declare_parameter(leaf.name, leaf.default,
                                              setting_descriptor(leaf.setting, leaf.name))
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
