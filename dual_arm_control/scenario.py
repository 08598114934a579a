"""
Scenario files (config/scenarios/*.yaml) as frozen dataclasses.

A scenario fixes everything a run needs besides the controllers' parameters: task, object (type
from the catalogue or explicit size/mass/friction, pose), release or landing target, placing
position, task speeds, scripted perturbations, duration, initial joint configuration and sensor
models of the twin, and optionally the ranges a batch evaluation draws its trials from
(sample_trial). Positions given as [x, y] rest on the surface below (pallet, front table or
floor of config/cell.yaml). Every error names the file and the dotted key. scenario_document
writes a Scenario back as such a file.
"""

from dataclasses import dataclass, field, fields, replace
import math
from pathlib import Path

from dual_arm_control.catalogue import load_catalogue
from dual_arm_control.core.arms import ARMS
from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.robot_model import ArmModel, JOINTS_PER_ARM
from dual_arm_control.core.validation import check_range, check_vector
from dual_arm_control.description.cell import load_cell
from dual_arm_control.resources import config_path, load_yaml, require
import numpy as np

TASKS = ('pick_and_toss', 'pick_and_place', 'pick_and_lift', 'place_toss', 'toss_to_target')
TOSS_TASKS = ('pick_and_toss', 'toss_to_target')
PLACE_TASKS = ('pick_and_place', 'place_toss')
# Randomization keys given as [low, high] ranges, with their units.
RANDOMIZED_RANGES = {'mass': 'kg', 'size_scale': '', 'friction': '', 'mocap_noise': 'm'}
# The uniform draws of one trial, in the order they are taken from its generator.
_TRIAL_DRAWS = ('object_x', 'object_y', 'object_yaw', 'mass', 'size_scale', 'friction',
                'mocap_noise')


def _frozen_vector(name, value, size, unit):
    array = check_vector(name, value, size, unit).copy()
    array.setflags(write=False)
    return array


@dataclass(frozen=True)
class ObjectConfig:
    """
    The box to manipulate.

    Fields: type (catalogue name or None when given explicitly); size (3,) edge lengths along
    object x, y, z [m] (y is the squeeze axis); mass [kg]; friction: pad-box Coulomb
    coefficient [-]; position (3,) initial centre in the world [m]; yaw: initial rotation about
    world z [rad].
    """

    type: object  # noqa: A003 (the scenario file's key)
    size: np.ndarray
    mass: float
    friction: float
    position: np.ndarray
    yaw: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, 'size', _frozen_vector('object.size', self.size, 3, 'm'))
        if np.any(self.size <= 0.0):
            raise ConfigError(f'object.size must be positive [m], got {self.size.tolist()}')
        check_range('object.mass', self.mass, 0.0, math.inf, 'kg', low_open=True)
        check_range('object.friction', self.friction, 0.0, math.inf, '', low_open=True)
        object.__setattr__(self, 'position',
                           _frozen_vector('object.position', self.position, 3, 'm'))
        check_range('object.yaw', self.yaw, -math.pi, math.pi, 'rad')


@dataclass(frozen=True)
class ReleaseConfig:
    """Desired release state of the object centre: position (3,) [m], velocity (3,) [m/s]."""

    position: np.ndarray
    velocity: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, 'position',
                           _frozen_vector('release.position', self.position, 3, 'm'))
        object.__setattr__(self, 'velocity',
                           _frozen_vector('release.velocity', self.velocity, 3, 'm/s'))


@dataclass(frozen=True)
class Speeds:
    """Task speeds [m/s]: reach (approach), impact (at contact) and toss (at release)."""

    reach: float = 0.85
    impact: float = 0.5
    toss: float = 0.85

    def __post_init__(self):
        for item in fields(self):
            check_range(f'speeds.{item.name}', getattr(self, item.name), 0.0, 3.0, 'm/s',
                        low_open=True)


@dataclass(frozen=True)
class Perturbation:
    """A scripted displacement of the object at sim time `time` [s] by (3,) [m]."""

    time: float
    object_displacement: np.ndarray

    def __post_init__(self):
        check_range('time', self.time, 0.0, math.inf, 's')
        object.__setattr__(self, 'object_displacement', _frozen_vector(
            'object_displacement', self.object_displacement, 3, 'm'))


