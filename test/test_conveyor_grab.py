"""
The grab from the incoming belt, piece by piece.

The moving-grab rules, the grab metrics, the scenario and its draws, and the twin's belt
carrying a box by friction.
"""

from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.core.moving_grab import (belt_feed_forward, decayed_belt_velocity,
                                               filtered_belt_velocity, grab_wait_reason,
                                               MovingGrabConfig, predicted_box_position)
from dual_arm_control.description.cell import load_cell
from dual_arm_control.evaluation.grab_metrics import (belt_drag, grab_metrics,
                                                      grab_succeeded, relative_impact_speed)
from dual_arm_control.runtime.configuration import motion_config_for_scenario
from dual_arm_control.scenario import load_scenario
from dual_arm_control.trial_sampling import sample_trial
import numpy as np
import pytest
from sim_bridge.twin import DualArmTwin

CELL = load_cell()
DT = 0.005


def test_feed_forward_adds_the_belt_velocity_to_both_tools():
    relative = np.array([[0.0, -0.5, 0.0], [0.0, 0.5, 0.0]])
    belt = np.array([0.0, -0.2, 0.0])
    velocity = belt_feed_forward(relative, belt)
    # Relative to the box, each tool closes at the DS's speed.
    assert np.allclose(velocity - belt, relative)
    assert np.allclose(velocity, [[0.0, -0.7, 0.0], [0.0, 0.3, 0.0]])
    # The tracking gain scales the whole command that moves with the box.
    assert np.allclose(belt_feed_forward(relative, belt, 1.06), 1.06 * velocity)


def test_belt_velocity_filter_converges_to_the_horizontal_velocity():
    belt = np.zeros(3)
    box = np.array([0.01, -0.25, 0.3])
    for _ in range(200):                         # 1 s at 200 Hz, ten time constants
        belt = filtered_belt_velocity(belt, box, DT, 0.1)
    assert np.allclose(belt, [0.01, -0.25, 0.0], atol=1e-4)
    one_tick = filtered_belt_velocity(np.zeros(3), box, DT, 0.1)
    assert one_tick[1] == pytest.approx(-0.25 * (1.0 - np.exp(-DT / 0.1)))


def test_carried_belt_velocity_fades_with_its_time_constant():
    velocity = np.array([0.0, -0.2, 0.0])
    for _ in range(30):                          # 0.15 s: one time constant
        velocity = decayed_belt_velocity(velocity, DT, 0.15)
    assert velocity[1] == pytest.approx(-0.2 * np.exp(-1.0))


def test_reach_waits_until_the_box_is_predicted_in_the_grab_range():
    config = MovingGrabConfig(enabled=True, reach_duration=1.5, grab_y_range=(-0.05, 0.02))
    velocity = np.array([0.0, -0.2, 0.05])       # the vertical part is not the belt's
    far = predicted_box_position([0.41, 0.40, 0.33], velocity, config.reach_duration)
    assert far == pytest.approx([0.41, 0.10, 0.33])
    assert 'outside the grab range' in grab_wait_reason(far, config)
    near = predicted_box_position([0.41, 0.30, 0.33], velocity, config.reach_duration)
    assert grab_wait_reason(near, config) == ''
    with pytest.raises(ConfigError):
        MovingGrabConfig(grab_y_range=(0.1, -0.1))


def test_relative_impact_speed_subtracts_the_box_velocity():
    tool = np.array([[0.0, -0.7, 0.0], [0.0, -0.69, 0.0]])
    box = np.array([0.0, -0.2, 0.0])
    assert relative_impact_speed(tool, box, 1, [0.0, -1.0, 0.0]) == pytest.approx(0.5)
    assert relative_impact_speed(tool, box, 0, [0.0, -1.0, 0.0]) is None
    assert relative_impact_speed(tool, None, 1, [0.0, -1.0, 0.0]) is None


def _grab_log(box_speed, belt_speed=-0.2, samples=11, dt=0.002):
    """Return a log where the box moves at box_speed, the belt at belt_speed (world y)."""
    t = dt * np.arange(samples)
    position = np.zeros((samples, 3))
    position[:, 1] = box_speed * t
    return t, position, np.tile([0.0, belt_speed, 0.0], (samples, 1))


def test_belt_drag_is_the_box_motion_relative_to_the_belt():
    t, carried, belt = _grab_log(-0.2)
    assert belt_drag(t, carried, belt, 0, 10) == pytest.approx(0.0, abs=1e-12)
    t, stopped, belt = _grab_log(0.0)
    assert belt_drag(t, stopped, belt, 0, 10) == pytest.approx(0.2 * 0.02)
    t, pushed, belt = _grab_log(0.3)
    assert belt_drag(t, pushed, belt, 0, 10) == pytest.approx(0.5 * 0.02)
    assert belt_drag(t, pushed, belt, None, 10) is None


