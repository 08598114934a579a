"""
Malformed messages for every topic a node of the graph subscribes to, drawn with Hypothesis.

Each drawn message has one named defect (DEFECTS): NaN, Inf or 1e12 values, empty or
wrong-length arrays, unknown joint names, a stamp from the past or the future, or a wrong
frame id; the rest of its content is drawn from the same bad values and plausible ones. The
stamp is set when the message is sent, relative to the sim clock then (MalformedMessage.build).
"""

from dataclasses import dataclass
import math

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from dual_arm_control import contract
from dual_arm_control.nodes.messages import time_msg
from geometry_msgs.msg import Transform, Twist
from hypothesis import given, HealthCheck, Phase, seed, settings, strategies
from trajectory_msgs.msg import MultiDOFJointTrajectoryPoint

DEFECTS = ('nan', 'inf', 'huge', 'empty', 'wrong_length', 'unknown_joints', 'stamp_past',
           'stamp_future', 'wrong_frame')
BAD_VALUES = {'nan': math.nan, 'inf': math.inf, 'huge': 1e12}
STAMP_OFFSETS_NS = {'stamp_past': -1_000_000_000, 'stamp_future': 10_000_000_000}
UNKNOWN_JOINTS = ('A1', 'left_A8', 'joint_1', '', 'right_tool')
WRONG_FRAMES = ('map', 'base_link', 'left_link_0', 'nowhere')
# (topic, arm or None) of every subscription of the product graph's nodes.
SUBSCRIBED = tuple(
    [(contract.JOINT_STATES, arm) for arm in contract.ARMS]
    + [(contract.FT_WRENCH, arm) for arm in contract.ARMS]
    + [(contract.DS_COMMAND, arm) for arm in contract.ARMS]
    + [(contract.CONTACT_WRENCH, arm) for arm in contract.ARMS]
    + [(contract.TORQUE_COMMAND, arm) for arm in contract.ARMS]
    + [(contract.MOCAP_OBJECT_POSE, None), (contract.OBJECT_STATE, None),
       (contract.OBJECT_DESIRED_TWIST, None), (contract.PHASE, None),
       (contract.LANDING_TARGET, None), (contract.CLOCK, None)])

_plain_values = strategies.floats(-2.0, 2.0, allow_nan=False)


@dataclass(frozen=True)
class MalformedMessage:
    """One drawn message: its topic, arm, defect and the numbers it carries."""

    topic: object
    arm: str
    defect: str
    values: tuple
    lengths: tuple
    names: tuple

    @property
    def topic_name(self):
        """Return the resolved topic name."""
        return self.topic.resolved(self.arm) if self.arm else self.topic.name

    def stamp_ns(self, clock_ns):
        """Return the stamp to send with at sim clock clock_ns."""
        return max(0, clock_ns + STAMP_OFFSETS_NS.get(self.defect, 0))

    def build(self, clock_ns):
        """Return the ROS message, stamped relative to clock_ns [ns]."""
        msg = self.topic.msg_type()
        stamp = time_msg(self.stamp_ns(clock_ns))
        if hasattr(msg, 'clock'):
            msg.clock = stamp
            return msg
        msg.header.stamp = stamp
        msg.header.frame_id = (WRONG_FRAMES[len(self.values) % len(WRONG_FRAMES)]
                               if self.defect == 'wrong_frame' else contract.WORLD_FRAME)
        _fill(msg, self)
        return msg


def _numbers(drawn, count):
    """Return count numbers from the drawn values (cycled), never an empty source."""
    values = drawn or (0.0,)
    return [float(values[i % len(values)]) for i in range(count)]