@dataclass(frozen=True)
class MocapConfig:
    """
    Motion-capture model of the twin.

    Fields: rate_hz: sampling rate on the sim clock [Hz]; latency: delay from sampling to
    delivery [s]; position_noise: Gaussian standard deviation per axis [m];
    orientation_noise: Gaussian standard deviation of the rotation vector per axis [rad];
    dropout_probability: chance that a sample is lost [-].
    """

    rate_hz: float = 200.0
    latency: float = 0.005
    position_noise: float = 0.0005
    orientation_noise: float = 0.005
    dropout_probability: float = 0.0

    def __post_init__(self):
        check_range('rate_hz', self.rate_hz, 1.0, 1000.0, 'Hz')
        check_range('latency', self.latency, 0.0, 1.0, 's')
        check_range('position_noise', self.position_noise, 0.0, 0.1, 'm')
        check_range('orientation_noise', self.orientation_noise, 0.0, 0.5, 'rad')
        check_range('dropout_probability', self.dropout_probability, 0.0, 1.0, '',
                    high_open=True)


@dataclass(frozen=True)
class FtConfig:
    """
    Force-torque sensor model of the twin (same for both grabbers).

    Fields: force_noise [N] and torque_noise [N m]: Gaussian standard deviation per axis
    (defaults: ATI Mini45-class resolution); force_bias (3,) [N] and torque_bias (3,) [N m]:
    constant offsets in the sensor frame.
    """

    force_noise: float = 0.05
    torque_noise: float = 0.002
    force_bias: np.ndarray = (0.0, 0.0, 0.0)
    torque_bias: np.ndarray = (0.0, 0.0, 0.0)

    def __post_init__(self):
        check_range('force_noise', self.force_noise, 0.0, 100.0, 'N')
        check_range('torque_noise', self.torque_noise, 0.0, 10.0, 'N m')
        object.__setattr__(self, 'force_bias',
                           _frozen_vector('force_bias', self.force_bias, 3, 'N'))
        object.__setattr__(self, 'torque_bias',
                           _frozen_vector('torque_bias', self.torque_bias, 3, 'N m'))


@dataclass(frozen=True)
class SensorConfig:
    """Sensor models of the twin: motion capture of the object and the two FT sensors."""

    mocap: MocapConfig = field(default_factory=MocapConfig)
    ft: FtConfig = field(default_factory=FtConfig)


@dataclass(frozen=True)
class Randomization:
    """
    Per-trial randomization of a scenario (dual_arm_eval): uniform draws around its values.

    Fields: object_position (2,) half-ranges [m] of the offset of the object's initial centre
    along world x and y (uniform in +-, the gap to the surface below is kept); object_yaw:
    half-range [rad] of the offset of the initial yaw; mass (low, high) [kg], size_scale
    (low, high) [-] (factor on all three edges), friction (low, high) [-] and mocap_noise
    (low, high) [m] (mocap position noise standard deviation): ranges drawn uniformly, None
    keeps the scenario's value. The controllers are given the drawn values (the scenario is
    their prior as well as the twin's truth).
    """

    object_position: np.ndarray = (0.0, 0.0)
    object_yaw: float = 0.0
    mass: object = None
    size_scale: object = None
    friction: object = None
    mocap_noise: object = None

    def __post_init__(self):
        position = _frozen_vector('randomization.object_position', self.object_position, 2, 'm')
        for half_range in position:
            check_range('randomization.object_position', half_range, 0.0, 0.5, 'm')
        object.__setattr__(self, 'object_position', position)
        check_range('randomization.object_yaw', self.object_yaw, 0.0, math.pi, 'rad')
        bounds = {'mass': (0.0, 100.0, 'kg'), 'size_scale': (0.0, 10.0, ''),
                  'friction': (0.0, 10.0, ''), 'mocap_noise': (0.0, 0.1, 'm')}
        for name, (low, high, unit) in bounds.items():
            value = getattr(self, name)
            if value is None:
                continue
            interval = _frozen_vector(f'randomization.{name}', value, 2, unit)
            for bound in interval:
                check_range(f'randomization.{name}', bound, low, high, unit,
                            low_open=name != 'mocap_noise')
            if interval[0] > interval[1]:
                raise ConfigError(f'randomization.{name} must be [low, high] with low <= high, '
                                  f'got {interval.tolist()}')
            object.__setattr__(self, name, interval)