def test_grab_metrics_and_criteria():
    t, position, belt = _grab_log(-0.2)
    contact = {'left': 4, 'right': 6}
    left, right = np.zeros(11, bool), np.zeros(11, bool)
    left[4:], right[6:] = True, True
    data = {'t': t, 'object_position': position, 'incoming_belt_velocity': belt,
            'object_velocity': np.tile([0.0, -0.2, 0.0], (11, 1)),
            'left_tool_velocity': np.tile([0.0, -0.7, 0.0], (11, 1)),
            'right_tool_velocity': np.tile([0.0, 0.3, 0.0], (11, 1)),
            'left_pad_contact': left, 'right_pad_contact': right}
    directions = {'left': [0.0, -1.0, 0.0], 'right': [0.0, 1.0, 0.0]}
    result = grab_metrics(data, contact, directions)
    assert result['impact_speed_relative_left'] == pytest.approx(0.5)
    assert result['impact_speed_relative_right'] == pytest.approx(0.5)
    assert result['belt_drag'] == pytest.approx(0.0, abs=1e-12)
    assert grab_succeeded(result, 0.5)
    assert not grab_succeeded(result, 0.4)            # 25 % above the desired speed
    assert not grab_succeeded({**result, 'belt_drag': 0.011}, 0.5)


def test_conveyor_grab_scenario_and_its_draws():
    scenario = load_scenario('conveyor_grab', cell=CELL)
    belt = scenario.incoming_belt
    assert belt is not None and scenario.conveyor is None
    assert scenario.object.position[2] == pytest.approx(belt.belt_top_height + 0.1)
    assert motion_config_for_scenario(scenario, CELL).moving_grab.enabled
    assert not motion_config_for_scenario(load_scenario('paper_toss', cell=CELL),
                                          CELL).moving_grab.enabled
    speeds, starts = [], []
    for index in range(40):
        trial = sample_trial(scenario, index, cell=CELL)
        speeds.append(trial.incoming_belt.speed)
        starts.append(trial.incoming_belt.start_time)
        # Off the pallet, the box still rests on the belt.
        assert trial.object.position[2] == pytest.approx(scenario.object.position[2])
    assert 0.1 <= min(speeds) < 0.15 and 0.25 < max(speeds) <= 0.3
    assert 0.3 <= min(starts) and max(starts) <= 1.0


def test_a_moving_grab_times_its_pads_by_the_commanded_speeds_alone():
    """The tools' measured speeds carry the belt's: no lag term (a still box keeps its own)."""
    moving = motion_config_for_scenario(load_scenario('conveyor_grab', cell=CELL), CELL)
    still = motion_config_for_scenario(load_scenario('paper_toss', cell=CELL), CELL)
    assert moving.arrival_synchroniser()[1].lag == 0.0
    assert still.arrival_synchroniser()[1].lag == still.impact.synchronisation_lag > 0.0


def test_incoming_belt_carries_the_box_at_its_speed():
    scenario = load_scenario('conveyor_grab', cell=CELL)
    twin = DualArmTwin(scenario, CELL)
    start_y = twin.object_pose()[0][1]
    while twin.time < scenario.incoming_belt.start_time + 0.5:
        twin.step({arm: twin.hold_torques(arm) for arm in ('left', 'right')})
    belt = twin.incoming_belt
    position = twin.object_pose()[0]
    # Friction has brought the box to the belt's speed: it moved 0.5 s at about 0.2 m/s +-20 %
    # toward -y, stayed on the belt's top and did not leave its line.
    assert -0.13 < position[1] - start_y < -0.07
    assert position[2] == pytest.approx(scenario.object.position[2], abs=0.002)
    assert position[0] == pytest.approx(scenario.object.position[0], abs=0.002)
    assert belt.velocity == pytest.approx(-belt.belt.at(twin.time), abs=0.01)
    assert twin.object_twist()[0] == pytest.approx(belt.surface_velocity(), abs=0.01)
    # The slab itself stays in place: only its surface moves.
    joint = twin.model.joint('incoming_belt')
    assert twin.data.qpos[joint.qposadr[0]] == pytest.approx(0.0, abs=1e-3)
    twin.set_incoming_belt_speed(0.0)
    later = twin.time + 0.3
    while twin.time < later:
        twin.step({arm: twin.hold_torques(arm) for arm in ('left', 'right')})
    stopped = twin.object_pose()[0][1]
    twin.step({arm: twin.hold_torques(arm) for arm in ('left', 'right')})
    assert twin.object_pose()[0][1] == pytest.approx(stopped, abs=1e-4)
