"""
The runtime's policies, without ROS: arrival barrier, signal validation, FRI cycle, controller.

The FRI cycle runs on the real MuJoCo twin; the controller step on the real pinocchio model.
"""

import math

from dual_arm_control.core.arms import ARMS, joint_names
from dual_arm_control.core.exceptions import InputError
from dual_arm_control.core.passive_control import PassiveControllerConfig
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.runtime.controller_step import ControllerStep
from dual_arm_control.runtime.fri import command_refusal, FriCycle
from dual_arm_control.runtime.inputs import ArrivalBarrier, MAX_PENDING_STAMPS
from dual_arm_control.runtime.signals import (arm_command_sample, joint_state_sample,
                                              JointStateSample, wrench_sample)
from dual_arm_control.runtime.timing import seconds_to_ns
from dual_arm_control.scenario import load_scenario
import numpy as np
import pytest
from sim_bridge.twin import DualArmTwin

CELL = load_cell()
MS = 1_000_000


# -- arrival barrier -----------------------------------------------------------------------------

def test_barrier_completes_each_stamp_once_all_its_inputs_arrived_in_any_order():
    barrier = ArrivalBarrier(lambda stamp: {'a', 'b'} | ({'c'} if stamp % (10 * MS) == 0
                                                         else set()))
    assert barrier.arrived(2 * MS, 'b') == []
    assert barrier.arrived(2 * MS, 'a') == [2 * MS]
    assert barrier.arrived(10 * MS, 'a') == []
    assert barrier.arrived(10 * MS, 'b') == []
    assert barrier.pending(10 * MS) == {'c'}
    assert barrier.arrived(10 * MS, 'c') == [10 * MS]
    assert barrier.dropped == 0


def test_barrier_drops_older_incomplete_stamps_and_bounds_its_memory():
    barrier = ArrivalBarrier(lambda stamp: {'a', 'b'})
    barrier.arrived(2 * MS, 'a')
    barrier.arrived(4 * MS, 'a')
    assert barrier.arrived(4 * MS, 'b') == [4 * MS]
    assert barrier.dropped == 1 and barrier.pending(2 * MS) == {'a', 'b'}
    for k in range(MAX_PENDING_STAMPS + 10):
        barrier.arrived((6 + 2 * k) * MS, 'a')
    assert barrier.dropped == 1 + 10


def test_barrier_starts_over_when_the_clock_goes_back():
    barrier = ArrivalBarrier(lambda stamp: {'a', 'b'})
    barrier.arrived(2000 * MS, 'a')
    barrier.arrived(2000 * MS, 'b')
    barrier.arrived(2002 * MS, 'a')
    assert barrier.arrived(0, 'a') == []
    assert barrier.arrived(0, 'b') == [0]
    assert barrier.pending(2002 * MS) == {'a', 'b'}, 'the old timeline is forgotten'


def test_stray_future_stamps_complete_alone_and_drop_no_awaited_cycle():
    """Refused inputs stamped 10 s ahead (a malformed burst) once stalled the lockstep graph."""
    barrier = ArrivalBarrier(lambda stamp: {'a', 'b', 'c'})
    for name in 'abc':
        barrier.arrived(650 * MS, name)
    assert barrier.arrived(652 * MS, 'a') == []
    for name in 'ab':
        assert barrier.arrived(10_652 * MS, name) == []
    assert barrier.arrived(10_652 * MS, 'c') == [10_652 * MS]
    assert barrier.pending(652 * MS) == {'b', 'c'}
    assert barrier.arrived(652 * MS, 'b') == []
    assert barrier.arrived(652 * MS, 'c') == [652 * MS]
    assert barrier.dropped == 0


# -- signals -------------------------------------------------------------------------------------

