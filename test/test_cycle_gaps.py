"""
The realtime FRI clock's accounting: late cycles, stalls, the longest gap, and their reports.

A stall (5 cycles or more without a cycle) is what a real FRI connection would see as that many
commands missing in a row; the bridge counts it, the metrics carry it, the console explains it.
"""

from dual_arm_control.evaluation.episode import clock_stall_note, realtime_clock_metrics
from dual_arm_control.runtime.timing import CycleGaps
import numpy as np
import pytest
from sim_bridge.bridge_diagnostics import diagnostics_message

PERIOD = 0.002


def ticked(gaps):
    """Return a CycleGaps at PERIOD after cycles separated by the given wall-clock gaps [s]."""
    clock = CycleGaps(PERIOD)
    now = 100.0
    clock.tick(now)
    for gap in gaps:
        now += gap
        clock.tick(now)
    return clock


def test_cycles_on_time_or_slightly_late_count_as_nothing():
    clock = ticked([PERIOD] * 50 + [1.4 * PERIOD] * 5)
    assert (clock.late, clock.stalls) == (0, 0)
    assert clock.longest == pytest.approx(1.4 * PERIOD)


def test_a_late_cycle_is_counted_and_a_stall_is_five_periods_or_more():
    clock = ticked([PERIOD, 1.6 * PERIOD, PERIOD, 4.9 * PERIOD, 5.1 * PERIOD, 0.040, PERIOD])
    assert clock.late == 4
    assert clock.stalls == 2
    assert clock.as_dict() == {'late_cycles': 4, 'cycle_stalls': 2,
                               'longest_cycle_gap': pytest.approx(0.040)}


def test_a_restart_forgets_the_last_cycle_so_a_pause_is_no_stall():
    clock = ticked([PERIOD] * 3)
    clock.restart()
    clock.tick(500.0)
    clock.tick(500.0 + PERIOD)
    assert (clock.late, clock.stalls) == (0, 0)
    assert clock.longest == pytest.approx(PERIOD)


def test_a_non_positive_period_is_refused():
    with pytest.raises(ValueError, match='period'):
        CycleGaps(0.0)


def test_the_metrics_carry_the_clock_of_a_realtime_log_and_null_in_lockstep():
    realtime = {'late_cycles': np.int64(12), 'cycle_stalls': np.int64(3),
                'longest_cycle_gap': np.float64(0.0421)}
    assert realtime_clock_metrics(realtime) == {'late_cycles': 12, 'cycle_stalls': 3,
                                                'longest_cycle_gap': 0.0421}
    lockstep = {'late_cycles': np.int64(0), 'cycle_stalls': np.int64(0),
                'longest_cycle_gap': np.float64(0.0)}
    assert set(realtime_clock_metrics(lockstep).values()) == {None}
    assert set(realtime_clock_metrics({}).values()) == {None}


def test_the_stall_note_names_the_stalls_the_holds_and_the_kernel_budget(tmp_path):
    budget = tmp_path / 'sched_rt_runtime_us'
    budget.write_text('950000\n')
    metrics = {'cycle_stalls': 3, 'longest_cycle_gap': 0.0421, 'watchdog_hold_count': 61}
    note = clock_stall_note(metrics, budget)
    assert 'stalled 3 times' in note and 'longest 42 ms' in note
    assert 'held an arm 61 times' in note and '950000 us' in note
    assert 'unknown here' in clock_stall_note(metrics, tmp_path / 'missing')


def test_the_bridge_status_warns_on_stalls():
    values = {'sim_bridge': {'mode': 'realtime', 'cycles': 2000, 'late_cycles': 9,
                             'cycle_stalls': 2, 'longest_cycle_gap': 0.04}}
    status = diagnostics_message(values, 0).status[0]
    assert status.level == status.WARN
    assert status.message == '2 stalls of the FRI clock'
    calm = {'sim_bridge': dict(values['sim_bridge'], cycle_stalls=0)}
    assert diagnostics_message(calm, 0).status[0].level == status.OK
