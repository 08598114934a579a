"""The grasp planner's choice among equivalent grasps: pad roll and shift along the face."""

import math

from conftest import yaw_rotation
from dual_arm_control.core.approach import rolled_impact_config
from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.geometry import rotation_log
from dual_arm_control.core.grasp import grasp_frame, rolled_pad_half_extents
from dual_arm_control.core.impact import clearance_limited_direction
from dual_arm_control.core.motion_config import MotionGeneratorConfig
from dual_arm_control.core.reachability import (grasp_candidates, grasp_lift, grasp_shifts,
                                                last_resort_shifts, PAD_ROLLS, plan_grasp,
                                                ReachabilityConfig)
from dual_arm_control.description.cell import arm_model, load_cell
import numpy as np
import pytest

ARMS = ('left', 'right')
CUBE = np.array([0.2, 0.2, 0.2])
# The paper cube resting on the pallet (top at 0.22 m).
CUBE_HEIGHT = 0.32
# iiwa A4 folds at most 120 deg, so the wrist (A6 axis) stays at least this far from the
# shoulder (A2 axis): the law of cosines over the upper arm and forearm (URDF d3, d5) [m].
SHOULDER_WRIST_MIN = {'left': math.sqrt(0.4 ** 2 + 0.4 ** 2 - 0.4 * 0.4),
                      'right': math.sqrt(0.42 ** 2 + 0.4 ** 2 - 0.42 * 0.4)}
SHOULDER = {arm: load_cell().arm(arm).base_position + [0.0, 0.0, height]
            for arm, height in (('left', 0.34), ('right', 0.36))}
# Tool point to wrist along the tool axis: A6 -> A7 0.081 m, flange 0.045 m, pad 0.115 m.
WRIST_TO_TOOL = 0.241


@pytest.fixture(scope='module')
def cell():
    return load_cell()


@pytest.fixture(scope='module')
def models(cell):
    return {arm: arm_model(arm, cell) for arm in ARMS}


def test_a_rolled_pad_covers_its_width_along_the_face():
    assert rolled_pad_half_extents(0.0, 0.075, 0.05) == pytest.approx((0.075, 0.05))
    assert rolled_pad_half_extents(0.5 * math.pi, 0.075, 0.05) == pytest.approx((0.05, 0.075))
    assert rolled_pad_half_extents(-0.5 * math.pi, 0.075, 0.05) == pytest.approx((0.05, 0.075))
    # At 45 deg the rectangle's corners set both extents: (a + b) / sqrt(2).
    diagonal = (0.075 + 0.05) / math.sqrt(2.0)
    assert rolled_pad_half_extents(0.25 * math.pi, 0.075, 0.05) == pytest.approx(
        (diagonal, diagonal))


def test_a_rolled_grasp_frame_keeps_the_face_point_and_normal():
    p_world_object, R_world_object = np.array([0.41, 0.0, CUBE_HEIGHT]), yaw_rotation(0.3)
    for arm in ARMS:
        flat = grasp_frame(arm, p_world_object, R_world_object, CUBE)
        rolled = grasp_frame(arm, p_world_object, R_world_object, CUBE, roll=0.5 * math.pi)
        np.testing.assert_array_equal(rolled.p_world_grasp, flat.p_world_grasp)
        np.testing.assert_allclose(rolled.normal, flat.normal, atol=1e-15)
        np.testing.assert_allclose(rolled.R_world_grasp.T @ rolled.R_world_grasp, np.eye(3),
                                   atol=1e-12)
        assert np.linalg.det(rolled.R_world_grasp) == pytest.approx(1.0)
        # A quarter turn puts the pad's long side (tool x) along the vertical object z.
        assert abs(rolled.R_world_grasp[:, 0] @ R_world_object[:, 2]) == pytest.approx(1.0)


