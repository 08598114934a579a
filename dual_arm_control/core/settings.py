"""
Declarative settings: one entry per tunable value, with its default, range, unit and meaning.

A Setting is the single source of a value's facts: config dataclasses declare their fields
with setting() and validate them with check_settings(); node tables list their node-only
parameters as Settings. The ROS parameter layer, the launcher's file checks, the generated
parameter reference (docs/parameters.md) and the config-file tests all read the same entries,
so a range cannot be declared in one place and enforced differently in another.
"""

from dataclasses import dataclass, field, fields, replace
import enum
import math

from dual_arm_control.core.exceptions import ConfigError
import numpy as np

SETTING_KEY = 'setting'


@dataclass(frozen=True)
class Setting:
    """
    One tunable value.

    name: parameter name (a config field's name; dotted paths are built by the tree walk);
    default: the value when nothing is set (its type is the parameter's type: bool, int, float,
    str, or a tuple of numbers); description: what it is and why; unit: SI unit ('' if none);
    low, high: the allowed interval (numbers, or each element of a vector), open at an end
    with low_open / high_open; choices: the allowed values of a string; size: the length a
    vector must have (None: the default's); read_only: fixed once a node runs; required: a
    string that may not be empty.
    """

    name: str
    default: object
    description: str
    unit: str = ''
    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False
    choices: tuple = ()
    size: object = None
    read_only: bool = False
    required: bool = False

    @property
    def kind(self):
        """Return the value's type: bool, int, float, str, list (of numbers) or tuple (of str)."""
        if isinstance(self.default, bool):
            return bool
        if isinstance(self.default, (int, np.integer)):
            return int
        if isinstance(self.default, (float, np.floating)):
            return float
        if isinstance(self.default, str):
            return str
        if all(isinstance(item, str) for item in self.default) and self.default:
            return tuple
        return list

    @property
    def length(self):
        """Return the required length of a vector setting, or None."""
        if self.kind is not list:
            return None
        return len(self.default) if self.size is None else self.size

    def interval_text(self):
        """Return the allowed interval as text, e.g. '(0, 2] m/s', or '' if unbounded."""
        if self.choices:
            unit = f' {self.unit}' if self.unit and self.kind is not str else ''
            return 'one of ' + ', '.join(f'{c:g}' if isinstance(c, float) else str(c)
                                         for c in self.choices) + unit
        if self.low == -math.inf and self.high == math.inf:
            return ''
        left = '(' if self.low_open else '['
        right = ')' if self.high_open else ']'
        unit = f' {self.unit}' if self.unit else ''
        return f'{left}{self.low:g}, {self.high:g}{right}{unit}'

    def problem(self, value, name=None):
        """Return why value is not allowed (naming the setting, value and range), or None."""
        name = name or self.name
        if isinstance(value, enum.Enum):
            value = value.value
        kind = self.kind
        if kind is bool:
            return None if isinstance(value, (bool, np.bool_)) else (
                f'{name} must be true or false, got {value!r}')
        if kind is str:
            if not isinstance(value, str):
                return f'{name} must be a string, got {value!r}'
            if self.choices and value not in self.choices:
                return f'{name} must be one of {", ".join(self.choices)}, got {value!r}'
            if self.required and not value:
                return f'{name} must not be empty'
            return None
        if kind is tuple:
            if isinstance(value, str) or not all(isinstance(item, str) for item in value):
                return f'{name} must be a list of strings, got {value!r}'
            return None
        if kind is list:
            try:
                values = [float(v) for v in value]
            except (TypeError, ValueError):
                return f'{name} must be a list of numbers, got {value!r}'
            if self.length is not None and len(values) != self.length:
                return f'{name} must have {self.length} elements, got {len(values)}'
            for index, number in enumerate(values):
                reason = self._number_problem(f'{name}[{index}]', number)
                if reason is not None:
                    return reason
            return None
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer,
                                                             np.floating)):
            return f'{name} must be a number, got {value!r}'
        if kind is int and int(value) != value:
            return f'{name} must be an integer, got {value!r}'
        if self.choices and not any(math.isclose(value, c) for c in self.choices):
            return (f'{name} must be one of {", ".join(f"{c:g}" for c in self.choices)}'
                    f'{" " + self.unit if self.unit else ""}, got {value!r}')
        return self._number_problem(name, float(value))

    def _number_problem(self, name, number):
        if not math.isfinite(number):
            return f'{name} must be finite, got {number!r}'
        too_low = number <= self.low if self.low_open else number < self.low
        too_high = number >= self.high if self.high_open else number > self.high
        if too_low or too_high:
            unit = f' {self.unit}' if self.unit else ''
            return f'{name} = {number:g}{unit} is outside {self.interval_text()}'
        return None


def setting(default, description, unit='', low=-math.inf, high=math.inf, low_open=False,
            high_open=False, choices=(), size=None):
    """Return a dataclass field whose default and metadata are a Setting (name filled later)."""
    entry = Setting('', default, description, unit, low, high, low_open, high_open,
                    tuple(choices), size)
    return field(default=default, metadata={SETTING_KEY: entry})


def settings_of(config_class):
    """Return the Settings of a config dataclass's declared fields (named), in field order."""
    return [replace(f.metadata[SETTING_KEY], name=f.name) for f in fields(config_class)
            if SETTING_KEY in f.metadata]


def check_settings(config):
    """
    Raise ConfigError unless every setting field of config holds an allowed value.

    Vector settings are stored back as tuples of floats, so a frozen config stays hashable and
    its fields cannot be changed through a shared list.
    """
    for entry in settings_of(type(config)):
        value = getattr(config, entry.name)
        reason = entry.problem(value)
        if reason is not None:
            raise ConfigError(reason)
        if entry.kind is list:
            object.__setattr__(config, entry.name, tuple(float(v) for v in value))
