"""
The twin's injected mocap faults: a dropout window loses exactly its samples, an outlier jumps.

The fault campaign (dual_arm_faults) places a marker occlusion at the impact and a 10 cm jump of
one sample; both must be exactly what the scenario asks, and nothing else may change.
"""

from dataclasses import replace

from dual_arm_control.scenario import load_scenario
from dual_arm_control.tools.faults.outcome import premature_drop
import numpy as np
import pytest
from sim_bridge.twin import DualArmTwin

DURATION = 0.3


def mocap_samples(**mocap_fields):
    """Return {stamp index: position} of the samples a held twin delivers in DURATION."""
    scenario = load_scenario('paper_toss')
    scenario = replace(scenario, sensors=replace(scenario.sensors, mocap=replace(
        scenario.sensors.mocap, **mocap_fields)))
    twin = DualArmTwin(scenario)
    rate = scenario.sensors.mocap.rate_hz
    samples = {}
    while twin.time < DURATION - 1e-9:
        twin.step({arm: twin.hold_torques(arm) for arm in twin.arms})
        for sample in twin.mocap_samples():
            samples[round(sample.stamp * rate)] = sample.p_world
    return samples


def test_a_dropout_window_loses_exactly_its_samples():
    nominal = mocap_samples()
    occluded = mocap_samples(dropout_start=0.1, dropout_duration=0.05)
    lost = sorted(set(nominal) - set(occluded))
    assert lost == list(range(20, 30)), lost
    assert set(occluded) <= set(nominal)
    for index, position in occluded.items():
        np.testing.assert_array_equal(position, nominal[index])


def test_an_outlier_moves_one_sample_along_the_squeeze_axis():
    nominal = mocap_samples()
    jumped = mocap_samples(outlier_time=0.1, outlier_jump=0.1)
    assert set(jumped) == set(nominal)
    moved = {index: jumped[index] - nominal[index] for index in nominal
             if not np.array_equal(jumped[index], nominal[index])}
    assert list(moved) == [20]
    np.testing.assert_allclose(moved[20], [0.0, 0.1, 0.0], atol=1e-12)


@pytest.mark.parametrize('field, value', [('dropout_duration', -0.1), ('outlier_jump', 2.0)])
def test_fault_fields_out_of_range_are_refused(field, value):
    from dual_arm_control.core.exceptions import ConfigError
    from dual_arm_control.sensor_models import MocapConfig
    with pytest.raises(ConfigError, match=field):
        MocapConfig(**{field: value})


def test_a_box_has_left_the_pads_after_10_ms_without_a_pad_on_it():
    """A one-cycle chatter of both pads is no drop; a box that falls free is, by its fall."""
    t = np.arange(0.0, 1.0, 0.002)
    heights = np.full(t.size, 0.32)
    contact = t < 0.8
    contact[100] = False
    heights[400:] = 0.45
    heights[450:] = 0.45 - (t[450:] - t[450]) * 0.5
    data = {'t': t, 'object_position': np.column_stack((np.zeros(t.size), np.zeros(t.size),
                                                        heights)),
            'left_pad_contact': contact.copy(), 'right_pad_contact': contact.copy()}
    assert premature_drop(data, 0.1, release_time=0.8) == (None, 0.0)
    start, fall = premature_drop(data, 0.3, release_time=0.95)
    assert start == pytest.approx(0.8)
    assert fall == pytest.approx(0.45 - heights[-1])
    assert premature_drop(data, 0.3, release_time=0.8) == (None, 0.0)