def test_joint_states_are_matched_by_name_in_any_order():
    names = joint_names('left')
    shuffled = [names[index] for index in (3, 0, 6, 1, 5, 2, 4)] + ['gripper']
    position = [float(names.index(n)) if n in names else 99.0 for n in shuffled]
    sample = joint_state_sample(7, shuffled, position, [0.5] * 8, [], names)
    np.testing.assert_array_equal(sample.position, np.arange(7.0))
    np.testing.assert_array_equal(sample.effort, np.zeros(7))
    with pytest.raises(InputError, match=r"lacks joints \['left_A7'\]"):
        joint_state_sample(7, names[:6], [0.0] * 6, [0.0] * 6, [], names)
    with pytest.raises(InputError, match='velocity has 6 values, expected 7'):
        joint_state_sample(7, names, [0.0] * 7, [0.0] * 6, [], names)
    with pytest.raises(InputError, match='NaN or Inf'):
        joint_state_sample(7, names, [0.0] * 6 + [math.nan], [0.0] * 7, [], names)


def test_torque_commands_are_refused_for_a_reason():
    names = joint_names('right')
    assert command_refusal(names, [1.0] * 7, names) is None
    assert command_refusal(list(reversed(names)), [1.0] * 7, names) is None
    assert command_refusal(names, [1.0] * 6, names) == 'wrong_length'
    assert command_refusal(names[:6] + ['left_A7'], [1.0] * 7, names) == 'joint_names'
    assert command_refusal(names, [1.0] * 6, names) == 'wrong_length'
    assert command_refusal(names, [1.0] * 6 + [math.inf], names) == 'non_finite'


# -- FRI cycle -----------------------------------------------------------------------------------

@pytest.fixture
def fri():
    return FriCycle(DualArmTwin(load_scenario('hold', cell=CELL), CELL))


def answer_all(fri, torques):
    for arm in ARMS:
        fri.answer(arm, fri.awaited_ns, joint_names(arm), list(torques[arm]))


def test_a_refused_command_holds_the_arm_for_that_cycle(fri):
    state = fri.begin()
    assert state.stamp_ns == 0 and set(state.joints) == set(ARMS)
    names = joint_names('left')
    assert not fri.answer('left', 0, names, [0.0] * 6 + [math.nan])
    assert fri.refused('left') == 'non_finite'
    assert fri.answer('right', 0, joint_names('right'), [0.0] * 7)
    hold = fri.backend.hold_torques('left', fri.backend.joint_state('left').position)
    applied = fri.advance()
    np.testing.assert_array_equal(applied['left'], hold)
    np.testing.assert_array_equal(applied['right'], np.zeros(7))
    assert fri.counters['left'].refused['non_finite'] == 1


def test_a_missing_command_repeats_the_last_torque_once_then_holds(fri):
    """FRI deadline policy: the previous torque for at most one cycle, then the hold."""
    gravity = {arm: fri.backend.hold_torques(arm) for arm in ARMS}
    fri.begin()
    answer_all(fri, gravity)
    fri.advance()
    fri.begin()
    fri.answer('left', fri.awaited_ns, joint_names('left'), list(gravity['left']))
    assert fri.stop_position('right') is None
    first_missed = fri.backend.joint_state('right').position
    applied = fri.advance()
    np.testing.assert_array_equal(applied['right'], gravity['right'])
    assert fri.counters['right'].previous_torque_repeats == 1
    assert fri.counters['right'].watchdog_holds == 0
    # The robot holds the joints where the commands stopped: at the first missed cycle.
    stopped_at = fri.stop_position('right')
    np.testing.assert_array_equal(stopped_at, first_missed)
    # Pushed away from there, the held arm is pulled back (stiffness), not just damped.
    fri.backend.data.qpos[fri.backend.index.arms['right'].qpos] += 0.01
    for _ in range(3):
        fri.begin()
        hold = fri.backend.hold_torques('right', stopped_at)
        assert np.abs(hold - fri.backend.hold_torques('right')).max() > 1.0
        applied = fri.advance()
        np.testing.assert_array_equal(applied['right'], hold)
        np.testing.assert_array_equal(fri.stop_position('right'), stopped_at)
    assert fri.counters['right'].watchdog_holds == 3
    assert fri.counters['right'].previous_torque_repeats == 1
    fri.begin()
    late_stamp = fri.awaited_ns - 2 * MS
    fri.answer('right', late_stamp, joint_names('right'), list(gravity['right']))
    assert fri.counters['right'].late == 1 and fri.missing() == ['left', 'right']


