"""
The pose of a resting box as the reach sees it: the tracker's estimate, low-passed.

The grasp frames, the impact directions and the arrival synchroniser's gaps all run from the
tracked box. At rest its estimate wanders with the mocap's noise, and the synchroniser reads
a wander along the squeeze axis as one pad ahead of the other: with 1.7 mm of mocap noise the
estimate strayed 3.4 mm for 30 ms just before contact (catalogue_random seed 11, trial 88),
the synchroniser sped the left arm to 0.67 m/s and slowed the right to 0.38, and the pads
touched 10 ms apart. A box that rests does not move, so while the arms reach for it the motion
generator reads a first-order low-pass of the estimate instead; a box that moves away from the
low-passed pose by more than snap_distance (pushed, or lifted by hand) restarts it there. A
box on a belt is not at rest: the moving grab reads the tracker alone.
"""

from dataclasses import dataclass

from dual_arm_control.core.geometry import slerp_rotation, vector_norm
from dual_arm_control.core.settings import check_settings, setting
import numpy as np


@dataclass(frozen=True)
class RestingObjectConfig:
    """Low-pass of a resting box's tracked pose while the arms reach for it (SI units)."""

    time_constant: float = setting(
        0.1, "Time constant of the low-pass on the tracker's pose of the box while the arms "
        'stand by and reach (catalogue_random seed 11, trials 150-209: pads touching within 4 '
        'ms 59 of 59 at 0.1 s, 54 of 59 reading the tracker alone); 0 reads the tracker alone.',
        unit='s', low=0, high=2.0)
    snap_distance: float = setting(
        0.01, 'A tracked position this far from the low-passed one restarts the low-pass at the '
        'tracked pose (the box was moved); five times the noisiest resting estimate.',
        unit='m', low=0, high=1.0, low_open=True)

    def __post_init__(self):
        check_settings(self)


class RestingObjectFilter:
    """First-order low-pass of a resting box's position and orientation."""

    def __init__(self):
        self.reset()

    def reset(self):
        """Forget the low-passed pose: the next resting tick starts from the tracked one."""
        self._position = None
        self._rotation = None

    def update(self, resting, p_world_object, R_world_object, dt, config):
        """
        Return the box pose (p (3,) [m], R (3, 3)) the reach reads after a tick of dt [s].

        While resting, the low-passed pose: position and rotation (on SO(3)) move toward the
        tracked pose by dt / (time_constant + dt); otherwise, or with time_constant 0, the
        tracked pose itself, and the filter restarts at the next resting tick.
        """
        if not resting or config.time_constant <= 0.0:
            self.reset()
            return p_world_object, R_world_object
        if (self._position is None
                or vector_norm(p_world_object - self._position) > config.snap_distance):
            self._position = np.array(p_world_object, dtype=float)
            self._rotation = np.array(R_world_object, dtype=float)
        else:
            weight = dt / (config.time_constant + dt)
            self._position = self._position + weight * (p_world_object - self._position)
            self._rotation = slerp_rotation(self._rotation, R_world_object, weight)
        return self._position.copy(), self._rotation.copy()
