"""The run-in of the reach kept within the elbow's reach (core.elbow_reach)."""

import math

from conftest import yaw_rotation
from dual_arm_control.core.elbow_reach import (clearest_direction, elbow_clear_direction,
                                               reachable_release_rotation, run_in_elbow_margin,
                                               wrist_offset, wrist_overreach)
from dual_arm_control.core.geometry import matrix_to_rpy, quat_xyzw_to_matrix
from dual_arm_control.core.grasp import grasp_frame
from dual_arm_control.core.impact import impact_direction
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.graph import EPISODE_START_TIME
from dual_arm_control.inprocess import run_episode
from dual_arm_control.scenario import load_scenario
from dual_arm_control.trial_sampling import sample_trial
import numpy as np
import pytest

ARMS = ('left', 'right')
# The elbow (A4) folds at most 120 deg: law of cosines over the upper arm and forearm (URDF d3,
# d5 of robot_facts) [m].
FOLDED_WRIST_DISTANCE = {'left': math.sqrt(0.4 ** 2 + 0.4 ** 2 - 0.4 * 0.4),
                         'right': math.sqrt(0.42 ** 2 + 0.4 ** 2 - 0.42 * 0.4)}
# Stretched straight (A4 = 0), upper arm plus forearm [m].
STRAIGHT_WRIST_DISTANCE = {'left': 0.4 + 0.4, 'right': 0.42 + 0.4}
# Base position plus d1 (0.34 m iiwa 7, 0.36 m iiwa 14) [m].
SHOULDER = {arm: load_cell().arm(arm).base_position + [0.0, 0.0, height]
            for arm, height in (('left', 0.34), ('right', 0.36))}
# Tool point to wrist along the flange axis: A6 -> flange 0.126 m, pad 0.115 m.
WRIST_TO_TOOL = 0.241
TOSS_VELOCITY = np.array([0.7603, 0.0, 0.3801])
MAX_TILT = math.radians(40.0)
RUN_IN = 0.2


@pytest.fixture(scope='module')
def models():
    cell = load_cell()
    return {arm: arm_model(arm, cell) for arm in ARMS}


def sampled_margin(reach, frame, direction, run_in=RUN_IN):
    """Return the run-in's least margin by brute force over 401 points of the run-in."""
    wrists = [wrist_offset(reach, frame.p_world_grasp - s * direction, frame.R_world_grasp)
              for s in np.linspace(0.0, run_in, 401)]
    return min(np.linalg.norm(w) for w in wrists) - reach.min_wrist_distance


def cone_directions(normal, max_tilt, count=2000, seed=0):
    """Return unit directions spread over the cone of half-angle max_tilt about normal."""
    rng = np.random.default_rng(seed)
    side = np.cross(normal, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side)
    up = np.cross(normal, side)
    tilts = max_tilt * np.sqrt(rng.uniform(0.0, 1.0, count))
    headings = rng.uniform(0.0, 2.0 * math.pi, count)
    return [math.cos(t) * normal + math.sin(t) * (math.cos(h) * side + math.sin(h) * up)
            for t, h in zip(tilts, headings)]


@pytest.mark.parametrize('arm', ARMS)
def test_elbow_reach_is_the_robot_facts_geometry(models, arm):
    """Shoulder at base + d1, wrist 0.241 m behind the pad, distance at 120 deg of elbow fold."""
    reach = models[arm].elbow_reach()
    np.testing.assert_allclose(reach.shoulder, SHOULDER[arm], atol=1e-9)
    np.testing.assert_allclose(reach.wrist_in_tool, [0.0, 0.0, -WRIST_TO_TOOL], atol=1e-9)
    assert reach.min_wrist_distance == pytest.approx(FOLDED_WRIST_DISTANCE[arm], abs=1e-6)
    assert reach.max_wrist_distance == pytest.approx(STRAIGHT_WRIST_DISTANCE[arm], abs=1e-6)


@pytest.mark.parametrize('arm', ARMS)
def test_the_wrist_offset_of_any_posture_is_outside_the_folded_distance(models, arm):
    """Within the joint limits the shoulder-wrist distance stays between folded and straight."""
    model = models[arm]
    reach = model.elbow_reach()
    lower, upper = model.position_limits
    rng = np.random.default_rng(3)
    distances = []
    for _ in range(300):
        q = rng.uniform(lower, upper)
        p_world_tool, R_world_tool = model.tool_pose(q)
        distances.append(np.linalg.norm(wrist_offset(reach, p_world_tool, R_world_tool)))
    q[3] = lower[3]
    p_world_tool, R_world_tool = model.tool_pose(q)
    folded = np.linalg.norm(wrist_offset(reach, p_world_tool, R_world_tool))
    assert min(distances) >= reach.min_wrist_distance - 1e-9
    assert max(distances) <= reach.max_wrist_distance + 1e-9
    assert folded == pytest.approx(reach.min_wrist_distance, abs=1e-9)