def assert_both_arms_reach(models, plan, p_world_object, R_world_object, size, config):
    """Assert each arm's planned joints are within its limits and put its tool on its frame."""
    for arm in ARMS:
        frame = grasp_frame(arm, p_world_object, R_world_object, size, plan.offset, plan.roll)
        q = plan.solutions[arm].q
        lower, upper = models[arm].position_limits
        assert np.all(q >= lower) and np.all(q <= upper)
        p_world_tool, R_world_tool = models[arm].tool_pose(q)
        assert np.linalg.norm(p_world_tool - frame.p_world_grasp) <= config.position_tolerance
        assert np.linalg.norm(rotation_log(frame.R_world_grasp @ R_world_tool.T)) <= (
            config.orientation_tolerance)


def test_candidates_prefer_the_unrolled_centred_grasp_and_keep_the_pad_on_the_face():
    config = ReachabilityConfig()
    clearance = 0.02
    for size in ([0.16] * 3, CUBE, [0.26] * 3, [0.2, 0.3, 0.2], [0.25, 0.19, 0.2]):
        candidates = grasp_candidates(size, config, clearance)
        assert candidates[0][0] == 0.0 and not candidates[0][1].any()
        rolls = [roll for roll, _ in candidates]
        assert rolls == sorted(rolls, key=PAD_ROLLS.index) and set(rolls) == set(PAD_ROLLS)
        for roll in PAD_ROLLS:
            offsets = np.array([offset for candidate, offset in candidates if candidate == roll])
            assert offsets[:, 0].tolist() == list(grasp_shifts(size, config, roll))
            assert offsets[0, 0] == 0.0 and np.all(np.diff(offsets[:, 0]) > 0.0)
            half_along, half_across = rolled_pad_half_extents(roll, 0.075, 0.05)
            # The pad overhangs the face's front and top edges by at most -edge_margin ...
            assert offsets[-1, 0] + half_along <= 0.5 * size[0] - config.edge_margin + 1e-12
            assert np.all(offsets[:, 2] + half_across
                          <= 0.5 * size[2] - config.edge_margin + 1e-12)
            # ... and its lowest point clears the surface the box rests on.
            assert np.all(offsets[:, 2] - half_across >= -0.5 * size[2] + clearance - 1e-12)
        # The rolled pad, 0.05 m narrower along the face, shifts 0.025 m farther toward +x.
        assert grasp_shifts(size, config, 0.5 * math.pi)[-1] == pytest.approx(
            grasp_shifts(size, config, 0.0)[-1] + 0.025, abs=1e-12)


def test_the_last_resort_grasps_come_after_all_others_and_overhang_at_most_their_margin():
    """
    Beyond every grasp within edge_margin come, shift by shift, each roll's last resorts.

    They shift on toward +x only until the pad's end overhangs the face by
    -last_resort_edge_margin, the overhang never shrinks along them, and with no last-resort
    steps there are none; plan_grasp asks for them for a box to be tossed only.
    """
    config = ReachabilityConfig()
    assert config.last_resort_edge_margin < config.edge_margin
    clearance = 0.02
    for size in ([0.16] * 3, CUBE, [0.26] * 3, [0.2, 0.3, 0.2], [0.25, 0.19, 0.2]):
        regular = grasp_candidates(size, config, clearance)
        candidates = grasp_candidates(size, config, clearance, last_resort=True)
        assert len(candidates) == len(regular) + config.last_resort_steps * len(
            {roll for roll, _ in regular})
        for (roll, offset), (regular_roll, regular_offset) in zip(candidates, regular):
            assert roll == regular_roll
            np.testing.assert_array_equal(offset, regular_offset)
        overhangs = []
        for roll, offset in candidates[len(regular):]:
            half_along, _ = rolled_pad_half_extents(roll, 0.075, 0.05)
            assert offset[0] > max(grasp_shifts(size, config, roll)) + 1e-3
            overhangs.append(offset[0] + half_along - 0.5 * size[0])
            assert offset[1] == 0.0 and offset[2] == grasp_lift(size, config, roll, clearance)
        assert overhangs == sorted(overhangs)
        assert overhangs[-1] == pytest.approx(-config.last_resort_edge_margin)
        assert len(grasp_candidates(size, ReachabilityConfig(last_resort_steps=0), clearance,
                                    last_resort=True)) == len(regular)
    with pytest.raises(ConfigError, match='last_resort_edge_margin'):
        ReachabilityConfig(last_resort_edge_margin=-0.02)


