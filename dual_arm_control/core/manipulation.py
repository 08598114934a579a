"""
Cooperative manipulation of the grasped object: eq. 7, toss DS (eqs. 8-9) and lift.

The object is a point x_o (3,) [m], world frame; the arms are stacked as x = [x_L; x_R] (6,).
Object fields use the absolute gain of the coordination (the object moves with the absolute
position of the hands), so one gain matrix A serves reaching and manipulation alike.
"""

from dataclasses import dataclass
from typing import NamedTuple

from dual_arm_control.core.cooperative import absolute_relative, left_right
from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.geometry import cross3, matrix_to_rpy, rpy_to_matrix, unit
from dual_arm_control.core.modulation import (
    activation_distances, activations, modulated_velocity, modulation_bases,
    ModulationRegionConfig, region_activations, RegionActivation, transitory_attractor)
from dual_arm_control.core.orientation import orientation_ds_angular_velocity, OrientationDsConfig
from dual_arm_control.core.settings import check_settings, setting
from dual_arm_control.core.speed_shaping import saturated_velocity
from dual_arm_control.core.validation import check_vector, finite_array
import numpy as np

ORIENTATION_MODES = ('free', 'given', 'hold', 'level')
"""How the toss orients the carried object (TossConfig.orientation)."""

_TOSS_REGION = ModulationRegionConfig(
    transitory_distance=0.14, radial_distance=0.30, normal_distance=0.15,
    tangent_distance=0.02, radial_slope=100.0, normal_slope=80.0, tangent_slope=300.0)


