"""Scenario files: the shipped ones load, broken ones name the file and the key."""

import math
import warnings

from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.impact import ImpactConfig
from dual_arm_control.core.manipulation import TossConfig
from dual_arm_control.core.speed_shaping import SpeedProfileConfig
from dual_arm_control.description.cell import load_cell
from dual_arm_control.runtime.configuration import motion_config_for_scenario
from dual_arm_control.scenario import (IgnoredSettingWarning, load_scenario, ObjectConfig,
                                       Scenario, Speeds)
from dual_arm_control.sensor_models import MocapConfig
import numpy as np
import pytest
import yaml

SHIPPED = ('paper_toss', 'paper_place', 'hold', 'cube_drop')
PAPER_CUBE_HEIGHT = 0.20    # [m]
PALLET_TOP = 0.22           # [m]
TABLE_TOP = 0.15            # [m]


@pytest.fixture(scope='module')
def cell():
    return load_cell()


@pytest.mark.parametrize('name', SHIPPED)
def test_shipped_scenarios_load(cell, name):
    scenario = load_scenario(name, cell)
    assert scenario.name == name
    assert scenario.duration > 0.0
    assert scenario.object.mass == pytest.approx(0.7)
    assert scenario.object.size == pytest.approx([PAPER_CUBE_HEIGHT] * 3)
    for arm in ('left', 'right'):
        assert scenario.initial_configuration[arm] == pytest.approx(cell.arm(arm).q_home)


def test_paper_toss_values(cell):
    scenario = load_scenario('paper_toss', cell)
    assert scenario.task == 'pick_and_toss'
    assert scenario.object.position == pytest.approx(
        [0.41, 0.0, PALLET_TOP + PAPER_CUBE_HEIGHT / 2])
    assert scenario.release.position == pytest.approx([0.68, 0.0, 0.45])
    velocity = scenario.release.velocity
    assert np.linalg.norm(velocity) == pytest.approx(0.85, abs=1e-3)
    assert velocity / np.linalg.norm(velocity) == pytest.approx(
        np.array([1.0, 0.0, 0.5]) / math.sqrt(1.25), abs=1e-4)
    assert (scenario.speeds.reach, scenario.speeds.impact, scenario.speeds.toss) == \
        (0.85, 0.5, 0.85)
    assert scenario.duration == 4.0
    assert scenario.sensors.mocap == MocapConfig()


def test_place_rests_on_the_front_table(cell):
    scenario = load_scenario('paper_place', cell)
    assert scenario.place == pytest.approx([0.75, 0.0, TABLE_TOP + PAPER_CUBE_HEIGHT / 2])


def test_cube_drop_starts_five_centimetres_up(cell):
    scenario = load_scenario('cube_drop', cell)
    bottom = scenario.object.position[2] - PAPER_CUBE_HEIGHT / 2
    assert bottom - PALLET_TOP == pytest.approx(0.05)
    assert scenario.sensors.mocap.dropout_probability == pytest.approx(0.05)


def write(tmp_path, data, name='broken.yaml'):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


def good_data():
    return {
        'name': 'test', 'seed': 0, 'task': 'pick_and_toss',
        'object': {'type': 'paper_cube', 'position': [0.41, 0.0]},
        'release': {'position': [0.68, 0.0, 0.45], 'velocity': [0.76, 0.0, 0.38]},
        'speeds': {'reach': 0.85, 'impact': 0.5, 'toss': 0.85},
        'duration': 4.0,
    }


def test_minimal_file_loads_with_defaults(tmp_path, cell):
    data = good_data()
    data['perturbations'] = [{'time': 1.5, 'object_displacement': [0.0, 0.02, 0.0]},
                             {'time': 0.5, 'object_displacement': [0.01, 0.0, 0.0]}]
    data['initial_configuration'] = {'left': [0.0] * 7}
    data['object'] = {'size': [0.1, 0.2, 0.3], 'mass': 1.0, 'friction': 0.5,
                      'position': [1.0, 0.0], 'yaw': 0.3}
    scenario = load_scenario(write(tmp_path, data), cell)
    assert [item.time for item in scenario.perturbations] == [0.5, 1.5]
    assert scenario.initial_configuration['left'] == pytest.approx(np.zeros(7))
    assert scenario.initial_configuration['right'] == pytest.approx(cell.arm('right').q_home)
    assert scenario.object.type is None
    assert scenario.object.position == pytest.approx([1.0, 0.0, TABLE_TOP + 0.15])
    assert scenario.sensors.ft.force_noise >= 0.0


def without(data, dotted):
    parent = data
    *path, key = dotted.split('.')
    for part in path:
        parent = parent[part]
    del parent[key]
    return data


def replaced(data, dotted, value):
    parent = data
    *path, key = dotted.split('.')
    for part in path:
        parent = parent[part]
    parent[key] = value
    return data


@pytest.mark.parametrize('dotted', ['name', 'seed', 'task', 'object', 'object.position',
                                    'speeds', 'speeds.impact', 'duration', 'release',
                                    'release.velocity'])
def test_missing_key_names_file_and_key(tmp_path, cell, dotted):
    path = write(tmp_path, without(good_data(), dotted))
    with pytest.raises(ConfigError) as error:
        load_scenario(path, cell)
    assert str(path) in str(error.value)
    assert dotted in str(error.value), str(error.value)


