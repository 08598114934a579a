"""
What the motion generator takes and returns each DS tick: arm and object measurements, commands.

Plain frozen records, so the runtime and the tests build them without the generator's state.
"""

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ArmMeasurement:
    """
    What one arm reports to the motion generator.

    Fields: p_world_tool (3,) m and R_world_tool (3, 3), the tool frame; ft_wrench_sensor (6,)
    [N, N m], the raw Net F/T reading (wrench the tool applies to the sensor, sensor frame);
    R_world_sensor (3, 3); sample_age [s], how long before the tick the joint state these come
    from was sampled (0 in lockstep; in realtime the newest sample may be a cycle or two off).
    """

    p_world_tool: np.ndarray
    R_world_tool: np.ndarray
    ft_wrench_sensor: np.ndarray
    R_world_sensor: np.ndarray
    sample_age: float = 0.0


def arm_measurement(model, q, ft_wrench_sensor, sample_age=0.0):
    """Return the ArmMeasurement of an arm at joints q (7,) [rad], posed by model (ArmModel)."""
    (p_world_tool, R_world_tool), (_, R_world_sensor) = model.tool_and_sensor_poses(q)
    return ArmMeasurement(p_world_tool, R_world_tool, ft_wrench_sensor, R_world_sensor,
                          sample_age)


@dataclass(frozen=True)
class ObjectMeasurement:
    """Estimated object state: p_world_object (3,) m, R_world_object, v_world_object m/s."""

    p_world_object: np.ndarray
    R_world_object: np.ndarray
    v_world_object: np.ndarray


@dataclass(frozen=True)
class ArmCommand:
    """
    DS command for one arm: desired tool twist and orientation, and its current attractor.

    Fields: v_world (3,) m/s, w_world (3,) rad/s, R_world_desired (3, 3), p_world_attractor (3,)
    m (grasp point while reaching, standby while retracting).
    """

    v_world: np.ndarray
    w_world: np.ndarray
    R_world_desired: np.ndarray
    p_world_attractor: np.ndarray


class DeferredMapping(Mapping):
    """
    A read-only mapping whose items compute() returns as a dict, called at the first look-up.

    For outputs of a tick that only some ticks and consumers use (the impact directions outside
    the reach feed only the markers): they cost nothing until read, and read the same.
    """

    def __init__(self, compute):
        self._compute = compute
        self._items = None

    def _computed(self):
        if self._items is None:
            self._items = self._compute()
            self._compute = None
        return self._items

    def __getitem__(self, key):
        return self._computed()[key]

    def __iter__(self):
        return iter(self._computed())

    def __len__(self):
        return len(self._computed())


@dataclass(frozen=True)
class MotionOutput:
    """
    Result of one tick.

    Fields: phase (PhaseMachineOutput); commands {arm: ArmCommand}; object_velocity (3,) m/s and
    object_angular_velocity (3,) rad/s, the desired object twist; contacts {arm: ContactState};
    pad_forces {arm: (3,) N, compensated force of the pad on the object, world}; grasp_frames
    {arm: GraspFrame}; impact_directions {arm: (3,)} (a mapping); release_position (3,) m and
    release_velocity (3,) m/s of toss tasks (None otherwise).
    """

    phase: object
    commands: dict
    object_velocity: np.ndarray
    object_angular_velocity: np.ndarray
    contacts: dict
    pad_forces: dict
    grasp_frames: dict
    impact_directions: Mapping
    release_position: object
    release_velocity: object
