"""
The FRI cycle of the robots' side: state out, one torque command per arm in, then a step.

FriCycle drives a backend (the MuJoCo twin, or anything with its interface: time,
joint_state(arm), ft_wrench(arm), mocap_samples(), container_mocap_samples(),
hold_torques(arm, stop_position), step(torques) returning what it clamped and applied) the way
KUKA's FRI drives a robot:

- begin() returns the state of the current cycle (what the robots report) and awaits one command
  per arm stamped with it;
- answer() takes an arm's command: a command stamped for another cycle is ignored (counted; one
  for an earlier cycle counts as late); a malformed one (wrong joints, NaN/Inf) is refused,
  counted, and that arm holds this cycle; refuse_foreign() counts a command that is not from the
  arm's controller (the bridge checks its signature): it is no answer;
- advance() applies the commands and steps the backend. An arm without a command for the cycle
  (realtime: its deadline passed) keeps its previous commanded torque for one cycle, then holds
  (the robot's own hold: gravity compensation, joint stiffness toward the joint positions of
  the first cycle without a command, joint damping) until a command is on time again.
  Torques beyond the limits are clamped by the backend (counted).

The lockstep bridge and the in-process runner call advance() once every arm answered; the
realtime bridge calls it at each FRI deadline.
"""

from dataclasses import dataclass, field
import math

from dual_arm_control.core.arms import ARMS, joint_names
from dual_arm_control.runtime.signals import (JointStateSample, PoseSample, TorqueSample,
                                              WrenchSample)
from dual_arm_control.runtime.timing import seconds_to_ns
import numpy as np

REFUSAL_REASONS = ('non_finite', 'wrong_length', 'joint_names')
_IDENTITY_QUAT = np.array([0.0, 0.0, 0.0, 1.0])


def command_refusal(names, efforts, expected_names):
    """
    Return why a torque command is refused, or None if it is acceptable.

    names, efforts: the command's joint names and torques; every expected joint must be named
    once (any order; other names are ignored). Reasons: 'joint_names' (an expected joint
    missing or named twice), 'wrong_length' (not one effort per name), 'non_finite' (NaN/Inf).
    """
    names = list(names)
    if any(names.count(name) != 1 for name in expected_names):
        return 'joint_names'
    if len(efforts) != len(names):
        return 'wrong_length'
    if not all(math.isfinite(efforts[names.index(name)]) for name in expected_names):
        return 'non_finite'
    return None


def ordered_efforts(names, efforts, expected_names):
    """Return the efforts of an accepted command (7,) in the order of expected_names."""
    names = list(names)
    return np.array([efforts[names.index(name)] for name in expected_names], dtype=float)


@dataclass
class ArmCounters:
    """What happened to one arm's commands."""

    accepted: int = 0
    refused: dict = field(default_factory=lambda: dict.fromkeys(REFUSAL_REASONS, 0))
    ignored: int = 0
    late: int = 0
    previous_torque_repeats: int = 0
    watchdog_holds: int = 0
    clamps: int = 0
    foreign: int = 0

    def as_dict(self):
        """Return the counters as a flat {name: count}."""
        counts = {'commands_accepted': self.accepted, 'ignored_commands': self.ignored,
                  'late_commands': self.late,
                  'previous_torque_repeats': self.previous_torque_repeats,
                  'watchdog_holds': self.watchdog_holds, 'torque_clamps': self.clamps,
                  'refused_foreign': self.foreign}
        counts.update({f'refused_{reason}': n for reason, n in self.refused.items()})
        return counts


@dataclass(frozen=True)
class CycleState:
    """
    What the robots report at one cycle: joints and FT per arm, delivered mocap samples.

    container_mocap: the delivered samples of a conveyor's container, PoseSamples with the
    identity orientation (none without a conveyor).
    """

    stamp_ns: int
    joints: dict
    ft_wrenches: dict
    mocap: tuple
    container_mocap: tuple = ()


