"""
Per-arm contact detection from the pad force and the pad/face geometry, and FT bias estimation.

Force-torque convention (matches MuJoCo's force/torque sensors, checked on a hanging tool): the
raw reading is the wrench the sensor applies to the tool, in the sensor frame, about the sensor
origin. A resting tool therefore reads minus its weight, and after removing the bias and the tool
weight the remainder is, quasi-statically, the wrench the pad applies to the object. A sensor
that reports the opposite sign (load applied to the sensor) must be negated by its driver.

The detection follows the authors' setup: normal force above 2 N and the tool
within 0.055 m of its face along the normal, plus a tangential gate that the reference computed
but never used. Filters use time constants in seconds, so the behaviour does not depend on the
update rate.
"""

from dataclasses import dataclass

from dual_arm_control.core.exceptions import InputError
from dual_arm_control.core.geometry import cross3, vector_norm
from dual_arm_control.core.settings import check_settings, setting
from dual_arm_control.core.validation import check_range, finite_array
import numpy as np


def _checked_dt(dt):
    """Return dt as a float, raising InputError unless it is finite and > 0 (s)."""
    dt = float(dt)
    if not np.isfinite(dt) or dt <= 0.0:
        raise InputError(f'dt = {dt:g} s must be finite and > 0')
    return dt


class FirstOrderLowPass:
    """
    First-order low-pass y_dot = (u - y) / tau, discretised exactly for a held input.

    y <- y + (1 - exp(-dt / tau)) (u - y): a step response samples 1 - exp(-t / tau) at every
    rate. The state starts at `initial` (zero force before any contact).
    """

    def __init__(self, time_constant, initial=0.0):
        check_range('time_constant', time_constant, 0.0, unit='s', low_open=True)
        self._time_constant = float(time_constant)
        self._initial = initial
        self.value = initial

    def reset(self):
        """Return the output to its initial value."""
        self.value = self._initial

    def update(self, sample, dt):
        """Advance by dt seconds with the input held at sample; return the filtered value."""
        blend = -np.expm1(-_checked_dt(dt) / self._time_constant)
        self.value = self.value + blend * (sample - self.value)
        return self.value


@dataclass(frozen=True)
class ContactConfig:
    """Thresholds of the per-arm contact detector."""

    force_threshold: float = setting(
        2.0, 'Filtered normal force above which the pad presses (reference 2 N).',
        unit='N', low=0, low_open=True)
    force_hysteresis: float = setting(
        0.5, 'Contact by force persists until the filtered normal force drops below '
        'force_threshold - force_hysteresis; less than force_threshold.', unit='N', low=0)
    force_time_constant: float = setting(
        0.05, 'Low-pass on the normal force (reference: per-cycle 0.9 at 200 Hz = 0.047 s).',
        unit='s', low=0, low_open=True)
    contact_distance: float = setting(
        0.055, '|normal gap| between tool origin and face below which the pad is at the face '
        '(reference 0.055 m).', unit='m', low=0, low_open=True)
    pad_size: tuple = setting(
        (0.15, 0.10), 'Pad extent along tool x and tool y (0.15 x 0.10 m).',
        unit='m', low=0, low_open=True, size=2)
    tangential_margin: float = setting(
        0.02, "The face's grasp point may lie this far outside the pad.", unit='m', low=0)

    def __post_init__(self):
        check_settings(self)
        check_range('force_hysteresis', self.force_hysteresis, 0.0, self.force_threshold,
                    unit='N', high_open=True)


@dataclass(frozen=True)
class ContactGeometry:
    """
    Where a face's grasp point lies relative to the tool.

    Fields:
        normal_gap: m; (p_grasp - p_tool) . n, positive while the pad is outside the face.
        tangential_offset: (2,) m; grasp point relative to the tool along tool x and tool y.
        within_reach: True iff |normal_gap| <= contact_distance and the offset lies within the
            pad grown by tangential_margin.

    """

    normal_gap: float
    tangential_offset: tuple
    within_reach: bool


def contact_geometry(p_world_tool, R_world_tool, p_world_grasp, n_world_grasp, config):
    """
    Return the ContactGeometry of one pad against its face (the geometry gate).

    p_world_tool: (3,) m, tool (pad centre) origin. R_world_tool: (3, 3). p_world_grasp: (3,) m,
    grasp point on the face. n_world_grasp: (3,) grasp normal pointing into the object.
    """
    p_world_tool = finite_array('p_world_tool', p_world_tool, (3,))
    R_world_tool = finite_array('R_world_tool', R_world_tool, (3, 3))
    p_world_grasp = finite_array('p_world_grasp', p_world_grasp, (3,))
    n_world_grasp = finite_array('n_world_grasp', n_world_grasp, (3,))
    norm = vector_norm(n_world_grasp)
    if norm < 1e-9:
        raise InputError('n_world_grasp has no direction')
    p_world_offset = p_world_grasp - p_world_tool
    normal_gap = float(p_world_offset @ n_world_grasp / norm)
    tangential_offset = tuple((R_world_tool.T @ p_world_offset)[:2].tolist())
    within_reach = abs(normal_gap) <= config.contact_distance and all(
        abs(offset) <= 0.5 * size + config.tangential_margin
        for offset, size in zip(tangential_offset, config.pad_size))
    return ContactGeometry(normal_gap, tangential_offset, within_reach)


@dataclass(frozen=True)
class ContactState:
    """
    Contact state of one arm after an update.

    Fields:
        in_contact: force_contact and geometry.within_reach: the pad presses on its face.
        force_contact: the filtered normal force is above threshold (with hysteresis).
        normal_force: N, low-passed F . n (pad force on the object along the grasp normal).
        geometry: ContactGeometry of the pad against its face.

    """

    in_contact: bool
    force_contact: bool
    normal_force: float
    geometry: ContactGeometry


