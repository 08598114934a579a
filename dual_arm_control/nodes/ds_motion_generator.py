"""
ds_motion_generator: phases, coordinated modulated DS, orientation and object DS (eqs. 1-9).

On every DS tick (200 Hz on the FRI cycle stamps) it gathers both arms' joint states and FT
readings of that cycle and the newest object estimate (with `lockstep`, the tracker's estimate
stamped with the tick, waited for), runs DualArmMotionGenerator.step and
publishes, stamped with the tick: per-arm DS commands, the desired object twist, the phase and
markers. Parameters: the whole MotionGeneratorConfig tree (live), plus the scenario, auto-start
time and rates. Services start an episode, send the arms home and reset. A complete cycle
stamped earlier than the last tick means the clock went back (/sim/reset): the node starts over
as at start-up (fresh generator, auto start armed again), like the tracker, QP and controllers.
"""

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from dual_arm_control import contract
from dual_arm_control.contract import ARMS, joint_names
from dual_arm_control.core.exceptions import InputError
from dual_arm_control.core.motion_generator import (ArmMeasurement, DualArmMotionGenerator,
                                                    MotionGeneratorConfig, ObjectMeasurement)
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.nodes.common import (CounterDiagnostics, create_topic_publisher,
                                           fill_odometry, has_estimate,
                                           joint_state_arrays, odometry_arrays, RefusalCounter,
                                           run_node, seconds_to_ns, set_vector3, stamp_ns,
                                           TickSchedule, time_msg, wrench_array)
from dual_arm_control.nodes.markers import motion_markers
from dual_arm_control.parameters import ConfigParameters
from dual_arm_control.runtime.configuration import motion_config_for_scenario
from dual_arm_control.runtime.timing import object_state_at
from dual_arm_control.scenario import load_scenario
from geometry_msgs.msg import TwistStamped
from nav_msgs.msg import Odometry
import numpy as np
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from std_msgs.msg import Header
from std_srvs.srv import Trigger

MARKER_PERIOD = 0.05


