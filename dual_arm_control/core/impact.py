"""
Coordinated reaching with impact: desired impact velocity and the eq. 6 attractor.

Stacked arm vectors are x = [x_L; x_R] (6,) in the world frame [m]; per-arm arrays are (2, 3)
with row 0 left and row 1 right. The impact DS is eq. 1 with the nominal field eq. 4 aimed at
the transitory attractors and the per-direction target fields of Proposition 2.
"""

from dataclasses import dataclass
import math
from typing import NamedTuple

from dual_arm_control.core.cooperative import (
    cooperative_transform, cooperative_transform_inverse, coordinated_gain_matrix,
    impact_frame_gain_matrix)
from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.geometry import unit
from dual_arm_control.core.modulation import (
    activation_distances, activations, modulated_velocity, modulation_bases,
    ModulationRegionConfig, region_activations, RegionActivation, transitory_attractor)
from dual_arm_control.core.settings import check_settings, setting
from dual_arm_control.core.validation import check_range, finite_array
import numpy as np

_PARALLEL_TOLERANCE = 1e-9


@dataclass(frozen=True)
class ImpactConfig:
    """Desired impact and its modulation region (region, around each grasp point)."""

    impact_speed: float = setting(
        0.5, 'Speed of each pad along its impact direction at contact. Default 0.5 m/s, the '
        "paper's impact speed (section IV-A).", unit='m/s', low=0, high=2.0, low_open=True)
    max_tilt_deg: float = setting(
        40.0, 'Largest tilt of the impact direction away from the contact normal toward the '
        "object's desired motion. Default 40 (reference max_friction_angle).",
        unit='deg', low=0, high=89.0)
    synchronise: bool = setting(
        True, 'True keeps the attraction of the relative coordinate along e1 while the desired '
        'velocity is applied (see impact_target_field); false is eq. 6 as printed, which '
        'switches that attraction off as gamma -> 1.')
    pad_half_height: float = setting(
        0.05, 'Half extent of a pad across the impact plane, i.e. how far below the grasp point '
        'the pad reaches. Default 0.05 (the 0.15 x 0.10 m pad).', unit='m', low=0, high=0.5)
    support_clearance: float = setting(
        0.02, "The pad's lowest point stays this far above the surface the box rests on while it "
        'runs in along e1 (see clearance_limited_direction).', unit='m', low=0, high=0.5)
    elbow_clearance: float = setting(
        0.02, 'An impact direction whose run-in would draw the wrist closer to the shoulder than '
        "this beyond the elbow's joint limit (or than the grasp pose itself does) turns, within "
        'max_tilt_deg of the face normal, away from the shoulder until it does not '
        '(core.elbow_reach.elbow_clear_direction).', unit='m', low=0, high=0.5)
    synchronisation_distance: float = setting(
        0.1, 'Within this gap of its face the arms are timed to touch together '
        "(core.approach.synchronised_arrival); 0 disables it. The box's yaw otherwise delays "
        'one pad by about 0.9 ms per degree. 0.15 made the gaps worse (catalogue_random, 100 '
        'trials: p95 8 ms against 6).', unit='m', low=0, high=2.0)
    synchronisation_gain: float = setting(
        3.0, 'Gain k of the arrival synchroniser: the difference of the times to contact '
        'shrinks like T^k, so k > 1 fades the speed change before contact.', low=0, high=20.0)
    synchronisation_max_speedup: float = setting(
        1.35, 'Largest factor by which the synchroniser speeds up the arm behind. The pad of an '
        'arm whose elbow is near its limit stays a few degrees off its face and its corner '
        'leads, so the arm behind may need much more than the average.', low=1.0, high=3.0)
    synchronisation_max_slowdown: float = setting(
        0.75, 'Smallest factor by which the synchroniser slows the arm ahead.', low=0.1,
        high=1.0)
    synchronisation_final_gap: float = setting(
        0.005, 'The synchroniser fades out between twice this gap and this gap of the nearer '
        'pad, where a gap is within the mocap noise and the arms could not follow a change in '
        'time; over 100 catalogue_random trials 0 / 0.005 / 0.01 m gave contact-time gap p95 '
        '6 / 6.4 / 8 ms and 67 / 99 / 100 % of the pads within 10 % of the impact speed.',
        unit='m', low=0, high=0.1)
    synchronisation_lag: float = setting(
        0.025, 'Time constant with which a pad regains the commanded closing speed as the '
        'synchroniser fades; the times to contact count the gap an arm slower than commanded '
        'loses that way (or one faster gains). 0 times by the commanded speeds alone: over 60 '
        'catalogue_random_place trials (seed 12) contact gap p95 6.4 ms against 4.0, pads '
        'within 10 % of the impact speed in 54 against 56 of 57; catalogue_random (100, seed '
        '11) p95 4 ms either way, max 4 against 8 ms.', unit='s', low=0, high=0.2)
    region: ModulationRegionConfig = ModulationRegionConfig()

    def __post_init__(self):
        check_settings(self)
        if not isinstance(self.region, ModulationRegionConfig):
            raise ConfigError(f'region must be a ModulationRegionConfig, got {self.region!r}')