@dataclass(frozen=True)
class TossConfig:
    """
    Desired release state of the object and the modulation region of the toss DS.

    region: the modulation region around x_r. Defaults: x_t 0.14 m before the release (the
    reference's 0.4 rho with rho = 0.35), delta_tangent 0.02 m and a radial ball of 0.30 m
    around x_t, which keeps the field along e1 positive through the release point and 0.1 m
    beyond; delta_normal 0.15 m with a normal slope of 80/m, so that a box off the release line
    joins it in the line's own field instead of going to x_t first. Thrown sideways, x_t lies
    to the side of the box; with delta_normal 0.04 m (slope 600/m) the field turned from x_t
    onto the line within a few cm and asked the held box for up to 70 m/s^2 along the pads'
    normal, and the box left the grasp (toss_to_target, a 0.16 m cube to y = -0.285 m).
    """

    release_position: tuple = setting(
        (0.68, 0.0, 0.45), "x_r, world frame. Default (0.68, 0, 0.45): the reference's release x "
        "with a height on the line through the paper's grasp pose (0.41, 0, 0.32) along the "
        'release direction.', unit='m', size=3)
    release_direction: tuple = setting(
        (1.0, 0.0, 0.5), 'Direction of the release velocity, normalised here. Default (1, 0, '
        "0.5), the reference's releaseLinVel_dir.", size=3)
    toss_speed: float = setting(
        0.85, 'Release speed. Default 0.85 (reference desVtoss).',
        unit='m/s', low=0, high=3.0, low_open=True)
    region: ModulationRegionConfig = _TOSS_REGION
    lateral_gain: float = setting(
        9.0, 'k_n, rate of the target fields along e2, e3 that bring the object onto the release '
        'line, away from the release plane (eq. 6 uses the DS gain k for them; '
        'max_lateral_gain raises it as the plane nears). With k_n = 9 (twice k) and no rise, a '
        'box that starts off the line was released ~0.3 deg closer to the planned direction per '
        'mm of its initial offset than with k.', unit='1/s', low=0, high=100.0, low_open=True)
    max_lateral_gain: float = setting(
        30.0, 'Largest rate of the target fields along e2, e3 as the release plane nears '
        '(core.manipulation.lateral_rate: 2 |x_dot_r| / s, s left to the plane, so that the '
        'offset reaches the release line with no sideways velocity); at most lateral_gain turns '
        'the rise off. A box thrown 49 deg sideways joins a release line that starts 28 cm '
        'beside it: at lateral_gain alone it left 1.4 cm off the line and 7.7 deg off the '
        'planned direction, with the rise 1.6 deg (toss_to_target_random seed 51, trial 96; '
        '195 of 200 succeed against 192).',
        unit='1/s', low=0, high=200.0)
    speed_integral_gain: float = setting(
        40.0, "Gain of the outer loop on the carried object's speed shortfall "
        "(SpeedErrorIntegrator); 0 turns the loop off. The held box's speed is read from the "
        "pads' kinematics (core.held_object), clean enough for more than 20: over 100 "
        'paper_toss_random trials the release speed error is -1.2 % median at 20, -0.7 % at '
        '40, -0.2 % at 80; in realtime mode 80 wound up behind late ticks (paper_toss 1 of 4 '
        'within its release limits, 3 of 3 at 40).', unit='1/s', low=0, high=200.0)
    speed_correction_limit: float = setting(
        0.45, "The speed loop's correction is capped to this fraction of the desired speed. "
        'The arms carry the 3-6 kg catalogue boxes up to 40 % slow without it '
        '(catalogue_random, seed 11, 300 trials: 252 succeed at 0.45 or 0.7, 247 at 0.25, '
        '12 and 18 of them released too slow or off direction).', low=0, high=1.0)
    release_correction_share: float = setting(
        0.5, "Share of the speed loop's correction that the pads keep while they open "
        '(core.speed_shaping.released_velocity). The arms carry a heavy box until the pads let '
        'go of it: with none kept, 6 kg packs grabbed at the end of the reach left 5-8 % slow and '
        '3-6 deg flat; with all of it, paper_toss_random left 1.5 % fast (median, 100 trials; '
        '-0.55 % with none, +0.04 % with half). Half costs slow throws: two at 0.6 m/s, 40 deg '
        'to the side, left 8.5 % fast (3.2 and 5.8 % with none; toss_to_target_random seed 3: '
        '197 of 200 succeed, 199 with none).', low=0, high=1.0)
    orientation: str = setting(
        'hold', "The carried object's orientation (the rotation term of eq. 8): hold keeps the "
        'orientation the box had when the grasp settled, so the impact and the unequal lag of '
        'the arms do not set it turning (catalogue_random seed 11: 47 %, landing p95 4 cm, '
        'against 42 % and 7 cm with free); free leaves it as the grasp holds it (omega = 0); '
        'given turns it to release_rpy_deg; level keeps it upright at its current yaw. hold '
        "turns the yaw toward the toss heading where an arm's wrist would be beyond its reach at "
        'the release point (release_overreach).', choices=ORIENTATION_MODES)
    release_overreach: float = setting(
        0.0, "In the hold mode, how far an arm's wrist may lie beyond its straight-arm reach at "
        'the release point (the box held at its grasp yaw) before the box is turned toward the '
        'toss heading while carried (core.elbow_reach.reachable_release_rotation). A stretched '
        'far arm falls behind and lets the box turn in the grasp: over catalogue_random (seed '
        '11, 300 trials) the boxes whose far wrist lay 5-10 cm beyond slipped 5.1 mm (median; '
        '44 of 84 above 5 mm) with 0.1 m, those within reach 2.4 mm. With 0 (and '
        'hold_turn_rate 4/s) the slip p95 fell from 6.3 to 5.8 mm.',
        unit='m', low=0, high=1.0)
    release_rpy_deg: tuple = setting(
        (0.0, 0.0, 0.0), 'Desired orientation of the object at release, world frame: roll, '
        'pitch, yaw (URDF convention, R = Rz Ry Rx).', unit='deg', low=-180.0, high=180.0,
        size=3)
    orientation_rate: float = setting(
        12.0, "Convergence rate of the object's orientation while carried (the appendix-A "
        'orientation DS applied to the object) in the level mode, and of its roll and pitch in '
        'the hold mode (its yaw: hold_turn_rate): the toss carries '
        'the box for about 0.35 s, in which 12/s leaves 1.5 % of an error (catalogue_random '
        'seed 11, 300 trials, bases 1.2 m apart: 242 succeed at 12/s, 236 at 16/s).',
        unit='1/s', low=0, high=50.0, low_open=True)
    hold_turn_rate: float = setting(
        4.0, "In the hold mode, the convergence rate of the box's yaw about its own vertical axis "
        '(orientation_rate holds its roll and pitch): a box turned for the far arm '
        '(release_overreach) turns by up to 17 deg in the 0.35 s carry. At orientation_rate '
        '(12/s) the turn starts at up to 1.4 rad/s as the grasp settles and pulled the near pad '
        'off its face for 20-30 ms (slides of 8-11 mm); at 4/s for all three axes the boxes '
        'left rolling at 0.6 rad/s and landed up to 46 mm off (catalogue_random seed 11, 100 '
        'trials: landing p95 34 mm, 21 at 12/s); yaw alone at 4/s: 19 mm.',
        unit='1/s', low=0, high=50.0, low_open=True)
    release_orientation_rate: float = setting(
        20.0, 'The same rate in the given mode, turning the box to release_rpy_deg: the box turns '
        'by up to 40 deg on its way. paper_toss_oriented_random (seed 3, 200 trials, 70 N grip '
        'floor): release orientation error p95 5.15 deg at 16/s, 4.83 at 20; 180 and 183 '
        'succeed; release direction p95 4.78 and 5.03 deg. Turns of 30-45 deg still leave '
        '5.1 deg median.',
        unit='1/s', low=0, high=50.0, low_open=True)

    def __post_init__(self):
        check_settings(self)
        direction = check_vector('release_direction', self.release_direction, 3)
        if np.linalg.norm(direction) < 1e-6:
            raise ConfigError(f'release_direction must be non-zero, got {direction.tolist()}')
        if not isinstance(self.region, ModulationRegionConfig):
            raise ConfigError(f'region must be a ModulationRegionConfig, got {self.region!r}')