def test_a_rolled_pad_rises_to_clear_the_support_or_is_left_out():
    config = ReachabilityConfig()
    # The unrolled pad reaches 0.05 m down: on every catalogue box it clears 2 cm unraised.
    assert grasp_lift([0.16] * 3, config, 0.0, 0.02) == 0.0
    # Rolled it reaches 0.075 m down: on the 0.16 m cube it rises 1.5 cm (0.075 + 0.02 - 0.08).
    assert grasp_lift([0.16] * 3, config, 0.5 * math.pi, 0.02) == pytest.approx(0.015)
    assert grasp_lift(CUBE, config, 0.5 * math.pi, 0.02) == 0.0
    # On a 0.1 m high box the rolled pad would have to overhang the top by 4.5 cm: no roll.
    low_box = [0.2, 0.2, 0.1]
    assert grasp_lift(low_box, config, 0.5 * math.pi, 0.02) is None
    assert {roll for roll, _ in grasp_candidates(low_box, config, 0.02)} == {0.0}


def test_a_box_to_be_set_down_is_grasped_as_high_as_the_overhang_allows():
    """
    Raised, the pad's top overhangs the face's top by -edge_margin - place_top_margin (2 cm).

    The unrolled pads sit 5-10 cm higher on the catalogue boxes than the least lift puts them
    (the rolled ones, longer across the face, 1-5 cm), and so do the wrists and forearms over
    the front table; the pad still clears the support, and a box too low for a roll has none.
    """
    config = ReachabilityConfig()
    clearance = 0.02
    overhang = -config.edge_margin - config.place_top_margin
    for size in ([0.16] * 3, CUBE, [0.26] * 3, [0.2, 0.3, 0.2], [0.25, 0.19, 0.2]):
        low = grasp_candidates(size, config, clearance, both_ways=True)
        high = grasp_candidates(size, config, clearance, both_ways=True, raised=True)
        assert [roll for roll, _ in high] == [roll for roll, _ in low]
        for (roll, raised), (_, lowest) in zip(high, low):
            _, half_across = rolled_pad_half_extents(roll, 0.075, 0.05)
            assert raised[2] + half_across == pytest.approx(0.5 * size[2] + overhang)
            assert raised[2] - half_across >= -0.5 * size[2] + clearance - 1e-12
            assert raised[2] >= lowest[2] + (0.05 if roll == 0.0 else 0.01) - 1e-12
            np.testing.assert_array_equal(raised[:2], lowest[:2])
    low_box = [0.2, 0.2, 0.1]
    assert grasp_lift(low_box, config, 0.5 * math.pi, 0.02, raised=True) is None
    # Unrolled on a 0.1 m high box: the pad's top at the face's top plus the overhang.
    assert grasp_lift(low_box, config, 0.0, 0.02, raised=True) == pytest.approx(overhang)


def test_a_box_turned_toward_an_arm_is_grasped_with_rolled_pads(models, cell):
    """
    At 25 deg of yaw, 9 cm closer than nominal, the left face turns toward the left base.

    The unrolled pad cannot shift far enough along the face for the left elbow; the quarter
    rolled pad, 0.05 m narrower along the face, can: the plan is rolled, both tools reach
    their rolled grasp frames within the joint limits, and the pads stay on the faces.
    """
    config = ReachabilityConfig()
    home = {arm: cell.arm(arm).q_home for arm in ARMS}
    p_world_object = np.array([0.32, 0.0, CUBE_HEIGHT])
    R_world_object = yaw_rotation(math.radians(25.0))
    plan = plan_grasp(models, home, p_world_object, R_world_object, CUBE, config, 0.02)
    assert plan.reachable and plan.reason == ''
    assert abs(plan.roll) == pytest.approx(0.5 * math.pi)
    flat_reach = max(grasp_shifts(CUBE, config, 0.0))
    assert flat_reach < plan.offset[0] <= 0.1 - 0.05 - config.edge_margin + 1e-12
    assert_both_arms_reach(models, plan, p_world_object, R_world_object, CUBE, config)
    # Without the rolled candidates the same box is out of reach of the left arm.
    for shift in grasp_shifts(CUBE, config, 0.0):
        frame = grasp_frame('left', p_world_object, R_world_object, CUBE, [shift, 0.0, 0.0])
        wrist = frame.p_world_grasp - WRIST_TO_TOOL * frame.normal
        assert np.linalg.norm(wrist - SHOULDER['left']) < SHOULDER_WRIST_MIN['left']


