"""
dual_arm_param: value parsing and params-file formatting, then the real CLI on a running node.

The process tests run the console script against one ds_motion_generator (paper_toss scenario)
in its own ROS domain: list, get, set (int given for a double, an out-of-range refusal with the
node's reason), an unknown node, dump restored by a fresh node's --params-file, load, and a set
recorded by bag_record on /parameter_events.
"""

import math
from pathlib import Path
import random
import signal
import subprocess
import sys
import time

from dual_arm_control import contract
from dual_arm_control.core.exceptions import InputError
from dual_arm_control.nodes.recorder_status import recorder_has_matched, recorder_matched_counts
from dual_arm_control.tools.param import main
from dual_arm_control.tools.param_events import parameter_changes
from dual_arm_control.tools.param_values import (coerce_value, describe_value, dump_text,
                                                 flat_parameters, nested_parameters,
                                                 parameter_message, parameters_for_node,
                                                 parse_value, read_params_file)
from graph_helpers import GraphProbe, ProcessGroup, ros_environment
import pytest
from rcl_interfaces.msg import ParameterEvent, ParameterType, ParameterValue
from rosbags.highlevel import AnyReader
import yaml

SCRIPTS = Path(sys.prefix) / 'bin'
SCENARIO = Path(__file__).resolve().parents[1] / 'config' / 'scenarios' / 'paper_toss.yaml'
NODE = '/ds_motion_generator'
STARTUP_TIMEOUT = 20.0
CLI_TIMEOUT = 30.0
SERVICE_TIMEOUT = '10'


# -- values and files (no ROS graph) ----------------------------------------------------------

@pytest.mark.parametrize('text, expected', [
    ('true', True), ('False', False), ('1', 1), ('-3', -3), ('1.0', 1.0), ('0.5', 0.5),
    ('[1.0, 2.0]', [1.0, 2.0]), ('[1, 2.5]', [1.0, 2.5]), ('[1, 2]', [1, 2]),
    ('[true, false]', [True, False]), ('[a, b]', ['a', 'b']), ('pick_and_toss', 'pick_and_toss'),
    ("'1.0'", '1.0'), ('[1, a]', '[1, a]'), ('{a: 1}', '{a: 1}'), ('null', 'null'), ('', ''),
    ('[1', '[1'),
])
def test_values_are_read_as_yaml_like_ros2_param(text, expected):
    value = parse_value(text)
    assert value == expected
    assert type(value) is type(expected)
    if isinstance(value, list):
        assert [type(v) for v in value] == [type(v) for v in expected]


def test_values_are_converted_to_the_declared_type_only_without_loss():
    assert type(coerce_value(1, ParameterType.PARAMETER_DOUBLE)) is float
    assert coerce_value('1e-5', ParameterType.PARAMETER_DOUBLE) == 1e-5
    assert coerce_value([1, 2.5], ParameterType.PARAMETER_DOUBLE_ARRAY) == [1.0, 2.5]
    assert [type(v) for v in coerce_value([1, 2], ParameterType.PARAMETER_DOUBLE_ARRAY)] == [
        float, float]
    assert coerce_value(1, ParameterType.PARAMETER_STRING, '01') == '01'
    assert coerce_value(True, ParameterType.PARAMETER_DOUBLE) is True
    assert coerce_value(1.5, ParameterType.PARAMETER_INTEGER) == 1.5
    assert coerce_value('fast', ParameterType.PARAMETER_DOUBLE) == 'fast'
    assert coerce_value(2, None) == 2


def test_parameter_messages_carry_the_ros_type():
    assert parameter_message('a', 1).value.type == ParameterType.PARAMETER_INTEGER
    assert parameter_message('a', 1.0).value.double_value == 1.0
    empty = parameter_message('a', [], ParameterType.PARAMETER_DOUBLE_ARRAY)
    assert empty.value.type == ParameterType.PARAMETER_DOUBLE_ARRAY
    with pytest.raises(InputError, match='a: .* is not a ROS parameter value'):
        parameter_message('a', [1, 'x'])


def test_values_print_like_ros2_param_get():
    value = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=0.5)
    assert describe_value(value) == 'Double value is: 0.5'
    value = ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=True)
    assert describe_value(value) == 'Boolean value is: True'
    value = ParameterValue(type=ParameterType.PARAMETER_DOUBLE_ARRAY, double_array_value=[1.0])
    assert describe_value(value) == 'Double values are: [1.0]'
    assert describe_value(ParameterValue()) == 'Parameter not set.'


