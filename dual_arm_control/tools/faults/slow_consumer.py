"""
The slow consumer: one node of the lockstep graph stalled for STALL_TIME of wall time.

The node's process gets SIGSTOP at a stage (reach, impact, carry) and SIGCONT STALL_TIME later;
trial i stalls STALLED_NODES[i % 5] at STAGES[i % 3], so 15 trials cover every pair. The rule:
lockstep waits for the stalled node, so the episode is the trial's fault-free one (the same
torques on both arms), with no NaN torque, none beyond the limits, no node exit and no stall.
"""

import os
import signal
import time

from dual_arm_control.tools.faults.graph_run import GraphRun
from dual_arm_control.tools.faults.outcome import TrialOutcome
from dual_arm_control.tools.faults.trial import judge_same_episode, skipped

STALL_TIME = 0.1
STALLED_NODES = ('object_tracker', 'ds_motion_generator', 'wrench_qp', 'left_passive_controller',
                 'right_passive_controller')
STAGES = ('reach', 'impact', 'carry')
GRAPH_TIMEOUT = 300.0


def stall(run, label, duration):
    """SIGSTOP a node, spin the probe for duration [s] of wall time, SIGCONT it; return sim [s]."""
    pid = run.pid(label)
    before = run.probe.clock_ns
    os.kill(pid, signal.SIGSTOP)
    stopped = time.monotonic()
    try:
        run.probe.spin_until(lambda: time.monotonic() - stopped >= duration, 2.0 * duration)
    finally:
        os.kill(pid, signal.SIGCONT)
    return (run.probe.clock_ns - before) * 1e-9


def slow_consumer(kind, trial):
    """Stall one node for STALL_TIME at a stage (module text); the episode must not change."""
    label, stage = STALLED_NODES[trial.index % 5], STAGES[trial.index % 3]
    t_stage = trial.stage_time(stage)
    if t_stage is None:
        return skipped(kind, trial, f'no {stage} in the fault-free episode')
    outcome = TrialOutcome(kind, trial.index, trial.seed, fault_time=t_stage)
    with GraphRun(trial.scenario_file(), trial.out_dir, trial.domain,
                  trial.scenario.duration) as run:
        if not run.wait_for_sim_time(t_stage, GRAPH_TIMEOUT):
            outcome.held, outcome.note = False, f'graph stopped before the stall: {run.exited()}'
            return outcome
        advanced = stall(run, label, STALL_TIME)
        exits = run.wait_for_end(GRAPH_TIMEOUT)
        stalled_at = None if 'sim_bridge' in exits else run.probe.clock_ns * 1e-9
        outcome.refused = sum(sum(c.values()) for c in run.probe.refusal_counts().values())
    return judge_same_episode(outcome, run.trajectory_file, trial, exits, stalled_at,
                              f'{label} stopped {STALL_TIME * 1e3:g} ms at {stage}; sim time '
                              f'advanced {advanced * 1e3:g} ms meanwhile')
