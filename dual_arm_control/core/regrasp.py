"""
Regrasp through a staging pose: a box that no single grasp both picks up and sets down.

A box near the arms' bases and yawed toward an arm is reached only with the grasp shifted along
its faces away from the bases; the front-table place only with it shifted toward them
(core.reachability). Such a box is set down once more on its own pallet, turned to the place's
yaw and moved away from the bases, where both grasps reach it: the first carries it there, the
arms go back to standby, and the second picks it up and sets it down at the place.
"""

from dataclasses import dataclass

from dual_arm_control.core.arms import ARMS
from dual_arm_control.core.elbow_reach import wrist_overreach
from dual_arm_control.core.geometry import rpy_to_matrix
from dual_arm_control.core.reachability import grasp_solutions, plan_grasp
from dual_arm_control.core.settings import check_settings, setting
import numpy as np


@dataclass(frozen=True)
class RegraspConfig:
    """The staging pose a pick-and-place falls back on when one grasp cannot do both ends."""

    enabled: bool = setting(
        True, 'Pick-and-place: a box no grasp both picks up and sets down is staged on its '
        'pallet, turned to place.yaw_deg, and picked again (false: such a task is refused).')
    step: float = setting(
        0.03, 'Spacing of the staging positions tried along world x, away from the arms.',
        unit='m', low=0, high=0.2, low_open=True)
    steps: int = setting(
        4, 'Number of staging positions tried beyond the first.', low=0, high=20)
    min_travel: float = setting(
        0.04, 'Least horizontal travel from the pick to the staging pose: the place DS lifts '
        'the box only over a travel (core.place.place_target), and a box turned in place '
        'would scrape the pallet.', unit='m', low=0, high=0.3)
    retract_timeout: float = setting(
        2.0, 'The second pass starts once both tools are back at standby, or after this long in '
        "the first pass's retract, from where the arms stopped: an arm that set the box down "
        'with its elbow turned over can stall on the way back with a wrist joint on its limit '
        '(catalogue_random_place seed 9494, trial 43: 8 cm from standby; a retract that gets '
        'there takes about 1 s, 0.95 s in paper_place_regrasp).', unit='s', low=0, high=60.0,
        low_open=True)
    pallet_margin: float = setting(
        0.06, "The staged box's centre stays this far inside the pallet's top, so it rests on "
        'the pallet with its centre of mass well inside the edge.', unit='m', low=0, high=0.2)

    def __post_init__(self):
        check_settings(self)


@dataclass(frozen=True)
class StagingPlan:
    """
    The staging pose of a regrasp: position (3,) [m] and rotation (3, 3) of the box there.

    first, second: the GraspPlans that carry the box from the pick to the staging pose and from
    the staging pose to the place; reachable: a staging pose serves both; reason: why none does.
    """

    position: np.ndarray
    rotation: np.ndarray
    first: object
    second: object
    reachable: bool
    reason: str


def staging_positions(p_world_object, pallet, config):
    """
    Return the staging positions (3,) [m] to try for a box at p_world_object (3,) [m].

    On the pallet's centre line in world y, from the pick's x away from the arms' bases in
    config.step, each at least min_travel from the pick and with its centre pallet_margin inside
    the pallet's top ((x_min, x_max), (y_min, y_max), top); the box rests at its pick height.
    """
    (x_min, x_max), (y_min, y_max), _ = pallet
    p_world_object = np.asarray(p_world_object, dtype=float)
    y_stage = 0.5 * (y_min + y_max)
    positions = []
    for index in range(config.steps + 1):
        position = np.array([p_world_object[0] + index * config.step, y_stage,
                             p_world_object[2]])
        inside = (x_min + config.pallet_margin <= position[0] <= x_max - config.pallet_margin
                  and y_min + config.pallet_margin <= y_stage <= y_max - config.pallet_margin)
        travel = float(np.hypot(*(position - p_world_object)[:2]))
        if inside and travel >= config.min_travel:
            positions.append(position)
    return positions


def plan_staging(models, q_current, p_world_object, R_world_object, size, reachability, place,
                 pallet, yaw, config, support_clearance=0.0, clear_only=False):
    """
    Return the StagingPlan of a box (pose, size (3,) [m]) whose pick and place no grasp serves.

    The first grasp is the one that picks the box up where it lies (core.reachability
    .plan_grasp, the last resorts included: the carry to the staging pose is short). Each of
    staging_positions, with the box at yaw [rad] there, is tried in turn: it serves when the
    first grasp also reaches it (inverse kinematics, and every wrist place_wrist_margin inside
    its straight-arm reach) and another grasp picks the box up there and sets it down at place
    ((p (3,) [m], R (3, 3))), from the arms' joints q_current {arm: (7,)}; with clear_only a
    grasp that would set the box down short of the place (GraspPlan.short) does not serve.
    """
    rotation = rpy_to_matrix((0.0, 0.0, yaw))
    first = plan_grasp(models, q_current, p_world_object, R_world_object, size, reachability,
                       support_clearance)
    if not first.reachable:
        return StagingPlan(np.zeros(3), rotation, first, None, False,
                           f'no grasp picks the box up: {first.reason}')
    positions = staging_positions(p_world_object, pallet, config)
    reaches = {arm: models[arm].elbow_reach() for arm in ARMS}
    for position in positions:
        if not _sets_down(models, reaches, first, position, rotation, size, reachability):
            continue
        second = plan_grasp(models, q_current, position, rotation, size, reachability,
                            support_clearance, place)
        if second.reachable and not (clear_only and second.short):
            return StagingPlan(position, rotation, first, second, True, '')
    reason = (f'no staging pose on the pallet serves both grasps ({len(positions)} tried)'
              if positions else 'no staging pose fits on the pallet')
    return StagingPlan(np.zeros(3), rotation, first, None, False, reason)


def _sets_down(models, reaches, grasp, position, rotation, size, reachability):
    """Return whether the arms ({arm: ElbowReach}) holding the box by grasp reach it at a pose."""
    if (wrist_overreach(reaches, position, rotation, size, grasp.offset, grasp.roll)
            > -reachability.place_wrist_margin):
        return False
    solutions = grasp_solutions(models, {arm: grasp.solutions[arm].q for arm in ARMS}, position,
                                rotation, size, grasp.offset, grasp.roll, reachability)
    return all(solution.reachable for solution in solutions.values())
