"""Passive-DS torque controller on the pinocchio models of both arms (iiwa7 left, iiwa14 right)."""

from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.geometry import rotation_exp, rotation_log
from dual_arm_control.core.passive_control import (
    orientation_error_vector, passive_ds_damping_matrix, passive_ds_force, PassiveController,
    PassiveControllerConfig, saturated_torque)
from dual_arm_control.description.cell import arm_model, load_cell
import numpy as np
import pytest

DT = 0.001  # s, semi-implicit Euler step of the forward-dynamics simulation
ARMS = ('left', 'right')


@pytest.fixture(scope='module')
def cell():
    return load_cell()


@pytest.fixture(scope='module', params=ARMS)
def arm(request, cell):
    """Return (arm name, ArmModel, home posture) for each arm."""
    return request.param, arm_model(request.param, cell), cell.arm(request.param).q_home


def simulate(model, controller, q, dq, desired, seconds):
    """Run the closed loop at 1 kHz; yield (q, dq, command) before each step."""
    for _ in range(int(round(seconds / DT))):
        command = controller.torque_command(q, dq, *desired(q))
        yield q, dq, command
        dq = dq + DT * model.forward_dynamics(q, dq, command.torque)
        q = q + DT * dq


def test_damping_matrix_is_kronander_billard_and_continuous():
    along, across, blend = 150.0, 70.0, 0.01
    v_desired = np.array([0.3, -0.4, 0.5])
    matrix = passive_ds_damping_matrix(v_desired, along, across, blend)
    np.testing.assert_allclose(matrix, matrix.T)
    direction = v_desired / np.linalg.norm(v_desired)
    expected_along = across + (along - across) * 0.5 / (0.5 + blend ** 2)
    np.testing.assert_allclose(matrix @ direction, expected_along * direction, rtol=1e-12)
    assert expected_along == pytest.approx(along, rel=1e-3)
    orthogonal = np.cross(direction, [1.0, 0.0, 0.0])
    np.testing.assert_allclose(matrix @ orthogonal, across * orthogonal, atol=1e-12)
    np.testing.assert_allclose(passive_ds_damping_matrix(np.zeros(3), along, across, blend),
                               across * np.eye(3))
    tiny = passive_ds_damping_matrix([1e-6, 0.0, 0.0], along, across, blend)
    assert np.abs(tiny - across * np.eye(3)).max() < 1e-6
    config = PassiveControllerConfig(damping_along=along, damping_across=across)
    v = np.array([0.1, 0.2, -0.3])
    np.testing.assert_allclose(passive_ds_force(v, v_desired, config),
                               -matrix @ (v - v_desired), rtol=1e-12)


def test_orientation_error_vector_matches_rotation_log():
    rng = np.random.default_rng(0)
    for angle in (0.0, 1e-10, 1e-4, 0.5, 2.0, 3.0, np.pi - 1e-8, np.pi):
        axis = rng.normal(size=3)
        rotation = rotation_exp(angle * axis / np.linalg.norm(axis))
        np.testing.assert_allclose(orientation_error_vector(rotation), rotation_log(rotation),
                                   atol=1e-9)


def test_controller_uses_the_tool_point_twist(arm):
    # The damping must act on the velocity of the tool point itself (the sign of w x d
    # matters), which finite differences of tool_pose give independently.
    _, model, q_home = arm
    config = PassiveControllerConfig(free_orientation_stiffness=0.0,
                                     null_space_stiffness=(0.0,) * 7)
    controller = PassiveController(model, q_home, config)
    dq = np.array([0.3, -0.2, 0.4, 0.5, -0.6, 0.7, -0.8])
    step = 1e-7
    v_tool = (model.tool_pose(q_home + step * dq)[0]
              - model.tool_pose(q_home - step * dq)[0]) / (2 * step)
    command = controller.torque_command(q_home, dq, np.zeros(3), np.zeros(3), np.eye(3))
    np.testing.assert_allclose(command.task_wrench[:3], -config.damping_across * v_tool,
                               rtol=1e-6, atol=1e-6)


