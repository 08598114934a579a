"""
A controller that dies: the robot holds its arm, the motion generator stops the task.

The rule of docs/reliability.md for a dead controller, in-process (the same steps and FRI
cycle as the lockstep graph that goes on without a killed controller; test_faults.py runs the
graph itself): its arm holds, its tool is below 0.05 m/s from 0.3 s on, and a carried box falls
from no more than 2 cm.
"""

from dual_arm_control.contract import ARMS
from dual_arm_control.inprocess import run_episode, RunnerConfig
from dual_arm_control.runtime.controller_watch import (controller_silent, ControllerWatch,
                                                       FUTURE_TOLERANCE_NS)
from dual_arm_control.runtime.node_settings import FRI_PERIOD
from dual_arm_control.tools.faults.outcome import (DROP_HEIGHT_LIMIT, fill_from_trajectory,
                                                   SETTLED_TOOL_SPEED, TrialOutcome)
from dual_arm_control.tools.faults.trial import cell, prepare_trial, torque_limits
import numpy as np
import pytest

MS = 1_000_000


def test_a_controller_is_lost_only_after_it_was_heard_and_then_silent_too_long():
    assert not controller_silent(None, 500 * MS, 10 * MS)
    assert not controller_silent(100 * MS, 110 * MS, 10 * MS)
    assert controller_silent(100 * MS, 111 * MS, 10 * MS)
    assert not controller_silent(100 * MS, 900 * MS, 0)
    watch = ControllerWatch(10 * MS)
    watch.heard('left', 0)
    assert watch.newly_lost(0) == ()
    for stamp in range(0, 12 * MS, 2 * MS):
        watch.heard('left', stamp)
        watch.heard('right', min(stamp, 2 * MS))
    assert watch.newly_lost(12 * MS) == ()
    watch.heard('left', 12 * MS)
    assert watch.newly_lost(13 * MS) == (), 'silent 11 ms, but only 10 ms behind the partner'
    watch.heard('left', 14 * MS)
    assert watch.newly_lost(14 * MS) == ('right',)
    assert watch.newly_lost(20 * MS) == (), 'a loss is reported once'
    watch.heard('left', 20 * MS + FUTURE_TOLERANCE_NS + 1)
    assert watch.newly_lost(31 * MS) == (), 'its partner silent too: not judged'
    for stamp in range(14 * MS, 31 * MS, 2 * MS):
        watch.heard('right', stamp)
    assert watch.newly_lost(31 * MS) == ('left',), 'a command from the future is not believed'
    watch.restart()
    assert watch.lost_arms == () and watch.newly_lost(500 * MS) == ()
    watch.heard('left', 500 * MS)
    for stamp in range(500 * MS, 596 * MS, 5 * MS):
        watch.heard('right', stamp)
    assert watch.newly_lost(600 * MS, judge=False) == (), 'not judged (standby)'
    assert watch.newly_lost(600 * MS) == ('left',)


def test_a_watcher_behind_on_both_arms_judges_no_controller_lost():
    """
    The realtime case: the tick's joint state is fresh, both arms' commands still queued.

    The watcher took the commands up to 20 ms (left) and 22 ms (right) when the tick at 34 ms
    runs: both silent for more than the 10 ms timeout at the tick, neither behind the other by
    more, so neither is lost. Then the two streams come back 6 ms apart (as measured in a
    realtime run): the left one first, which does not make the right one lost, since the left
    was silent over the same time. Once the right controller dies (at 60 ms) while the left one
    answers on, the right arm alone is lost.
    """
    watch = ControllerWatch(10 * MS)
    watch.newly_lost(0)
    for stamp in range(0, 23 * MS, 2 * MS):
        watch.heard('right', stamp)
        watch.heard('left', min(stamp, 20 * MS))
    assert watch.newly_lost(34 * MS) == ()
    for stamp in range(34 * MS, 42 * MS, 2 * MS):
        watch.heard('left', stamp)
    assert watch.newly_lost(42 * MS) == (), 'the left stream was silent too: not judged'
    for stamp in range(40 * MS, 61 * MS, 2 * MS):
        watch.heard('right', stamp)
    for stamp in range(42 * MS, 76 * MS, 2 * MS):
        watch.heard('left', stamp)
    assert watch.newly_lost(70 * MS) == ()
    assert watch.newly_lost(76 * MS) == ('right',)


def kill_while_carrying(tmp_path, controller_timeout=None):
    """Kill trial 0's left controller halfway through its carry; return (outcome, log)."""
    trial = prepare_trial(0, tmp_path)
    kill = round(trial.stage_time('carry') / FRI_PERIOD) * FRI_PERIOD
    timeout = {} if controller_timeout is None else {'controller_timeout': controller_timeout}
    config = RunnerConfig(controller_deaths=(('left', kill),), **timeout)
    data = run_episode(trial.scenario, config, cell=cell(), duration=kill + 0.6).trajectory
    outcome = fill_from_trajectory(TrialOutcome('controller_kill_carry', 0, trial.seed), data,
                                   torque_limits(), ('left',), kill, trial.release_time)
    print(f'controller_timeout {controller_timeout}: box fell {outcome.drop_height:.4f} m, '
          f'dead arm from 0.3 s on <= {outcome.worst_tool_speed:.3f} m/s, pads touching at '
          f'the end: {[bool(data[f"{arm}_pad_contact"][-1]) for arm in ARMS]}')
    return outcome, data


@pytest.mark.slow
def test_a_controller_killed_while_carrying_leaves_the_box_held(tmp_path):
    outcome, data = kill_while_carrying(tmp_path)
    assert outcome.drop_height <= DROP_HEIGHT_LIMIT
    assert outcome.worst_tool_speed < SETTLED_TOOL_SPEED
    assert outcome.nan_torques == 0 and outcome.torque_clamps == 0
    assert all(bool(data[f'{arm}_pad_contact'][-1]) for arm in ARMS), 'the box is still held'
    assert outcome.held


@pytest.mark.slow
def test_without_the_motion_generator_halt_the_living_arm_carries_on(tmp_path):
    """
    The robot's hold alone cannot stop the task: the partner arm carries the box on.

    It drags the held arm's tool along, at several times the 0.05 m/s of a settled arm (0.23
    m/s since the held box turns until no wrist overreaches, 2026-11-29; 0.42 m/s before; 0.68
    m/s before the held box was read from the pads, core.held_object), and the box leaves both
    pads (dropped, or tossed on by the living arm near the planned release).
    """
    outcome, data = kill_while_carrying(tmp_path, controller_timeout=0.0)
    assert outcome.worst_tool_speed > 3.0 * SETTLED_TOOL_SPEED
    assert not any(bool(data[f'{arm}_pad_contact'][-1]) for arm in ARMS)
    assert not outcome.held


@pytest.mark.slow
def test_a_controller_dead_before_the_episode_halts_it_at_the_start_of_the_reach(tmp_path):
    """Silence in standby is not judged (realtime start-up); at the reach the task halts."""
    trial = prepare_trial(0, tmp_path)
    data = run_episode(trial.scenario, RunnerConfig(controller_deaths=(('left', 0.1),)),
                       cell=cell(), duration=1.0).trajectory
    moved = np.linalg.norm(data['right_tool_position'] - data['right_tool_position'][0], axis=1)
    print(f'the living arm moved at most {moved.max() * 1e3:.1f} mm')
    assert moved.max() < 0.01, 'the living arm reached for the box with its partner dead'
