"""
Benchmark the bridge with two separate-process gravity-compensation controllers.

Prints (1) the lockstep real-time factor, sim seconds per wall second over a 10 s sim run, and
(2) for realtime mode over a 30 s wall window: late cycles, watchdog holds and the CPU share of
each process (from /proc/<pid>/stat). Run with `python -m sim_bridge.benchmark`; it starts the
console scripts' mains exactly as the launcher does, in a random ROS domain.
"""

import argparse
import os
from pathlib import Path
import random
import signal
import subprocess
import sys
import tempfile
import time

from dual_arm_control.bringup import node_command
from dual_arm_control.graph import hold_graph
from dual_arm_control.trajectory_log import load_trajectory

CLOCK_TICKS_PER_SECOND = os.sysconf('SC_CLK_TCK')
STOP_GRACE_PERIOD = 5.0


def cpu_seconds(pid):
    """Return the user + system CPU time [s] a live process has used, from /proc."""
    with open(f'/proc/{pid}/stat') as stat:
        fields = stat.read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS_PER_SECOND


class Graph:
    """The hold graph (bridge + two controllers) as child processes of this benchmark."""

    def __init__(self, out_dir, bridge_parameters):
        env = dict(os.environ)
        env.update({'ROS_DOMAIN_ID': str(random.randint(1, 200)),
                    'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST', 'PYTHONUNBUFFERED': '1'})
        env.setdefault('AMENT_PREFIX_PATH', sys.prefix)
        self.processes = {}
        self.exit_usage = {}
        for spec in hold_graph():
            arguments = []
            if spec.executable == 'sim_bridge':
                for name, value in bridge_parameters.items():
                    arguments += ['-p', f'{name}:={value}']
            log = open(Path(out_dir) / f'{spec.label}.log', 'w')
            self.processes[spec.label] = subprocess.Popen(
                node_command(spec, arguments), stdout=log, stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL, env=env)
            log.close()

    def exited(self, label):
        """Tell whether a child has finished; reap it and keep its resource usage."""
        if label in self.exit_usage:
            return True
        pid, _, usage = os.wait4(self.processes[label].pid, os.WNOHANG)
        if pid == 0:
            return False
        self.exit_usage[label] = usage
        return True

    def wait(self, label, timeout):
        """Wait up to timeout [s] for a child to exit; return whether it did."""
        deadline = time.monotonic() + timeout
        while not self.exited(label):
            if time.monotonic() > deadline:
                return False
            time.sleep(0.02)
        return True

    def stop(self):
        """SIGINT every child still running, SIGKILL it after the grace period."""
        for label, process in self.processes.items():
            if not self.exited(label):
                process.send_signal(signal.SIGINT)
                if not self.wait(label, STOP_GRACE_PERIOD):
                    process.kill()
                    self.wait(label, STOP_GRACE_PERIOD)

    def cpu_seconds(self):
        """Return {label: CPU seconds so far} of the running children."""
        return {label: cpu_seconds(process.pid) for label, process in self.processes.items()
                if label not in self.exit_usage}


def lockstep_real_time_factor(out_dir, sim_seconds):
    """Run lockstep for sim_seconds; return (real-time factor, log, CPU seconds per process)."""
    log_path = Path(out_dir) / 'lockstep.npz'
    graph = Graph(out_dir, {'mode': 'lockstep', 'duration': sim_seconds,
                            'trajectory_log': log_path})
    try:
        finished = graph.wait('sim_bridge', timeout=20.0 + 20.0 * sim_seconds)
    finally:
        graph.stop()
    if not finished:
        raise RuntimeError(f'lockstep run did not finish; see {out_dir}/sim_bridge.log')
    data = load_trajectory(log_path)
    cpu = {label: usage.ru_utime + usage.ru_stime for label, usage in graph.exit_usage.items()}
    return float(data['t'][-1]) / float(data['wall_time']), data, cpu


def realtime_window(out_dir, warm_up, window, fri_period):
    """Run realtime mode; return (log, {label: CPU share over the window [-]}, wall window)."""
    log_path = Path(out_dir) / 'realtime.npz'
    graph = Graph(out_dir, {'mode': 'realtime', 'duration': 1.0e6, 'fri_period': fri_period,
                            'trajectory_log': log_path})
    try:
        time.sleep(warm_up)
        start_cpu, start_wall = graph.cpu_seconds(), time.monotonic()
        time.sleep(window)
        end_cpu, end_wall = graph.cpu_seconds(), time.monotonic()
    finally:
        graph.stop()
    wall = end_wall - start_wall
    share = {label: (end_cpu[label] - start_cpu[label]) / wall for label in end_cpu}
    return load_trajectory(log_path), share, wall


def main(argv=None):
    """Run both benchmarks and print the numbers."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--lockstep-sim-seconds', type=float, default=10.0)
    parser.add_argument('--realtime-window', type=float, default=30.0,
                        help='wall seconds measured in realtime mode')
    parser.add_argument('--fri-period', type=float, default=0.002)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix='sim_bridge_benchmark_') as out_dir:
        factor, data, cpu = lockstep_real_time_factor(out_dir, args.lockstep_sim_seconds)
        cycles = int(data['cycles'])
        print(f'lockstep, FRI period 2 ms, two controller processes: {data["t"][-1]:.1f} s sim '
              f'in {float(data["wall_time"]):.2f} s wall -> real-time factor {factor:.2f} '
              f'({cycles / float(data["wall_time"]):.0f} cycles/s)')
        print('  CPU seconds over the whole run incl. start-up: '
              + ', '.join(f'{label} {seconds:.1f}' for label, seconds in sorted(cpu.items())))
        warm_up = 3.0
        data, share, wall = realtime_window(out_dir, warm_up, args.realtime_window,
                                            args.fri_period)
        cycles = int(data['cycles'])
        print(f'realtime, FRI period {args.fri_period * 1e3:g} ms: {cycles} cycles, '
              f'{float(data["t"][-1]):.1f} s sim over ~{wall + warm_up:.1f} s wall; late cycles '
              f'{int(data["late_cycles"])} ({100.0 * int(data["late_cycles"]) / cycles:.2f} %); '
              f'watchdog holds left {int(data["left_watchdog_holds"])}, right '
              f'{int(data["right_watchdog_holds"])} (incl. discovery at start)')
        print(f'  CPU share over the {wall:.1f} s window: '
              + ', '.join(f'{label} {100.0 * value:.0f} %'
                          for label, value in sorted(share.items())))
    return 0


if __name__ == '__main__':
    sys.exit(main())
