"""
Which arms' controllers are lost: the motion generator's watch on their torque commands.

Every torque command an arm's controller sends (heard()) says it is alive at its stamp. At each
DS tick newly_lost() names the arms whose controller, heard before, has been silent for longer
than the timeout (sim time), at the tick and behind the other arm's commands, which were heard
without a silence of their own over that time: the robot then holds that arm in place, and the
motion generator must stop the task rather than carry the box away from the held arm. The
partner is what tells a dead controller from commands that did not reach the watcher: a
realtime watcher went on taking fresh joint states while no torque command of either arm
reached it for 20-26 ms, and the two streams came back 6 ms apart (the robot had held neither
arm for more than two cycles). A controller never heard is not judged (the graph may still be
starting), nor one whose partner is silent too (with every arm held by the robot a halt would
command no one); a loss is kept until restart() (a new episode after a clock reset), so the
task is stopped once. Stamps further ahead of the newest cycle than FUTURE_TOLERANCE are
ignored, so a stray message from the future cannot mask a dead controller.
"""

from dual_arm_control.core.arms import ARMS

# A command stamped this far after the newest cycle seen is not believed [ns].
FUTURE_TOLERANCE_NS = 100_000_000


def controller_silent(last_command_ns, stamp_ns, timeout_ns):
    """
    Return True if a controller last heard at last_command_ns is lost at cycle stamp_ns.

    Lost: heard before (not None) and silent for more than timeout_ns; timeout_ns 0 disables
    the watch. Why: a controller that answers no cycle for that long is dead or stalled, and
    its arm is in the robot's hold.
    """
    return (timeout_ns > 0 and last_command_ns is not None
            and stamp_ns - last_command_ns > timeout_ns)


class ControllerWatch:
    """The newest torque command stamp of each arm, and the arms lost so far."""

    def __init__(self, timeout_ns):
        self.timeout_ns = int(timeout_ns)
        self.restart()

    def restart(self):
        """Forget every stamp and loss (a new episode after a clock reset)."""
        self._last_ns = dict.fromkeys(ARMS)
        self._run_start_ns = dict.fromkeys(ARMS)
        self._now_ns = None
        self.lost_arms = ()

    def heard(self, arm, stamp_ns):
        """Note a torque command of arm stamped stamp_ns [ns] (see the module text)."""
        if self._now_ns is None or stamp_ns > self._now_ns + FUTURE_TOLERANCE_NS:
            return
        last = self._last_ns[arm]
        if last is None or stamp_ns > last:
            if last is None or controller_silent(last, stamp_ns, self.timeout_ns):
                self._run_start_ns[arm] = int(stamp_ns)
            self._last_ns[arm] = int(stamp_ns)

    def newly_lost(self, stamp_ns, judge=True):
        """
        Return the arms found lost at cycle stamp_ns that were not lost before (a tuple).

        judge False only notes the cycle (the newest stamp a command may carry) and finds none.
        """
        self._now_ns = stamp_ns if self._now_ns is None else max(self._now_ns, stamp_ns)
        if not judge:
            return ()
        new = tuple(arm for arm in ARMS if arm not in self.lost_arms
                    and self._silent(arm, stamp_ns))
        self.lost_arms += new
        return new

    def _silent(self, arm, stamp_ns):
        """Return True if arm's controller is silent at stamp_ns and over a partner's run."""
        last = self._last_ns[arm]
        return controller_silent(last, stamp_ns, self.timeout_ns) and any(
            self._last_ns[other] is not None and self._run_start_ns[other] <= last
            and controller_silent(last, self._last_ns[other], self.timeout_ns)
            for other in ARMS if other != arm)

    def silence_ns(self, arm, stamp_ns):
        """Return how long arm's controller has been silent at stamp_ns [ns] (None: unheard)."""
        last = self._last_ns[arm]
        return None if last is None else stamp_ns - last