def test_tracking_a_linear_ds_converges_to_the_target(arm):
    name, model, q_home = arm
    controller = PassiveController(model, q_home)
    p_world_start, R_world_start = model.tool_pose(q_home)
    target = p_world_start + np.array([0.10, -0.05, -0.15])
    gain = 3.0  # 1/s

    def desired(q):
        return -gain * (model.tool_pose(q)[0] - target), np.zeros(3), R_world_start

    limits = model.torque_limits
    peak_ratio = 0.0
    for q, dq, command in simulate(model, controller, q_home.copy(), np.zeros(7), desired, 3.0):
        assert np.isfinite(command.torque).all() and not command.held
        peak_ratio = max(peak_ratio, float(np.max(np.abs(command.torque) / limits)))
    p_world_end, R_world_end = model.tool_pose(q)
    assert np.linalg.norm(p_world_end - target) < 0.005, name
    assert np.linalg.norm(rotation_log(R_world_start @ R_world_end.T)) < 0.02
    assert peak_ratio <= 1.0


def test_zero_desired_field_never_increases_energy(arm):
    # Passivity: with v_d = w_d = 0, gravity compensated by the same model, the stored energy
    # (kinetic, armature included, plus the orientation spring K_R theta^2 / 2, free-motion
    # K_R as no contact wrench is applied) must not grow.
    # The posture spring is off: projected through N it is not a potential force.
    _, model, q_home = arm
    config = PassiveControllerConfig(null_space_stiffness=(0.0,) * 7)
    controller = PassiveController(model, q_home, config)
    rng = np.random.default_rng(1)
    R_world_desired = model.tool_pose(q_home)[1] @ rotation_exp([0.2, -0.1, 0.15])

    def desired(q):
        return np.zeros(3), np.zeros(3), R_world_desired

    energies = []
    start_velocity = rng.uniform(-0.5, 0.5, 7)
    for q, dq, command in simulate(model, controller, q_home.copy(), start_velocity, desired,
                                   2.0):
        R_world_tool = model.tool_pose(q)[1]
        angle = np.linalg.norm(rotation_log(R_world_desired @ R_world_tool.T))
        energies.append(0.5 * dq @ model.mass_matrix(q) @ dq
                        + 0.5 * config.free_orientation_stiffness * angle ** 2)
        assert not command.saturated
    increments = np.diff(energies)
    assert increments.max() <= 1e-7   # J per 1 ms step: integration tolerance
    assert energies[-1] < 0.01 * energies[0]


def test_orientation_gains_are_the_free_ones_until_the_first_contact_wrench(arm):
    """Free gains in the reach; the contact gains from the first contact wrench on."""
    _, model, q_home = arm
    config = PassiveControllerConfig()
    assert config.free_orientation_stiffness > config.orientation_stiffness
    controller = PassiveController(model, q_home, config)
    dq = np.array([0.1, -0.2, 0.1, 0.3, -0.2, 0.4, -0.3])
    w_tool = model.tool_jacobian(q_home)[3:] @ dq
    R_world_tool = model.tool_pose(q_home)[1]
    turn = np.array([0.05, -0.02, 0.03])
    R_world_desired = rotation_exp(turn) @ R_world_tool
    contact_wrench = np.array([3.0, -2.0, 30.0, 0.2, -0.1, 0.05])
    free = (config.free_orientation_stiffness, config.free_angular_damping)
    touched = (config.orientation_stiffness, config.angular_damping)
    for wrench, (stiffness, damping) in ((None, free), (np.zeros(6), free),
                                         (contact_wrench, touched), (None, touched)):
        command = controller.torque_command(q_home, dq, np.zeros(3), np.zeros(3),
                                            R_world_desired, wrench)
        applied = np.zeros(3) if wrench is None else wrench[3:]
        np.testing.assert_allclose(command.task_wrench[3:] - applied,
                                   stiffness * turn - damping * w_tool, atol=1e-9)
    controller.start_episode()
    command = controller.torque_command(q_home, dq, np.zeros(3), np.zeros(3), R_world_desired)
    np.testing.assert_allclose(command.task_wrench[3:], free[0] * turn - free[1] * w_tool,
                               atol=1e-9)


