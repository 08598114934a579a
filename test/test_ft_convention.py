"""The twin's FT reading and the core's FT compensation use one sign convention."""

from dual_arm_control.core.contact import FtBiasEstimator, FtCompensationConfig
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.scenario import load_scenario, scenario_path
import numpy as np
from sim_bridge.twin import DualArmTwin

FRI_PERIOD = 0.002


def test_compensated_twin_reading_is_zero_free_and_pad_force_when_pressing():
    cell = load_cell()
    scenario = load_scenario(scenario_path('hold'), cell=cell)
    twin = DualArmTwin(scenario, cell, fri_period=FRI_PERIOD)
    config = FtCompensationConfig(bias_duration=0.1)
    models = {arm: arm_model(arm, cell) for arm in twin.arms}
    estimators = {arm: FtBiasEstimator(config) for arm in twin.arms}
    results = {}
    for _ in range(150):
        twin.step({arm: twin.hold_torques(arm) for arm in twin.arms})
        for arm in twin.arms:
            _, R_world_sensor = models[arm].sensor_pose(twin.joint_state(arm).position)
            reading = np.concatenate(twin.ft_wrench_true(arm))
            results[arm] = estimators[arm].update(reading, R_world_sensor, FRI_PERIOD)
    for arm in twin.arms:
        assert results[arm].ready
        np.testing.assert_allclose(results[arm].wrench_world[:3], 0.0, atol=1e-3)
