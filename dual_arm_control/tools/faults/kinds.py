"""
The fault kinds of the campaign: one function per kind, each running one trial.

A kind is a FaultKind(name, runner, rule, run): run(trial) injects its fault into the trial's
episode and returns the TrialOutcome measured on the twin. 'graph' kinds run the lockstep node
graph (GraphRun, or dual_arm_bringup itself); 'inprocess' kinds inject a sensor fault of the
twin and run the same episode in one process (the same steps, about 8x faster), which is how the
randomized dropout trials reach their count. A trial whose fault-free episode lacks the stage
the fault is placed at is skipped (TrialOutcome.note says so).
"""

from dataclasses import dataclass
from functools import partial
import json

from dual_arm_control.contract import ARMS
from dual_arm_control.core.exceptions import DualArmControlError
from dual_arm_control.graph import EPISODE_START_TIME
from dual_arm_control.runtime.node_settings import FRI_PERIOD
from dual_arm_control.tools.faults.graph_run import GraphRun
from dual_arm_control.tools.faults.launcher_kill import kill_under_launcher
from dual_arm_control.tools.faults.malformed import draw_malformed
from dual_arm_control.tools.faults.outcome import (bag_status, fill_from_trajectory, SETTLE_TIME,
                                                   TrialOutcome)
from dual_arm_control.tools.faults.param_fuzz import parameter_fuzz
from dual_arm_control.tools.faults.slow_consumer import slow_consumer
from dual_arm_control.tools.faults.torque_flood import torque_flood
from dual_arm_control.tools.faults.trial import (measure_graph_episode, run_inprocess, skipped,
                                                 torque_limits)
from dual_arm_control.trajectory_log import load_trajectory

# Wall time a lockstep bridge waits for a command before the cycle goes on without it [s].
KILL_ANSWER_TIMEOUT = 0.05
# Sim time the twin runs on after a kill: the settling window and a margin [s].
AFTER_KILL = SETTLE_TIME + 0.2
GRAPH_TIMEOUT = 300.0
MALFORMED_PER_TRIAL = 200
# Sim time window over which a malformed burst is spread [s]: standby, reach, impact, carry.
MALFORMED_WINDOW = (0.2, 2.2)


@dataclass(frozen=True)
class FaultKind:
    """A fault kind: name, runner ('graph' or 'inprocess'), the rule it is held to, run."""

    name: str
    runner: str
    rule: str
    run: object


def controller_kill(kind, stage, trial):
    """SIGKILL one arm's controller (left on even trials) at a stage; the twin goes on."""
    t_kill = trial.stage_time(stage)
    if t_kill is None:
        return skipped(kind, trial, f'no {stage} in the fault-free episode')
    arm = ARMS[trial.index % 2]
    outcome = TrialOutcome(kind, trial.index, trial.seed)
    with GraphRun(trial.scenario_file(), trial.out_dir, trial.domain, t_kill + AFTER_KILL,
                  KILL_ANSWER_TIMEOUT) as run:
        if not run.wait_for_sim_time(t_kill, GRAPH_TIMEOUT):
            outcome.held, outcome.note = False, f'graph stopped before the kill: {run.exited()}'
            return outcome
        run.kill(f'{arm}_passive_controller')
        run.probe.spin_until(lambda: False, 1.0)
        last = run.probe.last_command_ns[arm]
        outcome.fault_time = (last * 1e-9 if last is not None else t_kill) + FRI_PERIOD
        exits = run.wait_for_end(GRAPH_TIMEOUT)
        outcome.refused = sum(sum(c.values()) for c in run.probe.refusal_counts().values())
    outcome.node_exits = sum(1 for label, code in exits.items()
                             if label != f'{arm}_passive_controller' and code not in (0, None))
    outcome.bag_status = bag_status(run.bag_file)
    outcome.note = f'{arm} controller killed'
    outcome = measure_graph_episode(outcome, run.trajectory_file, trial, (arm,))
    hold = fri_hold_problem(run.trajectory_file, arm, outcome.fault_time)
    if hold or outcome.bag_status != 'complete' or outcome.node_exits:
        outcome.held = False
        outcome.note += f'; {hold}' if hold else ''
    return outcome


def fri_hold_problem(trajectory_file, arm, fault_time):
    """
    Return what is wrong with the FRI hold of arm after its controller died, or ''.

    FriCycle's policy: the previous torque once, then the hold on every later cycle (the
    bridge's counters in the log; one cycle of slack for the last command's delivery). Cycles
    a loaded machine answered after KILL_ANSWER_TIMEOUT before the kill add repeats and holds
    too, so these are lower bounds.
    """
    try:
        data = load_trajectory(trajectory_file)
    except DualArmControlError as error:
        return f'no trajectory: {error}'
    t = data['t']
    cycles_after = int(((t >= fault_time - 1e-9) & (t < t[-1] - 1e-9)).sum())
    repeats = int(data.get(f'{arm}_previous_torque_repeats', -1))
    holds = int(data.get(f'{arm}_watchdog_holds', -1))
    if repeats < 1 or holds < cycles_after - 2:
        return (f'FRI hold not kept: {repeats} previous-torque repeats, {holds} holds in '
                f'{cycles_after} cycles after the kill')
    return ''


def mocap_dropout(kind, duration, stage, trial):
    """Lose every mocap sample for duration [s] from a stage on (impact: centred on it)."""
    t_stage = trial.stage_time(stage)
    if t_stage is None:
        return skipped(kind, trial, f'no {stage} in the fault-free episode')
    start = t_stage - 0.5 * duration if stage == 'impact' else t_stage
    return _inprocess(kind, trial, start, dropout_start=start, dropout_duration=duration)


