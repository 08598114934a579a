"""Modulation of the coordinated DS (paper eqs. 1-3, 5) and Proposition 1."""

from dual_arm_control.core.cooperative import (
    coordinated_gain_matrix, CoordinationConfig, impact_frame_gain_matrix)
from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.modulation import (
    activation_distances, activations, blended_modulation_gains, modulated_velocity,
    modulation_bases, modulation_gains, modulation_matrix, ModulationRegionConfig,
    region_activations, transitory_attractor)
import numpy as np
import pytest

GRASP_POINTS = np.array([[0.41, 0.1, 0.32], [0.41, -0.1, 0.32]])
IMPACT_DIRECTIONS = np.array([[0.575, -0.766, 0.287], [0.575, 0.766, 0.287]])


def random_case(rng, count=2):
    """Return random bases (count, 3, 3), nominal (count, 3) and targets (count, 3, 3)."""
    bases = modulation_bases(rng.normal(size=(count, 3)))
    return bases, rng.normal(size=(count, 3)), rng.normal(size=(count, 3, 3))


def matrix_velocity(bases, nominal, targets, alpha):
    """Return M f_n with M = E Lambda-bar E^T built from eqs. 5, 3, 2 (no closed form)."""
    blended = blended_modulation_gains(modulation_gains(bases, nominal, targets), alpha)
    return (modulation_matrix(bases, blended) @ nominal.reshape(-1)).reshape(-1, 3)


def test_bases_are_orthonormal_deterministic_and_aligned():
    bases = modulation_bases(IMPACT_DIRECTIONS)
    for basis, direction in zip(bases, IMPACT_DIRECTIONS):
        np.testing.assert_allclose(basis.T @ basis, np.eye(3), atol=1e-14)
        np.testing.assert_allclose(basis[:, 0], direction / np.linalg.norm(direction),
                                   atol=1e-15)
    np.testing.assert_array_equal(bases, modulation_bases(IMPACT_DIRECTIONS))


def test_transitory_attractor_is_rho_before_the_target_along_e1():
    bases = modulation_bases(IMPACT_DIRECTIONS)
    transitory = transitory_attractor(GRASP_POINTS, bases, 0.2)
    offsets = GRASP_POINTS - transitory
    np.testing.assert_allclose(np.linalg.norm(offsets, axis=1), [0.2, 0.2], atol=1e-15)
    np.testing.assert_allclose(offsets / 0.2, bases[:, :, 0], atol=1e-14)


def test_activation_distances_in_the_basis():
    bases = modulation_bases(IMPACT_DIRECTIONS)
    transitory = transitory_attractor(GRASP_POINTS, bases, 0.2)
    along, lateral_2, lateral_3 = 0.05, 0.03, -0.04
    point = transitory + along * bases[:, :, 0] + lateral_2 * bases[:, :, 1] \
        + lateral_3 * bases[:, :, 2]
    distances = activation_distances(point, transitory, bases, 0.2)
    np.testing.assert_allclose(distances[:, 0], np.sqrt(0.05 ** 2 + 0.03 ** 2 + 0.04 ** 2))
    np.testing.assert_allclose(distances[:, 1], 0.05, atol=1e-15)
    np.testing.assert_allclose(distances[:, 2], 0.2 - along, atol=1e-15)


def test_activations_are_logistic_half_at_delta_and_saturate_without_overflow():
    region = ModulationRegionConfig()
    half = activations(np.array([region.distances]), region)
    np.testing.assert_allclose(half, 0.5, atol=1e-15)
    with np.errstate(over='raise'):
        far = activations(np.array([[1e6, 1e6, 1e6]]), region)
        near = activations(np.zeros((1, 3)), region)
    assert np.all(far < 1e-200)
    assert np.all(near > 0.99)
    expected = 1.0 / (1.0 + np.exp(-200.0 * (0.25 - 0.1)))
    np.testing.assert_allclose(activations(np.array([[0.1, 0.0, 0.0]]), region)[0, 0], expected)


def test_region_activations_chain_per_arm_before_averaging():
    # Left: inside the ball but off the line; right: on the line but outside the ball.
    phi = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0]])
    shared = region_activations(phi)
    np.testing.assert_array_equal(shared.alpha, [0.5, 0.5])
    np.testing.assert_array_equal(shared.gamma, [0.0, 0.0])
    np.testing.assert_array_equal(shared.kappa, [0.0, 0.0])
    phi = np.array([[0.9, 0.8, 0.5], [0.7, 0.6, 0.4]])
    own = region_activations(phi, shared=False)
    np.testing.assert_allclose(own.gamma, [0.72, 0.42])
    np.testing.assert_allclose(own.kappa, [0.36, 0.168])
    np.testing.assert_allclose(region_activations(phi).gamma, [0.57, 0.57])


def test_modulation_is_identity_when_alpha_is_zero():
    rng = np.random.default_rng(5)
    bases, nominal, targets = random_case(rng)
    blended = blended_modulation_gains(modulation_gains(bases, nominal, targets), [0.0, 0.0])
    np.testing.assert_allclose(modulation_matrix(bases, blended), np.eye(6), atol=1e-14)
    np.testing.assert_allclose(modulated_velocity(bases, nominal, targets, [0.0, 0.0]),
                               nominal, atol=1e-15)


