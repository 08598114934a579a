"""
Reachability of a grasp: whether each arm can put its pad on its face within its joint limits.

The reach DS (eqs. 1-6) drives the tools to the grasp frames whatever the arms can do; a grasp
frame an arm cannot reach with margin to its joint limits ends with the arm on a limit, its
pad misaligned with the face and the box pushed away by one pad. plan_grasp checks the grasp
frames with inverse kinematics before the reach starts, shifting the grasp points along the
faces (toward +x of the object, away from the arms' bases, as far as the pad stays on the face)
and rolling the pads a quarter turn about the face normals (a narrower extent along the face,
so a longer shift) when the centred ones are out of reach, as a last resort lets the pads
overhang the face's edge a little more, and says why when nothing helps.

A box to be set down is grasped so that the arms also reach the place: on the front table the
box's centre lies farther from the shoulders than the arms' straight reach for the narrower
boxes, and an arm driven there stretches to its elbow singularity and stops short. The grasp
then shifts toward -x of the object (toward the arms) until every wrist stays a margin inside
its straight-arm reach at the place.
"""

from dataclasses import dataclass
import math

from dual_arm_control.core.arms import ARMS
from dual_arm_control.core.elbow_reach import wrist_overreach
from dual_arm_control.core.geometry import rotation_log, vector_norm
from dual_arm_control.core.grasp import grasp_frame, rolled_pad_half_extents
from dual_arm_control.core.linear_solve import solve
from dual_arm_control.core.settings import check_settings, setting
from dual_arm_control.core.validation import check_range
import numpy as np

# Pad rolls about the face normal [rad] the grasp planner tries, in order of preference.
PAD_ROLLS = (0.0, 0.5 * math.pi, -0.5 * math.pi)
_IDENTITY_6 = np.eye(6)
_IDENTITY_6.setflags(write=False)