def test_contact_wrench_is_pushed_with_its_own_sign(arm):
    # At rest on the posture and orientation targets, the command minus gravity is J^T w_c:
    # the robot applies +w_c on the object, as the QP asked.
    _, model, q_home = arm
    controller = PassiveController(model, q_home)
    R_world_tool = model.tool_pose(q_home)[1]
    contact_wrench = np.array([3.0, -2.0, 30.0, 0.2, -0.1, 0.05])
    command = controller.torque_command(q_home, np.zeros(7), np.zeros(3), np.zeros(3),
                                        R_world_tool, contact_wrench)
    expected = (model.gravity_torque(q_home)
                + model.tool_jacobian(q_home).T @ contact_wrench)
    np.testing.assert_allclose(command.torque, expected, atol=1e-9)


def test_elbow_lift_pushes_the_elbow_up_from_the_first_contact_wrench_on(arm):
    """
    No lift in the reach; once touched, a null-space torque that does positive work lifting it.

    The lift torque is N J_e,z^T F with N the damped projector, symmetric positive
    semi-definite, so J_e,z (its effect on the elbow's upward velocity) is >= 0.
    """
    _, model, q_home = arm
    config = PassiveControllerConfig(elbow_lift_force=20.0)
    lifting = PassiveController(model, q_home, config)
    plain = PassiveController(model, q_home, PassiveControllerConfig(elbow_lift_force=0.0))
    R_world_tool = model.tool_pose(q_home)[1]
    contact_wrench = np.array([3.0, -2.0, 30.0, 0.2, -0.1, 0.05])
    elbow_up = model.elbow_jacobian(q_home)[2]

    def lift_torque(wrench):
        commands = [controller.torque_command(q_home, np.zeros(7), np.zeros(3), np.zeros(3),
                                              R_world_tool, wrench)
                    for controller in (lifting, plain)]
        assert not any(command.saturated for command in commands)
        return commands[0].torque - commands[1].torque

    np.testing.assert_allclose(lift_torque(None), 0.0, atol=1e-12)
    lift = lift_torque(contact_wrench)
    assert elbow_up @ lift > 0.05 * config.elbow_lift_force * (elbow_up @ elbow_up)
    np.testing.assert_allclose(lift_torque(None), lift, atol=1e-12)
    lifting.start_episode()
    plain.start_episode()
    np.testing.assert_allclose(lift_torque(None), 0.0, atol=1e-12)


def test_null_space_torque_does_no_work_on_tool_motion(arm):
    """
    The projected torque leaves the tool alone: J tau is what leaks through the damped projector.

    At the posture target only the null-space damping acts, tau_in = -D dq; the projector
    N = I - J^T (J J^T + d^2 I)^-1 J lets d^2 / sigma_min^2 of J tau_in through (about 1.5e-4
    here, sigma_min of J about 0.08), so 1e-3 is a bound with margin, not a tuned figure.
    """
    _, model, q_home = arm
    rng = np.random.default_rng(2)
    q = q_home + rng.uniform(-0.3, 0.3, 7)
    controller = PassiveController(model, q)
    jacobian = model.tool_jacobian(q)
    dq = rng.normal(size=7)
    torque_in = -controller.config.null_space_damping * dq
    torque = controller.null_space_torque(jacobian, q, dq)
    assert np.abs(jacobian @ torque).max() < 1e-3 * np.abs(jacobian @ torque_in).max()
    assert np.abs(torque).max() > 0.05 * np.abs(torque_in).max()


