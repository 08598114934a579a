"""The whole pipeline in one process on the twin: the paper's toss, and bit-identical reruns."""

from dual_arm_control.description.cell import load_cell
from dual_arm_control.evaluation.episode import episode_metrics
from dual_arm_control.inprocess import run_episode
from dual_arm_control.scenario import load_scenario, scenario_path
import numpy as np
import pytest


@pytest.fixture(scope='module')
def cell():
    return load_cell()


def test_paper_toss_in_process(cell):
    scenario = load_scenario(scenario_path('paper_toss'), cell=cell)
    metrics = episode_metrics(scenario, run_episode(scenario, cell=cell).trajectory, cell)
    assert metrics['contact_time_gap'] <= 0.010
    assert metrics['impact_speed_along_direction_left'] == pytest.approx(0.5, rel=0.15)
    assert metrics['impact_speed_along_direction_right'] == pytest.approx(0.5, rel=0.15)
    assert metrics['max_slip'] <= 0.01
    assert metrics['release_position_error'] <= 0.03
    assert metrics['release_velocity_error'] <= 0.10
    assert metrics['landing_prediction_error'] <= 0.05
    assert metrics['success']


def test_reruns_are_bit_identical(cell):
    scenario = load_scenario(scenario_path('paper_toss'), cell=cell)
    first = run_episode(scenario, cell=cell, duration=2.0).trajectory
    second = run_episode(scenario, cell=cell, duration=2.0).trajectory
    assert first['left_pad_contact'].any()
    for name, values in first.items():
        assert np.array_equal(values, second[name]), name