class ArrivalSchedule(NamedTuple):
    """Settings of core.approach.synchronised_arrival: gaps [m], gain, speed factors, lag [s]."""

    horizon: float
    final_gap: float
    gain: float
    slowest: float
    fastest: float
    lag: float


class ImpactGeometry(NamedTuple):
    """Constant data of one coordinated impact, built by impact_geometry."""

    desired_positions: np.ndarray
    """x_d (2, 3) [m], the grasp points."""
    bases: np.ndarray
    """E^L, E^R (2, 3, 3), e1 along the impact direction."""
    transitory: np.ndarray
    """x_t (6,) [m], stacked transitory attractors."""
    desired_velocity: np.ndarray
    """x_dot_d (6,) [m/s], stacked desired impact velocities."""
    gain_matrix: np.ndarray
    """E A' E^T (6, 6) [1/s], the coordinated gain in the impact frames."""
    relative_projector: np.ndarray
    """P_rel (6, 6), zero unless synchronising coordinated arms."""
    region: ModulationRegionConfig
    shared: bool
    """Activations shared by both arms (coordinated) or per arm (decoupled)."""


class ImpactDSOutput(NamedTuple):
    """One evaluation of the impact DS."""

    velocity: np.ndarray
    """x_dot (6,) [m/s], eq. 1."""
    nominal: np.ndarray
    """f_n (6,) [m/s], eq. 4 toward the transitory attractors."""
    activation: RegionActivation


def max_impact_tilt(config, friction=None):
    """Return the largest impact tilt [rad]: max_tilt_deg, or atan(friction) if smaller."""
    tilt = math.radians(config.max_tilt_deg)
    if friction is not None:
        check_range('friction', friction, 0.0, math.inf, low_open=True)
        tilt = min(tilt, math.atan(friction))
    return tilt


def impact_direction(contact_normal, object_desired_velocity, max_tilt):
    """
    Return the unit impact direction (3,): the contact normal tilted toward the object motion.

    contact_normal (3,) points into the object; object_desired_velocity (3,) [m/s] is the
    velocity the object should take after the grasp (e.g. the toss field at the object). The
    result lies in the plane of the two vectors, tilted from the normal by the angle between
    them, clamped to max_tilt [rad] (the friction cone). Without a tangential component the
    normal itself is returned.
    """
    normal = unit(contact_normal, 'contact_normal')
    velocity = finite_array('object_desired_velocity', object_desired_velocity, (3,))
    along = velocity @ normal
    tangential = velocity - along * normal
    tangential_norm = np.linalg.norm(tangential)
    if tangential_norm <= _PARALLEL_TOLERANCE * max(np.linalg.norm(velocity), 1e-12):
        return normal
    tilt = min(math.atan2(tangential_norm, along), max_tilt)
    return math.cos(tilt) * normal + math.sin(tilt) / tangential_norm * tangential


