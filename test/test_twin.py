"""The MuJoCo twin in process: holding, falling, contacts, sensors, determinism, input checks."""

import dataclasses

from dual_arm_control.core.exceptions import ConfigError, InputError
from dual_arm_control.core.geometry import quat_xyzw_to_matrix, rotation_log
from dual_arm_control.core.wrench_qp import WrenchQPConfig
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.runtime.node_settings import FRI_PERIODS
from dual_arm_control.scenario import load_scenario, Perturbation
import mujoco
import numpy as np
import pinocchio as pin
import pytest
from sim_bridge.scene import pad_torsion_arm
from sim_bridge.twin import DualArmTwin

GRAVITY = 9.81          # [m/s^2]
TOOL_MASS = 0.2         # [kg]
TOOL_COM = 0.035        # [m] from the sensor along flange z


@pytest.fixture(scope='module')
def cell():
    return load_cell()


@pytest.fixture(scope='module')
def hold_scenario(cell):
    return load_scenario('hold', cell)


def hold_all(twin):
    return {arm: twin.hold_torques(arm) for arm in twin.arms}


def tool_positions(twin):
    return {arm: twin.tool_pose(arm)[0] for arm in twin.arms}


def test_hold_torques_keep_tools_still(cell, hold_scenario):
    twin = DualArmTwin(hold_scenario, cell)
    start = tool_positions(twin)
    drift = 0.0
    while twin.time < 5.0 - 1e-9:
        twin.step(hold_all(twin))
        drift = max(drift, max(np.linalg.norm(twin.tool_pose(arm)[0] - start[arm])
                               for arm in twin.arms))
    print(f'hold_torques: worst tool drift over 5 s = {drift:.3g} m')
    assert drift < 1e-3, f'tool moved {drift:.4f} m under the safety hold (limit 0.001 m)'


@pytest.mark.parametrize('fri_period', FRI_PERIODS)
def test_the_safety_hold_brings_the_arms_back_to_where_the_commands_stopped(
        cell, hold_scenario, fri_period):
    """A KUKA holds its position on command loss: stiffness + damping, stable at every period."""
    twin = DualArmTwin(hold_scenario, cell, fri_period=fri_period)
    stops = {arm: twin.joint_state(arm).position for arm in twin.arms}
    stop_tools = tool_positions(twin)
    for arm in twin.arms:
        twin.data.qpos[twin.index.arms[arm].qpos] += 0.02
    speed_after = 0.0
    while twin.time < 1.0 - 1e-9:
        report = twin.step({arm: twin.hold_torques(arm, stops[arm]) for arm in twin.arms})
        assert not any(report.clamped.values())
        if twin.time >= 0.3 - 1e-9:
            speed_after = max(speed_after, *(np.linalg.norm(twin.tool_twist(arm)[0])
                                             for arm in twin.arms))
    back = max(np.linalg.norm(twin.tool_pose(arm)[0] - stop_tools[arm]) for arm in twin.arms)
    print(f'FRI {fri_period * 1e3:g} ms: tool speed from 0.3 s on <= {speed_after:.3f} m/s, '
          f'{back * 1e3:.2f} mm from the stop pose after 1 s')
    assert speed_after < 0.05
    assert back < 1e-3


def test_pinocchio_gravity_keeps_tools_still(cell, hold_scenario):
    twin = DualArmTwin(hold_scenario, cell)
    models = {arm: arm_model(arm, cell) for arm in twin.arms}
    start = tool_positions(twin)
    drift = 0.0
    while twin.time < 5.0 - 1e-9:
        twin.step({arm: models[arm].gravity_torque(twin.joint_state(arm).position)
                   for arm in twin.arms})
        drift = max(drift, max(np.linalg.norm(twin.tool_pose(arm)[0] - start[arm])
                               for arm in twin.arms))
    print(f'pinocchio gravity: worst tool drift over 5 s = {drift:.3g} m')
    assert drift < 1e-3, f'tool moved {drift:.4f} m under pinocchio gravity compensation'


def test_zero_torque_lets_the_arms_fall(cell, hold_scenario):
    twin = DualArmTwin(hold_scenario, cell)
    start = tool_positions(twin)
    zero = {arm: np.zeros(7) for arm in twin.arms}
    while twin.time < 1.0 - 1e-9:
        twin.step(zero)
    drop = {arm: start[arm][2] - twin.tool_pose(arm)[0][2] for arm in twin.arms}
    print(f'tool drop after 1 s with zero torque: {drop} m')
    for arm, value in drop.items():
        assert value > 0.05, f'{arm} tool dropped only {value:.4f} m in 1 s with zero torque'


