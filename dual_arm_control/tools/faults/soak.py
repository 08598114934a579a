"""
The soak: consecutive episodes in ONE running lockstep graph, each with its own seed.

The product graph starts once (GraphRun, no bag) with the bridge waiting at the end of every
episode (at_duration 'wait'), so every episode lasts exactly `duration` of sim time. Episode i
runs with the twin's noise seed `seed + i`: before it the probe sets the bridge's `seed` and
calls /sim/reset, which writes the episode that ends to the trajectory log and starts the next
from the scenario's initial state; every node starts over on the clock going back. The episode
the graph runs by itself at its start is not counted: the probe may not hear all of it. After each
episode: its metrics (from the log, the twin's ground truth), success, the resident memory
(VmRSS) and open file descriptors of every node process. Last, the seeds of the first two
episodes run again: the graph being a function of scenario and seed, their metrics must be
identical.
soak_report.soak_summary judges the records.
"""

from dataclasses import dataclass
import json
import math
import os
from pathlib import Path
import time

from dual_arm_control import contract
from dual_arm_control.core.exceptions import DualArmControlError
from dual_arm_control.description.cell import load_cell
from dual_arm_control.evaluation.episode import episode_metrics
from dual_arm_control.scenario import load_scenario
from dual_arm_control.tools.faults.graph_run import GraphRun
from dual_arm_control.tools.faults.soak_report import soak_summary
from dual_arm_control.trajectory_log import load_trajectory
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from std_srvs.srv import Trigger

# Wall time an episode (or a service call) may take before the soak gives up [s].
EPISODE_TIMEOUT = 120.0
SERVICE_TIMEOUT = 30.0
# Wall time without ground truth after which the probe takes the bridge for waiting [s].
QUIET_TIME = 5.0
BRIDGE = '/sim_bridge'


@dataclass(frozen=True)
class SoakPlan:
    """What to soak: scenario, episodes, their sim duration [s], first seed, warm-up, block."""

    scenario: str = 'hold'
    episodes: int = 50
    duration: float = 2.0
    seed: int = 1000
    warmup: int = 5
    block: int = 10


def process_resources(pid):
    """Return (resident memory [kB], open file descriptors) of a process, from /proc."""
    with open(f'/proc/{pid}/status') as status:
        rss = next(int(line.split()[1]) for line in status if line.startswith('VmRSS:'))
    return rss, len(os.listdir(f'/proc/{pid}/fd'))


def metrics_record(metrics):
    """Return metrics as plain JSON values (NaN kept as None), in a fixed key order."""
    def plain(value):
        if isinstance(value, dict):
            return {key: plain(value[key]) for key in sorted(value)}
        if isinstance(value, (list, tuple)) or hasattr(value, 'tolist'):
            value = value.tolist() if hasattr(value, 'tolist') else value
            return [plain(item) for item in value] if isinstance(value, list) else plain(value)
        if isinstance(value, float) and not math.isfinite(value):
            return None
        return value
    return plain(metrics)