@dataclass(frozen=True)
class ReachabilityConfig:
    """Inverse-kinematics check of the grasp frames (SI units)."""

    enabled: bool = setting(
        True, 'Check the grasp frames before the reach (false: reach whatever the arms can do).')
    pad_half_length: float = setting(
        0.075, "Half the pad's extent along the face (object x).",
        unit='m', low=0, high=0.5, low_open=True)
    pad_half_width: float = setting(
        0.05, "Half the pad's extent across the face (object z), unrolled (0.15 x 0.10 m pad).",
        unit='m', low=0, high=0.5, low_open=True)
    joint_margin: float = setting(0.0, 'Kept from every joint limit.', unit='rad', low=0, high=0.5)
    position_tolerance: float = setting(
        0.005, 'Largest position residual of a reachable pose.',
        unit='m', low=0, high=0.1, low_open=True)
    orientation_tolerance: float = setting(
        0.05, 'Largest orientation residual of a reachable pose.',
        unit='rad', low=0, high=1.0, low_open=True)
    max_iterations: int = setting(
        300, 'Iterations of the damped least-squares solve.', low=1, high=10000)
    max_step: float = setting(
        0.2, 'Largest joint step of one iteration.', unit='rad', low=0, high=1.0, low_open=True)
    damping: float = setting(
        1e-4, 'Regularisation of the damped least-squares solve.',
        unit='(m or rad)^2', low=0, high=1.0, low_open=True)
    shift_steps: int = setting(
        3, 'Number of grasp shifts along the face tried beyond the centred grasp.', low=0, high=10)
    edge_margin: float = setting(
        -0.03, "Kept between the pad's end and the face's edge (negative: the pad may overhang "
        'the edge by that much; -0.03 m leaves 80 % of the 0.15 m pad on the face).',
        unit='m', low=-0.1, high=0.5)
    last_resort_edge_margin: float = setting(
        -0.045, 'When no grasp within edge_margin reaches, the pads shift on toward +x of the '
        'object in last_resort_steps until their ends overhang the face by at most this '
        '(-0.045 m: 70 % of the unrolled, 55 % of the rolled pad on the face), the least shift '
        'first; at most edge_margin (equal: no last resort). Boxes to be tossed near the '
        "reach's end (centre x 0.345-0.385 m, yawed 19-25 deg toward an arm, 200 draws): 7 of "
        '8 catalogue boxes grasped so succeed (one 3 kg cube slips 21 mm); catalogue_random '
        'seed 11: 2 of its 7 refusals; boxes scaled 0.8-1.2 at 0.4-6 kg: 3 of 9 (5 slip '
        '15-22 mm, 1 leaves 10.9 % off). Every shift up to -0.06 m instead: of 12 refused, 2 '
        'succeed and 4 slip more than 1 cm.',
        unit='m', low=-0.1, high=0.5)
    last_resort_steps: int = setting(
        2, 'Number of last-resort shifts beyond the largest within edge_margin.', low=0, high=10)
    place_wrist_margin: float = setting(
        0.01, 'Pick-and-place: at the place every wrist stays this far inside its straight-arm '
        'reach (A4 = 0), where the controller still moves the pad along the arm (a box whose '
        'wrists needed the straight arm stopped 5-8 mm short); the grasp shifts toward the '
        'arms until they do.', unit='m', low=0, high=0.2)
    place_top_margin: float = setting(
        0.01, 'Pick-and-place: the pads grasp the box as high on its faces as the overhang '
        '-edge_margin allows, less this margin, so that the wrists and forearms pass higher '
        "above the front table as the box is set down (grasped low, at the support's "
        "clearance, 2 of 60 forearms met the table's edge in a randomization of boxes scaled "
        '0.75-1.25, 0 once grasped high).', unit='m', low=0, high=0.2)
    max_place_overreach: float = setting(
        0.05, 'Pick-and-place, when no grasp the pick allows keeps place_wrist_margin and no '
        'regrasp serves (core.regrasp): the grasp whose wrists lie least beyond the straight '
        'arm at the place is taken if that is at most this far (the box is then set down '
        'short: 12-28 mm at 16-65 mm in catalogue_random_place seed 22); beyond it the task '
        'is refused.',
        unit='m', low=0, high=0.2)

    def __post_init__(self):
        check_settings(self)
        check_range('last_resort_edge_margin', self.last_resort_edge_margin, -0.1,
                    self.edge_margin, 'm')


@dataclass(frozen=True)
class PoseSolution:
    """An inverse-kinematics result: q (7,) [rad], residuals [m] and [rad], reachable."""

    q: np.ndarray
    position_error: float
    orientation_error: float
    reachable: bool


@dataclass(frozen=True)
class GraspPlan:
    """
    The grasp to reach: offset (3,) [m] of both grasp points from the face centres, object frame.

    roll [rad]: both pads' roll about their face normals (core.grasp.grasp_frame); reachable:
    both arms reach their grasp frames; reason: why not (empty when reachable); solutions
    {arm: PoseSolution} of the chosen (or, unreachable, the first tried) grasp; empty when the
    place left no grasp to try; short: a box to be set down is reached at its place only with a
    wrist beyond place_wrist_margin (place_order), so it is set down short of the place.
    """

    offset: np.ndarray
    reachable: bool
    reason: str
    solutions: dict
    roll: float = 0.0
    short: bool = False


def pose_error(model, q, p_world_target, R_world_target):
    """Return the tool's pose error (6,) [m, rad] at q: [p_target - p; log(R_target R^T)]."""
    p_world_tool, R_world_tool = model.tool_pose(q)
    return tool_pose_error(p_world_tool, R_world_tool, p_world_target, R_world_target)


def tool_pose_error(p_world_tool, R_world_tool, p_world_target, R_world_target):
    """Return the pose error (6,) [m, rad] of a tool pose: [p_target - p; log(R_target R^T)]."""
    return np.concatenate((p_world_target - p_world_tool,
                           rotation_log(R_world_target @ R_world_tool.T)))