@dataclass(frozen=True)
class Scenario:
    """
    One run of the cell.

    Fields: name; seed (noise RNG); task (one of TASKS); object (ObjectConfig); release
    (ReleaseConfig or None); landing_target (3,) object centre at landing [m] or None; place:
    object centre at placing (3,) [m] or None; speeds (Speeds); perturbations (tuple of
    Perturbation, sorted by time); duration [s]; initial_configuration {arm: (7,) [rad]};
    sensors (SensorConfig); randomization (Randomization or None: a template for dual_arm_eval,
    see sample_trial; a single run ignores it); path (source file or None).
    """

    name: str
    seed: int
    task: str
    object: ObjectConfig  # noqa: A003 (the scenario file's key)
    speeds: Speeds
    duration: float
    initial_configuration: dict
    release: object = None
    landing_target: object = None
    place: object = None
    perturbations: tuple = ()
    sensors: SensorConfig = field(default_factory=SensorConfig)
    randomization: object = None
    path: object = None

    def __post_init__(self):
        if self.task not in TASKS:
            raise ConfigError(f'task must be one of {TASKS}, got {self.task!r}')
        if not isinstance(self.seed, int) or isinstance(self.seed, bool) or self.seed < 0:
            raise ConfigError(f'seed must be an integer >= 0, got {self.seed!r}')
        check_range('duration', self.duration, 0.0, 3600.0, 's', low_open=True)
        if self.task in TOSS_TASKS and self.release is None and self.landing_target is None:
            raise ConfigError(f'task {self.task} needs release or landing_target')
        if self.task == 'toss_to_target' and self.landing_target is None:
            raise ConfigError('task toss_to_target needs landing_target')
        if self.release is not None and self.landing_target is not None:
            raise ConfigError('give either release or landing_target, not both')
        if self.task in PLACE_TASKS and self.place is None:
            raise ConfigError(f'task {self.task} needs place')
        if set(self.initial_configuration) != set(ARMS):
            raise ConfigError(f'initial_configuration needs the arms {ARMS}')
        if self.randomization is not None and not isinstance(self.randomization,
                                                             Randomization):
            raise ConfigError(f'randomization must be a Randomization or None, got '
                              f'{self.randomization!r}')


def scenario_path(name_or_path):
    """Return the path of a scenario given its file path or its name under config/scenarios."""
    candidate = Path(name_or_path)
    if candidate.suffix in ('.yaml', '.yml') or candidate.is_file():
        return candidate
    return config_path('scenarios', f'{name_or_path}.yaml')


class _Reader:
    """Reads typed values from one YAML file; every error names the file and the dotted key."""

    def __init__(self, path):
        self.path = path

    def error(self, key, message):
        return ConfigError(f'{self.path}: key {key!r}: {message}')

    def check_keys(self, mapping, allowed, context):
        unknown = sorted(set(mapping) - set(allowed))
        if unknown:
            where = f'{context}.{unknown[0]}' if context else unknown[0]
            raise self.error(where, f'unknown key; allowed: {sorted(allowed)}')

    def mapping(self, parent, key, context='', optional=False):
        if optional and (not isinstance(parent, dict) or key not in parent):
            return None
        return require(parent, key, self.path, dict, context)

    def number(self, parent, key, context='', default=None):
        if default is not None and key not in parent:
            return float(default)
        value = require(parent, key, self.path, (int, float), context)
        if isinstance(value, bool):
            raise self.error(self._dotted(context, key), f'must be a number, got {value!r}')
        return float(value)

    def vector(self, parent, key, sizes, context='', unit=''):
        value = require(parent, key, self.path, list, context)
        dotted = self._dotted(context, key)
        if len(value) not in sizes or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
            raise self.error(dotted, f'must be a list of {" or ".join(map(str, sizes))} '
                                     f'numbers [{unit}], got {value!r}')
        return [float(v) for v in value]

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


def _resting_position(reader, cell, parent, key, context, height):
    """Read [x, y] or [x, y, z]; [x, y] rests on the surface below (centre = top + h / 2)."""
    xy_or_xyz = reader.vector(parent, key, (2, 3), context, 'm')
    if len(xy_or_xyz) == 3:
        return np.array(xy_or_xyz)
    x, y = xy_or_xyz
    return np.array([x, y, cell.surface_height(x, y) + 0.5 * height])


