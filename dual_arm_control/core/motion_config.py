"""
The motion generator's configuration: task, object, standby, speeds and the component configs.

One frozen dataclass gathers every setting of the DS motion generator (the ds_motion_generator
node's parameters, docs/parameters.md); core.motion_generator runs it.
"""

from dataclasses import dataclass, field

from dual_arm_control.core.contact import ContactConfig, FtCompensationConfig
from dual_arm_control.core.cooperative import CoordinationConfig
from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.impact import ArrivalSchedule, ImpactConfig
from dual_arm_control.core.manipulation import LiftConfig, TossConfig
from dual_arm_control.core.moving_grab import MovingGrabConfig
from dual_arm_control.core.moving_target import ConveyorTossConfig
from dual_arm_control.core.orientation import OrientationDsConfig
from dual_arm_control.core.phases import PhaseConfig, Task, task_from_name, TASK_NAMES
from dual_arm_control.core.place import PlaceConfig
from dual_arm_control.core.reachability import ReachabilityConfig
from dual_arm_control.core.regrasp import RegraspConfig
from dual_arm_control.core.resting_object import RestingObjectConfig
from dual_arm_control.core.settings import check_settings, setting
from dual_arm_control.core.speed_shaping import SpeedProfileConfig
from dual_arm_control.core.toss_planning import ReleasePlanningConfig
import numpy as np


