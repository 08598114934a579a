"""
Object state estimation from motion-capture poses: a pose + twist Kalman filter.

Position: per-axis constant-velocity Kalman filter driven by continuous white acceleration of
power spectral density q = acceleration_noise**2 [m^2/s^3], so over an interval dt the process
noise of one axis is q * [[dt^3/3, dt^2/2], [dt^2/2, dt]]. The three axes have identical models
and are measured together, so they share one (2, 2) covariance. During a declared free flight
(set_free_flight) gravity is a known input to the prediction.

Orientation: error-state (multiplicative) Kalman filter on SO(3). The nominal state is the
rotation R_world_object and the angular velocity omega (world frame, rad/s); the error state is
(delta_theta, delta_omega) with R = exp([delta_theta]x) R_hat, i.e. a small rotation vector
expressed in the world frame. Constant angular velocity gives the exact error transition
delta_theta(t + dt) = Phi delta_theta + dt J_l(omega dt) delta_omega with Phi = exp([omega dt]x)
and J_l the left Jacobian of SO(3); white angular acceleration of intensity
angular_acceleration_noise**2 gives the same noise blocks as the position model. The
orientation residual of a measured R_m is log(R_m R_hat^T). After each update the correction is
injected into R_hat and the error covariance is kept as is (the reset Jacobian
I - [delta_theta_hat]x / 2 differs from I by less than 1 % for corrections below 0.02 rad).

Time: nothing reads a clock. Each measurement carries the stamp at which the mocap sampled it;
update() applies it at that stamp, so the filter posterior lives at the last accepted sample
time, and state(t) predicts forward to the query time t. This compensates the transport latency
exactly as far as the motion model holds. A sample not newer than the posterior (out of order,
duplicate) is refused and counted as stale: at 200 Hz with a steady latency reordering is rare,
and refusing costs one sample, whereas re-filtering would need a history buffer.

Robustness: position and orientation innovations are each tested against a chi-square gate
(3 degrees of freedom) on the Mahalanobis distance; a sample failing either test is refused and
counted. If samples keep failing the gate for rejection_reset_time, the motion really changed
(e.g. the object was hit or moved by hand) and the track restarts at the newest sample. When no
sample was accepted for lost_timeout the track is declared lost; the next valid sample restarts
it wherever it is (a jump is accepted). Samples containing NaN or Inf, or a zero quaternion,
are what mocap systems send for an untracked body: they are refused and counted as invalid (no
exception); a wrongly shaped input is a programming error and raises InputError.
"""

from dataclasses import dataclass, field
import math

from dual_arm_control.core.container_tracker import ContainerTrackerConfig
from dual_arm_control.core.estimate import (left_jacobian_so3, MeasurementOutcome, ObjectEstimate,
                                            white_acceleration_noise)
from dual_arm_control.core.exceptions import InputError
from dual_arm_control.core.geometry import (matrix_to_quat_xyzw, quat_xyzw_to_matrix,
                                            rotation_exp, rotation_log)
from dual_arm_control.core.linear_solve import solve
from dual_arm_control.core.settings import check_settings, setting
import numpy as np

_IDENTITY_2 = np.eye(2)
_IDENTITY_3 = np.eye(3)
_IDENTITY_6 = np.eye(6)


