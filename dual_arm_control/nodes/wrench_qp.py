"""
wrench_qp: the contact wrench of each pad, once per DS tick (runtime WrenchStep, eq. 10).

With `lockstep` a tick t is computed once /object/desired_twist(t), /dual_arm/phase(t), both
arms' joint states (t) and the tracker's /object/state(t) arrived; in realtime each phase
message triggers its tick with the newest of the other inputs (take-latest). It publishes
/<arm>/contact_wrench (WrenchStamped, frame world, force the pad applies on the object, moment
about the tool point) stamped t. Malformed inputs are refused and counted; a refused input still
counts as arrived and the newest valid one is used. Parameters: the WrenchDistributorConfig
fields (live), `object_mass` [kg] and `object_size` [m] (defaults from `scenario` if given, else
the catalogue's paper_cube; applied at the next tick outside a grasp), `scenario`, `lockstep`
(read-only) and `diagnostics_period`.
"""

import sys

from diagnostic_msgs.msg import DiagnosticStatus
from dual_arm_control import contract
from dual_arm_control.catalogue import object_spec
from dual_arm_control.core.wrench_distribution import WrenchDistributorConfig
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.nodes.diagnostics import CounterDiagnostics, refusal_logger
from dual_arm_control.nodes.messages import (fill_wrench, joint_state_of, LatestMessage,
                                             object_state_of, phase_of, stamp_ns, twist_of)
from dual_arm_control.nodes.process import create_topic_publisher, run_node
from dual_arm_control.parameters import ConfigParameters, NodeParameters
from dual_arm_control.runtime.inputs import ArrivalBarrier, RefusalCounter
from dual_arm_control.runtime.node_settings import node_table
from dual_arm_control.runtime.wrench_step import WrenchStep
from dual_arm_control.scenario import load_scenario
from rclpy.node import Node

DEFAULT_OBJECT = 'paper_cube'
TICK_INPUTS = frozenset(('desired_twist', 'phase', *contract.ARMS))


def object_defaults(values):
    """Return the object_mass and object_size defaults of the node's scenario (or catalogue)."""
    if 'scenario' not in values:
        return {}
    scenario = values['scenario']
    box = load_scenario(scenario).object if scenario else object_spec(DEFAULT_OBJECT)
    return {'object_mass': float(box.mass), 'object_size': [float(s) for s in box.size]}


class WrenchQPNode(Node):
    """Distribute the desired object wrench over the two pads once per DS tick."""

    def __init__(self, node_name='wrench_qp', **node_options):
        super().__init__(node_name, **node_options)
        settings = NodeParameters(self, node_table('wrench_qp').settings, object_defaults,
                                  on_change=self._on_setting)
        mass, size, lockstep = (settings[name] for name in ('object_mass', 'object_size',
                                                            'lockstep'))
        self._diagnostics = CounterDiagnostics(self)
        parameters = ConfigParameters(self, WrenchDistributorConfig(), self.step_reconfigure)
        cell = load_cell()
        self.step = WrenchStep(parameters.config, mass, size,
                               {arm: arm_model(arm, cell) for arm in contract.ARMS})
        self.refusals = RefusalCounter(refusal_logger(self.get_logger()))
        # Lockstep: a tick waits for every input stamped with it. Realtime: take-latest, the
        # phase of a DS tick triggers it.
        required = TICK_INPUTS | {'object'} if lockstep else {'phase'}
        self._barrier = ArrivalBarrier(lambda stamp: required)
        self._wrench_pubs = {arm: create_topic_publisher(self, contract.CONTACT_WRENCH, arm)
                             for arm in contract.ARMS}
        self._wrench_msgs = {arm: contract.CONTACT_WRENCH.msg_type() for arm in contract.ARMS}
        for msg in self._wrench_msgs.values():
            msg.header.frame_id = contract.WORLD_FRAME
        inputs = [(contract.OBJECT_STATE, contract.OBJECT_STATE.name, 'object', object_state_of),
                  (contract.OBJECT_DESIRED_TWIST, contract.OBJECT_DESIRED_TWIST.name,
                   'desired_twist', twist_of),
                  (contract.PHASE, contract.PHASE.name, 'phase', phase_of)]
        inputs += [(contract.JOINT_STATES, contract.JOINT_STATES.resolved(arm), arm,
                    lambda msg, names=contract.joint_names(arm): joint_state_of(msg, names))
                   for arm in contract.ARMS]
        self._inputs = {key: LatestMessage(read, key, self.refusals.refuse)
                        for _, _, key, read in inputs}
        self._input_subs = [self.create_subscription(
            topic.msg_type, name, lambda msg, key=key: self._on_input(key, msg),
            topic.subscription_qos(lockstep))
            for topic, name, key, _ in inputs]
        self.get_logger().info(f'wrench QP up: object {mass:g} kg, {list(size)} m')

    @property
    def config(self):
        """Return the WrenchDistributorConfig the distributor runs with."""
        return self.step.config

    def step_reconfigure(self, config):
        """Hand an accepted distributor config to the step (applies at the next tick)."""
        self.step.reconfigure(config)

    def _on_setting(self, name, value):
        """Apply a new object mass or size at the next tick outside a grasp."""
        if name == 'object_mass':
            self.step.change_object(mass=value)
        elif name == 'object_size':
            self.step.change_object(size=value)

    def _on_input(self, key, msg):
        self._inputs[key].offer(msg)
        for t_ns in self._barrier.arrived(stamp_ns(msg.header.stamp), key):
            self._tick(t_ns)

    def _tick(self, t_ns):
        phase = self._inputs['phase'].value()
        joints = {arm: state.position for arm in contract.ARMS
                  if (state := self._inputs[arm].value()) is not None}
        wrenches = self.step.tick(t_ns, None if phase is None else phase.phase,
                                  self._inputs['desired_twist'].value(), joints,
                                  self._inputs['object'].value())
        result = self.step.last_result
        if result is not None and not result.feasible:
            self.get_logger().warning(f'wrench QP: {result.status}', throttle_duration_sec=1.0)
        for arm in contract.ARMS:
            fill_wrench(self._wrench_msgs[arm], wrenches[arm])
            self._wrench_pubs[arm].publish(self._wrench_msgs[arm])
        self._diagnostics.publish_if_due(t_ns, self._report)

    def _report(self):
        values = dict(self.step.counters, dropped_stamps=self._barrier.dropped)
        values.update({f'refused_{reason}': n for reason, n in self.refusals.counts.items()})
        phase = self._inputs['phase'].value()
        result = self.step.last_result
        values.update({'phase': 'none' if phase is None else phase.phase.value,
                       'object_mass': self.step.object_mass,
                       'normal_force_floor': 0.0 if result is None else result.normal_force_floor})
        if self.refusals.total or self.step.counters['infeasible_ticks']:
            return DiagnosticStatus.WARN, 'inputs refused or QP infeasible', values
        return DiagnosticStatus.OK, 'running', values


def main(args=None):
    """Run the wrench QP until Ctrl-C or SIGTERM; return the exit code."""
    return run_node(WrenchQPNode, 'wrench_qp', args)


if __name__ == '__main__':
    sys.exit(main())
