"""
The object tracker role: mocap samples in, object estimates out (core ObjectTracker).

Every accepted sample is answered by the estimate at its stamp, also when the filter rejects
the sample as an outlier or as stale (the estimate is then the prediction). Every FRI cycle is
answered by the estimate at the cycle, or by "no estimate" before a track exists. Samples with
NaN or Inf, a zero quaternion or a stamp older than the previous sample are refused (counted,
not answered). A stamp more than TIME_RESET_GAP older than the previous one is no late sample
but a clock that went back (simulation reset): the filter restarts at that sample.

A new TrackerConfig is applied at the next sample by restarting the filter when that costs
nothing: no track yet, track lost, or the object at rest (the restart takes the measured pose
and zero velocity). While the object moves the change stays pending.

The container of a conveyor has a filter of its own (core.container_tracker), fed by its mocap
stream in the same way (container_sample, container_at); its estimates are ObjectStates with an
identity orientation and the filter's position and velocity covariances. Its config (the
TrackerConfig's `container`) is taken when its track starts, or restarts after a time reset.
"""

from dual_arm_control.core.container_tracker import ContainerTracker
from dual_arm_control.core.estimate import MeasurementOutcome
from dual_arm_control.core.exceptions import InputError
from dual_arm_control.core.tracker import ObjectTracker
from dual_arm_control.runtime.inputs import RefusalCounter
from dual_arm_control.runtime.signals import no_object_state, ObjectState, pose_sample
from dual_arm_control.runtime.timing import NANOSECONDS_PER_SECOND, seconds_to_ns
import numpy as np

# Below these estimated speeds the object counts as at rest, so restarting the filter with a new
# config loses nothing; they sit above the velocity noise of a static object with the default
# noise model (99th percentile 0.09 m/s and 0.5 rad/s at 200 Hz).
REST_SPEED = 0.2
REST_ANGULAR_SPEED = 1.0
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
_IDENTITY_QUAT = np.array([0.0, 0.0, 0.0, 1.0])


def _block_diagonal(upper, lower):
    covariance = np.zeros((6, 6))
    covariance[:3, :3] = upper
    covariance[3:, 3:] = lower
    return covariance


def _state(stamp_ns, estimate):
    return ObjectState(stamp_ns, True, estimate.position, estimate.quat_xyzw,
                       estimate.linear_velocity, estimate.angular_velocity,
                       _block_diagonal(estimate.position_covariance,
                                       estimate.orientation_covariance),
                       _block_diagonal(estimate.linear_velocity_covariance,
                                       estimate.angular_velocity_covariance))


def _container_state(stamp_ns, prediction):
    """Return the ObjectState of a ContainerPrediction (identity orientation, no rotation)."""
    return ObjectState(stamp_ns, True, prediction.position, _IDENTITY_QUAT,
                       prediction.velocity, np.zeros(3),
                       _block_diagonal(prediction.position_variance * np.eye(3), np.zeros((3, 3))),
                       _block_diagonal(prediction.velocity_variance * np.eye(3), np.zeros((3, 3))))


