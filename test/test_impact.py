"""Coordinated reach with impact: impact direction, eq. 6 and Proposition 2."""

import math

from dual_arm_control.core.cooperative import coordinated_gain_matrix, CoordinationConfig
from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.impact import (
    desired_impact_velocity, grasp_distance, impact_attractor, impact_direction,
    impact_ds_velocity, impact_geometry, impact_target_field, impact_target_fields,
    ImpactConfig, max_impact_tilt)
from dual_arm_control.core.modulation import modulated_velocity, ModulationRegionConfig
from dual_arm_control.core.speed_shaping import (
    boosted_coordinated_velocity, reach_speed, SpeedProfileConfig)
import numpy as np
import pytest

# Paper section IV-A: 0.2 m cube at (0.41, 0, 0.32); left pad on the +y face, right on -y.
OBJECT_POSITION = np.array([0.41, 0.0, 0.32])
GRASP_POINTS = np.array([OBJECT_POSITION + [0.0, 0.1, 0.0], OBJECT_POSITION - [0.0, 0.1, 0.0]])
CONTACT_NORMALS = np.array([[0.0, -1.0, 0.0], [0.0, 1.0, 0.0]])
# Desired object velocity after the grasp: the toss direction (1, 0, 0.5) at 0.85 m/s.
OBJECT_VELOCITY = 0.85 * np.array([1.0, 0.0, 0.5]) / math.sqrt(1.25)
STANDBY = np.array([0.35, 0.31, 0.80, 0.35, -0.31, 0.80])


def paper_geometry(coordination=None, impact=None):
    """Return (geometry, impact config) of the paper grasp with tilted impact directions."""
    coordination = coordination or CoordinationConfig()
    impact = impact or ImpactConfig()
    tilt = max_impact_tilt(impact)
    directions = np.array([impact_direction(normal, OBJECT_VELOCITY, tilt)
                           for normal in CONTACT_NORMALS])
    return impact_geometry(GRASP_POINTS, directions, coordination, impact), impact


def simulate_reach(x, geometry, impact, boosted, dt=0.001, duration=4.0, push=None):
    """
    Euler-integrate the impact DS from x until both pads cross their face planes.

    Return [(time [s], position (3,), velocity (3,)) or None] per arm at the crossing,
    interpolated linearly inside the step. push (3,) [m], in the left arm's basis E^L, displaces
    the left arm once, in the middle of the run, as a tracking error would.
    """
    speed_profile = SpeedProfileConfig()
    hits = [None, None]
    basis_left = geometry.bases[0]
    time = 0.0
    while time < duration and None in hits:
        output = impact_ds_velocity(x, geometry)
        velocity = output.velocity
        if boosted:
            speed = reach_speed(grasp_distance(x, geometry), impact.impact_speed, speed_profile)
            velocity = boosted_coordinated_velocity(velocity, speed)
        progress = basis_left[:, 0] @ (x[:3] - geometry.transitory[:3])
        if push is not None and output.activation.gamma[0] > 0.99 and progress > 0.1:
            x = x + np.concatenate((basis_left @ push, np.zeros(3)))
            push = None
            continue
        x_next = x + dt * velocity
        for h in range(2):
            before = CONTACT_NORMALS[h] @ (x[3 * h:3 * h + 3] - GRASP_POINTS[h])
            after = CONTACT_NORMALS[h] @ (x_next[3 * h:3 * h + 3] - GRASP_POINTS[h])
            if hits[h] is None and before < 0.0 <= after:
                fraction = -before / (after - before)
                arm_velocity = velocity[3 * h:3 * h + 3]
                hits[h] = (time + fraction * dt, x[3 * h:3 * h + 3] + fraction * dt *
                           arm_velocity, arm_velocity.copy())
        x = x_next
        time += dt
    return hits


def contact_errors(hits, geometry, impact):
    """Return (arrival gap [s], position error [m], speed error [-], direction error [deg])."""
    desired = geometry.desired_velocity.reshape(2, 3)
    position = max(np.linalg.norm(hits[h][1] - GRASP_POINTS[h]) for h in range(2))
    speed = max(abs(np.linalg.norm(hits[h][2]) / impact.impact_speed - 1.0) for h in range(2))
    angle = max(math.degrees(math.acos(np.clip(
        hits[h][2] @ desired[h] / (np.linalg.norm(hits[h][2]) * impact.impact_speed), -1, 1)))
        for h in range(2))
    return abs(hits[0][0] - hits[1][0]), position, speed, angle