def test_dotted_names_dump_as_nested_mappings_and_read_back_exactly():
    values = {
        'impact.region.normal_distance': 0.02, 'impact.region.radial_slope': 200.0,
        'impact.impact_speed': 1.0, 'impact.synchronise': True, 'task': 'pick_and_toss',
        'number_text': '1.0', 'count': 3, 'tiny': 1e-300, 'unbounded': math.inf,
        'lift.position': [0.45, 0.0, 0.45], 'names': ['a', 'b'],
        'gain': 2.0, 'gain.scale': 0.5,
    }
    text = dump_text(NODE, values)
    document = yaml.safe_load(text)
    tree = document[NODE]['ros__parameters']
    assert tree['impact']['region'] == {'normal_distance': 0.02, 'radial_slope': 200.0}
    assert tree['gain'] == 2.0 and tree['gain.scale'] == 0.5
    assert 'lift:\n      position: [0.45, 0.0, 0.45]\n' in text
    assert nested_parameters(flat_parameters(tree)) == tree
    round_trip = flat_parameters(tree)
    assert round_trip == values
    assert {name: type(value) for name, value in round_trip.items()} == {
        name: type(value) for name, value in values.items()}


def test_params_files_apply_wildcards_first_then_the_node_key():
    document = {
        '/**': {'ros__parameters': {'use_sim_time': True, 'gain': 1.0}},
        'left': {'passive_controller': {'ros__parameters': {'gain': 3.0, 'a': {'b': 1}}}},
        '/left/*': {'ros__parameters': {'gain': 2.0, 'lockstep': False}},
        '/**/passive_controller': {'ros__parameters': {'fri_period': 0.002}},
        '/right/passive_controller': {'ros__parameters': {'gain': 9.0}},
    }
    assert parameters_for_node(document, '/left/passive_controller') == {
        'use_sim_time': True, 'gain': 3.0, 'a.b': 1, 'lockstep': False, 'fri_period': 0.002}
    assert parameters_for_node(document, 'ds_motion_generator') == {
        'use_sim_time': True, 'gain': 1.0}
    with pytest.raises(InputError, match='/x: expected a mapping'):
        parameters_for_node({'x': 3}, NODE)


def test_bad_params_files_are_user_errors_naming_the_file(tmp_path, capsys):
    broken = tmp_path / 'broken.yaml'
    broken.write_text(f'{NODE}:\n  ros__parameters: [1\n')
    with pytest.raises(InputError, match=r'broken.yaml: not valid YAML: line 3, column 1'):
        read_params_file(broken, NODE)
    other = tmp_path / 'other.yaml'
    other.write_text('/wrench_qp:\n  ros__parameters: {a: 1.0}\n')
    with pytest.raises(InputError, match=r'other.yaml: no parameters for /ds_motion_generator '
                                         r'\(node keys: /wrench_qp\)'):
        read_params_file(other, 'ds_motion_generator')
    assert main(['load', NODE, str(broken)]) == 2
    error = capsys.readouterr().err
    assert error.count('\n') == 1 and 'broken.yaml' in error
    assert main(['load', NODE, str(tmp_path / 'missing.yaml')]) == 2
    assert 'missing.yaml: cannot read' in capsys.readouterr().err


# -- the console script on a running node -----------------------------------------------------

def other_domain(domain_id):
    """Return a ROS domain id different from domain_id."""
    return domain_id % 200 + 1


def start_motion_generator(group, label, *ros_arguments):
    """Start ds_motion_generator (paper_toss); return once it logged that it is up."""
    group.start(label, 'ds_motion_generator', ['-p', f'scenario:={SCENARIO}', *ros_arguments])
    deadline = time.monotonic() + STARTUP_TIMEOUT
    while 'ds_motion_generator up' not in group.log(label):
        assert group.poll(label) is None and time.monotonic() < deadline, group.log(label)
        time.sleep(0.1)


def param(domain_id, *arguments, timeout=SERVICE_TIMEOUT):
    """Run dual_arm_param in a domain; return (exit code, stdout, stderr)."""
    result = subprocess.run(
        [str(SCRIPTS / 'dual_arm_param'), *arguments, '--timeout', timeout],
        capture_output=True, text=True, timeout=CLI_TIMEOUT, env=ros_environment(domain_id))
    return result.returncode, result.stdout, result.stderr


