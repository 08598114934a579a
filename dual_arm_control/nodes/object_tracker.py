"""
object_tracker: the object's pose and twist from motion capture, per sample and per cycle.

Wraps core.tracker.ObjectTracker. Every accepted /mocap/object_pose sample is answered by one
/object/state (nav_msgs/Odometry, frame world, child 'object') carrying the sample's stamp and
the estimate at that stamp, also when the filter rejects the sample as an outlier or as stale
(the estimate is then the prediction), so the lockstep bridge's wait for the tracker always
ends. Every /clock cycle gets one more /object/state stamped with the cycle: the estimate at
that time, or (pose covariance[0] = contract.NO_ESTIMATE_COVARIANCE) the news that there is no
track yet; the lockstep DS and wrench QP wait for it at their ticks. Samples with NaN or Inf, a
zero quaternion or a stamp older than the previous sample are refused: counted, logged
(throttled) and not answered. A stamp more than TIME_RESET_GAP older than the previous one is no
late sample but a clock that went back (simulation reset): the filter restarts at that sample.
This is decided on the stamps alone because the lockstep bridge sends a reset cycle's mocap
samples, and waits for their answers, before its /clock.

Live tuning: a TrackerConfig change (ConfigParameters) is applied at the next sample by
restarting the filter with the new config when that costs nothing: no track yet, track lost, or
the object at rest (the restart takes the measured pose and zero velocity). While the object
moves the change stays pending. Counters go to /diagnostics at most once per
`diagnostics_period` of sim time (sample stamps).
"""

import sys

from diagnostic_msgs.msg import DiagnosticStatus
from dual_arm_control import contract
from dual_arm_control.core.tracker import MeasurementOutcome, ObjectTracker, TrackerConfig
from dual_arm_control.nodes.common import (CounterDiagnostics, create_topic_publisher,
                                           NANOSECONDS_PER_SECOND, quaternion,
                                           RefusalCounter, run_node, seconds_to_ns, set_odometry,
                                           stamp_ns, time_msg, vector3)
from dual_arm_control.parameters import ConfigParameters
import numpy as np
from rclpy.node import Node

# Below these estimated speeds the object counts as at rest, so restarting the filter with a new
# config loses nothing; they sit above the velocity noise of a static object with the default
# noise model (99th percentile 0.09 m/s and 0.5 rad/s at 200 Hz).
REST_SPEED = 0.2
REST_ANGULAR_SPEED = 1.0
MIN_QUATERNION_NORM = 1e-6
# A sample this much older than the previous one means the clock went back (simulation reset),
# not a late sample: mocap samples reorder by a few milliseconds at most [s].
TIME_RESET_GAP = 0.1
OUTCOME_COUNTERS = {
    MeasurementOutcome.INITIALISED: 'track_starts',
    MeasurementOutcome.ACCEPTED: 'samples_used',
    MeasurementOutcome.REJECTED_OUTLIER: 'samples_rejected_outlier',
    MeasurementOutcome.REJECTED_STALE: 'samples_rejected_stale',
    MeasurementOutcome.REJECTED_INVALID: 'samples_rejected_invalid',
}


