"""
What a fault did to the cell, from the simulator's ground truth (the trajectory log).

Every number is measured on the twin, not taken from a node's own account: the torques the arms
really got, the tool speeds and the box's fall. The rules (docs/reliability.md):

- no NaN torque, no torque beyond the limits: the applied ratio |tau| / limit stays <= 1 (the
  twin clamps a command beyond them, like the robot, and counts it: TrialOutcome.torque_clamps);
- an arm whose controller died settles: tool speed below SETTLED_TOOL_SPEED from
  SETTLE_TIME after the fault on;
- the box is never dropped from more than DROP_HEIGHT_LIMIT: if a box held at the fault leaves
  both pads before the trial's fault-free episode releases it (a toss's flight is no drop),
  the drop is how far it then falls: its highest minus its lowest centre height from that
  moment to the end of the log.
"""

from dataclasses import asdict, dataclass

from dual_arm_control.bags.info import inspect_bag
from dual_arm_control.contract import ARMS
from dual_arm_control.core.exceptions import DualArmControlError
import numpy as np

SETTLED_TOOL_SPEED = 0.05
SETTLE_TIME = 0.3
DROP_HEIGHT_LIMIT = 0.02
# A release this much before the fault-free one is still on time [s].
RELEASE_TOLERANCE = 0.02
# Time [s] without any pad on the box after which it has left the pads.
LEFT_PADS_TIME = 0.01


@dataclass
class TrialOutcome:
    """One trial of one fault kind: what was injected and what the twin shows."""

    kind: str
    trial: int
    seed: int
    fault_time: float = None
    held: bool = True
    recovered: bool = None
    refused: int = 0
    nan_torques: int = 0
    torque_clamps: int = 0
    worst_torque_ratio: float = None
    worst_tool_speed: float = None
    drop_height: float = None
    node_exits: int = 0
    bag_status: str = ''
    exit_code: int = None
    note: str = ''

    def as_dict(self):
        """Return the outcome as a JSON-ready dict."""
        return asdict(self)


def torque_extremes(data, torque_limits):
    """Return (NaN torque count, worst |tau| / limit) over both arms of a trajectory log."""
    nan_count, worst = 0, 0.0
    for arm in ARMS:
        tau = np.asarray(data[f'{arm}_tau'], dtype=float)
        finite = np.isfinite(tau)
        nan_count += int((~finite).sum())
        ratios = np.abs(np.where(finite, tau, 0.0)) / np.asarray(torque_limits[arm])
        worst = max(worst, float(ratios.max(initial=0.0)))
    return nan_count, worst


def tool_speed_after(data, arms, start_time):
    """Return the largest tool speed [m/s] of arms from start_time [s] on (None: no samples)."""
    after = np.asarray(data['t']) >= start_time - 1e-9
    if not after.any():
        return None
    return max(float(np.linalg.norm(data[f'{arm}_tool_velocity'][after], axis=1).max())
               for arm in arms)


def premature_drop(data, fault_time, release_time=None, tolerance=RELEASE_TOLERANCE):
    """
    Return (time the held box left both pads early or None, height [m] it then fell).

    Early: before release_time - tolerance [s] (None: any time after fault_time). Leaving
    means no pad touching the box for at least LEFT_PADS_TIME: a grasp chattering off both
    pads for a cycle after the impact has not let the box go.
    """
    t = np.asarray(data['t'])
    held = np.logical_or.reduce([np.asarray(data[f'{arm}_pad_contact'], dtype=bool)
                                 for arm in ARMS])
    free = (t >= fault_time - 1e-9) & ~held
    if release_time is not None:
        free &= t < release_time - tolerance
    edges = np.flatnonzero(np.diff(np.concatenate(([0], free.astype(np.int8), [0]))))
    for start, end in zip(edges[::2], edges[1::2]):
        if t[end - 1] - t[start] >= LEFT_PADS_TIME - 1e-9 or end == len(t):
            heights = np.asarray(data['object_position'])[start:, 2]
            return float(t[start]), float(heights.max() - heights.min())
    return None, 0.0


def was_held(data, t):
    """Return True if both pads touched the box at sim time t [s]."""
    index = int(np.searchsorted(np.asarray(data['t']), t))
    index = min(index, len(data['t']) - 1)
    return all(bool(data[f'{arm}_pad_contact'][index]) for arm in ARMS)


def fill_from_trajectory(outcome, data, torque_limits, dead_arms=(), fault_time=None,
                         release_time=None):
    """
    Fill an outcome's torque, speed and drop fields from a trajectory log; return it.

    dead_arms: the arms whose controller died at fault_time [s]; their tool speed from
    fault_time + SETTLE_TIME on must be below SETTLED_TOOL_SPEED. A box held at fault_time
    must not fall from more than DROP_HEIGHT_LIMIT before release_time [s] (the fault-free
    episode's release; None: the end of the log).
    """
    outcome.nan_torques, outcome.worst_torque_ratio = torque_extremes(data, torque_limits)
    outcome.torque_clamps = int(data.get('torque_clamp_count', 0))
    outcome.refused += int(data.get('refused_message_count', 0))
    safe = outcome.nan_torques == 0 and outcome.worst_torque_ratio <= 1.0 + 1e-9
    if fault_time is not None and dead_arms:
        outcome.worst_tool_speed = tool_speed_after(data, dead_arms, fault_time + SETTLE_TIME)
        settled = outcome.worst_tool_speed is not None and \
            outcome.worst_tool_speed < SETTLED_TOOL_SPEED
        safe = safe and settled
    outcome.drop_height = 0.0
    if fault_time is not None and was_held(data, fault_time):
        _, outcome.drop_height = premature_drop(data, fault_time, release_time)
        safe = safe and outcome.drop_height <= DROP_HEIGHT_LIMIT
    outcome.held = bool(safe and outcome.held)
    return outcome


def bag_status(path):
    """Return bag_info's status of a bag ('complete', 'torn', ...) or why it is unreadable."""
    try:
        return inspect_bag(path).status
    except DualArmControlError as error:
        return f'unreadable: {error}'
