"""
ParameterTool: the ROS client of dual_arm_param, calling the parameter services of other nodes.

It runs an rclpy node on its own context and talks to the standard rcl_interfaces parameter
services every node offers, so it works with any ROS 2 node.
"""

import os
import time

from dual_arm_control.core.exceptions import InputError
from dual_arm_control.tools.param_values import full_node_name
import rclpy
from rclpy.exceptions import NameValidationException
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter_client import AsyncParameterClient

DISCOVERY_SETTLE_TIME = 0.5
GRAPH_POLL_PERIOD = 0.02


class ParameterTool:
    """An rclpy node on its own context that calls the parameter services of other nodes."""

    def __init__(self, domain_id=None, timeout=5.0):
        self.timeout = timeout
        self.context = rclpy.Context()
        rclpy.init(args=[], context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node(f'dual_arm_param_{os.getpid()}', context=self.context,
                                      start_parameter_services=False)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._clients = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)

    def node_names(self):
        """Return the full names of the graph's nodes (not ours, not hidden), sorted."""
        own = self.node.get_fully_qualified_name()
        deadline = time.monotonic() + self.timeout
        names, stable_since = set(), time.monotonic()
        while time.monotonic() < deadline:
            current = {f'{namespace.rstrip("/")}/{name}'
                       for name, namespace in self.node.get_node_names_and_namespaces()
                       if not name.startswith('_')} - {own}
            if current != names:
                names, stable_since = current, time.monotonic()
            elif names and time.monotonic() - stable_since > DISCOVERY_SETTLE_TIME:
                break
            time.sleep(GRAPH_POLL_PERIOD)
        return sorted(names)

    def client(self, node_name):
        """Return the AsyncParameterClient of a node once its services are up, else InputError."""
        node_name = full_node_name(node_name)
        if node_name not in self._clients:
            try:
                client = AsyncParameterClient(self.node, node_name)
            except NameValidationException:
                raise InputError(f'{node_name} is not a valid node name') from None
            deadline = time.monotonic() + self.timeout
            while not client.services_are_ready() and time.monotonic() < deadline:
                time.sleep(GRAPH_POLL_PERIOD)
            if not client.services_are_ready():
                raise InputError(f'node {node_name} not found: its parameter services did not '
                                 f'appear within {self.timeout:g} s (ROS domain '
                                 f'{self.context.get_domain_id()})')
            self._clients[node_name] = client
        return self._clients[node_name]

    def call(self, node_name, method, *arguments):
        """Call one parameter service of a node and return its response; InputError on timeout."""
        future = getattr(self.client(node_name), method)(*arguments)
        self.executor.spin_until_future_complete(future, timeout_sec=self.timeout)
        if not future.done():
            raise InputError(f'node {full_node_name(node_name)} did not answer {method} within '
                             f'{self.timeout:g} s')
        return future.result()

    def names(self, node_name):
        """Return the node's parameter names, sorted."""
        return sorted(self.call(node_name, 'list_parameters', [], 0).result.names)

    def values(self, node_name, names):
        """Return {name: ParameterValue} (empty if any name is not declared)."""
        return dict(zip(names, self.call(node_name, 'get_parameters', names).values))

    def descriptors(self, node_name, names):
        """Return {name: ParameterDescriptor} (empty if any name is not declared)."""
        return dict(zip(names, self.call(node_name, 'describe_parameters', names).descriptors))

    def set_parameters(self, node_name, messages):
        """Set parameters one by one; return their SetParametersResult list."""
        return self.call(node_name, 'set_parameters', messages).results
