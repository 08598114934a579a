"""Wrench QP (eq. 10): grasp matrix, constraints, optimum, infeasibility, warm start."""

import math

from dual_arm_control.core.exceptions import ConfigError, InputError, SolverError
from dual_arm_control.core.geometry import rotation_exp
from dual_arm_control.core.pad_contact import (grasp_matrix, pad_contact_geometry, PAD_ORDER,
                                               PadContact)
from dual_arm_control.core.wrench_qp import ContactWrenchQP, WrenchQPConfig
import numpy as np
import pytest

BOX = np.array([0.2, 0.2, 0.2])
GRAVITY = 9.81
CONSTRAINT_TOLERANCE = 1e-6   # N, N m: proxsuite eps_abs is 1e-9, leaves margin for scaling
BALANCE_TOLERANCE = 1e-6      # N, N m


def random_grasp(rng, gaps=(0.0, 0.0)):
    """Return (p_world_object, R_world_object, contacts) of a 0.2 m box squeezed on +-y."""
    R_world_object = rotation_exp(rng.normal(size=3) * 0.6)
    p_world_object = np.array([0.5, 0.0, 0.4]) + rng.uniform(-0.15, 0.15, 3)
    contacts = {}
    for arm, gap in zip(PAD_ORDER, gaps):
        sign = 1.0 if arm == 'left' else -1.0
        z_axis = -sign * R_world_object[:, 1]
        x_axis = rotation_exp(z_axis * rng.uniform(-0.4, 0.4)) @ R_world_object[:, 0]
        R_world_tool = np.column_stack((x_axis, np.cross(z_axis, x_axis), z_axis))
        offset = np.array([rng.uniform(-0.03, 0.03), sign * (0.1 + gap),
                           rng.uniform(-0.03, 0.03)])
        contacts[arm] = pad_contact_geometry(
            arm, p_world_object + R_world_object @ offset, R_world_tool, p_world_object,
            R_world_object, BOX)
    return p_world_object, R_world_object, contacts


def pad_wrench_in_pad_frame(wrench, contact):
    """Return (f, m) of a world-frame pad wrench expressed in the pad frame."""
    R = contact.R_world_pad
    return R.T @ wrench[:3], R.T @ wrench[3:]


def random_feasible_pad_wrench(rng, contact, config, margin=0.9):
    """Return a world-frame pad wrench strictly inside every contact constraint."""
    normal = rng.uniform(config.min_normal_force + 1.0, config.max_normal_force - 1.0)
    pyramid = config.friction_coefficient / math.sqrt(2.0) * normal * margin
    force = np.array([rng.uniform(-pyramid, pyramid), rng.uniform(-pyramid, pyramid), normal])
    moment = np.array([
        rng.uniform(-1.0, 1.0) * config.pad_half_width * normal * margin,
        rng.uniform(-1.0, 1.0) * config.pad_half_length * normal * margin,
        rng.uniform(-1.0, 1.0) * config.torsion_arm * normal * margin])
    R = contact.R_world_pad
    return np.concatenate((R @ force, R @ moment))


def constraint_violation(wrench, contact, config):
    """Return the largest violation [N, N m] of the pad's contact constraints (0 if none)."""
    force, moment = pad_wrench_in_pad_frame(wrench, contact)
    normal = force[2]
    pyramid = config.friction_coefficient / math.sqrt(2.0) * normal
    violations = [
        config.min_normal_force - normal, normal - config.max_normal_force,
        abs(force[0]) - pyramid, abs(force[1]) - pyramid,
        abs(moment[2]) - config.torsion_arm * normal,
        abs(moment[0]) - config.pad_half_width * normal,
        abs(moment[1]) - config.pad_half_length * normal]
    return max(0.0, max(violations))


def stacked(result):
    return np.concatenate([result.wrenches[arm] for arm in PAD_ORDER])