@pytest.mark.parametrize('yaw_deg', [-25.0, 0.0, 25.0])
@pytest.mark.parametrize('arm', ARMS)
def test_run_in_margin_is_the_least_distance_along_the_run_in(models, arm, yaw_deg):
    reach = models[arm].elbow_reach()
    frame = grasp_frame(arm, np.array([0.41, 0.03, 0.32]), yaw_rotation(math.radians(yaw_deg)),
                        np.array([0.2, 0.2, 0.2]))
    for direction in cone_directions(frame.normal, MAX_TILT, count=40):
        assert run_in_elbow_margin(reach, frame.p_world_grasp, frame.R_world_grasp, direction,
                                   RUN_IN) == pytest.approx(
                                       sampled_margin(reach, frame, direction), abs=2e-4)


@pytest.mark.parametrize('yaw_deg', [-25.0, -10.0, 0.0, 10.0, 25.0])
@pytest.mark.parametrize('arm', ARMS)
def test_clearest_direction_keeps_the_wrist_farthest_of_the_cone(models, arm, yaw_deg):
    reach = models[arm].elbow_reach()
    frame = grasp_frame(arm, np.array([0.41, 0.0, 0.32]), yaw_rotation(math.radians(yaw_deg)),
                        np.array([0.2, 0.2, 0.2]))
    clearest = clearest_direction(reach, frame.p_world_grasp, frame.R_world_grasp, frame.normal,
                                  MAX_TILT)
    assert math.degrees(math.acos(min(1.0, clearest @ frame.normal))) == pytest.approx(40.0)
    best = run_in_elbow_margin(reach, frame.p_world_grasp, frame.R_world_grasp, clearest, RUN_IN)
    sampled = max(run_in_elbow_margin(reach, frame.p_world_grasp, frame.R_world_grasp, d, RUN_IN)
                  for d in cone_directions(frame.normal, MAX_TILT))
    assert best >= sampled - 1e-6


@pytest.mark.parametrize('yaw_deg', [-25.0, -10.0, 0.0, 10.0, 25.0])
@pytest.mark.parametrize('arm', ARMS)
def test_the_paper_tilt_is_kept_when_clear_and_turned_when_not(models, arm, yaw_deg):
    """
    Keep the paper's e1 when its run-in clears the elbow's limit, else turn it.

    The paper's e1 (tilted toward the toss) draws the wrist in past the elbow's limit in this
    cell; the chosen e1 stays in the friction cone and clears it, or is the clearest there is.
    """
    reach = models[arm].elbow_reach()
    frame = grasp_frame(arm, np.array([0.45, 0.0, 0.32]), yaw_rotation(math.radians(yaw_deg)),
                        np.array([0.2, 0.2, 0.2]))
    paper = impact_direction(frame.normal, TOSS_VELOCITY, MAX_TILT)
    chosen = elbow_clear_direction(paper, frame.normal, MAX_TILT, reach, frame.p_world_grasp,
                                   frame.R_world_grasp, RUN_IN, 0.02)
    paper_margin = sampled_margin(reach, frame, paper)
    grasp_margin = sampled_margin(reach, frame, paper, run_in=0.0)
    required = min(0.02, grasp_margin)
    chosen_margin = sampled_margin(reach, frame, chosen)
    assert np.linalg.norm(chosen) == pytest.approx(1.0)
    assert chosen @ frame.normal >= math.cos(MAX_TILT) - 1e-9
    if paper_margin >= required:
        np.testing.assert_allclose(chosen, paper)
    else:
        clearest = clearest_direction(reach, frame.p_world_grasp, frame.R_world_grasp,
                                      frame.normal, MAX_TILT)
        assert chosen_margin >= required - 1e-3 or np.allclose(chosen, clearest)
        assert chosen_margin > paper_margin


def test_the_nominal_toss_run_in_would_fold_the_elbow_past_its_limit(models):
    """Why the rule exists: at the paper's pose the paper's tilt needs the elbow past 120 deg."""
    frame = {arm: grasp_frame(arm, np.array([0.41, 0.0, 0.32]), np.eye(3),
                              np.array([0.2, 0.2, 0.2])) for arm in ARMS}
    for arm in ARMS:
        reach = models[arm].elbow_reach()
        paper = impact_direction(frame[arm].normal, TOSS_VELOCITY, MAX_TILT)
        assert sampled_margin(reach, frame[arm], paper, run_in=0.0) > 0.0
        assert sampled_margin(reach, frame[arm], paper) < -0.05


