"""
Single-process episode runner: the twin and every role's runtime step in one loop.

Wires the same step objects the nodes wrap (runtime/), in the order the lockstep graph runs
them within one FRI cycle: the robots report (FriCycle.begin), the tracker filters the delivered
mocap samples and estimates the object at the cycle, the motion generator ticks (200 Hz), the
wrench QP answers the tick, each controller answers the cycle, the twin steps. Signals pass as
the same values the messages carry, so an in-process run and a lockstep graph run of the same
scenario and seed are the same episode (test_runtime_equivalence). For tuning, batch evaluation
and benchmarks: about 8x faster than the graph.
"""

from contextlib import contextmanager, nullcontext
from dataclasses import dataclass, field
import time

from dual_arm_control.core.arms import ARMS, joint_names
from dual_arm_control.core.passive_control import PassiveControllerConfig
from dual_arm_control.core.tracker import TrackerConfig
from dual_arm_control.core.wrench_distribution import WrenchDistributorConfig
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.graph import EPISODE_START_TIME
from dual_arm_control.runtime.configuration import motion_config_for_scenario
from dual_arm_control.runtime.controller_step import ControllerStep
from dual_arm_control.runtime.fri import FriCycle
from dual_arm_control.runtime.motion_step import MotionGeneratorStep
from dual_arm_control.runtime.node_settings import (COMMAND_TIMEOUT, CONTROLLER_TIMEOUT,
                                                    DS_PERIOD, FRI_PERIOD)
from dual_arm_control.runtime.timing import seconds_to_ns
from dual_arm_control.runtime.tracker_step import TrackerStep
from dual_arm_control.runtime.wrench_step import WrenchStep
from dual_arm_control.trajectory_log import TrajectoryRecorder
import numpy as np
from sim_bridge.twin import DualArmTwin


@dataclass(frozen=True)
class RunnerConfig:
    """Rates, timeouts and component configs of an in-process run (periods in seconds)."""

    fri_period: float = FRI_PERIOD
    ds_period: float = DS_PERIOD
    command_timeout: float = COMMAND_TIMEOUT
    controller_timeout: float = CONTROLLER_TIMEOUT
    torque_interface: str = 'full'
    start_time: float = EPISODE_START_TIME
    motion_base: object = None
    controller: PassiveControllerConfig = field(default_factory=PassiveControllerConfig)
    wrench: WrenchDistributorConfig = field(default_factory=WrenchDistributorConfig)
    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    command_outages: tuple = ()
    """Fault injection: (arm, start, end) sim-time windows [s] in which that arm's controller
    gets no DS command (it holds once its last command is stale), e.g. a late start."""
    controller_deaths: tuple = ()
    """Fault injection: (arm, time [s]) an arm's controller dies at: from then on it answers
    no cycle (the FRI hold acts) and the motion generator hears no command from it, as when the
    lockstep graph goes on without a killed controller (lockstep_answer_timeout)."""
    landing_target_changes: tuple = ()
    """Operator input: (time [s], (x, y, z) [m]) landing targets handed to the motion generator
    at those sim times, as /dual_arm/landing_target does in the graph."""
    commands: tuple = ()
    """Operator input: (time [s], 'start', 'go_home' or 'reset') requests handed to the motion
    generator at those sim times, as the ds_motion_generator node's command service does."""


@dataclass
class EpisodeLog:
    """
    What an in-process run produced.

    trajectory: ground truth; phases: the phase at every DS tick; events: (time, events,
    reason) of every tick with events; landing_target_refusals: per landing target change, the
    reason it was refused ('' if applied).
    """

    trajectory: dict
    phases: list = field(default_factory=list)
    events: list = field(default_factory=list)
    landing_target_refusals: list = field(default_factory=list)


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


class EpisodeRoles:
    """The runtime step of every role of the graph, configured for one scenario."""

    def __init__(self, scenario, config, cell):
        models = {arm: arm_model(arm, cell) for arm in ARMS}
        self.tracker = TrackerStep(config.tracker)
        self.motion = MotionGeneratorStep(
            motion_config_for_scenario(scenario, cell, config.motion_base), models,
            config.ds_period, seconds_to_ns(config.start_time),
            controller_timeout=config.controller_timeout)
        self.wrench = WrenchStep(config.wrench, scenario.object.mass, scenario.object.size,
                                 models)
        self.controllers = {arm: ControllerStep(models[arm], cell.arm(arm).q_home,
                                                config.controller, config.ds_period,
                                                config.command_timeout, config.torque_interface)
                            for arm in ARMS}


