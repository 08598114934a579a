"""
Experiment catalogue_grasps: every catalogue box at its mass, centred, tossed and placed.

Each box of config/objects.yaml replaces the paper cube of paper_toss and paper_place (same
pose, its own size, mass and friction) and runs through the node graph (dual_arm_bringup,
lockstep, topics recorded). Per run: the outcome and the slip (metrics.json), and how much of
the friction cone the pads use while they hold the box (CONTACT and MANIPULATE), twice:
- planned: the wrench QP's pad wrenches (the contact_wrench topics), tangential over normal
  force in the pad's frame against the QP's design friction (its pyramid, eq. 10, allows
  1 / sqrt 2 ~ 0.71 along one tangent, 1 at its corners) and against the box's own friction;
- measured: the MuJoCo contact force of each pad on the box against the box's friction, its
  worst and its 95th percentile over the samples (the worst falls in the impact and release
  transients).
A ratio below 1 is inside the cone; 1 - ratio is the margin left.
"""

from pathlib import Path
import tempfile
import time

from dual_arm_control import contract
from dual_arm_control.bags.reader import BagReader
from dual_arm_control.catalogue import load_catalogue
from dual_arm_control.core.arms import ARMS
from dual_arm_control.core.wrench_qp import WrenchQPConfig
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.evaluation.experiment_runs import (ExperimentError, results_header,
                                                         run_graph_episode, write_results)
from dual_arm_control.scenario import scenario_path
from dual_arm_control.tools.episode_bag import decoded_messages
import numpy as np

TASKS = ('paper_toss', 'paper_place')
GRASP_PHASES = ('contact', 'manipulate')
# Pads pressing less than this are not holding the box (the ramp in, the release) [N].
HOLDING_FORCE = 5.0


def friction_ratio(force_world, normal_world, friction):
    """
    Return |f_t| / (mu f_n) of a pad force (3,) [N] on its face, inward normal (3,) unit.

    Below 1 the force lies inside the Coulomb cone of coefficient friction; inf if the pad
    pulls (f_n <= 0).
    """
    force_world = np.asarray(force_world, dtype=float)
    normal_world = np.asarray(normal_world, dtype=float)
    normal_force = float(force_world @ normal_world)
    if normal_force <= 0.0:
        return float('inf')
    tangential = force_world - normal_force * normal_world
    return float(np.linalg.norm(tangential)) / (friction * normal_force)


def grasp_scenario_text(base_text, object_type):
    """Return the YAML of a base scenario with its box replaced by a catalogue type."""
    lines = base_text.splitlines()
    replaced = [line.replace('type: paper_cube', f'type: {object_type}', 1)
                if line.strip().startswith('type: paper_cube') else line for line in lines]
    if replaced == lines and object_type != 'paper_cube':
        raise ExperimentError('the base scenario names no paper_cube type to replace')
    return '\n'.join(replaced) + '\n'


def run_catalogue_grasps(out_dir, limit=None, timeout=600.0):
    """Run every catalogue box (the first limit) tossed and placed; write results.json."""
    started = time.monotonic()
    cell = load_cell()
    models = {arm: arm_model(arm, cell) for arm in ARMS}
    catalogue = load_catalogue()
    names = sorted(catalogue)[:limit]
    qp_friction = WrenchQPConfig().friction_coefficient
    runs = []
    with tempfile.TemporaryDirectory(prefix='catalogue_grasps_') as tmp:
        for name in names:
            for task in TASKS:
                folder = Path(tmp) / f'{name}_{task}'
                folder.mkdir()
                scenario = folder / 'scenario.yaml'
                scenario.write_text(grasp_scenario_text(
                    scenario_path(task).read_text(), name))
                metrics = run_graph_episode(scenario, folder, timeout, record=True)
                friction = catalogue[name].friction
                planned = _planned_ratios(folder, models, qp_friction, friction)
                measured = _measured_ratios(folder / 'trajectory.npz', models, friction)
                runs.append({'object': name, 'task': task, 'mass': catalogue[name].mass,
                             'friction': friction, 'success': metrics['success'],
                             'max_slip': metrics['max_slip'],
                             'contact_time_gap': metrics['contact_time_gap'],
                             'place_position_error': metrics['place_position_error'],
                             'landing_error': metrics['landing_error'], **planned, **measured})
    results = results_header('catalogue_grasps', 'dual_arm_bringup (node graph, lockstep)',
                             started, limit)
    results.update({'qp_friction_coefficient': qp_friction, 'runs': runs})
    write_results(out_dir, results)
    return results


def _planned_ratios(folder, models, qp_friction, friction):
    """Return the QP's worst friction ratios over the grasp, from the run's recorded bag."""
    reader = BagReader(folder / 'bag.mcap')
    joints = {contract.JOINT_STATES.resolved(arm): arm for arm in ARMS}
    wrenches = {contract.CONTACT_WRENCH.resolved(arm): arm for arm in ARMS}
    latest_q, phase = {}, None
    design = actual = 0.0
    for topic, msg, _ in decoded_messages(reader, [contract.PHASE.name, *joints, *wrenches]):
        if topic == contract.PHASE.name:
            phase = next((status.message for status in msg.status
                          if status.name == contract.PHASE_STATUS_NAME), phase)
        elif topic in joints:
            latest_q[joints[topic]] = np.array(msg.position[:7])
        elif phase in GRASP_PHASES and wrenches[topic] in latest_q:
            arm = wrenches[topic]
            force = np.array([msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z])
            normal = models[arm].tool_pose(latest_q[arm])[1][:, 2]
            if force @ normal < HOLDING_FORCE:
                continue
            design = max(design, friction_ratio(force, normal, qp_friction))
            actual = max(actual, friction_ratio(force, normal, friction))
    return {'planned_friction_ratio_design': design, 'planned_friction_ratio': actual}


def _measured_ratios(path, models, friction):
    """Return the pads' MuJoCo contact forces' friction ratios (worst, p95) while both press."""
    ratios = []
    with np.load(path) as data:
        for index in np.flatnonzero(data['left_pad_contact'] & data['right_pad_contact']):
            for arm in ARMS:
                normal = models[arm].tool_pose(data[f'{arm}_q'][index])[1][:, 2]
                force = data[f'{arm}_pad_force'][index]
                if force @ normal >= HOLDING_FORCE:
                    ratios.append(friction_ratio(force, normal, friction))
    if not ratios:
        return {'measured_friction_ratio': None, 'measured_friction_ratio_p95': None}
    return {'measured_friction_ratio': max(ratios),
            'measured_friction_ratio_p95': float(np.percentile(ratios, 95))}
