"""
Realtime mode's process layout: which share of the cores each node is pinned to, and how.

The launcher gives each realtime node its SCHED_FIFO priority and its cores through the
environment (graph.realtime_core_sets); the node's process applies both before rclpy starts.
"""

import os

from dual_arm_control.bringup import Launcher
from dual_arm_control.graph import (CONTROL_CORES, full_graph, realtime_core_sets,
                                    ROBOT_CORES)
from dual_arm_control.nodes.process import (REALTIME_CORES_VARIABLE,
                                            REALTIME_PRIORITY_VARIABLE, use_realtime_cores)
import pytest


@pytest.mark.parametrize('available, robot, control', [
    ({0}, None, None),
    ({0, 1}, {0}, {1}),
    ({5, 2, 7}, {2}, {5, 7}),
    ({0, 1, 2, 3}, {0, 1}, {2, 3}),
])
def test_the_cores_are_split_in_two_shares(available, robot, control):
    shares = realtime_core_sets(available)
    assert shares.get(ROBOT_CORES) == robot
    assert shares.get(CONTROL_CORES) == control


def test_realtime_nodes_get_their_priority_and_share_and_lockstep_nodes_neither(tmp_path):
    nodes = {spec.label: spec for spec in full_graph()}
    realtime = Launcher(full_graph(), tmp_path, 0, realtime=True)
    shares = realtime_core_sets(os.sched_getaffinity(0))
    env = {label: realtime.node_environment({}, spec) for label, spec in nodes.items()}

    def cores(label):
        text = env[label][REALTIME_CORES_VARIABLE]
        return {int(core) for core in text.split(',')} if text else None

    assert env['sim_bridge'][REALTIME_PRIORITY_VARIABLE] == '40'
    assert env['left_passive_controller'][REALTIME_PRIORITY_VARIABLE] == '35'
    assert env['cell_state_publisher'][REALTIME_PRIORITY_VARIABLE] == ''
    assert cores('cell_state_publisher') is None, 'the viewers node runs on any core'
    for label in ('sim_bridge', 'ds_motion_generator'):
        assert cores(label) == shares.get(ROBOT_CORES)
    for label in ('left_passive_controller', 'right_passive_controller', 'wrench_qp',
                  'object_tracker'):
        assert cores(label) == shares.get(CONTROL_CORES)
    lockstep = Launcher(full_graph(), tmp_path, 0, realtime=False)
    assert lockstep.node_environment({'A': '1'}, nodes['sim_bridge']) == {'A': '1'}


@pytest.fixture
def restored_affinity():
    """Give the test its process's cores and put them back afterwards."""
    before = os.sched_getaffinity(0)
    yield before
    os.sched_setaffinity(0, before)


def test_a_process_is_pinned_to_its_cores_and_a_bad_list_changes_nothing(restored_affinity):
    core = min(restored_affinity)
    assert use_realtime_cores(str(core)) == f'pinned to cores {core}'
    assert os.sched_getaffinity(0) == {core}
    os.sched_setaffinity(0, restored_affinity)
    assert use_realtime_cores('') == '' and use_realtime_cores(None) == ''
    for bad in ('one', '0,,1', '100000'):
        note = use_realtime_cores(bad)
        assert note.startswith(f'pinning to cores {bad} refused') and 'any core' in note
        assert os.sched_getaffinity(0) == restored_affinity