def test_a_yawed_box_is_met_flush_by_both_pads_with_the_elbows_inside_their_limits(models):
    """
    Meet a yawed box flush with both pads, no elbow running along its limit on the way.

    catalogue_random trial 97 (paper cube, 3.9 cm off centre, yawed 6.9 deg): both pads meet
    their faces flush and together, and no elbow runs along its joint limit on the way.

    Before the run-in was kept within the elbow's reach and the free-motion orientation gains
    raised, both elbows sat on their 120 deg limit for half a second and the pads met the faces
    8.6 and 11.6 deg off flush, 12 ms apart.
    """
    cell = load_cell()
    scenario = sample_trial(load_scenario('catalogue_random', cell), 97, cell)
    assert scenario.object.type == 'paper_cube'
    data = run_episode(scenario, cell=cell, duration=EPISODE_START_TIME + 2.0).trajectory
    contact = {arm: int(np.argmax(data[f'{arm}_pad_contact'])) for arm in ARMS}
    assert all(data[f'{arm}_pad_contact'][contact[arm]] for arm in ARMS)
    for arm in ARMS:
        index = contact[arm]
        R_world_object = quat_xyzw_to_matrix(data['object_quat_xyzw'][index])
        normal = grasp_frame(arm, data['object_position'][index], R_world_object,
                             scenario.object.size).normal
        R_world_tool = models[arm].tool_pose(data[f'{arm}_q'][index])[1]
        off_flush = math.degrees(math.acos(min(1.0, R_world_tool[:, 2] @ normal)))
        elbow_limit = models[arm].position_limits[0][3]
        start = int(np.argmax(data['t'] >= EPISODE_START_TIME))
        elbow_margin = math.degrees(np.min(data[f'{arm}_q'][start:index, 3] - elbow_limit))
        print(f'{arm}: {off_flush:.1f} deg off flush; elbow at least {elbow_margin:.1f} deg '
              'from its limit')
        assert off_flush <= 3.0
        assert elbow_margin >= 1.0
    assert abs(data['t'][contact['left']] - data['t'][contact['right']]) <= 0.004 + 1e-9


@pytest.fixture(scope='module')
def reaches(models):
    return {arm: models[arm].elbow_reach() for arm in ARMS}


# The 0.26 m cube grabbed 85 mm off its faces' centres (the longest shift), tossed from the
# catalogue scenarios' release point.
CUBE_260 = np.array([0.26, 0.26, 0.26])
SHIFTED = np.array([0.085, 0.0, 0.0])
RELEASE = np.array([0.68, 0.0, 0.45])


def test_a_box_held_square_to_the_toss_is_not_turned(reaches):
    """Centred, a box 3 deg off the heading is within reach; shifted, 2 cm beyond, allowed."""
    held = yaw_rotation(math.radians(3.0))
    assert wrist_overreach(reaches, RELEASE, held, CUBE_260) < 0.0
    assert 0.0 < wrist_overreach(reaches, RELEASE, held, CUBE_260, SHIFTED) < 0.1
    turned = reachable_release_rotation(reaches, RELEASE, TOSS_VELOCITY, held, CUBE_260,
                                        SHIFTED, 0.0, overreach=0.1)
    np.testing.assert_array_equal(turned, held)


@pytest.mark.parametrize('yaw_deg', [-23.0, 25.0])
def test_a_yawed_box_is_turned_just_far_enough_for_the_far_arm_to_reach(reaches, yaw_deg):
    """
    Yawed 23 deg toward the right arm's side, the left wrist lies 16 cm beyond its reach.

    The box is turned toward the heading (yaw 0) to the first whole degree at which no wrist is
    more than the allowed overreach beyond its reach: one degree less would not do.
    """
    held = yaw_rotation(math.radians(yaw_deg))
    allowed = 0.1
    before = wrist_overreach(reaches, RELEASE, held, CUBE_260, SHIFTED)
    turned = reachable_release_rotation(reaches, RELEASE, TOSS_VELOCITY, held, CUBE_260,
                                        SHIFTED, 0.0, overreach=allowed)
    after = wrist_overreach(reaches, RELEASE, turned, CUBE_260, SHIFTED)
    turn = math.degrees(matrix_to_rpy(turned)[2]) - yaw_deg
    print(f'yaw {yaw_deg} deg: overreach {before:.3f} m; turned {turn:+.1f} deg: {after:.3f} m')
    assert before > allowed
    assert after <= allowed
    assert 0.0 < abs(turn) < abs(yaw_deg) and np.sign(turn) == -np.sign(yaw_deg)
    assert turn == pytest.approx(round(turn), abs=1e-9)
    one_less = yaw_rotation(math.radians(yaw_deg + turn - np.sign(turn)))
    assert wrist_overreach(reaches, RELEASE, one_less, CUBE_260, SHIFTED) > allowed
    np.testing.assert_allclose(turned[:, 2], [0.0, 0.0, 1.0], atol=1e-12)


def test_an_unreachable_release_keeps_the_yaw_of_the_least_overreach(reaches):
    """No yaw satisfies a negative allowance of 1 m: the answer is the best one on the way."""
    held = yaw_rotation(math.radians(-25.0))
    turned = reachable_release_rotation(reaches, RELEASE, TOSS_VELOCITY, held, CUBE_260,
                                        SHIFTED, 0.0, overreach=-1.0)
    candidates = [wrist_overreach(reaches, RELEASE, yaw_rotation(math.radians(yaw)), CUBE_260,
                                  SHIFTED) for yaw in np.arange(-25.0, 0.5, 1.0)]
    assert wrist_overreach(reaches, RELEASE, turned, CUBE_260, SHIFTED) == pytest.approx(
        min(candidates), abs=1e-12)