def _object_config(reader, data, cell, catalogue_path):
    entry = reader.mapping(data, 'object')
    reader.check_keys(entry, ('type', 'size', 'mass', 'friction', 'position', 'yaw'), 'object')
    spec = None
    if 'type' in entry:
        name = require(entry, 'type', reader.path, str, 'object')
        catalogue = load_catalogue(catalogue_path)
        if name not in catalogue:
            raise reader.error('object.type', f'unknown object type {name!r}; catalogue has '
                                              f'{sorted(catalogue)}')
        spec = catalogue[name]
    elif not {'size', 'mass', 'friction'} <= set(entry):
        raise reader.error('object.type', 'missing: give a catalogue type or size, mass and '
                                          'friction')
    size = reader.vector(entry, 'size', (3,), 'object', 'm') if 'size' in entry else spec.size
    mass = reader.number(entry, 'mass', 'object') if 'mass' in entry else spec.mass
    friction = (reader.number(entry, 'friction', 'object') if 'friction' in entry
                else spec.friction)
    if not (np.all(np.isfinite(size)) and min(size) > 0.0):
        raise reader.error('object.size', f'must be 3 positive lengths [m], got {size}')
    position = _resting_position(reader, cell, entry, 'position', 'object', size[2])
    yaw = reader.number(entry, 'yaw', 'object', default=0.0)
    return reader.build('object', ObjectConfig, spec.name if spec else None, size, mass,
                        friction, position, yaw)


def _initial_configuration(reader, data, cell):
    entry = reader.mapping(data, 'initial_configuration', optional=True) or {}
    reader.check_keys(entry, ARMS, 'initial_configuration')
    configuration = {}
    for arm in ARMS:
        description = cell.arm(arm)
        if arm not in entry:
            configuration[arm] = description.q_home
            continue
        context = f'initial_configuration.{arm}'
        q = np.array(reader.vector(entry, arm, (JOINTS_PER_ARM,), 'initial_configuration',
                                   'rad'))
        limits = _position_limits(description.urdf)
        outside = np.flatnonzero((q < limits[0]) | (q > limits[1]))
        if outside.size:
            index = int(outside[0])
            raise reader.error(context, f'A{index + 1} = {q[index]:g} rad is outside '
                                        f'[{limits[0][index]:g}, {limits[1][index]:g}] rad')
        q.setflags(write=False)
        configuration[arm] = q
    return configuration


def _position_limits(urdf):
    return ArmModel(urdf, [f'A{index}' for index in range(1, 8)]).position_limits


def _sensor_config(reader, data):
    entry = reader.mapping(data, 'sensors', optional=True)
    if entry is None:
        return SensorConfig()
    reader.check_keys(entry, ('mocap', 'ft'), 'sensors')
    mocap_entry = reader.mapping(entry, 'mocap', 'sensors', optional=True) or {}
    mocap_keys = [item.name for item in fields(MocapConfig)]
    reader.check_keys(mocap_entry, mocap_keys, 'sensors.mocap')
    mocap = reader.build('sensors.mocap', MocapConfig, **{
        key: reader.number(mocap_entry, key, 'sensors.mocap') for key in mocap_entry})
    ft_entry = reader.mapping(entry, 'ft', 'sensors', optional=True) or {}
    reader.check_keys(ft_entry, ('force_noise', 'torque_noise', 'force_bias', 'torque_bias'),
                      'sensors.ft')
    ft_values = {}
    for key in ft_entry:
        if key.endswith('_bias'):
            unit = 'N' if key == 'force_bias' else 'N m'
            ft_values[key] = reader.vector(ft_entry, key, (3,), 'sensors.ft', unit)
        else:
            ft_values[key] = reader.number(ft_entry, key, 'sensors.ft')
    return SensorConfig(mocap, reader.build('sensors.ft', FtConfig, **ft_values))


def _randomization(reader, data):
    entry = reader.mapping(data, 'randomization', optional=True)
    if entry is None:
        return None
    reader.check_keys(entry, [item.name for item in fields(Randomization)], 'randomization')
    values = {}
    if 'object_position' in entry:
        values['object_position'] = reader.vector(entry, 'object_position', (2,),
                                                  'randomization', 'm')
    if 'object_yaw' in entry:
        values['object_yaw'] = reader.number(entry, 'object_yaw', 'randomization')
    for key, unit in RANDOMIZED_RANGES.items():
        if key in entry:
            values[key] = reader.vector(entry, key, (2,), 'randomization', unit)
    return reader.build('randomization', Randomization, **values)


