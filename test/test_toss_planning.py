"""
Release planning for a landing target (core/toss_planning.py) and a target changed at run time.

The planner must land the box centre on the target by the drag-free parabola, from a point of
the release region the arms can hold, within the speed and direction limits; a target it cannot
serve is refused with the limit it misses. The in-process episode checks the physical outcome:
a target handed over mid-reach is where the box lands.
"""

from dataclasses import replace
import itertools
import math

from dual_arm_control.core.arms import ARMS
from dual_arm_control.core.ballistics import landing_without_drag, UnreachableTargetError
from dual_arm_control.core.reachability import plan_grasp, ReachabilityConfig
from dual_arm_control.core.release import clear_of_the_box
from dual_arm_control.core.toss_planning import (plan_release, release_candidates,
                                                 ReleasePlanningConfig)
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.evaluation.episode import episode_metrics
from dual_arm_control.inprocess import run_episode, RunnerConfig
from dual_arm_control.scenario import load_scenario
import numpy as np
import pytest

NOMINAL = np.array([0.68, 0.0, 0.45])
CONFIG = ReleasePlanningConfig()


@pytest.fixture(scope='module')
def cell():
    return load_cell()


@pytest.mark.parametrize('target', [(0.75, -0.3, 0.25), (0.85, 0.0, 0.25), (0.95, 0.15, 0.25),
                                    (1.0, -0.15, 0.25), (0.80, 0.2, 0.30),
                                    (1.15, -0.3, 0.25), (1.15, 0.3, 0.25)])
def test_the_planned_release_lands_on_the_target_within_the_limits(target):
    target = np.array(target)
    plan = plan_release(target, NOMINAL, CONFIG)
    landing = landing_without_drag(plan.position, plan.velocity, target[2])
    np.testing.assert_allclose(landing.position[:2], target[:2], atol=1e-9)
    np.testing.assert_allclose(plan.predicted_landing, landing.position, atol=1e-12)
    speed = np.linalg.norm(plan.velocity)
    assert CONFIG.min_release_speed - 1e-9 <= speed <= CONFIG.max_release_speed
    elevation = math.degrees(math.asin(plan.velocity[2] / speed))
    assert CONFIG.min_elevation_deg <= elevation <= CONFIG.max_elevation_deg
    assert abs(math.degrees(math.atan2(plan.velocity[1], plan.velocity[0]))) \
        <= CONFIG.max_heading_deg
    assert abs(plan.velocity[1]) <= CONFIG.max_lateral_speed + 1e-9
    for value, (low, high) in zip(plan.position, (CONFIG.x_range, CONFIG.y_range,
                                                  CONFIG.z_range)):
        assert low - 1e-9 <= value <= high + 1e-9


def test_a_near_target_is_thrown_at_the_task_speed_and_a_far_one_faster():
    near = plan_release(np.array([0.80, 0.0, 0.25]), NOMINAL, CONFIG)
    far = plan_release(np.array([1.0, 0.0, 0.25]), NOMINAL, CONFIG)
    assert np.linalg.norm(near.velocity) == pytest.approx(CONFIG.min_release_speed)
    assert np.linalg.norm(far.velocity) > CONFIG.min_release_speed + 0.2


@pytest.mark.parametrize('target, limit', [((1.6, 0.0, 0.25), 'max_release_speed'),
                                           ((0.70, 0.6, 0.25), 'max_heading_deg'),
                                           ((0.85, -0.45, 0.25), 'max_lateral_speed')])
def test_a_target_no_release_serves_is_refused_with_the_limit(target, limit):
    with pytest.raises(UnreachableTargetError, match=limit):
        plan_release(np.array(target), NOMINAL, CONFIG)


def test_a_bad_region_is_refused():
    with pytest.raises(Exception, match='x_range'):
        ReleasePlanningConfig(x_range=(0.8, 0.6))
    with pytest.raises(Exception, match='max_release_speed'):
        ReleasePlanningConfig(min_release_speed=1.0, max_release_speed=0.5)


def test_the_arms_hold_the_paper_cube_at_every_corner_of_the_release_region(cell):
    """The region is where the pads can be: IK within the joint limits at its corners."""
    scenario = load_scenario('paper_toss', cell=cell)
    models = {arm: arm_model(arm, cell) for arm in ARMS}
    seeds = {arm: np.asarray(scenario.initial_configuration[arm]) for arm in ARMS}
    corners = itertools.product(CONFIG.x_range, CONFIG.y_range, CONFIG.z_range)
    for corner in corners:
        plan = plan_grasp(models, seeds, np.array(corner), np.eye(3),
                          np.asarray(scenario.object.size), ReachabilityConfig())
        assert plan.reachable, (corner, plan.reason)
    assert len(release_candidates(CONFIG)) > 100


def test_a_target_given_mid_reach_is_where_the_box_lands(cell):
    """paper_toss starts toward its own release; 0.5 s into the reach it gets a new target."""
    scenario = load_scenario('paper_toss', cell=cell)
    target = np.array([0.95, 0.15, 0.25])
    log = run_episode(scenario, cell=cell, config=RunnerConfig(
        landing_target_changes=((0.8, target),)))
    metrics = episode_metrics(scenario, log.trajectory, cell)
    assert log.landing_target_refusals == ['']
    assert metrics['contact_time_gap'] <= 0.010
    assert metrics['t_contact_left'] > 0.8 - 0.3
    landing = np.asarray(metrics['landing_position'])
    # 2 cm: the median landing error; the planned landing itself is exact.
    assert np.linalg.norm(landing[:2] - target[:2]) <= 0.02


