"""Release velocity, flight time and landing prediction: closed forms against integration."""

import math

from dual_arm_control.core.ballistics import (centre_landing_height, flight_time, FlightModel,
                                              landing_by_integration, landing_without_drag,
                                              minimum_speed_elevation, release_speed,
                                              release_velocity_at_elevation,
                                              release_velocity_minimum_speed,
                                              STANDARD_GRAVITY, UnreachableTargetError)
from dual_arm_control.core.exceptions import ConfigError, InputError
import numpy as np
import pytest

G = STANDARD_GRAVITY
RELEASE = np.array([0.68, 0.0, 0.37])
TARGETS = [np.array([1.2, 0.3, 0.05]), np.array([0.9, -0.4, 0.37]),
           np.array([1.5, 0.2, 0.6]), np.array([0.7, 0.01, -0.2])]


def random_releases(count, seed):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        yield (rng.uniform([0.3, -0.5, 0.2], [0.9, 0.5, 0.8]),
               rng.uniform([-1.0, -1.0, -1.0], [2.5, 1.0, 3.0]))


def test_closed_form_landing_matches_rk4_without_drag():
    worst = 0.0
    for p_release, v_release in random_releases(50, seed=1):
        closed = landing_without_drag(p_release, v_release, 0.05)
        integrated = landing_by_integration(p_release, v_release, 0.05)
        worst = max(worst, np.max(np.abs(closed.position - integrated.position)))
        np.testing.assert_allclose(integrated.position, closed.position, atol=1e-6)
        np.testing.assert_allclose(integrated.velocity, closed.velocity, atol=1e-6)
        assert integrated.flight_time == pytest.approx(closed.flight_time, abs=1e-9)
        assert closed.position[2] == pytest.approx(0.05, abs=1e-12)
    print(f'worst closed-form vs RK4 landing difference: {worst:.2e} m')


def test_rk4_with_drag_matches_the_exact_vertical_fall_with_fourth_order_convergence():
    # Vertical fall from rest with quadratic drag k: v_t = sqrt(g / k),
    # depth(t) = v_t^2 / g ln cosh(g t / v_t), so t_land = v_t / g acosh(exp(h g / v_t^2)).
    k, h = 0.4, 1.5
    terminal = math.sqrt(G / k)
    t_land = terminal / G * math.acosh(math.exp(h * G / terminal ** 2))
    v_land = terminal * math.tanh(G * t_land / terminal)
    speed_errors = []
    for step in (0.02, 0.01):
        landing = landing_by_integration([0.0, 0.0, h], np.zeros(3), 0.0,
                                         FlightModel(drag_coefficient=k, integration_step=step))
        speed_errors.append(abs(landing.velocity[2] + v_land))
        print(f'drag fall, step {step} s: time error {landing.flight_time - t_land:.2e} s, '
              f'speed error {speed_errors[-1]:.2e} m/s')
        assert landing.flight_time == pytest.approx(t_land, abs=1e-8)
        assert landing.position[2] == pytest.approx(0.0, abs=1e-12)
    # Classical RK4: halving the step divides the error by 2^4 (an Euler-like scheme: by 2).
    assert 12.0 < speed_errors[0] / speed_errors[1] < 20.0
    assert speed_errors[1] < 1e-7


def test_minimum_speed_elevation_minimises_speed_over_a_grid():
    for target in TARGETS:
        delta = target - RELEASE
        r, z = math.hypot(delta[0], delta[1]), delta[2]
        best = minimum_speed_elevation(r, z)
        line_of_sight = math.atan2(z, r)
        grid = np.linspace(line_of_sight + 1e-3, 0.5 * math.pi - 1e-3, 2001)
        speeds = np.array([release_speed(r, z, theta) for theta in grid])
        v_best = release_speed(r, z, best)
        assert v_best <= speeds.min() + 1e-12
        assert abs(grid[np.argmin(speeds)] - best) <= grid[1] - grid[0]
        assert v_best ** 2 == pytest.approx(G * (math.hypot(r, z) + z), rel=1e-12)
        solution = release_velocity_minimum_speed(RELEASE, target)
        assert solution.speed == pytest.approx(v_best, rel=1e-12)


@pytest.mark.parametrize('elevation', [None, 0.3, 0.8, 1.2])
def test_release_velocity_lands_on_target_when_simulated(elevation):
    for target in TARGETS:
        delta = target - RELEASE
        if elevation is None:
            solution = release_velocity_minimum_speed(RELEASE, target)
        elif math.tan(elevation) < 2.0 * delta[2] / math.hypot(delta[0], delta[1]):
            with pytest.raises(UnreachableTargetError, match='still rising|line of sight'):
                release_velocity_at_elevation(RELEASE, target, elevation)
            continue
        else:
            solution = release_velocity_at_elevation(RELEASE, target, elevation)
        assert np.linalg.norm(solution.velocity) == pytest.approx(solution.speed, rel=1e-12)
        landing = landing_by_integration(RELEASE, solution.velocity, target[2])
        np.testing.assert_allclose(landing.position, target, atol=1e-6)
        assert landing.flight_time == pytest.approx(solution.flight_time, abs=1e-9)
        assert landing.velocity[2] < 0.0