def load_scenario(path, cell=None, catalogue_path=None):
    """
    Load a scenario file (path or name under config/scenarios) into a Scenario.

    Raises ConfigError naming the file and the dotted key on a missing key, a wrong type, an
    unknown key or object type, or a value out of range.
    """
    path = scenario_path(path)
    cell = cell or load_cell()
    reader = _Reader(path)
    data = load_yaml(path)
    reader.check_keys(data, ('name', 'seed', 'task', 'object', 'release', 'landing_target',
                             'place', 'speeds', 'perturbations', 'duration',
                             'initial_configuration', 'sensors', 'randomization'), '')
    name = require(data, 'name', path, str)
    seed = require(data, 'seed', path, int)
    if isinstance(seed, bool) or seed < 0:
        raise reader.error('seed', f'must be an integer >= 0, got {seed!r}')
    task = require(data, 'task', path, str)
    if task not in TASKS:
        raise reader.error('task', f'must be one of {TASKS}, got {task!r}')
    if task in TOSS_TASKS and not {'release', 'landing_target'} & set(data):
        raise reader.error('release', f'missing: task {task} needs release or landing_target')
    if task == 'toss_to_target' and 'landing_target' not in data:
        raise reader.error('landing_target', 'missing: task toss_to_target needs it')
    if {'release', 'landing_target'} <= set(data):
        raise reader.error('landing_target', 'give either release or landing_target, not both')
    if task in PLACE_TASKS and 'place' not in data:
        raise reader.error('place', f'missing: task {task} needs place')
    object_config = _object_config(reader, data, cell, catalogue_path)
    height = object_config.size[2]
    release = None
    if 'release' in data:
        entry = reader.mapping(data, 'release')
        reader.check_keys(entry, ('position', 'velocity'), 'release')
        release = reader.build('release', ReleaseConfig,
                               reader.vector(entry, 'position', (3,), 'release', 'm'),
                               reader.vector(entry, 'velocity', (3,), 'release', 'm/s'))
    landing_target = None
    if 'landing_target' in data:
        landing_target = _resting_position(reader, cell, data, 'landing_target', '', height)
        landing_target.setflags(write=False)
    place = None
    if 'place' in data:
        entry = reader.mapping(data, 'place')
        reader.check_keys(entry, ('position',), 'place')
        place = _resting_position(reader, cell, entry, 'position', 'place', height)
        place.setflags(write=False)
    speeds_entry = reader.mapping(data, 'speeds')
    reader.check_keys(speeds_entry, ('reach', 'impact', 'toss'), 'speeds')
    speeds = reader.build('speeds', Speeds, **{
        key: reader.number(speeds_entry, key, 'speeds') for key in ('reach', 'impact', 'toss')})
    duration = reader.number(data, 'duration')
    perturbations = []
    entries = data.get('perturbations') or []
    if not isinstance(entries, list):
        raise reader.error('perturbations', f'must be a list, got {entries!r}')
    for index, entry in enumerate(entries):
        context = f'perturbations[{index}]'
        if not isinstance(entry, dict):
            raise reader.error(context, f'must be a mapping, got {entry!r}')
        reader.check_keys(entry, ('time', 'object_displacement'), context)
        time = reader.number(entry, 'time', context)
        if time > duration:
            raise reader.error(f'{context}.time', f'{time:g} s is after the end of the run '
                                                  f'({duration:g} s)')
        perturbations.append(reader.build(
            context, Perturbation, time,
            reader.vector(entry, 'object_displacement', (3,), context, 'm')))
    return reader.build(
        '', Scenario, name=name, seed=seed, task=task, object=object_config, speeds=speeds,
        duration=duration, initial_configuration=_initial_configuration(reader, data, cell),
        release=release, landing_target=landing_target, place=place,
        perturbations=tuple(sorted(perturbations, key=lambda item: item.time)),
        sensors=_sensor_config(reader, data), randomization=_randomization(reader, data),
        path=path)


