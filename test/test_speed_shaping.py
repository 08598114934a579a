"""Speed shaping of the DS outputs ("boosted" fields) and the first-order speed filter."""

from dataclasses import replace
import math

from dual_arm_control.core.exceptions import ConfigError, InputError
from dual_arm_control.core.manipulation import TossConfig
from dual_arm_control.core.motion_config import MotionGeneratorConfig
from dual_arm_control.core.motion_generator import DualArmMotionGenerator
from dual_arm_control.core.speed_shaping import (
    arm_velocities_near_object, boosted_coordinated_velocity, boosted_velocity, profile_speed,
    reach_speed, released_velocity, saturated_velocity, speed_blend_weight, SpeedErrorIntegrator,
    SpeedFilter, SpeedProfileConfig)
import numpy as np
import pytest


def test_blend_weight_is_a_smooth_step_between_the_distances():
    distances = np.linspace(0.0, 1.0, 1001)
    weight = speed_blend_weight(distances, 0.25, 0.5)
    assert np.all(weight[distances <= 0.25] == 0.0)
    assert np.all(weight[distances >= 0.5] == 1.0)
    assert np.all(np.diff(weight) >= 0.0)
    assert speed_blend_weight(0.375, 0.25, 0.5) == pytest.approx(0.5)
    # Continuous slope: zero derivative at both ends.
    step = 1e-7
    for edge in (0.25, 0.5):
        slope = (speed_blend_weight(edge + step, 0.25, 0.5)
                 - speed_blend_weight(edge - step, 0.25, 0.5)) / (2 * step)
        assert abs(slope) < 1e-5


def test_reach_speed_is_impact_speed_near_and_reach_speed_far():
    config = SpeedProfileConfig()
    assert reach_speed(0.1, 0.45, config) == pytest.approx(0.45)
    assert reach_speed(config.near_distance, 0.45, config) == pytest.approx(0.45)
    assert reach_speed(2.0, 0.45, config) == pytest.approx(config.reach_speed)
    middle = 0.5 * (config.near_distance + config.far_distance)
    assert reach_speed(middle, 0.45, config) == pytest.approx(0.5 * (0.45 + 0.85))
    assert profile_speed(0.0, 1.0, 2.0, 0.1, 0.2) == 1.0


def test_boosted_velocity_keeps_direction_and_imposes_speed():
    rng = np.random.default_rng(30)
    velocity = rng.normal(size=(10, 3))
    speeds = rng.uniform(0.1, 1.0, 10)
    boosted = boosted_velocity(velocity, speeds)
    np.testing.assert_allclose(np.linalg.norm(boosted, axis=1), speeds, atol=1e-14)
    np.testing.assert_allclose(np.cross(boosted, velocity), 0.0, atol=1e-14)
    assert np.all(np.einsum('ij,ij->i', boosted, velocity) > 0.0)
    np.testing.assert_array_equal(boosted_velocity(np.zeros(3), 0.85), np.zeros(3))


def test_boosted_coordinated_velocity_scales_both_arms_alike():
    velocity = np.array([0.3, -0.4, 0.0, 0.1, 0.1, 0.0])
    boosted = boosted_coordinated_velocity(velocity, 0.45)
    np.testing.assert_allclose(boosted, velocity * 0.45 / 0.5, atol=1e-15)
    assert np.linalg.norm(boosted[:3]) == pytest.approx(0.45)
    np.testing.assert_array_equal(boosted_coordinated_velocity(np.zeros(6), 0.45), np.zeros(6))


def test_saturated_velocity_caps_only_fast_points():
    velocity = np.array([[0.3, 0.0, 0.0], [0.0, 3.0, 4.0]])
    capped = saturated_velocity(velocity, 1.0)
    np.testing.assert_array_equal(capped[0], velocity[0])
    np.testing.assert_allclose(capped[1], [0.0, 0.6, 0.8], atol=1e-15)
    np.testing.assert_array_equal(saturated_velocity(np.zeros(3), 1.0), np.zeros(3))


def test_a_single_point_saturates_as_a_row_of_the_array_form():
    rng = np.random.default_rng(5)
    points = rng.normal(size=(2000, 3)) * 10.0 ** rng.uniform(-9, 2, size=(2000, 1))
    limits = 10.0 ** rng.uniform(-2, 1, size=2000)
    for point, limit in zip(points, limits):
        np.testing.assert_array_equal(saturated_velocity(point, limit),
                                      saturated_velocity(point[None], limit)[0])
    with np.errstate(invalid='ignore'):
        assert np.all(np.isnan(saturated_velocity(np.array([np.nan, 0.0, 0.0]), 1.0)))


def test_speed_filter_response_does_not_depend_on_the_step():
    results = []
    for dt in (0.001, 0.005):
        speed_filter = SpeedFilter(time_constant=0.05)
        for _ in range(int(round(0.05 / dt))):
            speed = speed_filter.update(0.85, dt)
        results.append(speed)
    np.testing.assert_allclose(results, 0.85 * (1.0 - math.exp(-1.0)), rtol=1e-12)
    speed_filter = SpeedFilter(0.05, initial_speed=0.45)
    assert speed_filter.update(0.85, 0.0) == 0.45
    speed_filter.reset()
    assert speed_filter.speed == 0.0


