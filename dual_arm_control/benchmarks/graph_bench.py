"""
Measurements of the whole node graph on this machine, run by `dual_arm_bench`.

1. Lockstep real-time factor of the full graph on the paper_toss episode (sim s / wall s).
2. Realtime mode for a given sim duration: late FRI cycles (500 Hz) and watchdog holds counted
   by the bridge, DS ticks (200 Hz) and their wall-clock gaps seen on /dual_arm/phase, and the
   CPU share of every process.
"""

import json
import os
from pathlib import Path
import random
import subprocess
import sys
import time

from dual_arm_control import contract
from dual_arm_control.resources import config_path
from dual_arm_control.runtime.node_settings import DS_PERIOD
import numpy as np
import rclpy
from rclpy.experimental import EventsExecutor

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


def _bringup(arguments, domain):
    bringup = Path(sys.executable).parent / 'dual_arm_bringup'
    return subprocess.Popen([str(bringup), '--domain-id', str(domain), *arguments],
                            stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)


def lockstep_real_time_factor(out):
    """Run paper_toss in lockstep; return (sim duration, wall time, exit code)."""
    started = time.monotonic()
    process = _bringup(['--scenario', str(config_path('scenarios', 'paper_toss.yaml')),
                        '--out', str(out)], random.randint(1, 200))
    code = process.wait()
    wall = time.monotonic() - started
    metrics = json.loads((out / 'metrics.json').read_text())
    return metrics['sim_duration'], wall, code


def realtime_run(out, duration):
    """Run the graph in realtime for duration sim seconds; return the measured numbers."""
    domain = random.randint(1, 200)
    params = out / 'params.yaml'
    log = out / 'trajectory.npz'
    params.write_text(f'sim_bridge:\n  ros__parameters:\n    duration: {duration}\n'
                      f'    trajectory_log: {log}\n')
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain)
    node = rclpy.create_node('graph_bench', context=context)
    executor = EventsExecutor(context=context)
    executor.add_node(node)
    tick_walls = []
    node.create_subscription(contract.PHASE.msg_type, contract.PHASE.name,
                             lambda msg: tick_walls.append(time.monotonic()), contract.PHASE.qos)
    process = _bringup(['--mode', 'realtime', '--out', str(out), '--params', str(params)],
                       domain)
    cpu, labels = {}, {}
    started = time.monotonic()
    while process.poll() is None:
        executor.spin_once(timeout_sec=0.05)
        for pid in child_pids(process.pid):
            if labels.get(pid, str(pid)) == str(pid):
                labels[pid] = _label(pid)
            seconds = _cpu_seconds(pid)
            if seconds is not None:
                cpu[pid] = (labels[pid], seconds)
    wall = time.monotonic() - started
    executor.remove_node(node)
    node.destroy_node()
    rclpy.try_shutdown(context=context)
    with np.load(log) as archive:
        counters = {name: int(archive[name]) for name in archive.files
                    if archive[name].shape == ()
                    and ('late' in name or 'hold' in name or name == 'cycles')}
    gaps = np.diff(tick_walls)
    return {'wall': wall, 'counters': counters, 'ds_ticks': len(tick_walls),
            'ds_late_ticks': int(np.sum(gaps > 1.5 * DS_PERIOD * 1.2)),
            'ds_gap_p99_ms': float(np.percentile(gaps, 99) * 1e3) if gaps.size else None,
            'cpu': dict(cpu.values())}
