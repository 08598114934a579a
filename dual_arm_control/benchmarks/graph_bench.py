"""
Measurements of the whole node graph on this machine, run by `dual_arm_bench`.

1. Lockstep real-time factor of the full graph on the paper_toss episode (sim s / wall s).
2. Realtime mode, repeated paper_toss episodes for a given wall time: late FRI cycles (500 Hz),
   late commands, watchdog holds and clock stalls counted by the bridge, DS ticks (200 Hz) and
   their wall-clock gaps seen on /dual_arm/phase, how far behind the newest DS tick the
   controllers' DS commands and contact wrenches were (their /diagnostics), the episodes, and
   the CPU share of every process.
"""

import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

from domain_coordinator import domain_id
from dual_arm_control import contract
from dual_arm_control.graph import RUN_FOREVER
from dual_arm_control.resources import config_path
from dual_arm_control.runtime.controller_step import LAG_COUNTERS
from dual_arm_control.runtime.node_settings import DS_PERIOD
from dual_arm_control.scenario import load_scenario
import numpy as np
import rclpy
from rclpy.experimental import EventsExecutor
from std_srvs.srv import Trigger

CLOCK_TICKS = os.sysconf('SC_CLK_TCK')


def child_pids(pid):
    """Return the direct child pids of a process, read from /proc (Linux)."""
    found = []
    for task in Path(f'/proc/{pid}/task').glob('*'):
        try:
            found += [int(p) for p in (task / 'children').read_text().split()]
        except OSError:
            pass
    return found


