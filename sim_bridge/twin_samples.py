"""What the twin reports: per-cycle step reports, joint and mocap samples, snapshots."""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class StepReport:
    """
    What one FRI cycle did, per arm.

    clamped: the joint torque exceeded a limit and was clamped; applied: the joint torques
    [N m] (7,) the drives produced (the command, plus gravity compensation with the
    gravity_compensated interface), after clamping; arm_collisions: the ArmCollisions that
    began during the cycle (sim_bridge.arm_collisions).
    """

    clamped: dict
    applied: dict
    arm_collisions: tuple = ()


@dataclass(frozen=True)
class JointSample:
    """Joint state of one arm: position [rad], velocity [rad/s], measured torque [N m], (7,)."""

    position: np.ndarray
    velocity: np.ndarray
    measured_torque: np.ndarray


@dataclass(frozen=True)
class MocapSample:
    """A motion-capture sample of the object: stamp (sampling sim time) [s], pose in world."""

    stamp: float
    p_world: np.ndarray
    quat_xyzw: np.ndarray


@dataclass(frozen=True)
class TwinState:
    """A snapshot of the twin (physics and sensor models) for set_state()."""

    physics: np.ndarray
    tick: int
    ctrl: np.ndarray
    next_sample: int
    next_perturbation: int
    pending: tuple
    ft_cache: dict
    rng_states: tuple
    colliding_pairs: frozenset
    container: object = None
    container_pending: tuple = ()