def net_wrench(wrenches, p_world_contacts, p_world_object):
    """Independent net wrench: sum of forces, sum of (r x f) + m about the object centre."""
    force = np.zeros(3)
    moment = np.zeros(3)
    for wrench, p_world_contact in zip(wrenches, p_world_contacts):
        force += wrench[:3]
        moment += np.cross(p_world_contact - p_world_object, wrench[:3]) + wrench[3:]
    return np.concatenate((force, moment))


def test_grasp_matrix_gives_net_wrench_about_object_centre():
    rng = np.random.default_rng(0)
    for _ in range(50):
        p_world_contacts = rng.normal(size=(2, 3))
        p_world_object = rng.normal(size=3)
        wrenches = rng.normal(size=(2, 6))
        G = grasp_matrix(p_world_contacts, p_world_object)
        assert G.shape == (6, 12)
        expected = net_wrench(wrenches, p_world_contacts, p_world_object)
        np.testing.assert_allclose(G @ wrenches.ravel(), expected, atol=1e-12)


def test_grasp_matrix_lever_arm_sign_is_textbook():
    # A pad 0.1 m along +y pushing down 10 N yields a moment of -1 N m about +x (r x f).
    G = grasp_matrix([[0.0, 0.1, 0.0], [0.0, -0.1, 0.0]], np.zeros(3))
    wrench = np.zeros(12)
    wrench[2] = -10.0
    np.testing.assert_allclose(G @ wrench, [0.0, 0.0, -10.0, -1.0, 0.0, 0.0], atol=1e-12)


def test_pad_contact_geometry_of_left_pad():
    R_world_object = rotation_exp([0.0, 0.0, 0.3])
    p_world_object = np.array([0.5, 0.0, 0.3])
    z_axis = -R_world_object[:, 1]
    R_world_tool = np.column_stack((R_world_object[:, 0], np.cross(z_axis, R_world_object[:, 0]),
                                    z_axis))
    p_world_tool = p_world_object + R_world_object @ np.array([0.02, 0.13, -0.01])
    contact = pad_contact_geometry('left', p_world_tool, R_world_tool, p_world_object,
                                   R_world_object, BOX)
    assert contact.normal_distance == pytest.approx(0.03, abs=1e-12)
    np.testing.assert_allclose(contact.p_world_contact,
                               p_world_object + R_world_object @ [0.02, 0.1, -0.01], atol=1e-12)
    np.testing.assert_allclose(contact.R_world_pad, R_world_tool, atol=1e-12)


def test_random_feasible_object_wrenches_are_produced_within_constraints():
    rng = np.random.default_rng(1)
    config = WrenchQPConfig()
    solver = ContactWrenchQP(config)
    worst_constraint = worst_balance = 0.0
    for _ in range(120):
        p_world_object, _, contacts = random_grasp(rng)
        feasible_wrenches = [random_feasible_pad_wrench(rng, contacts[arm], config)
                             for arm in PAD_ORDER]
        p_world_contacts = [contacts[arm].p_world_contact for arm in PAD_ORDER]
        object_wrench = net_wrench(feasible_wrenches, p_world_contacts, p_world_object)
        result = solver.contact_wrenches(object_wrench, p_world_object, contacts)
        assert result.feasible and result.status == 'PROXQP_SOLVED'
        assert result.slack_norm < BALANCE_TOLERANCE
        for arm in PAD_ORDER:
            worst_constraint = max(worst_constraint, constraint_violation(
                result.wrenches[arm], contacts[arm], config))
        produced = net_wrench([result.wrenches[arm] for arm in PAD_ORDER], p_world_contacts,
                              p_world_object)
        worst_balance = max(worst_balance, np.abs(produced - object_wrench).max())
    assert worst_constraint < CONSTRAINT_TOLERANCE
    assert worst_balance < BALANCE_TOLERANCE


