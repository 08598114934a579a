"""
Position and velocity of a container carried by a belt, from its motion-capture positions.

Per-axis constant-velocity Kalman filter (the position model of core.tracker): white
acceleration of PSD acceleration_noise**2 covers the belt's speed changes; the three axes share
one (2, 2) covariance. Latency compensation as in core.tracker: a sample is applied at the stamp
at which it was taken, and prediction(t) carries the posterior forward to any later time, e.g.
the instant a tossed box will land, with the covariance grown by the process noise over that
interval (the uncertainty the tracker publishes). A sample not newer than the posterior is
refused as stale, one outside the chi-square gate as an outlier (a run of them for
rejection_reset_time restarts the track), one with NaN or Inf as invalid.
"""

from dataclasses import dataclass

from dual_arm_control.core.estimate import MeasurementOutcome, white_acceleration_noise
from dual_arm_control.core.exceptions import InputError
from dual_arm_control.core.settings import check_settings, setting
import numpy as np


@dataclass(frozen=True)
class ContainerTrackerConfig:
    """Noise model and gating of ContainerTracker."""

    position_noise: float = setting(
        0.0005, 'Standard deviation of each measured container position coordinate.',
        unit='m', low=0, high=1, low_open=True)
    acceleration_noise: float = setting(
        0.1, 'Square root of the white acceleration PSD of the container. The belt changes '
        'speed slowly (+-20 % of 0.4 m/s over 2 s: 0.25 m/s^2 at most); on that motion, 200 Hz '
        'and 0.5 mm noise, 0.1 gave a velocity error of 0.010 m/s (std) and a 0.3 s prediction '
        'error of 16 mm (p95), 0.3 gave 0.019 m/s and 20 mm.',
        unit='m/s^2/sqrt(s)', low=0, high=1e3, low_open=True)
    initial_velocity_std: float = setting(
        0.5, 'Prior standard deviation of each velocity component at track start.',
        unit='m/s', low=0, high=100.0, low_open=True)
    gate_chi_square: float = setting(
        21.11, 'Gate on the squared Mahalanobis distance of a sample (3 dof).',
        low=0, low_open=True)
    rejection_reset_time: float = setting(
        0.05, 'Duration of uninterrupted gate failures after which the track restarts.',
        unit='s', low=0, high=60.0, low_open=True)

    def __post_init__(self):
        check_settings(self)


@dataclass(frozen=True)
class ContainerPrediction:
    """The container at time stamp [s]: position, velocity (3,) and their per-axis variances."""

    stamp: float
    position: np.ndarray
    velocity: np.ndarray
    position_variance: float
    velocity_variance: float

    def position_at(self, t):
        """Return the position (3,) [m] at time t [s] by constant velocity from this one."""
        return self.position + self.velocity * (float(t) - self.stamp)


class ContainerTracker:
    """Constant-velocity Kalman filter of the container's position (see the module text)."""

    def __init__(self, config=None):
        self.config = config or ContainerTrackerConfig()
        self._r = self.config.position_noise ** 2
        self._q = self.config.acceleration_noise ** 2
        self._stamp = None
        self._first_rejection = None
        self._position = np.zeros(3)
        self._velocity = np.zeros(3)
        self._covariance = np.zeros((2, 2))

    @property
    def initialised(self):
        """Return True once a sample has been accepted."""
        return self._stamp is not None

    def update(self, stamp, position):
        """Apply a sample of the container centre (3,) [m] taken at stamp [s]."""
        position = np.asarray(position, dtype=float)
        if position.shape != (3,):
            raise InputError(f'position must have shape (3,), got {position.shape}')
        stamp = float(stamp)
        if not np.isfinite(stamp) or not np.all(np.isfinite(position)):
            return MeasurementOutcome.REJECTED_INVALID
        if self._stamp is None:
            return self._start(stamp, position)
        if stamp <= self._stamp:
            return MeasurementOutcome.REJECTED_STALE
        prior = self.prediction(stamp)
        residual = position - prior.position
        innovation_variance = prior.position_variance + self._r
        if residual @ residual / innovation_variance > self.config.gate_chi_square:
            if self._first_rejection is None:
                self._first_rejection = stamp
            if stamp - self._first_rejection >= self.config.rejection_reset_time:
                return self._start(stamp, position)
            return MeasurementOutcome.REJECTED_OUTLIER
        self._first_rejection = None
        covariance = self._propagated_covariance(stamp - self._stamp)
        gain = covariance[:, 0] / innovation_variance
        self._position = prior.position + gain[0] * residual
        self._velocity = prior.velocity + gain[1] * residual
        correction = np.eye(2) - np.outer(gain, [1.0, 0.0])
        self._covariance = (correction @ covariance @ correction.T
                            + self._r * np.outer(gain, gain))
        self._stamp = stamp
        return MeasurementOutcome.ACCEPTED

    def prediction(self, t):
        """Return the ContainerPrediction at time t [s], or None before the first sample."""
        if self._stamp is None:
            return None
        dt = float(t) - self._stamp
        covariance = self._propagated_covariance(dt)
        return ContainerPrediction(float(t), self._position + self._velocity * dt,
                                   self._velocity.copy(), float(covariance[0, 0]),
                                   float(covariance[1, 1]))

    def _propagated_covariance(self, dt):
        """Return the (2, 2) per-axis covariance carried dt [s] forward (constant velocity)."""
        transition = np.array([[1.0, dt], [0.0, 1.0]])
        return (transition @ self._covariance @ transition.T
                + white_acceleration_noise(self._q, dt))

    def _start(self, stamp, position):
        self._stamp = stamp
        self._first_rejection = None
        self._position = position.copy()
        self._velocity = np.zeros(3)
        self._covariance = np.diag([self._r, self.config.initial_velocity_std ** 2])
        return MeasurementOutcome.INITIALISED