class ContactDetector:
    """Contact state of one arm: filtered normal force with hysteresis, gated by geometry."""

    def __init__(self, config):
        self._config = config
        self._normal_force = FirstOrderLowPass(config.force_time_constant)
        self._force_contact = False

    def reset(self):
        """Forget the filter state and the force latch (no contact)."""
        self._normal_force.reset()
        self._force_contact = False

    def update(self, f_world_pad, p_world_tool, R_world_tool, p_world_grasp, n_world_grasp,
               dt):
        """
        Advance by dt seconds and return the ContactState.

        f_world_pad: (3,) N, force the pad applies to the object in the world frame (the
        compensated FT force rotated to world). Other arguments as in contact_geometry.
        """
        f_world_pad = finite_array('f_world_pad', f_world_pad, (3,))
        geometry = contact_geometry(p_world_tool, R_world_tool, p_world_grasp, n_world_grasp,
                                    self._config)
        n_world = np.asarray(n_world_grasp, dtype=float)
        normal_force = float(self._normal_force.update(
            f_world_pad @ n_world / vector_norm(n_world), dt))
        if self._force_contact:
            release_level = self._config.force_threshold - self._config.force_hysteresis
            self._force_contact = normal_force > release_level
        else:
            self._force_contact = normal_force > self._config.force_threshold
        return ContactState(in_contact=self._force_contact and geometry.within_reach,
                            force_contact=self._force_contact, normal_force=normal_force,
                            geometry=geometry)


@dataclass(frozen=True)
class FtCompensationConfig:
    """Tool load and bias window of the FT compensation (the authors' setup)."""

    tool_mass: float = setting(0.2, 'Mass below the sensor (0.2 kg).', unit='kg', low=0)
    p_sensor_tool_com: tuple = setting(
        (0.0, 0.0, 0.035), 'Tool centre of mass in the sensor frame (0, 0, 0.035).',
        unit='m', size=3)
    gravity_world: tuple = setting(
        (0.0, 0.0, -9.81), 'Gravity in the world frame.', unit='m/s^2', size=3)
    bias_duration: float = setting(
        0.25, 'The bias is the time-weighted mean over the first bias_duration seconds of '
        'weight-compensated readings (reference: 50 samples at 200 Hz = 0.25 s).',
        unit='s', low=0, low_open=True)

    def __post_init__(self):
        check_settings(self)


def tool_weight_reading(R_world_sensor, config):
    """
    Return the (6,) reading [force; torque] a resting tool produces, sensor frame (N, N m).

    The sensor holds the tool against gravity: force = -m R^T g, torque = p_com x force, both
    with the CURRENT sensor rotation R_world_sensor (3, 3) (no one-cycle lag).
    """
    R_world_sensor = finite_array('R_world_sensor', R_world_sensor, (3, 3))
    force = -config.tool_mass * (R_world_sensor.T @ np.asarray(config.gravity_world))
    torque = cross3(np.asarray(config.p_sensor_tool_com), force)
    return np.concatenate((force, torque))


@dataclass(frozen=True)
class CompensatedWrench:
    """
    Result of one FT update.

    Fields:
        ready: the bias window is complete; the wrenches are zero until then.
        wrench_sensor: (6,) [N, N m]; pad wrench on the object in the sensor frame, about the
            sensor origin.
        wrench_world: (6,) the same wrench with force and torque axes rotated to world.

    """

    ready: bool
    wrench_sensor: np.ndarray
    wrench_world: np.ndarray


class FtBiasEstimator:
    """Estimate the FT bias over the first bias_duration seconds, then compensate readings."""

    def __init__(self, config):
        self._config = config
        self.reset()

    def reset(self):
        """Restart the bias window (e.g. after re-taring with the pad free)."""
        self._weighted_sum = np.zeros(6)
        self._elapsed = 0.0
        self._bias = None

    @property
    def ready(self):
        """Return True once the bias window is complete."""
        return self._bias is not None

    @property
    def bias(self):
        """Return the (6,) bias as it appears in the raw readings, or None while estimating."""
        return None if self._bias is None else -self._bias

    def update(self, raw_wrench_sensor, R_world_sensor, dt):
        """
        Feed one reading (6,) [N, N m] taken with rotation R_world_sensor; return the result.

        The reading follows the Net F/T convention of the bridge's ft_wrench topic: the wrench
        the tool applies to the sensor, in the sensor frame. It is negated here into the wrench
        the sensor applies to the tool, the convention of tool_weight_reading.

        dt (s) is the time this sample represents (time since the previous reading). While the
        window is open the weight-compensated reading is accumulated with weight dt (the last
        sample only for the part inside the window) and zeros are returned with ready False.
        """
        raw_wrench_sensor = finite_array('raw_wrench_sensor', raw_wrench_sensor, (6,))
        dt = _checked_dt(dt)
        R_world_sensor = finite_array('R_world_sensor', R_world_sensor, (3, 3))
        unloaded = -raw_wrench_sensor - tool_weight_reading(R_world_sensor, self._config)
        if self._bias is None:
            weight = min(dt, self._config.bias_duration - self._elapsed)
            self._weighted_sum += weight * unloaded
            self._elapsed += weight
            if self._elapsed >= self._config.bias_duration * (1.0 - 1e-9):
                self._bias = self._weighted_sum / self._elapsed
            return CompensatedWrench(False, np.zeros(6), np.zeros(6))
        wrench_sensor = unloaded - self._bias
        wrench_world = np.concatenate((R_world_sensor @ wrench_sensor[:3],
                                       R_world_sensor @ wrench_sensor[3:]))
        return CompensatedWrench(True, wrench_sensor, wrench_world)