@pytest.mark.parametrize('alpha', [0.0, 0.3, 1.0])
def test_closed_form_equals_the_modulation_matrix(alpha):
    rng = np.random.default_rng(6)
    for _ in range(50):
        bases, nominal, targets = random_case(rng)
        alphas = np.full(2, alpha)
        np.testing.assert_allclose(modulated_velocity(bases, nominal, targets, alphas),
                                   matrix_velocity(bases, nominal, targets, alphas), atol=1e-9)


def test_proposition_1_full_modulation_follows_the_target_fields():
    rng = np.random.default_rng(7)
    for _ in range(50):
        bases, nominal, targets = random_case(rng)
        velocity = matrix_velocity(bases, nominal, targets, np.ones(2))
        for h in range(2):
            for i in range(3):
                e_i = bases[h][:, i]
                assert abs(e_i @ velocity[h] - e_i @ targets[h, i]) < 1e-9


def test_zero_nominal_field_is_handled():
    rng = np.random.default_rng(8)
    bases, _, targets = random_case(rng)
    nominal = np.zeros((2, 3))
    gains = modulation_gains(bases, nominal, targets)
    assert np.all(np.isfinite(gains))
    velocity = modulated_velocity(bases, nominal, targets, np.ones(2))
    expected = np.einsum('nki,ni->nk', bases, np.einsum('nki,nik->ni', bases, targets))
    np.testing.assert_allclose(velocity, expected, atol=1e-15)


def test_grasp_velocity_is_added():
    rng = np.random.default_rng(9)
    bases, nominal, targets = random_case(rng)
    grasp = rng.normal(size=(2, 3))
    np.testing.assert_allclose(
        modulated_velocity(bases, nominal, targets, [0.4, 0.4], grasp),
        modulated_velocity(bases, nominal, targets, [0.4, 0.4]) + grasp, atol=1e-15)


def integrate_proposition_1(x, bases, gains, attractor, dt=0.001, duration=4.0):
    """
    RK4-integrate x_dot = M f_n with alpha = 1 and f_mi = A'_i (x - x_*) (Proposition 1).

    Return the final state and the first times [s] each arm is within 1 cm of its attractor.
    """
    first, others = gains

    def field(state):
        error = state - attractor
        nominal = (others @ error).reshape(2, 3)
        targets = np.stack(((first @ error).reshape(2, 3), nominal, nominal), axis=1)
        return modulated_velocity(bases, nominal, targets, np.ones(2)).reshape(6)

    arrival = [None, None]
    for step in range(int(round(duration / dt))):
        k1 = field(x)
        k2 = field(x + 0.5 * dt * k1)
        k3 = field(x + 0.5 * dt * k2)
        k4 = field(x + dt * k3)
        x = x + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        for h in range(2):
            arm = slice(3 * h, 3 * h + 3)
            if arrival[h] is None and np.linalg.norm(x[arm] - attractor[arm]) < 0.01:
                arrival[h] = (step + 1) * dt
    return x, arrival


def random_starts(rng, count):
    """Return count asymmetric starts (6,) around the standby poses, +-0.15 m per axis."""
    standby = np.array([0.35, 0.31, 0.80, 0.35, -0.31, 0.80])
    return standby + rng.uniform(-0.15, 0.15, (count, 6))


@pytest.mark.parametrize('coordinated', [True, False])
def test_proposition_1_converges_and_coordination_synchronises_arrival(coordinated):
    bases = modulation_bases(IMPACT_DIRECTIONS)
    gains = [impact_frame_gain_matrix(coordinated_gain_matrix(CoordinationConfig(
        absolute_gain=absolute, relative_gain=relative, coordinated=coordinated)), bases)
        for absolute, relative in ((4.5, 10.0), (3.0, 8.0))]
    attractor = GRASP_POINTS.reshape(6)
    rng = np.random.default_rng(10)
    gaps = []
    for start in random_starts(rng, 20):
        final, arrival = integrate_proposition_1(start, bases, gains, attractor)
        # Slowest rate 3 /s over 4 s: the error shrinks by e^-12 from at most 0.7 m.
        assert np.linalg.norm(final - attractor) < 1e-4
        gaps.append(abs(arrival[0] - arrival[1]))
    print(f'coordinated={coordinated}: arrival gap within 1 cm, max {max(gaps) * 1e3:.1f} ms')
    if coordinated:
        assert max(gaps) < 0.005
    else:
        assert max(gaps) > 0.02


@pytest.mark.parametrize('field, value', [
    ('transitory_distance', 0.0), ('radial_distance', 0.1), ('normal_distance', -0.01),
    ('tangent_distance', float('inf')), ('radial_slope', 0.0), ('normal_slope', -5.0)])
def test_region_config_rejects_bad_values_naming_the_field(field, value):
    with pytest.raises(ConfigError, match=field):
        ModulationRegionConfig(**{field: value})


def test_region_config_requires_the_target_inside_the_ball():
    with pytest.raises(ConfigError, match='radial_distance'):
        ModulationRegionConfig(transitory_distance=0.2, radial_distance=0.21, radial_slope=100.0)