def mocap_outlier(kind, jump, trial):
    """Displace the mocap sample at the first contact by jump [m] along the squeeze axis."""
    t_impact = trial.stage_time('impact')
    if t_impact is None:
        return skipped(kind, trial, 'no impact in the fault-free episode')
    return _inprocess(kind, trial, t_impact, outlier_time=t_impact, outlier_jump=jump)


def _inprocess(kind, trial, fault_time, **mocap_fields):
    outcome = TrialOutcome(kind, trial.index, trial.seed, fault_time=fault_time)
    metrics, trajectory = run_inprocess(trial.with_mocap(**mocap_fields))
    outcome.recovered = bool(metrics['success'])
    if not trial.nominal['success']:
        outcome.note = 'fault-free episode fails too'
    release_time = trial.release_time
    if metrics['t_release'] is not None:
        own_release = EPISODE_START_TIME + metrics['t_release']
        release_time = own_release if release_time is None else min(release_time, own_release)
    return fill_from_trajectory(outcome, trajectory, torque_limits(), fault_time=fault_time,
                                release_time=release_time)


def malformed_burst(kind, trial):
    """Send MALFORMED_PER_TRIAL malformed messages over every subscribed topic; all must run."""
    messages = draw_malformed(MALFORMED_PER_TRIAL, trial.index)
    outcome = TrialOutcome(kind, trial.index, trial.seed, fault_time=MALFORMED_WINDOW[0])
    step = (MALFORMED_WINDOW[1] - MALFORMED_WINDOW[0]) / len(messages)
    with GraphRun(trial.scenario_file(), trial.out_dir, trial.domain,
                  trial.scenario.duration) as run:
        publishers = {}
        for index, message in enumerate(messages):
            if not run.wait_for_sim_time(MALFORMED_WINDOW[0] + index * step, GRAPH_TIMEOUT):
                break
            key = message.topic_name
            if key not in publishers:
                publishers[key] = run.probe.node.create_publisher(
                    message.topic.msg_type, key, message.topic.publisher_qos)
            publishers[key].publish(message.build(run.probe.clock_ns))
        exits = run.wait_for_end(GRAPH_TIMEOUT)
        counts = run.probe.refusal_counts()
        stalled_at = None if 'sim_bridge' in exits else run.probe.clock_ns * 1e-9
    outcome.node_exits = sum(1 for label, code in exits.items()
                             if (label, code) != ('sim_bridge', 0))
    outcome.refused = sum(sum(c.values()) for c in counts.values())
    outcome.bag_status = bag_status(run.bag_file)
    outcome.note = json.dumps(counts, sort_keys=True)
    if stalled_at is not None:
        outcome.held, outcome.note = False, f'graph stalled at {stalled_at:.3f} s; {outcome.note}'
    outcome = measure_graph_episode(outcome, run.trajectory_file, trial)
    outcome.held = outcome.held and outcome.node_exits == 0 and stalled_at is None
    return outcome


KILL_RULE = ('its arm holds (previous torque once, then the robot hold: gravity + stiffness '
             'toward the joints where its commands stopped + damping) and the motion generator '
             'stops the task; tool speed < 0.05 m/s from 0.3 s on; a held box falls from '
             '<= 2 cm; bag whole')
DROPOUT_RULE = ('held: no NaN torque, none beyond the limits, a held box not dropped; recovered: '
                'the task still succeeds (the tracker predicts through the gap)')
FAULT_KINDS = {kind.name: kind for kind in [
    *(FaultKind(f'controller_kill_{stage}', 'graph', KILL_RULE,
                partial(controller_kill, f'controller_kill_{stage}', stage))
      for stage in ('reach', 'impact', 'carry')),
    FaultKind('node_kill_launcher', 'graph', 'dual_arm_bringup exits 3 naming the node; the '
              'bag up to the kill reads whole', partial(kill_under_launcher,
                                                        'node_kill_launcher')),
    *(FaultKind(f'mocap_dropout_{int(ms)}ms_impact', 'inprocess', DROPOUT_RULE,
                partial(mocap_dropout, f'mocap_dropout_{int(ms)}ms_impact', ms / 1000.0,
                        'impact'))
      for ms in (50, 200, 500)),
    FaultKind('mocap_dropout_200ms_carry', 'inprocess', DROPOUT_RULE,
              partial(mocap_dropout, 'mocap_dropout_200ms_carry', 0.2, 'carry')),
    FaultKind('mocap_outlier_10cm_impact', 'inprocess', DROPOUT_RULE.replace(
        'predicts through the gap', 'gates or filters the jump'),
        partial(mocap_outlier, 'mocap_outlier_10cm_impact', 0.1)),
    FaultKind('parameter_fuzz', 'graph', 'every invalid set refused; no node exits, no NaN '
              'torque, none beyond the limits', partial(parameter_fuzz, 'parameter_fuzz')),
    FaultKind('malformed_burst', 'graph', 'refused and counted per node and input in '
              '/diagnostics; no NaN torque, none beyond the limits; no node exits, no stall',
              partial(malformed_burst, 'malformed_burst')),
    FaultKind('torque_flood', 'graph', 'the bridge applies one command per cycle and arm, its '
              "controller's: the flood's are ignored or refused and counted; the episode is the "
              'fault-free one (the same torques); no NaN torque, none beyond the limits; no node '
              'exits, no stall', partial(torque_flood, 'torque_flood')),
    FaultKind('slow_consumer', 'graph', 'lockstep waits for the stalled node: the episode is '
              'the fault-free one (the same torques); no NaN torque, none beyond the limits; no '
              'node exits, no stall', partial(slow_consumer, 'slow_consumer')),
]}