def test_ft_sensor_at_rest_reads_the_grabber_weight(cell, hold_scenario):
    twin = DualArmTwin(hold_scenario, cell)
    twin.step(hold_all(twin))
    for arm in twin.arms:
        index = twin.index.arms[arm]
        R_world_sensor = twin.data.site_xmat[index.sensor_site].reshape(3, 3)
        weight_world = np.array([0.0, 0.0, -TOOL_MASS * GRAVITY])
        expected_force = R_world_sensor.T @ weight_world
        expected_torque = np.cross([0.0, 0.0, TOOL_COM], expected_force)
        force, torque = twin.ft_wrench_true(arm)
        assert force == pytest.approx(expected_force, abs=1e-6), \
            f'{arm}: FT force {force} N, expected the grabber weight {expected_force} N'
        assert torque == pytest.approx(expected_torque, abs=1e-6)
        noisy_force, _ = twin.ft_wrench(arm)
        sigma = hold_scenario.sensors.ft.force_noise
        assert np.all(np.abs(noisy_force - force) < 5.0 * sigma)


def test_dropped_cube_settles_and_mocap_tracks_it(cell):
    scenario = load_scenario('cube_drop', cell)
    twin = DualArmTwin(scenario, cell, fri_period=0.001)
    mocap = scenario.sensors.mocap
    truth = {0: twin.object_pose()}
    samples = []
    while twin.time < 1.5 - 1e-9:
        twin.step(hold_all(twin))
        truth[round(twin.time / twin.physics_timestep)] = twin.object_pose()
        for sample in twin.mocap_samples():
            delay = twin.time - sample.stamp
            assert mocap.latency - 1e-9 <= delay < mocap.latency + twin.fri_period + 1e-9, \
                f'sample stamped {sample.stamp} s delivered at {twin.time} s'
            samples.append(sample)
    p_world, _ = twin.object_pose()
    v_world, w_world = twin.object_twist()
    expected_height = 0.22 + 0.10
    print(f'cube after 1.5 s: z = {p_world[2]:.5f} m, speed {np.linalg.norm(v_world):.2e} m/s')
    assert p_world[2] == pytest.approx(expected_height, abs=0.002)
    assert np.linalg.norm(v_world) < 1e-3 and np.linalg.norm(w_world) < 1e-2
    position_errors = []
    rotation_errors = []
    for sample in samples:
        p_true, quat_true = truth[round(sample.stamp / twin.physics_timestep)]
        position_errors.append(sample.p_world - p_true)
        rotation_errors.append(rotation_log(
            quat_xyzw_to_matrix(sample.quat_xyzw) @ quat_xyzw_to_matrix(quat_true).T))
    position_errors = np.array(position_errors)
    rotation_errors = np.array(rotation_errors)
    print(f'{len(samples)} mocap samples; position error std {position_errors.std():.2e} m, '
          f'max {np.abs(position_errors).max():.2e} m; rotation error std '
          f'{rotation_errors.std():.2e} rad')
    assert np.abs(position_errors).max() < 4.0 * mocap.position_noise
    assert np.abs(rotation_errors).max() < 4.0 * mocap.orientation_noise
    assert position_errors.std() == pytest.approx(mocap.position_noise, rel=0.2)
    assert rotation_errors.std() == pytest.approx(mocap.orientation_noise, rel=0.2)
    due = {index for index in range(int(1.5 * mocap.rate_hz) + 1)
           if index / mocap.rate_hz + mocap.latency <= 1.5 + 1e-9}
    delivered = [round(sample.stamp * mocap.rate_hz) for sample in samples]
    assert len(set(delivered)) == len(delivered) and set(delivered) <= due
    assert [sample.stamp for sample in samples] == sorted(sample.stamp for sample in samples)
    dropped = len(due) - len(delivered)
    assert 0 < dropped < 4 * len(due) * mocap.dropout_probability, \
        f'{dropped} of {len(due)} samples dropped at p = {mocap.dropout_probability}'