def test_a_box_only_a_last_resort_grasp_reaches_is_grasped_with_it(models, cell):
    """
    The 0.26 m cube 5 cm closer than nominal, 4 cm to the right, yawed -20 deg toward the right.

    No grasp within edge_margin reaches the right face (catalogue_random seed 11 refused this
    draw, trial 249); the first last-resort shift does: the rolled pads overhang the face by
    at most -last_resort_edge_margin and both tools reach their grasp frames within the joint
    limits.
    """
    size = np.array([0.26] * 3)
    p_world_object = np.array([0.36, -0.041, 0.22 + 0.13])
    R_world_object = yaw_rotation(math.radians(-20.0))
    home = {arm: cell.arm(arm).q_home for arm in ARMS}
    refused = plan_grasp(models, home, p_world_object, R_world_object, size,
                         ReachabilityConfig(last_resort_steps=0), 0.02)
    assert not refused.reachable and 'right arm misses its grasp frame' in refused.reason
    config = ReachabilityConfig()
    plan = plan_grasp(models, home, p_world_object, R_world_object, size, config, 0.02)
    assert plan.reachable and plan.reason == ''
    half_along, _ = rolled_pad_half_extents(plan.roll, 0.075, 0.05)
    assert plan.offset[0] > max(grasp_shifts(size, config, plan.roll)) + 1e-3
    assert plan.offset[0] == last_resort_shifts(size, config, plan.roll)[0]
    assert plan.offset[0] + half_along <= 0.13 - config.last_resort_edge_margin + 1e-12
    assert_both_arms_reach(models, plan, p_world_object, R_world_object, size, config)


def test_a_box_no_flush_pad_can_reach_is_still_refused(models, cell):
    """
    25 deg of yaw, 11 cm closer than nominal: the refusal is genuine.

    Whatever the pad's roll, its tool axis is the face normal, so the wrist sits 0.241 m out
    from the contact point; wherever the contact point is on the face, from edge to edge along
    it and from the top edge down to where an unrolled pad still clears the pallet by 2 cm
    (0.03 m below the centre), the left wrist stays closer to its shoulder than the elbow can
    fold, and the planner refuses.
    """
    p_world_object = np.array([0.30, 0.0, CUBE_HEIGHT])
    R_world_object = yaw_rotation(math.radians(25.0))
    home = {arm: cell.arm(arm).q_home for arm in ARMS}
    for shift in np.linspace(-0.1, 0.1, 21):
        for lift in np.linspace(-0.03, 0.1, 14):
            frame = grasp_frame('left', p_world_object, R_world_object, CUBE,
                                [shift, 0.0, lift])
            wrist = frame.p_world_grasp - WRIST_TO_TOOL * frame.normal
            assert np.linalg.norm(wrist - SHOULDER['left']) < SHOULDER_WRIST_MIN['left']
    plan = plan_grasp(models, home, p_world_object, R_world_object, CUBE, ReachabilityConfig())
    assert not plan.reachable and plan.roll == 0.0 and not plan.offset.any()
    assert 'left arm misses its grasp frame' in plan.reason


def test_the_run_in_of_a_rolled_pad_clears_the_support():
    config = MotionGeneratorConfig()
    assert rolled_impact_config(config, 0.0) is config.impact
    rolled = rolled_impact_config(config, 0.5 * math.pi)
    assert rolled.pad_half_height == pytest.approx(config.reachability.pad_half_length)
    rho = rolled.region.transitory_distance
    rising = np.array([0.6, -0.6, 0.5]) / np.linalg.norm([0.6, -0.6, 0.5])
    for height in (0.08, 0.1, 0.13, 0.2):
        direction = clearance_limited_direction(rising, height, rolled)
        # The rolled pad reaches 0.075 m below its centre, 2.5 cm more than the unrolled one.
        lowest_pad_point = height - rho * direction[2] - 0.075
        assert lowest_pad_point >= rolled.support_clearance - 1e-12 or direction[2] == 0.0


