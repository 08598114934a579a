"""
The conveyor's pieces: container tracking, the landing-time fixed point, the belt, the metrics.

Container tracking is judged against the filter's own published uncertainty: the truth moves at
constant velocity (the filter's model, so its covariance is exact), and over many seeds and
query times the prediction error must stay within 4 standard deviations of what the filter
reports. A filter that dropped its velocity correction, or ignored the samples' stamps (the
latency), misses by far more than that.
"""

from dataclasses import replace

from dual_arm_control.core.ballistics import landing_without_drag, UnreachableTargetError
from dual_arm_control.core.container_tracker import ContainerTracker, ContainerTrackerConfig
from dual_arm_control.core.estimate import MeasurementOutcome
from dual_arm_control.core.moving_target import (aim_at_moving_container, ConveyorTossConfig,
                                                 time_to_release)
from dual_arm_control.core.phases import Phase
from dual_arm_control.core.toss_planning import plan_release, ReleasePlanningConfig
from dual_arm_control.description.cell import load_cell
from dual_arm_control.evaluation.container_metrics import container_metrics
from dual_arm_control.scenario import load_scenario
import numpy as np
import pytest
from sim_bridge.belt import disturbed_speed
from sim_bridge.twin import DualArmTwin

PERIOD = 0.005
LATENCY = 0.005
NOISE = 0.0005
BELT_VELOCITY = np.array([0.0, -0.35, 0.0])
START = np.array([0.92, 0.5, 0.18])
CELL = load_cell()


def _tracked(seed, duration):
    """Feed a tracker samples of the constant-velocity belt; return it and the truth function."""
    rng = np.random.default_rng(seed)
    tracker = ContainerTracker(ContainerTrackerConfig(position_noise=NOISE))

    def truth(t):
        return START + BELT_VELOCITY * t

    for k in range(int(round(duration / PERIOD)) + 1):
        stamp = k * PERIOD
        outcome = tracker.update(stamp, truth(stamp) + rng.normal(0.0, NOISE, 3))
        assert outcome in (MeasurementOutcome.INITIALISED, MeasurementOutcome.ACCEPTED)
    return tracker, truth


@pytest.mark.parametrize('horizon', [LATENCY, 0.3, 0.6])
def test_container_prediction_within_its_published_uncertainty(horizon):
    worst = 0.0
    for seed in range(20):
        tracker, truth = _tracked(seed, 1.0)
        t = 1.0 + horizon
        prediction = tracker.prediction(t)
        error = np.abs(prediction.position - truth(t))
        worst = max(worst, float(np.max(error / np.sqrt(prediction.position_variance))))
        velocity_error = np.abs(prediction.velocity - BELT_VELOCITY)
        assert np.all(velocity_error <= 4.0 * np.sqrt(prediction.velocity_variance))
    assert worst <= 4.0


def test_container_uncertainty_grows_with_the_horizon():
    tracker, _ = _tracked(0, 1.0)
    variances = [tracker.prediction(1.0 + h).position_variance for h in (0.0, 0.1, 0.3, 0.6)]
    assert np.all(np.diff(variances) > 0.0)
    assert np.sqrt(variances[-1]) > 2.0 * np.sqrt(variances[0])


def test_container_stale_outlier_and_invalid_samples_are_refused():
    tracker, truth = _tracked(1, 0.5)
    assert tracker.update(0.5, truth(0.5)) is MeasurementOutcome.REJECTED_STALE
    assert tracker.update(0.505, truth(0.505) + [0.0, 0.05, 0.0]) is \
        MeasurementOutcome.REJECTED_OUTLIER
    assert tracker.update(0.51, [np.nan, 0.0, 0.0]) is MeasurementOutcome.REJECTED_INVALID
    assert tracker.update(0.515, truth(0.515)) is MeasurementOutcome.ACCEPTED


def _belt(now, y_now, speed):
    """Return container_position_at(t) of a belt moving toward -y, at landing height 0.32 m."""
    def position_at(t):
        return np.array([0.92, y_now - speed * (t - now), 0.32])
    return position_at


@pytest.mark.parametrize('speed, y_now', [(0.1, 0.25), (0.4, 0.5)])
def test_fixed_point_lands_where_the_container_will_be(speed, y_now):
    nominal = np.array([0.68, 0.0, 0.45])
    planning = ReleasePlanningConfig(x_range=(0.7, 0.7), y_range=(0.02, 0.02),
                                     z_range=(0.47, 0.47))
    config = ConveyorTossConfig()
    now = 2.0
    position_at = _belt(now, y_now, speed)

    def plan_for(target):
        return plan_release(target, nominal, planning)

    def release_in_for(plan):
        return 1.0 + 0.3 * np.linalg.norm(plan.velocity)

    aim = aim_at_moving_container(now, position_at, plan_for, release_in_for,
                                  position_at(now + 1.3), config)
    flight = landing_without_drag(aim.plan.position, aim.plan.velocity, aim.target[2])
    landing_time = now + release_in_for(aim.plan) + flight.flight_time
    assert aim.landing_time == pytest.approx(landing_time, abs=1e-9)
    assert np.linalg.norm(position_at(landing_time) - aim.target) < 1e-3
    assert np.linalg.norm(flight.position - aim.target) < 1e-6
    assert aim.residual < 1e-3


def test_fixed_point_refuses_a_container_out_of_the_served_region():
    config = ConveyorTossConfig()

    def plan_for(target):
        return plan_release(target, np.array([0.68, 0.0, 0.45]), ReleasePlanningConfig())

    with pytest.raises(UnreachableTargetError):
        aim_at_moving_container(0.0, _belt(0.0, 1.5, 0.0), plan_for, lambda plan: 1.0,
                                np.array([0.92, 1.5, 0.32]), config)


