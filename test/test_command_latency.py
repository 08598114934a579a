"""The realtime DS command lag the toss release leads by (paper section IV-A)."""

from dual_arm_control.runtime.command_latency import CommandLatency
import pytest


def test_no_report_yet_means_no_latency():
    assert CommandLatency().seconds == 0.0


def test_the_latency_is_the_mean_of_each_controllers_newest_report():
    latency = CommandLatency()
    assert latency.reported('left/passive_controller', 0.006)
    assert latency.seconds == pytest.approx(0.006)
    assert latency.reported('right/passive_controller', 0.002)
    assert latency.reported('left/passive_controller', 0.004)
    assert latency.seconds == pytest.approx(0.003)


def test_a_lag_beyond_the_limit_counts_as_the_limit():
    latency = CommandLatency(limit=0.02)
    latency.reported('left/passive_controller', 0.5)
    assert latency.seconds == pytest.approx(0.02)


@pytest.mark.parametrize('lag', [-0.001, float('nan'), float('inf'), None, '4'])
def test_a_lag_that_is_not_one_is_refused_and_changes_nothing(lag):
    latency = CommandLatency()
    latency.reported('left/passive_controller', 0.004)
    assert not latency.reported('right/passive_controller', lag)
    assert latency.seconds == pytest.approx(0.004)


@pytest.mark.parametrize('limit', [0.0, -1.0, float('nan')])
def test_a_limit_that_is_not_positive_is_refused(limit):
    with pytest.raises(ValueError):
        CommandLatency(limit)