def run_trajectory(twin, steps):
    """Step with hold torques plus a seeded excitation; return every observable as arrays."""
    excitation = np.random.default_rng(5).uniform(-5.0, 5.0, (steps, 2, 7))
    record = []
    for step in range(steps):
        torques = hold_all(twin)
        twin.step({arm: torques[arm] + excitation[step, i] for i, arm in enumerate(twin.arms)})
        row = [twin.object_pose()[0], twin.object_pose()[1]]
        for arm in twin.arms:
            state = twin.joint_state(arm)
            row += [state.position, state.velocity, state.measured_torque, *twin.ft_wrench(arm)]
        row += [np.concatenate((sample.p_world, sample.quat_xyzw, [sample.stamp]))
                for sample in twin.mocap_samples()]
        record.append(np.concatenate(row))
    return record


def test_same_seed_gives_bit_identical_runs(cell):
    scenario = dataclasses.replace(
        load_scenario('cube_drop', cell),
        perturbations=(Perturbation(0.3, [0.01, 0.0, 0.0]),))
    first = run_trajectory(DualArmTwin(scenario, cell), 400)
    twin = DualArmTwin(scenario, cell)
    second = run_trajectory(twin, 400)
    twin.reset()
    third = run_trajectory(twin, 400)
    assert all(np.array_equal(a, b) for a, b in zip(first, second))
    assert all(np.array_equal(a, b) for a, b in zip(first, third))
    other_seed = DualArmTwin(dataclasses.replace(scenario, seed=scenario.seed + 1), cell)
    assert not all(np.array_equal(a, b)
                   for a, b in zip(first, run_trajectory(other_seed, 400)))


def test_a_reset_with_a_seed_reseeds_the_sensor_noise(cell):
    """The soak's episodes: /sim/reset with seed s gives the run of a scenario whose seed is s."""
    scenario = load_scenario('cube_drop', cell)
    reference = run_trajectory(DualArmTwin(dataclasses.replace(scenario, seed=77), cell), 200)
    twin = DualArmTwin(scenario, cell)
    own = run_trajectory(twin, 200)
    twin.reset(seed=77)
    assert twin.seed == 77
    reseeded = run_trajectory(twin, 200)
    assert all(np.array_equal(a, b) for a, b in zip(reference, reseeded))
    assert not all(np.array_equal(a, b) for a, b in zip(own, reseeded))
    twin.reset()
    assert twin.seed == scenario.seed
    assert all(np.array_equal(a, b) for a, b in zip(own, run_trajectory(twin, 200)))


def test_state_snapshot_restores_the_run(cell, hold_scenario):
    twin = DualArmTwin(load_scenario('cube_drop', cell), cell)
    run_trajectory(twin, 50)
    snapshot = twin.state()
    first = run_trajectory(twin, 100)
    twin.set_state(snapshot)
    second = run_trajectory(twin, 100)
    assert all(np.array_equal(a, b) for a, b in zip(first, second))


def test_invalid_torques_raise_and_change_nothing(cell, hold_scenario):
    twin = DualArmTwin(hold_scenario, cell)
    twin.step(hold_all(twin))
    before = twin.state()
    bad_commands = [
        {'left': np.full(7, np.nan), 'right': np.zeros(7)},
        {'left': np.zeros(7), 'right': np.array([0, 0, 0, np.inf, 0, 0, 0])},
        {'left': np.zeros(6), 'right': np.zeros(7)},
        {'left': np.zeros(7)},
        [np.zeros(7), np.zeros(7)],
    ]
    for command in bad_commands:
        with pytest.raises(InputError):
            twin.step(command)
        after = twin.state()
        assert twin.time == before.tick * twin.physics_timestep
        assert np.array_equal(after.physics, before.physics)
        assert np.array_equal(after.ctrl, before.ctrl)


def test_out_of_limit_torque_is_clamped_and_reported(cell, hold_scenario):
    twin = DualArmTwin(hold_scenario, cell)
    torques = hold_all(twin)
    limits = twin.torque_limits('left')
    torques['left'][0] = 2.0 * limits[0]
    torques['left'][6] = -3.0 * limits[6]
    report = twin.step(torques)
    assert report.clamped == {'left': True, 'right': False}
    applied = twin.joint_state('left').measured_torque
    assert applied[0] == pytest.approx(limits[0]) and applied[6] == pytest.approx(-limits[6])
    assert twin.step(hold_all(twin)).clamped == {'left': False, 'right': False}


def test_fri_period_must_be_supported(hold_scenario, cell):
    with pytest.raises(ConfigError, match='fri_period'):
        DualArmTwin(hold_scenario, cell, fri_period=0.003)
    twin = DualArmTwin(hold_scenario, cell, fri_period=0.005)
    twin.step(hold_all(twin))
    assert twin.time == pytest.approx(0.005)