class TrackerStep:
    """The tracker role; config: TrackerConfig; on_refusal as RefusalCounter's."""

    def __init__(self, config, on_refusal=None):
        self._tracker = ObjectTracker(config)
        self._container = ContainerTracker(config.container)
        self._container_stamp_ns = None
        self._pending_config = None
        self._last_stamp_ns = None
        self.refusals = RefusalCounter(on_refusal)
        self.counters = dict.fromkeys(
            ('samples_received', 'config_changes_applied', 'time_resets',
             *OUTCOME_COUNTERS.values(), 'container_samples_received',
             *(f'container_{name}' for name in OUTCOME_COUNTERS.values())), 0)

    @property
    def config(self):
        """Return the TrackerConfig the filter runs with (a pending change not included)."""
        return self._tracker.config

    @property
    def pending_config(self):
        """Return the accepted TrackerConfig waiting for the object to rest, or None."""
        return self._pending_config

    def reconfigure(self, config):
        """Use config from the next sample at which the object rests (or no track runs)."""
        self._pending_config = config

    def sample(self, stamp_ns, position, quat_xyzw):
        """Filter one mocap sample; return the ObjectState at its stamp, or None if refused."""
        self.counters['samples_received'] += 1
        try:
            pose = pose_sample(stamp_ns, position, quat_xyzw)
        except InputError as error:
            finite = np.isfinite(np.asarray(position, float)).all() and np.isfinite(
                np.asarray(quat_xyzw, float)).all()
            self.refusals.refuse('zero_quaternion' if finite else 'non_finite',
                                 f'sample at {stamp_ns} ns: {error}')
            return None
        if self._last_stamp_ns is not None and (self._last_stamp_ns - pose.stamp_ns
                                                > seconds_to_ns(TIME_RESET_GAP)):
            self._tracker = ObjectTracker(self._pending_config or self._tracker.config)
            self._pending_config = None
            self.counters['time_resets'] += 1
        elif self._last_stamp_ns is not None and pose.stamp_ns < self._last_stamp_ns:
            self.refusals.refuse('old_stamp', f'sample at {pose.stamp_ns} ns is older than the '
                                              f'previous one at {self._last_stamp_ns} ns')
            return None
        self._last_stamp_ns = pose.stamp_ns
        t = pose.stamp_ns / NANOSECONDS_PER_SECOND
        self._apply_pending_config(t)
        outcome = self._tracker.update(t, pose.position, pose.quat_xyzw)
        self.counters[OUTCOME_COUNTERS[outcome]] += 1
        if outcome is MeasurementOutcome.INITIALISED:
            self.counters['samples_used'] += 1
        return _state(pose.stamp_ns, self._tracker.state(t))

    def at(self, stamp_ns):
        """
        Return the ObjectState at a cycle stamp (no estimate before the first sample).

        The mean only (no covariances): it is asked for every FRI cycle.
        """
        if self._last_stamp_ns is None or stamp_ns < self._last_stamp_ns:
            return no_object_state(stamp_ns)
        mean = self._tracker.mean_state(stamp_ns / NANOSECONDS_PER_SECOND)
        return ObjectState(stamp_ns, True, *mean)

    def container_sample(self, stamp_ns, position):
        """Filter one container sample; return the ObjectState at its stamp, or None if refused."""
        self.counters['container_samples_received'] += 1
        if self._container_stamp_ns is not None and (self._container_stamp_ns - int(stamp_ns)
                                                     > seconds_to_ns(TIME_RESET_GAP)):
            self._container = ContainerTracker(self.config.container)
        outcome = self._container.update(int(stamp_ns) / NANOSECONDS_PER_SECOND, position)
        self.counters[f'container_{OUTCOME_COUNTERS[outcome]}'] += 1
        if outcome in (MeasurementOutcome.REJECTED_INVALID, MeasurementOutcome.REJECTED_STALE):
            self.refusals.refuse('container_sample', f'container sample at {stamp_ns} ns: '
                                                     f'{outcome.value}')
            return None
        self._container_stamp_ns = int(stamp_ns)
        return self.container_at(stamp_ns)

    def container_at(self, stamp_ns):
        """Return the container's ObjectState at a stamp, with covariances (or none yet)."""
        prediction = self._container.prediction(int(stamp_ns) / NANOSECONDS_PER_SECOND)
        if prediction is None:
            return no_object_state(stamp_ns)
        return _container_state(int(stamp_ns), prediction)

    def tracking(self):
        """Return True while a track runs and is not lost."""
        if self._last_stamp_ns is None:
            return False
        return not self._tracker.state(self._last_stamp_ns / NANOSECONDS_PER_SECOND).lost

    def _apply_pending_config(self, t):
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