@pytest.fixture(scope='module')
def motion_node(tmp_path_factory):
    """Run one ds_motion_generator in its own domain for the module; yield (domain, group)."""
    log_dir = tmp_path_factory.mktemp('param_tool')
    domain_id = random.SystemRandom().randint(1, 200)
    with ProcessGroup(log_dir, domain_id) as group:
        start_motion_generator(group, 'motion')
        yield domain_id, group


def test_list_get_and_set_through_the_parameter_services(motion_node):
    domain_id, _ = motion_node
    code, out, err = param(domain_id, 'list', NODE)
    names = [line.strip() for line in out.splitlines()]
    assert code == 0, err
    assert names == sorted(names)
    assert {'impact.impact_speed', 'impact.region.normal_distance', 'scenario',
            'use_sim_time'} <= set(names)

    assert param(domain_id, 'get', NODE, 'impact.impact_speed')[:2] == (
        0, 'Double value is: 0.5\n')
    assert param(domain_id, 'set', NODE, 'impact.impact_speed', '1')[:2] == (
        0, 'Set parameter successful\n')
    assert param(domain_id, 'get', NODE, 'impact.impact_speed')[1] == 'Double value is: 1.0\n'

    code, out, _ = param(domain_id, 'set', NODE, 'impact.impact_speed', '100.0')
    assert code == 1
    assert out.startswith('Setting parameter failed: ')
    assert 'impact.impact_speed out of range' in out and 'Max: 2.0' in out
    assert param(domain_id, 'get', NODE, 'impact.impact_speed')[1] == 'Double value is: 1.0\n'

    code, out, _ = param(domain_id, 'set', NODE, 'speed.near_distance', '0.6')
    assert (code, out) == (
        1, 'Setting parameter failed: far_distance = 0.5 m is outside (0.6, 5] m\n')

    code, out, err = param(domain_id, 'get', NODE, 'no_such_parameter')
    assert (code, out) == (1, '')
    assert err == f'Parameter no_such_parameter is not declared on {NODE}\n'


def test_unknown_node_is_one_line_and_exit_2(motion_node):
    domain_id, _ = motion_node
    code, out, err = param(domain_id, 'set', '/no_such_node', 'a', '1', timeout='1')
    assert (code, out) == (2, '')
    assert err.count('\n') == 1 and 'node /no_such_node not found' in err, err


def test_list_of_the_graph_and_descriptions(motion_node):
    domain_id, _ = motion_node
    code, out, err = param(domain_id, 'list', '--describe')
    assert code == 0, err
    assert f'{NODE}:\n' in out
    assert '  impact.impact_speed: double, range [0, 2]\n' in out
    assert '  scenario: string, read-only\n' in out


def test_dump_is_restored_by_a_fresh_node_from_its_params_file(motion_node, tmp_path):
    domain_id, _ = motion_node
    changes = {'coordination.relative_gain': 7.25, 'orientation.convergence_rates':
               [2.0, 2.5, 3.5], 'coordination.coordinated': False}
    values = tmp_path / 'values.yaml'
    values.write_text(dump_text(NODE, changes))
    assert param(domain_id, 'load', NODE, str(values))[0] == 0
    dump = tmp_path / 'dump.yaml'
    code, out, err = param(domain_id, 'dump', NODE, '--output', str(dump))
    assert code == 0, err
    dumped = flat_parameters(yaml.safe_load(dump.read_text())[NODE]['ros__parameters'])
    listed = param(domain_id, 'list', NODE)[1].split()
    assert sorted(dumped) == listed
    assert {name: dumped[name] for name in changes} == changes

    fresh_domain = other_domain(domain_id)
    with ProcessGroup(tmp_path, fresh_domain) as group:
        start_motion_generator(group, 'restored', '--params-file', str(dump))
        again = tmp_path / 'again.yaml'
        code, _, err = param(fresh_domain, 'dump', NODE, '-o', str(again))
        assert code == 0, err + group.log('restored')
    assert again.read_text() == dump.read_text()


