"""
The fault campaign's kinds, one trial each, judged on the twin's ground truth.

A controller killed while carrying, a malformed burst on every subscribed topic, a 200 ms mocap
dropout at the impact, a torque command flood, a node stalled for 100 ms.

Each test runs the kind exactly as dual_arm_faults does (the lockstep graph for the first two)
and checks the physical outcome on the twin's ground truth.
"""

import json
import os
import re

from dual_arm_control.contract import ARMS, TORQUE_COMMAND
from dual_arm_control.runtime.node_settings import FRI_PERIOD
from dual_arm_control.tools.faults.graph_run import SimProbe
from dual_arm_control.tools.faults.kinds import (FAULT_KINDS, fri_hold_problem,
                                                 MALFORMED_PER_TRIAL)
from dual_arm_control.tools.faults.malformed import DEFECTS, draw_malformed, SUBSCRIBED
from dual_arm_control.tools.faults.outcome import (DROP_HEIGHT_LIMIT, SETTLE_TIME,
                                                   SETTLED_TOOL_SPEED, tool_speed_after)
from dual_arm_control.tools.faults.slow_consumer import STALL_TIME
from dual_arm_control.tools.faults.trial import prepare_trial, run_inprocess, torque_limits
from dual_arm_control.trajectory_log import load_trajectory
import numpy as np
import pytest


@pytest.mark.slow
def test_a_controller_killed_while_carrying_leaves_the_box_held(tmp_path, ros_domain):
    """
    The rule: its arm gets the FRI hold, settles below 0.05 m/s from 0.3 s on; no drop > 2 cm.

    The robot holds the arm where its commands stopped and the motion generator, hearing no
    more commands from that controller, stops the task with the box squeezed in place.
    """
    trial = prepare_trial(0, tmp_path / 'kill', int(ros_domain))
    outcome = FAULT_KINDS['controller_kill_carry'].run(trial)
    print(outcome.as_dict())
    arm = ARMS[0]
    data = load_trajectory(trial.out_dir / 'trajectory.npz')
    t = data['t']
    cycles_after = int(np.sum((t >= outcome.fault_time - 1e-9) & (t < t[-1] - 1e-9)))
    assert outcome.note == f'{arm} controller killed'
    # The kill is sent once sim time reaches the stage: the first cycle without a command is
    # that cycle or the next, so the fault time may equal the stage time.
    assert trial.stage_time('carry') <= outcome.fault_time < t[-1]
    assert fri_hold_problem(trial.out_dir / 'trajectory.npz', arm, outcome.fault_time) == ''
    assert int(data[f'{arm}_previous_torque_repeats']) >= 1
    assert int(data[f'{arm}_watchdog_holds']) >= cycles_after - 2
    assert outcome.nan_torques == 0 and outcome.torque_clamps == 0
    assert outcome.worst_torque_ratio <= 1.0 + 1e-9
    assert outcome.node_exits == 0
    assert outcome.bag_status == 'complete'
    speed_at_kill = tool_speed_after(data, (arm,), outcome.fault_time - FRI_PERIOD)
    other = ARMS[1]
    print(f'{arm} tool speed at the kill {speed_at_kill:.3f} m/s; from 0.3 s on at most '
          f'{outcome.worst_tool_speed:.3f} m/s ({other}: '
          f'{tool_speed_after(data, (other,), outcome.fault_time + SETTLE_TIME):.3f} m/s); '
          f'box fell {outcome.drop_height:.4f} m')
    assert outcome.worst_tool_speed < SETTLED_TOOL_SPEED
    assert outcome.drop_height <= DROP_HEIGHT_LIMIT
    assert all(bool(data[f'{side}_pad_contact'][-1]) for side in ARMS), 'the box is held'
    assert outcome.held


@pytest.mark.slow
def test_a_malformed_burst_on_every_topic_is_refused_and_nothing_exits(tmp_path, ros_domain):
    messages = draw_malformed(MALFORMED_PER_TRIAL, 0)
    assert {message.topic_name for message in messages} == {
        topic.resolved(arm) if arm else topic.name for topic, arm in SUBSCRIBED}
    assert {message.defect for message in messages} == set(DEFECTS)
    trial = prepare_trial(0, tmp_path / 'malformed', int(ros_domain))
    outcome = FAULT_KINDS['malformed_burst'].run(trial)
    print(outcome.as_dict())
    counts = json.loads(outcome.note)
    torque_commands = sum(1 for message in messages if message.topic is TORQUE_COMMAND)
    assert outcome.node_exits == 0
    assert outcome.nan_torques == 0
    assert outcome.worst_torque_ratio <= 1.0 + 1e-9
    assert outcome.torque_clamps == 0, 'an unsigned torque command was applied'
    assert outcome.bag_status == 'complete'
    assert {'object_tracker', 'left/passive_controller', 'right/passive_controller', 'wrench_qp',
            'ds_motion_generator'} <= set(counts), counts
    assert sum(counts[f'sim_bridge: {arm} arm'].get('refused_foreign', 0)
               for arm in ARMS) == torque_commands, counts
    assert outcome.refused > 0.2 * MALFORMED_PER_TRIAL
    assert outcome.held