@dataclass(frozen=True)
class TrackerConfig:
    """
    Noise model, gating and timeouts of ObjectTracker.

    Defaults: mocap at 200 Hz with up to 2 mm and 0.005 rad of noise. The position noise is the
    noisiest mocap the cell accepts, not the best one: a filter that assumes less noise than it
    gets refuses good samples at its gate and restarts on a noisy one (1.65 mm of noise against
    an assumed 0.5 mm: the resting box's estimate jumped up to 11 mm between ticks, std 3 mm;
    assuming 2 mm: 3 mm and 1 mm). The price is lag on a steady acceleration: 0.18 m/s at
    8.5 m/s^2 (the toss ramp) instead of 0.08; a held box is estimated from the pads instead.
    """

    position_noise: float = setting(
        0.002, 'Standard deviation of each measured position coordinate.',
        unit='m', low=0, high=1, low_open=True)
    orientation_noise: float = setting(
        0.005, 'Standard deviation of each component of the measured rotation error vector.',
        unit='rad', low=0, high=1, low_open=True)
    acceleration_noise: float = setting(
        0.5, 'Square root of the white linear acceleration PSD.',
        unit='m/s^2/sqrt(s)', low=0, high=1e3, low_open=True)
    angular_acceleration_noise: float = setting(
        2.0, 'Square root of the white angular acceleration PSD.',
        unit='rad/s^2/sqrt(s)', low=0, high=1e4, low_open=True)
    initial_velocity_std: float = setting(
        1.0, 'Prior standard deviation of each linear velocity component at track start.',
        unit='m/s', low=0, high=100.0, low_open=True)
    initial_angular_velocity_std: float = setting(
        3.0, 'Prior standard deviation of each angular velocity component at track start.',
        unit='rad/s', low=0, high=1000.0, low_open=True)
    gate_chi_square: float = setting(
        21.11, 'Gate on the squared Mahalanobis distance (3 dof); 21.11 is the 0.9999 quantile.',
        low=0, low_open=True)
    rejection_reset_time: float = setting(
        0.05, 'Duration of uninterrupted gate failures after which the track restarts.',
        unit='s', low=0, high=60.0, low_open=True)
    lost_timeout: float = setting(
        0.5, 'Time without an accepted sample after which the object is declared lost.',
        unit='s', low=0, high=60.0, low_open=True)
    gravity: float = setting(
        9.81, 'Gravitational acceleration applied along -z during a declared free flight.',
        unit='m/s^2', low=0, high=100.0)
    container: ContainerTrackerConfig = field(default_factory=ContainerTrackerConfig)

    def __post_init__(self):
        check_settings(self)