def kkt_certificate(problem, x, active_tolerance=1e-7):
    """
    Re-solve the QP restricted to the active set of x with a numpy KKT system.

    Returns (x_kkt, worst sign violation of the inequality multipliers, worst primal
    violation of x_kkt). For a convex QP, a KKT point with correctly signed multipliers is
    the global optimum, which certifies x independently of proxsuite.
    """
    H, g, A, b, C, lower, upper = (problem[key] for key in 'HgAbClu')
    Cx = C @ x
    at_upper = np.isfinite(upper) & (np.abs(Cx - upper) < active_tolerance)
    at_lower = (np.isfinite(lower) & (np.abs(Cx - lower) < active_tolerance) & ~at_upper)
    active = at_upper | at_lower
    bounds = np.where(at_upper, upper, lower)[active]
    constraints = np.vstack((A, C[active]))
    n, m = H.shape[0], constraints.shape[0]
    kkt = np.block([[H, constraints.T], [constraints, np.zeros((m, m))]])
    rhs = np.concatenate((-g, b, bounds))
    solution = np.linalg.lstsq(kkt, rhs, rcond=None)[0]
    x_kkt, multipliers = solution[:n], solution[n + A.shape[0]:]
    signs = np.where(at_upper[active], 1.0, -1.0)  # z >= 0 on upper, z <= 0 on lower bounds
    sign_violation = max(0.0, float(np.max(-signs * multipliers, initial=0.0)))
    Cx_kkt = C @ x_kkt
    primal_violation = max(float(np.max(Cx_kkt - upper)), float(np.max(lower - Cx_kkt)),
                           float(np.abs(A @ x_kkt - b).max()), 0.0)
    return x_kkt, sign_violation, primal_violation


def test_solution_is_the_certified_optimum_of_eq_10():
    rng = np.random.default_rng(2)
    config = WrenchQPConfig()
    solver = ContactWrenchQP(config)
    for trial in range(100):
        p_world_object, _, contacts = random_grasp(rng)
        feasible_wrenches = [random_feasible_pad_wrench(rng, contacts[arm], config)
                             for arm in PAD_ORDER]
        object_wrench = net_wrench(feasible_wrenches,
                                   [contacts[arm].p_world_contact for arm in PAD_ORDER],
                                   p_world_object)
        if trial % 4 == 0:
            object_wrench = object_wrench + rng.normal(size=6) * [20, 20, 20, 2, 2, 2]
        result = solver.contact_wrenches(object_wrench, p_world_object, contacts)
        x = solver._qp.results.x.copy()
        x_kkt, sign_violation, primal_violation = kkt_certificate(solver.problem(), x)
        np.testing.assert_allclose(x_kkt, x, atol=1e-6)
        for index, arm in enumerate(PAD_ORDER):   # x holds pad-frame wrenches
            rotation = contacts[arm].R_world_pad
            np.testing.assert_allclose(
                result.wrenches[arm], np.concatenate((rotation @ x[6 * index:6 * index + 3],
                                                      rotation @ x[6 * index + 3:6 * index + 6])),
                atol=1e-12)
        assert sign_violation < 1e-5   # multipliers are O(1e3); 1e-5 is far from a sign flip
        assert primal_violation < 1e-6