def test_a_200_ms_mocap_dropout_at_the_impact_keeps_the_task(tmp_path):
    """
    Over the first five randomized trials, at least four succeed despite the dropout.

    Must-show: >= 90 % over 50 trials (the campaign); five trials in the suite allow one miss
    (trial 0 misses the 10 ms contact gap by one FRI cycle while the tracker predicts).
    """
    recovered = 0
    for index in range(5):
        trial = prepare_trial(index, tmp_path / f'dropout_{index}')
        assert trial.nominal['success']
        outcome = FAULT_KINDS['mocap_dropout_200ms_impact'].run(trial)
        print(outcome.as_dict())
        assert outcome.fault_time == pytest.approx(trial.stage_time('impact') - 0.1)
        assert outcome.held
        assert outcome.nan_torques == 0 and outcome.torque_clamps == 0
        recovered += int(outcome.recovered)
    assert recovered >= 4


def assert_fault_free_episode(trial):
    """Return the graph run's log after checking it is the trial's fault-free episode."""
    data = load_trajectory(trial.out_dir / 'trajectory.npz')
    fault_free = run_inprocess(trial.scenario)[1]
    assert data['t'][-1] == pytest.approx(trial.scenario.duration)
    for arm in ARMS:
        tau = np.asarray(data[f'{arm}_tau'], dtype=float)
        assert np.isfinite(tau).all()
        assert (np.abs(tau) <= np.asarray(torque_limits()[arm]) + 1e-9).all()
        assert tau.shape == fault_free[f'{arm}_tau'].shape
        assert np.abs(tau - fault_free[f'{arm}_tau']).max() <= 1e-9, f'{arm} left its controller'
    return data


@pytest.mark.slow
def test_a_torque_command_flood_never_commands_the_arm(tmp_path, ros_domain):
    """
    10 foreign commands a cycle (wrong stamps, huge, NaN): the arm follows its controller.

    The bridge waits for no state to be published again: the flood does not push the
    controller's command out of its reader (a few republishes: a loaded machine).
    """
    trial = prepare_trial(0, tmp_path / 'flood', int(ros_domain))
    outcome = FAULT_KINDS['torque_flood'].run(trial)
    print(outcome.as_dict())
    data = assert_fault_free_episode(trial)
    arm = ARMS[0]
    assert int(data[f'{arm}_refused_foreign']) > 100, 'the flood did not reach the bridge'
    assert int(data[f'{arm}_torque_clamps']) == 0 and int(data[f'{arm}_refused_non_finite']) == 0
    assert outcome.node_exits == 0 and 'stalled' not in outcome.note
    republished = int(re.search(r'(\d+) flooded states republished', outcome.note).group(1))
    assert republished <= 5, "the flood pushed the controller's commands out"
    assert outcome.held and outcome.recovered == trial.nominal['success']


@pytest.mark.slow
def test_a_controller_stalled_for_100_ms_leaves_the_episode_as_it_was(tmp_path, ros_domain):
    """Trial 3 stops the left controller at the reach: lockstep waits; the episode is unchanged."""
    trial = prepare_trial(3, tmp_path / 'stall', int(ros_domain))
    outcome = FAULT_KINDS['slow_consumer'].run(trial)
    print(outcome.as_dict())
    assert outcome.note.startswith(f'left_passive_controller stopped {STALL_TIME * 1e3:g} ms')
    assert_fault_free_episode(trial)
    assert outcome.node_exits == 0 and 'stalled' not in outcome.note
    assert outcome.held and outcome.recovered == trial.nominal['success']


def test_a_closed_probe_leaves_no_threads_or_descriptors(ros_domain):
    """A campaign process opens one probe per trial; leaked ones hung the graphs after ~27."""
    def resources():
        return len(os.listdir('/proc/self/task')), len(os.listdir('/proc/self/fd'))

    SimProbe(int(ros_domain)).close()
    before = resources()
    for _ in range(3):
        probe = SimProbe(int(ros_domain))
        probe.spin_until(lambda: False, 0.1)
        probe.close()
    assert resources() == before