class SoakRun:
    """One soak in out_dir on ROS domain `domain` (see the module text)."""

    def __init__(self, plan, out_dir, domain):
        self.plan = plan
        self.out_dir = Path(out_dir)
        self.scenario = load_scenario(plan.scenario)
        self.cell = load_cell()
        self.run = GraphRun(self.scenario.path, self.out_dir, domain, plan.duration,
                            record=False, bridge_parameters={'at_duration': 'wait',
                                                             'seed': plan.seed})

    def __enter__(self):
        self.run.__enter__()
        node = self.run.probe.node
        self._reset = node.create_client(Trigger, contract.SIM_RESET_SERVICE)
        self._parameters = AsyncParameterClient(node, BRIDGE)
        return self

    def __exit__(self, *exc_info):
        self.run.__exit__(*exc_info)

    def _call(self, future):
        if not self.run.probe.spin_until(future.done, SERVICE_TIMEOUT):
            raise DualArmControlError(f'no answer within {SERVICE_TIMEOUT:g} s')
        return future.result()

    def start(self, seed):
        """
        Start the first counted episode with seed, never in the middle of the graph's own one.

        Once the probe has found the bridge: if it hears the episode the graph started by
        itself, wait for its end; if it hears nothing for QUIET_TIME, the bridge is waiting at
        that episode's end already (or has not started: a reset then only reseeds the twin).
        """
        probe = self.run.probe
        found = probe.spin_until(
            lambda: probe.node.count_publishers(contract.GROUND_TRUTH_OBJECT.name) > 0
            and self._reset.service_is_ready() or bool(self.run.exited()), EPISODE_TIMEOUT)
        if not found or self.run.exited():
            raise DualArmControlError(f'the graph did not come up: exited {self.run.exited()}')
        if probe.spin_until(lambda: probe.last_truth_ns >= 0, QUIET_TIME):
            self.wait_for_episode_end()
        self.next_episode(seed)

    def wait_for_episode_end(self):
        """Spin until the bridge waits at the end of the episode; False on exit or timeout."""
        end_ns = round(self.plan.duration * 1e9)
        probe = self.run.probe
        probe.spin_until(lambda: probe.last_truth_ns >= end_ns or bool(self.run.exited())
                         or probe.stalled(), EPISODE_TIMEOUT)
        return probe.last_truth_ns >= end_ns and not self.run.exited()

    def next_episode(self, seed):
        """Start the next episode with seed; return the ended one's log (/sim/reset writes it)."""
        result = self._call(self._parameters.set_parameters(
            [Parameter('seed', Parameter.Type.INTEGER, int(seed))]))
        if not result.results[0].successful:
            raise DualArmControlError(f'seed {seed} refused: {result.results[0].reason}')
        self.run.probe.last_truth_ns = -1
        if not self._reset.wait_for_service(timeout_sec=SERVICE_TIMEOUT):
            raise DualArmControlError('/sim/reset not available')
        response = self._call(self._reset.call_async(Trigger.Request()))
        if not response.success:
            raise DualArmControlError(f'/sim/reset failed: {response.message}')
        return load_trajectory(self.run.trajectory_file)

    def record(self, index, seed, data, resources, wall):
        """Return the record of one ended episode."""
        metrics = metrics_record(episode_metrics(self.scenario, data, self.cell))
        return {'episode': index, 'seed': seed, 'log_seed': int(data.get('seed', -1)),
                'success': bool(metrics['success']), 'metrics': metrics,
                'rss_kb': {label: rss for label, (rss, _) in resources.items()},
                'fds': {label: fds for label, (_, fds) in resources.items()},
                'wall_time': round(wall, 2)}


def write_soak(out_dir, plan, summary, records):
    """Write OUT/soak.json: the plan, the summary and every episode's record."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / 'soak.json').write_text(json.dumps(
        {'plan': plan.__dict__, 'summary': summary, 'episodes': records}, indent=1) + '\n')


def run_soak(plan, out_dir, domain, progress=print, stop_requested=lambda: False):
    """
    Run a soak (SoakPlan); write OUT/soak.json; return its summary (soak_report).

    OUT/soak.json is written after every block as well (summary 'running'). Once
    stop_requested() is true, no more counted episodes start: the re-runs follow the ended one.
    """
    reruns = [plan.seed, plan.seed + 1]
    seeds = [plan.seed + index for index in range(plan.episodes)] + reruns
    counted = plan.episodes
    records = []
    with SoakRun(plan, out_dir, domain) as soak:
        soak.start(seeds[0])
        started = time.monotonic()
        for index, seed in enumerate(seeds):
            if not soak.wait_for_episode_end():
                progress(f'soak: episode {index} did not end: exited {soak.run.exited()}')
                break
            resources = {label: process_resources(pid)
                         for label, pid in soak.run.pids().items()}
            if index < counted - 1 and stop_requested():
                counted = index + 1
                seeds[counted:] = reruns
                progress(f'soak: stopped after {counted} episodes; the re-runs follow')
            last = index == len(seeds) - 1
            data = soak.next_episode(plan.seed if last else seeds[index + 1])
            records.append(soak.record(index, seed, data, resources,
                                       time.monotonic() - started))
            started = time.monotonic()
            if index % plan.block == plan.block - 1 or last:
                progress(f'soak: episode {index} seed {seed}: success {records[-1]["success"]}, '
                         f'RSS {sum(records[-1]["rss_kb"].values()) / 1024:.0f} MB, '
                         f'fds {sum(records[-1]["fds"].values())}')
                write_soak(out_dir, plan, {'running': True, 'episodes': len(records)}, records)
        exits = soak.run.exited()
    summary = soak_summary(records[:counted], records[counted:], plan.warmup, plan.block)
    summary['node_exits'] = dict(exits)
    summary['passed'] = summary['passed'] and not exits
    write_soak(out_dir, plan, summary, records)
    return summary