@dataclass(frozen=True)
class LiftConfig:
    """Point attractor for the grasped object (pick and lift)."""

    position: tuple = setting(
        (0.45, 0.0, 0.45), 'Lift position, world frame. Default (0.45, 0, 0.45) (reference).',
        unit='m', size=3)
    max_speed: float = setting(
        0.85, 'Speed cap of the object.', unit='m/s', low=0, high=3.0, low_open=True)

    def __post_init__(self):
        check_settings(self)


class TossGeometry(NamedTuple):
    """Constant data of the toss DS, built by toss_geometry."""

    release_position: np.ndarray
    """x_r (3,) [m]."""
    basis: np.ndarray
    """E^o (1, 3, 3), e1 along the release velocity."""
    transitory: np.ndarray
    """x_t^o (3,) [m], rho before x_r on the release line."""
    release_velocity: np.ndarray
    """x_dot_r (3,) [m/s]."""
    gain: float
    """k > 0 [1/s]; the object field is -k (x_o - x_*)."""
    lateral_gain: float
    """k_n > 0 [1/s]; the target fields along e2, e3 are -k_n (x_o - x_t) far from x_r."""
    max_lateral_gain: float
    """[1/s] the most lateral_rate raises k_n to near the release plane."""
    region: ModulationRegionConfig


class TossOutput(NamedTuple):
    """One evaluation of the toss DS."""

    velocity: np.ndarray
    """x_dot_abs = M^o f_o (3,) [m/s], eq. 8."""
    activation: RegionActivation


def release_velocity(config):
    """Return x_dot_r = toss_speed * unit(release_direction) (3,) [m/s]."""
    return config.toss_speed * unit(config.release_direction, 'release_direction')


def toss_geometry(config, coordination):
    """Return the TossGeometry of a TossConfig; the gain is coordination.absolute_gain."""
    velocity = release_velocity(config)
    basis = modulation_bases(velocity)
    position = np.asarray(config.release_position, dtype=float)
    transitory = transitory_attractor(position[None], basis,
                                      config.region.transitory_distance)[0]
    return TossGeometry(position, basis, transitory, velocity,
                        float(coordination.absolute_gain), float(config.lateral_gain),
                        float(config.max_lateral_gain), config.region)


