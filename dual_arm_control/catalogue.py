"""The object catalogue (config/objects.yaml) as typed entries."""

from dataclasses import dataclass

from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.resources import config_path, load_yaml, require
import numpy as np


@dataclass(frozen=True)
class ObjectSpec:
    """A box: edge lengths along object x, y, z [m] (y squeezed), mass [kg], pad friction."""

    name: str
    size: tuple
    mass: float
    friction: float

    def __post_init__(self):
        if len(self.size) != 3 or not all(np.isfinite(s) and s > 0.0 for s in self.size):
            raise ConfigError(f'object {self.name}: size must be 3 positive lengths [m], '
                              f'got {self.size}')
        if not (np.isfinite(self.mass) and self.mass > 0.0):
            raise ConfigError(f'object {self.name}: mass must be > 0 kg, got {self.mass}')
        if not (np.isfinite(self.friction) and self.friction > 0.0):
            raise ConfigError(f'object {self.name}: friction must be > 0, got {self.friction}')


def load_catalogue(path=None):
    """Return {name: ObjectSpec} from the catalogue file; errors name the file and the key."""
    path = path or config_path('objects.yaml')
    data = load_yaml(path)
    entries = require(data, 'objects', path, dict)
    catalogue = {}
    for name, entry in entries.items():
        context = f'objects.{name}'
        size = require(entry, 'size', path, list, context)
        mass = require(entry, 'mass', path, (int, float), context)
        friction = require(entry, 'friction', path, (int, float), context)
        try:
            catalogue[name] = ObjectSpec(name, tuple(float(s) for s in size), float(mass),
                                         float(friction))
        except (ConfigError, TypeError, ValueError) as error:
            raise ConfigError(f'{path}: {context}: {error}') from None
    return catalogue


def object_spec(name, path=None):
    """Return one catalogue entry, or raise ConfigError listing the known names."""
    catalogue = load_catalogue(path)
    if name not in catalogue:
        raise ConfigError(f'unknown object type {name!r}; catalogue has {sorted(catalogue)}')
    return catalogue[name]
