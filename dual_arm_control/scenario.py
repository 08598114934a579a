"""
Scenario files (config/scenarios/*.yaml) as frozen dataclasses.

A scenario fixes everything a run needs besides the controllers' parameters: task, object (type
from the catalogue or explicit size/mass/friction, pose), release or landing target, placing
position, task speeds, scripted perturbations, duration, initial joint configuration and sensor
models of the twin, and optionally the ranges a batch evaluation draws its trials from
(dual_arm_control.randomization). Positions given as [x, y] rest on the surface below
(pallet, front table or floor of config/cell.yaml). Every error names the file and the
dotted key. dual_arm_control.scenario_writer writes a Scenario back as such a file.
"""

from dataclasses import dataclass, field
import math
from pathlib import Path
import warnings

from dual_arm_control.catalogue import load_catalogue
from dual_arm_control.conveyor import ConveyorConfig
from dual_arm_control.core.arms import ARMS
from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.impact import ImpactConfig
from dual_arm_control.core.manipulation import TossConfig
from dual_arm_control.core.robot_model import ArmModel, JOINTS_PER_ARM
from dual_arm_control.core.speed_shaping import SpeedProfileConfig
from dual_arm_control.core.validation import check_range, frozen_vector
from dual_arm_control.description.cell import load_cell
from dual_arm_control.incoming_belt import IncomingBeltConfig
from dual_arm_control.randomization import Randomization, read_randomization
from dual_arm_control.resources import config_path, load_yaml, require
from dual_arm_control.scenario_reader import ScenarioReader
from dual_arm_control.sensor_models import read_sensor_config, SensorConfig
import numpy as np

TASKS = ('pick_and_toss', 'pick_and_place', 'pick_and_lift', 'place_toss', 'toss_to_target')
TOSS_TASKS = ('pick_and_toss', 'toss_to_target')
PLACE_TASKS = ('pick_and_place', 'place_toss')


class IgnoredSettingWarning(UserWarning):
    """A scenario setting that another one overrides (load_scenario names the file)."""


# Largest difference [m/s] between speeds.toss and |release.velocity| taken as agreement
# (release velocities are written to 4 decimals: the paper's [0.7603, 0, 0.3801] is 0.85002).
TOSS_SPEED_TOLERANCE = 0.005


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
        object.__setattr__(self, 'size', frozen_vector('object.size', self.size, 3, 'm'))
        if np.any(self.size <= 0.0):
            raise ConfigError(f'object.size must be positive [m], got {self.size.tolist()}')
        check_range('object.mass', self.mass, 0.0, math.inf, 'kg', low_open=True)
        check_range('object.friction', self.friction, 0.0, math.inf, '', low_open=True)
        object.__setattr__(self, 'position',
                           frozen_vector('object.position', self.position, 3, 'm'))
        check_range('object.yaw', self.yaw, -math.pi, math.pi, 'rad')


@dataclass(frozen=True)
class ReleaseConfig:
    """Desired release state of the object centre: position (3,) [m], velocity (3,) [m/s]."""

    position: np.ndarray
    velocity: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, 'position',
                           frozen_vector('release.position', self.position, 3, 'm'))
        object.__setattr__(self, 'velocity',
                           frozen_vector('release.velocity', self.velocity, 3, 'm/s'))


# Each task speed configures one core setting, whose default and range it takes.
_SPEED_SETTINGS = {'reach': (SpeedProfileConfig, 'reach_speed'),
                   'impact': (ImpactConfig, 'impact_speed'),
                   'toss': (TossConfig, 'toss_speed')}


@dataclass(frozen=True)
class Speeds:
    """
    Task speeds [m/s]: reach (approach), impact (at contact) and toss (at release).

    toss may be None (left out): a scenario's release velocity sets the toss speed, and the
    release planner chooses it for a landing target (ignored_toss_speed says when it differs).
    """

    reach: float = SpeedProfileConfig.reach_speed
    impact: float = ImpactConfig.impact_speed
    toss: object = None

    def __post_init__(self):
        for name, (config_class, setting) in _SPEED_SETTINGS.items():
            if getattr(self, name) is None and name == 'toss':
                continue
            try:
                config_class(**{setting: getattr(self, name)})
            except ConfigError as error:
                raise ConfigError(str(error).replace(setting, f'speeds.{name}', 1)) from None


@dataclass(frozen=True)
class Perturbation:
    """A scripted displacement of the object at sim time `time` [s] by (3,) [m]."""

    time: float
    object_displacement: np.ndarray

    def __post_init__(self):
        check_range('time', self.time, 0.0, math.inf, 's')
        object.__setattr__(self, 'object_displacement', frozen_vector(
            'object_displacement', self.object_displacement, 3, 'm'))