def clearance_limited_direction(direction, height_above_support, config):
    """
    Return the impact direction e1 (3,) with its rise limited so the run-in clears the support.

    The DS runs the last rho along e1 from the transitory attractor x_t = x_d - rho e1 (eq. 5):
    a direction that rises toward the grasp point starts the run-in rho e1_z below it. With the
    grasp point height_above_support [m] above the surface the box rests on, the pad's lowest
    point (pad_half_height below its centre) stays support_clearance above that surface when
    e1_z <= (height_above_support - pad_half_height - support_clearance) / rho. A steeper e1
    keeps its horizontal heading and gets the largest rise allowed (none if the box is too
    low for any); a level or falling e1 is returned unchanged.
    """
    direction = np.asarray(direction, dtype=float)
    rho = config.region.transitory_distance
    room = height_above_support - config.pad_half_height - config.support_clearance
    max_rise = max(room, 0.0) / rho
    if direction[2] <= max_rise:
        return direction
    horizontal = direction[:2]
    horizontal_norm = math.hypot(horizontal[0], horizontal[1])
    if horizontal_norm < _PARALLEL_TOLERANCE:
        return direction
    rise = min(max_rise, 1.0)
    scale = math.sqrt(1.0 - rise * rise) / horizontal_norm
    return np.array([horizontal[0] * scale, horizontal[1] * scale, rise])


def desired_impact_velocity(directions, impact_speed):
    """Return x_dot_d = impact_speed * direction per arm (2, 3) [m/s]."""
    return impact_speed * np.asarray(directions, dtype=float)


def relative_projector(bases):
    """
    Return P_rel = E T_b^-1 diag(0, I3) T_b E^T (6, 6).

    Projects stacked vectors onto the relative coordinate of the arms' local positions in the
    bases E^h: the part of the motion that makes one arm lead the other.
    """
    rotation = np.zeros((6, 6))
    rotation[:3, :3] = bases[0]
    rotation[3:, 3:] = bases[1]
    selector = np.diag(np.repeat([0.0, 1.0], 3))
    local = cooperative_transform_inverse() @ selector @ cooperative_transform()
    return rotation @ local @ rotation.T


def impact_target_field(nominal, desired_velocity, gamma, projector):
    """
    Return f_m1 = A'(x - x_*) (6,) [m/s] for the e1 directions, x_* from impact_attractor.

    nominal: f_n = A'(x - x_t) (6,). gamma (2,) per arm (equal entries for coordinated arms).
    With projector = 0 this is eq. 6 as printed: f_m1 = (1 - gamma) f_n + gamma x_dot_d.
    With projector = P_rel the relative part of f_n is kept:
    f_m1 = (1 - gamma) f_n + gamma (x_dot_d + P_rel f_n). The desired velocities are equal in
    the impact frames, so P_rel x_dot_d = 0 and the absolute motion along e1 still gets exactly
    x_dot_d, but an arm that leads the other along its e1 is slowed and the other sped up at
    the relative rate. Eq. 6 as printed leaves that difference uncorrected once gamma = 1.
    """
    gamma6 = np.repeat(gamma, 3)
    return nominal + gamma6 * (desired_velocity - nominal + projector @ nominal)


def impact_attractor(x, transitory, gain_matrix, desired_velocity, gamma, projector=None):
    """
    Return the attractor x_* (6,) [m] of the e1 directions (eq. 6).

    x_* = (1 - gamma) x_t + gamma (x - A'^-1 x_dot_d) - gamma P_rel (x - x_t); the last term
    is absent (projector None or 0) in eq. 6 as printed, see impact_target_field. The e2, e3
    directions keep x_* = x_t. gamma (2,) per arm; with unequal entries (decoupled arms, A'
    block diagonal) the blend is applied arm by arm.
    """
    x = np.asarray(x, dtype=float)
    projector = np.zeros((6, 6)) if projector is None else projector
    nominal = gain_matrix @ (x - transitory)
    field = impact_target_field(nominal, desired_velocity, gamma, projector)
    return x - np.linalg.solve(gain_matrix, field)