def test_impact_direction_of_the_paper_grasp():
    left = impact_direction([0.0, -1.0, 0.0], OBJECT_VELOCITY, math.radians(40.0))
    toward = np.array([1.0, 0.0, 0.5]) / math.sqrt(1.25)
    expected = math.cos(math.radians(40.0)) * np.array([0.0, -1.0, 0.0]) \
        + math.sin(math.radians(40.0)) * toward
    np.testing.assert_allclose(left, expected, atol=1e-15)


def test_impact_direction_stays_in_the_tilt_cone_and_the_plane():
    rng = np.random.default_rng(11)
    for _ in range(500):
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        velocity = rng.normal(size=3) * rng.uniform(0.01, 2.0)
        max_tilt = rng.uniform(0.0, math.radians(60.0))
        direction = impact_direction(normal, velocity, max_tilt)
        assert abs(np.linalg.norm(direction) - 1.0) < 1e-12
        assert math.acos(min(1.0, direction @ normal)) <= max_tilt + 1e-9
        assert abs(direction @ np.cross(normal, velocity)) < 1e-9 * np.linalg.norm(velocity)
        tangential = velocity - (velocity @ normal) * normal
        assert (direction - (direction @ normal) * normal) @ tangential >= -1e-12
        angle = math.acos(np.clip(velocity @ normal / np.linalg.norm(velocity), -1.0, 1.0))
        if angle < max_tilt:
            np.testing.assert_allclose(direction, velocity / np.linalg.norm(velocity),
                                       atol=1e-12)


def test_impact_direction_without_tangential_motion_is_the_normal():
    normal = np.array([0.0, 1.0, 0.0])
    np.testing.assert_array_equal(impact_direction(normal, [0.0, 0.3, 0.0], 0.7), normal)
    np.testing.assert_array_equal(impact_direction(normal, np.zeros(3), 0.7), normal)


def test_max_tilt_is_limited_by_the_friction_cone():
    config = ImpactConfig(max_tilt_deg=40.0)
    assert max_impact_tilt(config) == pytest.approx(math.radians(40.0))
    assert max_impact_tilt(config, friction=0.5) == pytest.approx(math.atan(0.5))
    assert max_impact_tilt(config, friction=1.0) == pytest.approx(math.radians(40.0))


def test_desired_impact_velocity_is_speed_times_direction():
    geometry, impact = paper_geometry()
    directions = geometry.bases[:, :, 0]
    np.testing.assert_allclose(desired_impact_velocity(directions, 0.45), 0.45 * directions)
    np.testing.assert_allclose(geometry.desired_velocity,
                               impact.impact_speed * directions.reshape(6))


def test_eq_6_attractor_limits():
    geometry, _ = paper_geometry(impact=ImpactConfig(synchronise=False))
    gain = geometry.gain_matrix
    rng = np.random.default_rng(12)
    x = STANDBY + rng.uniform(-0.1, 0.1, 6)
    desired = geometry.desired_velocity
    np.testing.assert_allclose(impact_attractor(x, geometry.transitory, gain, desired, [0, 0]),
                               geometry.transitory, atol=1e-12)
    np.testing.assert_allclose(impact_attractor(x, geometry.transitory, gain, desired, [1, 1]),
                               x - np.linalg.solve(gain, desired), atol=1e-12)
    gamma = np.array([0.3, 0.3])
    blend = 0.7 * geometry.transitory + 0.3 * (x - np.linalg.solve(gain, desired))
    np.testing.assert_allclose(impact_attractor(x, geometry.transitory, gain, desired, gamma),
                               blend, atol=1e-12)


def test_synchronised_eq_6_attractor_keeps_the_relative_attraction():
    geometry, _ = paper_geometry()
    gain, projector = geometry.gain_matrix, geometry.relative_projector
    np.testing.assert_allclose(projector @ projector, projector, atol=1e-14)
    np.testing.assert_allclose(projector @ geometry.desired_velocity, np.zeros(6), atol=1e-15)
    rng = np.random.default_rng(16)
    x = STANDBY + rng.uniform(-0.1, 0.1, 6)
    attractor = impact_attractor(x, geometry.transitory, gain, geometry.desired_velocity,
                                 [1.0, 1.0], projector)
    expected = x - np.linalg.solve(gain, geometry.desired_velocity) \
        - projector @ (x - geometry.transitory)
    np.testing.assert_allclose(attractor, expected, atol=1e-12)


