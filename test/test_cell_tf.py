"""
/robot_description and TF from cell_state_publisher, seen by a plain rclpy process over DDS.

The bridge (lockstep), the gravity-compensation controllers, the object tracker and the cell
state publisher run as real processes; the test process subscribes to /robot_description and
/tf_static only after the publisher sent them (late joining), and compares the tool (pad) frames
of TF with the twin's tool poses on /<arm>/ground_truth/tool at the same stamps.
"""

import xml.etree.ElementTree as ElementTree

from dual_arm_control import contract
from dual_arm_control.core.geometry import quat_xyzw_to_matrix
from dual_arm_control.nodes.cell_state_publisher import CellStatePublisher
from dual_arm_control.nodes.messages import quaternion, stamp_ns, vector3
from graph_helpers import GraphProbe, parameter_arguments, ProcessGroup
from nav_msgs.msg import Odometry
import numpy as np

SCENARIO = 'paper_toss'
DURATION = 1.0
TIMEOUT = 60.0
PAD_TOLERANCE = 1e-3            # [m]
ROTATION_TOLERANCE = 1e-3       # [rad]
PROBE = 'tf_probe'
TARGETS = ('release_target', 'landing_target')


def transform_matrix(transform):
    """Return the 4x4 matrix of a geometry_msgs/Transform."""
    matrix = np.eye(4)
    matrix[:3, :3] = quat_xyzw_to_matrix(quaternion(transform.rotation))
    matrix[:3, 3] = vector3(transform.translation)
    return matrix


def pose_in_world(frame, parents, static, dynamic, stamp):
    """Return the world pose (4x4) of frame at stamp, composing TF up to 'world'."""
    pose = np.eye(4)
    while frame != contract.WORLD_FRAME:
        transform = static.get(frame) or dynamic[(frame, stamp)]
        pose = transform_matrix(transform) @ pose
        frame = parents[frame]
    return pose


def test_the_node_is_destroyed_without_an_error(ros_domain):
    """It used to overwrite rclpy's Node._subscriptions: destroy_node raised at every exit."""
    probe = GraphProbe(ros_domain, PROBE)
    try:
        node = CellStatePublisher(context=probe.context)
        node.destroy_node()
    finally:
        probe.close()


def test_late_subscriber_gets_description_and_tf_matching_the_twin(tmp_path, ros_domain):
    probe = GraphProbe(ros_domain, PROBE)
    received = {'tf': [], 'description': [], 'static': [], 'truth': {}}
    node = probe.node
    node.create_subscription(contract.TF.msg_type, contract.TF.name, received['tf'].append,
                             contract.TF.qos)
    for arm in contract.ARMS:
        node.create_subscription(
            Odometry, contract.GROUND_TRUTH_TOOL.resolved(arm),
            lambda msg: received['truth'].__setitem__(
                (msg.child_frame_id, stamp_ns(msg.header.stamp)), msg),
            contract.GROUND_TRUTH_TOOL.qos)
    try:
        with ProcessGroup(tmp_path, ros_domain) as group:
            group.start('cell_state_publisher', 'cell_state_publisher', parameter_arguments(
                use_sim_time=True, scenario=SCENARIO))
            group.start('object_tracker', 'object_tracker', parameter_arguments(
                use_sim_time=True))
            for arm in contract.ARMS:
                group.start_controller(arm)
            # /tf is volatile: the publisher must know the probe before the 1 s episode runs.
            assert probe.spin_until(lambda: node.count_publishers(contract.TF.name), TIMEOUT), \
                group.log('cell_state_publisher')
            group.start_bridge(scenario=SCENARIO, duration=DURATION, ground_truth_period=0.0,
                               wait_for_nodes=['/cell_state_publisher', '/object_tracker',
                                               f'/{PROBE}'])
            assert probe.spin_until(lambda: received['tf'], TIMEOUT), \
                group.log('cell_state_publisher') + group.log('sim_bridge')
            node.create_subscription(contract.ROBOT_DESCRIPTION.msg_type,
                                     contract.ROBOT_DESCRIPTION.name,
                                     received['description'].append,
                                     contract.ROBOT_DESCRIPTION.qos)
            node.create_subscription(contract.TF_STATIC.msg_type, contract.TF_STATIC.name,
                                     received['static'].append, contract.TF_STATIC.qos)
            assert probe.spin_until(
                lambda: group.poll('sim_bridge') is not None and received['description']
                and received['static'], TIMEOUT), group.log('sim_bridge')
            assert group.poll('sim_bridge') == 0, group.log('sim_bridge')
            probe.spin_until(lambda: False, 0.5)
    finally:
        probe.close()

    assert len(received['description']) == 1
    robot = ElementTree.fromstring(received['description'][0].data)
    links = {link.get('name') for link in robot.iter('link')}
    revolute = [joint.get('name') for joint in robot.iter('joint')
                if joint.get('type') == 'revolute']
    assert revolute == [name for arm in contract.ARMS for name in contract.joint_names(arm)]

    static = {t.child_frame_id: t.transform for msg in received['static']
              for t in msg.transforms}
    dynamic = {(t.child_frame_id, stamp_ns(t.header.stamp)): t.transform
               for msg in received['tf'] for t in msg.transforms}
    parents = {t.child_frame_id: t.header.frame_id
               for msg in received['static'] + received['tf'] for t in msg.transforms}
    frames = set(parents) | {contract.WORLD_FRAME}
    assert links <= frames, links - frames
    assert {'object', *TARGETS} <= frames
    for frame in frames:
        chain = [frame]
        while chain[-1] != contract.WORLD_FRAME:
            assert chain[-1] in parents, f'{frame}: {chain} does not reach world'
            chain.append(parents[chain[-1]])
            assert len(chain) < 30, chain

    compared = dict.fromkeys(contract.ARMS, 0)
    for arm in contract.ARMS:
        tool = f'{arm}_tool'
        arm_stamps = {stamp for child, stamp in dynamic if child == f'{arm}_link_1'}
        for stamp in sorted(arm_stamps):
            if (tool, stamp) not in received['truth'] or \
                    (f'{arm}_link_7', stamp) not in dynamic:
                continue
            pose = pose_in_world(tool, parents, static, dynamic, stamp)
            truth = received['truth'][(tool, stamp)].pose.pose
            assert np.linalg.norm(pose[:3, 3] - vector3(truth.position)) < PAD_TOLERANCE
            R_error = pose[:3, :3].T @ quat_xyzw_to_matrix(quaternion(truth.orientation))
            assert np.arccos(np.clip((np.trace(R_error) - 1) / 2, -1, 1)) < ROTATION_TOLERANCE
            compared[arm] += 1
    # 1 s of sim time at 50 Hz: about 50 TF stamps per arm (measured 50-51); a few may go
    # before the probe's subscriptions to ground truth match.
    assert min(compared.values()) >= 40, compared