def test_speed_filter_rejects_bad_inputs():
    with pytest.raises(ConfigError, match='time_constant'):
        SpeedFilter(0.0)
    with pytest.raises(InputError, match='dt'):
        SpeedFilter(0.05).update(1.0, -0.001)
    with pytest.raises(InputError, match='dt'):
        SpeedFilter(0.05).update(1.0, float('nan'))


@pytest.mark.parametrize('field, value', [
    ('reach_speed', 0.0), ('reach_speed', 2.5), ('near_distance', -0.1),
    ('far_distance', 0.2), ('time_constant', 0.0)])
def test_config_rejects_bad_values_naming_the_field(field, value):
    with pytest.raises(ConfigError, match=field):
        SpeedProfileConfig(**{field: value})


@pytest.mark.parametrize('changes, name', [
    ({'max_carry_speed': 1.5}, 'release_planning.max_release_speed'),
    ({'toss': TossConfig(toss_speed=2.2)}, 'toss.toss_speed')])
def test_a_release_faster_than_the_carry_cap_is_refused_naming_both(changes, name):
    """The carry's tool-speed cap must let the box reach every release speed it may be given."""
    with pytest.raises(ConfigError, match=f'{name} = .* exceeds max_carry_speed'):
        MotionGeneratorConfig(**changes)


def test_the_speed_loop_makes_up_a_lagging_tracker_without_turning_the_direction():
    """A plant reaching 94 % of its command is brought to the desired speed, same direction."""
    loop = SpeedErrorIntegrator(integral_gain=20.0, limit_ratio=0.25)
    desired = np.array([0.8, 0.1, 0.4])
    measured = np.zeros(3)
    for _ in range(400):
        command = loop.update(desired, measured, 0.005)
        measured = 0.94 * command
    assert np.linalg.norm(measured) == pytest.approx(np.linalg.norm(desired), rel=0.005)
    assert np.cross(command, desired) == pytest.approx(np.zeros(3), abs=1e-12)


def test_the_speed_loop_is_capped_and_forgets_on_reset():
    """A stalled measurement cannot push the command beyond (1 + limit) times the DS speed."""
    loop = SpeedErrorIntegrator(integral_gain=50.0, limit_ratio=0.25)
    desired = np.array([0.0, 0.6, 0.0])
    for _ in range(200):
        command = loop.update(desired, np.zeros(3), 0.005)
    assert np.linalg.norm(command) == pytest.approx(0.75)
    loop.reset()
    assert loop.update(desired, desired, 0.005) == pytest.approx(desired)
    with pytest.raises(ConfigError):
        SpeedErrorIntegrator(integral_gain=-1.0, limit_ratio=0.25)


def test_a_live_parameter_change_keeps_the_speed_loop_correction():
    """Reconfiguring mid-toss (any parameter) takes the new gains, not a zeroed integral."""
    config = MotionGeneratorConfig()
    generator = DualArmMotionGenerator(config)
    loop = generator._toss_feedback
    loop.update(np.array([1.0, 0.0, 0.0]), np.array([0.8, 0.0, 0.0]), 0.005)
    integrated = loop.correction
    assert integrated == pytest.approx(config.toss.speed_integral_gain * 0.005 * 0.2)
    generator.reconfigure(replace(config, toss=replace(config.toss, speed_integral_gain=30.0),
                                  max_linear_speed=1.2))
    assert generator._toss_feedback.correction == integrated
    assert generator._toss_feedback.integral_gain == 30.0


def test_the_pads_keep_the_configured_share_of_the_speed_loop_correction_as_they_open():
    """The release velocity is the toss field plus its share (half by default) of the loop's."""
    field = np.array([0.7603, 0.0, 0.3801])
    loop = SpeedErrorIntegrator(integral_gain=40.0, limit_ratio=0.45)
    for _ in range(100):
        corrected = loop.update(field, 0.92 * field, 0.005)
    assert np.linalg.norm(corrected) > 1.1 * np.linalg.norm(field)
    share = TossConfig().release_correction_share
    assert share == 0.5
    np.testing.assert_allclose(released_velocity(field, corrected, 0.0), field)
    np.testing.assert_allclose(released_velocity(field, corrected, 1.0), corrected)
    kept = released_velocity(field, corrected, share)
    np.testing.assert_allclose(kept - field, 0.5 * (corrected - field))
    assert np.cross(kept, field) == pytest.approx(np.zeros(3), abs=1e-12)


def test_near_the_object_each_arm_moves_at_the_speed_far_from_it_the_arms_keep_their_ratio():
    config = SpeedProfileConfig()
    # The coordinated field asks the left arm (waiting for the right) for half the speed.
    field = np.array([0.0, -0.2, 0.0, 0.0, 0.4, 0.0])
    far = arm_velocities_near_object(field, 0.85, config.far_distance, config)
    np.testing.assert_allclose(np.linalg.norm(far, axis=1), [0.425, 0.85])
    near = arm_velocities_near_object(field, 0.5, config.near_distance, config)
    np.testing.assert_allclose(near, [[0.0, -0.5, 0.0], [0.0, 0.5, 0.0]])
    between = arm_velocities_near_object(
        field, 0.6, 0.5 * (config.near_distance + config.far_distance), config)
    assert 0.3 < np.linalg.norm(between[0]) < 0.6
    np.testing.assert_allclose(np.linalg.norm(between[1]), 0.6)