def _fill(msg, drawn):
    """Write the drawn numbers into the message's fields, sized by the defect."""
    values, lengths = drawn.values, drawn.lengths
    if hasattr(msg, 'effort'):
        msg.name = list(drawn.names)
        msg.position, msg.velocity, msg.effort = (
            _numbers(values[i:], lengths[i]) for i in range(3))
    elif hasattr(msg, 'wrench'):
        for vector, offset in ((msg.wrench.force, 0), (msg.wrench.torque, 3)):
            vector.x, vector.y, vector.z = _numbers(values[offset:], 3)
    elif hasattr(msg, 'pose') and hasattr(msg, 'twist'):
        _pose(msg.pose.pose, values)
        msg.twist.twist.linear.x, msg.twist.twist.linear.y, msg.twist.twist.linear.z = \
            _numbers(values[7:], 3)
        msg.pose.covariance = _numbers(values[1:], 36)
    elif hasattr(msg, 'pose'):
        _pose(msg.pose, values)
    elif hasattr(msg, 'points') and hasattr(msg, 'joint_names'):
        msg.joint_names = list(drawn.names)
        msg.points = [MultiDOFJointTrajectoryPoint(
            transforms=[_transform(values) for _ in range(lengths[1])],
            velocities=[_twist(values) for _ in range(lengths[2])]) for _ in range(lengths[0])]
    elif hasattr(msg, 'twist'):
        msg.twist = _twist(values)
    elif hasattr(msg, 'point'):
        msg.point.x, msg.point.y, msg.point.z = _numbers(values, 3)
    elif hasattr(msg, 'status'):
        _phase(msg, drawn)


def _pose(pose, values):
    numbers = _numbers(values, 7)
    pose.position.x, pose.position.y, pose.position.z = numbers[:3]
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = numbers[3:]


def _transform(values):
    transform = Transform()
    numbers = _numbers(values, 7)
    transform.translation.x, transform.translation.y, transform.translation.z = numbers[:3]
    rotation = transform.rotation
    rotation.x, rotation.y, rotation.z, rotation.w = numbers[3:]
    return transform


def _twist(values):
    twist = Twist()
    numbers = _numbers(values[2:], 6)
    twist.linear.x, twist.linear.y, twist.linear.z = numbers[:3]
    twist.angular.x, twist.angular.y, twist.angular.z = numbers[3:]
    return twist


def _phase(msg, drawn):
    texts = ('reach', 'no_such_phase', '', 'nan', '1e12')
    status = DiagnosticStatus(name=contract.PHASE_STATUS_NAME,
                              message=texts[len(drawn.names) % len(texts)])
    time_in_phase = drawn.values[0] if drawn.values else math.nan
    status.values = [KeyValue(key='time_in_phase', value=repr(time_in_phase)),
                     KeyValue(key='task', value=texts[len(drawn.values) % len(texts)])]
    msg.status = [status]


@strategies.composite
def malformed_messages(draw, topic, arm):
    """Draw one MalformedMessage for a topic (and arm): a defect and its content."""
    defect = draw(strategies.sampled_from(DEFECTS))
    value = BAD_VALUES.get(defect)
    pool = _plain_values if value is None else strategies.one_of(
        strategies.just(value), _plain_values)
    values = draw(strategies.lists(pool, min_size=1, max_size=12))
    if value is not None:
        values[draw(strategies.integers(0, len(values) - 1))] = value
    if defect == 'empty':
        lengths, values = (0, 0, 0), []
    elif defect == 'wrong_length':
        lengths = tuple(draw(strategies.lists(strategies.sampled_from((0, 1, 2, 6, 8, 12)),
                                              min_size=3, max_size=3)))
    else:
        lengths = (1, 1, 1) if topic is contract.DS_COMMAND else (7, 7, 7)
    names = tuple(contract.joint_names(arm)) if arm else ()
    if defect == 'unknown_joints' or topic is contract.DS_COMMAND:
        names = tuple(draw(strategies.lists(strategies.sampled_from(UNKNOWN_JOINTS + names),
                                            min_size=0, max_size=9)))
    return MalformedMessage(topic, arm, defect, tuple(values), lengths, tuple(names))


def draw_malformed(count, draw_seed):
    """
    Return count MalformedMessages drawn by Hypothesis with a fixed seed.

    Each example is one message per subscribed topic (so every topic gets its share), sent in
    that order; count is rounded up to whole examples.
    """
    drawn = []

    @seed(draw_seed)
    @settings(max_examples=-(-count // len(SUBSCRIBED)), database=None, deadline=None,
              phases=[Phase.generate], suppress_health_check=list(HealthCheck))
    @given(strategies.tuples(*(malformed_messages(topic, arm) for topic, arm in SUBSCRIBED)))
    def collect(messages):
        drawn.extend(messages)

    collect()
    return drawn