def sample_trial(scenario, trial_index, cell=None):
    """
    Return trial number trial_index of scenario: a concrete Scenario, its randomization drawn.

    Deterministic in (scenario.seed, trial_index): a generator seeded with
    SeedSequence([seed, trial_index]) draws one uniform number per randomizable quantity in a
    fixed order (adding a range to a file leaves the other quantities' draws unchanged), then
    the trial's own seed, so every trial has different but reproducible sensor noise. The
    object keeps its gap to the surface below it; resting targets (landing_target, place)
    follow a scaled height. The trial has no randomization and no path.
    """
    if isinstance(trial_index, bool) or not isinstance(trial_index, int) or trial_index < 0:
        raise ConfigError(f'trial_index must be an integer >= 0, got {trial_index!r}')
    cell = cell or load_cell()
    generator = np.random.default_rng(np.random.SeedSequence([scenario.seed, trial_index]))
    draw = dict(zip(_TRIAL_DRAWS, generator.random(len(_TRIAL_DRAWS))))
    trial_seed = int(generator.integers(0, 2 ** 31))
    spec = scenario.randomization or Randomization()

    def from_range(name, default):
        interval = getattr(spec, name)
        if interval is None:
            return default
        return float(interval[0] + (interval[1] - interval[0]) * draw[name])

    def offset(name, half_range):
        return float(half_range * (2.0 * draw[name] - 1.0))

    box = scenario.object
    size = box.size * from_range('size_scale', 1.0)
    lift = 0.5 * (size[2] - box.size[2])
    x, y, z = box.position
    new_x = x + offset('object_x', spec.object_position[0])
    new_y = y + offset('object_y', spec.object_position[1])
    new_z = z + (cell.surface_height(new_x, new_y) - cell.surface_height(x, y)) + lift
    yaw = math.remainder(box.yaw + offset('object_yaw', spec.object_yaw), 2.0 * math.pi)
    trial_object = ObjectConfig(box.type, size, from_range('mass', box.mass),
                                from_range('friction', box.friction), [new_x, new_y, new_z],
                                yaw)
    mocap = replace(scenario.sensors.mocap, position_noise=from_range(
        'mocap_noise', scenario.sensors.mocap.position_noise))

    def raised(position):
        if position is None:
            return None
        moved = np.array(position, dtype=float) + [0.0, 0.0, lift]
        moved.setflags(write=False)
        return moved

    return replace(scenario, seed=trial_seed, object=trial_object,
                   landing_target=raised(scenario.landing_target), place=raised(scenario.place),
                   sensors=replace(scenario.sensors, mocap=mocap), randomization=None,
                   path=None)


def scenario_document(scenario):
    """
    Return scenario as the mapping load_scenario reads (write it with yaml.safe_dump).

    Every value is explicit (object size, mass and friction beside its type, 3D positions,
    both arms' initial configuration, every sensor field), so loading the document gives back
    an equal Scenario whatever the catalogue's and the loader's defaults.
    """
    def numbers(values):
        return [float(value) for value in values]

    box = scenario.object
    object_entry = {} if box.type is None else {'type': box.type}
    object_entry.update(size=numbers(box.size), mass=float(box.mass),
                        friction=float(box.friction), position=numbers(box.position),
                        yaw=float(box.yaw))
    document = {'name': scenario.name, 'seed': int(scenario.seed), 'task': scenario.task,
                'object': object_entry}
    if scenario.release is not None:
        document['release'] = {'position': numbers(scenario.release.position),
                               'velocity': numbers(scenario.release.velocity)}
    if scenario.landing_target is not None:
        document['landing_target'] = numbers(scenario.landing_target)
    if scenario.place is not None:
        document['place'] = {'position': numbers(scenario.place)}
    document['speeds'] = {item.name: float(getattr(scenario.speeds, item.name))
                          for item in fields(Speeds)}
    if scenario.perturbations:
        document['perturbations'] = [
            {'time': float(item.time), 'object_displacement': numbers(item.object_displacement)}
            for item in scenario.perturbations]
    document['duration'] = float(scenario.duration)
    document['initial_configuration'] = {arm: numbers(scenario.initial_configuration[arm])
                                         for arm in ARMS}
    mocap, ft = scenario.sensors.mocap, scenario.sensors.ft
    document['sensors'] = {
        'mocap': {item.name: float(getattr(mocap, item.name)) for item in fields(MocapConfig)},
        'ft': {'force_noise': float(ft.force_noise), 'torque_noise': float(ft.torque_noise),
               'force_bias': numbers(ft.force_bias), 'torque_bias': numbers(ft.torque_bias)}}
    spec = scenario.randomization
    if spec is not None:
        entry = {'object_position': numbers(spec.object_position),
                 'object_yaw': float(spec.object_yaw)}
        entry.update({name: numbers(getattr(spec, name)) for name in RANDOMIZED_RANGES
                      if getattr(spec, name) is not None})
        document['randomization'] = entry
    return document