def test_time_to_release_follows_the_phase():
    config = ConveyorTossConfig(reach_duration=1.4, run_in_speed=0.5, carry_lag=0.02)
    release = np.array([0.68, 0.0, 0.45])
    velocity = np.array([0.8, 0.0, 0.0])
    obj = np.array([0.44, 0.0, 0.45])
    carry = 0.02 + 0.24 / 0.8
    assert time_to_release(Phase.STANDBY, 0.0, 0.5, obj, release, velocity, config) == \
        pytest.approx(1.4 + carry)
    assert time_to_release(Phase.REACH, 1.0, 0.1, obj, release, velocity, config) == \
        pytest.approx(0.4 + carry)
    assert time_to_release(Phase.REACH, 1.3, 0.1, obj, release, velocity, config) == \
        pytest.approx(0.2 + carry)
    assert time_to_release(Phase.MANIPULATE, 0.1, 0.0, obj, release, velocity, config) == \
        pytest.approx(carry)
    assert time_to_release(Phase.RELEASE, 0.0, 0.0, obj, release, velocity, config) is None


def test_belt_speed_disturbance_spans_its_amplitude_after_the_start():
    times = np.linspace(1.0, 3.0, 2001)
    speeds = np.array([disturbed_speed(0.3, t, 1.0, 0.2, 2.0, 0.7) for t in times])
    assert speeds.max() == pytest.approx(0.36, abs=1e-4)
    assert speeds.min() == pytest.approx(0.24, abs=1e-4)
    assert disturbed_speed(0.3, 0.999, 1.0, 0.2, 2.0, 0.7) == 0.0
    assert disturbed_speed(0.3, 1.5, 1.0, 0.0, 2.0, 0.7) == 0.3


def test_belt_drive_moves_the_container_at_the_disturbed_speed():
    scenario = load_scenario('conveyor_toss', cell=CELL)
    twin = DualArmTwin(scenario, CELL)
    conveyor = scenario.conveyor
    start = conveyor.container_start_time
    hold = {arm: twin.hold_torques(arm) for arm in twin.arms}
    expected, tick = conveyor.container_start, 0
    while twin.time < start + 0.5 - 1e-9:
        for _ in range(2):
            expected -= disturbed_speed(
                conveyor.speed, tick * 1e-3, start, conveyor.disturbance_amplitude,
                conveyor.disturbance_period, twin.container.belt.phase) * 1e-3
            tick += 1
        twin.step(hold)
        hold = {arm: twin.hold_torques(arm) for arm in twin.arms}
    position, velocity = twin.container.pose(twin.data)
    assert position[1] == pytest.approx(expected, abs=1e-9)
    assert position[1] < conveyor.container_start - 0.5 * 0.8 * conveyor.speed
    assert velocity[1] == pytest.approx(-twin.container.belt.at(twin.time - 1e-3), abs=1e-9)
    twin.set_belt_speed(0.0)
    twin.step(hold)
    assert twin.container.pose(twin.data)[1][1] == 0.0


def test_container_samples_come_after_the_mocap_latency():
    scenario = load_scenario('conveyor_toss', cell=CELL)
    twin = DualArmTwin(scenario, CELL)
    hold = {arm: twin.hold_torques(arm) for arm in twin.arms}
    delivered = []
    for _ in range(10):
        twin.step(hold)
        delivered += [(twin.time, sample) for sample in twin.container_mocap_samples()]
    assert delivered
    latency = scenario.sensors.mocap.latency
    for time, sample in delivered:
        assert time >= sample.stamp + latency - 1e-9
        assert np.linalg.norm(sample.p_world - [scenario.conveyor.belt_x,
                                                scenario.conveyor.container_start,
                                                scenario.conveyor.floor_top_height]) < 0.005


def test_conveyor_config_is_checked():
    scenario = load_scenario('conveyor_toss', cell=CELL)
    with pytest.raises(Exception, match='inner_size'):
        replace(scenario.conveyor, inner_size=(0.3, -0.2))


def test_container_metrics_judge_where_the_box_passed_the_rim_and_ended():
    conveyor = load_scenario('conveyor_toss', cell=CELL).conveyor
    rim = conveyor.rim_height
    container = np.array([[0.92, 0.1 - 0.01 * k, conveyor.floor_top_height] for k in range(6)])
    inside = np.array([[0.80, 0.10, rim + 0.20], [0.86, 0.09, rim + 0.12],
                       [0.93, 0.075, rim + 0.08], [0.94, 0.07, rim + 0.02],
                       [0.945, 0.06, conveyor.floor_top_height + 0.08],
                       [0.945, 0.05, conveyor.floor_top_height + 0.08]])
    result = container_metrics({'object_position': inside, 'container_position': container},
                               conveyor, 0.16, 0)
    assert result['container_landing_index'] == 2
    assert result['landing_offset_in_container'] == pytest.approx([0.01, -0.005])
    assert result['landing_error_in_container'] == pytest.approx(np.hypot(0.01, 0.005))
    assert result['landed_in_container'] is True
    on_the_wall = inside.copy()
    on_the_wall[-1] = [0.92 + 0.5 * conveyor.inner_size[0] + 0.03, 0.05, rim + 0.08]
    assert container_metrics({'object_position': on_the_wall, 'container_position': container},
                             conveyor, 0.16, 0)['landed_in_container'] is False
    beside = inside.copy()
    beside[-1] = [0.92, 0.05 - 0.5 * conveyor.inner_size[1] - 0.02, 0.23]
    assert container_metrics({'object_position': beside, 'container_position': container},
                             conveyor, 0.16, 0)['landed_in_container'] is False
