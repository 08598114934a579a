"""
conveyor_grab in process: the box is grabbed from the moving incoming belt and tossed.

Judged on the twin's ground truth. The belt must really have carried the box (it moved more
than 0.2 m toward -y before the first contact, at the belt's speed), and the arms must have
waited at standby for it (events). Both pads meet it within the 10 ms contact gap at the impact
speed relative to the box within 15 % (the issue's criterion; without the box's velocity fed
forward the pads would be off by the belt speed, 0.2 m/s = 40 %; this nominal run gives 8 ms
and 0.463 / 0.547 m/s, so the gap has 2 ms of margin), the grab leaves it where the belt
would have carried it within 1 cm, and afterwards the box leaves the belt (its bottom 5 cm
above the belt's top, where only the pads hold it) and lands within 5 cm of the toss's
landing point, the paper_toss criterion.
"""

from dual_arm_control.description.cell import load_cell
from dual_arm_control.evaluation.episode import episode_metrics
from dual_arm_control.inprocess import run_episode
from dual_arm_control.scenario import load_scenario
import numpy as np

CELL = load_cell()


def test_box_grabbed_from_the_moving_belt_and_tossed():
    scenario = load_scenario('conveyor_grab', cell=CELL)
    log = run_episode(scenario, cell=CELL)
    data = log.trajectory
    metrics = episode_metrics(scenario, data, CELL)
    events = [event for _, names, _ in log.events for event in names]
    assert events.index('waiting_for_box') < events.index('box_in_range') < \
        events.index('released')
    contact = min(int(np.argmax(data[f'{arm}_pad_contact'])) for arm in ('left', 'right'))
    before = data['object_position'][contact - 1]
    assert before[1] < scenario.object.position[1] - 0.2
    assert abs(data['object_velocity'][contact - 1][1]
               - data['incoming_belt_velocity'][contact - 1][1]) < 0.02
    assert metrics['contact_time_gap'] <= 0.010
    for arm in ('left', 'right'):
        assert abs(metrics[f'impact_speed_relative_{arm}'] - scenario.speeds.impact) <= \
            0.15 * scenario.speeds.impact
    assert metrics['belt_drag'] <= 0.01
    bottom = data['object_position'][:, 2] - 0.5 * scenario.object.size[2]
    assert np.max(bottom[contact:]) > scenario.incoming_belt.belt_top_height + 0.05
    assert metrics['landing_error'] <= 0.05
    assert metrics['success'] is True
