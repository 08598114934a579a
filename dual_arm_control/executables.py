"""
Every executable of the package: name -> 'module:function'.

The one table behind setup.py's console scripts (what `ros2 run dual_arm_control <name>`
finds) and the launcher's node table. Pure Python with no imports so setup.py can read it.
"""

EXECUTABLES = {
    'sim_bridge': 'sim_bridge.bridge_node:main',
    'object_tracker': 'dual_arm_control.nodes.object_tracker:main',
    'ds_motion_generator': 'dual_arm_control.nodes.ds_motion_generator:main',
    'wrench_qp': 'dual_arm_control.nodes.wrench_qp:main',
    'passive_controller': 'dual_arm_control.nodes.passive_controller:main',
    'cell_state_publisher': 'dual_arm_control.nodes.cell_state_publisher:main',
    'gravity_comp_controller': 'sim_bridge.gravity_comp_controller:main',
    'dual_arm_bringup': 'dual_arm_control.bringup:main',
    'bag_record': 'dual_arm_control.nodes.bag_record:main',
    'bag_info': 'dual_arm_control.bags.info:main',
    'bag_play': 'dual_arm_control.nodes.bag_play:main',
    'dual_arm_param': 'dual_arm_control.tools.param:main',
    'dual_arm_render': 'dual_arm_control.tools.render:main',
    'dual_arm_eval': 'dual_arm_control.evaluation.trials:main',
    'dual_arm_experiment': 'dual_arm_control.evaluation.experiments:main',
    'dual_arm_bench': 'dual_arm_control.benchmarks.bench:main',
    'dual_arm_faults': 'dual_arm_control.tools.faults.campaign:main',
}


def console_scripts():
    """Return the setuptools console_scripts entries."""
    return [f'{name} = {target}' for name, target in EXECUTABLES.items()]