def test_scripted_perturbation_moves_the_object_at_its_time(cell, hold_scenario):
    displacement = np.array([0.02, -0.01, 0.0])
    scenario = dataclasses.replace(hold_scenario,
                                   perturbations=(Perturbation(0.1, displacement),))
    twin = DualArmTwin(scenario, cell)
    start, _ = twin.object_pose()
    while twin.time < 0.1 - 1e-9:
        twin.step(hold_all(twin))
    assert twin.object_pose()[0][:2] == pytest.approx(start[:2], abs=1e-5)
    twin.step(hold_all(twin))
    assert twin.object_pose()[0][:2] == pytest.approx((start + displacement)[:2], abs=1e-4)


def tool_configuration(model, q_start, p_world_goal, R_world_goal):
    """Damped least-squares IK of the tool pose within the joint limits (test helper)."""
    lower, upper = model.position_limits
    q = np.array(q_start, dtype=float)
    for _ in range(300):
        p_world_tool, R_world_tool = model.tool_pose(q)
        error = np.concatenate((p_world_goal - p_world_tool,
                                pin.log3(R_world_goal @ R_world_tool.T)))
        jacobian = model.tool_jacobian(q)
        step = jacobian.T @ np.linalg.solve(jacobian @ jacobian.T + 1e-6 * np.eye(6), error)
        q = np.clip(q + 0.5 * step, 0.98 * lower, 0.98 * upper)
    assert np.linalg.norm(error) < 1e-9
    return q


@pytest.mark.parametrize('impact_speed', [0.5, 1.0])
def test_pad_impact_on_the_box_stays_stable(cell, hold_scenario, impact_speed):
    """The left pad, velocity-controlled at impact_speed, hits the box's +y face."""
    twin = DualArmTwin(hold_scenario, cell)
    model = arm_model('left', cell)
    index = twin.index.arms['left']
    R_world_goal = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    q = tool_configuration(model, cell.arm('left').q_home, np.array([0.41, 0.13, 0.32]),
                           R_world_goal)
    v_desired = np.array([0.0, -impact_speed, 0.0])
    twin.data.qpos[index.qpos] = q
    twin.data.qvel[index.dof] = np.linalg.pinv(model.tool_jacobian(q)) @ np.concatenate(
        (v_desired, np.zeros(3)))
    mujoco.mj_forward(twin.model, twin.data)
    deepest = 0.0
    object_speed = 0.0
    contact_forces = []
    while twin.time < 0.15 - 1e-9:
        state = twin.joint_state('left')
        v_tool, w_tool = model.tool_twist(state.position, state.velocity)
        wrench = np.concatenate((150.0 * (v_desired - v_tool), -5.0 * w_tool))
        torque = model.gravity_torque(state.position) + \
            model.tool_jacobian(state.position).T @ wrench
        twin.step({'left': torque, 'right': twin.hold_torques('right')})
        assert np.all(np.isfinite(twin.data.qpos)) and np.all(np.isfinite(twin.data.qvel))
        for contact in twin.data.contact[:twin.data.ncon]:
            if index.pad_geom in (contact.geom1, contact.geom2):
                deepest = max(deepest, -contact.dist)
        object_speed = max(object_speed, np.linalg.norm(twin.object_twist()[0]))
        force, in_contact = twin.pad_contact('left')
        if in_contact:
            contact_forces.append(force)
    print(f'impact at {impact_speed} m/s: deepest pad penetration {deepest * 1e3:.2f} mm, '
          f'fastest box {object_speed:.3f} m/s, {len(contact_forces)} contact cycles')
    assert contact_forces, 'the pad never touched the box'
    assert deepest < 0.005, f'pad penetrated the box by {deepest * 1e3:.2f} mm (limit 5 mm)'
    # A rigid impactor can at most double the target's speed (elastic limit); more means the
    # contact injected energy.
    assert object_speed < 2.0 * impact_speed, \
        f'box reached {object_speed:.3f} m/s after a {impact_speed} m/s impact'
    assert object_speed > 0.5 * impact_speed, 'the impact did not move the box'
    mean_force = np.mean(contact_forces, axis=0)
    assert mean_force[1] < 0.0, f'pad force on the box {mean_force} N must point along -y'