def test_target_fields_through_the_attractor_equal_the_direct_field():
    geometry, _ = paper_geometry()
    rng = np.random.default_rng(13)
    for _ in range(20):
        x = STANDBY + rng.uniform(-0.3, 0.3, 6)
        gamma = np.full(2, rng.uniform())
        targets = impact_target_fields(x, geometry.transitory, geometry.gain_matrix,
                                       geometry.desired_velocity, gamma,
                                       geometry.relative_projector)
        nominal = geometry.gain_matrix @ (x - geometry.transitory)
        direct = impact_target_field(nominal, geometry.desired_velocity, gamma,
                                     geometry.relative_projector)
        np.testing.assert_allclose(targets[:, 0].reshape(6), direct, atol=1e-12)
        np.testing.assert_allclose(targets[:, 1].reshape(6), nominal, atol=1e-12)
        np.testing.assert_allclose(targets[:, 2], targets[:, 1], atol=0.0)


@pytest.mark.parametrize('synchronise', [False, True])
def test_proposition_2_desired_velocity_along_e1_when_gamma_is_one(synchronise):
    geometry, impact = paper_geometry(impact=ImpactConfig(synchronise=synchronise))
    bases = geometry.bases
    rng = np.random.default_rng(14)
    for _ in range(50):
        local = rng.uniform(-0.05, 0.05, (2, 3))
        if synchronise:
            local[1, 0] = local[0, 0]   # equal progress along e1: the synchronised manifold
        x = (geometry.transitory.reshape(2, 3) + np.einsum('nki,ni->nk', bases, local)).reshape(6)
        targets = impact_target_fields(x, geometry.transitory, geometry.gain_matrix,
                                       geometry.desired_velocity, np.ones(2),
                                       geometry.relative_projector)
        nominal = (geometry.gain_matrix @ (x - geometry.transitory)).reshape(2, 3)
        velocity = modulated_velocity(bases, nominal, targets, np.ones(2))
        for h in range(2):
            e1 = bases[h][:, 0]
            assert abs(e1 @ velocity[h] - impact.impact_speed) < 1e-9
            for i in (1, 2):
                assert abs(bases[h][:, i] @ velocity[h] - bases[h][:, i] @ nominal[h]) < 1e-9


def test_synchronised_field_slows_the_leading_arm_at_the_relative_rate():
    geometry, impact = paper_geometry()
    lead = 0.01
    x = (geometry.transitory.reshape(2, 3) + 0.1 * geometry.bases[:, :, 0]).reshape(6)
    x[:3] += lead * geometry.bases[0][:, 0]
    targets = impact_target_fields(x, geometry.transitory, geometry.gain_matrix,
                                   geometry.desired_velocity, np.ones(2),
                                   geometry.relative_projector)
    e1 = geometry.bases[:, :, 0]
    # Relative rate 10 /s: the 1 cm lead is shared as -+ 10 / 2 * 0.01 m/s.
    assert e1[0] @ targets[0, 0] == pytest.approx(impact.impact_speed - 0.05, abs=1e-12)
    assert e1[1] @ targets[1, 0] == pytest.approx(impact.impact_speed + 0.05, abs=1e-12)


@pytest.mark.parametrize('boosted', [False, True])
@pytest.mark.parametrize('synchronise', [False, True])
def test_proposition_2_reach_hits_both_contacts_together(boosted, synchronise):
    geometry, impact = paper_geometry(impact=ImpactConfig(synchronise=synchronise))
    rng = np.random.default_rng(15)
    errors = []
    for start in STANDBY + rng.uniform(-0.15, 0.15, (20, 6)):
        hits = simulate_reach(start, geometry, impact, boosted)
        assert None not in hits, f'no contact from {start}'
        errors.append(contact_errors(hits, geometry, impact))
    gap, position, speed, angle = np.max(errors, axis=0)
    print(f'boosted={boosted} synchronise={synchronise}: max over 20 starts: '
          f'arrival gap {gap * 1e3:.2f} ms, '
          f'contact point {position * 1e3:.2f} mm, speed {speed * 100:.2f} %, '
          f'direction {angle:.2f} deg')
    assert gap < 0.005
    # The residual off the line to the grasp point grows with the speed: 3.5 mm at 0.5 m/s.
    assert position < 0.008 * impact.impact_speed
    assert speed < 0.02
    assert angle < 2.0


@pytest.mark.parametrize('synchronise, lower, upper', [(True, 0.0, 0.005), (False, 0.015, 1.0)])
def test_synchronisation_recovers_a_lag_during_the_run(synchronise, lower, upper):
    geometry, impact = paper_geometry(impact=ImpactConfig(synchronise=synchronise))
    hits = simulate_reach(STANDBY.copy(), geometry, impact, True, push=[-0.01, 0.0, 0.0])
    gap = contact_errors(hits, geometry, impact)[0]
    print(f'synchronise={synchronise}: 1 cm lag mid-run -> arrival gap {gap * 1e3:.2f} ms')
    assert lower <= gap < upper