# -- controller step -----------------------------------------------------------------------------

@pytest.fixture
def controller():
    return ControllerStep(arm_model('left', CELL), CELL.arm('left').q_home,
                          PassiveControllerConfig(), 0.005, 0.05)


def joint_state(stamp_ns, q, dq):
    return JointStateSample(stamp_ns, np.asarray(q, float), np.asarray(dq, float), np.zeros(7))


def test_controller_holds_without_a_fresh_command_and_repeats_a_repeated_cycle(controller):
    q = CELL.arm('left').q_home
    dq = np.full(7, 0.1)
    first = controller.cycle(joint_state(0, q, dq))
    np.testing.assert_allclose(first.effort, controller.hold(q, dq), atol=0.0)
    assert controller.counters['holds_no_command'] == 1
    assert controller.cycle(joint_state(0, q, dq)) is first
    assert controller.counters['repeated_answers'] == 1
    controller.command(arm_command_sample(2 * MS, np.zeros(3), [0.0, 0.0, 0.0, 1.0],
                                          [0.1, 0.0, 0.0], np.zeros(3)))
    live = controller.cycle(joint_state(2 * MS, q, dq))
    assert not np.allclose(live.effort, controller.hold(q, dq))
    stale_ns = 2 * MS + seconds_to_ns(0.05) + 2 * MS
    stale = controller.cycle(joint_state(stale_ns, q, dq))
    np.testing.assert_allclose(stale.effort, controller.hold(q, dq), atol=0.0)
    assert controller.counters['holds_stale_command'] == 1
    assert all(np.isfinite(sample.effort).all() for sample in (first, live, stale))


def test_controller_returns_to_the_free_gains_after_a_stretch_without_contact(controller):
    """
    The contact gains end after free_gains_after without a contact wrench, not before.

    They hold across a parameter change; then the next reach has the free gains though the
    clock never went back (a real robot's).
    """
    q, dq = CELL.arm('left').q_home, np.zeros(7)
    free_after = controller.controller.config.free_gains_after

    def cycle_at(stamp_ns, force):
        controller.command(arm_command_sample(stamp_ns, np.zeros(3), [0.0, 0.0, 0.0, 1.0],
                                              np.zeros(3), np.zeros(3)))
        controller.wrench(wrench_sample(stamp_ns, force, np.zeros(3)))
        controller.cycle(joint_state(stamp_ns, q, dq))
        return controller.controller.touched

    assert not cycle_at(2 * MS, np.zeros(3))
    assert cycle_at(4 * MS, [0.0, 20.0, 0.0])
    last_contact_ns = 4 * MS
    controller.reconfigure(PassiveControllerConfig(orientation_stiffness=12.0))
    stamps = np.arange(6 * MS, last_contact_ns + seconds_to_ns(free_after) + 4 * MS, 2 * MS)
    touched = [cycle_at(int(stamp), np.zeros(3)) for stamp in stamps]
    assert controller.controller.config.orientation_stiffness == 12.0
    expected = [stamp - last_contact_ns < seconds_to_ns(free_after) for stamp in stamps]
    assert touched == expected and not touched[-1]


