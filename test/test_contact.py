"""Contact detection (filtered normal force + geometry gates) and FT bias/weight compensation."""

from dual_arm_control.core.contact import (
    contact_geometry, ContactConfig, ContactDetector, FirstOrderLowPass, FtBiasEstimator,
    FtCompensationConfig, tool_weight_reading)
from dual_arm_control.core.exceptions import ConfigError, InputError
from dual_arm_control.core.geometry import rotation_exp
import mujoco
import numpy as np
import pytest


def step_response(time_constant, dt, duration):
    """Return (times, outputs) of a unit step fed to the low-pass at a fixed dt."""
    low_pass = FirstOrderLowPass(time_constant)
    steps = int(round(duration / dt))
    times = dt * np.arange(1, steps + 1)
    return times, np.array([low_pass.update(1.0, dt) for _ in range(steps)])


def test_low_pass_step_response_is_rate_independent():
    """At 1 ms and 5 ms the step response samples 1 - exp(-t / tau) exactly (to 1e-12)."""
    time_constant = 0.05
    times_fast, fast = step_response(time_constant, 0.001, 0.3)
    times_slow, slow = step_response(time_constant, 0.005, 0.3)
    np.testing.assert_allclose(fast, 1.0 - np.exp(-times_fast / time_constant), atol=1e-12)
    np.testing.assert_allclose(slow, 1.0 - np.exp(-times_slow / time_constant), atol=1e-12)
    np.testing.assert_allclose(fast[4::5], slow, atol=1e-12)
    # time constant respected: 63.2 % after tau
    assert fast[49] == pytest.approx(1.0 - np.exp(-1.0), abs=1e-12)
    # irregular steps land on the same curve
    low_pass = FirstOrderLowPass(time_constant)
    for dt in (0.001, 0.004, 0.0025, 0.0075, 0.01):
        value = low_pass.update(1.0, dt)
    assert value == pytest.approx(1.0 - np.exp(-0.025 / time_constant), abs=1e-12)


def face_setup(gap=0.0, tangential=(0.0, 0.0)):
    """Left pad facing the object's +y face: tool z = grasp normal = -y (world)."""
    R_world_tool = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    n_world_grasp = R_world_tool[:, 2]
    p_world_grasp = np.array([0.6, 0.08, 0.2])
    p_world_tool = (p_world_grasp - gap * n_world_grasp
                    - R_world_tool[:, :2] @ np.asarray(tangential))
    return p_world_tool, R_world_tool, p_world_grasp, n_world_grasp


def test_geometry_gates():
    config = ContactConfig()
    geometry = contact_geometry(*face_setup(gap=0.02, tangential=(0.03, -0.01)), config)
    assert geometry.normal_gap == pytest.approx(0.02, abs=1e-12)
    np.testing.assert_allclose(geometry.tangential_offset, (0.03, -0.01), atol=1e-12)
    assert geometry.within_reach
    assert not contact_geometry(*face_setup(gap=0.056), config).within_reach
    assert not contact_geometry(*face_setup(gap=-0.056), config).within_reach
    # pad half extents 0.075 / 0.05 m plus the 0.02 m margin
    assert contact_geometry(*face_setup(tangential=(0.094, 0.0)), config).within_reach
    assert not contact_geometry(*face_setup(tangential=(0.096, 0.0)), config).within_reach
    assert contact_geometry(*face_setup(tangential=(0.0, -0.069)), config).within_reach
    assert not contact_geometry(*face_setup(tangential=(0.0, -0.071)), config).within_reach


def detection_time(dt, force, config, geometry=None):
    """Return the first time the detector reports contact for a force step along the normal."""
    detector = ContactDetector(config)
    p_world_tool, R_world_tool, p_world_grasp, n_world_grasp = geometry or face_setup()
    for step in range(1, int(round(1.0 / dt)) + 1):
        state = detector.update(force * n_world_grasp, p_world_tool, R_world_tool,
                                p_world_grasp, n_world_grasp, dt)
        if state.in_contact:
            return step * dt, state
    return None, state


def test_detection_delay_matches_time_constant_at_both_rates():
    """A 30 N press is detected when 30 (1 - exp(-t / tau)) > 2 N: t = 3.45 ms for 50 ms."""
    config = ContactConfig()
    expected = -config.force_time_constant * np.log(1.0 - 2.0 / 30.0)
    for dt in (0.001, 0.002, 0.005):
        detected, state = detection_time(dt, 30.0, config)
        assert expected <= detected < expected + dt + 1e-12
        assert state.force_contact and state.normal_force > 2.0


def test_no_contact_without_force_or_geometry():
    config = ContactConfig()
    assert detection_time(0.005, 1.9, config)[0] is None
    detected, state = detection_time(0.005, 30.0, config, face_setup(gap=0.08))
    assert detected is None and state.force_contact and not state.in_contact
    # pulling (negative normal force) is never contact
    assert detection_time(0.005, -30.0, config)[0] is None


def test_hysteresis_on_release():
    """Contact holds down to 1.5 N and ends below it."""
    config = ContactConfig(force_time_constant=0.001)
    detector = ContactDetector(config)
    setup = face_setup()
    n_world = setup[3]
    states = []
    for force in (10.0,) * 20 + (1.6,) * 50 + (1.4,) * 50:
        states.append(detector.update(force * n_world, *setup, 0.001))
    assert states[19].in_contact and states[69].in_contact and not states[-1].in_contact
    detector.reset()
    assert not detector.update(1.6 * n_world, *setup, 0.001).force_contact