@pytest.mark.parametrize('mass, friction_needs_more', [
    (0.7, False),   # m g / 2 = 3.4 N of tangential force: the minimum squeeze holds it
    (5.0, False),   # 24.5 N < 0.42 * 70 N (mu 0.6)
    (8.0, True),    # 39.2 N needs 92.5 N at mu 0.6, within the 105 N bound
])
def test_squeeze_is_the_minimum_friction_requires(mass, friction_needs_more):
    # Horizontal pads at the height of the centre of mass holding a box against gravity: by
    # symmetry each pad carries m g / 2 tangentially, so the least normal force is
    # max(f_min, m g / (2 mu / sqrt 2)) and the minimal-internal-force distribution uses it.
    config = WrenchQPConfig()
    friction_force = mass * GRAVITY / 2.0 / (config.friction_coefficient / math.sqrt(2.0))
    expected_squeeze = max(config.min_normal_force, friction_force)
    assert (friction_force > config.min_normal_force) == friction_needs_more
    assert expected_squeeze <= config.max_normal_force
    contacts = {}
    for arm, sign in (('left', 1.0), ('right', -1.0)):
        z_axis = np.array([0.0, -sign, 0.0])
        R_world_pad = np.column_stack(([1.0, 0.0, 0.0], np.cross(z_axis, [1.0, 0.0, 0.0]),
                                       z_axis))
        contacts[arm] = PadContact(np.array([0.5, sign * 0.1, 0.3]), R_world_pad, 0.0)
    object_wrench = np.array([0.0, 0.0, mass * GRAVITY, 0.0, 0.0, 0.0])
    result = ContactWrenchQP(config).contact_wrenches(object_wrench, [0.5, 0.0, 0.3], contacts)
    assert result.feasible
    for arm in PAD_ORDER:
        force, moment = pad_wrench_in_pad_frame(result.wrenches[arm], contacts[arm])
        assert force[2] == pytest.approx(expected_squeeze, abs=1e-6)
        assert result.wrenches[arm][2] == pytest.approx(mass * GRAVITY / 2.0, abs=1e-6)
        np.testing.assert_allclose(moment, 0.0, atol=1e-6)


def test_wrench_beyond_friction_capacity_is_reported_through_slack():
    # 14 kg needs 162 N of normal force per pad, above the 105 N bound.
    contacts = {}
    for arm, sign in (('left', 1.0), ('right', -1.0)):
        z_axis = np.array([0.0, -sign, 0.0])
        R_world_pad = np.column_stack(([1.0, 0.0, 0.0], np.cross(z_axis, [1.0, 0.0, 0.0]),
                                       z_axis))
        contacts[arm] = PadContact(np.array([0.5, sign * 0.1, 0.3]), R_world_pad, 0.0)
    config = WrenchQPConfig()
    object_wrench = np.array([0.0, 0.0, 14.0 * GRAVITY, 0.0, 0.0, 0.0])
    result = ContactWrenchQP(config).contact_wrenches(object_wrench, [0.5, 0.0, 0.3], contacts)
    capacity = 2.0 * config.max_normal_force * config.friction_coefficient / math.sqrt(2.0)
    assert not result.feasible
    assert result.slack[2] == pytest.approx(14.0 * GRAVITY - capacity, abs=1e-6)
    for arm in PAD_ORDER:
        assert constraint_violation(result.wrenches[arm], contacts[arm], config) < 1e-6


def test_pad_out_of_contact_carries_no_wrench_and_is_reported():
    rng = np.random.default_rng(3)
    config = WrenchQPConfig()
    solver = ContactWrenchQP(config)
    for _ in range(10):
        p_world_object, _, contacts = random_grasp(rng, gaps=(0.08, 0.0))
        object_wrench = np.array([0.0, 0.0, 0.7 * GRAVITY, 0.0, 0.0, 0.0])
        result = solver.contact_wrenches(object_wrench, p_world_object, contacts)
        assert result.in_contact == {'left': False, 'right': True}
        np.testing.assert_allclose(result.wrenches['left'], 0.0, atol=1e-8)
        assert constraint_violation(result.wrenches['right'], contacts['right'], config) < 1e-6
        # the right pad alone pushes >= f_min along its normal n, so n . s <= n . f_o - f_min
        normal = contacts['right'].R_world_pad[:, 2]
        unbalanced = config.min_normal_force - normal @ object_wrench[:3]
        assert not result.feasible and result.slack_norm >= unbalanced - 1e-6
        G = grasp_matrix([contacts[arm].p_world_contact for arm in PAD_ORDER], p_world_object)
        np.testing.assert_allclose(G @ stacked(result) + result.slack, object_wrench,
                                   atol=1e-6)
    p_world_object, _, contacts = random_grasp(rng, gaps=(0.1, 0.2))
    object_wrench = rng.normal(size=6)
    result = solver.contact_wrenches(object_wrench, p_world_object, contacts)
    np.testing.assert_allclose(stacked(result), 0.0, atol=1e-8)
    np.testing.assert_allclose(result.slack, object_wrench, atol=1e-6)
    assert not result.feasible


