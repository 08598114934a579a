"""The parameter table is the one source: nodes declare it, config files and docs agree."""

import dataclasses
import math

from conftest import SOURCE_ROOT
from dual_arm_control.core.arms import ARMS
from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.motion_config import MotionGeneratorConfig
from dual_arm_control.core.settings import Setting
from dual_arm_control.description.cell import load_cell
from dual_arm_control.graph import GRAPHS
from dual_arm_control.nodes.ds_motion_generator import DsMotionGenerator
from dual_arm_control.nodes.object_tracker import ObjectTrackerNode
from dual_arm_control.nodes.passive_controller import PassiveControllerNode
from dual_arm_control.nodes.wrench_qp import WrenchQPNode
from dual_arm_control.parameter_files import (BUILT_IN_PARAMETERS, key_applies,
                                              node_parameter_names, parameter_file_problems,
                                              parameter_reference)
from dual_arm_control.resources import load_yaml
from dual_arm_control.runtime.config_tree import config_leaves, config_with_values
from dual_arm_control.runtime.configuration import motion_config_for_scenario
from dual_arm_control.runtime.node_settings import node_table, NODE_TABLES
from dual_arm_control.scenario import load_scenario
from graph_helpers import GraphProbe
import numpy as np
import pytest
from rclpy.parameter import Parameter
from sim_bridge.bridge_node import SimBridge
from sim_bridge.gravity_comp_controller import GravityCompController

CONFIG = SOURCE_ROOT / 'config'
NODE_CONFIG_FILES = sorted(path for path in CONFIG.glob('*.yaml')
                           if path.name not in ('cell.yaml', 'objects.yaml'))
GRAPH = GRAPHS['full']() + GRAPHS['hold']()


def test_the_parameter_reference_is_generated_from_the_table():
    text = (SOURCE_ROOT / 'docs' / 'parameters.md').read_text()
    assert text == parameter_reference(), (
        'docs/parameters.md is stale: python -m dual_arm_control.parameter_files > '
        'docs/parameters.md')


@pytest.mark.parametrize('path', NODE_CONFIG_FILES, ids=lambda path: path.name)
def test_shipped_config_files_agree_with_the_table(path):
    """Every key is a parameter of a node it applies to, with the table's default value."""
    assert parameter_file_problems(path, GRAPH) == []
    for key, entry in load_yaml(path).items():
        for spec in (spec for spec in GRAPH if key_applies(key, spec)):
            table = node_table(spec.executable)
            defaults = {leaf.name: leaf.setting for leaf in (
                config_leaves(table.config()) if table.config else [])}
            defaults.update({setting.name: setting for setting in table.settings})
            for name, value in entry['ros__parameters'].items():
                setting = defaults.get(name)
                if setting is None or setting.problem(setting.default) is not None:
                    continue
                assert value == pytest.approx(setting.default), (path.name, key, name)


def test_a_bad_file_is_reported_with_file_node_key_and_reason(tmp_path):
    path = tmp_path / 'bad.yaml'
    path.write_text('wrench_qp:\n  ros__parameters:\n    qp.friction_coefficient: -1.0\n'
                    '    object_size: [0.2, 0.2]\n    speed: 3\n'
                    '/right/passive_controller:\n  ros__parameters:\n    command_timeout: 0.006\n')
    problems = parameter_file_problems(path, GRAPH)
    assert problems == [
        f'{path}: wrench_qp: qp.friction_coefficient: friction_coefficient = -1 is outside '
        '(0, 5]',
        f'{path}: wrench_qp: object_size: object_size must have 3 elements, got 2',
        f'{path}: wrench_qp: speed: unknown parameter (not declared by /wrench_qp)',
        f'{path}: /right/passive_controller: command_timeout = 0.006 s must exceed ds_period + '
        'fri_period = 0.007 s, the longest gap between two DS commands',
    ]


def test_settings_refuse_what_they_do_not_allow():
    speed = Setting('speed', 0.5, 'a speed', 'm/s', 0.0, 2.0, low_open=True)
    assert speed.problem(0.5) is None and speed.problem(2.0) is None
    assert speed.problem(0.0) == 'speed = 0 m/s is outside (0, 2] m/s'
    assert speed.problem(math.nan) == 'speed must be finite, got nan'
    assert speed.problem(True) == 'speed must be a number, got True'
    assert speed.problem('fast') == "speed must be a number, got 'fast'"
    period = Setting('period', 0.002, 'a period', 's', choices=(0.001, 0.002, 0.005))
    assert period.problem(0.003) == 'period must be one of 0.001, 0.002, 0.005 s, got 0.003'
    mode = Setting('mode', 'a', 'a mode', choices=('a', 'b'))
    assert mode.problem('c') == "mode must be one of a, b, got 'c'"
    names = Setting('nodes', ('',), 'names')
    assert names.problem(['/a', '/b']) is None and names.problem([1]) is not None