def test_a_parameter_change_keeps_the_tracked_posture_and_changes_only_that_gain():
    """
    Reconfiguring mid-task keeps the null-space posture the arm has tracked so far.

    Two controllers see the same 100 cycles toward an attractor 0.2 m from the home tool
    position (their postures move up to 0.01 rad a cycle); one is then given an equal config.
    Rebuilt from its start posture instead, its null-space spring would pull every joint up to
    the 0.4 rad error limit back toward home: tens of N m at 10 N m/rad.
    """
    model = arm_model('left', CELL)
    q_home, dq = CELL.arm('left').q_home, np.zeros(7)
    steps = [ControllerStep(model, q_home, PassiveControllerConfig(), 0.005, 0.05)
             for _ in range(2)]
    p_world_home, _ = model.tool_pose(q_home)
    attractor = p_world_home + np.array([0.2, 0.0, -0.1])

    def cycle_all(stamp_ns):
        for step in steps:
            step.command(arm_command_sample(stamp_ns, attractor, [1.0, 0.0, 0.0, 0.0],
                                            np.zeros(3), np.zeros(3)))
            step.wrench(wrench_sample(stamp_ns, np.zeros(3), np.zeros(3)))
        return [step.cycle(joint_state(stamp_ns, q_home, dq)).effort for step in steps]

    for k in range(1, 101):
        cycle_all(2 * k * MS)
    tracked = steps[1].controller.q_null.copy()
    assert np.abs(tracked - q_home).max() > 0.1, 'the posture followed the attractor'
    steps[1].reconfigure(PassiveControllerConfig())
    unchanged, reconfigured = cycle_all(202 * MS)
    np.testing.assert_array_equal(reconfigured, unchanged)
    steps[1].reconfigure(PassiveControllerConfig(null_space_stiffness=(20.0,) * 7))
    unchanged, stiffer = cycle_all(204 * MS)
    assert np.abs(steps[1].controller.q_null - steps[0].controller.q_null).max() == 0.0
    assert not np.array_equal(stiffer, unchanged), 'the new gain acts'


def test_controller_waits_for_tick_inputs_only_on_new_ticks(controller):
    q, dq = CELL.arm('left').q_home, np.zeros(7)
    assert controller.needs_tick_inputs(0)
    controller.cycle(joint_state(0, q, dq))
    assert not controller.needs_tick_inputs(0), 'a repeated cycle is answered at once'
    assert not controller.needs_tick_inputs(2 * MS)
    assert not controller.needs_tick_inputs(4 * MS)
    assert controller.needs_tick_inputs(6 * MS), 'the 200 Hz grid of the DS ticks'
    controller.cycle(joint_state(6 * MS, q, dq))
    controller.cycle(joint_state(0, q, dq))
    assert controller.counters['schedule_restarts'] == 1


def tick_inputs(stamp_ns):
    """Return a DS command and a contact wrench stamped with a DS tick."""
    return (arm_command_sample(stamp_ns, np.zeros(3), [0.0, 0.0, 0.0, 1.0], np.zeros(3),
                               np.zeros(3)),
            wrench_sample(stamp_ns, np.zeros(3), np.zeros(3)))


def run_ticks(controller, arrivals):
    """Answer cycles 0-10 ms on the 2 ms grid; arrivals = {cycle ms: [tick ms, ...]} before it."""
    q, dq = CELL.arm('left').q_home, np.zeros(7)
    for cycle_ms in range(0, 12, 2):
        for tick_ms in arrivals.get(cycle_ms, []):
            command, wrench = tick_inputs(tick_ms * MS)
            controller.command(command)
            controller.wrench(wrench)
        controller.cycle(joint_state(cycle_ms * MS, q, dq))
    return {key: controller.counters[key] for key in (
        'ds_command_behind', 'ds_command_lag_max_ms', 'contact_wrench_behind',
        'contact_wrench_lag_max_ms')}


def test_inputs_of_the_newest_tick_are_never_behind(controller):
    """As in lockstep: each tick's command and wrench arrive before its cycle (ticks 0, 6, 10)."""
    assert set(run_ticks(controller, {0: [0], 6: [6], 10: [10]}).values()) == {0}
    assert controller.take_ds_command_lag() == 0.0
    assert controller.take_ds_command_lag() is None, 'no cycle since the last report'


def test_inputs_a_cycle_late_are_counted_behind_with_their_lag(controller):
    """Realtime: tick 6's inputs come a cycle after it, tick 10's not at all before 10 ms."""
    assert run_ticks(controller, {0: [0], 8: [6]}) == {
        'ds_command_behind': 2, 'ds_command_lag_max_ms': 6,
        'contact_wrench_behind': 2, 'contact_wrench_lag_max_ms': 6}
    lags_ms = [0, 0, 0, 6, 0, 4]
    assert controller.take_ds_command_lag() == pytest.approx(sum(lags_ms) / 6 * 1e-3)