def test_warm_started_solves_equal_cold_solves():
    rng = np.random.default_rng(4)
    warm_solver = ContactWrenchQP()
    p_world_object, R_world_object, contacts = random_grasp(rng)
    base_wrench = np.array([2.0, -1.0, 8.0, 0.2, -0.1, 0.05])
    warm_iterations, cold_iterations = [], []
    for tick in range(60):
        rotation = rotation_exp([0.002 * tick, -0.001 * tick, 0.003 * tick])
        moved = {arm: PadContact(rotation @ (c.p_world_contact - p_world_object)
                                 + p_world_object + [0.001 * tick, 0.0, 0.0],
                                 rotation @ c.R_world_pad, c.normal_distance)
                 for arm, c in contacts.items()}
        object_wrench = base_wrench + [np.sin(0.1 * tick), 0.0, np.cos(0.2 * tick), 0.0,
                                       0.05 * np.sin(0.3 * tick), 0.0]
        p_object = p_world_object + [0.001 * tick, 0.0, 0.0]
        warm = warm_solver.contact_wrenches(object_wrench, p_object, moved)
        cold = ContactWrenchQP().contact_wrenches(object_wrench, p_object, moved)
        np.testing.assert_allclose(stacked(warm), stacked(cold), atol=1e-6)
        np.testing.assert_allclose(warm.slack, cold.slack, atol=1e-6)
        if tick > 0:
            warm_iterations.append(warm.iterations)
            cold_iterations.append(cold.iterations)
    assert np.mean(warm_iterations) < np.mean(cold_iterations)


def test_solver_failure_raises_solver_error_with_problem_and_status():
    rng = np.random.default_rng(5)
    p_world_object, _, contacts = random_grasp(rng)
    solver = ContactWrenchQP(WrenchQPConfig(max_iterations=1, warm_max_iterations=1))
    with pytest.raises(SolverError) as error:
        solver.contact_wrenches([1.0, 2.0, 7.0, 0.1, 0.2, 0.3], p_world_object, contacts)
    assert error.value.status == 'PROXQP_MAX_ITER_REACHED'
    assert set(error.value.problem) == set('HgAbClu')


def test_non_finite_inputs_and_bad_config_are_refused():
    rng = np.random.default_rng(6)
    p_world_object, _, contacts = random_grasp(rng)
    solver = ContactWrenchQP()
    with pytest.raises(InputError, match='object_wrench'):
        solver.contact_wrenches([np.nan, 0, 0, 0, 0, 0], p_world_object, contacts)
    broken = dict(contacts, right=PadContact(contacts['right'].p_world_contact,
                                             contacts['right'].R_world_pad, np.inf))
    with pytest.raises(InputError, match='right normal_distance'):
        solver.contact_wrenches(np.zeros(6), p_world_object, broken)
    with pytest.raises(InputError, match='shape'):
        solver.contact_wrenches(np.zeros(5), p_world_object, contacts)
    with pytest.raises(ConfigError, match='max_normal_force'):
        WrenchQPConfig(min_normal_force=30.0, max_normal_force=20.0)
    with pytest.raises(ConfigError, match='friction_coefficient'):
        WrenchQPConfig(friction_coefficient=0.0)


def test_result_arrays_are_read_only():
    rng = np.random.default_rng(7)
    p_world_object, _, contacts = random_grasp(rng)
    result = ContactWrenchQP().contact_wrenches([0, 0, 7.0, 0, 0, 0], p_world_object, contacts)
    with pytest.raises(ValueError):
        result.wrenches['left'][0] = 1.0
    with pytest.raises(ValueError):
        result.slack[0] = 1.0
