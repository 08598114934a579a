"""
The node tables: which executables form a graph, under which names and namespaces.

The launcher (`dual_arm_bringup`) and the ROS launch file (launch/dual_arm.launch.py) are both
built from these tables; run_parameters() maps one run's choices (scenario, mode, output) onto
node parameters, the same way for both.
"""

from dataclasses import dataclass, field

from dual_arm_control.contract import ARMS
from dual_arm_control.scenario import load_scenario


@dataclass(frozen=True)
class NodeSpec:
    """
    One process of the graph: executable, node name, namespace, parameters, param files.

    realtime_priority: the SCHED_FIFO priority of the process in realtime mode (0: normal). The
    robot side (bridge) and the torque controllers, whose answers have a 2 ms deadline, come
    first; the 200 Hz roles next.
    """

    executable: str
    name: str
    namespace: str = ''
    parameters: dict = field(default_factory=dict)
    param_files: tuple = ()
    realtime_priority: int = 0

    @property
    def full_name(self):
        """Return the node's fully qualified name, e.g. /left/passive_controller."""
        return f'{self.namespace.rstrip("/")}/{self.name}'

    @property
    def label(self):
        """Return a unique, file-name-safe label, used for log files."""
        return f'{self.namespace.strip("/")}_{self.name}' if self.namespace else self.name


# SCHED_FIFO priorities in realtime mode: the FRI side, the 500 Hz controllers, the 200 Hz roles.
ROBOT_PRIORITY, CONTROLLER_PRIORITY, PLANNER_PRIORITY = 40, 35, 20


def full_graph():
    """
    Return the product graph: bridge, tracker, DS, wrench QP and one controller per arm.

    The control nodes stamp every output with the stamp of the cycle it answers and never read
    their node clock, so they run without use_sim_time: its time source would take /clock at
    the FRI rate in each of them for nothing (about 7 % of the graph's CPU in lockstep).
    """
    nodes = [
        NodeSpec('sim_bridge', 'sim_bridge', param_files=('sim_bridge.yaml',),
                 parameters={'lockstep_wait_for_tracker': True},
                 realtime_priority=ROBOT_PRIORITY),
        NodeSpec('object_tracker', 'object_tracker', param_files=('object_tracker.yaml',),
                 realtime_priority=PLANNER_PRIORITY),
        NodeSpec('ds_motion_generator', 'ds_motion_generator', realtime_priority=PLANNER_PRIORITY),
        NodeSpec('wrench_qp', 'wrench_qp', param_files=('wrench_qp.yaml',),
                 realtime_priority=PLANNER_PRIORITY),
    ]
    for arm in ARMS:
        nodes.append(NodeSpec('passive_controller', 'passive_controller', f'/{arm}',
                              {'arm': arm}, ('passive_controller.yaml',),
                              realtime_priority=CONTROLLER_PRIORITY))
    return tuple(nodes) + (cell_state_publisher(),)


def cell_state_publisher():
    """Return the node publishing /robot_description and TF (viewers; no cycle waits for it)."""
    return NodeSpec('cell_state_publisher', 'cell_state_publisher',
                    parameters={'use_sim_time': True})


def hold_graph():
    """Return the twin with one gravity-compensation test controller per arm."""
    nodes = [NodeSpec('sim_bridge', 'sim_bridge', param_files=('sim_bridge.yaml',),
                      realtime_priority=ROBOT_PRIORITY)]
    for arm in ARMS:
        nodes.append(NodeSpec('gravity_comp_controller', 'controller', f'/{arm}',
                              {'arm': arm, 'mode': 'gravity'},
                              realtime_priority=CONTROLLER_PRIORITY))
    return tuple(nodes) + (cell_state_publisher(),)


GRAPHS = {'full': full_graph, 'hold': hold_graph}
# The node name of bag_record, which the bridge awaits in a recorded lockstep run.
RECORDER_NODE = '/bag_record'

# Sim time at which an episode starts by itself: after the FT sensors' tare window.
EPISODE_START_TIME = 0.3
# Bridge duration [s] of a graph run without a scenario: until stopped.
RUN_FOREVER = 1.0e6


def run_parameters(graph, scenario=None, mode='lockstep', trajectory_log=None, record=False):
    """Return {node name: {parameter: value}} for one run of a graph."""
    parameters = {'sim_bridge': {'mode': mode}}
    awaited = [spec.full_name for spec in GRAPHS[graph]() if spec.name != 'sim_bridge']
    if record:
        parameters['sim_bridge']['wait_for_subscribers'] = True
        parameters['sim_bridge']['wait_for_recorder'] = True
        awaited.append(RECORDER_NODE)
    parameters['sim_bridge']['wait_for_nodes'] = awaited
    if scenario is not None:
        parameters['sim_bridge']['scenario'] = str(scenario)
    else:
        parameters['sim_bridge']['duration'] = RUN_FOREVER
    if trajectory_log is not None:
        parameters['sim_bridge']['trajectory_log'] = str(trajectory_log)
    if scenario is not None:
        parameters['cell_state_publisher'] = {'scenario': str(scenario)}
    if graph == 'full':
        if scenario is not None:
            parameters['ds_motion_generator'] = {'scenario': str(scenario),
                                                 'auto_start_time': EPISODE_START_TIME}
            parameters['wrench_qp'] = {'scenario': str(scenario)}
        for name in ('object_tracker', 'ds_motion_generator', 'wrench_qp'):
            parameters.setdefault(name, {})['lockstep'] = mode == 'lockstep'
        if scenario is not None and load_scenario(scenario).conveyor is not None:
            parameters['object_tracker']['track_container'] = True
        parameters['passive_controller'] = {'lockstep': mode == 'lockstep'}
        if mode != 'lockstep':
            parameters['sim_bridge']['lockstep_wait_for_tracker'] = False
    return parameters