def test_load_sets_the_file_values_and_reports_the_bad_ones(motion_node, tmp_path):
    domain_id, _ = motion_node
    values = tmp_path / 'values.yaml'
    values.write_text(
        '/**:\n  ros__parameters:\n    standby_gain: 2\n'
        f'{NODE}:\n  ros__parameters:\n'
        '    phases: {place_speed: 0.2}\n    scenario: other.yaml\n'
        '    no_such_parameter: 1.0\n    speed: {reach_speed: 7.0}\n')
    code, out, err = param(domain_id, 'load', NODE, str(values))
    assert code == 1, err
    assert out.splitlines() == [
        'Skipped read-only parameter scenario (set at start-up only)',
        f'Setting parameter no_such_parameter failed: not declared on {NODE}',
        'Set parameter phases.place_speed successful',
        'Setting parameter speed.reach_speed failed: Parameter speed.reach_speed out of range '
        'Min: 0.0, Max: 2.0, value: 7.0',
        'Set parameter standby_gain successful']
    code, out, err = param(domain_id, 'dump', NODE)
    assert code == 0, err
    dumped = flat_parameters(yaml.safe_load(out)[NODE]['ros__parameters'])
    assert (dumped['standby_gain'], dumped['phases.place_speed']) == (2.0, 0.2)
    assert (dumped['scenario'], dumped['speed.reach_speed']) == (str(SCENARIO), 0.85)


def wait_until_recorder_matched(domain_id, topic, recorder):
    """
    Wait until bag_record matched every publisher of topic that a probe sees, the node's included.

    Discovery is asynchronous: an event published before the recorder matched its publisher is
    not delivered (volatile), so the set must wait for the match, as a recorded bridge does.
    """
    probe = GraphProbe(domain_id, name='param_recorder_probe')
    matched = [None]

    def on_status(msg):
        matched[0] = recorder_matched_counts(msg)

    probe.node.create_subscription(contract.RECORDER_STATUS.msg_type,
                                   contract.RECORDER_STATUS.name, on_status,
                                   contract.RECORDER_STATUS.qos)

    def ready():
        node_publishes = any(f'/{p.node_name}' == NODE
                             for p in probe.node.get_publishers_info_by_topic(topic))
        return (recorder.poll() is not None
                or (node_publishes and topic in (matched[0] or {})
                    and recorder_has_matched(probe.node, matched[0])))
    try:
        return probe.spin_until(ready, STARTUP_TIMEOUT) and recorder.poll() is None
    finally:
        probe.close()


def test_a_set_is_recorded_on_parameter_events_in_a_bag(motion_node, tmp_path):
    domain_id, _ = motion_node
    bag = tmp_path / 'events.mcap'
    log_path = tmp_path / 'record.log'
    with open(log_path, 'w') as log_file:
        recorder = subprocess.Popen(
            [str(SCRIPTS / 'bag_record'), '-o', str(bag), '/parameter_events'],
            stdout=log_file, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
            env=ros_environment(domain_id))
    try:
        assert wait_until_recorder_matched(domain_id, '/parameter_events', recorder), (
            log_path.read_text())
        assert param(domain_id, 'set', NODE, 'speed.time_constant', '0.08')[0] == 0
    finally:
        recorder.send_signal(signal.SIGINT)
        recorder.wait(timeout=STARTUP_TIMEOUT)
    assert recorder.returncode == 0, log_path.read_text()

    with AnyReader([bag]) as reader:
        events = [reader.deserialize(data, connection.msgtype)
                  for connection, _, data in reader.messages()
                  if connection.topic == '/parameter_events']
    changed = [(event.node, parameter.name, parameter.value.double_value)
               for event in events for parameter in event.changed_parameters]
    assert (NODE, 'speed.time_constant', 0.08) in changed

    found = [change for change in parameter_changes(bag) if change.name == 'speed.time_constant']
    assert [(c.node, c.value, c.kind) for c in found] == [(NODE, 0.08, 'changed')]
    assert found[0].stamp_ns > 0 and found[0].log_time_ns > 0

    replay_domain = random.SystemRandom().randint(1, 200)
    probe = GraphProbe(replay_domain, 'parameter_events_probe')
    replayed = []
    probe.node.create_subscription(
        ParameterEvent, '/parameter_events',
        lambda event: replayed.extend((event.node, p.name, p.value.double_value)
                                      for p in event.changed_parameters), 100)
    try:
        player = subprocess.Popen(
            [str(SCRIPTS / 'bag_play'), str(bag), '--wait-for-subscribers'],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
            env=ros_environment(replay_domain), text=True)
        assert probe.spin_until(lambda: (NODE, 'speed.time_constant', 0.08) in replayed,
                                STARTUP_TIMEOUT), replayed
        assert player.wait(timeout=STARTUP_TIMEOUT) == 0, player.stdout.read()
    finally:
        probe.close()
