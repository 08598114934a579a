"""The time between two ticks' joint samples (core.sample_time)."""

from dual_arm_control.core.sample_time import sample_span
import numpy as np


def test_in_lockstep_the_span_is_the_tick_exactly():
    assert sample_span(0.005, 0.0, 0.0) == 0.005
    assert np.array_equal(sample_span(0.005, np.zeros(2), np.zeros(2)), [0.005, 0.005])


def test_samples_a_cycle_off_the_ticks_span_the_time_between_them():
    """Read 2 ms late at one tick and 2 ms early at the next, samples are 9 ms apart, not 5."""
    assert np.isclose(sample_span(0.005, 0.002, -0.002), 0.009)
    assert np.allclose(sample_span(0.005, [0.0, 0.004], [0.002, 0.0]), [0.003, 0.009])


def test_a_sample_read_at_two_ticks_spans_nothing():
    assert sample_span(0.005, 0.001, 0.006) is None
    assert sample_span(0.005, [0.0, 0.001], [0.0, 0.006]) is None
