"""
wrench_qp: the contact wrench of each pad, once per DS tick (core WrenchDistributor).

A tick t_j is processed when /object/desired_twist(t_j), /dual_arm/phase(t_j) and the joint
states (t_j) of both arms have arrived (with `lockstep`, also the tracker's /object/state(t_j));
the tool poses come from the arms' pinocchio models and the object state is the newest
/object/state predicted to t_j with its own twist. Every tick
publishes /<arm>/contact_wrench (WrenchStamped, frame world, force the pad applies on the
object, moment about the tool point) stamped t_j: zeros outside CONTACT / MANIPULATE, before the
first object state and when the QP fails (the distributor reports it; counted).

Malformed or non-finite inputs are refused and counted; a refused input still counts as arrived
for its tick and the newest valid one is used. Parameters: the WrenchDistributorConfig fields
(ConfigParameters, applied at the next tick), `object_mass` [kg] and `object_size` [m] (defaults
from `scenario` if given, else the catalogue's paper_cube; applied at the next tick outside a
grasp), `scenario` (read-only) and `diagnostics_period`.
"""

import sys

from diagnostic_msgs.msg import DiagnosticStatus
from dual_arm_control import contract
from dual_arm_control.catalogue import object_spec
from dual_arm_control.core.exceptions import ConfigError, InputError
from dual_arm_control.core.phases import Phase
from dual_arm_control.core.validation import check_range
from dual_arm_control.core.wrench_distribution import (GRASPING_PHASES, WrenchDistributor,
                                                       WrenchDistributorConfig)
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.nodes.common import (CounterDiagnostics, create_topic_publisher,
                                           has_estimate, joint_state_arrays,
                                           odometry_arrays, RefusalCounter,
                                           run_node, set_wrench, stamp_ns, TickSchedule, time_msg,
                                           vector3)
from dual_arm_control.parameters import ConfigParameters, parameter_descriptor
from dual_arm_control.runtime.timing import object_state_at
from dual_arm_control.scenario import load_scenario
import numpy as np
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.node import Node

DEFAULT_OBJECT = 'paper_cube'
# Period assumed for the first tick (the ramp of the grasp wrench needs a dt) [s].
FIRST_TICK_PERIOD = 0.005
MASS_RANGE = (1e-3, 100.0)
MAX_OBJECT_EDGE = 2.0
# Ticks waiting for inputs are kept at most this many cycles (bounded after a lost message).
MAX_PENDING_STAMPS = 64
TICK_INPUTS = frozenset(('desired_twist', 'phase', *contract.ARMS))
COUNTERS = ('ticks', 'repeated_answers', 'grasp_ticks', 'infeasible_ticks',
            'ticks_without_object_state', 'ticks_without_joint_states', 'ticks_without_phase',
            'object_changes_applied')


def object_parameter_problem(name, value):
    """Return why an object parameter value is invalid, or None if it is acceptable."""
    try:
        if name == 'object_mass':
            check_range('object_mass', value, MASS_RANGE[0], MASS_RANGE[1], 'kg')
        elif name == 'object_size':
            if len(value) != 3:
                return f'object_size must be 3 edge lengths [m], got {list(value)}'
            for axis, edge in zip('xyz', value):
                check_range(f'object_size {axis}', edge, 0.0, MAX_OBJECT_EDGE, 'm',
                            low_open=True)
        elif name == 'scenario' and value:
            load_scenario(value)
    except ConfigError as error:
        return str(error)
    return None


