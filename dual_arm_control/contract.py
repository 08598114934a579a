"""
The graph's interface, defined once: arms, joint names, topics, message types and QoS.

Every node, the launcher, the bag tools and the tests take names and types from here. Per-arm
topics are relative names resolved under the arm namespace (``/left``, ``/right``).
"""

from dataclasses import dataclass

from diagnostic_msgs.msg import DiagnosticArray
from dual_arm_control.core.arms import ARMS, joint_names, JOINTS_PER_ARM  # noqa: F401
from geometry_msgs.msg import PointStamped, PoseStamped, TwistStamped, WrenchStamped
from nav_msgs.msg import Odometry
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy)
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, String
from tf2_msgs.msg import TFMessage
from trajectory_msgs.msg import MultiDOFJointTrajectory
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
# Sensor data (joint states, FT, mocap), subscribed best effort so that a best-effort driver
# (rclpy's qos_profile_sensor_data) connects; our publishers stay reliable, and in lockstep a
# lost sample is published again by the bridge.
SENSOR_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=HISTORY_DEPTH,
    reliability=ReliabilityPolicy.BEST_EFFORT, durability=DurabilityPolicy.VOLATILE)
# Streams for viewers and evaluation (ground truth, markers, diagnostics).
MONITOR_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=HISTORY_DEPTH, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE)
# The phase is a state: a late subscriber gets the latest ones; every tick's is delivered.
LATCHED_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=HISTORY_DEPTH, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL)
# Depth of a node's sensor subscriptions in lockstep: the bridge runs ahead of a DS or QP tick
# by at most the FRI cycles of one DS period (3), so 10 samples never overflow.
SENSOR_SUBSCRIPTION_DEPTH = 10
# Depth of command subscriptions (DS command, contact wrench): only the newest
# counts, and in lockstep the next one is not sent before the current one was answered.
COMMAND_SUBSCRIPTION_DEPTH = 1
# Depth of the torque command subscriptions in lockstep (bridge, motion generator): a burst from
# another publisher on the topic must not push the controller's command out before it is taken.
TORQUE_COMMAND_SUBSCRIPTION_DEPTH = HISTORY_DEPTH


@dataclass(frozen=True)
class Topic:
    """
    A topic of the graph: name (relative names live under an arm namespace), type, QoS.

    lockstep_depth: the depth a node subscribes with in lockstep (None: the QoS's).
    """

    name: str
    msg_type: type
    qos: QoSProfile
    per_arm: bool = False
    lockstep_depth: int = None

    @property
    def publisher_qos(self):
        """Return the QoS our publishers offer: reliable, PUBLISHER_HISTORY_DEPTH deep."""
        return QoSProfile(history=self.qos.history,
                          depth=max(self.qos.depth, PUBLISHER_HISTORY_DEPTH),
                          reliability=ReliabilityPolicy.RELIABLE, durability=self.qos.durability)

    def subscription_qos(self, lockstep):
        """
        Return the QoS a node subscribes with in lockstep or in realtime.

        In lockstep (every stamp matters) the topic's reliability and durability, and the depth
        lockstep_depth, or the QoS's. In realtime only the newest message matters (take-latest):
        depth 1, so a node that fell behind answers the present, not a backlog; and best effort
        for a volatile topic, as FRI's own UDP: a lost sample is superseded by the next one
        within a cycle, and the writer skips the acknowledgements of reliable delivery
        (measured: a third of the publishing CPU of a 500 Hz JointState).
        """
        if lockstep:
            return QoSProfile(history=HistoryPolicy.KEEP_LAST,
                              depth=self.lockstep_depth or self.qos.depth,
                              reliability=self.qos.reliability, durability=self.qos.durability)
        reliability = (ReliabilityPolicy.BEST_EFFORT
                       if self.qos.durability == DurabilityPolicy.VOLATILE
                       else self.qos.reliability)
        return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=reliability,
                          durability=self.qos.durability)

    def resolved(self, arm=None):
        """Return the absolute topic name, for the given arm if the topic is per arm."""
        if self.per_arm:
            if arm not in ARMS:
                raise ValueError(f'topic {self.name} is per arm; give one of {ARMS}')
            return f'/{arm}/{self.name}'
        return self.name