def test_flight_time_formula_is_the_descending_root():
    v, theta, z = 3.0, 0.7, -0.25
    t = flight_time(v, theta, z)
    assert v * math.sin(theta) * t - 0.5 * G * t ** 2 == pytest.approx(z, abs=1e-12)
    assert v * math.sin(theta) - G * t < 0.0
    assert flight_time(v, theta, 0.0) == pytest.approx(2.0 * v * math.sin(theta) / G)


def test_drag_shortens_the_range():
    v_release = release_velocity_minimum_speed(RELEASE, TARGETS[0]).velocity
    ranges = []
    for k in (0.0, 0.05, 0.2, 0.5):
        landing = landing_by_integration(RELEASE, v_release, TARGETS[0][2],
                                         FlightModel(drag_coefficient=k))
        ranges.append(np.linalg.norm(landing.position[:2] - RELEASE[:2]))
    print('range vs drag coefficient 0, 0.05, 0.2, 0.5 1/m:', np.round(ranges, 4))
    assert ranges[0] == pytest.approx(np.linalg.norm(TARGETS[0][:2] - RELEASE[:2]), abs=1e-6)
    assert all(a > b for a, b in zip(ranges, ranges[1:]))


def test_vertical_targets():
    above = release_velocity_minimum_speed(RELEASE, RELEASE + [0.0, 0.0, 0.2])
    np.testing.assert_allclose(above.velocity, [0.0, 0.0, math.sqrt(2.0 * G * 0.2)],
                               atol=1e-12)
    below = release_velocity_minimum_speed(RELEASE, RELEASE - [0.0, 0.0, 0.2])
    assert below.speed == 0.0
    assert below.flight_time == pytest.approx(math.sqrt(2.0 * 0.2 / G))


def test_box_centre_lands_half_a_height_above_the_table():
    box_height = 0.1
    landing_height = centre_landing_height(0.05, box_height)
    assert landing_height == pytest.approx(0.1)
    landing = landing_without_drag(RELEASE, [1.0, 0.0, 0.5], landing_height)
    assert landing.position[2] - 0.5 * box_height == pytest.approx(0.05)


def test_unreachable_targets_raise_clear_errors():
    target = TARGETS[0]
    with pytest.raises(UnreachableTargetError, match='line of sight'):
        release_velocity_at_elevation(RELEASE, target, -0.6)
    with pytest.raises(UnreachableTargetError, match='still rising'):
        release_velocity_at_elevation(RELEASE, RELEASE + [1.0, 0.0, 0.3], 0.45)
    with pytest.raises(UnreachableTargetError, match='above the limit'):
        release_velocity_minimum_speed(RELEASE, RELEASE + [3.0, 0.0, 0.0], max_speed=2.0)
    with pytest.raises(UnreachableTargetError, match='between -90 and 90'):
        release_speed(0.5, 0.0, 0.5 * math.pi)
    with pytest.raises(UnreachableTargetError, match='undefined'):
        release_velocity_at_elevation(RELEASE, RELEASE + [0.0, 0.0, 0.3], 0.5)
    with pytest.raises(UnreachableTargetError, match='apex'):
        flight_time(1.0, 0.5, 0.5)
    with pytest.raises(UnreachableTargetError, match='apex'):
        landing_without_drag(RELEASE, [1.0, 0.0, 1.0], RELEASE[2] + 0.2)
    with pytest.raises(UnreachableTargetError, match='apex'):
        landing_by_integration(RELEASE, [1.0, 0.0, 1.0], RELEASE[2] + 0.2)
    with pytest.raises(UnreachableTargetError, match='without upward speed'):
        landing_by_integration(RELEASE, [1.0, 0.0, 0.0], RELEASE[2] + 0.2)
    with pytest.raises(UnreachableTargetError, match='still above'):
        landing_by_integration(RELEASE, [1.0, 0.0, 30.0], 0.0, FlightModel(max_flight_time=1.0))
    with pytest.raises(InputError, match='coincide'):
        release_velocity_minimum_speed(RELEASE, RELEASE)
    with pytest.raises(InputError, match='NaN'):
        landing_without_drag([math.nan, 0.0, 0.0], [1.0, 0.0, 1.0], 0.0)


def test_flight_model_rejects_bad_values():
    with pytest.raises(ConfigError, match='drag_coefficient'):
        FlightModel(drag_coefficient=-0.1)
    with pytest.raises(ConfigError, match='integration_step'):
        FlightModel(integration_step=0.0)