class WrenchQPNode(Node):
    """Distribute the desired object wrench over the two pads once per DS tick."""

    def __init__(self, node_name='wrench_qp', **node_options):
        super().__init__(node_name, **node_options)
        self.add_on_set_parameters_callback(self._validate_parameters)
        self._declare_object_parameters()
        self.add_post_set_parameters_callback(self._apply_object_parameters)
        self._diagnostics = CounterDiagnostics(self)
        self._config_parameters = ConfigParameters(self, WrenchDistributorConfig(),
                                                   self._on_config)
        cell = load_cell()
        self._models = {arm: arm_model(arm, cell) for arm in contract.ARMS}
        self.object_mass = self.get_parameter('object_mass').value
        self.object_size = tuple(self.get_parameter('object_size').value)
        self._config = self._config_parameters.config
        self._distributor = WrenchDistributor(self._config, self.object_mass, self.object_size)
        self._pending_config = None
        self._pending_object = None
        self._tick_inputs = TICK_INPUTS | ({'object'} if self.declare_parameter(
            'lockstep', False, ParameterDescriptor(
                description='on each tick also wait for the object estimate stamped with the '
                            'tick (the tracker answers every /clock cycle): lockstep runs '
                            'become independent of message timing', read_only=True)).value
            else set())
        self._schedule = TickSchedule(FIRST_TICK_PERIOD)
        self._last_wrenches = None

        self.refusals = RefusalCounter(self.get_logger())
        self.counters = dict.fromkeys(COUNTERS, 0)
        self._arrivals = {}
        self._latest = {}
        self._object_state = None

        self._wrench_pubs, self._wrench_msgs = {}, {}
        for arm in contract.ARMS:
            self._wrench_pubs[arm] = create_topic_publisher(self, contract.CONTACT_WRENCH, arm)
            self._wrench_msgs[arm] = contract.CONTACT_WRENCH.msg_type()
            self._wrench_msgs[arm].header.frame_id = contract.WORLD_FRAME
        self._input_subs = [
            self.create_subscription(topic.msg_type, name, callback, topic.qos)
            for topic, name, callback in (
                (contract.OBJECT_STATE, contract.OBJECT_STATE.name, self._on_object_state),
                (contract.OBJECT_DESIRED_TWIST, contract.OBJECT_DESIRED_TWIST.name,
                 self._on_desired_twist),
                (contract.PHASE, contract.PHASE.name, self._on_phase),
                *((contract.JOINT_STATES, contract.JOINT_STATES.resolved(arm),
                   lambda msg, arm=arm: self._on_joint_state(arm, msg))
                  for arm in contract.ARMS))]
        self.get_logger().info(
            f'wrench QP up: object {self.object_mass:g} kg, {list(self.object_size)} m')

    @property
    def config(self):
        """Return the WrenchDistributorConfig the distributor runs with."""
        return self._config

    def _declare_object_parameters(self):
        """Declare scenario, object_mass and object_size (defaults from the scenario)."""
        self.declare_parameter('scenario', '', ParameterDescriptor(
            description='scenario YAML (path or name under config/scenarios) whose object gives '
                        'the defaults of object_mass and object_size; empty: catalogue '
                        f'{DEFAULT_OBJECT}', read_only=True))
        scenario = self.get_parameter('scenario').value
        box = load_scenario(scenario).object if scenario else object_spec(DEFAULT_OBJECT)
        self.declare_parameter('object_mass', float(box.mass), parameter_descriptor(
            'mass of the grasped box [kg]', floating_range=MASS_RANGE))
        self.declare_parameter('object_size', [float(s) for s in box.size], ParameterDescriptor(
            description='edge lengths of the box along object x, y (squeeze axis), z [m]',
            additional_constraints=f'3 lengths in (0, {MAX_OBJECT_EDGE:g}] m'))

    def _validate_parameters(self, parameters):
        """Refuse invalid object parameters with a reason naming the value and range."""
        for parameter in parameters:
            problem = object_parameter_problem(parameter.name, parameter.value)
            if problem is not None:
                return SetParametersResult(successful=False, reason=problem)
        return SetParametersResult(successful=True)

    def _apply_object_parameters(self, parameters):
        """Keep a new object mass or size for the next tick outside a grasp."""
        changes = {p.name: p.value for p in parameters
                   if p.name in ('object_mass', 'object_size')}
        if changes:
            mass, size = self._pending_object or (self.object_mass, self.object_size)
            self._pending_object = (changes.get('object_mass', mass),
                                    tuple(changes.get('object_size', size)))

    def _on_config(self, config):
        """Keep an accepted distributor config for the next tick."""
        self._pending_config = config

    # -- inputs ----------------------------------------------------------------------------------

    def _on_object_state(self, msg):
        """Keep the newest valid object state (None: no track yet); mark it as arrived."""
        t_ns = stamp_ns(msg.header.stamp)
        if not has_estimate(msg):
            self._object_state = None
        else:
            try:
                p_world, R_world, v_world, w_world = odometry_arrays(msg)
            except InputError as error:
                self.refusals.refuse('object_state', str(error))
                return
            self._object_state = (t_ns, p_world, R_world, v_world, w_world)
        self._arrived(t_ns, 'object')

    def _on_desired_twist(self, msg):
        """Keep the newest valid desired object twist; mark the tick's input as arrived."""
        twist = (vector3(msg.twist.linear), vector3(msg.twist.angular))
        if np.all(np.isfinite(twist)):
            self._latest['desired_twist'] = twist
        else:
            self.refusals.refuse('desired_twist', 'desired twist contains NaN or Inf')
        self._arrived(stamp_ns(msg.header.stamp), 'desired_twist')

    def _on_phase(self, msg):
        """Keep the newest valid phase; mark the tick's input as arrived."""
        statuses = [status for status in msg.status if status.name == contract.PHASE_STATUS_NAME]
        try:
            self._latest['phase'] = Phase(statuses[0].message)
        except (IndexError, ValueError):
            self.refusals.refuse('phase', f'no {contract.PHASE_STATUS_NAME} status with a phase '
                                          f'in {[(s.name, s.message) for s in msg.status]}')
        self._arrived(stamp_ns(msg.header.stamp), 'phase')

    def _on_joint_state(self, arm, msg):
        """Keep the arm's newest valid joint positions; mark the tick's input as arrived."""
        try:
            self._latest[arm], _, _ = joint_state_arrays(msg, contract.joint_names(arm))
        except InputError as error:
            self.refusals.refuse(f'{arm}_joint_state', str(error))
        self._arrived(stamp_ns(msg.header.stamp), arm)

    def _arrived(self, t_ns, name):
        """Record an input of stamp t_ns; process the tick t_ns once all its inputs are in."""
        arrived = self._arrivals.setdefault(t_ns, set())
        arrived.add(name)
        if arrived >= self._tick_inputs:
            self._arrivals = {t: inputs for t, inputs in self._arrivals.items() if t > t_ns}
            self._process_tick(t_ns)
        while len(self._arrivals) > MAX_PENDING_STAMPS:
            del self._arrivals[next(iter(self._arrivals))]

    # -- tick ------------------------------------------------------------------------------------

    def _process_tick(self, t_ns):
        """
        Run the distributor for tick t_ns and publish both pad wrenches.

        The same tick again (the bridge republished a stalled cycle, e.g. while a subscriber
        was still being discovered) gets the same answer without touching the filters.
        """
        if t_ns == self._schedule.last_tick_ns and self._last_wrenches is not None:
            self.counters['repeated_answers'] += 1
            self._publish_wrenches(t_ns, self._last_wrenches)
            return
        self.counters['ticks'] += 1
        dt = self._schedule.take(t_ns)
        if self._pending_config is not None:
            self._config, self._pending_config = self._pending_config, None
            self._distributor.reconfigure(self._config)
        phase = self._latest.get('phase')
        if self._pending_object is not None and phase not in GRASPING_PHASES:
            self.object_mass, self.object_size = self._pending_object
            self._pending_object = None
            self._distributor = WrenchDistributor(self._config, self.object_mass,
                                                  self.object_size)
            self.counters['object_changes_applied'] += 1
        self._last_wrenches = self._wrenches(t_ns, phase, dt)
        self._publish_wrenches(t_ns, self._last_wrenches)
        self._diagnostics.publish_if_due(t_ns, self._report)

    def _publish_wrenches(self, t_ns, wrenches):
        """Publish both pad wrenches stamped t_ns."""
        for arm in contract.ARMS:
            msg = self._wrench_msgs[arm]
            msg.header.stamp = time_msg(t_ns)
            set_wrench(msg.wrench, wrenches[arm])
            self._wrench_pubs[arm].publish(msg)

    def _wrenches(self, t_ns, phase, dt):
        """Return {arm: (6,) wrench} of the tick: the distributor's, or zeros without inputs."""
        zeros = {arm: np.zeros(6) for arm in contract.ARMS}
        if phase is None:
            self.counters['ticks_without_phase'] += 1
            return zeros
        if any(arm not in self._latest for arm in contract.ARMS):
            self.counters['ticks_without_joint_states'] += 1
            return zeros
        if self._object_state is None:
            self.counters['ticks_without_object_state'] += 1
            return zeros
        v_desired, w_desired = self._latest.get('desired_twist', (np.zeros(3), np.zeros(3)))
        p_tools, R_tools = {}, {}
        for arm in contract.ARMS:
            p_tools[arm], R_tools[arm] = self._models[arm].tool_pose(self._latest[arm])
        p_object, R_object, v_object, w_object = object_state_at(self._object_state, t_ns)
        result = self._distributor.step(phase, p_tools, R_tools, p_object, R_object, v_object,
                                        w_object, v_desired, w_desired, dt)
        if phase in GRASPING_PHASES:
            self.counters['grasp_ticks'] += 1
            if not result.feasible:
                self.counters['infeasible_ticks'] += 1
                self.get_logger().warning(f'wrench QP: {result.status}',
                                          throttle_duration_sec=1.0)
        return result.wrenches

    def _report(self):
        """Return (level, message, values) of the diagnostics."""
        values = dict(self.counters)
        values.update({f'refused_{reason}': n for reason, n in self.refusals.counts.items()})
        values.update({'phase': self._latest['phase'].value if 'phase' in self._latest
                       else 'none', 'object_mass': self.object_mass})
        if self.refusals.total or self.counters['infeasible_ticks']:
            return DiagnosticStatus.WARN, 'inputs refused or QP infeasible', values
        return DiagnosticStatus.OK, 'running', values


def main(args=None):
    """Run the wrench QP until Ctrl-C or SIGTERM; return the exit code."""
    return run_node(WrenchQPNode, 'wrench_qp', args)


if __name__ == '__main__':
    sys.exit(main())