@dataclass(frozen=True)
class Scenario:
    """
    One run of the cell.

    Fields: name; seed (noise RNG); task (one of TASKS); object (ObjectConfig); release
    (ReleaseConfig or None); landing_target (3,) object centre at landing [m] or None;
    release_orientation (3,) roll, pitch, yaw [deg] of the object at release, world frame (toss
    tasks; None: the object keeps the orientation it was grasped in); place:
    object centre at placing (3,) [m] or None; speeds (Speeds); perturbations (tuple of
    Perturbation, sorted by time); duration [s]; initial_configuration {arm: (7,) [rad]};
    sensors (SensorConfig); conveyor (ConveyorConfig or None: the outgoing belt and its
    container; toss tasks then aim into the moving container); incoming_belt
    (IncomingBeltConfig or None: the belt the box arrives on); randomization (Randomization
    or None: a template for dual_arm_eval, see sample_trial; a single run ignores it); path
    (source file or None).
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
    release_orientation: object = None
    place: object = None
    perturbations: tuple = ()
    sensors: SensorConfig = field(default_factory=SensorConfig)
    conveyor: object = None
    incoming_belt: object = None
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
        if self.release_orientation is not None:
            if self.task not in TOSS_TASKS:
                raise ConfigError(f'release_orientation needs a toss task, got {self.task}')
            rpy = frozen_vector('release_orientation', self.release_orientation, 3, 'deg')
            for index, angle in enumerate(rpy):
                check_range(f'release_orientation[{index}]', angle, -180.0, 180.0, 'deg')
            object.__setattr__(self, 'release_orientation', rpy)
        if set(self.initial_configuration) != set(ARMS):
            raise ConfigError(f'initial_configuration needs the arms {ARMS}')
        if self.conveyor is not None and not isinstance(self.conveyor, ConveyorConfig):
            raise ConfigError(f'conveyor must be a ConveyorConfig or None, got {self.conveyor!r}')
        if self.incoming_belt is not None and not isinstance(self.incoming_belt,
                                                             IncomingBeltConfig):
            raise ConfigError('incoming_belt must be an IncomingBeltConfig or None')
        if self.randomization is not None and not isinstance(self.randomization,
                                                             Randomization):
            raise ConfigError(f'randomization must be a Randomization or None, got '
                              f'{self.randomization!r}')
        if (self.randomization is not None and self.randomization.landing_target is not None
                and self.landing_target is None):
            raise ConfigError('randomization.landing_target offsets the landing_target, and '
                              'the scenario has none (task toss_to_target)')


def ignored_toss_speed(scenario):
    """
    Return why a Scenario's speeds.toss is ignored, or '' (left out, or it agrees).

    A release's velocity sets the toss speed, and the release planner chooses it for a
    landing_target; a speeds.toss beside them that says otherwise would be dropped unseen.
    """
    toss = scenario.speeds.toss
    if toss is None:
        return ''
    if scenario.landing_target is not None:
        return (f'speeds.toss = {toss:g} m/s is ignored: the release planner chooses the '
                f'release speed for the landing_target; leave speeds.toss out')
    if scenario.release is not None:
        release_speed = float(np.linalg.norm(scenario.release.velocity))
        if abs(toss - release_speed) > TOSS_SPEED_TOLERANCE:
            return (f'speeds.toss = {toss:g} m/s is ignored: |release.velocity| = '
                    f'{release_speed:.4g} m/s sets the toss speed; leave speeds.toss out or '
                    f'make the two agree')
    return ''


def scenario_path(name_or_path):
    """Return the path of a scenario given its file path or its name under config/scenarios."""
    candidate = Path(name_or_path)
    if candidate.suffix in ('.yaml', '.yml') or candidate.is_file():
        return candidate
    return config_path('scenarios', f'{name_or_path}.yaml')


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


def load_scenario(path, cell=None, catalogue_path=None):
    """
    Load a scenario file (path or name under config/scenarios) into a Scenario.

    Raises ConfigError naming the file and the dotted key on a missing key, a wrong type, an
    unknown key or object type, or a value out of range; warns (IgnoredSettingWarning) of a
    speeds.toss the release velocity or the release planner overrides.
    """
    path = scenario_path(path)
    cell = cell or load_cell()
    reader = ScenarioReader(path)
    data = load_yaml(path)
    reader.check_keys(data, ('name', 'seed', 'task', 'object', 'release', 'landing_target',
                             'release_orientation', 'place', 'speeds', 'perturbations', 'duration',
                             'initial_configuration', 'sensors', 'conveyor', 'incoming_belt',
                             'randomization'), '')
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
        key: reader.number(speeds_entry, key, 'speeds') for key in ('reach', 'impact')},
        toss=(reader.number(speeds_entry, 'toss', 'speeds') if 'toss' in speeds_entry
              else None))
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
    scenario = reader.build(
        '', Scenario, name=name, seed=seed, task=task, object=object_config, speeds=speeds,
        duration=duration, initial_configuration=_initial_configuration(reader, data, cell),
        release=release, landing_target=landing_target, place=place,
        release_orientation=(reader.vector(data, 'release_orientation', (3,), '', 'deg')
                             if 'release_orientation' in data else None),
        perturbations=tuple(sorted(perturbations, key=lambda item: item.time)),
        sensors=read_sensor_config(reader, data),
        conveyor=reader.settings_block(data, 'conveyor', ConveyorConfig),
        incoming_belt=reader.settings_block(data, 'incoming_belt', IncomingBeltConfig),
        randomization=read_randomization(reader, data, catalogue_path),
        path=path)
    ignored = ignored_toss_speed(scenario)
    if ignored:
        warnings.warn(f'{path}: {ignored}', IgnoredSettingWarning, stacklevel=2)
    return scenario