@dataclass(frozen=True)
class MotionGeneratorConfig:
    """
    Everything the motion generator needs besides its inputs (SI units).

    standby_positions (2, 3) [m] and standby_rotations (2, 3, 3) are the tool standby poses in the
    world, rows left, right (set by the cell, not tunable); coordination, impact, toss, lift,
    place, speed, orientation, phases, contact, ft, reachability, regrasp, release_planning,
    conveyor, moving_grab and resting_object are the component configs (see their modules).
    """

    task: object = setting(
        Task.PICK_AND_TOSS.value, 'The task of the episode: what follows the grasp.',
        choices=TASK_NAMES)
    object_size: tuple = setting(
        (0.2, 0.2, 0.2), 'Box edges along object x, y (the squeeze axis) and z.',
        unit='m', low=0, low_open=True, size=3)
    standby_positions: tuple = ((0.35, 0.36, 0.80), (0.35, -0.36, 0.80))
    standby_rotations: tuple = (tuple(map(tuple, np.eye(3))), tuple(map(tuple, np.eye(3))))
    standby_gain: float = setting(
        3.0, 'Per-arm point attractor gain toward standby (and on retract).',
        unit='1/s', low=0, high=100.0, low_open=True)
    max_linear_speed: float = setting(
        1.4, 'Every tool velocity command is capped to this, but those of the carry and the '
        'release (max_carry_speed).', unit='m/s', low=0, high=3.0, low_open=True)
    max_carry_speed: float = setting(
        2.0, 'The cap on the tool velocity commands that carry the object and release it: above '
        'release_planning.max_release_speed (1.8), with room for the release-speed loop; a '
        'toss.toss_speed or max_release_speed above it is refused. The reach and the retract '
        'keep max_linear_speed.', unit='m/s', low=0, high=3.0, low_open=True)
    release_opening_speed: float = setting(
        0.3, 'Speed at which the pads move apart along their normals at release.',
        unit='m/s', low=0, high=2.0, low_open=True)
    release_clearance: float = setting(
        0.3, "Within this distance of the box's centre a retracting tool moves away from a box "
        'that comes toward it, horizontally, at its closing speed plus release_opening_speed '
        '(core.release.clear_of_the_box); 0 switches it off.', unit='m', low=0, high=2.0)
    toss_speed_time_constant: float = setting(
        0.05, "The object's desired speed rises from the impact speed to the toss speed with "
        'this time constant after contact.', unit='s', low=0, high=5.0, low_open=True)
    halt_squeeze_speed: float = setting(
        0.1, 'When the task halts with a box held (a controller lost), each pad is driven into '
        "its face at this speed: the arms stop from the carry's speed within about 20 ms and "
        'the box, held by friction only, slid out of a loose squeeze (in-process, 16 kills '
        'halfway through the carry of paper_toss_random trials: 5 fell 2.0-2.5 cm at 0, none '
        'over 1.2 cm at 0.1 m/s).', unit='m/s', low=0, high=0.5)
    held_object_time_constant: float = setting(
        0.1, "While both pads hold the box it is read from the pads' kinematics, its offset "
        "from their midpoint following the tracker's estimate with this time constant "
        '(core.held_object); 0 reads the tracker alone.', unit='s', low=0, high=10.0)
    coordination: CoordinationConfig = field(default_factory=CoordinationConfig)
    impact: ImpactConfig = field(default_factory=ImpactConfig)
    toss: TossConfig = field(default_factory=TossConfig)
    lift: LiftConfig = field(default_factory=LiftConfig)
    place: PlaceConfig = field(default_factory=PlaceConfig)
    speed: SpeedProfileConfig = field(default_factory=SpeedProfileConfig)
    orientation: OrientationDsConfig = field(default_factory=OrientationDsConfig)
    phases: PhaseConfig = field(default_factory=PhaseConfig)
    contact: ContactConfig = field(default_factory=ContactConfig)
    ft: FtCompensationConfig = field(default_factory=FtCompensationConfig)
    reachability: ReachabilityConfig = field(default_factory=ReachabilityConfig)
    regrasp: RegraspConfig = field(default_factory=RegraspConfig)
    release_planning: ReleasePlanningConfig = field(default_factory=ReleasePlanningConfig)
    conveyor: ConveyorTossConfig = field(default_factory=ConveyorTossConfig)
    moving_grab: MovingGrabConfig = field(default_factory=MovingGrabConfig)
    resting_object: RestingObjectConfig = field(default_factory=RestingObjectConfig)

    def __post_init__(self):
        object.__setattr__(self, 'task', task_from_name(self.task))
        check_settings(self)
        positions = np.asarray(self.standby_positions, dtype=float)
        rotations = np.asarray(self.standby_rotations, dtype=float)
        if positions.shape != (2, 3) or rotations.shape != (2, 3, 3):
            raise ConfigError('standby_positions must be (2, 3) and standby_rotations (2, 3, 3)')
        for rotation in rotations:
            if not np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-6):
                raise ConfigError('standby_rotations must be rotation matrices')
        for name, speed in (('toss.toss_speed', self.toss.toss_speed),
                            ('release_planning.max_release_speed',
                             self.release_planning.max_release_speed)):
            if speed > self.max_carry_speed:
                raise ConfigError(
                    f'{name} = {speed:g} m/s exceeds max_carry_speed = '
                    f'{self.max_carry_speed:g} m/s: the carry could not reach that release speed')

    def arrival_synchroniser(self):
        """
        Return the arrival synchroniser's (pad half extents (2,) [m], ArrivalSchedule).

        Over a still box the gaps run from the pads' nearest corners (reachability's pad size);
        a moving grab measures from the pads' centres and speeds the arm behind up by at most
        moving_grab.synchronisation_max_speedup (never slowing the arm ahead broke the timing:
        5 of 14 conveyor_grab trials 12-20 ms apart), timed by the commanded speeds alone: the
        tools' measured speeds carry the belt's, which the lag term would read as the arms'
        lag (conveyor_grab: 33 of the first 40 trials 12-24 ms apart).
        """
        impact = self.impact
        schedule = ArrivalSchedule(
            impact.synchronisation_distance, impact.synchronisation_final_gap,
            impact.synchronisation_gain, impact.synchronisation_max_slowdown,
            impact.synchronisation_max_speedup, impact.synchronisation_lag)
        if self.moving_grab.enabled:
            return (0.0, 0.0), schedule._replace(
                fastest=self.moving_grab.synchronisation_max_speedup, lag=0.0)
        return (self.reachability.pad_half_length, self.reachability.pad_half_width), schedule