# Every topic's semantics (frames, stamps, units) is in the README's topic table. Stamps are sim
# time; vectors are SI and in the world frame unless a frame_id says otherwise.
CLOCK = Topic('/clock', Clock, CONTROL_QOS)
# Joints matched by name (any order; other joints ignored, a missing one refused).
JOINT_STATES = Topic('joint_states', JointState, SENSOR_QOS, per_arm=True,
                     lockstep_depth=SENSOR_SUBSCRIPTION_DEPTH)
TORQUE_COMMAND = Topic('torque_command', JointState, CONTROL_QOS, per_arm=True,
                       lockstep_depth=TORQUE_COMMAND_SUBSCRIPTION_DEPTH)
# Raw F/T reading: the wrench the tool applies to the sensor, frame <arm>_ft_sensor.
FT_WRENCH = Topic('ft_wrench', WrenchStamped, SENSOR_QOS, per_arm=True,
                  lockstep_depth=SENSOR_SUBSCRIPTION_DEPTH)
MOCAP_OBJECT_POSE = Topic('/mocap/object_pose', PoseStamped, SENSOR_QOS,
                          lockstep_depth=SENSOR_SUBSCRIPTION_DEPTH)
# The tracker answers every mocap sample (stamp = the sample's) and every /clock cycle (stamp =
# the cycle's). Pose and twist of the child frame 'object' in 'world', twist in 'world' at the
# object centre; covariances from the filter. Before a track exists pose.covariance[0] is
# NO_ESTIMATE_COVARIANCE (-1), the "no estimate" convention of sensor_msgs/Imu.
OBJECT_STATE = Topic('/object/state', Odometry, CONTROL_QOS)
NO_ESTIMATE_COVARIANCE = -1.0
# A conveyor's container, seen by motion capture: the centre of its floor in 'world' (identity
# orientation), stamped with the sampling time, delivered after the mocap latency.
MOCAP_CONTAINER_POSE = Topic('/mocap/container_pose', PoseStamped, SENSOR_QOS,
                             lockstep_depth=SENSOR_SUBSCRIPTION_DEPTH)
# The tracker's container estimate, answered like /object/state (each sample, each cycle; only
# with track_container): child 'container', position and velocity in 'world', the filter's
# position and velocity covariances (rows x, y, z), the same "no estimate" flag.
CONTAINER_STATE = Topic('/container/state', Odometry, CONTROL_QOS)
# Commanded speed of the outgoing belt [m/s], toward world -y, as the cell would command a belt
# driver; the twin adds the scenario's disturbance. Kept for a bridge that starts later.
OUTGOING_BELT_SPEED = Topic('/belt/outgoing/speed', Float64, QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL))
# Commanded speed of the incoming belt [m/s], toward world -y (it carries the box to be
# grabbed); the twin adds the scenario's disturbance. Kept for a bridge that starts later.
INCOMING_BELT_SPEED = Topic('/belt/incoming/speed', Float64, QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL))
# The DS command of one arm for a tick: a one-point MultiDOFJointTrajectory in 'world' for the
# joint '<arm>_tool': transforms[0] = the DS attractor (translation) and the desired tool
# orientation (rotation); velocities[0] = the desired tool twist in 'world' at the tool point.
DS_COMMAND = Topic('ds_command', MultiDOFJointTrajectory, CONTROL_QOS, per_arm=True,
                   lockstep_depth=COMMAND_SUBSCRIPTION_DEPTH)
# Force the pad applies on the object and moment about the tool point, frame 'world'.
CONTACT_WRENCH = Topic('contact_wrench', WrenchStamped, CONTROL_QOS, per_arm=True,
                       lockstep_depth=COMMAND_SUBSCRIPTION_DEPTH)
