"""
The randomization block of a scenario file: the ranges a batch evaluation draws its trials from.

dual_arm_control.trial_sampling turns a scenario and a trial number into a concrete trial; this
module holds the block's typed form, its reading from the file and its writing back.
"""

from dataclasses import dataclass, fields
import math

from dual_arm_control.catalogue import load_catalogue
from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.validation import check_range, frozen_vector
import numpy as np

# Randomization keys given as [low, high] ranges: unit, bounds, whether 0 is allowed.
RANDOMIZED_RANGES = {
    'mass': ('kg', 0.0, 100.0, False),
    'size_scale': ('', 0.0, 10.0, False),
    'friction': ('', 0.0, 10.0, False),
    'mocap_noise': ('m', 0.0, 0.1, True),
    'mocap_latency': ('s', 0.0, 1.0, True),
    'release_yaw': ('deg', -180.0, 180.0, True),
    'belt_speed': ('m/s', -2.0, 2.0, True),
    'container_start': ('m', -3.0, 3.0, True),
    'container_start_time': ('s', 0.0, 600.0, True),
}


@dataclass(frozen=True)
class Randomization:
    """
    Per-trial randomization of a scenario (dual_arm_eval): uniform draws around its values.

    Fields: object_types: catalogue names (config/objects.yaml) or None; each trial draws one,
    uniformly, and takes its size, mass and friction (the ranges below still apply on top);
    object_position (2,) half-ranges [m] of the offset of the object's initial centre along
    world x and y (uniform in +-, the box rests on the surface below); object_yaw: half-range
    [rad] of the offset of the initial yaw; mass (low, high) [kg], size_scale (low, high) [-]
    (factor on all three edges), friction (low, high) [-], mocap_noise (low, high) [m] (mocap
    position noise standard deviation), mocap_latency (low, high) [s] and release_yaw (low,
    high) [deg] (yaw of the object's orientation at release, toss tasks), belt_speed (low,
    high) [m/s], container_start (low, high) [m] and container_start_time (low, high) [s]
    (the scenario's conveyor: its speed, the container's start y and start time): ranges drawn
    uniformly, None keeps the scenario's (or the drawn type's) value; landing_target (2,)
    half-ranges [m] of the offset of the scenario's landing target along world x and y
    (toss_to_target), or None. The controllers are
    given the drawn object (the scenario is their prior as well as the twin's truth).
    """

    object_types: object = None
    object_position: np.ndarray = (0.0, 0.0)
    object_yaw: float = 0.0
    mass: object = None
    size_scale: object = None
    friction: object = None
    mocap_noise: object = None
    mocap_latency: object = None
    release_yaw: object = None
    belt_speed: object = None
    container_start: object = None
    container_start_time: object = None
    landing_target: object = None

    def __post_init__(self):
        if self.object_types is not None:
            types = tuple(self.object_types)
            if not types or not all(isinstance(name, str) for name in types) or \
                    len(set(types)) != len(types):
                raise ConfigError(f'randomization.object_types must be distinct catalogue '
                                  f'names, got {self.object_types!r}')
            object.__setattr__(self, 'object_types', types)
        position = frozen_vector('randomization.object_position', self.object_position, 2, 'm')
        for half_range in position:
            check_range('randomization.object_position', half_range, 0.0, 0.5, 'm')
        object.__setattr__(self, 'object_position', position)
        if self.landing_target is not None:
            target = frozen_vector('randomization.landing_target', self.landing_target, 2, 'm')
            for half_range in target:
                check_range('randomization.landing_target', half_range, 0.0, 1.0, 'm')
            object.__setattr__(self, 'landing_target', target)
        check_range('randomization.object_yaw', self.object_yaw, 0.0, math.pi, 'rad')
        for name, (unit, low, high, zero_allowed) in RANDOMIZED_RANGES.items():
            value = getattr(self, name)
            if value is None:
                continue
            interval = frozen_vector(f'randomization.{name}', value, 2, unit)
            for bound in interval:
                check_range(f'randomization.{name}', bound, low, high, unit,
                            low_open=not zero_allowed)
            if interval[0] > interval[1]:
                raise ConfigError(f'randomization.{name} must be [low, high] with low <= high, '
                                  f'got {interval.tolist()}')
            object.__setattr__(self, name, interval)


def read_randomization(reader, data, catalogue_path=None):
    """
    Return the Randomization of a scenario file's mapping data, or None without the block.

    reader: a ScenarioReader of the file; object types must be in the catalogue.
    """
    entry = reader.mapping(data, 'randomization', optional=True)
    if entry is None:
        return None
    reader.check_keys(entry, [item.name for item in fields(Randomization)], 'randomization')
    values = {}
    if 'object_types' in entry:
        types = reader.names(entry, 'object_types', 'randomization')
        catalogue = load_catalogue(catalogue_path)
        unknown = [name for name in types if name not in catalogue]
        if unknown:
            raise reader.error('randomization.object_types',
                               f'unknown object type {unknown[0]!r}; catalogue has '
                               f'{sorted(catalogue)}')
        values['object_types'] = types
    if 'object_position' in entry:
        values['object_position'] = reader.vector(entry, 'object_position', (2,),
                                                  'randomization', 'm')
    if 'object_yaw' in entry:
        values['object_yaw'] = reader.number(entry, 'object_yaw', 'randomization')
    if 'landing_target' in entry:
        values['landing_target'] = reader.vector(entry, 'landing_target', (2,),
                                                 'randomization', 'm')
    for key, (unit, *_) in RANDOMIZED_RANGES.items():
        if key in entry:
            values[key] = reader.vector(entry, key, (2,), 'randomization', unit)
    return reader.build('randomization', Randomization, **values)


def randomization_document(spec):
    """Return the randomization block of a scenario file for spec (a Randomization)."""
    entry = {}
    if spec.object_types is not None:
        entry['object_types'] = list(spec.object_types)
    entry.update(object_position=[float(value) for value in spec.object_position],
                 object_yaw=float(spec.object_yaw))
    entry.update({name: [float(value) for value in getattr(spec, name)]
                  for name in RANDOMIZED_RANGES if getattr(spec, name) is not None})
    if spec.landing_target is not None:
        entry['landing_target'] = [float(value) for value in spec.landing_target]
    return entry