def random_rotation(rng):
    axis = rng.normal(size=3)
    return rotation_exp(axis / np.linalg.norm(axis) * rng.uniform(0.0, np.pi))


def test_tool_weight_matches_mujoco_force_torque_sensor():
    """The MuJoCo force/torque sensor on a 0.2 kg tool (CoM 0.035 m along z) reads our model."""
    xml = """
    <mujoco><option gravity="0 0 -9.81"/><worldbody>
      <body name="flange" pos="0 0 1"><site name="ft"/>
        <body name="tool"><geom type="sphere" size="0.02" mass="0.2" pos="0 0 0.035"/></body>
      </body></worldbody>
      <sensor><force site="ft"/><torque site="ft"/></sensor></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    config = FtCompensationConfig()
    rng = np.random.default_rng(1)
    for _ in range(5):
        R_world_sensor = random_rotation(rng)
        quat_wxyz = np.empty(4)
        mujoco.mju_mat2Quat(quat_wxyz, R_world_sensor.reshape(-1))
        model.body_quat[model.body('flange').id] = quat_wxyz
        mujoco.mj_forward(model, data)
        np.testing.assert_allclose(data.sensordata, tool_weight_reading(R_world_sensor, config),
                                   atol=1e-9)


def synthetic_reading(R_world_sensor, bias, config, f_world_pad=np.zeros(3)):
    """Net F/T reading: bias - (tool weight + pad wrench on the object about the sensor)."""
    p_sensor_contact = np.array([0.0, 0.0, 0.115])
    f_sensor_pad = R_world_sensor.T @ f_world_pad
    contact = np.concatenate((f_sensor_pad, np.cross(p_sensor_contact, f_sensor_pad)))
    return bias - (tool_weight_reading(R_world_sensor, config) + contact)


@pytest.mark.parametrize('dt', [0.001, 0.002, 0.005])
def test_bias_estimator_removes_bias_and_weight(dt):
    """
    The arm rotates during calibration: the current rotation is used (no one-cycle lag).

    After the 0.25 s window the residual at 8 new orientations is below 1e-9 N and a 12 N pad
    force is recovered in the world frame.
    """
    rng = np.random.default_rng(12)
    config = FtCompensationConfig()
    bias = np.array([3.0, -1.5, 7.0, 0.2, -0.1, 0.05])
    estimator = FtBiasEstimator(config)
    axis = np.array([0.3, 1.0, -0.2]) / np.linalg.norm([0.3, 1.0, -0.2])
    samples = 0
    result = None
    while result is None or not estimator.ready:
        R_world_sensor = rotation_exp(axis * 2.0 * samples * dt)
        result = estimator.update(synthetic_reading(R_world_sensor, bias, config),
                                  R_world_sensor, dt)
        assert not result.ready and not np.any(result.wrench_world)
        samples += 1
    assert samples == round(config.bias_duration / dt)
    np.testing.assert_allclose(estimator.bias, bias, atol=1e-9)
    f_world_pad = np.array([0.0, -12.0, 1.0])
    for _ in range(8):
        R_world_sensor = random_rotation(rng)
        free = estimator.update(synthetic_reading(R_world_sensor, bias, config),
                                R_world_sensor, dt)
        assert free.ready and np.max(np.abs(free.wrench_world)) < 1e-9
        pressed = estimator.update(synthetic_reading(R_world_sensor, bias, config, f_world_pad),
                                   R_world_sensor, dt)
        np.testing.assert_allclose(pressed.wrench_world[:3], f_world_pad, atol=1e-9)


def test_bias_window_is_time_weighted():
    """Two readings lasting 0.05 s and 0.20 s average with weights 1/5 and 4/5."""
    config = FtCompensationConfig(tool_mass=0.0)
    estimator = FtBiasEstimator(config)
    R_world_sensor = np.eye(3)
    estimator.update(np.full(6, 10.0), R_world_sensor, 0.05)
    assert not estimator.ready
    estimator.update(np.full(6, 20.0), R_world_sensor, 0.5)
    np.testing.assert_allclose(estimator.bias, np.full(6, 18.0), atol=1e-12)
    estimator.reset()
    assert not estimator.ready and estimator.bias is None


@pytest.mark.parametrize('kwargs', [
    {'force_threshold': 0.0}, {'force_hysteresis': 2.0}, {'force_time_constant': 0.0},
    {'contact_distance': -0.01}, {'pad_size': (0.15,)}, {'tangential_margin': -0.1},
])
def test_contact_config_rejects_invalid(kwargs):
    with pytest.raises(ConfigError):
        ContactConfig(**kwargs)


def test_runtime_inputs_rejected():
    with pytest.raises(InputError):
        FirstOrderLowPass(0.05).update(1.0, 0.0)
    with pytest.raises(InputError):
        FtBiasEstimator(FtCompensationConfig()).update(np.full(6, np.nan), np.eye(3), 0.001)
    with pytest.raises(ConfigError):
        FtCompensationConfig(bias_duration=0.0)