def release_rotation(config):
    """Return the desired object orientation at release R (3, 3) of a TossConfig, world frame."""
    return rpy_to_matrix(np.radians(np.asarray(config.release_rpy_deg, dtype=float)))


def level_rotation(R_world_object):
    """Return the upright orientation (3, 3) with the yaw of R_world_object: roll, pitch zero."""
    return rpy_to_matrix((0.0, 0.0, matrix_to_rpy(R_world_object)[2]))


def object_orientation_ds(config, max_angular_speed, place=None):
    """
    Return the OrientationDsConfig turning the carried object.

    At TossConfig.release_orientation_rate toward a given release orientation, else at
    orientation_rate, but in the hold mode at hold_turn_rate about the box's own z axis (the
    third error component: the target is the grasped box, upright, turned about world z).
    place: the PlaceConfig of a box to be set down, which turns to the place's yaw at
    orientation_rate and at most place.max_angular_speed [rad/s].
    """
    if place is not None:
        return OrientationDsConfig(
            convergence_rates=(config.orientation_rate,) * 3,
            max_angular_speed=min(max_angular_speed, place.max_angular_speed))
    if config.orientation == 'given':
        rates = (config.release_orientation_rate,) * 3
    elif config.orientation == 'hold':
        rates = (config.orientation_rate, config.orientation_rate, config.hold_turn_rate)
    else:
        rates = (config.orientation_rate,) * 3
    return OrientationDsConfig(convergence_rates=rates, max_angular_speed=max_angular_speed)


def object_angular_velocity(R_world_object, R_world_desired, orientation_ds):
    """
    Return the desired object angular velocity omega^o (3,) [rad/s], world frame (eq. 8).

    The appendix-A orientation DS applied to the object: omega^o turns R_world_object toward
    R_world_desired at the DS's rate, saturated to its max angular speed. The arms realise it
    through eq. 8: the relative velocity -[x_o^R - x_o^L]x omega^o and each tool turning with
    omega^o.
    """
    return orientation_ds_angular_velocity(R_world_object, R_world_desired, orientation_ds)


def toss_attractor(x_object, geometry, gamma):
    """
    Return the e1 attractor x_*^o (3,) [m] of the toss DS (eq. 9).

    x_*^o = (1 - gamma) x_t^o + gamma (x^o - A^-1 x_dot_r) with A = -k I3; the directions
    e2, e3 keep x_t^o.
    """
    x_object = np.asarray(x_object, dtype=float)
    return ((1.0 - gamma) * geometry.transitory
            + gamma * (x_object + geometry.release_velocity / geometry.gain))


def lateral_rate(x_object, geometry):
    """
    Return the rate [1/s] of the toss's target fields along e2, e3 at x_o (3,) [m].

    Carried at the release speed v toward the release plane, an offset from the release line
    that decays at 2 v / s (s: what is left to the plane along e1) shrinks as s^2: it reaches
    the line with no sideways velocity at the plane, under a constant sideways deceleration.
    A constant k_n leaves k_n d of sideways velocity at release for an offset d still left.
    The rate is k_n at least and max_lateral_gain at most (also at and past the plane).
    """
    remaining = float((geometry.release_position - x_object) @ geometry.basis[0, :, 0])
    speed = float(np.linalg.norm(geometry.release_velocity))
    arrival = (geometry.max_lateral_gain if remaining <= 0.0
               else min(2.0 * speed / remaining, geometry.max_lateral_gain))
    return max(geometry.lateral_gain, arrival)


def toss_target_fields(x_object, geometry, gamma):
    """
    Return f_mi (1, 3, 3) [m/s]: A(x^o - x_*^o) along e1, -k_n (x^o - x_t^o) along e2, e3.

    k_n is lateral_rate at x_o.
    """
    x_object = np.asarray(x_object, dtype=float)
    first = -geometry.gain * (x_object - toss_attractor(x_object, geometry, gamma))
    other = -lateral_rate(x_object, geometry) * (x_object - geometry.transitory)
    return np.stack((first, other, other))[None]