@pytest.mark.parametrize('dotted, value', [
    ('seed', 'one'), ('seed', -1), ('task', 'juggle'), ('duration', 'long'), ('duration', -1.0),
    ('object.type', 'anvil'), ('object.type', 3), ('object.position', [0.4]),
    ('object.position', 'here'), ('object.yaw', 7.0), ('speeds.toss', -0.5),
    ('speeds.reach', True), ('release.position', [0.6, 0.0]), ('release.velocity', 'fast'),
    ('object.colour', 'red'), ('sensors.mocap.rate_hz', 0.0),
    ('sensors.mocap.dropout_probability', 1.0), ('sensors.ft.force_bias', [0.0, 1.0]),
    ('initial_configuration', {'left': [9.0] * 7}), ('perturbations', [{'time': 9.0,
                                                     'object_displacement': [0, 0, 0]}]),
])
def test_bad_value_names_file_and_key(tmp_path, cell, dotted, value):
    data = good_data()
    if dotted.startswith('sensors'):
        data['sensors'] = {'mocap': {}, 'ft': {}}
    path = write(tmp_path, replaced(data, dotted, value))
    with pytest.raises(ConfigError) as error:
        load_scenario(path, cell)
    message = str(error.value)
    assert str(path) in message
    assert f"key '{dotted}" in message, message


def test_task_requirements(tmp_path, cell):
    data = good_data()
    data['task'] = 'pick_and_place'
    with pytest.raises(ConfigError, match="'place'"):
        load_scenario(write(tmp_path, data), cell)
    data['task'] = 'toss_to_target'
    with pytest.raises(ConfigError, match='landing_target'):
        load_scenario(write(tmp_path, data), cell)
    del data['release'], data['speeds']['toss']
    data['landing_target'] = [1.0, 0.1]
    scenario = load_scenario(write(tmp_path, data), cell)
    assert scenario.landing_target == pytest.approx([1.0, 0.1, TABLE_TOP + 0.1])


def test_a_toss_speed_the_release_velocity_overrides_is_reported(tmp_path, cell):
    """A speeds.toss that differs from |release.velocity| is ignored, and the loader says so."""
    data = good_data()
    data['speeds']['toss'] = 0.5
    path = write(tmp_path, data)
    with pytest.warns(IgnoredSettingWarning) as caught:
        scenario = load_scenario(path, cell)
    [message] = [str(item.message) for item in caught]
    assert str(path) in message and 'speeds.toss' in message and 'release.velocity' in message
    release_speed = np.linalg.norm([0.76, 0.0, 0.38])
    toss = motion_config_for_scenario(scenario, cell).toss
    assert toss.toss_speed == pytest.approx(release_speed, abs=1e-12)
    for agreeing in ({'toss': 0.852}, {}):
        data['speeds'] = {'reach': 0.85, 'impact': 0.5, **agreeing}
        with warnings.catch_warnings():
            warnings.simplefilter('error')
            scenario = load_scenario(write(tmp_path, data), cell)
        assert motion_config_for_scenario(scenario, cell).toss.toss_speed == pytest.approx(
            release_speed, abs=1e-12)


def test_a_toss_speed_beside_a_landing_target_is_reported(tmp_path, cell):
    """The release planner chooses the speed for a landing target; a given one is ignored."""
    data = good_data()
    data['task'] = 'toss_to_target'
    del data['release']
    data['landing_target'] = [1.0, 0.1]
    path = write(tmp_path, data)
    with pytest.warns(IgnoredSettingWarning, match='speeds.toss .* landing_target') as caught:
        scenario = load_scenario(path, cell)
    assert str(path) in str(caught[0].message)
    del data['speeds']['toss']
    planned = motion_config_for_scenario(load_scenario(write(tmp_path, data), cell), cell)
    assert motion_config_for_scenario(scenario, cell).toss == planned.toss


def test_unknown_scenario_name_names_the_file(cell):
    with pytest.raises(ConfigError, match='no_such_scenario.yaml'):
        load_scenario('no_such_scenario', cell)


def test_dataclasses_validate_on_their_own():
    with pytest.raises(ConfigError, match='speeds.impact'):
        Speeds(impact=0.0)
    with pytest.raises(ConfigError, match='object.mass'):
        ObjectConfig('x', [0.1, 0.1, 0.1], -1.0, 1.0, [0.0, 0.0, 0.0])
    box = ObjectConfig('x', [0.1, 0.1, 0.1], 1.0, 1.0, [0.0, 0.0, 0.0])
    with pytest.raises(ConfigError, match='needs place'):
        Scenario('s', 0, 'pick_and_place', box, Speeds(), 1.0,
                 {'left': np.zeros(7), 'right': np.zeros(7)})


@pytest.mark.parametrize('name, config_class, setting', [
    ('reach', SpeedProfileConfig, 'reach_speed'), ('impact', ImpactConfig, 'impact_speed'),
    ('toss', TossConfig, 'toss_speed')])
def test_task_speeds_have_the_core_settings_defaults_and_ranges(name, config_class, setting):
    # The toss speed has no default of its own: the release velocity or the planner sets it.
    default = None if name == 'toss' else getattr(config_class(), setting)
    assert getattr(Speeds(), name) == default
    for value in (0.0, -0.1, 2.5, 3.5, math.inf):
        try:
            config_class(**{setting: value})
        except ConfigError:
            with pytest.raises(ConfigError, match=f'speeds.{name}'):
                Speeds(**{name: value})
        else:
            assert getattr(Speeds(**{name: value}), name) == value
