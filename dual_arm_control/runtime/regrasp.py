"""
The two passes of a regrasp (core.regrasp): set the box down at its staging pose, then place it.

The first pass is an ordinary pick-and-place whose place is the staging pose on the pallet; the
task's configuration comes back for the second, which starts by itself once the arms are back
at standby after the first release, and picks the box up again where the tracker sees it.
"""

from dataclasses import replace

from dual_arm_control.core.phases import Phase
from dual_arm_control.core.regrasp import plan_staging
from dual_arm_control.runtime.configuration import PLACE_PRESS_DEPTH
import numpy as np

# Share of the travel to the staging pose over which the box descends onto it (start, end):
# the place DS lifts the box over the rest of the travel (core.place.place_target).
DESCENT_SHARES = (0.6, 0.2)


class RegraspSequence:
    """
    A regrasp under way: task_config (the task's MotionGeneratorConfig), staging (StagingPlan).

    pick_position (3,) [m]: where the box was picked up. second_pass: the box has been set
    down at the staging pose and the task's configuration is back.
    """

    def __init__(self, task_config, staging, pick_position):
        self.task_config = task_config
        self.staging = staging
        self._travel = float(np.hypot(*(staging.position - np.asarray(pick_position))[:2]))
        self._released = False
        self._started = False
        self.second_pass = False

    def staging_config(self, config=None):
        """
        Return config (default the task's) with its place at the staging pose.

        The box is pressed PLACE_PRESS_DEPTH into the pallet as into a table; the pallet is no
        obstacle to keep clear of, as the box is set down on it; the descent spans the shares
        DESCENT_SHARES of a travel shorter than the place's own descent distances.
        """
        config = config or self.task_config
        place = config.place
        position = self.staging.position - np.array([0.0, 0.0, PLACE_PRESS_DEPTH])
        start, end = DESCENT_SHARES
        return replace(config, place=replace(
            place, position=tuple(float(value) for value in position), pallet=(),
            descent_start_distance=min(place.descent_start_distance, start * self._travel),
            descent_end_distance=min(place.descent_end_distance, end * self._travel)))

    def reconfigured(self, config):
        """Take config as the task's; return the configuration to apply now."""
        self.task_config = config
        return config if self.second_pass else self.staging_config(config)

    def advance(self, phase, time_in_phase, cancelled=False):
        """
        Note the generator's Phase and time in it [s] after a tick; return what the caller does.

        'second_pass': the first pass has ended back in standby after its release: apply
        task_config and start again. 'retract_stalled': its retract has lasted
        regrasp.retract_timeout: apply task_config, reset to standby and start again from where
        the arms stopped. 'abandoned': it ended in standby without a release (the grasp
        aborted, a go_home before the grasp) or cancelled (a go_home or reset requested on the
        tick): apply task_config and stop. '' otherwise.
        """
        if self.second_pass:
            return ''
        if cancelled:
            return 'abandoned'
        self._released = self._released or phase is Phase.RELEASE
        self._started = self._started or phase is not Phase.STANDBY
        if (self._released and phase is Phase.RETRACT
                and time_in_phase >= self.task_config.regrasp.retract_timeout):
            self.second_pass = True
            return 'retract_stalled'
        if phase is Phase.STANDBY and self._started:
            self.second_pass = True
            return 'second_pass' if self._released else 'abandoned'
        return ''


def staged_regrasp(models, q_current, position, rotation, place, config, refused_plan):
    """
    Return (RegraspSequence or None, GraspPlan to adopt, event reason) for a refused place.

    models {arm: ArmModel}; q_current {arm: (7,)} [rad]; the box's pose (position (3,) [m],
    rotation (3, 3)); place (p (3,) [m], R (3, 3)); config: the task's MotionGeneratorConfig;
    refused_plan: the GraspPlan that does not serve: unreachable, or short (it would set the box
    down short of the place; a regrasp then serves only if its second grasp is not short).
    Without a staging pose the plan comes back, an unreachable one with the staging planner's
    reason added.
    """
    staging = plan_staging(
        models, q_current, position, rotation, np.asarray(config.object_size),
        config.reachability, place, config.place.pallet, np.radians(config.place.yaw_deg),
        config.regrasp, config.impact.support_clearance, clear_only=refused_plan.reachable)
    if not staging.reachable:
        if refused_plan.reachable:
            return None, refused_plan, ''
        return None, replace(refused_plan, reason=(
            f'{refused_plan.reason}; no regrasp: {staging.reason}')), ''
    what = 'sets it down' if not refused_plan.reachable else 'sets it down on its place'
    reason = (f'no grasp both picks the box up and {what}: staged at '
              f'{np.round(staging.position, 3).tolist()} m, then picked up again')
    return RegraspSequence(config, staging, position), staging.first, reason