def toss_velocity(x_object, geometry):
    """
    Return TossOutput: desired absolute velocity x_dot_abs = M^o f_o (eq. 8) at x_o (3,) [m].

    f_o = -k (x^o - x_t^o) is the object's nominal field; M^o uses eq. 9's attractor for e1.
    On the release line the e1 component is alpha gamma |x_dot_r| - (1 - alpha gamma) k s
    (s = distance past x_t^o), positive wherever alpha gamma / (1 - alpha gamma) > k s /
    |x_dot_r|, i.e. through x_r and beyond for the default region.
    """
    x_object = finite_array('x_object', x_object, (3,))
    distances = activation_distances(x_object[None], geometry.transitory[None], geometry.basis,
                                     geometry.region.transitory_distance)
    activation = region_activations(activations(distances, geometry.region), shared=False)
    nominal = -geometry.gain * (x_object - geometry.transitory)
    targets = toss_target_fields(x_object, geometry, activation.gamma[0])
    velocity = modulated_velocity(geometry.basis, nominal[None], targets, activation.alpha)
    return TossOutput(velocity[0], activation)


def desired_relative_velocity(grasp_points, object_angular_velocity):
    """
    Return x_dot_rel = -[x_o^R - x_o^L]x omega^o (3,) [m/s] (eq. 8).

    grasp_points (2, 3) [m]: left and right grasp points; object_angular_velocity (3,)
    [rad/s], world frame. Zero in pure translation.
    """
    grasp_points = np.asarray(grasp_points, dtype=float)
    return cross3(object_angular_velocity, grasp_points[1] - grasp_points[0])


def manipulation_attractor(x, x_object, x_object_desired, grasp_points, kappa,
                           free_attractor):
    """
    Return x_* (6,) [m] of the manipulation DS (eq. 7), blended by the contact activation.

    x_* = kappa T_b^-1 [x_d^o + (x_abs - x^o); x_o^R - x_o^L] + (1 - kappa) free_attractor.
    Eq. 7 prints only the first term; with kappa = 0 that would be the origin, so the
    attractor of the free motion (e.g. the impact attractor) takes over instead. kappa = 1
    gives eq. 7 exactly. grasp_points (2, 3) are the current grasp points on the object.
    """
    x = np.asarray(x, dtype=float)
    grasp_points = np.asarray(grasp_points, dtype=float)
    absolute = absolute_relative(x)[:3]
    object_target = np.concatenate((
        np.asarray(x_object_desired, dtype=float) + absolute - x_object,
        grasp_points[1] - grasp_points[0]))
    return kappa * left_right(object_target) + (1.0 - kappa) * np.asarray(free_attractor)


def cooperative_manipulation_velocity(x, object_velocity, relative_velocity, grasp_points,
                                      coordination):
    """
    Return the arms' velocity x_dot (6,) [m/s] carrying the object (eqs. 7-8).

    x_dot = T_b^-1 [x_dot_abs; x_dot_rel - k_rel (x_rel - (x_o^R - x_o^L))]: the hands' midpoint
    moves with the desired object velocity, their relative position follows x_dot_rel and is
    held at the grasp points' separation. With object_velocity = -k_abs (x^o - x_d^o) this is
    A'(x - x_*) with x_* from eq. 7 (kappa = 1, Proposition 3).
    """
    x = np.asarray(x, dtype=float)
    grasp_points = np.asarray(grasp_points, dtype=float)
    relative = x[3:] - x[:3]
    relative_target = grasp_points[1] - grasp_points[0]
    abs_rel_velocity = np.concatenate((
        np.asarray(object_velocity, dtype=float),
        np.asarray(relative_velocity, dtype=float)
        - coordination.relative_gain * (relative - relative_target)))
    return left_right(abs_rel_velocity)


def lift_velocity(x_object, config, coordination):
    """Return the object velocity (3,) [m/s] toward the lift position, capped at max_speed."""
    x_object = finite_array('x_object', x_object, (3,))
    velocity = -coordination.absolute_gain * (x_object - np.asarray(config.position))
    return saturated_velocity(velocity, config.max_speed)
