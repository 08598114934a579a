"""
The ROS launch file and the launcher start the same graph, and that graph runs.

launch/launch_ros are not installable from pip, so this test loads the launch file with small
recording stand-ins for those two modules (only the launch API is replaced; the node table,
parameters and config paths are the product's own), compares what it would start with the
launcher's command lines, and starts the nodes it describes as real processes.
"""

import importlib.util
import sys
import types

from conftest import SOURCE_ROOT
from dual_arm_control.bringup import node_command, ros_value
from dual_arm_control.graph import GRAPHS, run_parameters
from dual_arm_control.nodes.ds_motion_generator import (phase_log_events, phase_log_line,
                                                        PHASE_LOG_PREFIX)
from graph_helpers import parameter_arguments, ProcessGroup
import pytest

EPISODE_TIMEOUT = 120.0         # [s] of wall time for 2 s of lockstep sim time on 2 loaded cores


class _Recorded:
    def __init__(self, *args, **kwargs):
        self.args = args
        self.kwargs = kwargs


class _LaunchConfiguration:
    values = {}

    def __init__(self, name):
        self.name = name

    def perform(self, context):
        return self.values[self.name]


def _load_launch_file(monkeypatch):
    launch = types.ModuleType('launch')
    launch.LaunchDescription = _Recorded
    actions = types.ModuleType('launch.actions')
    actions.DeclareLaunchArgument = _Recorded
    actions.OpaqueFunction = _Recorded
    substitutions = types.ModuleType('launch.substitutions')
    substitutions.LaunchConfiguration = _LaunchConfiguration
    launch_ros = types.ModuleType('launch_ros')
    ros_actions = types.ModuleType('launch_ros.actions')
    ros_actions.Node = _Recorded
    for name, module in (('launch', launch), ('launch.actions', actions),
                         ('launch.substitutions', substitutions), ('launch_ros', launch_ros),
                         ('launch_ros.actions', ros_actions)):
        monkeypatch.setitem(sys.modules, name, module)
    path = SOURCE_ROOT / 'launch' / 'dual_arm.launch.py'
    spec = importlib.util.spec_from_file_location('dual_arm_launch', path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _launcher_parameters(argv):
    """Return (param files, {name: value}) from a launcher command line's ROS arguments."""
    files, values = [], {}
    for flag, value in zip(argv, argv[1:]):
        if flag == '--params-file':
            files.append(value)
        elif flag == '-p':
            name, _, text = value.partition(':=')
            values[name] = text
    return files, values


@pytest.mark.parametrize('graph', sorted(GRAPHS))
@pytest.mark.parametrize('mode', ['lockstep', 'realtime'])
def test_launch_file_starts_the_launcher_graph(monkeypatch, graph, mode):
    module = _load_launch_file(monkeypatch)
    scenario = str(SOURCE_ROOT / 'config' / 'scenarios' / 'paper_toss.yaml')
    _LaunchConfiguration.values = {'graph': graph, 'scenario': scenario, 'mode': mode,
                                   'params_file': ''}
    launched = module.graph_nodes(context=None)
    specs = GRAPHS[graph]()
    assert len(launched) == len(specs)
    per_node = run_parameters(graph, scenario, mode)
    for action, spec in zip(launched, specs):
        assert action.kwargs['executable'] == spec.executable
        assert action.kwargs['name'] == spec.name
        assert (action.kwargs['namespace'] or '') == spec.namespace
        files = [p for p in action.kwargs['parameters'] if isinstance(p, str)]
        values = {k: v for p in action.kwargs['parameters'] if isinstance(p, dict)
                  for k, v in p.items()}
        run_arguments = []
        for name, value in per_node.get(spec.name, {}).items():
            run_arguments += ['-p', f'{name}:={ros_value(value)}']
        launcher_files, launcher_values = _launcher_parameters(node_command(spec, run_arguments))
        assert files == launcher_files
        assert {name: ros_value(value) for name, value in values.items()} == launcher_values


def test_a_users_parameter_file_has_the_last_word(tmp_path):
    from dual_arm_control.bringup import Launcher
    user_file = tmp_path / 'user.yaml'
    user_file.write_text('sim_bridge:\n  ros__parameters:\n    duration: 7.0\n'
                         '/**:\n  ros__parameters:\n    use_sim_time: false\n')
    specs = GRAPHS['full']()
    launcher = Launcher(specs, tmp_path, 1, user_file,
                        run_parameters('full', None, 'lockstep'))
    commands = {}
    for spec in specs:
        commands[spec.label] = launcher.command(spec)
    bridge = ' '.join(commands['sim_bridge'])
    assert 'duration:=' not in bridge and 'mode:=lockstep' in bridge
    assert bridge.endswith(f'--params-file {user_file}')
    assert 'use_sim_time:=' not in ' '.join(commands['left_passive_controller'])


def test_the_nodes_the_launch_file_describes_run_an_episode(monkeypatch, tmp_path, ros_domain):
    """Start each Node action as `ros2 run` would (name, namespace, files, values), lockstep."""
    module = _load_launch_file(monkeypatch)
    user_file = tmp_path / 'short.yaml'
    user_file.write_text('sim_bridge:\n  ros__parameters:\n    duration: 2.0\n')
    _LaunchConfiguration.values = {
        'graph': 'full', 'mode': 'lockstep', 'params_file': str(user_file),
        'scenario': str(SOURCE_ROOT / 'config' / 'scenarios' / 'paper_toss.yaml')}
    with ProcessGroup(tmp_path, ros_domain) as group:
        labels = []
        for action in module.graph_nodes(context=None):
            node = action.kwargs
            arguments = ['-r', f'__node:={node["name"]}']
            if node['namespace']:
                arguments += ['-r', f'__ns:=/{node["namespace"].strip("/")}']
            for parameters in node['parameters']:
                if isinstance(parameters, str):
                    arguments += ['--params-file', parameters]
                else:
                    arguments += parameter_arguments(**parameters)
            label = f'{node["namespace"] or ""}{node["name"]}'.strip('/').replace('/', '_')
            group.start(label, node['executable'], arguments)
            labels.append(label)
        assert group.wait('sim_bridge', EPISODE_TIMEOUT) == 0, group.log('sim_bridge')
        for label in labels:
            assert label == 'sim_bridge' or group.poll(label) is None, group.log(label)
        phases = [line for line in group.log('ds_motion_generator').splitlines()
                  if PHASE_LOG_PREFIX in line]
    assert any('contact' in line for line in phases), phases
    assert any('manipulate' in line for line in phases), phases
    events = phase_log_events(group.log('ds_motion_generator'))
    assert len(events) == len(phases), 'every phase line of the real log parses'
    assert any('grasp_settled' in names for _, names, _ in events), events


def test_a_phase_log_line_reads_back_as_it_was_written():
    """The launcher takes a refused start's reason from the motion generator's log lines."""
    reason = ('place [0.66, 0.0, 0.35] m out of reach: with any grasp on the faces a wrist lies '
              'at least 12 mm beyond its straight-arm reach there')
    lines = [phase_log_line(0.3, 'standby', ('episode_started',), 'start_episode command'),
             phase_log_line(0.305, 'standby', ('unreachable',), reason),
             phase_log_line(1.5, 'reach', (), 'back: [not an event]'),
             phase_log_line(2.0, 'contact', ('contact_left', 'contact_right'), 'both pads')]
    logged = [f'[INFO] [12.{k}] [ds_motion_generator]: {line}' for k, line in enumerate(lines)]
    text = '\n'.join(logged) + '\nan unrelated line\n'
    assert phase_log_events(text) == [
        (0.3, ('episode_started',), 'start_episode command'), (0.305, ('unreachable',), reason),
        (1.5, (), 'back: [not an event]'),
        (2.0, ('contact_left', 'contact_right'), 'both pads')]