class DsMotionGenerator(Node):
    """The motion generator node: one DualArmMotionGenerator driven by the FRI cycle stamps."""

    def __init__(self, node_name='ds_motion_generator', **node_options):
        super().__init__(node_name, **node_options)
        self._cell = load_cell()
        scenario_file = self.declare_parameter(
            'scenario', '', ParameterDescriptor(
                description='scenario YAML whose task, object, targets and speeds set the '
                            'defaults of the motion parameters (empty: built-in defaults)',
                read_only=True)).value
        base = MotionGeneratorConfig()
        if scenario_file:
            base = motion_config_for_scenario(load_scenario(scenario_file, cell=self._cell),
                                              self._cell)
        self._auto_start_ns = seconds_to_ns(self.declare_parameter(
            'auto_start_time', 0.0, ParameterDescriptor(
                description='sim time [s] at which an episode starts by itself (after the FT '
                            'tare, and once an object estimate arrived); 0 = wait for the start '
                            'service', read_only=True)).value)
        self._schedule = TickSchedule(self.declare_parameter(
            'ds_period', 0.005, ParameterDescriptor(
                description='DS tick period [s] on the FRI cycle grid', read_only=True)).value)
        self._lockstep = self.declare_parameter(
            'lockstep', False, ParameterDescriptor(
                description='on each tick wait for the object estimate stamped with the tick '
                            '(the tracker answers every /clock cycle): lockstep runs become '
                            'independent of message timing', read_only=True)).value
        self._config_parameters = ConfigParameters(self, base, self._on_config)
        self._pending_config = None
        self._generator = DualArmMotionGenerator(self._config_parameters.config)
        self._models = {arm: arm_model(arm, self._cell) for arm in ARMS}
        self._names = {arm: joint_names(arm) for arm in ARMS}
        self._refusals = RefusalCounter(self.get_logger())
        self._time_resets = 0
        self._diagnostics = CounterDiagnostics(self)
        self._joint_states = {}
        self._ft = {}
        self._object = None
        self._object_stamp_ns = None
        self._started = self._auto_start_ns == 0
        self._commands = {'start': False, 'go_home': False, 'reset': False}
        self._last_marker_ns = None
        self._last_output = None
        self._ds_publishers = {arm: self._publisher(contract.DS_COMMAND, arm) for arm in ARMS}
        self._twist_publisher = self._publisher(contract.OBJECT_DESIRED_TWIST)
        self._phase_publisher = self._publisher(contract.PHASE)
        self._marker_publisher = self._publisher(contract.MARKERS)
        for arm in ARMS:
            self.create_subscription(
                contract.JOINT_STATES.msg_type, contract.JOINT_STATES.resolved(arm),
                lambda msg, arm=arm: self._on_joint_state(arm, msg), contract.JOINT_STATES.qos)
            self.create_subscription(
                contract.FT_WRENCH.msg_type, contract.FT_WRENCH.resolved(arm),
                lambda msg, arm=arm: self._on_ft(arm, msg), contract.FT_WRENCH.qos)
        self.create_subscription(contract.OBJECT_STATE.msg_type, contract.OBJECT_STATE.name,
                                 self._on_object, contract.OBJECT_STATE.qos)
        for service, command in ((contract.START_EPISODE_SERVICE, 'start'),
                                 (contract.GO_HOME_SERVICE, 'go_home'),
                                 (contract.RESET_EPISODE_SERVICE, 'reset')):
            self.create_service(Trigger, service,
                                lambda request, response, command=command:
                                self._on_command(command, response))
        config = self._config_parameters.config
        self.get_logger().info(
            f'ds_motion_generator up: task {config.task.value}, impact speed '
            f'{config.impact.impact_speed:g} m/s, toss speed {config.toss.toss_speed:g} m/s, '
            f'auto start at {self._auto_start_ns * 1e-9:g} s (0 = start service), '
            f'{len(self._config_parameters.names)} tunable parameters')

    def _publisher(self, topic, arm=None):
        return create_topic_publisher(self, topic, arm)

    def _on_config(self, config):
        self._pending_config = config

    def _on_command(self, command, response):
        self._commands[command] = True
        response.success = True
        response.message = f'{command} requested for the next DS tick'
        return response

    def _on_object(self, msg):
        t_ns = stamp_ns(msg.header.stamp)
        if not has_estimate(msg):
            self._object = None
        else:
            try:
                position, rotation, linear, angular = odometry_arrays(msg)
            except InputError as error:
                self._refusals.refuse('object_state', str(error))
                return
            self._object = (t_ns, position, rotation, linear, angular)
        self._object_stamp_ns = t_ns
        self._try_tick()

    def _on_joint_state(self, arm, msg):
        try:
            position, _, _ = joint_state_arrays(msg, self._names[arm])
        except InputError as error:
            self._refusals.refuse('joint_state', f'{arm}: {error}')
            return
        self._joint_states.setdefault(stamp_ns(msg.header.stamp), {})[arm] = position
        self._try_tick()

    def _on_ft(self, arm, msg):
        try:
            reading = wrench_array(msg.wrench)
        except InputError as error:
            self._refusals.refuse('ft_wrench', f'{arm}: {error}')
            return
        self._ft.setdefault(stamp_ns(msg.header.stamp), {})[arm] = reading
        self._try_tick()

    def _try_tick(self):
        """Run every cycle whose four inputs are complete, in stamp order."""
        for t_ns in sorted(self._joint_states):
            if len(self._joint_states[t_ns]) < 2 or len(self._ft.get(t_ns, {})) < 2:
                continue
            if (self._lockstep and self._schedule.due(t_ns)
                    and self._object_stamp_ns != t_ns):
                break
            if self._schedule.went_back(t_ns):
                self._restart_after_time_reset(t_ns)
            joints = self._joint_states.pop(t_ns)
            readings = self._ft.pop(t_ns)
            for stale in [s for s in self._joint_states if s < t_ns]:
                del self._joint_states[stale]
            for stale in [s for s in self._ft if s < t_ns]:
                del self._ft[stale]
            if self._schedule.due(t_ns):
                self._tick(t_ns, self._schedule.take(t_ns), joints, readings)
            elif t_ns == self._schedule.last_tick_ns and self._last_output is not None:
                self._publish(t_ns, self._last_output)

    def _restart_after_time_reset(self, t_ns):
        """Start over as at start-up when a whole cycle came stamped before the last tick."""
        self.get_logger().info(
            f'cycle stamp went back from {self._schedule.last_tick_ns} ns to {t_ns} ns (clock '
            'reset): motion generator restarted in standby')
        self._generator = DualArmMotionGenerator(self._pending_config or self._generator.config)
        self._pending_config = None
        self._schedule.reset()
        self._started = self._auto_start_ns == 0
        self._commands = dict.fromkeys(self._commands, False)
        self._last_marker_ns = None
        self._last_output = None
        if self._object is not None and self._object[0] > t_ns:
            self._object = None
        for pending in (self._joint_states, self._ft):
            for stale in [s for s in pending if s > t_ns]:
                del pending[stale]
        self._time_resets += 1

    def _tick(self, t_ns, dt, joints, readings):
        if self._pending_config is not None:
            self._generator.reconfigure(self._pending_config)
            self._pending_config = None
        arms = {}
        for arm in ARMS:
            p_tool, R_tool = self._models[arm].tool_pose(joints[arm])
            _, R_sensor = self._models[arm].sensor_pose(joints[arm])
            arms[arm] = ArmMeasurement(p_tool, R_tool, readings[arm], R_sensor)
        obj = self._object_at(t_ns, arms)
        start = self._commands['start'] or (not self._started and t_ns >= self._auto_start_ns
                                            and self._object is not None)
        self._started = self._started or start
        try:
            output = self._generator.step(arms, obj, dt, start_episode=start,
                                          go_home=self._commands['go_home'],
                                          reset=self._commands['reset'])
        except InputError as error:
            self._refusals.refuse('tick', str(error))
            return
        self._commands = dict.fromkeys(self._commands, False)
        self._last_output = output
        self._publish(t_ns, output)
        self._diagnostics.publish_if_due(t_ns, lambda: self._report(output))

    def _report(self, output):
        """Return the (level, message, values) of this node's diagnostics."""
        level = DiagnosticStatus.WARN if self._refusals.total else DiagnosticStatus.OK
        values = dict(self._refusals.counts, phase=output.phase.phase.value,
                      refused_total=self._refusals.total, time_resets=self._time_resets)
        return level, f'phase {output.phase.phase.value}', values

    def _object_at(self, t_ns, arms):
        """Return the newest object estimate predicted to t_ns, or a stand-in between the pads."""
        if self._object is None:
            midpoint = 0.5 * (arms['left'].p_world_tool + arms['right'].p_world_tool)
            return ObjectMeasurement(midpoint, np.eye(3), np.zeros(3))
        position, rotation, linear, _ = object_state_at(self._object, t_ns)
        return ObjectMeasurement(position, rotation, linear)

    def _publish(self, t_ns, output):
        stamp = time_msg(t_ns)
        for arm in ARMS:
            command = output.commands[arm]
            msg = Odometry()
            msg.header.stamp = stamp
            msg.header.frame_id = contract.WORLD_FRAME
            msg.child_frame_id = f'{arm}_tool'
            fill_odometry(msg, command.p_world_attractor, command.R_world_desired,
                          command.v_world, command.w_world)
            self._ds_publishers[arm].publish(msg)
        twist = TwistStamped()
        twist.header.stamp = stamp
        twist.header.frame_id = contract.WORLD_FRAME
        set_vector3(twist.twist.linear, output.object_velocity)
        set_vector3(twist.twist.angular, output.object_angular_velocity)
        self._twist_publisher.publish(twist)
        self._phase_publisher.publish(phase_message(stamp, output.phase))
        if (self._last_marker_ns is None
                or t_ns - self._last_marker_ns >= seconds_to_ns(MARKER_PERIOD)):
            self._last_marker_ns = t_ns
            self._marker_publisher.publish(motion_markers(stamp, output))


def phase_message(stamp, phase_output):
    """Return the DiagnosticArray that carries one tick's phase, task, events and reason."""
    transition = phase_output.transition
    status = DiagnosticStatus(
        level=DiagnosticStatus.OK, name=contract.PHASE_STATUS_NAME, hardware_id='dual_arm',
        message=phase_output.phase.value,
        values=[KeyValue(key='task', value=phase_output.task.value),
                KeyValue(key='time_in_phase', value=f'{phase_output.time_in_phase:.6f}'),
                KeyValue(key='events', value=','.join(phase_output.events)),
                KeyValue(key='reason', value='' if transition is None else transition.reason)])
    return DiagnosticArray(header=Header(stamp=stamp, frame_id=contract.WORLD_FRAME),
                           status=[status])


def main(args=None):
    """Run the ds_motion_generator node."""
    return run_node(DsMotionGenerator, 'ds_motion_generator', args)
