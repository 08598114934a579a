"""
Single-process episode runner: the twin and the whole controller pipeline in one loop.

Runs the same core objects the nodes wrap, at the graph's rates (FRI period for the torque
controllers, 200 Hz for tracker-to-DS and the wrench QP), with the same one-way information
flow. For tuning, benchmarks and fast tests; the product runs the nodes
(`dual_arm_bringup`). Deterministic for a given scenario and seed.
"""

from contextlib import contextmanager, nullcontext
from dataclasses import dataclass, field
import time

from dual_arm_control.contract import ARMS
from dual_arm_control.core.geometry import quat_xyzw_to_matrix
from dual_arm_control.core.motion_generator import (ArmMeasurement, DualArmMotionGenerator,
                                                    ObjectMeasurement)
from dual_arm_control.core.passive_control import PassiveController, PassiveControllerConfig
from dual_arm_control.core.tracker import ObjectTracker, TrackerConfig
from dual_arm_control.core.wrench_distribution import WrenchDistributor, WrenchDistributorConfig
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.evaluation.trajectory import TrajectoryRecorder
from dual_arm_control.graph import EPISODE_START_TIME
from dual_arm_control.runtime.configuration import motion_config_for_scenario
from dual_arm_control.runtime.timing import seconds_to_ns, TickSchedule
import numpy as np
from sim_bridge.twin import DualArmTwin


@dataclass(frozen=True)
class RunnerConfig:
    """Rates and component configs of an in-process run (periods in seconds)."""

    fri_period: float = 0.002
    ds_period: float = 0.005
    start_time: float = EPISODE_START_TIME
    motion_base: object = None
    controller: PassiveControllerConfig = field(default_factory=PassiveControllerConfig)
    wrench: WrenchDistributorConfig = field(default_factory=WrenchDistributorConfig)
    tracker: TrackerConfig = field(default_factory=TrackerConfig)


@dataclass
class EpisodeLog:
    """What an in-process run produced: ground truth and the phase at every DS tick."""

    trajectory: dict
    phases: list = field(default_factory=list)


class StageTimer:
    """Wall time of each stage of the loop, one sample per call: {stage: [seconds]}."""

    def __init__(self):
        self.samples = {}

    @contextmanager
    def stage(self, name):
        """Time the block as one sample of stage name."""
        started = time.perf_counter()
        yield
        self.samples.setdefault(name, []).append(time.perf_counter() - started)


class _NoTimer:
    """The default: stages are not timed."""

    def stage(self, name):
        """Return a context that does nothing."""
        return nullcontext()


def run_episode(scenario, config=None, cell=None, duration=None, timer=None):
    """
    Run one episode of scenario and return its EpisodeLog.

    timer (a StageTimer) collects the wall time of each node's work per call: 'tracker' (the
    cycle's samples and the estimate), 'ds' (measurements and the motion generator step), 'qp'
    (the wrench distribution), 'controller' (one arm's torque) and 'bridge_step' (the twin).
    """
    timer = _NoTimer() if timer is None else timer
    config = RunnerConfig() if config is None else config
    cell = load_cell() if cell is None else cell
    twin = DualArmTwin(scenario, cell, fri_period=config.fri_period)
    models = {arm: arm_model(arm, cell) for arm in ARMS}
    controllers = {arm: PassiveController(models[arm], cell.arm(arm).q_home, config.controller)
                   for arm in ARMS}
    motion_config = motion_config_for_scenario(scenario, cell, config.motion_base)
    generator = DualArmMotionGenerator(motion_config)
    distributor = WrenchDistributor(config.wrench, scenario.object.mass, scenario.object.size)
    tracker = ObjectTracker(config.tracker)
    recorder = TrajectoryRecorder()
    log = EpisodeLog(trajectory={})
    duration = scenario.duration if duration is None else duration
    schedule = TickSchedule(config.ds_period)
    output = None
    wrenches = {arm: np.zeros(6) for arm in ARMS}
    torques = {arm: np.zeros(7) for arm in ARMS}
    started = False
    while twin.time < duration - 1e-9:
        t = twin.time
        joints = {arm: twin.joint_state(arm) for arm in ARMS}
        t_ns = seconds_to_ns(t)
        due = schedule.due(t_ns)
        with timer.stage('tracker'):
            for sample in twin.mocap_samples():
                tracker.update(sample.stamp, sample.p_world, sample.quat_xyzw)
            estimate = tracker.state(t) if due else None
        if due:
            dt = schedule.take(t_ns)
            if estimate is not None:
                start = not started and t >= config.start_time - 1e-9
                started = started or start
                output, wrenches = _ds_tick(generator, distributor, models, joints, twin,
                                            estimate, dt, start, timer)
                log.phases.append((t, output.phase.phase.value))
        for arm in ARMS:
            if output is None:
                torques[arm] = twin.hold_torques(arm)
                continue
            command = output.commands[arm]
            with timer.stage('controller'):
                result = controllers[arm].torque_command(
                    joints[arm].position, joints[arm].velocity, command.v_world,
                    command.w_world, command.R_world_desired, wrenches[arm])
            torques[arm] = result.torque
        with timer.stage('bridge_step'):
            report = twin.step(torques)
        recorder.counters['torque_clamp_count'] += sum(report.clamped.values())
        recorder.append(twin, torques)
    log.trajectory = recorder.arrays()
    return log


def _ds_tick(generator, distributor, models, joints, twin, estimate, dt, start, timer):
    """Run the DS and the wrench QP for one 200 Hz tick; return (MotionOutput, wrenches)."""
    with timer.stage('ds'):
        output, p_tools, R_tools, R_object = _motion_step(generator, models, joints, twin,
                                                          estimate, dt, start)
    with timer.stage('qp'):
        distributed = distributor.step(
            output.phase.phase, p_tools, R_tools, estimate.position, R_object,
            estimate.linear_velocity, estimate.angular_velocity, output.object_velocity,
            output.object_angular_velocity, dt)
    return output, distributed.wrenches


def _motion_step(generator, models, joints, twin, estimate, dt, start):
    """Build the DS node's measurements and step it; return (output, tool poses, R_object)."""
    arms = {}
    p_tools, R_tools = {}, {}
    for arm in ARMS:
        q = joints[arm].position
        p_tools[arm], R_tools[arm] = models[arm].tool_pose(q)
        _, R_world_sensor = models[arm].sensor_pose(q)
        force, torque = twin.ft_wrench(arm)
        arms[arm] = ArmMeasurement(p_tools[arm], R_tools[arm], np.concatenate((force, torque)),
                                   R_world_sensor)
    R_object = quat_xyzw_to_matrix(estimate.quat_xyzw)
    obj = ObjectMeasurement(estimate.position, R_object, estimate.linear_velocity)
    output = generator.step(arms, obj, dt, start_episode=start)
    return output, p_tools, R_tools, R_object
