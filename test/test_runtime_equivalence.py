"""
The node graph and the in-process runner are the same episode.

Both are built from the same runtime steps, and the messages between the processes carry the
signals' float64 values unchanged, so a lockstep graph run (`dual_arm_bringup --record`, one
process per node) and an in-process run of the same scenario and seed compute the same numbers:
the ground-truth trajectory and every numeric field of the metrics agree within 1e-9, and the
phase of every DS tick (from /dual_arm/phase in the bag) is the same. Usually they are equal to
the last bit; across processes they need not be, because the vectorised reductions of Eigen
(pinocchio, proxsuite) and BLAS may sum in an order that depends on a buffer's memory alignment
(seen: 6e-15 m after 4 s). With test_inprocess's bit-identical reruns in one process this also
makes the lockstep graph deterministic.
"""

import json
import math

from conftest import SOURCE_ROOT
from diagnostic_msgs.msg import DiagnosticArray
from dual_arm_control import contract
from dual_arm_control.bags.reader import BagReader
from dual_arm_control.description.cell import load_cell
from dual_arm_control.evaluation.episode import episode_metrics
from dual_arm_control.inprocess import run_episode
from dual_arm_control.nodes.messages import stamp_ns
from dual_arm_control.scenario import load_scenario
from dual_arm_control.scenario_writer import scenario_document
from dual_arm_control.trajectory_log import ARM_FIELDS, load_trajectory, OBJECT_FIELDS
from dual_arm_control.trial_sampling import sample_trial
from graph_helpers import record_episode
import numpy as np
import pytest
from rclpy.serialization import deserialize_message
import yaml

pytestmark = pytest.mark.slow
SCENARIOS = SOURCE_ROOT / 'config' / 'scenarios'
EPISODE_TIMEOUT = 240
TRAJECTORY_FIELDS = ['t', *OBJECT_FIELDS, *(f'{arm}_{name}' for arm in contract.ARMS
                                            for name in ARM_FIELDS)]
TOLERANCE = 1e-9


@pytest.fixture(scope='module')
def cell():
    return load_cell()


def bag_phases(bag):
    """
    Return [(stamp [s], phase)] of the /dual_arm/phase messages of a bag, one per DS tick.

    A tick the bridge republished in lockstep (no answer within its republish period, e.g.
    while the motion generator checks the grasp's reachability) is answered again with the
    same message; it is counted once.
    """
    phases = []
    for message in BagReader(bag).messages([contract.PHASE.name]):
        msg = deserialize_message(message.data, DiagnosticArray)
        entry = (stamp_ns(msg.header.stamp) * 1e-9, msg.status[0].message)
        if not phases or phases[-1] != entry:
            phases.append(entry)
    return phases


def numeric_fields(metrics, prefix=''):
    """Return {dotted key: number} of every numeric leaf of a metrics dict (lists indexed)."""
    fields = {}
    for key, value in metrics.items():
        name = f'{prefix}{key}'
        if isinstance(value, bool) or value is None or isinstance(value, str):
            continue
        if isinstance(value, (int, float)):
            fields[name] = float(value)
        elif isinstance(value, list):
            fields.update(numeric_fields(dict(enumerate(value)), f'{name}.'))
    return fields


def assert_same_episode(scenario, graph_dir, duration, cell):
    """Compare the graph run in graph_dir with an in-process run of the same scenario."""
    inprocess = run_episode(scenario, cell=cell, duration=duration)
    graph = load_trajectory(graph_dir / 'trajectory.npz')
    for name in TRAJECTORY_FIELDS:
        assert graph[name].shape == inprocess.trajectory[name].shape, name
        difference = np.abs(graph[name].astype(float) - inprocess.trajectory[name])
        assert difference.max(initial=0.0) <= TOLERANCE, (
            f'{name} differs by up to {difference.max():.3g}')
    graph_metrics = json.loads((graph_dir / 'metrics.json').read_text())
    inprocess_metrics = json.loads(json.dumps(episode_metrics(
        scenario, inprocess.trajectory, cell, events=inprocess.events)))
    graph_numbers = numeric_fields(graph_metrics)
    inprocess_numbers = numeric_fields(inprocess_metrics)
    assert graph_numbers.keys() == inprocess_numbers.keys()
    for key, value in graph_numbers.items():
        assert math.isclose(value, inprocess_numbers[key], rel_tol=0.0, abs_tol=TOLERANCE), key
    assert graph_metrics['success'] == inprocess_metrics['success']
    phases = bag_phases(graph_dir / 'bag.mcap')
    assert len(phases) > 0.9 * duration / 0.005
    assert phases == inprocess.phases
    return graph_metrics


def test_paper_toss_in_the_graph_is_the_in_process_episode(tmp_path, cell):
    """The README's main job: task criteria met, and the same episode as in-process."""
    scenario_file = SCENARIOS / 'paper_toss.yaml'
    out = tmp_path / 'paper_toss'
    scenario = load_scenario(scenario_file, cell=cell)
    record_episode(scenario_file, out, scenario.duration, EPISODE_TIMEOUT)
    m = assert_same_episode(scenario, out, scenario.duration, cell)
    assert m['contact_time_gap'] <= 0.010
    for arm in contract.ARMS:
        assert m[f'impact_speed_along_direction_{arm}'] == pytest.approx(0.5, rel=0.15)
    assert m['max_slip'] <= 0.01
    assert m['release_position_error'] <= 0.03
    assert m['release_velocity_error'] <= 0.10
    assert m['landing_prediction_error'] <= 0.05
    assert m['success']
    for name in ('tool_speeds.png', 'object_motion.png', 'trajectories_3d.png'):
        assert (out / name).stat().st_size > 10_000


def test_a_randomized_trial_in_the_graph_is_the_in_process_episode(tmp_path, cell):
    """One trial of paper_toss_random (its own pose, mass and sensor seed), first 2.5 s."""
    trial = sample_trial(load_scenario(SCENARIOS / 'paper_toss_random.yaml', cell=cell), 3,
                         cell)
    trial_file = tmp_path / 'trial.yaml'
    trial_file.write_text(yaml.safe_dump(scenario_document(trial), sort_keys=False))
    out = tmp_path / 'trial'
    duration = 2.5
    record_episode(trial_file, out, duration, EPISODE_TIMEOUT)
    m = assert_same_episode(load_scenario(trial_file, cell=cell), out, duration, cell)
    assert m['t_grasp'] is not None, 'the short run must include the grasp'