def test_saturation_scales_the_control_torque_within_limits():
    rng = np.random.default_rng(3)
    limits = np.array([176.0, 176.0, 110.0, 110.0, 110.0, 40.0, 40.0])
    for _ in range(100):
        gravity = rng.uniform(-0.5, 0.5, 7) * limits
        control = rng.normal(size=7) * 300.0
        torque, saturated = saturated_torque(gravity, control, limits)
        assert np.all(np.abs(torque) <= limits + 1e-9)
        if saturated:
            factor = (torque - gravity) @ control / (control @ control)
            assert 0.0 <= factor < 1.0
            np.testing.assert_allclose(torque - gravity, factor * control, atol=1e-9)
            assert np.isclose(np.abs(torque), limits).any()
        else:
            np.testing.assert_allclose(torque, gravity + control)


def test_large_command_saturates_instead_of_exceeding_limits(arm):
    _, model, q_home = arm
    controller = PassiveController(model, q_home)
    R_world_tool = model.tool_pose(q_home)[1]
    command = controller.torque_command(q_home, np.zeros(7), [50.0, -40.0, 30.0],
                                        [20.0, 0.0, 0.0], R_world_tool)
    assert command.saturated and command.status == 'saturated'
    assert np.all(np.abs(command.torque) <= model.torque_limits + 1e-9)


@pytest.mark.parametrize('field', ['q', 'dq', 'v_world_desired', 'R_world_desired',
                                   'contact_wrench'])
def test_non_finite_input_returns_the_hold_torque(arm, field):
    _, model, q_home = arm
    hold_damping = np.array([10.0, 10.0, 8.0, 8.0, 4.0, 2.0, 2.0])
    controller = PassiveController(model, q_home,
                                   PassiveControllerConfig(hold_damping=tuple(hold_damping)))
    dq = np.full(7, 0.1)
    R_world_tool = model.tool_pose(q_home)[1]
    controller.torque_command(q_home, dq, np.zeros(3), np.zeros(3), R_world_tool)
    inputs = {'q': q_home.copy(), 'dq': dq.copy(), 'v_world_desired': np.zeros(3),
              'w_world_desired': np.zeros(3), 'R_world_desired': R_world_tool.copy(),
              'contact_wrench': np.zeros(6)}
    inputs[field] = np.full_like(inputs[field], np.nan)
    command = controller.torque_command(**inputs)
    assert command.held and field in command.status
    assert np.isfinite(command.torque).all()
    assert np.all(np.abs(command.torque) <= model.torque_limits)
    expected_damping = 0.0 if field == 'dq' else hold_damping * dq
    np.testing.assert_allclose(command.torque,
                               model.gravity_torque(q_home) - expected_damping, atol=1e-9)


def test_invalid_config_is_refused():
    with pytest.raises(ConfigError, match='damping_along'):
        PassiveControllerConfig(damping_along=0.0)
    with pytest.raises(ConfigError, match='null_space_stiffness'):
        PassiveControllerConfig(null_space_stiffness=(1.0,) * 6)


def joint_speed_peak(model, q_home, config, speed=1.5, seconds=0.6):
    """Return the largest |dq| / limit of a fast DS run (speed [m/s], forward and down)."""
    controller = PassiveController(model, q_home, config)
    R_world_start = model.tool_pose(q_home)[1]
    velocity = speed * np.array([0.6, 0.0, -0.8])

    def desired(q):
        return velocity, np.zeros(3), R_world_start

    peak = 0.0
    for _, dq, command in simulate(model, controller, q_home.copy(), np.zeros(7), desired,
                                   seconds):
        assert np.isfinite(command.torque).all()
        peak = max(peak, float(np.max(np.abs(dq) / model.velocity_limits)))
    return peak


def test_the_joint_speed_brake_keeps_the_joints_near_their_limits(arm):
    """A tool driven at 1.5 m/s from home exceeds the iiwa's joint speeds unless braked."""
    name, model, q_home = arm
    unbraked = joint_speed_peak(model, q_home,
                                PassiveControllerConfig(joint_speed_brake_time=0.0))
    braked = joint_speed_peak(model, q_home, PassiveControllerConfig(
        joint_speed_brake_time=0.002, joint_speed_onset=0.8))
    assert unbraked > 1.3, name
    assert braked <= 1.05, name