def run_episode(scenario, config=None, cell=None, duration=None, timer=None):
    """
    Run one episode of scenario and return its EpisodeLog.

    timer (a StageTimer) collects the wall time of each role's work per call: 'tracker' (the
    cycle's samples and the estimate), 'ds' (the motion generator), 'qp' (the wrench
    distribution), 'controller' (one arm's torque) and 'bridge_step' (the twin).
    """
    timer = _NoTimer() if timer is None else timer
    config = RunnerConfig() if config is None else config
    cell = load_cell() if cell is None else cell
    twin = DualArmTwin(scenario, cell, fri_period=config.fri_period,
                       torque_interface=config.torque_interface)
    fri = FriCycle(twin)
    roles = EpisodeRoles(scenario, config, cell)
    names = {arm: joint_names(arm) for arm in ARMS}
    recorder = TrajectoryRecorder()
    recorder.append(twin, fri.applied)
    log = EpisodeLog(trajectory={})
    duration = scenario.duration if duration is None else duration
    targets = sorted(config.landing_target_changes, key=lambda change: change[0])
    commands = sorted(config.commands, key=lambda command: command[0])
    while twin.time < duration - 1e-9:
        state = fri.begin()
        while targets and targets[0][0] <= state.stamp_ns * 1e-9:
            log.landing_target_refusals.append(roles.motion.set_landing_target(
                np.asarray(targets.pop(0)[1], dtype=float)))
        while commands and commands[0][0] <= state.stamp_ns * 1e-9:
            roles.motion.request(commands.pop(0)[1])
        with timer.stage('tracker'):
            for sample in state.mocap:
                roles.tracker.sample(sample.stamp_ns, sample.position, sample.quat_xyzw)
            for sample in state.container_mocap:
                roles.tracker.container_sample(sample.stamp_ns, sample.position)
            estimate = roles.tracker.at(state.stamp_ns)
            container = (roles.tracker.container_at(state.stamp_ns) if twin.container is not None
                         else None)
        ticking = roles.motion.is_new_tick(state.stamp_ns)
        with timer.stage('ds') if ticking else nullcontext():
            tick = roles.motion.cycle(state.stamp_ns, state.joints, state.ft_wrenches, estimate,
                                      container)
        if tick is not None:
            log.phases.append((state.stamp_ns * 1e-9, tick.phase.phase.value))
            if tick.phase.events:
                log.events.append((state.stamp_ns * 1e-9, tick.phase.events, tick.phase.reason))
            with timer.stage('qp'):
                wrenches = roles.wrench.tick(
                    state.stamp_ns, tick.phase.phase, tick.desired_twist,
                    {arm: state.joints[arm].position for arm in ARMS}, estimate)
            for arm in ARMS:
                if not _in_outage(config.command_outages, arm, state.stamp_ns * 1e-9):
                    roles.controllers[arm].command(tick.commands[arm])
                roles.controllers[arm].wrench(wrenches[arm])
        for arm in ARMS:
            if _dead(config.controller_deaths, arm, state.stamp_ns * 1e-9):
                continue
            with timer.stage('controller'):
                torque = roles.controllers[arm].cycle(state.joints[arm])
            fri.answer(arm, torque.stamp_ns, names[arm], torque.effort)
            roles.motion.command_heard(arm, torque.stamp_ns)
        with timer.stage('bridge_step'):
            fri.advance()
        recorder.append(twin, fri.applied)
    recorder.counters.update(fri.log_counters())
    log.trajectory = recorder.arrays()
    return log


def _in_outage(outages, arm, time):
    """Return True if arm's commands are cut at sim time [s] by one of the outage windows."""
    return any(name == arm and start <= time < end for name, start, end in outages)


def _dead(deaths, arm, time):
    """Return True if arm's controller has died by sim time [s] (one of the deaths)."""
    return any(name == arm and time >= start - 1e-12 for name, start in deaths)
