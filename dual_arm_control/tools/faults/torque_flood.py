"""
The torque flood: a foreign publisher on one arm's torque command topic, 10 messages a cycle.

A lockstep cycle has no wall-time rate, so 10x the FRI rate is FLOOD_PER_CYCLE messages for
every state the bridge publishes (its stamp t_k, heard on the arm's joint states), from the
reach to the carry, half before the controller answers t_k and half after: some valid-looking
(joint names right, torques within the limits) stamped for other cycles, some stamped t_k:
valid-looking, huge (1e6 N m) or NaN. The rule: the bridge applies one command per cycle and
arm, its controller's; the flood is dropped and counted, so the episode is the trial's
fault-free one (the same torques on both arms), with no NaN torque, none beyond the limits, no
node exit and no stall.
"""

from dual_arm_control import contract
from dual_arm_control.nodes.messages import stamp_ns, time_msg
from dual_arm_control.runtime.node_settings import FRI_PERIOD
from dual_arm_control.tools.faults.graph_run import GraphRun
from dual_arm_control.tools.faults.outcome import TrialOutcome
from dual_arm_control.tools.faults.trial import judge_same_episode, skipped, torque_limits
import numpy as np

GRAPH_TIMEOUT = 300.0
HUGE_TORQUE = 1e6
PERIOD_NS = round(FRI_PERIOD * 1e9)
# The flood's messages of one cycle: stamp offset from the cycle's stamp [ns], torques. The
# first half goes out when the probe hears the cycle's state (before the controller answers, as
# a rule), the second when it hears the controller's command for it.
BEFORE_ANSWER = ((-PERIOD_NS, 'valid'), (PERIOD_NS, 'valid'), (0, 'valid'), (0, 'huge'),
                 (0, 'nan'))
AFTER_ANSWER = ((-10 * PERIOD_NS, 'valid'), (1_000_000_000, 'valid'), (0, 'valid'),
                (0, 'huge'), (0, 'nan'))
FLOOD_PER_CYCLE = len(BEFORE_ANSWER) + len(AFTER_ANSWER)
# The flood's frame_id: lets the probe tell its own messages from the controller's.
FLOOD_FRAME = 'torque_flood'


class TorqueFlood:
    """Floods arm's torque command topic from the probe for every cycle in [start, end) [s]."""

    def __init__(self, run, arm, start, end, seed):
        self.window_ns = (round(start * 1e9), round(end * 1e9))
        self.sent = 0
        self.cycles = 0
        self.republished = 0
        self._names = contract.joint_names(arm)
        self._limits = np.asarray(torque_limits()[arm])
        self._rng = np.random.default_rng(seed)
        self._flooded_ns = -1
        self._awaiting_answer_ns = None
        node = run.probe.node
        topic = contract.TORQUE_COMMAND.resolved(arm)
        self._publisher = node.create_publisher(contract.TORQUE_COMMAND.msg_type, topic,
                                                contract.TORQUE_COMMAND.qos)
        node.create_subscription(contract.JOINT_STATES.msg_type,
                                 contract.JOINT_STATES.resolved(arm), self._on_state,
                                 contract.JOINT_STATES.qos)
        node.create_subscription(contract.TORQUE_COMMAND.msg_type, topic, self._on_command,
                                 contract.TORQUE_COMMAND.qos)

    def _efforts(self, kind):
        if kind == 'huge':
            return HUGE_TORQUE * self._rng.choice([-1.0, 1.0], len(self._names))
        if kind == 'nan':
            return np.full(len(self._names), np.nan)
        return self._limits * self._rng.uniform(-0.5, 0.5, len(self._names))

    def _send(self, t_ns, pattern):
        for index in self._rng.permutation(len(pattern)):
            offset, kind = pattern[index]
            command = contract.TORQUE_COMMAND.msg_type()
            command.header.stamp = time_msg(max(t_ns + offset, 0))
            command.header.frame_id = FLOOD_FRAME
            command.name = self._names
            command.effort = self._efforts(kind).tolist()
            self._publisher.publish(command)
            self.sent += 1

    def _on_state(self, msg):
        t_ns = stamp_ns(msg.header.stamp)
        if t_ns == self._flooded_ns:
            self.republished += 1
        if not self.window_ns[0] <= t_ns < self.window_ns[1] or t_ns == self._flooded_ns:
            return
        self._flooded_ns = self._awaiting_answer_ns = t_ns
        self.cycles += 1
        self._send(t_ns, BEFORE_ANSWER)

    def _on_command(self, msg):
        t_ns = stamp_ns(msg.header.stamp)
        if msg.header.frame_id != FLOOD_FRAME and t_ns == self._awaiting_answer_ns:
            self._awaiting_answer_ns = None
            self._send(t_ns, AFTER_ANSWER)


def torque_flood(kind, trial):
    """Flood one arm's torque commands (left on even trials) from the reach to the carry."""
    start, end = trial.stage_time('reach'), trial.stage_time('carry')
    if start is None or end is None:
        return skipped(kind, trial, 'no reach or carry in the fault-free episode')
    arm = contract.ARMS[trial.index % 2]
    outcome = TrialOutcome(kind, trial.index, trial.seed, fault_time=start)
    with GraphRun(trial.scenario_file(), trial.out_dir, trial.domain,
                  trial.scenario.duration) as run:
        flood = TorqueFlood(run, arm, start, end, trial.seed)
        exits = run.wait_for_end(GRAPH_TIMEOUT)
        stalled_at = None if 'sim_bridge' in exits else run.probe.clock_ns * 1e-9
        outcome.refused = sum(sum(c.values()) for c in run.probe.refusal_counts().values())
    return judge_same_episode(outcome, run.trajectory_file, trial, exits, stalled_at,
                              f'{arm}: {flood.sent} flood messages over {flood.cycles} cycles; '
                              f'{flood.republished} flooded states republished')