class ObjectTracker:
    """
    Pose and twist Kalman filter for one rigid object seen by motion capture.

    Feed samples with update(stamp, position, quat_xyzw) as they arrive (one not newer than the
    last accepted sample is refused as stale); query the estimate at any time with state(t),
    which predicts from the last accepted sample. Times are seconds on one clock (ROS time).
    """

    def __init__(self, config=None):
        self.config = config or TrackerConfig()
        self._q_position = self.config.acceleration_noise ** 2
        self._q_orientation = self.config.angular_acceleration_noise ** 2
        self._r_position = self.config.position_noise ** 2
        self._r_orientation = self.config.orientation_noise ** 2
        self._posterior_stamp = None
        self._first_rejection_stamp = None
        self._position = np.zeros(3)
        self._velocity = np.zeros(3)
        self._covariance_position = np.zeros((2, 2))
        self._R_world_object = np.eye(3)
        self._angular_velocity = np.zeros(3)
        self._covariance_orientation = np.zeros((6, 6))
        self._flight_start = math.inf
        self._flight_end = math.inf
        self._samples_used = 0
        self._samples_rejected_outlier = 0
        self._samples_rejected_stale = 0
        self._samples_rejected_invalid = 0
        self._track_restarts = 0

    @property
    def initialised(self):
        """Return True once a sample has been accepted."""
        return self._posterior_stamp is not None

    def set_free_flight(self, stamp, in_flight):
        """
        Declare that from `stamp` [s] on the object flies freely (in_flight) or not any more.

        In free flight the prediction adds gravity (-gravity along world z) to the constant
        velocity model, which removes the lag a constant-velocity model has on a ballistic arc.
        """
        stamp = float(stamp)
        if not math.isfinite(stamp):
            raise InputError(f'free-flight stamp must be finite, got {stamp}')
        if in_flight:
            self._flight_start, self._flight_end = stamp, math.inf
        elif self._flight_start <= stamp:
            self._flight_end = min(self._flight_end, stamp)

    def update(self, stamp, position, quat_xyzw):
        """
        Apply one mocap sample taken at `stamp` [s]; return a MeasurementOutcome.

        position: (3,) world [m]; quat_xyzw: (4,) R_world_object, any norm > 0.
        """
        position = np.asarray(position, dtype=float)
        quat_xyzw = np.asarray(quat_xyzw, dtype=float)
        if position.shape != (3,) or quat_xyzw.shape != (4,):
            raise InputError(f'position must have shape (3,) and quat_xyzw (4,), got '
                             f'{position.shape} and {quat_xyzw.shape}')
        stamp = float(stamp)
        quat_norm = float(np.linalg.norm(quat_xyzw))
        if (not math.isfinite(stamp) or not np.all(np.isfinite(position))
                or not math.isfinite(quat_norm) or quat_norm < 1e-6):
            self._samples_rejected_invalid += 1
            return MeasurementOutcome.REJECTED_INVALID
        R_measured = quat_xyzw_to_matrix(quat_xyzw / quat_norm)
        if self._posterior_stamp is None or self._is_lost(stamp):
            return self._start_track(stamp, position, R_measured)
        if stamp <= self._posterior_stamp:
            self._samples_rejected_stale += 1
            return MeasurementOutcome.REJECTED_STALE
        prior = self._prediction(stamp)
        position_residual = position - prior['position']
        position_innovation_variance = prior['covariance_position'][0, 0] + self._r_position
        orientation_residual = rotation_log(R_measured @ prior['R_world_object'].T)
        P = prior['covariance_orientation']
        orientation_innovation = P[:3, :3] + self._r_orientation * _IDENTITY_3
        orientation_distance = orientation_residual @ solve(orientation_innovation,
                                                            orientation_residual)
        position_distance = position_residual @ position_residual / position_innovation_variance
        gate = self.config.gate_chi_square
        if position_distance > gate or orientation_distance > gate:
            if self._first_rejection_stamp is None:
                self._first_rejection_stamp = stamp
            if stamp - self._first_rejection_stamp >= self.config.rejection_reset_time:
                return self._start_track(stamp, position, R_measured)
            self._samples_rejected_outlier += 1
            return MeasurementOutcome.REJECTED_OUTLIER
        self._first_rejection_stamp = None

        P2 = prior['covariance_position']
        gain_position = P2[:, 0] / position_innovation_variance
        self._position = prior['position'] + gain_position[0] * position_residual
        self._velocity = prior['velocity'] + gain_position[1] * position_residual
        correction = _IDENTITY_2 - np.outer(gain_position, [1.0, 0.0])
        self._covariance_position = (correction @ P2 @ correction.T + self._r_position
                                     * np.outer(gain_position, gain_position))

        gain_orientation = solve(orientation_innovation, P[:3, :]).T
        error_state = gain_orientation @ orientation_residual
        self._R_world_object = rotation_exp(error_state[:3]) @ prior['R_world_object']
        self._angular_velocity = prior['angular_velocity'] + error_state[3:]
        correction = _IDENTITY_6.copy()
        correction[:, :3] -= gain_orientation
        covariance = (correction @ P @ correction.T
                      + self._r_orientation * gain_orientation @ gain_orientation.T)
        self._covariance_orientation = 0.5 * (covariance + covariance.T)

        self._posterior_stamp = stamp
        self._samples_used += 1
        return MeasurementOutcome.ACCEPTED

    def state(self, t):
        """
        Return the ObjectEstimate predicted to time t [s], or None before the first sample.

        Does not change the filter. A query older than the newest accepted sample is
        extrapolated backwards with the same model.
        """
        if self._posterior_stamp is None:
            return None
        t = float(t)
        if not math.isfinite(t):
            raise InputError(f'query time must be finite, got {t}')
        prior = self._prediction(t)
        P2 = prior['covariance_position']
        P = prior['covariance_orientation']
        lost = self._is_lost(t)
        if lost:
            position, R_world_object = self._position, self._R_world_object
            linear_velocity, angular_velocity = np.zeros(3), np.zeros(3)
        else:
            position, R_world_object = prior['position'], prior['R_world_object']
            linear_velocity, angular_velocity = prior['velocity'], prior['angular_velocity']
        return ObjectEstimate(
            stamp=t,
            position=position.copy(),
            quat_xyzw=matrix_to_quat_xyzw(R_world_object),
            linear_velocity=linear_velocity.copy(),
            angular_velocity=angular_velocity.copy(),
            position_covariance=P2[0, 0] * np.eye(3),
            orientation_covariance=P[:3, :3].copy(),
            linear_velocity_covariance=P2[1, 1] * np.eye(3),
            angular_velocity_covariance=P[3:, 3:].copy(),
            lost=lost,
            free_flight=self._flight_start <= t < self._flight_end,
            last_sample_stamp=self._posterior_stamp,
            samples_used=self._samples_used,
            samples_rejected_outlier=self._samples_rejected_outlier,
            samples_rejected_stale=self._samples_rejected_stale,
            samples_rejected_invalid=self._samples_rejected_invalid,
            track_restarts=self._track_restarts,
        )

    def _is_lost(self, t):
        return t - self._posterior_stamp > self.config.lost_timeout

    def _start_track(self, stamp, position, R_measured):
        if self._posterior_stamp is not None:
            self._track_restarts += 1
        self._position = position.copy()
        self._velocity = np.zeros(3)
        self._covariance_position = np.diag(
            [self._r_position, self.config.initial_velocity_std ** 2])
        self._R_world_object = R_measured
        self._angular_velocity = np.zeros(3)
        self._covariance_orientation = np.diag(
            [self._r_orientation] * 3 + [self.config.initial_angular_velocity_std ** 2] * 3)
        self._posterior_stamp = stamp
        self._first_rejection_stamp = None
        self._samples_used += 1
        return MeasurementOutcome.INITIALISED

    def mean_state(self, t):
        """
        Return (position, quat_xyzw, linear velocity, angular velocity) predicted to t [s].

        The mean of state(t) without its covariances (bit for bit the same numbers), for callers
        that need the estimate at every cycle; None before the first sample.
        """
        if self._posterior_stamp is None:
            return None
        t = float(t)
        if self._is_lost(t):
            return (self._position.copy(), matrix_to_quat_xyzw(self._R_world_object),
                    np.zeros(3), np.zeros(3))
        position, velocity, _, _, R_world_object = self._mean_prediction(t)
        return (position, matrix_to_quat_xyzw(R_world_object), velocity,
                self._angular_velocity.copy())

    def _mean_prediction(self, t):
        """Return (position, velocity, rotation increment, its rotation, R_world_object) at t."""
        dt = t - self._posterior_stamp
        gravity_displacement, gravity_velocity = self._gravity_effect(self._posterior_stamp, t)
        position = self._position + self._velocity * dt
        velocity = self._velocity.copy()
        position[2] += gravity_displacement
        velocity[2] += gravity_velocity
        rotation_increment = self._angular_velocity * dt
        rotation_transition = rotation_exp(rotation_increment)
        return (position, velocity, rotation_increment, rotation_transition,
                rotation_transition @ self._R_world_object)

    def _prediction(self, t):
        """Return the prior mean and covariances propagated from the posterior to time t."""
        dt = t - self._posterior_stamp
        position, velocity, rotation_increment, rotation_transition, R_world_object = (
            self._mean_prediction(t))
        transition = np.array([[1.0, dt], [0.0, 1.0]])
        covariance_position = (transition @ self._covariance_position @ transition.T
                               + white_acceleration_noise(self._q_position, dt))

        F = _IDENTITY_6.copy()
        F[:3, :3] = rotation_transition
        F[:3, 3:] = dt * left_jacobian_so3(rotation_increment)
        noise = white_acceleration_noise(self._q_orientation, dt)
        covariance_orientation = F @ self._covariance_orientation @ F.T
        for row in range(2):
            for column in range(2):
                covariance_orientation[3 * row:3 * row + 3, 3 * column:3 * column + 3] += (
                    noise[row, column] * _IDENTITY_3)
        return {
            'position': position,
            'velocity': velocity,
            'covariance_position': covariance_position,
            'R_world_object': R_world_object,
            'angular_velocity': self._angular_velocity.copy(),
            'covariance_orientation': covariance_orientation,
        }

    def _gravity_effect(self, t0, t1):
        """
        Return (dz, dvz) added by gravity between t0 and t1 for the declared flight interval.

        With u(s) = time spent in flight between flight start and s and G(s) its integral,
        dvz = -g (u(t1) - u(t0)) and dz = -g (G(t1) - G(t0) - u(t0) (t1 - t0)).
        """
        start, end = self._flight_start, self._flight_end
        if not math.isfinite(start):
            return 0.0, 0.0

        def time_in_flight(s):
            return min(max(s, start), end) - start

        def integral_of_time_in_flight(s):
            if s <= start:
                return 0.0
            if s <= end:
                return 0.5 * (s - start) ** 2
            return 0.5 * (end - start) ** 2 + (end - start) * (s - end)

        g = self.config.gravity
        u0 = time_in_flight(t0)
        velocity_change = -g * (time_in_flight(t1) - u0)
        displacement = -g * (integral_of_time_in_flight(t1) - integral_of_time_in_flight(t0)
                             - u0 * (t1 - t0))
        return displacement, velocity_change