class ObjectTrackerNode(Node):
    """Answer each mocap sample with the object estimate at the sample's stamp."""

    def __init__(self, node_name='object_tracker', **node_options):
        super().__init__(node_name, **node_options)
        self._diagnostics = CounterDiagnostics(self)
        self._config_parameters = ConfigParameters(self, TrackerConfig(), self._on_config)
        self._tracker = ObjectTracker(self._config_parameters.config)
        self._pending_config = None
        self._last_stamp_ns = None
        self.refusals = RefusalCounter(self.get_logger())
        self.counters = dict.fromkeys(
            ('samples_received', 'states_published', 'config_changes_applied', 'time_resets',
             *OUTCOME_COUNTERS.values()), 0)
        self._state_msg = contract.OBJECT_STATE.msg_type()
        self._state_msg.header.frame_id = contract.WORLD_FRAME
        self._state_msg.child_frame_id = 'object'
        self._state_pub = create_topic_publisher(self, contract.OBJECT_STATE)
        self._mocap_sub = self.create_subscription(
            contract.MOCAP_OBJECT_POSE.msg_type, contract.MOCAP_OBJECT_POSE.name, self._on_mocap,
            contract.MOCAP_OBJECT_POSE.qos)
        self._clock_sub = self.create_subscription(
            contract.CLOCK.msg_type, contract.CLOCK.name, self._on_clock, contract.CLOCK.qos)
        self.get_logger().info(
            f'object tracker up: {self._mocap_sub.topic_name} -> {self._state_pub.topic_name}')

    @property
    def config(self):
        """Return the TrackerConfig the filter runs with (a pending change not included)."""
        return self._tracker.config

    @property
    def pending_config(self):
        """Return the accepted TrackerConfig waiting for the object to rest, or None."""
        return self._pending_config

    def _on_config(self, config):
        """Keep an accepted config for the next sample."""
        self._pending_config = config

    def _restart_after_time_reset(self, t_ns):
        """Restart the filter when the clock went back (simulation reset)."""
        self._tracker = ObjectTracker(self._pending_config or self._tracker.config)
        self._pending_config = None
        self.counters['time_resets'] += 1
        self.get_logger().info(
            f'sample stamp went back from {self._last_stamp_ns} ns to {t_ns} ns (clock reset): '
            'filter restarted')

    def _on_mocap(self, msg):
        """Refuse an invalid sample, or filter it and publish the estimate at its stamp."""
        self.counters['samples_received'] += 1
        t_ns = stamp_ns(msg.header.stamp)
        position = vector3(msg.pose.position)
        quat_xyzw = quaternion(msg.pose.orientation)
        if not (np.all(np.isfinite(position)) and np.all(np.isfinite(quat_xyzw))):
            self.refusals.refuse('non_finite', f'sample at {t_ns} ns contains NaN or Inf')
            return
        if np.linalg.norm(quat_xyzw) < MIN_QUATERNION_NORM:
            self.refusals.refuse('zero_quaternion', f'sample at {t_ns} ns has no orientation')
            return
        if self._last_stamp_ns is not None and (self._last_stamp_ns - t_ns
                                                > seconds_to_ns(TIME_RESET_GAP)):
            self._restart_after_time_reset(t_ns)
        elif self._last_stamp_ns is not None and t_ns < self._last_stamp_ns:
            self.refusals.refuse('old_stamp', f'sample at {t_ns} ns is older than the previous '
                                              f'one at {self._last_stamp_ns} ns')
            return
        self._last_stamp_ns = t_ns
        t = t_ns / NANOSECONDS_PER_SECOND
        self._apply_pending_config(t)
        outcome = self._tracker.update(t, position, quat_xyzw)
        self.counters[OUTCOME_COUNTERS[outcome]] += 1
        if outcome is MeasurementOutcome.INITIALISED:
            self.counters['samples_used'] += 1
        self._publish_state(t_ns, self._tracker.state(t))
        self._diagnostics.publish_if_due(t_ns, self._report)

    def _on_clock(self, msg):
        """
        Publish the estimate at the cycle's time, or that there is none yet.

        In lockstep the bridge publishes /clock after the tracker answered the cycle's mocap
        samples, so this estimate holds all of them: the DS and the wrench QP wait for it at
        their ticks, which makes their input independent of message timing.
        """
        t_ns = stamp_ns(msg.clock)
        estimate = (self._tracker.state(t_ns / NANOSECONDS_PER_SECOND)
                    if self._last_stamp_ns is not None and t_ns >= self._last_stamp_ns else None)
        if estimate is None:
            self._publish_no_estimate(t_ns)
        else:
            self._publish_state(t_ns, estimate)

    def _apply_pending_config(self, t):
        """Restart the filter with the pending config if no track is running or it rests."""
        if self._pending_config is None:
            return
        estimate = self._tracker.state(t)
        if estimate is not None and not estimate.lost and (
                np.linalg.norm(estimate.linear_velocity) >= REST_SPEED
                or np.linalg.norm(estimate.angular_velocity) >= REST_ANGULAR_SPEED):
            return
        self._tracker = ObjectTracker(self._pending_config)
        self._pending_config = None
        self.counters['config_changes_applied'] += 1

    def _publish_no_estimate(self, t_ns):
        """Publish an /object/state stamped t_ns that says there is no estimate."""
        msg = contract.OBJECT_STATE.msg_type()
        msg.header.frame_id = contract.WORLD_FRAME
        msg.child_frame_id = 'object'
        msg.header.stamp = time_msg(t_ns)
        msg.pose.covariance[0] = contract.NO_ESTIMATE_COVARIANCE
        self._state_pub.publish(msg)

    def _publish_state(self, t_ns, estimate):
        """Publish the estimate stamped t_ns (a sample's or a cycle's time)."""
        msg = self._state_msg
        msg.header.stamp = time_msg(t_ns)
        set_odometry(msg, estimate.position, estimate.quat_xyzw, estimate.linear_velocity,
                     estimate.angular_velocity)
        self._state_pub.publish(msg)
        self.counters['states_published'] += 1

    def _report(self):
        """Return (level, message, values) of the diagnostics: counters and track status."""
        estimate = (None if self._last_stamp_ns is None
                    else self._tracker.state(self._last_stamp_ns / NANOSECONDS_PER_SECOND))
        tracking = estimate is not None and not estimate.lost
        values = dict(self.counters)
        values.update({f'refused_{reason}': n for reason, n in self.refusals.counts.items()})
        values.update({'tracking': tracking, 'config_change_pending':
                       self._pending_config is not None})
        if not tracking:
            return DiagnosticStatus.WARN, 'no object track', values
        if self.refusals.total:
            return DiagnosticStatus.WARN, 'tracking; invalid samples refused', values
        return DiagnosticStatus.OK, 'tracking', values


def main(args=None):
    """Run the tracker until Ctrl-C or SIGTERM; return the exit code."""
    return run_node(ObjectTrackerNode, 'object_tracker', args)


if __name__ == '__main__':
    sys.exit(main())
