"""
A lockstep object tracker answers every mocap sample, also one it refuses (a stray sample).

Found by the fault campaign (dual_arm_faults, malformed_burst): a mocap sample with a newer
stamp than the bridge's made the tracker refuse the bridge's own sample as old and leave it
unanswered, and the lockstep bridge waited for that answer forever.
"""

from dual_arm_control.contract import MOCAP_OBJECT_POSE, OBJECT_STATE
from dual_arm_control.nodes.messages import stamp_ns, time_msg
from geometry_msgs.msg import PoseStamped
from graph_helpers import GraphProbe, parameter_arguments, ProcessGroup
import pytest


@pytest.mark.slow
def test_a_lockstep_tracker_answers_a_sample_older_than_a_stray_one(tmp_path, ros_domain):
    """
    A stray mocap sample stamped after the bridge's must not stall the lockstep graph.

    The bridge waits for an /object/state with the stamp of each sample it sent. The tracker
    refuses a sample older than the previous one (counted), but still answers it.
    """
    answers = []
    probe = GraphProbe(ros_domain, 'stray_sample')
    probe.node.create_subscription(OBJECT_STATE.msg_type, OBJECT_STATE.name,
                                   lambda msg: answers.append(stamp_ns(msg.header.stamp)),
                                   OBJECT_STATE.qos)
    publisher = probe.node.create_publisher(MOCAP_OBJECT_POSE.msg_type, MOCAP_OBJECT_POSE.name,
                                            MOCAP_OBJECT_POSE.publisher_qos)
    try:
        with ProcessGroup(tmp_path, ros_domain) as graph:
            graph.start('object_tracker', 'object_tracker',
                        parameter_arguments(lockstep=True, use_sim_time=True))
            assert probe.spin_until(lambda: publisher.get_subscription_count() > 0 and
                                    probe.node.count_publishers(OBJECT_STATE.name) > 0, 30.0)
            probe.spin_until(lambda: False, 1.0)
            for stamp in (10_000_000, 5_000_000):
                sample = PoseStamped()
                sample.header.stamp = time_msg(stamp)
                sample.header.frame_id = 'world'
                sample.pose.position.x, sample.pose.position.z = 0.41, 0.32
                sample.pose.orientation.w = 1.0
                publisher.publish(sample)
            answered = probe.spin_until(lambda: 5_000_000 in answers, 10.0)
            log = graph.log('object_tracker')
    finally:
        probe.close()
    assert answered, (answers, log)
    assert answers[0] == 10_000_000
    assert 'refused old_stamp' in log
