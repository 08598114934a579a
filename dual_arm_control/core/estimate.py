"""
What the object tracker reports, and the two small pieces of its filter's algebra.

ObjectEstimate is the tracker's output (state, covariances, sample counts), MeasurementOutcome
says what one sample did; white_acceleration_noise and left_jacobian_so3 are the process
noise of a constant-velocity axis and the SO(3) left Jacobian the filter propagates with.
"""

from dataclasses import dataclass
import enum
import math

from dual_arm_control.core.geometry import skew
import numpy as np


class MeasurementOutcome(enum.Enum):
    """
    What update() did with a sample.

    INITIALISED: the sample (re)started the track (first sample, after loss, or after gate
    failures lasting rejection_reset_time); ACCEPTED: filtered in; REJECTED_OUTLIER: failed the
    gate; REJECTED_STALE: not newer than the posterior; REJECTED_INVALID: NaN, Inf or zero
    quaternion.
    """

    INITIALISED = 'initialised'
    ACCEPTED = 'accepted'
    REJECTED_OUTLIER = 'rejected_outlier'
    REJECTED_STALE = 'rejected_stale'
    REJECTED_INVALID = 'rejected_invalid'


@dataclass(frozen=True)
class ObjectEstimate:
    """
    Estimated object state at `stamp`, world frame.

    Covariances are (3, 3); orientation_covariance is that of the world-frame rotation error
    vector [rad^2]. When lost, position and orientation are the last posterior values (not
    extrapolated), velocities are zero and the covariances are those predicted to `stamp`.
    """

    stamp: float
    position: np.ndarray
    quat_xyzw: np.ndarray
    linear_velocity: np.ndarray
    angular_velocity: np.ndarray
    position_covariance: np.ndarray
    orientation_covariance: np.ndarray
    linear_velocity_covariance: np.ndarray
    angular_velocity_covariance: np.ndarray
    lost: bool
    free_flight: bool
    last_sample_stamp: float
    samples_used: int
    samples_rejected_outlier: int
    samples_rejected_stale: int
    samples_rejected_invalid: int
    track_restarts: int

    @property
    def samples_rejected(self):
        """Return the number of refused samples of every kind."""
        return (self.samples_rejected_outlier + self.samples_rejected_stale
                + self.samples_rejected_invalid)


def white_acceleration_noise(intensity, dt):
    """
    Return the (2, 2) process noise of one constant-velocity axis over dt seconds.

    Continuous white acceleration of PSD intensity [unit^2/s^3] integrated over |dt|:
    intensity * [[dt^3/3, dt^2/2], [dt^2/2, dt]].
    """
    dt = abs(dt)
    return intensity * np.array([[dt ** 3 / 3.0, dt ** 2 / 2.0], [dt ** 2 / 2.0, dt]])


def left_jacobian_so3(rotation_vector):
    """Return the (3, 3) left Jacobian J_l(phi) = sum_k [phi]x^k / (k + 1)! of SO(3)."""
    theta = float(np.linalg.norm(rotation_vector))
    k = skew(rotation_vector)
    if theta < 1e-6:
        return np.eye(3) + 0.5 * k + k @ k / 6.0
    return (np.eye(3) + (1.0 - math.cos(theta)) / theta ** 2 * k
            + (theta - math.sin(theta)) / theta ** 3 * k @ k)