def impact_target_fields(x, transitory, gain_matrix, desired_velocity, gamma, projector=None):
    """
    Return the per-direction target fields f_mi (2, 3, 3) [m/s] of Proposition 2.

    targets[h, 0] = f_m1 = A'(x - x_*) with x_* from eq. 6 (impact_attractor);
    targets[h, 1] = targets[h, 2] = A'(x - x_t).
    """
    x = np.asarray(x, dtype=float)
    attractor = impact_attractor(x, transitory, gain_matrix, desired_velocity, gamma, projector)
    first = (gain_matrix @ (x - attractor)).reshape(2, 3)
    other = (gain_matrix @ (x - transitory)).reshape(2, 3)
    return np.stack((first, other, other), axis=1)


def impact_geometry(grasp_points, impact_directions, coordination, impact):
    """
    Return the ImpactGeometry of a grasp.

    grasp_points (2, 3) [m]: contact points x_d (left, right), world frame.
    impact_directions (2, 3): unit impact directions e1 (e.g. from impact_direction).
    coordination: CoordinationConfig; impact: ImpactConfig.
    """
    grasp_points = finite_array('grasp_points', grasp_points, (2, 3))
    directions = finite_array('impact_directions', impact_directions, (2, 3))
    bases = modulation_bases(directions)
    rho = impact.region.transitory_distance
    gain = impact_frame_gain_matrix(coordinated_gain_matrix(coordination), bases)
    synchronised = coordination.coordinated and impact.synchronise
    projector = relative_projector(bases) if synchronised else np.zeros((6, 6))
    return ImpactGeometry(
        desired_positions=grasp_points,
        bases=bases,
        transitory=transitory_attractor(grasp_points, bases, rho).reshape(6),
        desired_velocity=desired_impact_velocity(bases[:, :, 0], impact.impact_speed).reshape(6),
        gain_matrix=gain,
        relative_projector=projector,
        region=impact.region,
        shared=bool(coordination.coordinated))


def grasp_distance(x, geometry):
    """Return max_h |x^h - x_d^h| [m], the larger distance of an arm to its grasp point."""
    error = np.asarray(x, dtype=float).reshape(2, 3) - geometry.desired_positions
    return math.sqrt(max(error[0] @ error[0], error[1] @ error[1]))


def impact_ds_velocity(x, geometry, grasp_velocity=None):
    """
    Return ImpactDSOutput: the coordinated reach-with-impact velocity (eq. 1) at x (6,) [m].

    f_n = E A' E^T (x - x_t) (eq. 4), f_m1 from eq. 6, f_m2 = f_m3 = f_n (Proposition 2),
    alpha, gamma from the region, x_dot = M f_n + f_g. grasp_velocity f_g (6,) is optional.
    """
    x = finite_array('x', x, (6,))
    nominal = geometry.gain_matrix @ (x - geometry.transitory)
    positions = x.reshape(2, 3)
    distances = activation_distances(positions, geometry.transitory.reshape(2, 3),
                                     geometry.bases, geometry.region.transitory_distance)
    activation = region_activations(activations(distances, geometry.region), geometry.shared)
    first = impact_target_field(nominal, geometry.desired_velocity, activation.gamma,
                                geometry.relative_projector).reshape(2, 3)
    other = nominal.reshape(2, 3)
    targets = np.stack((first, other, other), axis=1)
    grasp = None if grasp_velocity is None else np.reshape(grasp_velocity, (2, 3))
    velocity = modulated_velocity(geometry.bases, other, targets, activation.alpha, grasp)
    return ImpactDSOutput(velocity.reshape(6), nominal, activation)
