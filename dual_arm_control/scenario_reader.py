"""
Typed reading of one YAML configuration file: every error names the file and the dotted key.

Used by the scenario loader (dual_arm_control.scenario) and the randomization block
(dual_arm_control.randomization). A block that is one settings dataclass (the belts) is read by
ScenarioReader.settings_block and written back by settings_document.
"""

from dataclasses import fields

from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.settings import settings_of
from dual_arm_control.resources import require


def settings_document(config):
    """Return a settings dataclass as a file block: every field a float or a list of floats."""
    document = {}
    for item in fields(config):
        value = getattr(config, item.name)
        document[item.name] = ([float(v) for v in value] if isinstance(value, tuple)
                               else float(value))
    return document


class ScenarioReader:
    """Reads typed values from one YAML file; every error names the file and the dotted key."""

    def __init__(self, path):
        """Read values of the file at path (used in error messages only)."""
        self.path = path

    def error(self, key, message):
        """Return a ConfigError naming the file and the dotted key."""
        return ConfigError(f'{self.path}: key {key!r}: {message}')

    def check_keys(self, mapping, allowed, context):
        """Refuse a key of mapping that is not in allowed."""
        unknown = sorted(set(mapping) - set(allowed))
        if unknown:
            where = f'{context}.{unknown[0]}' if context else unknown[0]
            raise self.error(where, f'unknown key; allowed: {sorted(allowed)}')

    def mapping(self, parent, key, context='', optional=False):
        """Read a dict; return None if it is optional and absent."""
        if optional and (not isinstance(parent, dict) or key not in parent):
            return None
        return require(parent, key, self.path, dict, context)

    def number(self, parent, key, context='', default=None):
        """Return the value as a float (bools refused), or default if given and absent."""
        if default is not None and key not in parent:
            return float(default)
        value = require(parent, key, self.path, (int, float), context)
        if isinstance(value, bool):
            raise self.error(self._dotted(context, key), f'must be a number, got {value!r}')
        return float(value)

    def names(self, parent, key, context=''):
        """Read a non-empty list of distinct strings."""
        value = require(parent, key, self.path, list, context)
        if not value or not all(isinstance(item, str) for item in value) or \
                len(set(value)) != len(value):
            raise self.error(self._dotted(context, key),
                             f'must be a non-empty list of distinct names, got {value!r}')
        return tuple(value)

    def vector(self, parent, key, sizes, context='', unit=''):
        """Read a list of numbers whose length is one of sizes."""
        value = require(parent, key, self.path, list, context)
        dotted = self._dotted(context, key)
        if len(value) not in sizes or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
            raise self.error(dotted, f'must be a list of {" or ".join(map(str, sizes))} '
                                     f'numbers [{unit}], got {value!r}')
        return [float(v) for v in value]

    def settings_block(self, parent, key, factory):
        """
        Return the settings dataclass factory read from the optional block key, or None.

        The block's keys are the factory's settings (core.settings.setting), each a number or,
        for a vector setting, a list of its length; the factory checks the ranges.
        """
        entry = self.mapping(parent, key, optional=True)
        if entry is None:
            return None
        settings = {item.name: item for item in settings_of(factory)}
        self.check_keys(entry, list(settings), key)
        values = {}
        for name in entry:
            length = settings[name].length
            if length is not None:
                values[name] = tuple(self.vector(entry, name, (length,), key,
                                                 settings[name].unit))
            else:
                values[name] = self.number(entry, name, key)
        return self.build(key, factory, **values)

    def build(self, context, factory, *args, **kwargs):
        """Call factory; name the offending field as a dotted key under context on error."""
        try:
            return factory(*args, **kwargs)
        except ConfigError as error:
            message = str(error)
            token = message.split(' ', 1)[0]
            if context and token.startswith(context.split('[')[0].split('.')[0] + '.'):
                dotted = token
            elif token in {item.name for item in fields(factory)}:
                dotted = f'{context}.{token}' if context else token
            else:
                dotted = context or token
            raise ConfigError(f'{self.path}: key {dotted!r}: {message}') from None

    @staticmethod
    def _dotted(context, key):
        return f'{context}.{key}' if context else key
