"""
The graph's interface, defined once: arms, joint names, topics, message types and QoS.

Every node, the launcher, the bag tools and the tests take names and types from here. Per-arm
topics are relative names resolved under the arm namespace (``/left``, ``/right``).
"""

from dataclasses import dataclass

from diagnostic_msgs.msg import DiagnosticArray
from dual_arm_control.core.arms import ARMS, joint_names, JOINTS_PER_ARM  # noqa: F401
from geometry_msgs.msg import PoseStamped, TwistStamped, WrenchStamped
from nav_msgs.msg import Odometry
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy)
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool
from visualization_msgs.msg import MarkerArray

WORLD_FRAME = 'world'

# Messages a reliable publisher keeps for a subscriber that falls behind (a recorder under load):
# 100 FRI cycles of one topic.
HISTORY_DEPTH = 100
# Publishers keep this many of their latest messages for a reliable subscriber that falls
# behind (a recorder under load): 2 s of FRI cycles of one topic.
PUBLISHER_HISTORY_DEPTH = 1000
# Control-loop traffic: every message matters in lockstep. Reliable, keep-last HISTORY_DEPTH.
CONTROL_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=HISTORY_DEPTH, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE)
# Sensor-like streams that a late subscriber may join (mocap, ground truth, markers).
SENSOR_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=HISTORY_DEPTH, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE)
# The phase is a state: a late subscriber gets the latest ones; every tick's is delivered.
LATCHED_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=HISTORY_DEPTH, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL)


@dataclass(frozen=True)
class Topic:
    """A topic of the graph: name (relative names live under an arm namespace), type, QoS."""

    name: str
    msg_type: type
    qos: QoSProfile
    per_arm: bool = False

    @property
    def publisher_qos(self):
        """Return the QoS publishers offer: the topic's, with PUBLISHER_HISTORY_DEPTH."""
        return QoSProfile(history=self.qos.history,
                          depth=max(self.qos.depth, PUBLISHER_HISTORY_DEPTH),
                          reliability=self.qos.reliability, durability=self.qos.durability)

    def resolved(self, arm=None):
        """Return the absolute topic name, for the given arm if the topic is per arm."""
        if self.per_arm:
            if arm not in ARMS:
                raise ValueError(f'topic {self.name} is per arm; give one of {ARMS}')
            return f'/{arm}/{self.name}'
        return self.name


CLOCK = Topic('/clock', Clock, CONTROL_QOS)
JOINT_STATES = Topic('joint_states', JointState, CONTROL_QOS, per_arm=True)
TORQUE_COMMAND = Topic('torque_command', JointState, CONTROL_QOS, per_arm=True)
FT_WRENCH = Topic('ft_wrench', WrenchStamped, CONTROL_QOS, per_arm=True)
MOCAP_OBJECT_POSE = Topic('/mocap/object_pose', PoseStamped, SENSOR_QOS)
# The tracker answers every mocap sample (stamp = the sample's) and every /clock cycle (stamp =
# the cycle's; before a track exists the pose covariance[0] is NO_ESTIMATE_COVARIANCE).
OBJECT_STATE = Topic('/object/state', Odometry, CONTROL_QOS)
NO_ESTIMATE_COVARIANCE = -1.0
DS_COMMAND = Topic('ds_command', Odometry, CONTROL_QOS, per_arm=True)
CONTACT_WRENCH = Topic('contact_wrench', WrenchStamped, CONTROL_QOS, per_arm=True)
OBJECT_DESIRED_TWIST = Topic('/object/desired_twist', TwistStamped, CONTROL_QOS)
# One stamped status per DS tick: message = phase, values = task, time in phase, events, reason.
PHASE = Topic('/dual_arm/phase', DiagnosticArray, LATCHED_QOS)
PHASE_STATUS_NAME = 'dual_arm/phase'
MARKERS = Topic('/dual_arm/markers', MarkerArray, SENSOR_QOS)
GROUND_TRUTH_OBJECT = Topic('/ground_truth/object', Odometry, SENSOR_QOS)
GROUND_TRUTH_PAD_WRENCH = Topic('ground_truth/pad_wrench', WrenchStamped, SENSOR_QOS,
                                per_arm=True)
GROUND_TRUTH_PAD_CONTACT = Topic('ground_truth/pad_contact', Bool, SENSOR_QOS, per_arm=True)
# Tool-centre pose and twist in the world frame, from the simulator (evaluation only).
GROUND_TRUTH_TOOL = Topic('ground_truth/tool', Odometry, SENSOR_QOS, per_arm=True)
DIAGNOSTICS = Topic('/diagnostics', DiagnosticArray, SENSOR_QOS)
# bag_record's matched publishers per recorded topic (one status, values topic -> count): a
# recorded lockstep run starts once the recorder has matched every publisher the bridge sees.
RECORDER_STATUS = Topic('/bag_record/matched', DiagnosticArray, QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL))

ALL_TOPICS = (
    CLOCK, JOINT_STATES, TORQUE_COMMAND, FT_WRENCH, MOCAP_OBJECT_POSE, OBJECT_STATE, DS_COMMAND,
    CONTACT_WRENCH, OBJECT_DESIRED_TWIST, PHASE, MARKERS, GROUND_TRUTH_OBJECT,
    GROUND_TRUTH_PAD_WRENCH, GROUND_TRUTH_PAD_CONTACT, GROUND_TRUTH_TOOL, DIAGNOSTICS,
    RECORDER_STATUS,
)

# Services of the bridge (std_srvs/Trigger) and their names.
SIM_RESET_SERVICE = '/sim/reset'
SIM_MOVE_OBJECT_SERVICE = '/sim/move_object'
# Services of the motion generator (std_srvs/Trigger).
START_EPISODE_SERVICE = '/dual_arm/start_episode'
GO_HOME_SERVICE = '/dual_arm/go_home'
RESET_EPISODE_SERVICE = '/dual_arm/reset'
