"""
One lockstep run of the node graph that a fault is injected into, and a probe node beside it.

GraphRun starts the product graph as dual_arm_bringup does (its Launcher and node table, with
the bag recorder), plus an rclpy probe in this process on the run's ROS domain: it follows the
sim clock, the torque commands and every node's /diagnostics, publishes injected messages and
kills nodes. Unlike the launcher it does not stop the graph when a node dies, so the twin goes
on under the FRI hold policy and the arms' response can be measured.
"""

import os
from pathlib import Path
import signal
import time

from dual_arm_control import contract
from dual_arm_control.bringup import Launcher, start_recorder, stop_recorder
from dual_arm_control.graph import full_graph, run_parameters
from dual_arm_control.nodes.messages import stamp_ns
import rclpy
from rclpy.experimental import EventsExecutor

SPIN_PERIOD = 0.02
# Wall time without the sim clock moving after which a running graph counts as stalled [s].
STALL_TIMEOUT = 30.0


class SimProbe:
    """
    An rclpy node in this process on ROS domain `domain`: sim time, commands, diagnostics.

    The sim time is the bridge's ground truth stamp (every ground_truth_period, 10 ms), not
    /clock, which a malformed burst writes to as well: clock_ns the largest so far,
    last_truth_ns the newest (it goes back at a /sim/reset).
    """

    def __init__(self, domain, name='fault_probe'):
        self.clock_ns = 0
        self.last_truth_ns = -1
        self.clock_moved_wall = time.monotonic()
        self.last_command_ns = dict.fromkeys(contract.ARMS)
        self.diagnostics = {}
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=int(domain))
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = EventsExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.node.create_subscription(
            contract.GROUND_TRUTH_OBJECT.msg_type, contract.GROUND_TRUTH_OBJECT.name,
            lambda msg: self._on_sim_time(stamp_ns(msg.header.stamp)),
            contract.GROUND_TRUTH_OBJECT.qos)
        self.node.create_subscription(contract.DIAGNOSTICS.msg_type, contract.DIAGNOSTICS.name,
                                      self._on_diagnostics, contract.DIAGNOSTICS.qos)
        for arm in contract.ARMS:
            self.node.create_subscription(
                contract.TORQUE_COMMAND.msg_type, contract.TORQUE_COMMAND.resolved(arm),
                lambda msg, arm=arm: self._on_command(arm, msg), contract.TORQUE_COMMAND.qos)

    def close(self):
        """Destroy the node, shut its executor and context down (else a DDS participant leaks)."""
        self.executor.remove_node(self.node)
        self.node.destroy_node()
        self.executor.shutdown()
        rclpy.try_shutdown(context=self.context)

    def _on_sim_time(self, t_ns):
        if t_ns != self.last_truth_ns:
            self.clock_moved_wall = time.monotonic()
        self.last_truth_ns = t_ns
        self.clock_ns = max(self.clock_ns, t_ns)

    def stalled(self):
        """Return True if the sim time, once started, has not moved for STALL_TIMEOUT [s]."""
        return self.clock_ns > 0 and time.monotonic() - self.clock_moved_wall > STALL_TIMEOUT

    def _on_command(self, arm, msg):
        stamp = stamp_ns(msg.header.stamp)
        previous = self.last_command_ns[arm]
        self.last_command_ns[arm] = stamp if previous is None else max(previous, stamp)

    def _on_diagnostics(self, msg):
        for status in msg.status:
            self.diagnostics[status.name] = {value.key: value.value for value in status.values}

    def spin_until(self, condition, timeout):
        """Process the probe's callbacks until condition() or timeout [s]; return it."""
        deadline = time.monotonic() + timeout
        while not condition() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=SPIN_PERIOD)
        return condition()

    def refusal_counts(self):
        """Return {node status name: {counter: count}} of the non-zero refusal counters."""
        counts = {}
        for name, values in self.diagnostics.items():
            refused = {key: int(value) for key, value in values.items()
                       if key.startswith(('refused', 'samples_rejected_invalid'))
                       and value.isdigit() and int(value)}
            if refused:
                counts[name] = refused
        return counts


class GraphRun:
    """A lockstep graph run in out_dir on ROS domain `domain` (use as a context manager)."""

    def __init__(self, scenario_file, out_dir, domain, duration, answer_timeout=0.0,
                 record=True, bridge_parameters=None):
        self.out_dir = Path(out_dir)
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self.trajectory_file = self.out_dir / 'trajectory.npz'
        self.bag_file = self.out_dir / 'bag.mcap'
        parameters = run_parameters('full', scenario_file, 'lockstep',
                                    self.trajectory_file.resolve(), record)
        parameters['sim_bridge']['duration'] = duration
        parameters['sim_bridge']['lockstep_answer_timeout'] = answer_timeout
        parameters['sim_bridge'].update(bridge_parameters or {})
        self._nodes = full_graph()
        self.launcher = Launcher(self._nodes, self.out_dir, domain, node_parameters=parameters)
        self._scenario_file = scenario_file
        self._record = record
        self._domain = domain
        self.recorder = None
        self.probe = None
        self.recorder_code = None

    def __enter__(self):
        self.probe = SimProbe(self._domain)
        if self._record:
            self.recorder = start_recorder(self.out_dir, self.launcher.environment(),
                                           self._scenario_file)
        self.launcher.start()
        return self

    def __exit__(self, *exc_info):
        self.launcher.stop()
        if self.recorder is not None:
            self.recorder_code = stop_recorder(self.recorder)
        self.probe.close()

    def exited(self):
        """Return {label: exit code} of the graph's nodes that have exited."""
        return self.launcher.poll()

    def wait_for_sim_time(self, t, timeout):
        """Spin until the sim clock reaches t [s]; False if a node exited or on timeout."""
        self.probe.spin_until(lambda: self.probe.clock_ns * 1e-9 >= t - 1e-9
                              or bool(self.exited()) or self.probe.stalled(), timeout)
        return self.probe.clock_ns * 1e-9 >= t - 1e-9 and not self.exited()

    def wait_for_end(self, timeout):
        """Spin until the bridge exits; return {label: exit code} of every exited node."""
        self.probe.spin_until(lambda: 'sim_bridge' in self.exited() or self.probe.stalled(),
                              timeout)
        self.probe.spin_until(lambda: False, 0.3)
        return self.exited()

    def pids(self):
        """Return {label: process id} of the graph's nodes."""
        return dict(zip((spec.label for spec in self._nodes), self.launcher.pids))

    def pid(self, label):
        """Return the process id of the node with that label (e.g. left_passive_controller)."""
        labels = [spec.label for spec in self._nodes]
        return self.launcher.pids[labels.index(label)]

    def kill(self, label):
        """SIGKILL a node; return the sim time [s] of the last cycle the probe had seen."""
        os.kill(self.pid(label), signal.SIGKILL)
        return self.probe.clock_ns * 1e-9