NODE_CLASSES = {'sim_bridge': SimBridge, 'object_tracker': ObjectTrackerNode,
                'ds_motion_generator': DsMotionGenerator, 'wrench_qp': WrenchQPNode,
                'passive_controller': PassiveControllerNode,
                'gravity_comp_controller': GravityCompController}


@pytest.mark.parametrize('executable', sorted(NODE_CLASSES))
def test_each_node_declares_exactly_its_table(ros_domain, executable):
    probe = GraphProbe(ros_domain)
    overrides = ([Parameter('arm', value='left')] if executable.endswith('controller')
                 else [])
    try:
        node = NODE_CLASSES[executable](context=probe.context, parameter_overrides=overrides)
        declared = set(node._parameters) - set(BUILT_IN_PARAMETERS)
        spec = next(spec for spec in GRAPH if spec.executable == executable)
        assert declared == set(node_parameter_names(spec))
        for entry in node_table(executable).settings:
            descriptor = node.describe_parameter(entry.name)
            assert entry.description in descriptor.description
            assert descriptor.read_only == entry.read_only
        node.destroy_node()
    finally:
        probe.close()


CONFIG_TABLES = {name: table for name, table in NODE_TABLES.items() if table.config is not None}


def _outside(setting):
    """Return values just outside the declared interval of a numeric setting."""
    step = 1 if setting.kind is int else 1e-3 * max(1.0, abs(setting.high), abs(setting.low))
    values = []
    if math.isfinite(setting.high):
        values.append(setting.high if setting.high_open else setting.high + step)
    if math.isfinite(setting.low):
        values.append(setting.low if setting.low_open else setting.low - step)
    return values


@pytest.mark.parametrize('node', sorted(CONFIG_TABLES))
def test_config_validation_enforces_the_declared_ranges(node):
    """Every declared range is the one the config enforces: a value just outside is refused."""
    config = CONFIG_TABLES[node].config()
    checked = 0
    for leaf in config_leaves(config):
        entry = leaf.setting
        assert entry.description and entry.description != leaf.path[-1], leaf.name
        assert entry.problem(leaf.default) is None, leaf.name
        if entry.kind not in (int, float, list):
            continue
        for bad in _outside(entry):
            value = [bad] * entry.length if entry.kind is list else bad
            with pytest.raises(ConfigError, match=leaf.path[-1]):
                config_with_values(config, {leaf.path: value})
            checked += 1
    assert checked >= 10


def test_a_tunable_field_without_a_setting_is_refused():
    @dataclasses.dataclass(frozen=True)
    class BareConfig:
        gain: float = 1.0

    with pytest.raises(TypeError, match='BareConfig.gain'):
        config_leaves(BareConfig())


@pytest.mark.parametrize('scenario_name', ['paper_toss', 'paper_place', 'conveyor_toss'])
def test_a_scenario_config_is_the_motion_generators_parameters(scenario_name):
    """The cell facts a scenario adds (standby poses, the pallet) are not parameters."""
    cell = load_cell()
    config = motion_config_for_scenario(load_scenario(scenario_name, cell=cell), cell)
    names = {leaf.name for leaf in config_leaves(config)}
    assert names == {leaf.name for leaf in config_leaves(MotionGeneratorConfig())}
    assert config.place.pallet == cell.pallet.top_face()


def test_a_motion_generator_without_a_scenario_has_the_cells_pallet_and_standby_poses(
        ros_domain):
    """Started without a scenario (ros2 run), the node still keeps boxes clear of the pallet."""
    cell = load_cell()
    assert MotionGeneratorConfig().place.pallet == ()
    probe = GraphProbe(ros_domain)
    try:
        node = DsMotionGenerator(context=probe.context)
        config = node.step.config
        node.destroy_node()
    finally:
        probe.close()
    assert config.place.pallet == cell.pallet.top_face()
    for arm, position, rotation in zip(ARMS, config.standby_positions, config.standby_rotations):
        np.testing.assert_array_equal(position, cell.arm(arm).standby_position)
        np.testing.assert_array_equal(rotation, cell.arm(arm).R_world_standby)