# Shoulder-wrist distance with the elbow straight: upper arm plus forearm (URDF d3 + d5) [m].
SHOULDER_WRIST_MAX = {'left': 0.4 + 0.4, 'right': 0.42 + 0.4}
FRONT_TABLE_PLACE = np.array([0.75, 0.0, 0.25])


def largest_wrist_overreach(p_world_object, offset):
    """Return the largest shoulder-wrist distance beyond the straight arm [m], from geometry."""
    excess = []
    for arm in ARMS:
        frame = grasp_frame(arm, p_world_object, np.eye(3), CUBE, offset)
        wrist = frame.p_world_grasp - WRIST_TO_TOOL * frame.normal
        excess.append(np.linalg.norm(wrist - SHOULDER[arm]) - SHOULDER_WRIST_MAX[arm])
    return max(excess)


def test_shifts_both_ways_go_toward_the_arms_first():
    config = ReachabilityConfig()
    one_way = grasp_shifts(CUBE, config)
    both = grasp_shifts(CUBE, config, both_ways=True)
    assert both[0] == 0.0 and len(both) == 2 * len(one_way) - 1
    assert both[1::2] == tuple(-shift for shift in one_way[1:])
    assert both[2::2] == one_way[1:]


def test_a_box_to_be_set_down_is_grasped_where_the_arms_reach_the_place(models, cell):
    """
    The paper cube set down on the front table at x = 0.75 m.

    Grasped at its face centres, a wrist would lie beyond its straight arm there; the planner
    shifts the grasp toward the arms until both wrists are place_wrist_margin inside, and the
    shifted grasp is reached at the pallet.
    """
    config = ReachabilityConfig()
    home = {arm: cell.arm(arm).q_home for arm in ARMS}
    p_world_object = np.array([0.41, 0.0, CUBE_HEIGHT])
    free = plan_grasp(models, home, p_world_object, np.eye(3), CUBE, config, 0.02)
    assert free.reachable and free.offset[0] == 0.0
    assert largest_wrist_overreach(FRONT_TABLE_PLACE, free.offset) > 0.01
    plan = plan_grasp(models, home, p_world_object, np.eye(3), CUBE, config, 0.02,
                      place=(FRONT_TABLE_PLACE, np.eye(3)))
    assert plan.reachable and plan.reason == '' and plan.offset[0] < 0.0
    assert largest_wrist_overreach(FRONT_TABLE_PLACE, plan.offset) <= (
        -config.place_wrist_margin + 1e-9)
    for arm in ARMS:
        frame = grasp_frame(arm, p_world_object, np.eye(3), CUBE, plan.offset, plan.roll)
        p_world_tool, _ = models[arm].tool_pose(plan.solutions[arm].q)
        assert np.linalg.norm(p_world_tool - frame.p_world_grasp) <= config.position_tolerance


def test_a_place_beyond_the_arms_is_refused_before_the_reach(models, cell):
    home = {arm: cell.arm(arm).q_home for arm in ARMS}
    far_place = FRONT_TABLE_PLACE + [0.25, 0.0, 0.0]
    largest_shift = max(grasp_shifts(CUBE, ReachabilityConfig(), 0.5 * math.pi))
    assert largest_wrist_overreach(far_place, [-largest_shift, 0.0, 0.0]) > 0.0
    plan = plan_grasp(models, home, np.array([0.41, 0.0, CUBE_HEIGHT]), np.eye(3), CUBE,
                      ReachabilityConfig(), 0.02, place=(far_place, np.eye(3)))
    assert not plan.reachable and 'out of reach' in plan.reason
    assert 'place [1.0, 0.0, 0.25] m' in plan.reason