def inverse_kinematics_step(model, q, error, lower, upper, damping, max_step, jacobian=None):
    """
    Return q (7,) after one damped least-squares step toward a pose error (6,) within bounds.

    A joint on a bound that the step would push further is taken out of the Jacobian and the
    step recomputed with the others (an active set), so the remaining joints make up for it
    instead of the solve stalling against the bound; the step's norm is capped at max_step.
    jacobian: the tool Jacobian at q when the caller has it.
    """
    if jacobian is None:
        jacobian = model.tool_jacobian(q)
    regulariser = damping * _IDENTITY_6
    at_lower, at_upper = q <= lower, q >= upper
    on_a_bound = bool(at_lower.any() or at_upper.any())
    free = None
    for _ in range(q.size):
        active = jacobian if free is None else jacobian * free
        step = active.T @ solve(active @ active.T + regulariser, error)
        if not on_a_bound:
            break
        blocked = (at_lower & (step < 0.0)) | (at_upper & (step > 0.0))
        if free is not None:
            blocked &= free
        if not blocked.any():
            break
        free = ~blocked if free is None else free & ~blocked
    norm = vector_norm(step)
    if norm > max_step:
        step *= max_step / norm
    return np.minimum(np.maximum(q + step, lower), upper)


def inverse_kinematics(model, p_world_target, R_world_target, q_start, config):
    """
    Return the PoseSolution of the tool pose (p, R) for an ArmModel, from q_start.

    Repeated inverse_kinematics_step within the joint limits narrowed by joint_margin.
    """
    lower, upper = model.position_limits
    lower, upper = lower + config.joint_margin, upper - config.joint_margin
    q = np.clip(np.asarray(q_start, dtype=float), lower, upper)
    for _ in range(config.max_iterations):
        error = pose_error(model, q, p_world_target, R_world_target)
        if (np.linalg.norm(error[:3]) < 0.1 * config.position_tolerance
                and np.linalg.norm(error[3:]) < 0.1 * config.orientation_tolerance):
            break
        q = inverse_kinematics_step(model, q, error, lower, upper, config.damping,
                                    config.max_step)
    error = pose_error(model, q, p_world_target, R_world_target)
    position_error = float(np.linalg.norm(error[:3]))
    orientation_error = float(np.linalg.norm(error[3:]))
    return PoseSolution(q, position_error, orientation_error,
                        position_error <= config.position_tolerance
                        and orientation_error <= config.orientation_tolerance)


def largest_shift(size, config, roll, edge_margin):
    """
    Return the shift [m] along the face that puts the pad's end edge_margin inside its edge.

    A negative edge_margin lets the pad overhang the edge; roll [rad] sets the pad's extent
    along the face. 0 when even the centred pad reaches past that.
    """
    half_extent, _ = rolled_pad_half_extents(roll, config.pad_half_length, config.pad_half_width)
    return max(0.5 * float(size[0]) - half_extent - edge_margin, 0.0)


def grasp_shifts(size, config, roll=0.0, both_ways=False):
    """
    Return the grasp shifts [m] to try: centred first, up to the pad end at edge_margin.

    roll [rad]: the pads' roll about the face normal, which sets their extent along the face
    (core.grasp.rolled_pad_half_extents). The shifts go toward +x of the object, or with
    both_ways toward -x too (-x first at each length).
    """
    largest = largest_shift(size, config, roll, config.edge_margin)
    if largest == 0.0 or config.shift_steps == 0:
        return (0.0,)
    lengths = [largest * step / config.shift_steps for step in range(1, config.shift_steps + 1)]
    signs = (-1.0, 1.0) if both_ways else (1.0,)
    return (0.0,) + tuple(sign * length for length in lengths for sign in signs)


