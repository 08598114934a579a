"""
Run the package's console scripts as real processes in the test's ROS domain, and stop them.

Used by the multi-process bridge tests and the benchmark. Every process writes its output to a
log file so a failing test can show it; every process is stopped (SIGINT, then SIGKILL) when the
group is left, whatever happened.
"""

import os
from pathlib import Path
import signal
import subprocess
import sys
import time

from dual_arm_control.nodes.process import REALTIME_PRIORITY_VARIABLE
import rclpy
from rclpy.experimental import EventsExecutor

SCRIPTS_DIR = Path(sys.prefix) / 'bin'
STOP_GRACE_PERIOD = 5.0


def ros_environment(domain_id):
    """Return os.environ with an isolated ROS domain and localhost-only discovery."""
    env = dict(os.environ)
    env['ROS_DOMAIN_ID'] = str(domain_id)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env.setdefault('AMENT_PREFIX_PATH', sys.prefix)
    env.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    env['PYTHONUNBUFFERED'] = '1'
    return env


def parameter_arguments(**parameters):
    """Return `-p name:=value` arguments (bools in YAML spelling)."""
    arguments = []
    for name, value in parameters.items():
        if isinstance(value, bool):
            value = 'true' if value else 'false'
        elif isinstance(value, (list, tuple)):
            value = '[' + ', '.join(str(v) for v in value) + ']'
        arguments += ['-p', f'{name}:={value}']
    return arguments


class ProcessGroup:
    """The processes of one test; leaving the `with` block stops all of them."""

    def __init__(self, log_dir, domain_id):
        self._log_dir = Path(log_dir)
        self._env = ros_environment(domain_id)
        self._processes = {}
        self._log_files = []
        self.resource_usage = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.stop_all()

    def start(self, label, executable, ros_arguments=(), realtime_priority=None):
        """
        Start a console script with `--ros-args ...`; output goes to <log_dir>/<label>.log.

        realtime_priority: the SCHED_FIFO priority the node takes, as dual_arm_bringup gives
        its nodes in realtime mode (None: normal scheduling).
        """
        log_file = open(self._log_dir / f'{label}.log', 'w')
        self._log_files.append(log_file)
        argv = [str(SCRIPTS_DIR / executable), '--ros-args', *ros_arguments]
        env = self._env
        if realtime_priority is not None:
            env = dict(env, **{REALTIME_PRIORITY_VARIABLE: str(realtime_priority)})
        self._processes[label] = subprocess.Popen(
            argv, stdout=log_file, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=env)
        return self._processes[label]

    def start_bridge(self, realtime_priority=None, **parameters):
        """Start sim_bridge with the given parameters."""
        return self.start('sim_bridge', 'sim_bridge', parameter_arguments(**parameters),
                          realtime_priority)

    def start_controller(self, arm, realtime_priority=None, **parameters):
        """Start a gravity_comp_controller for one arm in its namespace."""
        return self.start(f'{arm}_controller', 'gravity_comp_controller',
                          ['-r', f'__ns:=/{arm}', *parameter_arguments(arm=arm, **parameters)],
                          realtime_priority)

    def wait(self, label, timeout):
        """Wait for a process to exit; return its exit code (None after the timeout)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.poll(label) is not None:
                return self._processes[label].returncode
            time.sleep(0.05)
        return None

    def poll(self, label):
        """Return the exit code of a process, or None while it runs (records its CPU use)."""
        process = self._processes[label]
        if process.returncode is None:
            pid, status, usage = os.wait4(process.pid, os.WNOHANG)
            if pid == 0:
                return None
            process.returncode = os.waitstatus_to_exitcode(status)
            self.resource_usage[label] = usage
        return process.returncode

    def stop(self, label):
        """SIGINT one process, SIGKILL it after the grace period; return its exit code."""
        process = self._processes[label]
        if self.poll(label) is None:
            process.send_signal(signal.SIGINT)
            if self.wait(label, STOP_GRACE_PERIOD) is None:
                process.kill()
                self.wait(label, STOP_GRACE_PERIOD)
        return process.returncode

    def stop_all(self):
        """Stop every process and close the log files."""
        for label in self._processes:
            self.stop(label)
        for log_file in self._log_files:
            log_file.close()

    def log(self, label):
        """Return the output of a process so far (for assertion messages)."""
        return (self._log_dir / f'{label}.log').read_text()[-6000:]


class GraphProbe:
    """An rclpy node in the test process, on its own context in the test's ROS domain."""

    def __init__(self, domain_id, name='bridge_test'):
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=int(domain_id))
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = EventsExecutor(context=self.context)
        self.executor.add_node(self.node)

    def spin_until(self, condition, timeout):
        """Process callbacks until condition() is true or timeout [s] passes; return it."""
        deadline = time.monotonic() + timeout
        while not condition() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)
        return condition()

    def close(self):
        """Destroy the node and shut its context down."""
        self.executor.remove_node(self.node)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def record_episode(scenario, out, duration, timeout):
    """
    Run `dual_arm_bringup --record` on a scenario for duration [sim s] into out.

    In a ROS domain the launcher reserves; returns the completed process (exit 0 or 1: the
    episode's criteria may fail in a shortened run).
    """
    params = Path(out).parent / f'{Path(out).name}_params.yaml'
    params.write_text(f'sim_bridge:\n  ros__parameters:\n    duration: {duration}\n')
    bringup = subprocess.run(
        [str(SCRIPTS_DIR / 'dual_arm_bringup'), '--scenario', str(scenario), '--params',
         str(params), '--out', str(out), '--record'],
        capture_output=True, text=True, timeout=timeout, env=dict(os.environ))
    assert bringup.returncode in (0, 1), bringup.stdout + bringup.stderr
    return bringup