def test_arm_pushed_off_its_line_mid_run_still_arrives_with_the_other():
    """
    A 1 cm lateral push 0.1 m before contact is only partly undone by contact (exp(-1)).

    With the 2 cm wide normal region (sized for the torque-controlled arms' tracking error)
    the lateral residual r stays below 7 mm at 0.5 m/s (it grows with the speed); it moves the
    face-plane crossing by up to r |n . e_lateral| / (v n . e1), about 10 ms at 6 mm, hence
    the bounds; progress along e1
    itself stays synchronised (previous test). The residual also tilts the arrival direction:
    up to 4 deg after a push (2 deg without pushes, Proposition 2 test).
    """
    geometry, impact = paper_geometry()
    for push in ([0.0, 0.015, 0.0], [0.0, 0.0, -0.01], [-0.005, 0.01, 0.0], [0.0, 0.01, 0.01]):
        hits = simulate_reach(STANDBY.copy(), geometry, impact, True, push=push)
        gap, position, speed, angle = contact_errors(hits, geometry, impact)
        print(f'left arm pushed by {push} m mid-run: gap {gap * 1e3:.2f} ms, contact point '
              f'{position * 1e3:.2f} mm, speed {speed * 100:.2f} %, direction {angle:.2f} deg')
        assert gap < 0.010
        assert position < 0.014 * impact.impact_speed
        assert speed < 0.02
        assert angle < 4.0


def test_decoupled_arms_do_not_arrive_together():
    geometry, impact = paper_geometry(coordination=CoordinationConfig(coordinated=False))
    rng = np.random.default_rng(15)
    gaps = [contact_errors(simulate_reach(start, geometry, impact, True), geometry, impact)[0]
            for start in STANDBY + rng.uniform(-0.15, 0.15, (5, 6))]
    print(f'decoupled: max arrival gap {max(gaps) * 1e3:.1f} ms')
    assert max(gaps) > 0.02


def test_world_frame_coupling_stalls_off_the_impact_lines():
    """Eq. 4's A' in world coordinates pushes each arm off its tilted line: no contact."""
    geometry, impact = paper_geometry()
    world = geometry._replace(gain_matrix=coordinated_gain_matrix(CoordinationConfig()))
    hits = simulate_reach(STANDBY.copy(), world, impact, boosted=False, duration=3.0)
    assert hits == [None, None]


def test_impact_ds_is_the_desired_velocity_on_both_lines():
    geometry, impact = paper_geometry()
    x = (geometry.transitory.reshape(2, 3) + 0.1 * geometry.bases[:, :, 0]).reshape(6)
    output = impact_ds_velocity(x, geometry)
    activation = output.activation.alpha[0] * output.activation.gamma[0]
    assert activation > 0.999
    # Eqs. 3 and 6 on the line: the velocity blends x_dot_d with f_n with weight alpha gamma,
    # so it differs from x_dot_d by at most (1 - alpha gamma) (|x_dot_d| + |f_n|).
    speed = np.linalg.norm(geometry.desired_velocity.reshape(2, 3), axis=1).max()
    bound = (1.0 - activation) * (speed + np.linalg.norm(output.nominal)) + 1e-9
    np.testing.assert_allclose(output.velocity, geometry.desired_velocity, atol=bound)


def test_impact_ds_far_away_is_the_nominal_field():
    geometry, _ = paper_geometry()
    output = impact_ds_velocity(STANDBY, geometry)
    assert output.activation.alpha[0] < 1e-6
    np.testing.assert_allclose(output.velocity, output.nominal, atol=1e-6)
    np.testing.assert_allclose(output.nominal,
                               geometry.gain_matrix @ (STANDBY - geometry.transitory))


@pytest.mark.parametrize('field, value', [
    ('impact_speed', 0.0), ('impact_speed', 3.0), ('max_tilt_deg', 95.0),
    ('max_tilt_deg', -1.0), ('synchronise', 1), ('region', {'rho': 0.1})])
def test_config_rejects_bad_values_naming_the_field(field, value):
    with pytest.raises(ConfigError, match=field):
        ImpactConfig(**{field: value})


def test_region_is_a_nested_config():
    config = ImpactConfig(region=ModulationRegionConfig(transitory_distance=0.1,
                                                        radial_distance=0.15))
    assert config.region.transitory_distance == 0.1