def last_resort_shifts(size, config, roll=0.0):
    """
    Return the last-resort grasp shifts [m] toward +x, () when there are none.

    They go beyond grasp_shifts' largest in last_resort_steps, up to the pad's end at
    last_resort_edge_margin.
    """
    largest = largest_shift(size, config, roll, config.edge_margin) if config.shift_steps else 0.0
    farthest = largest_shift(size, config, roll, config.last_resort_edge_margin)
    if farthest <= largest or config.last_resort_steps == 0:
        return ()
    steps = config.last_resort_steps
    return tuple(largest + (farthest - largest) * step / steps for step in range(1, steps + 1))


def grasp_lift(size, config, roll=0.0, support_clearance=0.0, raised=False):
    """
    Return how far [m] the grasp point rises above the face centre, or None if it cannot.

    A box rests on its bottom face, so the pad (rolled by roll [rad], core.grasp
    .rolled_pad_half_extents) must keep its lowest point support_clearance [m] above the
    face's bottom edge; the rise may not push its top past the face's top edge by more than
    the overhang -edge_margin allows. The lift is the least that clears the support, or with
    raised (a box to be set down) the most the overhang allows less place_top_margin.
    """
    _, half_height = rolled_pad_half_extents(roll, config.pad_half_length, config.pad_half_width)
    half_face = 0.5 * float(size[2])
    highest = half_face - min(config.edge_margin, 0.0) - half_height
    lift = max(half_height + support_clearance - half_face, 0.0)
    if lift > highest + 1e-12:
        return None
    if raised:
        lift = max(lift, highest - config.place_top_margin)
    return lift


def grasp_candidates(size, config, support_clearance=0.0, both_ways=False, raised=False,
                     last_resort=False):
    """
    Return the grasps to try, (roll [rad], offset (3,) [m] object frame), in order of preference.

    The flat pads are flush with their faces at any roll about the face normal and may sit
    anywhere on the face, so these grasps hold the box alike; they differ in where the wrist
    goes. The unrolled pads (long side along object x) come first, then the pads a quarter
    turn either way: their narrower extent along the face lets the grasp shift farther toward
    +x, which moves the wrists away from the shoulders when the face is turned toward an arm's
    base (the elbow, A4, folds at most 120 deg). Within a roll the smaller shift comes first:
    it leaves the box's weight the shorter lever about the squeeze axis. Each grasp point is
    raised by grasp_lift, so the pad clears the surface the box rests on by support_clearance
    [m]; a roll whose pad cannot is left out. both_ways: shift toward -x of the object too;
    raised: grasp as high as grasp_lift allows (a box to be set down). last_resort: append
    the last_resort_shifts after all of these, shift by shift, each roll in turn: a pad
    overhanging the face by more than edge_margin pivots on the face's edge as the box is
    carried, so it is taken only when nothing else reaches.
    """
    candidates, beyond = [], []
    for roll in PAD_ROLLS:
        lift = grasp_lift(size, config, roll, support_clearance, raised)
        if lift is not None:
            candidates.extend((roll, np.array([shift, 0.0, lift]))
                              for shift in grasp_shifts(size, config, roll, both_ways))
            if last_resort:
                beyond.append([(roll, np.array([shift, 0.0, lift]))
                               for shift in last_resort_shifts(size, config, roll)])
    for step in range(config.last_resort_steps):
        candidates.extend(shifts[step] for shifts in beyond if step < len(shifts))
    return tuple(candidates)


def grasp_solutions(models, q_start, p_world_object, R_world_object, size, offset, roll,
                    config):
    """Return {arm: PoseSolution} of both grasp frames of a grasp (offset, roll) from q_start."""
    solutions = {}
    for arm in ARMS:
        frame = grasp_frame(arm, p_world_object, R_world_object, size, offset, roll)
        solutions[arm] = inverse_kinematics(models[arm], frame.p_world_grasp,
                                            frame.R_world_grasp, q_start[arm], config)
    return solutions