def _cpu_seconds(pid):
    try:
        fields = Path(f'/proc/{pid}/stat').read_text().rsplit(') ', 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS
    except (OSError, IndexError, ValueError):
        return None


def _label(pid):
    try:
        arguments = Path(f'/proc/{pid}/cmdline').read_text().split('\0')
    except OSError:
        return str(pid)
    code = next((a for a in arguments if 'import main' in a), '')
    namespace = next((a.split(':=')[1] for a in arguments if a.startswith('__ns:=')), '')
    name = code.split(' import ')[0].split('from ')[-1].split('.')[-1] if code else str(pid)
    return f'{namespace.strip("/")}/{name}'.lstrip('/')


def _bringup(arguments, domain=None):
    bringup = Path(sys.executable).parent / 'dual_arm_bringup'
    domain_arguments = [] if domain is None else ['--domain-id', str(domain)]
    return subprocess.Popen([str(bringup), *domain_arguments, *arguments],
                            stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)


def lockstep_real_time_factor(out):
    """
    Run paper_toss in lockstep; return (sim duration, wall time, stepping wall time, exit code).

    The wall time is the whole run's, start-up and outputs included; the stepping wall time is
    the bridge's, from its first FRI cycle to its last (the trajectory log's wall_time).
    """
    started = time.monotonic()
    process = _bringup(['--scenario', str(config_path('scenarios', 'paper_toss.yaml')),
                        '--out', str(out)])
    code = process.wait()
    wall = time.monotonic() - started
    metrics = json.loads((out / 'metrics.json').read_text())
    with np.load(out / 'trajectory.npz') as archive:
        stepping = float(archive['wall_time'])
    return metrics['sim_duration'], wall, stepping, code


def controller_lags(status):
    """
    Return a passive controller's planner-lag counters from its DiagnosticStatus, else None.

    {cycles, and each of ControllerStep's LAG_COUNTERS}, as integers.
    """
    values = {value.key: value.value for value in status.values}
    keys = ('cycles',) + LAG_COUNTERS
    if not all(key in values for key in keys):
        return None
    try:
        return {key: int(values[key]) for key in keys}
    except ValueError:
        return None


class EpisodeDriver:
    """
    Watches /dual_arm/phase of a running graph and starts the next episode with /sim/reset.

    An episode is over when its arms are home again (the phase machine's 'home' event) or the
    scenario's duration has passed in sim time; the reset sends the clock back to 0 and every
    node starts over, the DS starting the episode by itself.
    """

    def __init__(self, node, episode_duration):
        self._node = node
        self._duration_ns = int(episode_duration * 1e9)
        self._reset = node.create_client(Trigger, contract.SIM_RESET_SERVICE)
        self._pending = None
        self.tick_walls = []
        self.episodes = []
        self._events = set()
        self.controller_lags = {}
        node.create_subscription(contract.PHASE.msg_type, contract.PHASE.name, self._on_phase,
                                 contract.PHASE.qos)
        node.create_subscription(contract.DIAGNOSTICS.msg_type, contract.DIAGNOSTICS.name,
                                 self._on_diagnostics, contract.DIAGNOSTICS.qos)

    def _on_diagnostics(self, msg):
        for status in msg.status:
            lags = controller_lags(status)
            if lags is not None:
                self.controller_lags[status.name] = lags

    def _on_phase(self, msg):
        self.tick_walls.append(time.monotonic())
        status = msg.status[0]
        stamp = msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec
        events = {value.value for value in status.values if value.key == 'events'}
        self._events.update(e for text in events for e in text.split(',') if e)
        done = 'home' in self._events or stamp >= self._duration_ns
        if done and self._pending is None and self._reset.service_is_ready():
            self.episodes.append(sorted(self._events))
            self._events = set()
            self._pending = self._reset.call_async(Trigger.Request())
            self._pending.add_done_callback(lambda future: setattr(self, '_pending', None))


def realtime_run(out, duration):
    """
    Run repeated paper_toss episodes in realtime for `duration` wall seconds.

    Returns the bridge's counters (late FRI cycles, late commands, watchdog holds, over every
    episode), the DS ticks and their wall-clock gaps, the episodes and which reached 'released'
    and 'home', and the CPU share of every process.
    """
    with domain_id() as domain:
        return _realtime_run(out, duration, domain)


def _realtime_run(out, duration, domain):
    params = out / 'params.yaml'
    params.write_text(f'sim_bridge:\n  ros__parameters:\n    duration: {RUN_FOREVER}\n')
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain)
    node = rclpy.create_node('graph_bench', context=context)
    executor = EventsExecutor(context=context)
    executor.add_node(node)
    scenario = load_scenario('paper_toss')
    driver = EpisodeDriver(node, scenario.duration)
    process = _bringup(['--mode', 'realtime', '--scenario', str(scenario.path), '--out',
                        str(out), '--params', str(params)], domain)
    cpu, cpu_start, labels = {}, {}, {}
    started = None
    while process.poll() is None:
        executor.spin_once(timeout_sec=0.05)
        if started is None and driver.tick_walls:
            started = time.monotonic()
            cpu = {pid: (label, seconds) for pid, (label, seconds) in _cpu(process, labels)}
            cpu_start = dict(cpu)
        elif started is not None:
            cpu.update(dict(_cpu(process, labels)))
            if time.monotonic() - started >= duration:
                process.send_signal(signal.SIGINT)
    wall = time.monotonic() - started if started else 0.0
    executor.remove_node(node)
    node.destroy_node()
    rclpy.try_shutdown(context=context)
    with np.load(out / 'trajectory.npz') as archive:
        counters = {name: archive[name].item() for name in archive.files
                    if archive[name].shape == ()
                    and ('late' in name or 'hold' in name or 'repeat' in name
                         or name in ('cycles', 'cycle_stalls', 'longest_cycle_gap'))}
    gaps = np.diff(driver.tick_walls)
    episodes = driver.episodes
    return {'wall': wall, 'counters': counters, 'ds_ticks': len(driver.tick_walls),
            'ds_late_ticks': int(np.sum(gaps > 1.5 * DS_PERIOD * 1.2)),
            'ds_gap_p99_ms': float(np.percentile(gaps, 99) * 1e3) if gaps.size else None,
            'episodes': len(episodes), 'controller_lags': driver.controller_lags,
            'episodes_released': sum('released' in events for events in episodes),
            'episodes_home': sum('home' in events for events in episodes),
            'cpu': {label: seconds - cpu_start.get(pid, (label, 0.0))[1]
                    for pid, (label, seconds) in cpu.items()}}


def _cpu(process, labels):
    """Yield (pid, (label, CPU seconds)) of the launcher's children."""
    for pid in child_pids(process.pid):
        if labels.get(pid, str(pid)) == str(pid):
            labels[pid] = _label(pid)
        seconds = _cpu_seconds(pid)
        if seconds is not None:
            yield pid, (labels[pid], seconds)