OBJECT_DESIRED_TWIST = Topic('/object/desired_twist', TwistStamped, CONTROL_QOS)
# One stamped status per DS tick: message = phase, values = task, time in phase, events, reason.
PHASE = Topic('/dual_arm/phase', DiagnosticArray, LATCHED_QOS)
PHASE_STATUS_NAME = 'dual_arm/phase'
MARKERS = Topic('/dual_arm/markers', MarkerArray, MONITOR_QOS)
# Where a toss should land (the box centre at rest on the landing surface), frame 'world': the
# motion generator plans the release state for it until the box is released, or refuses it
# with a reason (log, /diagnostics). Kept for a motion generator that starts later.
LANDING_TARGET = Topic('/dual_arm/landing_target', PointStamped, QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL))
GROUND_TRUTH_OBJECT = Topic('/ground_truth/object', Odometry, MONITOR_QOS)
# A conveyor's container from the simulator: centre of its floor, velocity, in 'world'.
GROUND_TRUTH_CONTAINER = Topic('/ground_truth/container', Odometry, MONITOR_QOS)
# Total force the pad exerts on the box and its moment about the tool point, frame 'world'
# (zero when the pad does not touch the box).
GROUND_TRUTH_PAD_WRENCH = Topic('ground_truth/pad_wrench', WrenchStamped, MONITOR_QOS,
                                per_arm=True)
# Tool-centre pose and twist in the world frame, from the simulator (evaluation only).
GROUND_TRUTH_TOOL = Topic('ground_truth/tool', Odometry, MONITOR_QOS, per_arm=True)
DIAGNOSTICS = Topic('/diagnostics', DiagnosticArray, MONITOR_QOS)
# bag_record's matched publishers per recorded topic (one status, values topic -> count): a
# recorded lockstep run starts once the recorder has matched every publisher the bridge sees.
RECORDER_STATUS = Topic('/bag_record/matched', DiagnosticArray, QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL))

# The cell model for viewers (cell_state_publisher): the URDF of both arms, each link and joint
# prefixed '<arm>_' (joints '<arm>_A1'..'<arm>_A7' as in joint_states), under the root link
# 'world', with the pallet and the front table; sent once, kept for late subscribers.
ROBOT_DESCRIPTION = Topic('/robot_description', String, QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL))
# TF frames (tf2 conventions): the URDF links ('world', '<arm>_link_0'..'<arm>_link_7',
# '<arm>_flange', '<arm>_ft_sensor', '<arm>_grabber', '<arm>_tool' = the pad's outer face, z out
# of the pad; 'pallet', 'front_table'), 'object' (the tracker's estimate of the box centre) and
# the task targets 'release_target', 'landing_target', 'place_target' (in 'world'). /tf carries
# the joints and the object, stamped with their inputs; /tf_static the rest, sent once.
TF = Topic('/tf', TFMessage, MONITOR_QOS)
TF_STATIC = Topic('/tf_static', TFMessage, QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL))

ALL_TOPICS = (
    CLOCK, JOINT_STATES, TORQUE_COMMAND, FT_WRENCH, MOCAP_OBJECT_POSE, OBJECT_STATE, DS_COMMAND,
    CONTACT_WRENCH, OBJECT_DESIRED_TWIST, PHASE, MARKERS, LANDING_TARGET, GROUND_TRUTH_OBJECT,
    GROUND_TRUTH_PAD_WRENCH, GROUND_TRUTH_TOOL, DIAGNOSTICS,
    RECORDER_STATUS, ROBOT_DESCRIPTION, TF, TF_STATIC, MOCAP_CONTAINER_POSE, CONTAINER_STATE,
    OUTGOING_BELT_SPEED, GROUND_TRUTH_CONTAINER, INCOMING_BELT_SPEED,
)

# Services of the bridge (std_srvs/Trigger) and their names.
SIM_RESET_SERVICE = '/sim/reset'
SIM_MOVE_OBJECT_SERVICE = '/sim/move_object'
# Services of the motion generator (std_srvs/Trigger).
START_EPISODE_SERVICE = '/dual_arm/start_episode'
GO_HOME_SERVICE = '/dual_arm/go_home'
RESET_EPISODE_SERVICE = '/dual_arm/reset'