def test_two_pads_squeeze_and_lift_the_box(cell, hold_scenario):
    """Both pads on the box's y faces, 30 N squeeze, tools raised 5 cm: the box follows."""
    squeeze = 30.0                                   # [N] per pad along tool z
    twin = DualArmTwin(hold_scenario, cell)
    models = {arm: arm_model(arm, cell) for arm in twin.arms}
    goals = {'left': (np.array([0.41, 0.10, 0.32]),
                      np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])),
             'right': (np.array([0.41, -0.10, 0.32]),
                       np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]))}
    for arm in twin.arms:
        twin.data.qpos[twin.index.arms[arm].qpos] = tool_configuration(
            models[arm], cell.arm(arm).q_home, *goals[arm])
    mujoco.mj_forward(twin.model, twin.data)
    start, _ = twin.object_pose()
    weight_share = np.array([0.0, 0.0, 0.5 * hold_scenario.object.mass * GRAVITY])

    def impedance_torque(arm):
        state = twin.joint_state(arm)
        model = models[arm]
        p_world_tool, R_world_tool = model.tool_pose(state.position)
        v_tool, w_tool = model.tool_twist(state.position, state.velocity)
        p_goal, R_goal = goals[arm]
        lift = 0.05 * np.clip((twin.time - 0.3) / 0.5, 0.0, 1.0)
        force = (800.0 * (p_goal + [0.0, 0.0, lift] - p_world_tool) - 80.0 * v_tool
                 + squeeze * R_world_tool[:, 2] + weight_share)
        moment = 30.0 * pin.log3(R_goal @ R_world_tool.T) - 3.0 * w_tool
        return model.gravity_torque(state.position) + \
            model.tool_jacobian(state.position).T @ np.concatenate((force, moment))

    slip = 0.0
    while twin.time < 1.5 - 1e-9:
        twin.step({arm: impedance_torque(arm) for arm in twin.arms})
        midpoint = 0.5 * (twin.tool_pose('left')[0] + twin.tool_pose('right')[0])
        slip = max(slip, np.linalg.norm(twin.object_pose()[0] - midpoint))
    rise = twin.object_pose()[0][2] - start[2]
    print(f'squeeze and lift: box rose {rise * 1e3:.1f} mm, worst offset from the pad midpoint '
          f'{slip * 1e3:.2f} mm')
    assert rise > 0.04, f'box rose only {rise * 1e3:.1f} mm (tools raised 50 mm)'
    assert slip < 0.002, f'box slipped {slip * 1e3:.2f} mm relative to the pads'
    for arm in twin.arms:
        force_world, in_contact = twin.pad_contact(arm)
        _, R_world_tool = twin.tool_pose(arm)
        assert in_contact
        assert R_world_tool[:, 2] @ force_world == pytest.approx(squeeze, abs=3.0)
        force_sensor, _ = twin.ft_wrench(arm)
        assert force_sensor[2] == pytest.approx(-squeeze, abs=3.0), \
            f'{arm}: FT z {force_sensor[2]:.1f} N; the pad pushing with {squeeze} N reads -z'


def test_pad_torsion_arm_is_the_mean_radius_of_the_pad():
    """The closed form equals the mean distance of 600 x 400 cell centres over the pad."""
    x = (np.arange(600) + 0.5) / 600 * 0.15 - 0.075
    y = (np.arange(400) + 0.5) / 400 * 0.10 - 0.05
    assert pad_torsion_arm(0.075, 0.05) == pytest.approx(
        np.hypot(*np.meshgrid(x, y)).mean(), rel=1e-4)
    assert pad_torsion_arm(0.05, 0.05) == pytest.approx(0.05 * 0.7652, rel=1e-3)


def test_the_wrench_qp_counts_on_less_torsion_than_the_twin_gives(cell, hold_scenario):
    """At the lowest pad friction any shipped randomization draws (0.6) the twin resists more."""
    low_friction = dataclasses.replace(
        hold_scenario, object=dataclasses.replace(hold_scenario.object, friction=0.6))
    twin = DualArmTwin(low_friction, cell)
    for arm in twin.arms:
        pair = mujoco.mj_name2id(twin.model, mujoco.mjtObj.mjOBJ_PAIR, f'{arm}/pad_object')
        torsion = twin.model.pair_friction[pair][2]
        assert torsion == pytest.approx(0.6 * pad_torsion_arm(0.075, 0.05))
        assert torsion > WrenchQPConfig().torsion_arm