def plan_grasp(models, q_current, p_world_object, R_world_object, size, config,
               support_clearance=0.0, place=None):
    """
    Return the GraspPlan of a box (pose, size (3,) [m]) for both arms ({arm: ArmModel}).

    The grasps of grasp_candidates (pad roll, shift along the object's x axis, rise to clear
    the support by support_clearance [m]) are tried in order from the arms' current joint
    positions q_current {arm: (7,)}; the first one both arms reach is the plan. (Moving the
    grasp point on the face by what the arms missed it by, in object x and z, was tried too:
    on 100 catalogue trials it made no unreachable grasp reachable. Taking the reachable grasp
    with the most joint-limit margin instead of the first: 35 % success on catalogue_random
    seed 11 against 41 %.) place: the box's pose (p (3,) [m], R (3, 3)) where it is to be set
    down, or None; given, the grasps shift both ways, sit high on the faces (grasp_lift's
    raised) and place_order ranks them; None (a toss), the last resorts follow the others (a
    box to be set down gets none: its grasp must reach the place too, and none of the places
    refused on the catalogue was reached with them).
    """
    candidates = grasp_candidates(size, config, support_clearance, both_ways=place is not None,
                                  raised=place is not None, last_resort=place is None)
    order, place_reason, clear = range(len(candidates)), '', len(candidates)
    if place is not None:
        order, place_reason, clear = place_order(models, candidates, place, size, config)
    first = None
    for rank, index in enumerate(order):
        roll, offset = candidates[index]
        solutions = grasp_solutions(models, q_current, p_world_object, R_world_object, size,
                                    offset, roll, config)
        if all(solution.reachable for solution in solutions.values()):
            return GraspPlan(offset, True, '', solutions, roll, short=rank >= clear)
        first = first or solutions
    if first is None:
        return GraspPlan(np.zeros(3), False, place_reason, {})
    unreachable = [arm for arm in ARMS if not first[arm].reachable]
    reason = '; '.join(
        f'{arm} arm misses its grasp frame by {1000.0 * first[arm].position_error:.0f} mm, '
        f'{math.degrees(first[arm].orientation_error):.0f} deg within its joint limits '
        f'(margin {config.joint_margin:g} rad)' for arm in unreachable)
    if place is not None:
        reason += (f' with every grasp that reaches the place (within '
                   f'{1000.0 * config.max_place_overreach:.0f} mm)')
    return GraspPlan(np.zeros(3), False, reason, first)


def place_order(models, candidates, place, size, config):
    """
    Return (candidate indices to try, why none is left, how many lead) for a box to be set down.

    place: the box's pose at the place (p (3,) [m], R (3, 3)). The candidates whose wrists all
    stay place_wrist_margin inside their straight-arm reach there (core.elbow_reach
    .wrist_overreach) come first, in their order; then, least overreach first, those whose
    wrists lie at most max_place_overreach beyond it: a box grasped near the arms' bases
    (shifted toward +x to be reached there) is set down short rather than refused. A grasp
    with a wrist farther out is left out: the arm would stop short with the box held above
    the table. The count is that of the leading candidates that keep the margin.
    """
    reaches = {arm: models[arm].elbow_reach() for arm in ARMS}
    p_world_place, R_world_place = place
    overreach = [wrist_overreach(reaches, p_world_place, R_world_place, size, offset, roll)
                 for roll, offset in candidates]
    clear = [index for index, excess in enumerate(overreach)
             if excess <= -config.place_wrist_margin]
    short = sorted((index for index, excess in enumerate(overreach)
                    if -config.place_wrist_margin < excess <= config.max_place_overreach),
                   key=overreach.__getitem__)
    reason = ''
    if not clear and not short:
        reason = (f'place {np.round(np.asarray(p_world_place, dtype=float), 3).tolist()} m out '
                  f'of reach: with any grasp on the faces a wrist lies at least '
                  f'{1000.0 * min(overreach):.0f} mm beyond its straight-arm reach there')
    return clear + short, reason, len(clear)