class FriCycle:
    """The robots' side of the FRI cycles of both arms (see the module text)."""

    def __init__(self, backend):
        self.backend = backend
        self.counters = {arm: ArmCounters() for arm in ARMS}
        self.cycles = 0
        self._names = {arm: joint_names(arm) for arm in ARMS}
        self.restart()

    def restart(self):
        """Forget the previous commands (after a backend reset)."""
        self.applied = {arm: np.zeros(len(self._names[arm])) for arm in ARMS}
        self._answers = dict.fromkeys(ARMS)
        self._repeated_previous = dict.fromkeys(ARMS, True)
        self._stop_positions = dict.fromkeys(ARMS)
        self.awaited_ns = None

    def stop_position(self, arm):
        """Return the joint positions (7,) [rad] arm holds since its commands stopped, or None."""
        return self._stop_positions[arm]

    def begin(self):
        """Return the CycleState of the backend's current time; await its commands."""
        self.awaited_ns = seconds_to_ns(self.backend.time)
        self._answers = dict.fromkeys(ARMS)
        return CycleState(
            stamp_ns=self.awaited_ns,
            joints={arm: self._joint_state(arm) for arm in ARMS},
            ft_wrenches={arm: WrenchSample(self.awaited_ns, np.concatenate(
                self.backend.ft_wrench(arm))) for arm in ARMS},
            mocap=tuple(PoseSample(seconds_to_ns(sample.stamp), sample.p_world,
                                   sample.quat_xyzw)
                        for sample in self.backend.mocap_samples()),
            container_mocap=tuple(PoseSample(seconds_to_ns(sample.stamp), sample.p_world,
                                             _IDENTITY_QUAT)
                                  for sample in self.backend.container_mocap_samples()))

    def _joint_state(self, arm):
        sample = self.backend.joint_state(arm)
        return JointStateSample(self.awaited_ns, sample.position, sample.velocity,
                                sample.measured_torque)

    def answer(self, arm, stamp_ns, names, efforts):
        """Take one arm's command for a cycle; return True once every arm answered this one."""
        counters = self.counters[arm]
        if stamp_ns != self.awaited_ns or self._answers[arm] is not None:
            counters.ignored += 1
            if self.awaited_ns is not None and stamp_ns < self.awaited_ns:
                counters.late += 1
            return self.all_answered()
        reason = command_refusal(names, efforts, self._names[arm])
        if reason is None:
            counters.accepted += 1
            self._answers[arm] = TorqueSample(stamp_ns, ordered_efforts(names, efforts,
                                                                        self._names[arm]))
        else:
            counters.refused[reason] += 1
            self._answers[arm] = reason
        return self.all_answered()

    def refuse_foreign(self, arm):
        """Count a command for arm that is not from its controller; it answers no cycle."""
        self.counters[arm].foreign += 1

    def refused(self, arm):
        """Return the refusal reason of arm's answer to this cycle, or None."""
        answer = self._answers[arm]
        return answer if isinstance(answer, str) else None

    def all_answered(self):
        """Return True once every arm answered the awaited cycle (a refusal is an answer)."""
        return all(answer is not None for answer in self._answers.values())

    def missing(self):
        """Return the arms that have not answered the awaited cycle."""
        return [arm for arm, answer in self._answers.items() if answer is None]

    def advance(self):
        """Apply this cycle's commands (module text), step the backend; return applied torques."""
        torques = {arm: self._torque(arm) for arm in ARMS}
        report = self.backend.step(torques)
        for arm in ARMS:
            self.counters[arm].clamps += int(report.clamped[arm])
            self.applied[arm] = report.applied[arm]
        self.cycles += 1
        return self.applied

    def log_counters(self):
        """Return the counters a trajectory log keeps: totals, cycles and per arm."""
        counters = self.counters.values()
        values = {'torque_clamp_count': sum(c.clamps for c in counters),
                  'refused_message_count': sum(sum(c.refused.values()) for c in counters),
                  'watchdog_hold_count': sum(c.watchdog_holds for c in counters),
                  'cycles': self.cycles}
        for arm, arm_counters in self.counters.items():
            values.update({f'{arm}_{key}': value for key, value in arm_counters.as_dict().items()})
        return values

    def _torque(self, arm):
        answer = self._answers[arm]
        if isinstance(answer, TorqueSample):
            self._repeated_previous[arm] = False
            self._stop_positions[arm] = None
            return answer.effort
        self._note_stop_position(arm)
        if answer is None and not self._repeated_previous[arm]:
            self._repeated_previous[arm] = True
            self.counters[arm].previous_torque_repeats += 1
            return self.applied[arm]
        self._repeated_previous[arm] = True
        if answer is None:
            self.counters[arm].watchdog_holds += 1
        return self.backend.hold_torques(arm, self._stop_positions[arm])

    def _note_stop_position(self, arm):
        """
        Keep where arm's commands stopped: the joints at its first cycle without a command.

        The robot's hold pulls the arm back there (a KUKA holds its position on command loss),
        so an arm whose controller died stays put instead of drifting under damping alone.
        """
        if self._stop_positions[arm] is None:
            self._stop_positions[arm] = np.array(self.backend.joint_state(arm).position,
                                                 dtype=float)
