"""
Launch the dual_arm_control graph on a ROS 2 Jazzy installation (`ros2 launch`).

Built from the same node table as `dual_arm_bringup` (dual_arm_control.graph), so both start
the same processes with the same names, namespaces and parameters. Arguments: scenario (path),
mode (lockstep | realtime), graph (full | hold), params_file (extra ROS parameter YAML).
"""

from dual_arm_control.graph import GRAPHS, run_parameters
from dual_arm_control.nodes.command_signature import COMMAND_KEY_VARIABLE, launch_key
from dual_arm_control.resources import config_path
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def graph_nodes(context):
    """Return the Node actions of the chosen graph for this launch's arguments."""
    graph = LaunchConfiguration('graph').perform(context)
    scenario = LaunchConfiguration('scenario').perform(context) or None
    mode = LaunchConfiguration('mode').perform(context)
    params_file = LaunchConfiguration('params_file').perform(context)
    per_node = run_parameters(graph, scenario, mode)
    actions = []
    for spec in GRAPHS[graph]():
        parameters = [str(config_path(name)) for name in spec.param_files]
        parameters.append(dict(spec.parameters, **per_node.get(spec.name, {})))
        if params_file:
            parameters.append(params_file)
        actions.append(Node(package='dual_arm_control', executable=spec.executable,
                            name=spec.name, namespace=spec.namespace or None,
                            parameters=parameters, output='screen',
                            additional_env={COMMAND_KEY_VARIABLE: launch_key()}))
    return actions


def generate_launch_description():
    """Return the launch description of the dual-arm graph."""
    return LaunchDescription([
        DeclareLaunchArgument('graph', default_value='full', choices=sorted(GRAPHS)),
        DeclareLaunchArgument('scenario', default_value='',
                              description='scenario YAML (empty: run until stopped)'),
        DeclareLaunchArgument('mode', default_value='lockstep',
                              choices=['lockstep', 'realtime']),
        DeclareLaunchArgument('params_file', default_value='',
                              description='extra ROS parameter YAML for every node'),
        OpaqueFunction(function=graph_nodes),
    ])
