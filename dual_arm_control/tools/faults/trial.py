"""
One trial of the fault campaign: its scenario, its fault-free timing, where it writes.

Trial i of a campaign is trial i of the randomized template (trial_sampling.sample_trial:
object pose, yaw, mass and its own sensor seed), so every trial has a different seed and is
reproducible from (template seed, i). The fault is placed on the trial's own fault-free episode,
run first in-process (the same episode as the lockstep graph, test_runtime_equivalence): the
sim times of its reach, first contact and carry.
"""

from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

from dual_arm_control.contract import ARMS
from dual_arm_control.core.exceptions import DualArmControlError
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.evaluation.episode import episode_metrics
from dual_arm_control.evaluation.trials import write_trial_scenario
from dual_arm_control.graph import EPISODE_START_TIME
from dual_arm_control.inprocess import run_episode
from dual_arm_control.scenario import load_scenario
from dual_arm_control.tools.faults.outcome import fill_from_trajectory, TrialOutcome
from dual_arm_control.trajectory_log import load_trajectory
from dual_arm_control.trial_sampling import sample_trial
import numpy as np

TEMPLATE = 'paper_toss_random'
# Largest |tau| difference [N m] of an episode that is still the fault-free one.
TORQUE_TOLERANCE = 1e-9


@lru_cache(maxsize=1)
def cell():
    """Return the cell description (loaded once)."""
    return load_cell()


@lru_cache(maxsize=1)
def torque_limits():
    """Return {arm: (7,) joint torque limits [N m]} of the robot models."""
    return {arm: arm_model(arm, cell()).torque_limits for arm in ARMS}


@dataclass
class Trial:
    """A trial: index, scenario, its fault-free metrics, output folder and ROS domain."""

    index: int
    scenario: object
    nominal: dict
    out_dir: Path
    domain: int = 0

    @property
    def seed(self):
        """Return the trial's sensor seed."""
        return int(self.scenario.seed)

    def stage_time(self, stage):
        """
        Return the sim time [s] of a stage of the fault-free episode, or None if it has none.

        reach: halfway from the start to the first contact; impact: the first contact; carry:
        halfway from the grasp to the release.
        """
        contacts = [self.nominal[f't_contact_{arm}'] for arm in ARMS
                    if self.nominal.get(f't_contact_{arm}') is not None]
        if not contacts:
            return None
        if stage == 'reach':
            return EPISODE_START_TIME + 0.5 * min(contacts)
        if stage == 'impact':
            return EPISODE_START_TIME + min(contacts)
        grasp, release = self.nominal.get('t_grasp'), self.nominal.get('t_release')
        if grasp is None or release is None:
            return None
        return EPISODE_START_TIME + 0.5 * (grasp + release)

    @property
    def release_time(self):
        """Return the sim time [s] of the fault-free episode's release, or None."""
        release = self.nominal.get('t_release')
        return None if release is None else EPISODE_START_TIME + release

    def with_mocap(self, **fields):
        """Return the trial's scenario with these sensors.mocap fields changed."""
        sensors = self.scenario.sensors
        return replace(self.scenario, sensors=replace(sensors, mocap=replace(sensors.mocap,
                                                                             **fields)))

    def scenario_file(self, scenario=None):
        """Write the (given or own) scenario into the trial folder; return its path."""
        path = self.out_dir / 'scenario.yaml'
        write_trial_scenario(scenario or self.scenario, path, TEMPLATE, self.index)
        return path


def run_inprocess(scenario):
    """Run a scenario in-process; return (metrics, trajectory)."""
    trajectory = run_episode(scenario, cell=cell()).trajectory
    return episode_metrics(scenario, trajectory, cell()), trajectory


@lru_cache(maxsize=256)
def _nominal(template, index):
    scenario = sample_trial(load_scenario(template, cell=cell()), index, cell=cell())
    return scenario, run_inprocess(scenario)[0]


def prepare_trial(index, out_dir, domain=0, template=TEMPLATE):
    """Return Trial number index of the template, with its fault-free metrics."""
    scenario, nominal = _nominal(template, index)
    return Trial(index, scenario, nominal, Path(out_dir), domain)


def measure_graph_episode(outcome, trajectory_file, trial, dead_arms=()):
    """Fill an outcome from a graph run's trajectory log: safety fields and task success."""
    try:
        data = load_trajectory(trajectory_file)
    except DualArmControlError as error:
        outcome.held, outcome.note = False, f'{outcome.note}; no trajectory: {error}'
        return outcome
    outcome = fill_from_trajectory(outcome, data, torque_limits(), dead_arms, outcome.fault_time,
                                   trial.release_time)
    if not dead_arms:
        outcome.recovered = bool(episode_metrics(trial.scenario, data, cell())['success'])
    return outcome


def skipped(kind, trial, why):
    """Return the outcome of a trial that is not run, and why."""
    return TrialOutcome(kind, trial.index, trial.seed, note=f'skipped: {why}')


def torque_deviation(trajectory_file, trial):
    """
    Return the largest |tau| difference [N m] of a graph run from the trial's fault-free episode.

    The fault-free episode runs in-process (the lockstep graph's episode to 1e-9); inf if the
    logs differ in length or the graph run left none.
    """
    try:
        data = load_trajectory(trajectory_file)
    except DualArmControlError:
        return np.inf
    nominal = run_inprocess(trial.scenario)[1]
    deviation = 0.0
    for arm in ARMS:
        graph, fault_free = np.asarray(data[f'{arm}_tau'], float), nominal[f'{arm}_tau']
        if graph.shape != fault_free.shape:
            return np.inf
        deviation = max(deviation, float(np.abs(graph - fault_free).max(initial=0.0)))
    return deviation


def judge_same_episode(outcome, trajectory_file, trial, exits, stalled_at, note):
    """
    Fill the outcome of a graph trial whose episode must be the fault-free one; return it.

    exits: {label: exit code} of the graph's nodes; stalled_at: the sim time [s] the graph
    stalled at, or None; note: what was injected. Held: no node exit, no stall, the safety
    fields kept and the torques within TORQUE_TOLERANCE of the fault-free episode.
    """
    outcome.node_exits = sum(1 for label, code in exits.items()
                             if (label, code) != ('sim_bridge', 0))
    outcome = measure_graph_episode(outcome, trajectory_file, trial)
    deviation = torque_deviation(trajectory_file, trial)
    outcome.note = f'{note}; max |tau - fault-free tau| {deviation:.3g} N m'
    if stalled_at is not None:
        outcome.note += f'; graph stalled at {stalled_at:.3f} s'
    outcome.held = (outcome.held and outcome.node_exits == 0 and stalled_at is None
                    and deviation <= TORQUE_TOLERANCE)
    return outcome
