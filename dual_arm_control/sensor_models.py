"""
Sensor models of the twin, as a scenario sets them: motion capture of the object and F/T sensors.

The twin (sim_bridge.twin) draws its noise, bias, latency and dropouts from these.
"""

from dataclasses import dataclass, field, fields

from dual_arm_control.core.validation import check_range, frozen_vector
import numpy as np

# Sample times are compared with this tolerance, the twin's clock being a sum of steps [s].
SAMPLE_TIME_TOLERANCE = 1e-9


@dataclass(frozen=True)
class MocapConfig:
    """
    Motion-capture model of the twin.

    Fields: rate_hz: sampling rate on the sim clock [Hz]; latency: delay from sampling to
    delivery [s]; position_noise: Gaussian standard deviation per axis [m];
    orientation_noise: Gaussian standard deviation of the rotation vector per axis [rad];
    dropout_probability: chance that a sample is lost [-]; dropout_start [s] and
    dropout_duration [s]: every sample taken in [start, start + duration) is lost (a marker
    occlusion; duration 0: none); outlier_time [s] and outlier_jump [m]: the first sample
    taken at or after outlier_time is displaced by outlier_jump along world y, the squeeze
    axis (outlier_time 0: none). The fault campaign (dual_arm_faults) places these.
    """

    rate_hz: float = 200.0
    latency: float = 0.005
    position_noise: float = 0.0005
    orientation_noise: float = 0.005
    dropout_probability: float = 0.0
    dropout_start: float = 0.0
    dropout_duration: float = 0.0
    outlier_time: float = 0.0
    outlier_jump: float = 0.0

    def __post_init__(self):
        check_range('rate_hz', self.rate_hz, 1.0, 1000.0, 'Hz')
        check_range('latency', self.latency, 0.0, 1.0, 's')
        check_range('position_noise', self.position_noise, 0.0, 0.1, 'm')
        check_range('orientation_noise', self.orientation_noise, 0.0, 0.5, 'rad')
        check_range('dropout_probability', self.dropout_probability, 0.0, 1.0, '',
                    high_open=True)
        check_range('dropout_start', self.dropout_start, 0.0, 1.0e6, 's')
        check_range('dropout_duration', self.dropout_duration, 0.0, 1.0e6, 's')
        check_range('outlier_time', self.outlier_time, 0.0, 1.0e6, 's')
        check_range('outlier_jump', self.outlier_jump, -1.0, 1.0, 'm')

    def occluded(self, t):
        """Return True if a sample taken at sim time t [s] falls in the dropout window."""
        t = t + SAMPLE_TIME_TOLERANCE
        return self.dropout_start <= t < self.dropout_start + self.dropout_duration

    def outlier_offset(self, t):
        """Return the displacement (3,) [m] of a sample taken at t (non-zero: the outlier)."""
        if self.outlier_time > 0.0 and \
                self.outlier_time <= t + SAMPLE_TIME_TOLERANCE < \
                self.outlier_time + 1.0 / self.rate_hz:
            return np.array([0.0, self.outlier_jump, 0.0])
        return np.zeros(3)


@dataclass(frozen=True)
class FtConfig:
    """
    Force-torque sensor model of the twin (same for both grabbers).

    Fields: force_noise [N] and torque_noise [N m]: Gaussian standard deviation per axis
    (defaults: ATI Mini45-class resolution); force_bias (3,) [N] and torque_bias (3,) [N m]:
    constant offsets in the sensor frame.
    """

    force_noise: float = 0.05
    torque_noise: float = 0.002
    force_bias: np.ndarray = (0.0, 0.0, 0.0)
    torque_bias: np.ndarray = (0.0, 0.0, 0.0)

    def __post_init__(self):
        check_range('force_noise', self.force_noise, 0.0, 100.0, 'N')
        check_range('torque_noise', self.torque_noise, 0.0, 10.0, 'N m')
        object.__setattr__(self, 'force_bias',
                           frozen_vector('force_bias', self.force_bias, 3, 'N'))
        object.__setattr__(self, 'torque_bias',
                           frozen_vector('torque_bias', self.torque_bias, 3, 'N m'))


@dataclass(frozen=True)
class SensorConfig:
    """Sensor models of the twin: motion capture of the object and the two FT sensors."""

    mocap: MocapConfig = field(default_factory=MocapConfig)
    ft: FtConfig = field(default_factory=FtConfig)


def read_sensor_config(reader, data):
    """Return the SensorConfig of a scenario file's mapping data (defaults without the block)."""
    entry = reader.mapping(data, 'sensors', optional=True)
    if entry is None:
        return SensorConfig()
    reader.check_keys(entry, ('mocap', 'ft'), 'sensors')
    mocap_entry = reader.mapping(entry, 'mocap', 'sensors', optional=True) or {}
    mocap_keys = [item.name for item in fields(MocapConfig)]
    reader.check_keys(mocap_entry, mocap_keys, 'sensors.mocap')
    mocap = reader.build('sensors.mocap', MocapConfig, **{
        key: reader.number(mocap_entry, key, 'sensors.mocap') for key in mocap_entry})
    ft_entry = reader.mapping(entry, 'ft', 'sensors', optional=True) or {}
    reader.check_keys(ft_entry, ('force_noise', 'torque_noise', 'force_bias', 'torque_bias'),
                      'sensors.ft')
    ft_values = {}
    for key in ft_entry:
        if key.endswith('_bias'):
            unit = 'N' if key == 'force_bias' else 'N m'
            ft_values[key] = reader.vector(ft_entry, key, (3,), 'sensors.ft', unit)
        else:
            ft_values[key] = reader.number(ft_entry, key, 'sensors.ft')
    return SensorConfig(mocap, reader.build('sensors.ft', FtConfig, **ft_values))
