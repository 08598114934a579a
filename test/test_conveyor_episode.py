"""
conveyor_toss in process: the box lands in the container the belt carries, and stays in it.

Judged on the twin's ground truth, not on the controller's beliefs. At the end of the run the
box must rest on the container's floor between its walls: its centre at most half the free
play from the container's centre (opening 0.30 x 0.20 m minus the 0.16 m cube: 7 cm across the
belt, 2 cm along it), plus 5 mm for the softness of the wall contacts and a small yaw, and its
centre half its height above the floor (5 mm: the contact penetration is about 1 mm); and it
must move with the container, at the belt's speed. The container has moved by then (it was
not waiting for the box), and the arms waited at standby before throwing.
"""

from dual_arm_control.description.cell import load_cell
from dual_arm_control.evaluation.episode import episode_metrics
from dual_arm_control.inprocess import run_episode
from dual_arm_control.scenario import load_scenario
import numpy as np

CELL = load_cell()
CONTACT_SLACK = 0.005


def test_box_lands_in_the_moving_container():
    scenario = load_scenario('conveyor_toss', cell=CELL)
    log = run_episode(scenario, cell=CELL)
    data = log.trajectory
    conveyor, box = scenario.conveyor, scenario.object.size
    relative = data['object_position'][-1] - data['container_position'][-1]
    free_play = 0.5 * (np.asarray(conveyor.inner_size) - box[:2])
    assert np.all(np.abs(relative[:2]) <= free_play + CONTACT_SLACK), relative
    assert abs(relative[2] - 0.5 * box[2]) <= CONTACT_SLACK
    assert np.linalg.norm(data['object_velocity'][-1] - data['container_velocity'][-1]) < 0.02
    assert data['container_velocity'][-1][1] < -0.1
    assert data['container_position'][-1][1] < conveyor.container_start - 0.5
    events = [event for _, names, _ in log.events for event in names]
    assert events.index('waiting_for_container') < events.index('container_in_range') < \
        events.index('released')
    metrics = episode_metrics(scenario, data, CELL)
    assert metrics['landed_in_container'] is True
    assert metrics['success'] is True
    assert metrics['landing_error_in_container'] <= 0.03