def test_the_far_row_is_thrown_at_its_planned_speed_and_lands_on_target(cell):
    """The far row (x = 1.15 m) needs 1.66 m/s, allowed by the carry's cap max_carry_speed."""
    target = np.array([1.15, 0.0, 0.25])
    base = load_scenario('paper_toss', cell=cell)
    scenario = replace(base, task='toss_to_target', release=None, landing_target=target,
                       speeds=replace(base.speeds, toss=None))
    assert np.linalg.norm(plan_release(target, NOMINAL, CONFIG).velocity) > 1.6
    log = run_episode(scenario, cell=cell)
    metrics = episode_metrics(scenario, log.trajectory, cell)
    # The release limits: speed within 3 %, and the landing within its 2 cm median.
    assert abs(metrics['release_speed_error']) <= 0.03
    landing = np.asarray(metrics['landing_position'])
    assert np.linalg.norm(landing[:2] - target[:2]) <= 0.02
    assert metrics['max_slip'] <= 0.01


def test_a_target_after_the_release_or_out_of_reach_is_refused(cell):
    scenario = replace(load_scenario('paper_toss', cell=cell), duration=2.6)
    log = run_episode(scenario, cell=cell, config=RunnerConfig(landing_target_changes=(
        (0.8, (1.8, 0.0, 0.25)), (2.5, (0.9, 0.0, 0.25)))))
    too_far, too_late = log.landing_target_refusals
    assert 'max_release_speed' in too_far
    assert 'after the release' in too_late
    metrics = episode_metrics(scenario, log.trajectory, cell)
    assert metrics['release_position_error'] <= 0.01


@pytest.mark.parametrize('mass, position, yaw, seed, target', [
    # toss_to_target_random seed 3 trial 199: the box 2.5 cm closer, 2.6 cm right, turned
    # -13 deg; without clear_of_the_box the right pad struck it 140 ms after the release.
    (0.9, (0.386, -0.026), -0.228, 761605522, (0.92, -0.284)),
    # Seed 61 trial 30 (digits as drawn): turned +10 deg, thrown 0.79 m/s along -y; with the
    # pad moved away along the full offset from the box's centre, the falling box read as
    # receding while its face ran into the pad, and landed 6.6 cm off.
    (1.041885939897496, (0.4223104401083776, -0.03701268312766583), 0.17082179024957342,
     1846787719, (0.8820210814656504, -0.29653464747252173))])
def test_a_box_thrown_across_toward_one_arm_flies_clear_of_its_pad(cell, mass, position, yaw,
                                                                   seed, target):
    """
    A target far to the right: the box leaves along -y, toward the right pad.

    The retracting pad must not be in its way: no pad touches the box between the release and
    the landing.
    """
    base = load_scenario('paper_toss', cell=cell)
    box = replace(base.object, mass=mass, position=np.array([*position, 0.32]), yaw=yaw)
    scenario = replace(base, task='toss_to_target', release=None, object=box, seed=seed,
                       landing_target=np.array([*target, 0.25]),
                       speeds=replace(base.speeds, toss=None))
    trajectory = run_episode(scenario, cell=cell).trajectory
    metrics = episode_metrics(scenario, trajectory, cell)
    assert metrics['release_velocity'][1] < -0.4
    t = trajectory['t'] - 0.3
    released = (t > metrics['t_release']) & (trajectory['object_position'][:, 2] > 0.3)
    assert released.sum() > 50
    for arm in ARMS:
        assert not trajectory[f'{arm}_pad_contact'][released].any(), arm


@pytest.mark.parametrize('fall_speed', [0.0, 1.0])
def test_a_pad_near_a_box_coming_toward_it_moves_away_faster_than_it_comes(fall_speed):
    """Away is horizontal: a box falling past a pad above its centre still comes toward it."""
    p_tool, p_box = np.array([0.8, -0.34, 0.59]), np.array([0.82, -0.20, 0.48])
    away = np.array([-0.02, -0.14, 0.0]) / np.hypot(0.02, 0.14)
    v_box = np.array([0.75, -0.65, -fall_speed])
    retract = np.array([-0.3, 0.0, 0.0])
    cleared = clear_of_the_box(retract, p_tool, p_box, v_box, 0.3, 0.3)
    assert cleared @ away == pytest.approx(v_box @ away + 0.3)
    np.testing.assert_allclose(cleared - (cleared @ away) * away,
                               retract - (retract @ away) * away, atol=1e-12)
    fast = retract + 2.0 * away
    np.testing.assert_array_equal(clear_of_the_box(fast, p_tool, p_box, v_box, 0.3, 0.3), fast)
    receding = np.array([0.75, 0.65, -fall_speed])
    np.testing.assert_array_equal(clear_of_the_box(retract, p_tool, p_box, receding, 0.3, 0.3),
                                  retract)
    far = p_box + 0.31 * away
    np.testing.assert_array_equal(clear_of_the_box(retract, far, p_box, v_box, 0.3, 0.3),
                                  retract)
